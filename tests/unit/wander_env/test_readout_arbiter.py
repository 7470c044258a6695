"""The readout's FIFO arbiter (IEBCS bottleneck model with a bounded queue) and its 1 µs
timestamps, against hand-computed departures."""

import numpy as np
import pytest

from wander_env.events import make_events
from wander_env.readout import ReadoutParams, SpeckReadout, arbiter_departures


def _burst(t: list[int]) -> np.ndarray:
    n = len(t)
    return make_events(list(range(n)), [0] * n, t, [1] * n)


def test_a_burst_beyond_the_queue_drops_exactly_the_overflow():
    # 1 Meps: one event per µs. Depth 4. Ten events at t = 0: events 0-3 enter (read at
    # 1, 2, 3, 4 µs), events 4-9 find four inside and are dropped. Then three at t = 2 µs:
    # by then two have left (at 1 and 2 µs, a departure at the arrival instant counts as
    # gone), two are inside: the first two enter (read at 5 and 6 µs), the third finds 4.
    ro = SpeckReadout(16, 1, ReadoutParams(throughput_eps=1e6, queue_depth=4))
    ro.reset(0)
    out = ro.step(_burst([0] * 10 + [2] * 3), t_us=100)
    assert out["t"].tolist() == [1, 2, 3, 4, 5, 6]
    assert out["x"].tolist() == [0, 1, 2, 3, 10, 11]  # first in, first out
    assert ro.counts["dropped_queue"] == 7
    assert ro.counts["in"] == 13 and ro.counts["out"] == 6 and ro.counts["pending"] == 0


def test_departures_follow_the_service_time():
    # 250 keps: 4 µs per event; unbounded queue. Arrivals 0, 1, 10, 30 µs:
    # 0 -> 4, 1 -> max(1, 4) + 4 = 8, 10 -> 14, 30 -> 34 (µs; returned in ns).
    dep = arbiter_departures(np.array([0, 1, 10, 30]), 4000, None)
    assert dep.tolist() == [4000, 8000, 14000, 34000]


def test_events_still_in_the_arbiter_wait_for_a_later_step():
    ro = SpeckReadout(16, 1, ReadoutParams(throughput_eps=1e6))
    ro.reset(0)
    out = ro.step(_burst([8, 8, 8, 8]), t_us=10)  # read at 9, 10, 11, 12 µs
    assert out["t"].tolist() == [9, 10]
    assert ro.counts["pending"] == 2
    out = ro.step(_burst([]), t_us=20)
    assert out["t"].tolist() == [11, 12] and ro.pending == 0
    assert ro.totals["in"] == 4 and ro.totals["out"] == 4


def test_a_new_arrival_queues_behind_the_backlog_of_the_last_step():
    # Depth 2: at t = 10 the two from t = 9 are inside (read at 10 and 11 µs, the one at 10
    # leaves as the new one arrives): one inside, the arrival enters and is read at 12 µs.
    ro = SpeckReadout(16, 1, ReadoutParams(throughput_eps=1e6, queue_depth=2))
    ro.reset(0)
    assert ro.step(_burst([9, 9]), t_us=9)["t"].tolist() == []
    out = ro.step(_burst([10, 10]), t_us=20)
    assert out["t"].tolist() == [10, 11, 12]
    assert ro.counts["dropped_queue"] == 1


def test_timestamps_are_whole_microseconds_of_the_departure():
    # 3 Meps: 333 ns per event (1e9 / 3e6 rounded to 1 ns). Arrivals at 5 µs leave at
    # 5.333, 5.666, 5.999 and 6.332 µs: stamped 5, 5, 5, 6 (the µs counter's value).
    ro = SpeckReadout(16, 1, ReadoutParams(throughput_eps=3e6))
    assert ro.params.service_ns == 333
    ro.reset(0)
    out = ro.step(_burst([5, 5, 5, 5]), t_us=10)
    assert out["t"].dtype == np.int64
    assert out["t"].tolist() == [5, 5, 5, 6]


def test_the_emulators_microsecond_stamps_pass_unchanged_without_an_arbiter():
    ev = _burst([1, 7, 7, 9])
    ro = SpeckReadout(16, 1, ReadoutParams())
    ro.reset(0)
    out = ro.step(ev, t_us=10)
    assert out.tobytes() == ev.tobytes()


def test_a_queue_needs_an_arbiter():
    with pytest.raises(ValueError, match="queue_depth: a queue needs an arbiter"):
        ReadoutParams(queue_depth=8)
