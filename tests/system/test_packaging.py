"""Packaging: the wheel holds every package and the scene assets (package data).

``.ci/run`` also installs the wheel into a fresh virtual environment outside the
checkout and runs ``wander run --seconds 1`` from another folder.
"""

from __future__ import annotations

import importlib.util
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest
from locations import ROOT

tomllib = pytest.importorskip("tomllib")  # the standard library's from Python 3.11

PACKAGE_ROOTS = ("wander_env", "agents", "hardware", "experiments")
SKIP_DIRS = {"__pycache__", ".pytest_cache"}


def _pyproject() -> dict:
    return tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))


def _source_packages() -> set[str]:
    """Every folder under the package roots that holds Python files or data."""
    found = set()
    for top in PACKAGE_ROOTS:
        for d in [ROOT / top, *(ROOT / top).rglob("*")]:
            if (
                d.is_dir()
                and not SKIP_DIRS & set(d.parts)
                and any(d.glob("*.py")) | any(d.glob("*.yaml"))
            ):
                found.add(".".join(d.relative_to(ROOT).parts))
    return found


def test_every_package_is_listed_in_pyproject():
    listed = set(_pyproject()["tool"]["setuptools"]["packages"])
    missing = _source_packages() - listed
    assert not missing, f"add {sorted(missing)} to [tool.setuptools] packages in pyproject.toml"
    assert _pyproject()["tool"]["setuptools"]["package-dir"] == {"wander_env.assets": "assets"}
    assert "wander_env.assets" in listed


def test_scenes_load_from_the_checkout_assets_folder():
    from wander_env.scenes import assets_dir, available_scenes

    assert assets_dir() == ROOT / "assets"
    assert set(available_scenes()) == {p.stem for p in (ROOT / "assets" / "scenes").glob("*.yaml")}


@pytest.mark.slow
def test_a_wheel_built_from_the_checkout_contains_the_scene_files(tmp_path):
    src = tmp_path / "src"
    patterns = shutil.ignore_patterns(".venv", ".git", "build", "dist", "*.egg-info", "__pycache__")

    def ignore(folder: str, names: list[str]) -> set[str]:
        # the checkout's own run folders, not the package experiments/runs
        top = {"runs", "results"} & set(names) if Path(folder) == ROOT else set()
        return set(patterns(folder, names)) | top

    shutil.copytree(ROOT, src, ignore=ignore)
    isolation = [] if importlib.util.find_spec("setuptools") is None else ["--no-build-isolation"]
    cmd = [
        sys.executable,
        "-m",
        "pip",
        "wheel",
        "--no-deps",
        *isolation,
        "-w",
        str(tmp_path),
        str(src),
    ]
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=600, check=False)
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-2000:]
    (wheel,) = tmp_path.glob("wander-*.whl")
    names = set(zipfile.ZipFile(wheel).namelist())
    scenes = sorted(p.name for p in (ROOT / "assets" / "scenes").glob("*.yaml"))
    assert len(scenes) >= 4
    for scene in scenes:
        assert f"wander_env/assets/scenes/{scene}" in names
    for top in PACKAGE_ROOTS:
        for py in (ROOT / top).rglob("*.py"):
            assert py.relative_to(ROOT).as_posix() in names
    for cfg in (ROOT / "experiments" / "configs").glob("*.yaml"):
        assert cfg.relative_to(ROOT).as_posix() in names
    assert any(n.endswith("/LICENSE") for n in names)
    entry = next(n for n in names if n.endswith("entry_points.txt"))
    assert "wander = experiments.cli.main:app" in zipfile.ZipFile(wheel).read(entry).decode()


def test_license_is_mit_as_pyproject_says():
    assert _pyproject()["project"]["license"] == {"text": "MIT"}
    text = (ROOT / "LICENSE").read_text(encoding="utf-8")
    assert text.startswith("MIT License\n")
    assert 'THE SOFTWARE IS PROVIDED "AS IS", WITHOUT WARRANTY OF ANY KIND' in text


PAPER = ROOT.parent / "shared" / "seed" / "paper.tex"


def test_citation_file_cites_us_and_the_paper():
    import yaml

    cff = yaml.safe_load((ROOT / "CITATION.cff").read_text(encoding="utf-8"))
    assert cff["cff-version"] == "1.2.0" and cff["type"] == "software"
    assert cff["license"] == "MIT" and cff["version"] == _pyproject()["project"]["version"]
    (paper,) = cff["references"]
    assert paper["title"].startswith("Wandering around: A bioinspired approach")
    names = [f"{a['given-names']} {a['family-names']}" for a in paper["authors"]]
    assert names[0] == "Giulia D'Angelo" and len(names) == 6
    if PAPER.is_file():  # the names exactly as the paper's source gives them, in order
        import re

        tex = PAPER.read_text(encoding="utf-8")
        assert names == re.findall(r"\\author\[[^\]]*\]\{([^}]*)\}", tex)
        title = re.search(r"\\title\{([^}]*)\}", tex)
        assert title is not None and paper["title"] == title[1]
