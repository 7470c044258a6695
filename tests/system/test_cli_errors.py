"""Bad command lines: one line on stderr naming the option and the allowed values, exit 2,
no traceback, before any work starts; run folders new per run; strict JSON."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest
from typer.testing import CliRunner

from experiments.cli.main import app
from experiments.runs.provenance import VERSIONED_PACKAGES, package_versions, run_record
from wander_env.strict_json import dumps_strict

runner = CliRunner()
SCENES = "gratings, hand, office, shelf or a scene .yaml file"


def _strict(text: str) -> object:
    def refuse(name: str) -> None:
        raise ValueError(f"non-standard JSON constant {name}")

    return json.loads(text, parse_constant=refuse)


def test_run_with_an_unknown_scene_prints_one_line_and_exits_2():
    """The issue's bar, through a real process: ≤ 3 lines on stderr, no traceback."""
    proc = subprocess.run(
        [
            sys.executable,
            "-c",
            "from experiments.cli.main import main; main()",
            "run",
            "--scene",
            "nosuch",
        ],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 2
    assert "Traceback" not in proc.stderr and proc.stdout == ""
    assert proc.stderr.splitlines() == [
        f"wander run: Invalid value for '--scene': unknown scene 'nosuch'; allowed: {SCENES}"
    ]


@pytest.mark.parametrize(
    ("args", "line"),
    [
        (
            ["run", "--dvs", "bogus"],
            "wander run: Invalid value for '--dvs': unknown DVS "
            "preset 'bogus'; choose one of ['ideal', 'paper', 'speck']",
        ),
        (
            ["run", "--seconds", "-1"],
            "wander run: Invalid value for '--seconds': must be a "
            "finite number of seconds in (0, 86400], got -1.0",
        ),
        (
            ["run", "--seconds", "nan"],
            "wander run: Invalid value for '--seconds': must be a "
            "finite number of seconds in (0, 86400], got nan",
        ),
        (
            ["run", "--window", "0"],
            "wander run: Invalid value for '--window': must be a "
            "finite number of seconds > 0, got 0.0",
        ),
        (
            ["record", "--policy", "wild"],
            "wander record: Invalid value for '--policy': 'wild' "
            "is not allowed; allowed: still, fixational, saccades",
        ),
        (
            ["record", "--scene", "no/such.yaml"],
            "wander record: Invalid value for '--scene': "
            f"scene file not found: no/such.yaml; allowed: {SCENES}",
        ),
        (
            ["evaluate", "--seeds", ","],
            "wander evaluate: Invalid value for '--seeds': needs at least one seed, e.g. 0,1,2",
        ),
        (
            ["demo", "--seconds", "0.1"],
            "wander demo: Invalid value for '--seconds': 8 panels of 20.0 ms do not fit in 0.1 s",
        ),
        (
            ["sweep", "x.yaml", "--backend", "mpi"],
            "wander sweep: Invalid value for "
            "'--backend': 'mpi' is not allowed; allowed: serial, local, ray",
        ),
        (
            ["experiment", "nosuch"],
            "wander experiment: error: unknown experiment 'nosuch'; "
            "available: oms_characterisation, event_suppression, detection, sac_accuracy, "
            "scanpath, saccade_speed, oms_scorecard",
        ),
        (
            ["rig", "--ptu", "emulate", "--camera", "davis"],
            "wander rig: Invalid value for "
            "'--camera': RigConfig.camera must be 'speck', 'speck:<serial number>' or "
            "'replay:<event file>', got 'davis'",
        ),
        (
            ["rig", "--ptu", "emulate", "--camera", "replay:no/such.npz"],
            "wander rig: Invalid value for '--camera': no such event file: 'no/such.npz'",
        ),
        (
            ["perf", "floor", "--calls", "0"],
            "wander perf floor: Invalid value for '--calls': must be an integer >= 1, got 0",
        ),
        (
            ["perf", "env", "--antialias", "-1"],
            "wander perf env: Invalid value for '--antialias': input should be greater than or "
            "equal to 0, got -1",
        ),
        (
            ["run", "--alpha", "-0.1"],
            "wander run: Invalid value for '--alpha': alpha must be in [0, 1], got -0.1",
        ),
        (
            ["rig", "--ptu", "/dev/no-such-ptu", "--camera", "speck"],
            "wander rig: Invalid value for '--ptu': no such serial port: '/dev/no-such-ptu' "
            "(is the PTU's USB-serial adapter plugged in? Give a device such as /dev/ttyUSB0, "
            "a pyserial URL such as socket://host:4000, or 'emulate')",
        ),
        (
            ["perf", "env", "--scene", "nosuch"],
            "wander perf env: Invalid value for "
            f"'--scene': unknown scene 'nosuch'; allowed: {SCENES}",
        ),
        (
            ["view", "no/such/run"],
            "wander view: Invalid value for 'RUN_DIR': no run.rrd in "
            "'no/such/run' (a run folder of wander run, record or rig)",
        ),
    ],
)
def test_bad_options_are_one_line_with_exit_2(args, line, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    result = runner.invoke(app, args, prog_name="wander")
    assert result.exit_code == 2, result.output
    assert result.stderr.splitlines() == [line]
    assert result.stdout == ""
    assert not (tmp_path / "runs").exists()  # refused before anything was written


def test_run_folders_are_new_per_run_and_never_overwritten(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    args = ["demo", "--seconds", "0.2"]
    for _ in range(2):
        assert runner.invoke(app, args).exit_code == 0
    made = sorted(p.name for p in (tmp_path / "runs").iterdir())
    assert len(made) == 2 and all(n.startswith("demo-") for n in made)
    out = tmp_path / "runs" / made[0]
    before = (out / "run.json").read_bytes()
    refused = runner.invoke(app, [*args, "--out", str(out)], prog_name="wander")
    assert refused.exit_code == 2
    assert refused.stderr.splitlines() == [
        f"wander demo: Invalid value for '--out': {str(out)!r} is not empty: pass --force to "
        "replace it, or leave --out out for a new folder"
    ]
    assert (out / "run.json").read_bytes() == before
    assert runner.invoke(app, [*args, "--out", str(out), "--force"]).exit_code == 0
    assert (out / "run.json").read_bytes() != before  # written again (new created time)


def test_report_never_overwrites_without_force(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "REPORT.md").write_text("my notes\n")
    result = runner.invoke(app, ["report", "--results", str(tmp_path)], prog_name="wander")
    assert result.exit_code == 2
    assert result.stderr.splitlines() == [
        "wander report: Invalid value for '--out': 'REPORT.md' exists: pass --force to "
        "overwrite it, or --out another file"
    ]
    assert (tmp_path / "REPORT.md").read_text() == "my notes\n"
    assert runner.invoke(app, ["report", "--results", str(tmp_path), "--force"]).exit_code == 0
    text = (tmp_path / "REPORT.md").read_text()
    assert "../shared" not in text and "paper.tex" not in text
    assert (
        "G. D'Angelo, V. Clerico, C. Bartolozzi, M. Hoffmann, P. M. Furlong and A. Hadjiivanov, "
        '"Wandering around: A bioinspired approach to visual attention through object motion '
        'sensitivity"'
    ) in text


def test_strict_json_and_versions():
    record = run_record("wander test", {"x": float("nan"), "y": [float("inf"), 2.0]}, 1)
    parsed = _strict(dumps_strict(record))
    assert parsed["config"] == {"x": None, "y": [None, 2.0]}
    assert set(parsed["versions"]) == {"python", *VERSIONED_PACKAGES}
    assert set(VERSIONED_PACKAGES) == {
        "numpy",
        "mujoco",
        "torch",
        "sinabs",
        "nengo",
        "gymnasium",
        "wander",
    }
    import numpy as np
    import torch

    versions = package_versions()
    assert versions["numpy"] == np.__version__
    assert versions["torch"] == torch.__version__
    assert versions["python"] == ".".join(map(str, sys.version_info[:3]))


SCENE_PART = "{shape: sphere, size: [0.1], position: [1, %s, 1], name: %s}"


@pytest.mark.parametrize(
    ("names", "problem"),
    [
        (["ball", "ball"], "static_objects: names must differ, got ball twice"),
        (["cup", "ball", "cup", "ball"], "static_objects: names must differ, got ball, cup twice"),
        (['"b\\0all"'], r"static_objects: a name must not hold control characters, got 'b\x00all'"),
        (['"b\\nall"'], r"static_objects: a name must not hold control characters, got 'b\nall'"),
    ],
)
def test_scene_object_names_are_checked_in_one_line(tmp_path, monkeypatch, names, problem):
    """Two objects of one name, or a NUL in a name, made MuJoCo's XML reader fail with a
    traceback; the scene's validation names them first."""
    monkeypatch.chdir(tmp_path)
    parts = [SCENE_PART % (0.3 * i, n) for i, n in enumerate(names)]
    (tmp_path / "s.yaml").write_text("static_objects:\n" + "".join(f"  - {p}\n" for p in parts))
    args = ["run", "--scene", "s.yaml", "--seconds", "0.1"]
    result = runner.invoke(app, args, prog_name="wander")
    assert result.exit_code == 2
    assert result.stderr.splitlines() == [
        f"wander run: Invalid value for '--scene': s.yaml: {problem}"
    ]
    assert not (tmp_path / "runs").exists()


def test_an_error_quotes_at_most_200_characters_of_a_file(tmp_path, monkeypatch):
    """The issue's case: ``--scene /etc/passwd`` quoted 1.3 KB of the file."""
    import yaml

    from wander_env.config_messages import SHOWN_CHARS

    monkeypatch.chdir(tmp_path)
    text = "".join(f"user{i}:x:{i}:{i}::/home/user{i}:/bin/sh\n" for i in range(40))
    (tmp_path / "etc").mkdir()
    (tmp_path / "etc" / "passwd").write_text(text)
    result = runner.invoke(app, ["run", "--scene", "etc/passwd"], prog_name="wander")
    assert result.exit_code == 2
    quoted = repr(yaml.safe_load(text))[: SHOWN_CHARS - 3] + "..."
    assert result.stderr.splitlines() == [
        f"wander run: Invalid value for '--scene': etc/passwd: expected a mapping of key: value, "
        f"got {quoted}"
    ]
    assert len(quoted) == 200 and len(text) > 1300


def test_unknown_keys_are_named_once_with_the_allowed_keys(tmp_path):
    """A scanpath config.json read as another experiment's said the allowed keys once per
    unknown key (2,885 characters); now once per block, at most ten keys named."""
    from dataclasses import dataclass

    from wander_env.config import ConfigError, validate

    @dataclass(frozen=True)
    class Box:
        size: float = 1.0

    with pytest.raises(ConfigError) as err:
        validate(Box, {**{f"k{i}": 1 for i in range(12)}, "size": "x"}, where="b.yaml")
    assert str(err.value) == (
        "b.yaml: size: expected float, got 'x'; unknown keys 'k0', 'k1', 'k2', 'k3', 'k4', "
        "'k5', 'k6', 'k7', 'k8', 'k9' and 2 more for Box; allowed keys: size (float)"
    )
