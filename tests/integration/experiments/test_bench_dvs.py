"""The DVS benchmark's input paths and peer comparison (speed is not asserted)."""

from __future__ import annotations

import importlib.util
import math
import re

import numpy as np
import pytest

from experiments.jobs.synthetic import drifting_texture
from experiments.perf import dvs as dvs_bench
from experiments.perf.dvs import (
    PEERS,
    SENSORS,
    bench_dvs,
    bench_inputs,
    bench_peers,
    calibration_fps,
    linear_frames,
)
from wander_env.dvs import DVSEmulator, DVSParams

LOAD = r"^\d+\.\d\d-\d+\.\d\d$"  # the load average column: start-end


def test_linear_frames_give_the_events_of_their_srgb_frames():
    srgb = drifting_texture(32, 24, 8, 0.5, seed=0)
    lin = linear_frames(srgb)
    assert lin.shape == (8, 24, 32) and lin.dtype == np.float32
    a, b = DVSEmulator(32, 24), DVSEmulator(32, 24)
    a.reset(srgb[0], 0)
    b.reset(lin[0], 0)
    for i in range(1, 8):
        assert np.array_equal(a.step(srgb[i], i * 1000), b.step(lin[i], i * 1000))


def test_input_rows_share_the_events_and_the_linear_row_is_the_unit():
    rows = bench_inputs(n_frames=6, repeats=1)
    assert [(r.sensor, r.input) for r in rows] == [
        (s, k)
        for s in ("128x128", "346x260")
        for k in ("uint8 sRGB", "uint8 grey", "float32 linear")
    ]
    for i in (0, 3):
        srgb, grey, lin = rows[i : i + 3]
        assert srgb.events == lin.events > 0  # the same luminance, bit for bit
        assert lin.time_ratio == 1.0
        assert srgb.frames_per_s > 0 and grey.frames_per_s > 0
    # Beside each wall-time rate, the rate by the process's CPU time; the load average.
    assert all(r.cpu_frames_per_s > 0 and re.match(LOAD, r.load) for r in rows)


def test_dvs_rows_report_cpu_and_load():
    rows = bench_dvs(n_frames=4, repeats=1)
    assert len(rows) == 8 and all(r.frames_per_s > 0 and r.cpu_frames_per_s > 0 for r in rows)
    assert all(re.match(LOAD, r.load) for r in rows)


def test_the_calibration_times_the_workload_of_the_128_moving_ideal_row(monkeypatch):
    """``calibration_fps``: a compile call of 3 frames, then ``repeats`` timed runs of the
    128×128 moving pattern (``n_frames`` steps) with ideal pixels, as ``bench_dvs``'s row."""
    runs = []
    real = dvs_bench._run

    def spy(emu, frames, clock=None):
        runs.append((emu.width, emu.height, emu.params, frames.copy()))
        return real(emu, frames, clock)

    monkeypatch.setattr(dvs_bench, "_run", spy)
    fps = calibration_fps(n_frames=6, repeats=2)
    assert math.isfinite(fps) and fps > 0
    assert [len(frames) for *_, frames in runs] == [3, 7, 7]
    assert all((w, h, p) == (128, 128, DVSParams()) for w, h, p, _ in runs)
    moving = drifting_texture(128, 128, 7, SENSORS[(128, 128)], seed=0)
    assert np.array_equal(runs[1][3], moving) and np.array_equal(runs[0][3], moving[:3])


def test_peer_rows_wander_first_and_missing_peers_say_so():
    rows = bench_peers(n_frames=6, repeats=1)
    assert [r.emulator for r in rows] == list(PEERS) * 2
    for r in rows:
        if r.emulator == "wander":
            assert r.wander_speedup == 1.0 and r.events_diff_pct == 0.0 and r.events > 0
            assert r.cpu_frames_per_s > 0 and re.match(LOAD, r.load)
        elif r.frames_per_s is None:
            assert r.note.startswith("not installed")
            assert r.events is None and r.wander_speedup is None
        else:
            assert r.events > 0 and r.wander_speedup > 0


@pytest.mark.skipif(importlib.util.find_spec("evlib") is None, reason="evlib not installed")
def test_esim_on_the_same_frames_counts_the_same_events_within_a_tenth_of_a_percent():
    # Same log model above the knee and the same threshold: only float rounding and the
    # treatment of the darkest pixels differ (measured: -0.01 %).
    rows = [r for r in bench_peers(n_frames=20, repeats=1) if r.emulator == "evlib ESIM"]
    assert len(rows) == 2
    for r in rows:
        assert abs(r.events_diff_pct) < 0.1
