"""Fault injection: event files whose claims would take the memory, and decoders that fail.

Issue 27's cases, each through the ``wander`` command in a fresh process under a 2.5 GB
address-space limit: one line on stderr naming the file, exit 2, no traceback, nothing
written. The files are generated here (the 2^27-event gzip HDF5 chunk by chunk, so the
test itself stays small).
"""

from __future__ import annotations

import json
import struct
import subprocess
import sys
import zlib
from pathlib import Path

import h5py
import numpy as np
import pytest

from wander_env.events import make_events
from wander_env.events.checks import MAX_EVENTS, EventFileError
from wander_env.events.formats import evt3_event_count
from wander_env.events.io import EventRecording, read_events, write_events

LIMIT_MB = 2500
BUDGET = "the agent and the benchmark model process at most 921,600 (about 1.2 KB of maps a pixel)"
# Runs ``wander ARGS`` under RLIMIT_AS and prints its exit code, stderr and peak RSS (MB).
_UNDER_LIMIT = """
import json, resource, subprocess, sys
limit = int(sys.argv[1]) << 20
def cap():
    resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
proc = subprocess.run(
    [sys.executable, "-c", "from experiments.cli.main import main; main()", *sys.argv[2:]],
    preexec_fn=cap, capture_output=True, text=True,
)
peak = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024
print(json.dumps({"rc": proc.returncode, "stderr": proc.stderr, "peak_mb": peak}))
"""


def wander(*args: object) -> dict:
    """``wander ARGS`` in a fresh process under a 2.5 GB address-space limit."""
    cmd = [sys.executable, "-c", _UNDER_LIMIT, str(LIMIT_MB), *map(str, args)]
    out = subprocess.run(cmd, capture_output=True, text=True, timeout=300, check=True)
    return json.loads(out.stdout)


def one_line(got: dict, command: str, line: str) -> None:
    assert got["rc"] == 2, got
    assert "Traceback" not in got["stderr"]
    assert got["stderr"].splitlines() == [f"{command}: {line}"]
    assert got["peak_mb"] < LIMIT_MB


def events(n: int = 50) -> np.ndarray:
    return make_events(
        np.arange(n) % 16, np.arange(n) // 16 % 16, 1000 + 40 * np.arange(n), np.arange(n) % 2
    )


@pytest.fixture(scope="module")
def masks(tmp_path_factory) -> Path:
    """Two 16x16 window masks covering the events of :func:`events`."""
    from PIL import Image

    folder = tmp_path_factory.mktemp("masks")
    for k, end in enumerate((2000, 3000)):
        m = np.zeros((16, 16), np.uint8)
        m[2:6, 2:6] = 255
        Image.fromarray(m).save(folder / f"{k:06d}_{end}.png")
    return folder


def big_sensor_h5(path: Path) -> Path:
    write_events(path, EventRecording(events(), (8192, 8192, 2)))
    return path


def big_geometry_evt3(path: Path) -> Path:
    """A real EVT3 file whose header claims an 8192x8192 sensor."""
    write_events(path, EventRecording(events(), (16, 16, 2)))
    data = path.read_bytes()
    assert data.count(b"% geometry 16x16\n") == 1
    path.write_bytes(data.replace(b"% geometry 16x16\n", b"% geometry 8192x8192\n"))
    return path


# ----------------------------------------------------------------------------------------
# The sensor area a file claims


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["h5 sensor_size", "EVT3 geometry", "--sensor"])
def test_a_claimed_8192_sensor_is_refused_in_one_line_by_the_benchmark(tmp_path, masks, kind):
    if kind == "EVT3 geometry":
        path, extra = big_geometry_evt3(tmp_path / "big.raw"), []
    elif kind == "h5 sensor_size":
        path, extra = big_sensor_h5(tmp_path / "big.h5"), []
    else:
        path = tmp_path / "small.h5"
        write_events(path, EventRecording(events(), (16, 16, 2)))
        extra = ["--sensor", "8192x8192"]
    out = tmp_path / "out"
    got = wander(
        "benchmark", "events", path, "--masks", masks, "--out", out, "--no-progress", *extra
    )
    one_line(
        got,
        "wander benchmark events",
        f"error: {path}: field 'sensor_size': 8192x8192 is 67,108,864 pixels; {BUDGET}",
    )
    assert not out.exists()


@pytest.mark.slow
def test_a_claimed_8192_sensor_is_refused_in_one_line_by_the_rig_replay(tmp_path):
    path = big_sensor_h5(tmp_path / "big.h5")
    out = tmp_path / "run"
    got = wander(
        "rig",
        "--ptu",
        "emulate",
        "--camera",
        f"replay:{path}",
        "--seconds",
        "1",
        "--out",
        out,
        "--no-video",
    )
    one_line(
        got,
        "wander rig",
        f"opening the camera 'replay:{path}' failed: {path}: field 'sensor_size': 8192x8192 "
        f"is 67,108,864 pixels; {BUDGET}",
    )
    assert not out.exists()


@pytest.mark.slow
def test_benchmark_suppression_names_the_file_over_the_budget(tmp_path):
    path = big_geometry_evt3(tmp_path / "big.raw")
    got = wander("benchmark", "suppression", path, "--out", tmp_path / "out", "--no-progress")
    one_line(
        got,
        "wander benchmark suppression",
        f"error: {path}: field 'sensor_size': 8192x8192 is 67,108,864 pixels; {BUDGET}",
    )


# ----------------------------------------------------------------------------------------
# Compressed files that inflate to GBs


@pytest.fixture(scope="module")
def gzip_2_27(tmp_path_factory) -> Path:
    """A 1.7 MB gzip HDF5 file holding 2^27 events, written 4 Mi events at a time."""
    path = tmp_path_factory.mktemp("gz") / "bomb.h5"
    n, step = 1 << 27, 1 << 22
    with h5py.File(path, "w") as f:
        g = f.create_group("events")
        for name, dtype in (("x", "<i2"), ("y", "<i2"), ("t", "<i8"), ("p", "i1")):
            ds = g.create_dataset(
                name, (n,), dtype, chunks=(1 << 20,), compression="gzip", compression_opts=9
            )
            zeros = np.zeros(step, dtype)
            for a in range(0, n, step):
                ds[a : a + step] = zeros
        f.attrs["sensor_size"] = np.array([128, 128, 2])
        f.attrs["metadata"] = "{}"
    return path


def refused_count(path: Path, n: int) -> str:
    return (
        f"{path}: field 'events': holds at least {n:,} events; at most {MAX_EVENTS:,} are "
        "read (the max_events of read_events)"
    )


@pytest.mark.slow
def test_a_gzip_h5_of_2_27_events_is_refused_before_it_inflates(tmp_path, gzip_2_27, masks):
    assert gzip_2_27.stat().st_size < 4 << 20
    with pytest.raises(EventFileError) as info:
        read_events(gzip_2_27)
    assert str(info.value) == refused_count(gzip_2_27, 1 << 27)
    got = wander(
        "benchmark", "events", gzip_2_27, "--masks", masks, "--out", tmp_path / "b", "--no-progress"
    )
    one_line(got, "wander benchmark events", f"error: {refused_count(gzip_2_27, 1 << 27)}")
    got = wander(
        "rig",
        "--ptu",
        "emulate",
        "--camera",
        f"replay:{gzip_2_27}",
        "--seconds",
        "1",
        "--out",
        tmp_path / "run",
        "--no-video",
    )
    one_line(
        got,
        "wander rig",
        f"opening the camera 'replay:{gzip_2_27}' failed: {refused_count(gzip_2_27, 1 << 27)}",
    )
    assert sorted(p.name for p in tmp_path.iterdir()) == []


@pytest.mark.parametrize("suffix", [".h5", ".npz", ".raw", ".aedat4"])
def test_every_format_counts_its_events_against_the_limit(tmp_path, suffix):
    path = tmp_path / f"ev{suffix}"
    write_events(path, EventRecording(events(50), (16, 16, 2)))
    assert len(read_events(path, max_events=50).events) == 50
    with pytest.raises(EventFileError, match=r"holds at least \d+ events; at most 49 are read"):
        read_events(path, max_events=49)


def test_evt3_events_are_counted_from_the_words():
    # ADDR_X: 1; VECT_12 with 12 bits set: 12; VECT_8 with 4 bits: 4; TIME_HIGH: none
    words = np.array([0x2005, 0x4FFF, 0x50F0, 0x8001, 0x0003], np.uint16)
    assert evt3_event_count(words) == 17


# ----------------------------------------------------------------------------------------
# Decoders and parsers that failed with a traceback


def test_an_evt21_raw_is_one_line_not_a_rust_panic(tmp_path):
    path = tmp_path / "evt21.raw"
    words = np.random.default_rng(0).integers(0, 2**63, 64, dtype=np.int64)
    path.write_bytes(b"% evt 2.1\n% geometry 640x480\n% end\n" + words.tobytes())
    got = wander("benchmark", "suppression", path, "--out", tmp_path / "out", "--no-progress")
    one_line(
        got,
        "wander benchmark suppression",
        f"error: {path}: EVT 2.1 is not read (faery has no decoder for it yet); convert it to "
        "EVT 3.0",
    )
    assert "panicked" not in got["stderr"]


def test_a_dat_header_of_100000_px_is_one_line(tmp_path):
    path = tmp_path / "wide.dat"
    head = b"% Version 2\n% Width 100000\n% Height 100000\n"
    path.write_bytes(head + bytes([0x0C, 8]) + bytes(32))
    got = wander("benchmark", "suppression", path, "--out", tmp_path / "out", "--no-progress")
    one_line(
        got,
        "wander benchmark suppression",
        f"error: {path}: field 'header geometry': (100000, 100000) exceeds 8192 pixels per "
        "side (pass a larger max_sensor_side to read it)",
    )
    with pytest.raises(EventFileError, match="DAT decoding failed, file damaged or truncated"):
        read_events(path, max_sensor_side=200_000)  # faery's OverflowError, as one error


def test_hdf5_metadata_nested_100000_deep_is_one_line(tmp_path):
    path = tmp_path / "deep.h5"
    write_events(path, EventRecording(events(), (16, 16, 2)))
    with h5py.File(path, "a") as f:
        f.attrs["metadata"] = '{"a": ' + "[" * 100_000 + "]" * 100_000 + "}"
    got = wander("benchmark", "suppression", path, "--out", tmp_path / "out", "--no-progress")
    one_line(
        got,
        "wander benchmark suppression",
        f"error: {path}: field 'metadata': JSON nested 100001 deep; at most 64",
    )
    with h5py.File(path, "a") as f:
        f.attrs["metadata"] = '{"a": ' + "[" * 64 + "]" * 64 + "}"  # 65 levels: parses
    with pytest.raises(EventFileError, match="JSON nested 65 deep; at most 64"):
        read_events(path)


def _png_header(path: Path, w: int, h: int) -> Path:
    """A PNG whose header claims ``w`` x ``h`` 8-bit grey pixels, with no pixel data."""

    def chunk(kind: bytes, data: bytes) -> bytes:
        return (
            struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))
        )

    ihdr = struct.pack(">IIBBBBB", w, h, 8, 0, 0, 0, 0)
    path.write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IEND", b""))
    return path


@pytest.mark.parametrize(
    ("side", "problem"),
    [
        (5000, "mask image of 5000x5000 pixels; at most 16,777,216 are read"),
        (
            15000,
            "mask image too large (Image size (225000000 pixels) exceeds limit of 178956970 "
            "pixels, could be decompression bomb DOS attack.)",
        ),
        (
            10000,
            "mask image too large (Image size (100000000 pixels) exceeds limit of 89478485 "
            "pixels, could be decompression bomb DOS attack.)",
        ),
    ],
)
def test_a_huge_mask_png_is_one_line(tmp_path, side, problem):
    path = tmp_path / "ev.h5"
    write_events(path, EventRecording(events(), (16, 16, 2)))
    folder = tmp_path / "masks"
    folder.mkdir()
    mask = _png_header(folder / "000000_2000.png", side, side)
    got = wander(
        "benchmark",
        "events",
        path,
        "--masks",
        folder,
        "--out",
        tmp_path / "out",
        "--window-us",
        "1000",
        "--no-progress",
    )
    one_line(got, "wander benchmark events", f"error: {mask}: {problem}")
    assert not (tmp_path / "out").exists()


class PanicException(BaseException):
    """Stands in for ``pyo3_runtime.PanicException``: a Rust panic, not an ``Exception``."""


def test_a_decoder_panic_becomes_one_event_file_error_and_nothing_broader():
    from wander_env.events.formats import _decoding

    path = Path("x.raw")
    with pytest.raises(EventFileError) as info, _decoding(path, "EVT2 decoding"):
        raise PanicException("index out of bounds")
    assert str(info.value) == (
        "x.raw: EVT2 decoding failed: the decoder gave up on this file (index out of bounds)"
    )
    with pytest.raises(EventFileError, match=r"damaged or truncated \(out of range\)"):
        with _decoding(path, "DAT decoding"):
            raise OverflowError("out of range")
    with pytest.raises(KeyboardInterrupt), _decoding(path, "EVT2 decoding"):
        raise KeyboardInterrupt
