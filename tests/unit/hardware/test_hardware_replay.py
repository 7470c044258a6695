"""ReplaySource: every real file format replays each event exactly once; real time; looping."""

from __future__ import annotations

import numpy as np
import pytest
from fake_clock import FakeClock
from locations import REALDATA

from hardware.event_source import EventSource
from hardware.replay import ReplayParams, ReplaySource
from wander_env.events import concatenate, make_events
from wander_env.events.io import EventRecording, read_events, write_events

needs_realdata = pytest.mark.skipif(not REALDATA.is_dir(), reason="../shared/realdata absent")

REAL_FILES = [
    "dvs128_people/alex_walking_for_10secs.aedat",
    "dvxplorer_person/dvxplorer_sample.aedat4",
    "dvs128_people/alex_walking_for_10secs_txyp.npy",
]


def small_recording() -> EventRecording:
    rng = np.random.default_rng(3)
    n = 2000
    t = np.sort(rng.integers(0, 300_000, n)) + 5_000_000
    ev = make_events(rng.integers(0, 64, n), rng.integers(0, 48, n), t, rng.integers(0, 2, n))
    return EventRecording(ev, (64, 48, 2), {"origin": "synthetic"})


def drain(src: ReplaySource, rng: np.random.Generator, max_window_us: int) -> list[np.ndarray]:
    chunks = []
    while not src.finished:
        if rng.random() < 0.3:
            chunks.append(src.read(until_t_us=src.cursor_us + int(rng.integers(0, max_window_us))))
        else:
            chunks.append(src.read(duration_us=int(rng.integers(1, max_window_us))))
    return chunks


@needs_realdata
@pytest.mark.parametrize("name", REAL_FILES)
def test_real_files_replay_every_event_once(name):
    path = REALDATA / name
    rec = read_events(path)
    rng = np.random.default_rng(0)
    with ReplaySource(path) as src:
        assert src.sensor_size == rec.sensor_size
        chunks = drain(src, rng, max_window_us=40_000)
        assert src.read(duration_us=10_000).size == 0 and src.finished
    got = concatenate(chunks)  # raises if windows overlap or reorder
    t0 = int(rec.events["t"][0])
    assert src.metadata["t_offset_us"] == t0
    assert got["t"][0] == 0
    assert len(got) == len(rec.events)
    for f in ("x", "y", "p"):
        assert np.array_equal(got[f], rec.events[f])
    assert np.array_equal(got["t"], rec.events["t"] - t0)
    assert src.stats["delivered"] == len(rec.events)


def test_windows_are_half_open_and_recording_input_works(tmp_path):
    rec = small_recording()
    path = tmp_path / "small.h5"
    write_events(path, rec)
    for source in (rec, path):
        with ReplaySource(source) as src:
            assert isinstance(src, EventSource)
            first = src.read(duration_us=100_000)
            assert np.all(first["t"] < 100_000)
            rest = src.read()
            assert np.all(rest["t"] >= 100_000)
            assert len(first) + len(rest) == len(rec.events)
            assert src.finished and src.dropped == 0
            assert src.metadata["origin"] == "synthetic"
            assert src.metadata["t_offset_us"] == int(rec.events["t"][0])


def test_t0_skips_earlier_events():
    rec = small_recording()
    t0 = int(rec.events["t"][100])
    with ReplaySource(rec, t0_us=t0) as src:
        got = src.read()
    skipped = int(np.searchsorted(rec.events["t"], t0))
    assert src.metadata["skipped_before_t0"] == skipped
    assert np.array_equal(got["t"], rec.events["t"][skipped:] - t0)


def paced(rec: EventRecording, clock: FakeClock, **kw) -> ReplaySource:
    return ReplaySource(rec, realtime=True, clock=clock, sleep=clock.sleep, **kw)


def test_realtime_read_sleeps_until_the_window_has_passed():
    clock = FakeClock()
    with paced(small_recording(), clock) as src:
        src.read(duration_us=125_000)  # 0.125 s: exact in binary, as the sums below
        clock.t += 0.0625  # the caller works 62.5 ms
        src.read(duration_us=125_000)
        clock.t += 0.5  # then falls behind: the next read returns at once
        src.read(duration_us=125_000)
        assert src.stats["max_lateness_s"] == 0.5 - 0.125
    assert clock.sleeps == [0.125, 0.0625]
    clock = FakeClock()
    with paced(small_recording(), clock, speed=4.0) as src:
        src.read(duration_us=200_000)
    assert clock.sleeps == [0.05]


def test_realtime_without_window_returns_events_up_to_now():
    clock = FakeClock()
    rec = small_recording()
    with paced(rec, clock) as src:
        clock.t += 0.0625
        got = src.read()
        assert src.cursor_us == 62_500 and clock.sleeps == []  # the clock it saw
        t = rec.events["t"] - rec.events["t"][0]
        np.testing.assert_array_equal(got["t"], t[t < 62_500])


def test_fast_mode_does_not_sleep():
    clock = FakeClock()
    with ReplaySource(small_recording(), clock=clock, sleep=clock.sleep) as src:
        src.read(duration_us=10_000_000)
    assert clock.sleeps == []  # a paced read of 10 s would sleep 10 s


def test_loop_wraps_with_increasing_timestamps():
    rec = small_recording()
    rng = np.random.default_rng(1)
    with ReplaySource(rec, loop=True) as src:
        period = src.duration_us
        chunks = []
        while src.cursor_us < int(2.5 * period):
            chunks.append(src.read(duration_us=int(rng.integers(1, 70_000))))
        assert not src.finished
        assert src.stats["laps"] == 2
        with pytest.raises(ValueError, match="looping"):
            src.read()
    got = concatenate(chunks)
    assert np.all(np.diff(got["t"]) >= 0)
    base = rec.events["t"] - rec.events["t"][0]
    n = len(base)
    for lap in range(2):
        assert np.array_equal(got["t"][lap * n : (lap + 1) * n], base + lap * period)
        assert np.array_equal(got["x"][lap * n : (lap + 1) * n], rec.events["x"])
    tail = got["t"][2 * n :]
    assert np.array_equal(tail, base[: len(tail)] + 2 * period)
    assert len(tail) > 0 and tail[-1] < src.cursor_us


def test_state_errors_and_idempotent_close():
    src = ReplaySource(small_recording())
    with pytest.raises(RuntimeError, match="before start"):
        src.read(duration_us=1)
    src.start()
    with pytest.raises(ValueError, match="duration_us must be a non-negative integer"):
        src.read(duration_us=-1)
    src.read(until_t_us=1000)
    with pytest.raises(ValueError, match=r"until_t_us=999 is before the end of the last window"):
        src.read(until_t_us=999)
    src.close()
    src.close()
    with pytest.raises(RuntimeError, match="closed"):
        src.read(duration_us=1)
    with pytest.raises(RuntimeError, match="closed"):
        src.start()


def test_empty_recording_is_finished_at_once():
    rec = EventRecording(make_events([], [], [], []), (8, 8, 2))
    with ReplaySource(rec, loop=True) as src:
        assert src.read(duration_us=1000).size == 0
        assert src.finished


def test_params_are_validated():
    with pytest.raises(ValueError, match="speed must be a positive finite number"):
        ReplayParams(speed=0)
    with pytest.raises(ValueError, match="speed must be a positive finite number"):
        ReplaySource(small_recording(), speed=float("nan"))
