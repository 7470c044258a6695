"""The README is a user's guide and the docs site holds together: the README's length,
line width and links, the pages the site's navigation names, and the README's Python
example, which runs."""

from __future__ import annotations

import re

import pytest
import yaml
from locations import ROOT
from test_tutorial import python_blocks

README = ROOT / "README.md"


def markdown_links(text: str) -> list[str]:
    """The targets of a Markdown page's inline links, without their anchors.

    >>> markdown_links("see [a](docs/a.md#x), [b](https://b.org) and [c](LICENSE)")
    ['docs/a.md', 'https://b.org', 'LICENSE']
    """
    return [target.split("#")[0] for target in re.findall(r"\]\(([^)\s]+)\)", text)]


def nav_pages(nav: list) -> list[str]:
    """Every page a mkdocs ``nav`` names, depth first.

    >>> nav_pages([{"Home": "index.md"}, {"Guide": [{"A": "a.md"}, "b.md"]}])
    ['index.md', 'a.md', 'b.md']
    """
    pages: list[str] = []
    for entry in nav:
        values = entry.values() if isinstance(entry, dict) else [entry]
        for value in values:
            pages.extend(nav_pages(value) if isinstance(value, list) else [value])
    return pages


def test_readme_is_a_short_guide_without_narration():
    lines = README.read_text(encoding="utf-8").splitlines()
    assert len(lines) <= 400
    assert max(len(line) for line in lines) <= 300
    text = "\n".join(lines).lower()
    for word in ("session", "this stop", "helper", "coordinator"):
        assert word not in text, word
    assert re.search(r"^## Quickstart$", "\n".join(lines), flags=re.MULTILINE)


def test_readme_links_resolve():
    targets = [t for t in markdown_links(README.read_text(encoding="utf-8")) if "://" not in t]
    assert len(targets) >= 20
    missing = [t for t in targets if not (ROOT / t).exists()]
    assert missing == []


def test_every_page_of_the_site_exists_and_every_page_is_in_it():
    config = yaml.safe_load((ROOT / "mkdocs.yml").read_text(encoding="utf-8"))
    pages = nav_pages(config["nav"])
    docs = ROOT / "docs"
    assert [p for p in pages if not (docs / p).is_file()] == []
    on_disk = sorted(str(p.relative_to(docs)) for p in docs.rglob("*.md"))
    assert sorted(pages) == on_disk


@pytest.mark.slow
def test_readme_python_example_runs(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    blocks = python_blocks(README.read_text(encoding="utf-8"))
    assert len(blocks) == 1
    namespace: dict = {"__name__": "readme"}
    exec(compile(blocks[0], "README.md", "exec"), namespace)
    assert namespace["obs"]["events"].shape == (2, 128, 128)
    assert namespace["obs"]["gaze"].shape == (2,)
