"""Full disks end in one line: write_events (every format), h5py's close after a failed
write, ``wander demo`` and ``wander record``'s conversion, on a tiny tmpfs; never a
segfault, and a run's folder marked INCOMPLETE with its metrics.json.

Needs root (to mount a tmpfs); skipped with the reason otherwise.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
from locations import ROOT
from test_faults_disk import _mount, _umount

ENV = {**os.environ, "PYTHONPATH": str(ROOT), "MUJOCO_GL": "egl"}


def _disk(tmp_path: Path, size: str) -> Path:
    if os.geteuid() != 0 or shutil.which("mount") is None:
        pytest.skip("a full disk needs a tiny tmpfs, and mounting one needs root")
    disk = tmp_path / "disk"
    _mount(disk, f"size={size}")
    return disk


@pytest.fixture
def tiny_disk(tmp_path):
    disk = _disk(tmp_path, "2m")
    yield disk
    _umount(disk)


def python(code: str, *args: str, cwd: Path | None = None) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-c", textwrap.dedent(code), *args],
        env=ENV,
        capture_output=True,
        text=True,
        timeout=300,
        cwd=cwd,
    )


# 2,000,000 events (32 MB raw, ~6 MB as .h5) written to a 2 MiB disk; ``checked``: the
# free-space check on, else off (a disk that fills while the file is written).
WRITE = """
    import sys
    import numpy as np
    from wander_env.events import make_events
    from wander_env.events.io import EventRecording, write_events
    from wander_env.events import io

    if sys.argv[2] == "unchecked":
        io.check_space = lambda path, need: None
    rng = np.random.default_rng(0)
    n = 2_000_000
    ev = make_events(
        rng.integers(0, 128, n), rng.integers(0, 128, n),
        np.sort(rng.integers(0, 10**7, n)), rng.integers(0, 2, n),
    )
    try:
        write_events(sys.argv[1], EventRecording(ev, (128, 128, 2), {}))
    except OSError as err:
        print(f"{type(err).__name__} {err.errno}: {err}")
"""


@pytest.mark.parametrize("name", ["e.h5", "e.npz", "e.aedat4", "e.raw"])
def test_write_events_on_a_full_disk_is_one_line_before_writing(tiny_disk, name):
    done = python(WRITE, str(tiny_disk / name), "checked")
    assert (done.returncode, done.stderr) == (0, "")
    need = {"e.h5": 5_896_817, "e.npz": 10_085_956, "e.aedat4": 32_065_536, "e.raw": 32_065_536}
    assert done.stdout == (
        f"OutputError 28: cannot write {tiny_disk / name}: No space left on device "
        f"(2,097,152 bytes free; {need[name]:,} needed plus a reserve of 1,048,576)\n"
    )
    assert list(tiny_disk.iterdir()) == []


@pytest.mark.parametrize("name", ["e.h5", "e.aedat4"])
def test_a_disk_that_fills_while_writing_is_one_line_not_a_segfault(tiny_disk, name):
    done = python(WRITE, str(tiny_disk / name), "unchecked")
    # plain h5py segfaults here (rc -11) in a dealloc after ENOSPC; faery raises a
    # RuntimeError: both are OutputError (an OSError, errno 28), the partial file removed
    assert (done.returncode, done.stderr) == (0, "")
    assert done.stdout == (
        f"OutputError 28: cannot write {tiny_disk / name}: No space left on device\n"
    )
    assert list(tiny_disk.iterdir()) == []


# An HDF5 file appended and flushed until the disk is full, then closed through divert_h5.
APPEND = """
    import sys
    import h5py
    import numpy as np
    from wander_env.events.io import divert_h5

    rng = np.random.default_rng(0)
    f = h5py.File(sys.argv[1], "w")
    ds = f.create_dataset("t", shape=(0,), maxshape=(None,), dtype="i8", chunks=(65536,),
                          compression="gzip")
    n = 0
    try:
        for k in range(100):
            ds.resize((n + 65536,))
            ds[n:] = rng.integers(0, 1 << 40, 65536)
            n += 65536
            f.attrs["rows"] = n
            f.flush()
    except (OSError, RuntimeError) as err:
        divert_h5(f)
        print("failed after", n - 65536, "rows")
    f.close()
    with h5py.File(sys.argv[1], "r") as g:
        print("reread", int(g.attrs["rows"]) >= n - 65536, g["t"].shape[0] >= n - 65536)
"""


def test_an_h5_file_diverted_after_a_failed_flush_closes_without_a_segfault(tiny_disk):
    done = python(APPEND, str(tiny_disk / "a.h5"))
    assert done.returncode == 0, done.stderr[-2000:]  # without divert_h5: -11 (segfault)
    lines = done.stdout.splitlines()
    assert lines[0].startswith("failed after ") and int(lines[0].split()[2]) > 0
    assert lines[1] == "reread True True"


@pytest.mark.slow
def test_demo_on_a_full_disk_is_one_line_and_an_incomplete_folder(tiny_disk):
    out = tiny_disk / "demo"
    code = "import sys; from experiments.cli.main import app; sys.argv[0] = 'wander'; app()"
    done = python(code, "demo", "--out", str(out))
    assert done.returncode == 1, done.stderr  # not 139 (segfault), not a traceback
    (line,) = [ln for ln in done.stderr.splitlines() if ln.startswith("wander")]
    assert line.startswith(
        f"wander demo: cannot write {out / 'events.h5'}: No space left on device (2,"
    )
    assert line.endswith(f"; {str(out)!r} is marked INCOMPLETE")
    assert "Traceback" not in done.stderr
    assert sorted(p.name for p in out.iterdir()) == ["INCOMPLETE", "metrics.json"]
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["incomplete"] is True and metrics["error"].startswith("OutputError: ")


@pytest.mark.slow
def test_record_whose_conversion_fills_the_disk_is_one_line_and_an_incomplete_folder(
    tmp_path,
):
    disk = _disk(tmp_path, "6m")  # the streamed events.h5 fits; its AEDAT 4 copy does not
    try:
        out = disk / "rec"
        code = "import sys; from experiments.cli.main import app; sys.argv[0] = 'wander'; app()"
        args = ["record", "--seconds", "1", "--no-video", "--format", "aedat4", "--out", str(out)]
        done = python(code, *args)
        assert done.returncode == 1, done.stderr
        (line,) = [ln for ln in done.stderr.splitlines() if ln.startswith("wander")]
        assert line.startswith(
            f"wander record: cannot write {out / 'events.aedat4'}: No space left on device ("
        )
        assert line.endswith(f"; {str(out)!r} is marked INCOMPLETE")
        assert "Traceback" not in done.stderr
        names = {p.name for p in out.iterdir()}
        assert {"INCOMPLETE", "metrics.json", "events.h5"} <= names
        assert "events.aedat4" not in names
        assert json.loads((out / "metrics.json").read_text())["incomplete"] is True
    finally:
        _umount(disk)
