"""Fault injection, disks: a full disk (a tiny tmpfs) and a read-only folder give one line
naming the file, a folder marked INCOMPLETE and a readable events.h5, never a segfault.

Needs root (to mount a tmpfs); skipped with the reason otherwise.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from locations import ROOT

from wander_env.events import make_events
from wander_env.events.io import read_events
from wander_env.events.stream import EventStreamWriter, OutputError


def _mount(path: Path, options: str) -> None:
    path.mkdir(parents=True, exist_ok=True)
    done = subprocess.run(
        ["mount", "-t", "tmpfs", "-o", options, "tmpfs", str(path)], capture_output=True
    )
    if done.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs: {done.stderr.decode().strip()}")


def _umount(path: Path) -> None:
    subprocess.run(["umount", str(path)], capture_output=True)


@pytest.fixture
def tiny_disk(tmp_path):
    if os.geteuid() != 0 or shutil.which("mount") is None:
        pytest.skip("a full disk needs a tiny tmpfs, and mounting one needs root")
    disk = tmp_path / "disk"
    _mount(disk, "size=2m")
    yield disk
    _umount(disk)


def steps(n: int, per_step: int = 20_000):
    rng = np.random.default_rng(0)
    for k in range(n):
        t = np.sort(rng.integers(k * 10_000, (k + 1) * 10_000, per_step))
        yield make_events(
            rng.integers(0, 128, per_step),
            rng.integers(0, 128, per_step),
            t,
            rng.integers(0, 2, per_step),
        )


def test_stream_writer_on_a_full_disk_names_the_file_and_keeps_what_was_flushed(tiny_disk):
    path = tiny_disk / "events.h5"
    writer = EventStreamWriter(path, (128, 128, 2), {"seed": 0}, chunk_events=20_000)
    written = 0
    with pytest.raises(OutputError) as info:
        for ev in steps(1000):
            writer.append(ev)
            written += len(ev)
    with pytest.raises(OutputError):
        writer.close()  # the rest cannot be written either; the file is closed, no crash
    assert str(info.value).startswith(f"cannot write {path}: No space left on device")
    rec = read_events(path)
    # every step before the one that did not fit, whole chunks, and the file says so
    assert 0 < len(rec.events) == written and written % 20_000 == 0
    assert rec.metadata["incomplete"] == {"events": written, "last_t_us": int(rec.events["t"][-1])}


@pytest.mark.slow
@pytest.mark.parametrize("video", [False, True])
def test_record_on_a_full_disk_is_one_line_and_an_incomplete_folder(tiny_disk, video):
    out = tiny_disk / "rec"
    env = {**os.environ, "PYTHONPATH": str(ROOT), "MUJOCO_GL": "egl"}
    code = "import sys; from experiments.cli.main import app; sys.argv[0] = 'wander'; app()"
    args = ["record", "--seconds", "10", "--out", str(out), "--video" if video else "--no-video"]
    done = subprocess.run(
        [sys.executable, "-c", code, *args], env=env, capture_output=True, text=True, timeout=600
    )
    assert done.returncode == 1, done.stderr  # not 139 (segfault), not a traceback
    lines = [ln for ln in done.stderr.splitlines() if ln.strip()]
    assert lines[-1].startswith(f"wander record: cannot write {out}/"), done.stderr
    assert "No space left on device" in lines[-1] and "marked INCOMPLETE" in lines[-1]
    assert "Traceback" not in done.stderr
    assert (out / "INCOMPLETE").is_file()
    rec = read_events(out / "events.h5")
    assert rec.sensor_size == (128, 128, 2)


def test_a_read_only_folder_is_one_line(tmp_path):
    if os.geteuid() != 0 or shutil.which("mount") is None:
        pytest.skip("a read-only folder for root needs a read-only mount (root only)")
    ro = tmp_path / "ro"
    _mount(ro, "size=1m,ro")
    try:
        from typer.testing import CliRunner

        from experiments.cli.main import app

        args = ["record", "--seconds", "0.1", "--out", str(ro / "x")]
        result = CliRunner().invoke(app, args, prog_name="wander")
        assert result.exit_code == 2  # refused when the folder is made, before any step
        assert result.stderr.strip() == (
            f"wander record: Invalid value for '--out': cannot create {str(ro / 'x')!r}: "
            "Read-only file system"
        )
    finally:
        _umount(ro)


@pytest.mark.slow
def test_a_full_disk_marks_the_default_run_folder_incomplete(tiny_disk):
    # No --out: the command names its folder (runs/record-DATE-TIME) and the failure is
    # said there, not in a folder it would have had to learn from the flag.
    env = {**os.environ, "PYTHONPATH": str(ROOT), "MUJOCO_GL": "egl"}
    code = "import sys; from experiments.cli.main import app; sys.argv[0] = 'wander'; app()"
    args = ["record", "--seconds", "10", "--no-video"]
    done = subprocess.run(
        [sys.executable, "-c", code, *args],
        env=env,
        cwd=tiny_disk,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert done.returncode == 1, done.stderr
    (out,) = (tiny_disk / "runs").iterdir()
    assert out.name.startswith("record-")
    lines = [ln for ln in done.stderr.splitlines() if ln.strip()]
    assert "No space left on device" in lines[-1] and "marked INCOMPLETE" in lines[-1]
    assert "Traceback" not in done.stderr
    assert (out / "INCOMPLETE").is_file()
    assert json.loads((out / "metrics.json").read_text())["incomplete"] is True
