"""Strict JSON written whole or not at all (:func:`wander_env.strict_json.write_strict`)."""

from __future__ import annotations

import errno
import os
from pathlib import Path

import pytest

from wander_env import strict_json
from wander_env.strict_json import write_strict


def test_a_write_replaces_the_file_and_leaves_nothing_beside_it(tmp_path):
    path = tmp_path / "run.json"
    path.write_text('{"seed": 0}\n')
    assert write_strict(path, {"seed": 1, "x": float("nan")}, indent=2) == path
    assert path.read_text() == '{\n  "seed": 1,\n  "x": null\n}\n'
    assert [p.name for p in tmp_path.iterdir()] == ["run.json"]


def test_a_full_disk_mid_write_keeps_the_earlier_file_and_removes_the_partial_one(
    tmp_path, monkeypatch
):
    path = tmp_path / "run.json"
    path.write_text('{"seed": 0}\n')
    write_text = Path.write_text

    def half_then_full(self: Path, text: str) -> int:
        write_text(self, text[: len(text) // 2])
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(Path, "write_text", half_then_full)
    with pytest.raises(OSError, match="No space left on device"):
        write_strict(path, {"seed": 1})
    monkeypatch.undo()
    assert path.read_text() == '{"seed": 0}\n'
    assert [p.name for p in tmp_path.iterdir()] == ["run.json"]


def test_a_refused_rename_keeps_the_earlier_file_and_removes_the_new_one(tmp_path, monkeypatch):
    path = tmp_path / "quality.json"
    path.write_text("[1]\n")

    def refuse(src: str, dst: str) -> None:
        raise OSError(errno.EXDEV, "Invalid cross-device link")

    monkeypatch.setattr(strict_json.os, "replace", refuse)
    with pytest.raises(OSError, match="cross-device"):
        write_strict(path, [2])
    monkeypatch.setattr(strict_json.os, "replace", os.replace)
    assert path.read_text() == "[1]\n"
    assert [p.name for p in tmp_path.iterdir()] == ["quality.json"]
