"""speed_ratio: the curve, the crossing ratios and the table from hand-made sweep rows."""

from __future__ import annotations

import math

import pytest
from typer.testing import CliRunner

from experiments.cli.main import app
from experiments.paper.speed_ratio import crossing, crossings, curve, table
from experiments.runs.tables import write_csv


def rows_of(hits: dict[float, list[float]], amp: float = 1.0) -> list[dict]:
    out = []
    for ratio, values in hits.items():
        for seed, v in enumerate(values):
            out.append(
                {
                    "seed": seed,
                    "phase": "both",
                    "cfg.hand_ratio": ratio,
                    "cfg.shake.amplitude_deg": amp,
                    "hand_hit_pct": v,
                    "suppressed_pct": 99.0,
                    "background_kept_pct": 1.0,
                    "object_kept_pct": v / 2,
                    "second:hand_hit_pct": v / 2,
                    "second:suppressed_pct": 98.0,
                    "second:background_kept_pct": 2.0,
                    "second:object_kept_pct": v / 4,
                }
            )
    return out


def test_crossing_interpolates_in_log_ratio_and_needs_the_curve_to_stay_up():
    assert crossing([0.5, 1, 2, 4], [0, 10, 50, 100], 50) == pytest.approx(2.0)
    assert crossing([1, 4], [0, 100], 50) == pytest.approx(2.0)  # halfway in log ratio
    # a dip back below the level: the crossing is the last one up
    assert crossing([1, 2, 4, 8], [60, 40, 80, 95], 50) == pytest.approx(2**1.25)
    assert crossing([1, 2, 4], [80, 90, 95], 50) == 1
    assert math.isnan(crossing([1, 2, 4], [10, 20, 30], 50))
    assert math.isnan(crossing([], [], 50))


def test_curve_and_crossings_from_rows():
    rows = rows_of({0.5: [0, 0, 10], 1.0: [10, 20, 30], 2.0: [60, 60, 60], 4.0: [100] * 3})
    pts = curve(rows, "", "hand_hit_pct", 1.0)
    assert [(p.ratio, p.mean, p.n) for p in pts] == [
        (0.5, pytest.approx(10 / 3), 3),
        (1.0, 20.0, 3),
        (2.0, 60.0, 3),
        (4.0, 100.0, 3),
    ]
    assert (pts[2].low, pts[2].high) == (60.0, 60.0)
    assert [p.mean for p in curve(rows, "second:", "hand_hit_pct", 1.0)] == pytest.approx(
        [5 / 3, 10.0, 30.0, 50.0]
    )
    assert curve(rows, "", "hand_hit_pct", 2.0) == []  # no rows at that amplitude
    mean, early, late = crossings(pts, 50.0)
    assert mean == pytest.approx(2 ** (30 / 40))  # 20 % at 1, 60 % at 2
    assert early <= mean <= late


def test_table_and_the_report_give_the_crossings(tmp_path):
    rows = rows_of({1.0: [0, 10], 2.0: [50, 70], 4.0: [90, 100]})
    rows += rows_of({1.0: [0, 0], 2.0: [0, 0], 4.0: [20, 40]}, amp=2.0)
    text = table(rows)
    assert "| sOMS | shake | measure | 1 | 2 | 4 |" in text
    assert "| agent's sOMS (quantile norm) | ±1° | hand hit | 5.0 [" in text
    # 50 %: means 5, 60, 95 at 1, 2, 4 -> 2 ** (45 / 55); 90 %: 2 ** (1 + 30 / 35)
    assert f"| agent's sOMS (quantile norm) | ±1° | {2 ** (45 / 55):.2f} (" in text
    assert f"| {2 ** (1 + 30 / 35):.2f} (" in text
    assert "| agent's sOMS (quantile norm) | ±2° | not reached | not reached |" in text
    sweep = tmp_path / "results" / "sweeps" / "speed_ratio"
    write_csv(rows, sweep / "results.csv")
    out = tmp_path / "REPORT.md"
    args = ["report", "--results", str(tmp_path / "results"), "--out", str(out)]
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 0, result.output
    report = out.read_text()
    assert "## The hand against the shake: sweep speed_ratio" in report
    assert text in report
    assert (tmp_path / "report_figures" / "sweep_speed_ratio_ratio.png").stat().st_size > 0
