"""Event files: round trips, the real recordings in ../shared/realdata, and bad files."""

from __future__ import annotations

import numpy as np
import pytest
from locations import REALDATA

from wander_env.events import make_events
from wander_env.events.io import EventFileError, EventRecording, read_events, write_events

needs_realdata = pytest.mark.skipif(not REALDATA.is_dir(), reason="../shared/realdata absent")


def recording() -> EventRecording:
    rng = np.random.default_rng(0)
    n = 5000
    ev = make_events(
        rng.integers(0, 128, n),
        rng.integers(0, 96, n),
        np.sort(rng.integers(0, 10**6, n)),
        rng.integers(0, 2, n),
    )
    return EventRecording(ev, (128, 96, 2), {"seed": 0, "preset": "ideal"})


@pytest.mark.parametrize("suffix", [".npz", ".h5", ".hdf5"])
def test_round_trip_keeps_events_size_and_metadata(tmp_path, suffix):
    rec = recording()
    path = tmp_path / f"ev{suffix}"
    write_events(path, rec)
    back = read_events(path)
    assert np.array_equal(back.events, rec.events)
    assert back.sensor_size == (128, 96, 2)
    assert back.metadata == {"seed": 0, "preset": "ideal"}


@pytest.mark.parametrize("suffix", [".npz", ".h5"])
def test_empty_recording_round_trips(tmp_path, suffix):
    rec = EventRecording(make_events([], [], [], []), (128, 128, 2), {"note": "failed at step 1"})
    write_events(tmp_path / f"e{suffix}", rec)
    back = read_events(tmp_path / f"e{suffix}")
    assert len(back.events) == 0 and back.events.dtype == rec.events.dtype
    assert back.sensor_size == (128, 128, 2) and back.metadata == {"note": "failed at step 1"}


@pytest.mark.parametrize(
    ("text", "problem"),
    [
        ('{"seed": 1, "seed": 2}', "the key 'seed' is given twice"),
        ('{"a": {"b": 1, "b": 1}}', "the key 'b' is given twice"),
        ('{"a": ' + "[" * 64 + "]" * 64 + "}", "JSON nested 65 deep; at most 64"),
    ],
)
def test_h5_metadata_is_parsed_by_the_rules_of_every_untrusted_json(tmp_path, text, problem):
    import h5py

    path = tmp_path / "m.h5"
    write_events(path, recording())
    with h5py.File(path, "a") as f:
        f.attrs["metadata"] = text
    with pytest.raises(EventFileError) as info:
        read_events(path)
    assert str(info.value) == f"{path}: field 'metadata': {problem}"
    assert info.value.field == "metadata"


def test_hdf5_is_compressed(tmp_path):
    rec = recording()
    write_events(tmp_path / "a.h5", rec)
    assert (tmp_path / "a.h5").stat().st_size < rec.events.nbytes


def test_writing_refuses_unknown_suffix_and_invalid_events(tmp_path):
    rec = recording()
    with pytest.raises(EventFileError, match=r"cannot write suffix '\.csv'"):
        write_events(tmp_path / "a.csv", rec)
    with pytest.raises(ValueError, match="outside the sensor"):
        write_events(tmp_path / "a.npz", EventRecording(rec.events, (64, 64, 2)))


@pytest.mark.parametrize(
    ("name", "keep", "message"),
    [
        ("cut.npz", 500, r"cut\.npz: not a readable \.npz file"),
        ("cut.h5", 2000, r"cut\.h5: not a readable HDF5 file"),
    ],
)
def test_truncated_file_names_the_file(tmp_path, name, keep, message):
    path = tmp_path / name
    write_events(path, recording())
    path.write_bytes(path.read_bytes()[:keep])
    with pytest.raises(EventFileError, match=message):
        read_events(path)


def test_wrong_format_is_named(tmp_path):
    path = tmp_path / "text.aedat4"
    path.write_text("hello, not events\n")
    with pytest.raises(EventFileError, match=r"text\.aedat4: not an AEDAT 4\.0 file"):
        read_events(path)
    path = tmp_path / "text.aedat"
    path.write_text("hello\n")
    with pytest.raises(EventFileError, match="not a jAER AEDAT file"):
        read_events(path)
    with pytest.raises(EventFileError, match=r"unknown suffix '\.bin'"):
        read_events(tmp_path / "x.bin")


def test_unsorted_timestamps_are_an_error(tmp_path):
    ev = np.zeros(3, dtype=[("t", "<i8"), ("x", "<i2"), ("y", "<i2"), ("p", "i1")])
    ev["t"] = [0, 10, 5]
    path = tmp_path / "unsorted.npy"
    np.save(path, ev)
    with pytest.raises(EventFileError, match=r"unsorted\.npy: .*not sorted: t\[1\]=10 > t\[2\]=5"):
        read_events(path, sensor_size=(4, 4, 2))


def test_aedat2_truncated_mid_event(tmp_path):
    header = b"#!AER-DAT2.0\r\n# a comment\r\n"
    body = np.array([[2, 100], [4, 200]], dtype=">i4").tobytes()
    path = tmp_path / "cut.aedat"
    path.write_bytes(header + body[:13])
    with pytest.raises(EventFileError, match="13 bytes of events is not a whole number"):
        read_events(path)
    path.write_bytes(header + body)
    rec = read_events(path)
    # address 2: x = 1 -> mirrored 126, y = 0 -> 127, polarity 0; address 4: x = 2 -> 125.
    assert rec.events["x"].tolist() == [126, 125]
    assert rec.events["y"].tolist() == [127, 127]
    assert rec.events["t"].tolist() == [100, 200]


@needs_realdata
def test_real_aedat2_dvs128_matches_the_reference_array():
    rec = read_events(REALDATA / "dvs128_people" / "alex_walking_for_10secs.aedat")
    ref = np.load(REALDATA / "dvs128_people" / "alex_walking_for_10secs_txyp.npy")
    assert rec.sensor_size == (128, 128, 2)
    assert len(rec.events) == 125_028
    for f in "xytp":
        assert np.array_equal(rec.events[f], ref[f])


@needs_realdata
def test_real_aedat4_dvxplorer_matches_the_reference_array():
    rec = read_events(REALDATA / "dvxplorer_person" / "dvxplorer_sample.aedat4")
    ref = np.load(REALDATA / "dvxplorer_person" / "events_txyp.npy")
    assert rec.sensor_size == (320, 240, 2)
    assert len(rec.events) == 111_954
    assert rec.metadata["other_stream_packets"]["imus"] > 0  # reported, not dropped
    for f in "xytp":
        assert np.array_equal(rec.events[f], ref[f])


@needs_realdata
def test_real_aedat4_truncated_is_an_error(tmp_path):
    data = (REALDATA / "dvxplorer_person" / "dvxplorer_sample.aedat4").read_bytes()
    path = tmp_path / "cut.aedat4"
    path.write_bytes(data[: len(data) // 2])
    with pytest.raises(EventFileError, match=r"cut\.aedat4: AEDAT 4\.0 decoding failed"):
        read_events(path)


@needs_realdata
def test_real_npy_with_inferred_sensor_size():
    rec = read_events(REALDATA / "eed_ball_net" / "events_txyp.npy")
    assert len(rec.events) == 271_264
    assert rec.metadata["sensor_size_inferred"] is True
    assert rec.sensor_size[0] <= 190 and rec.sensor_size[1] <= 180
    rec = read_events(REALDATA / "eed_ball_net" / "events_txyp.npy", sensor_size=(190, 180, 2))
    assert rec.sensor_size == (190, 180, 2)
