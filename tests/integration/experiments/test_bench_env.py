"""``wander perf env`` and the benches' clock: what the tables count (never how fast)."""

from __future__ import annotations

import math
import re
import time

import pytest

from experiments.perf.clock import Clock, Timings, timed
from experiments.perf.env import (
    ENV_COLUMNS,
    ENV_TIME_COLUMNS,
    EnvBenchConfig,
    bench_env,
    step_breakdown,
)
from wander_env.env_config import WanderConfig

LOAD = re.compile(r"^\d+\.\d\d-\d+\.\d\d$")


def test_a_clock_sums_its_spans_and_keeps_the_load_around_them() -> None:
    clock = Clock()
    assert clock.load == "–" and clock.ms_per(1) == (0.0, 0.0)
    for _ in range(3):
        with clock.span():
            sum(range(10_000))
    clock.add(0.5, 0.25)
    assert clock.spans == 4 and LOAD.match(clock.load)
    assert clock.wall_s >= 0.5 and 0.25 <= clock.cpu_s
    wall, cpu = clock.ms_per(4)
    assert wall == pytest.approx(250 * clock.wall_s) and cpu == pytest.approx(250 * clock.cpu_s)


def test_timed_keeps_each_calls_wall_and_cpu_time() -> None:
    acc = Timings()
    f = timed(lambda x: 2 * x, acc, "f")
    assert [f(k) for k in range(3)] == [0, 2, 4]
    assert len(acc.wall["f"]) == len(acc.cpu["f"]) == 3
    assert all(w >= 0 and c >= 0 for w, c in zip(acc.wall["f"], acc.cpu["f"], strict=True))

    def boom() -> None:
        raise ValueError("x")

    g = timed(boom, acc, "g")
    with pytest.raises(ValueError, match=r"^x$"):
        g()
    assert len(acc.wall["g"]) == 1  # a call that raised is timed too
    acc.clear()
    assert acc.wall == acc.cpu == {}
    # A CPU-bound call: its CPU time is most of its wall time, a sleep's is none of it.
    s = timed(time.sleep, acc, "sleep")
    s(0.02)
    assert acc.cpu["sleep"][0] < 0.5 * acc.wall["sleep"][0]


@pytest.mark.slow
def test_bench_env_steps_the_default_alone_as_well_as_in_turns() -> None:
    """One row (office, ideal, one env, 3 steps): the adaptive (default) env stepped
    alone after the turns makes the same events as in turns (same seed and steps), the
    exact env is stepped alone too (the speedup of the two alone); every
    wall-time column has its CPU column, and the row its load average."""
    config = EnvBenchConfig(env=WanderConfig(scene="office"), seconds=0.03)
    (row,) = bench_env(config, presets=("ideal",), env_counts=(1,))
    assert row.envs == 1 and row.adaptive_alone_events_diff_pct == 0.0
    for mode in ("exact", "keyframes", "adaptive", "adaptive_alone"):
        assert getattr(row, f"{mode}_ms_per_step") > 0
        assert math.isfinite(getattr(row, f"{mode}_cpu_ms_per_step"))
        assert {f"{mode}_cpu_ms_per_step", f"{mode}_ms_per_step"} <= ENV_TIME_COLUMNS.keys()
    assert row.adaptive_alone_rtf == pytest.approx(10.0 / row.adaptive_alone_ms_per_step)
    # the exact env alone too, and the speedup of the two alone
    assert row.exact_alone_rtf == pytest.approx(10.0 / row.exact_alone_ms_per_step)
    assert row.alone_speedup == pytest.approx(
        row.exact_alone_ms_per_step / row.adaptive_alone_ms_per_step
    )
    assert {"exact_alone_rtf", "alone_speedup"} <= ENV_COLUMNS.keys()
    assert LOAD.match(row.load) and ENV_COLUMNS["load"] == ""
    # the machine's speed just before the row (the DVS's frames/s on its calibration pattern)
    assert math.isfinite(row.dvs_fps) and row.dvs_fps > 0 and "dvs_fps" in ENV_COLUMNS


def test_step_breakdown_reports_cpu_and_load() -> None:
    part = step_breakdown(WanderConfig(scene="shelf", keyframe_px=2.0), seconds=0.02)
    assert part.frames == "adaptive" and part.ms_per_step > 0
    assert part.cpu_ms_per_step >= 0 and LOAD.match(part.load)
