"""Fault injection, files: malformed event files made from the real recordings are refused.

Each file below is a real recording from ``../shared/realdata`` with one thing broken;
every one must give an :class:`EventFileError` naming the file, the field and the value,
before anything large is allocated (the header bombs are read in a subprocess whose
peak RSS is measured).
"""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap
from pathlib import Path

import h5py
import numpy as np
import pytest
from locations import REALDATA

from wander_env.events.io import EventFileError, read_events

REAL = REALDATA / "dvs128_people" / "alex_walking_for_10secs_txyp.npy"
needs_realdata = pytest.mark.skipif(not REAL.is_file(), reason="../shared/realdata absent")
pytestmark = needs_realdata


@pytest.fixture(scope="module")
def real() -> np.ndarray:
    """The first 20 000 events of the DVS128 walking recording."""
    return np.load(REAL)[:20_000]


def write_h5(path: Path, ev: np.ndarray, size=(128, 128, 2), meta: str = "{}", **cols) -> Path:
    """An events.h5 as write_events makes it, with columns replaced by ``cols``."""
    with h5py.File(path, "w") as f:
        g = f.create_group("events")
        for name in "xytp":
            g.create_dataset(name, data=cols.get(name, ev[name]))
        f.attrs["sensor_size"] = np.asarray(size)
        f.attrs["metadata"] = meta
    return path


def refused(path: Path, field: str, text: str, **kwargs) -> EventFileError:
    with pytest.raises(EventFileError) as info:
        read_events(path, **kwargs)
    err = info.value
    assert err.path == str(path)
    assert err.field == field, str(err)
    assert text in str(err), str(err)
    return err


def test_the_untouched_real_file_reads(tmp_path, real):
    rec = read_events(write_h5(tmp_path / "ok.h5", real))
    assert len(rec.events) == 20_000 and rec.sensor_size == (128, 128, 2)
    for f in "xytp":
        assert np.array_equal(rec.events[f], real[f])


@pytest.mark.parametrize(
    ("column", "index", "value", "field", "text"),
    [
        ("x", 7, 65541, "x", "x[7]=65541 is outside the sensor (0..127)"),
        ("p", 3, 257, "p", "p[3]=257 is not 0 (OFF) or 1 (ON)"),
        ("x", 9, 12.7, "x", "x[9]=12.7 is not a whole number"),
        ("t", 5, np.nan, "t", "t[5]=nan is not a finite number"),
        ("y", 0, -1, "y", "y[0]=-1 is outside the sensor"),
        ("t", 2, 2**64 - 1, "t", "does not fit in int64"),
    ],
)
def test_values_that_do_not_fit_are_errors_not_casts(
    tmp_path, real, column, index, value, field, text
):
    dtype = np.float64 if isinstance(value, float) else np.int64
    col = real[column].astype(np.uint64 if value == 2**64 - 1 else dtype)
    col[index] = value
    err = refused(write_h5(tmp_path / "bad.h5", real, **{column: col}), field, text)
    assert "bad.h5" in str(err)


def test_unsorted_timestamps_name_the_index(tmp_path, real):
    t = real["t"].copy()
    t[100] = t[101] + 5
    refused(write_h5(tmp_path / "u.h5", real, t=t), "t", f"t[100]={t[100]} > t[101]={t[101]}")


@pytest.mark.parametrize(
    ("size", "text"),
    [
        ((100000, 100000, 2), "exceeds 8192 pixels per side"),
        ((0, 0, 2), "width and height must be >= 1"),
        ((128,), "must be (width, height)"),
        ((128.5, 128, 2), "not all whole numbers"),
        ((128, 128, 3), "third entry"),
    ],
)
def test_bad_sensor_sizes(tmp_path, real, size, text):
    refused(write_h5(tmp_path / "s.h5", real, size=size), "sensor_size", text)


def test_a_larger_limit_reads_a_large_sensor(tmp_path, real):
    path = write_h5(tmp_path / "big.h5", real, size=(10000, 10000, 2))
    refused(path, "sensor_size", "exceeds 8192")
    assert read_events(path, max_sensor_side=10000).sensor_size == (10000, 10000, 2)


def test_structure_errors(tmp_path, real):
    path = tmp_path / "ds.h5"
    with h5py.File(path, "w") as f:
        f.create_dataset("events", data=real)
    refused(path, "events", "expected a group")
    refused(write_h5(tmp_path / "m.h5", real, meta="{not json"), "metadata", "not valid JSON")
    refused(write_h5(tmp_path / "l.h5", real, meta="[1, 2]"), "metadata", "a JSON object")
    refused(
        write_h5(tmp_path / "2d.h5", real, x=np.zeros((20_000, 2), np.int16)), "events/x", "1-D"
    )
    refused(
        write_h5(tmp_path / "str.h5", real, p=np.array([b"a"] * 20_000)), "events/p", "not a number"
    )


def sparse_h5(path: Path, real: np.ndarray, claimed: int) -> Path:
    """Real events in a resizable dataset, then resized to ``claimed``: nothing stored."""
    with h5py.File(path, "w") as f:
        g = f.create_group("events")
        for name in "xytp":
            ds = g.create_dataset(name, data=real[name], maxshape=(None,), chunks=(4096,))
            ds.resize((claimed,))
        f.attrs["sensor_size"] = np.asarray((128, 128, 2))
        f.attrs["metadata"] = "{}"
    return path


def test_claimed_counts_are_checked_against_what_is_stored(tmp_path, real):
    path = sparse_h5(tmp_path / "sparse.h5", real, 2**27)
    assert path.stat().st_size < 1_000_000
    refused(path, "events/x", "claims 134,217,728 events")
    contiguous = tmp_path / "contiguous.h5"
    with h5py.File(contiguous, "w") as f:
        g = f.create_group("events")
        for name in "xytp":
            g.create_dataset(name, shape=(2**27,), dtype=real.dtype[name])
        f.attrs["sensor_size"] = np.asarray((128, 128, 2))
    refused(contiguous, "events/x", "but the file holds only 0 bytes")


def test_truncated_npy_and_forged_npz(tmp_path, real):
    path = tmp_path / "cut.npy"
    np.save(path, real)
    path.write_bytes(path.read_bytes()[:5000])
    refused(path, "array", "claims 20,000 entries")
    # A stored (uncompressed) zip of an array claiming 2^27 rows.
    forged = tmp_path / "claims.npz"
    import zipfile

    with zipfile.ZipFile(forged, "w", zipfile.ZIP_STORED) as zf:
        with zf.open("events.npy", "w") as fh:
            header = {
                "descr": [("x", "<i2"), ("y", "<i2"), ("t", "<i8"), ("p", "|i1")],
                "fortran_order": False,
                "shape": (2**27,),
            }
            np.lib.format.write_array_header_1_0(fh, header)
            fh.write(bytes(100))
    refused(forged, "events", "claims 134,217,728 entries")


@pytest.mark.slow
@pytest.mark.skipif(not Path("/proc/self/status").is_file(), reason="needs /proc (Linux)")
@pytest.mark.parametrize("bomb", ["sensor", "claimed"])
def test_header_bombs_are_refused_fast_with_little_memory(tmp_path, real, bomb):
    path = (
        write_h5(tmp_path / "bomb.h5", real, size=(100000, 100000, 2))
        if bomb == "sensor"
        else sparse_h5(tmp_path / "bomb.h5", real, 2**27)
    )
    code = textwrap.dedent(
        f"""
        import json, time
        from wander_env.events.io import EventFileError, read_events
        t0 = time.perf_counter()
        try:
            read_events({str(path)!r})
            outcome = "read"
        except EventFileError as err:
            outcome = str(err)
        # VmHWM: this process's own peak (ru_maxrss keeps the parent's across fork + exec)
        with open("/proc/self/status") as fh:
            hwm = next(int(ln.split()[1]) for ln in fh if ln.startswith("VmHWM:"))
        print(json.dumps({{"s": time.perf_counter() - t0, "outcome": outcome,
                          "rss_mb": hwm / 1024}}))
        """
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=True
    )
    got = json.loads(out.stdout.strip().splitlines()[-1])
    assert "bomb.h5" in got["outcome"] and got["outcome"] != "read"
    assert got["rss_mb"] < 400  # generous under load; the report gives the measured figure


def test_an_inferred_sensor_size_is_checked_too(tmp_path, real):
    ev = real.copy()
    ev["x"][11] = 30000  # fits int16, but a 30001-pixel-wide sensor is implausible
    path = tmp_path / "wide.npy"
    np.save(path, ev)
    refused(path, "x", "x[11]=30000 is outside the sensor (0..8191)")  # before inferring
    rec = read_events(path, max_sensor_side=32768)
    assert rec.sensor_size == (30001, 128, 2) and rec.metadata["sensor_size_inferred"]


def test_the_real_aedat2_cut_mid_event(tmp_path):
    data = (REALDATA / "dvs128_people" / "alex_walking_for_10secs.aedat").read_bytes()
    path = tmp_path / "cut.aedat"
    path.write_bytes(data[:-3])
    with pytest.raises(EventFileError, match=r"cut\.aedat: truncated: \d+ bytes of events"):
        read_events(path)
    path.write_bytes(data[:-8])  # one whole event less: reads, one event short
    assert len(read_events(path).events) == 125_027
