"""docs/tutorial.md: every ```python block runs, in order, in one namespace, in a fresh
folder — the page's own asserts are the test."""

from __future__ import annotations

import re

import pytest
from locations import ROOT

TUTORIAL = ROOT / "docs" / "tutorial.md"


def python_blocks(text: str) -> list[str]:
    """The fenced ```python blocks of a Markdown page, in order.

    >>> python_blocks("a\\n```python\\nx = 1\\n```\\n```bash\\nls\\n```\\n")
    ['x = 1\\n']
    """
    return re.findall(r"^```python\n(.*?)^```$", text, flags=re.DOTALL | re.MULTILINE)


def test_tutorial_has_the_four_parts():
    text = TUTORIAL.read_text(encoding="utf-8")
    headings = re.findall(r"^## (.+)$", text, flags=re.MULTILINE)
    assert headings == [
        "1. A scene of your own",
        "2. A policy of your own",
        "3. Events into Tonic",
        "4. A sweep",
    ]
    assert len(python_blocks(text)) == 5


@pytest.mark.slow
def test_tutorial_code_blocks_run(tmp_path, monkeypatch):
    pytest.importorskip("tonic")
    monkeypatch.chdir(tmp_path)
    namespace: dict = {"__name__": "tutorial"}
    for i, block in enumerate(python_blocks(TUTORIAL.read_text(encoding="utf-8"))):
        exec(compile(block, f"{TUTORIAL}:block{i + 1}", "exec"), namespace)
    assert (tmp_path / "pendulum.aedat4").is_file()
    assert (tmp_path / "sweep" / "results.csv").is_file()
