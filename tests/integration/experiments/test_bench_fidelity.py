"""``wander perf fidelity``: the measures, the pooling of seeds, the bar, determinism
and the command (tiny runs; the table itself is measured by the command, not here)."""

from __future__ import annotations

import numpy as np
import pytest
from typer.testing import CliRunner

from experiments.cli.main import app
from experiments.perf.fidelity import (
    MODES,
    ModeStats,
    Run,
    bar_cells,
    bar_check,
    matched_share,
    max_gap_ms,
    mode_kwargs,
    moving_windows,
    row_of,
    run_row,
)
from wander_env.events import EVENT_DTYPE


def ev(*rows: tuple[int, int, int, int]) -> np.ndarray:
    return np.array(list(rows), EVENT_DTYPE)


def test_matched_share_same_pixel_and_polarity_within_tolerance() -> None:
    a = ev((5, 5, 1000, 1), (5, 5, 3000, 1), (6, 5, 1000, 1), (5, 5, 1000, 0))
    b = ev((5, 5, 2000, 1), (5, 6, 1000, 1))
    # (5, 5, ON) at 1000 and 3000 are both 1000 µs from 2000: matched; another pixel or
    # polarity is not.
    assert matched_share(a, b, 1000, 128, 128) == 0.5
    assert matched_share(a, b, 999, 128, 128) == 0.0
    assert matched_share(b, a, 1000, 128, 128) == 0.5
    assert np.isnan(matched_share(b[:0], a, 1000, 128, 128))
    assert matched_share(a, b[:0], 1000, 128, 128) == 0.0


def test_gaps_in_moving_windows() -> None:
    assert moving_windows([True, True, False, False, True], 10_000) == [
        (0, 20_000),
        (40_000, 50_000),
    ]
    e = ev((0, 0, 2_000, 1), (0, 0, 19_000, 1), (0, 0, 45_000, 0))
    # 2 -> 19 ms is the longest gap in (0, 20] ms; (40, 50] ms has 5 ms on each side.
    assert max_gap_ms(e, [(0, 20_000), (40_000, 50_000)]) == 17.0
    assert max_gap_ms(e[:0], [(0, 20_000)]) == 20.0
    assert max_gap_ms(e, []) is None


def test_mode_kwargs_reference_and_modes() -> None:
    kw = mode_kwargs(0.01, 4000.0, 4)
    assert kw["reference"] == {"frames": "exact", "render_rate_hz": 4000.0, "supersample": 4}
    assert kw["exact"] == {"frames": "exact"} and kw["default"] == {}
    assert kw["aa16"] == {"frames": "exact", "supersample": 2}
    assert kw["one_key"] == {"frames": "keyframes", "keyframe_ms": 10.0, "keyframe_px": None}
    assert kw["panorama"] == {"frames": "panorama"}
    assert kw["fine"] == {"quality": "fine"}
    assert tuple(kw) == ("reference", *MODES)


def test_bar_limits_are_inclusive() -> None:
    exact = ModeStats(90, -10.0, 0.5, 40.0, 1.0, 10.0)
    at_limits = ModeStats(88, -12.0, 0.55, 37.0, 2.0, 5.0)
    assert bar_check(at_limits, exact).ok
    over = {
        "events": ModeStats(88, 12.1, 0.5, 40.0, 1.0, 5.0),
        "l1": ModeStats(90, -10.0, 0.5501, 40.0, 1.0, 5.0),
        "matched": ModeStats(90, -10.0, 0.5, 36.9, 1.0, 5.0),
        "gap": ModeStats(90, -10.0, 0.5, 40.0, 2.1, 5.0),
    }
    for failing, stats in over.items():
        check = bar_check(stats, exact)
        assert not check.ok and [k for k, v in vars(check).items() if not v] == [failing]
    assert bar_check(ModeStats(90, -10.0, 0.5, 40.0, None, 5.0), exact).gap


def _run(events: dict[str, np.ndarray], l1: dict[str, float], moving: list[bool]) -> Run:
    return Run(
        events={m: [e] for m, e in events.items()},
        l1=l1,
        renders={
            "reference": 80,
            "exact": 20,
            "aa16": 20,
            "default": 6,
            "fine": 6,
            "one_key": 2,
            "panorama": 2,
        },
        moving=moving,
        steps=2,
        period_us=10_000,
    )


def test_row_pools_seeds_against_the_reference() -> None:
    ref = ev((1, 1, 1000, 1), (2, 2, 5000, 0), (3, 3, 9000, 1), (4, 4, 15_000, 1))
    close = ev((1, 1, 1500, 1), (2, 2, 5000, 0), (4, 4, 19_000, 1))  # 2 of 4 matched
    events = {
        "reference": ref,
        "exact": close,
        "aa16": ref,
        "default": close,
        "fine": ref,
        "one_key": ref,
        "panorama": ref,
    }
    l1 = {"exact": 3.0, "aa16": 0.0, "default": 2.0, "fine": 2.5, "one_key": 1.0, "panorama": 0.0}
    runs = [_run(events, l1, [True, False]), _run(events, l1, [True, False])]
    row = row_of("shelf", "saccade", runs)
    assert (row.seeds, row.steps, row.reference_events, row.reference_renders) == (2, 4, 8, 40.0)
    ex = row.modes["exact"]
    assert (ex.events, ex.events_dev_pct, ex.l1_per_event, ex.matched_pct) == (6, -25.0, 0.75, 50.0)
    # in the moving first step (0, 10] ms: events at 1.5 and 5 ms -> the gap 5 -> 10 ms
    assert ex.max_gap_ms == 5.0 and ex.renders_per_step == 10.0
    assert row.modes["aa16"] == ModeStats(8, 0.0, 0.0, 100.0, 4.0, 10.0)
    assert row.modes["default"].l1_per_event == 0.5
    assert row.default_vs_exact_pct == 100.0
    # default vs exact: the same events dev and matched, L1 0.5 <= 0.825, gap 5 ms > 2
    assert (row.bar.events, row.bar.l1, row.bar.matched, row.bar.gap) == (True, True, True, False)
    cells = bar_cells(row)
    assert cells.gap == "5.0 ≤ 2 ✗" and cells.verdict == "FAIL"
    assert cells.l1 == "0.500 ≤ 0.825"
    assert cells.fine_l1 == "0.625 ≤ 0.562 ✗"  # fine: 2.5 / 4 events against 0.75 x 0.75
    still = row_of("shelf", "still", runs)
    assert still.modes["exact"].max_gap_ms is None and still.bar.ok
    none = ev()
    quiet = _run(dict.fromkeys(events, none), dict.fromkeys(l1, 0.0), [False, False])
    row = row_of("shelf", "still", [quiet])
    assert row.reference_events == 0 and row.modes["default"].events_dev_pct == 0.0
    assert np.isnan(row.modes["default"].matched_pct) and row.bar.ok
    assert bar_cells(row).matched == "— ≥ —" and bar_cells(row).verdict == "pass"


@pytest.mark.slow
def test_same_seed_identical_events_in_every_mode() -> None:
    """Two runs of one seed (a saccade, lighter reference) give the same events and
    renders in every env."""
    a, b = (run_row("shelf", "saccade", 3, 0.02, 2000.0, 2) for _ in range(2))
    assert a.steps == 2 and a.moving == b.moving and a.renders == b.renders
    assert a.renders["reference"] >= 2 * a.renders["exact"] > 0
    for m in ("reference", *MODES):
        assert len(a.events[m]) == 2
        for x, y in zip(a.events[m], b.events[m], strict=True):
            np.testing.assert_array_equal(x, y)
    assert a.l1 == b.l1


def test_command_prints_both_tables_and_refuses_unknown_motions() -> None:
    res = CliRunner().invoke(
        app,
        [
            "perf",
            "fidelity",
            "--scenes",
            "shelf",
            "--motions",
            "still",
            "--seeds",
            "0",
            "--seconds",
            "0.01",
            "--reference-hz",
            "2000",
            "--reference-supersample",
            "1",
        ],
    )
    assert res.exit_code == 0, res.output
    out = " ".join(res.output.split())
    assert "Frame modes against the reference (4 samples a pixel at 2000 Hz ticks)" in out
    assert "The bar, default frames against exact" in out
    assert "1 rows in" in out and "load average" in out
    bad = CliRunner().invoke(app, ["perf", "fidelity", "--motions", "jump"], prog_name="wander")
    assert (bad.exit_code, bad.stderr.splitlines()) == (
        2,
        [
            "wander perf fidelity: Invalid value for '--motions': 'jump' is not allowed; "
            "allowed: still, walk, saccade"
        ],
    )


def test_command_refuses_zero_seconds() -> None:
    result = CliRunner().invoke(app, ["perf", "fidelity", "--seconds", "0"], prog_name="wander")
    assert result.exit_code == 2
    assert result.stderr == (
        "wander perf fidelity: Invalid value for '--seconds': must be a whole number of "
        "0.01 s control periods in [0.01, 60] seconds, got 0.0\n"
    )
