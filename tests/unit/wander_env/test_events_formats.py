"""Event formats of the field (wander_env.events.formats) and the HDF5 index
(wander_env.events.hdf5_index).

Every writer's output is read back by a second, independent reader: AEDAT4 written by
faery is decoded by the ``aedat`` package, EVT3 written by faery by the ``evt3`` package
(and, for the readers, files built here byte by byte from the formats' specifications
are decoded by faery/evt3 through ``read_events``).
"""

from __future__ import annotations

import itertools
import struct

import h5py
import numpy as np
import pytest
from locations import REALDATA

from wander_env.events import EVENT_DTYPE, make_events, time_window
from wander_env.events.formats import es_expected_bytes, read_es
from wander_env.events.hdf5_index import MsToIdx, index_offset_us, ms_to_idx, read_h5_window
from wander_env.events.io import EventFileError, EventRecording, read_events, write_events

needs_realdata = pytest.mark.skipif(not REALDATA.is_dir(), reason="../shared/realdata absent")


def random_events(n: int, w: int, h: int, t_max: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    ev = np.empty(n, dtype=EVENT_DTYPE)
    ev["t"] = np.sort(rng.integers(0, t_max, n))
    ev["x"] = rng.integers(0, w, n)
    ev["y"] = rng.integers(0, h, n)
    ev["p"] = rng.integers(0, 2, n)
    return ev


def same_events(a: np.ndarray, b: np.ndarray) -> None:
    assert len(a) == len(b)
    for f in ("t", "x", "y", "p"):
        np.testing.assert_array_equal(np.asarray(a[f], np.int64), np.asarray(b[f], np.int64))


# ----------------------------------------------------------------------------------------
# Writers, read back by a second library


def test_aedat4_written_by_wander_is_read_by_the_aedat_decoder_event_for_event(tmp_path):
    import aedat

    ev = random_events(150_000, 346, 260, 3_000_000)  # > 2 packets of 65536
    path = tmp_path / "out.aedat4"
    write_events(path, EventRecording(ev, (346, 260, 2), {"seed": 0}))
    dec = aedat.Decoder(str(path))
    assert dec.id_to_stream() == {0: {"type": "events", "width": 346, "height": 260}}
    got = np.concatenate([p["events"] for p in dec if "events" in p])
    assert len(got) == 150_000
    np.testing.assert_array_equal(got["t"].astype(np.int64), ev["t"])
    np.testing.assert_array_equal(got["x"], ev["x"])
    np.testing.assert_array_equal(got["y"], ev["y"])
    np.testing.assert_array_equal(got["on"], ev["p"] == 1)
    back = read_events(path)
    assert back.sensor_size == (346, 260, 2)
    same_events(back.events, ev)


def test_evt3_written_by_wander_is_read_by_the_evt3_decoder_event_for_event(tmp_path):
    import evt3

    # 40 s spans two wraps of EVT3's 24-bit clock (16.78 s); coordinates use all 11 bits.
    ev = random_events(50_000, 1280, 720, 40_000_000, seed=1)
    ev["x"][:2], ev["y"][:2] = (0, 1279), (719, 0)
    path = tmp_path / "out.raw"
    write_events(path, EventRecording(ev, (1280, 720, 2)))
    dec = evt3.decode_file(str(path))
    assert (dec.sensor_width, dec.sensor_height) == (1280, 720)
    np.testing.assert_array_equal(np.asarray(dec.t, np.int64), ev["t"])
    np.testing.assert_array_equal(np.asarray(dec.x), ev["x"])
    np.testing.assert_array_equal(np.asarray(dec.y), ev["y"])
    np.testing.assert_array_equal(np.asarray(dec.p), ev["p"])
    back = read_events(path)
    assert back.sensor_size == (1280, 720, 2)
    assert back.metadata["source_format"] == "evt3"
    same_events(back.events, ev)


def test_evt3_writer_output_also_decodes_with_faery(tmp_path):
    import faery

    ev = random_events(2000, 64, 48, 200_000, seed=2)
    path = tmp_path / "a.raw"
    write_events(path, EventRecording(ev, (64, 48, 2)))
    with faery.evt.Decoder(path, None, None) as dec:
        assert dec.version == "evt3" and dec.dimensions == (64, 48)
        got = np.concatenate([p["events"] for p in dec if "events" in p])
    same_events(np.rec.fromarrays([got["t"], got["x"], got["y"], got["on"]], names="t,x,y,p"), ev)


def test_writers_refuse_what_the_formats_cannot_hold(tmp_path):
    ev = make_events([0], [0], [-5], [1])
    with pytest.raises(EventFileError, match=r"neg\.raw: t\[0\]=-5 µs is negative"):
        write_events(tmp_path / "neg.raw", EventRecording(ev, (4, 4, 2)))
    big = make_events([0], [0], [5], [1])
    with pytest.raises(EventFileError, match=r"big\.raw: sensor 4096x4 does not fit"):
        write_events(tmp_path / "big.raw", EventRecording(big, (4096, 4, 2)))
    with pytest.raises(EventFileError, match=r"x\.dat: cannot write suffix '\.dat'; writable"):
        write_events(tmp_path / "x.dat", EventRecording(big, (4, 4, 2)))


# ----------------------------------------------------------------------------------------
# Readers, on files built byte by byte from the specifications


def evt3_bytes(words: list[int], header: bytes = b"% evt 3.0\n% geometry 32x16\n% end\n") -> bytes:
    return header + struct.pack(f"<{len(words)}H", *words)


EVT3_WORDS = [
    0x8000 | 0x001,  # TIME_HIGH = 1  -> t = 4096 + low
    0x6000 | 0x00A,  # TIME_LOW = 10  -> t = 4106
    0x0000 | 3,  # ADDR_Y y = 3
    0x2000 | 0x800 | 7,  # ADDR_X x = 7, ON
    0x6000 | 0x014,  # TIME_LOW = 20 -> t = 4116
    0x0000 | 9,  # y = 9
    0x3000 | 4,  # VECT_BASE_X x = 4, OFF
    0x4000 | 0b101,  # VECT_12: x = 4 and 6
]


def test_evt3_reader_on_spec_bytes(tmp_path):
    path = tmp_path / "spec.raw"
    path.write_bytes(evt3_bytes(EVT3_WORDS))
    rec = read_events(path)
    assert rec.sensor_size == (32, 16, 2)
    assert rec.events.tolist() == [(7, 3, 4106, 1), (4, 9, 4116, 0), (6, 9, 4116, 0)]
    assert rec.metadata["event_words_before_first_time_high"] == 0
    # An event before the first TIME_HIGH has no time: skipped (as OpenEB does), and said.
    path.write_bytes(evt3_bytes([0x0000 | 1, 0x2000 | 2, *EVT3_WORDS]))
    rec = read_events(path)
    assert len(rec.events) == 3
    assert rec.metadata["event_words_before_first_time_high"] == 1


def test_evt2_reader_on_spec_bytes(tmp_path):
    def cd(on: int, t: int, x: int, y: int) -> int:
        return (on << 28) | ((t & 0x3F) << 22) | (x << 11) | y

    words = [0x8 << 28 | (1000 >> 6), cd(1, 1000, 5, 2), cd(0, 1010, 31, 15)]
    words += [0x8 << 28 | (70_000 >> 6), cd(1, 70_000, 0, 0)]
    path = tmp_path / "e2.raw"
    header = b"% evt 2.0\n% format EVT2;height=16;width=32\n% end\n"
    path.write_bytes(header + struct.pack("<5I", *words))
    rec = read_events(path)
    assert rec.sensor_size == (32, 16, 2)
    assert rec.metadata["source_format"] == "evt2"
    assert rec.events.tolist() == [(5, 2, 1000, 1), (31, 15, 1010, 0), (0, 0, 70_000, 1)]
    # No geometry in the header: the size is inferred from the events, and said.
    path.write_bytes(b"% evt 2.0\n" + struct.pack("<5I", *words))
    rec = read_events(path)
    assert rec.sensor_size == (32, 16, 2) and rec.metadata["sensor_size_inferred"] is True


def dat_bytes(events: list[tuple[int, int, int, int]]) -> bytes:
    body = b"".join(struct.pack("<II", t, x | (y << 14) | (p << 28)) for t, x, y, p in events)
    return b"% Version 2\n% Width 20\n% Height 10\n" + bytes([0x0C, 8]) + body


def test_dat_reader_on_spec_bytes(tmp_path):
    path = tmp_path / "a.dat"
    path.write_bytes(dat_bytes([(3, 1, 2, 1), (9, 19, 9, 0), (9, 0, 0, 1)]))
    rec = read_events(path)
    assert rec.sensor_size == (20, 10, 2)
    assert rec.events.tolist() == [(1, 2, 3, 1), (19, 9, 9, 0), (0, 0, 9, 1)]
    data = dat_bytes([(3, 1, 2, 1), (9, 19, 9, 0)]).replace(b"% Width 20\n% Height 10\n", b"")
    path.write_bytes(data)  # no geometry: inferred from the events, and said
    rec = read_events(path)
    assert rec.sensor_size == (20, 10, 2) and rec.metadata["sensor_size_inferred"] is True


def es_bytes(events: list[tuple[int, int, int, int]], w: int = 8, h: int = 6) -> bytes:
    """Event Stream 2.0 DVS: t, x, y (stored rows), p."""
    out = bytearray(b"Event Stream" + bytes([2, 0, 0, 1]) + struct.pack("<HH", w, h))
    t_prev = 0
    for t, x, y, p in events:
        dt = t - t_prev
        out += b"\xff" * (dt // 127)
        out += bytes([((dt % 127) << 1) | p]) + struct.pack("<HH", x, y)
        t_prev = t
    return bytes(out)


ES_EVENTS = [(5, 1, 0, 1), (400, 7, 5, 0), (400, 2, 3, 1), (1_000, 0, 1, 0)]


def test_es_reader_on_spec_bytes_flips_rows_to_top_left(tmp_path):
    path = tmp_path / "a.es"
    path.write_bytes(es_bytes(ES_EVENTS))
    assert path.stat().st_size == 20 + es_expected_bytes(np.array([t for t, *_ in ES_EVENTS]))
    rec = read_events(path)
    assert rec.sensor_size == (8, 6, 2)
    # Event Stream's origin is the bottom-left: row y is row 5 - y from the top.
    assert rec.events.tolist() == [(1, 5, 5, 1), (7, 0, 400, 0), (2, 2, 400, 1), (0, 4, 1000, 0)]
    kept = read_es(path, flip_y=False).events
    assert kept["y"].tolist() == [0, 5, 3, 1]
    # Trailing overflow bytes are legal, not truncation.
    path.write_bytes(es_bytes(ES_EVENTS) + b"\xff\xff")
    assert len(read_events(path).events) == 4


# ----------------------------------------------------------------------------------------
# Bad input: every reader names the file and the problem


@pytest.mark.parametrize(
    ("name", "content", "problem"),
    [
        ("odd.raw", evt3_bytes(EVT3_WORDS)[:-1], "not a whole number of 2-byte words"),
        ("nohdr.raw", bytes(range(200)), "no Prophesee header declaring the encoding"),
        ("outside.raw", evt3_bytes([0x8000, 0x0000 | 3, 0x2000 | 40]), r"x\[0\]=40 is outside"),
        ("cut.es", es_bytes(ES_EVENTS)[:-2], "truncated or damaged: 3 events need"),
        ("hdr.es", es_bytes(ES_EVENTS)[:14], "truncated: 14 bytes, the header alone is 20"),
        ("atis.es", b"Event Stream" + bytes([2, 0, 0, 2, 8, 0, 6, 0]), "type 'atis'"),
        ("v1.es", b"Event Stream" + bytes([1, 0, 0, 1, 8, 0, 6, 0]), r"version \(1, 0, 0\)"),
        ("cut.dat", dat_bytes([(3, 1, 2, 1), (9, 19, 9, 0)])[:-3], "not a whole number of 8"),
        ("type.dat", dat_bytes([])[:-2] + bytes([0x00, 8]), "only CD events"),
        ("nohdr.dat", b"\x00" * 16, "no Prophesee DAT header"),
        ("y.dat", dat_bytes([(3, 1, 12, 1)]), r"DAT decoding failed.*y=12 must be strictly"),
    ],
)
def test_readers_reject_damaged_files(tmp_path, name, content, problem):
    path = tmp_path / name
    path.write_bytes(content)
    with pytest.raises(EventFileError, match=problem) as err:
        read_events(path)
    assert err.value.path == str(path)


# ----------------------------------------------------------------------------------------
# HDF5: DSEC's ms_to_idx


def test_ms_to_idx_is_dsecs_index():
    t = np.array([0, 10, 999, 1000, 1001, 3500, 3999])
    idx = ms_to_idx(t)
    assert idx.tolist() == [0, 3, 5, 5]
    for ms, i in enumerate(idx):  # DSEC's definition, entry by entry
        assert (i == 0 or t[i - 1] < 1000 * ms) and (i == len(t) or t[i] >= 1000 * ms)
    assert index_offset_us(t) == 0
    assert ms_to_idx(np.array([5_000_250, 5_002_000]), 5_000_000).tolist() == [0, 1, 1]


def test_ms_to_idx_built_batch_by_batch_is_the_index_of_all_the_events():
    t = np.sort(np.random.default_rng(5).integers(0, 40_000, 3000))
    t[100:400] = t[99]  # a long run of equal timestamps split across batches
    cuts = [0, 0, 1, 99, 250, 250, 1700, 2999, 3000]
    for offset in (0, 7_000):
        index = MsToIdx()
        for a, b in itertools.pairwise(cuts):
            index.add(t[a:b] + offset)
        assert index.offset_us == index_offset_us(t + offset) == 0
        assert np.concatenate(index.parts).tolist() == ms_to_idx(t + offset).tolist()
    assert ms_to_idx(t, 0, first_ms=12).tolist() == ms_to_idx(t)[12:].tolist()
    late = MsToIdx()
    late.add(np.array([90_000_500, 90_002_100]))
    assert late.offset_us == 90_000_000 and np.concatenate(late.parts).tolist() == [0, 1, 1]


def test_h5_writer_adds_ms_to_idx_and_the_reader_seeks_windows_with_it(tmp_path):
    ev = random_events(20_000, 64, 64, 250_000, seed=3)
    path = tmp_path / "ev.h5"
    write_events(path, EventRecording(ev, (64, 64, 2)))
    with h5py.File(path, "r") as f:
        assert f["t_offset"][()] == 0
        np.testing.assert_array_equal(f["ms_to_idx"][()], ms_to_idx(ev["t"]))
        assert f["ms_to_idx"].shape == (int(ev["t"][-1]) // 1000 + 1,)
    for a, b in [(0, 1), (1234, 56_789), (99_000, 100_000), (249_000, 400_000), (-50, 10), (7, 7)]:
        same_events(read_h5_window(path, a, b), time_window(ev, a, b))
    same_events(read_events(path).events, ev)  # the index does not disturb the reader


def test_ms_to_idx_of_an_absolute_clock_counts_from_t_offset(tmp_path):
    t0 = 1_605_537_493_718_345  # the DVXplorer sample's UNIX µs
    ev = random_events(500, 8, 8, 30_000, seed=4)
    ev["t"] += t0
    path = tmp_path / "abs.h5"
    write_events(path, EventRecording(ev, (8, 8, 2)))
    with h5py.File(path, "r") as f:
        assert f["t_offset"][()] == t0 // 1000 * 1000
        assert f["ms_to_idx"].shape[0] == (int(ev["t"][-1]) - t0 // 1000 * 1000) // 1000 + 1
    a, b = t0 + 5000, t0 + 12_345
    same_events(read_h5_window(path, a, b), time_window(ev, a, b))


def test_read_h5_window_rejects_a_damaged_or_missing_index(tmp_path):
    ev = random_events(1000, 8, 8, 20_000, seed=5)
    path = tmp_path / "ev.h5"
    write_events(path, EventRecording(ev, (8, 8, 2)))
    with h5py.File(path, "a") as f:
        idx = f["ms_to_idx"][()]
        idx[10] += 3
        f["ms_to_idx"][...] = idx
    with pytest.raises(EventFileError, match=r"ev\.h5: ms_to_idx\[10\]=\d+ disagrees"):
        read_h5_window(path, 10_000, 12_000)
    with h5py.File(path, "a") as f:
        del f["ms_to_idx"]
        f["ms_to_idx"] = idx[:5]
    with pytest.raises(EventFileError, match="ms_to_idx has 5 entries; events up to"):
        read_h5_window(path, 0, 1000)
    with h5py.File(path, "a") as f:
        del f["ms_to_idx"]
    with pytest.raises(EventFileError, match="no 'ms_to_idx' index"):
        read_h5_window(path, 0, 1000)


# ----------------------------------------------------------------------------------------
# Real recordings


@needs_realdata
def test_real_dvxplorer_recording_survives_aedat4_and_evt3_round_trips(tmp_path):
    real = read_events(REALDATA / "dvxplorer_person" / "dvxplorer_sample.aedat4")
    assert len(real.events) == 111_954
    for suffix in (".aedat4", ".raw"):
        path = tmp_path / f"copy{suffix}"
        write_events(path, real)
        back = read_events(path)
        assert back.sensor_size == (320, 240, 2)
        same_events(back.events, real.events)


@needs_realdata
def test_real_eed_events_survive_an_evt3_round_trip(tmp_path):
    # The EED sequence came from an Event Stream file (its README); its events as .npy.
    real = read_events(REALDATA / "eed_ball_net" / "events_txyp.npy", sensor_size=(190, 180, 2))
    assert len(real.events) == 271_264
    path = tmp_path / "eed.raw"
    write_events(path, real)
    same_events(read_events(path).events, real.events)
