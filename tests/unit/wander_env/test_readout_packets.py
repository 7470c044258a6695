"""Host packets (batch interval, latency) and the readout's accounting: every event is
delivered, counted as removed, or pending."""

import numpy as np

from wander_env.events import make_events
from wander_env.readout import (
    COUNTERS,
    DvsFilterParams,
    DvsLayerParams,
    ReadoutParams,
    SpeckReadout,
)


def test_packets_reach_the_host_when_they_close_plus_the_latency():
    # Packets of 1000 µs from t0 = 500; latency 300. Events at 500, 1499 (packet 0: closes
    # at 1500, delivered at 1800), 1500, 2400 (packet 1: 2500 -> 2800), 2600 (-> 3800).
    ro = SpeckReadout(8, 1, ReadoutParams(batch_interval_us=1000, latency_us=300))
    ro.reset(500)
    ev = make_events([0, 1, 2, 3, 4], [0] * 5, [500, 1499, 1500, 2400, 2600], [1] * 5)
    assert ro.step(ev[:2], t_us=1799).size == 0  # packet 0 not delivered yet
    assert ro.counts["pending"] == 2
    out = ro.step(ev[2:3], t_us=1800)
    assert out["t"].tolist() == [500, 1499]  # each event keeps its own timestamp
    out = ro.step(ev[3:], t_us=2799)
    assert out.size == 0
    out = ro.step(ev[:0], t_us=2800)
    assert out["t"].tolist() == [1500, 2400]
    out = ro.step(ev[:0], t_us=3800)
    assert out["t"].tolist() == [2600] and ro.pending == 0


def test_latency_alone_delays_each_event():
    ro = SpeckReadout(8, 1, ReadoutParams(latency_us=100))
    ro.reset(0)
    ev = make_events([0, 1], [0, 0], [10, 60], [1, 0])
    assert ro.step(ev, t_us=150)["t"].tolist() == [10]
    assert ro.step(ev[:0], t_us=160)["t"].tolist() == [60]


def test_counters_add_up_in_every_step_and_in_total():
    params = ReadoutParams(
        kill_pixels=tuple((x, 0) for x in range(32)),  # row 0
        throughput_eps=2e5,
        queue_depth=8,
        dvs_filter=DvsFilterParams(enable=True, filter_size=(3, 3), threshold=3),
        dvs_layer=DvsLayerParams(off_channel=False, origin=(0, 0), cut=(20, 20)),
        batch_interval_us=500,
        latency_us=250,
    )
    ro = SpeckReadout(32, 32, params)
    ro.reset(0)
    rng = np.random.default_rng(0)
    removed = [k for k in COUNTERS if k not in ("in", "out", "pending")]
    pending_before, delivered, held = 0, 0, 0
    for k in range(1, 21):
        n = int(rng.integers(0, 40))
        # Bursts of up to 40 events in the step's last 50 µs: at 5 µs each they overflow
        # the queue of 8 and leave after the step's end.
        t = np.sort(rng.integers(k * 1000 - 49, k * 1000 + 1, n))
        ev = make_events(rng.integers(0, 32, n), rng.integers(0, 32, n), t, rng.integers(0, 2, n))
        out = ro.step(ev, t_us=k * 1000)
        c = ro.counts
        assert c["in"] == n and c["out"] == len(out)
        assert c["in"] + pending_before == c["out"] + sum(c[r] for r in removed) + c["pending"]
        pending_before, delivered = c["pending"], delivered + len(out)
        held = max(held, c["pending"])
    tot = ro.totals
    assert tot["in"] == tot["out"] + sum(tot[r] for r in removed) + tot["pending"]
    assert tot["out"] == delivered and tot["pending"] == ro.pending
    # the seeded bursts' exact accounting (integer arithmetic throughout)
    assert tot == {
        "in": 446,
        "out": 16,
        "killed": 12,
        "dropped_queue": 151,
        "filtered_noise": 215,
        "filtered_hot": 0,
        "filtered_flicker": 0,
        "channel_off": 24,
        "outside_roi": 20,
        "pending": 8,
    }
    assert held == 10
