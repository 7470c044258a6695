"""``wander perf agent`` and ``wander evaluate``: counts and pooling are exact."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import pytest
from typer.testing import CliRunner

from experiments.cli.main import app
from experiments.jobs.evaluate_agent import (
    QualityRow,
    detection_interval,
    pooled,
    read_quality,
)
from experiments.perf.agent import LOOP_COLUMNS, AgentBenchConfig, bench_agent, latency_row
from experiments.runs.tables import read_csv
from wander_env.config import validate
from wander_env.strict_json import to_strict_json


def test_latency_row_percentiles() -> None:
    row = latency_row("x", [0.001 * k for k in range(1, 101)])
    assert row.calls == 100 and row.median_ms == pytest.approx(50.5)
    assert row.p95_ms == pytest.approx(95.05) and row.max_ms == pytest.approx(100.0)
    assert math.isnan(latency_row("empty", []).median_ms)
    assert math.isnan(row.cpu_median_ms) and row.load == "–"
    cpu = latency_row("x", [0.002] * 3, [0.001, 0.003, 0.002], "1.00-2.00")
    assert cpu.cpu_median_ms == pytest.approx(2.0) and cpu.load == "1.00-2.00"


def test_bench_agent_times_every_stage_call() -> None:
    config = validate(AgentBenchConfig, {"env.scene": "shelf", "env.episode_seconds": 0.3})
    rows, loop = bench_agent(config)
    by = {r.stage: r for r in rows}
    assert by["sOMS (every step)"].calls == 30
    assert by["sAC nengo (every step)"].calls == 30
    assert by["agent act, all steps"].calls == 30 and by["env step"].calls == 30
    # One decision per 13-step window while fixating: the first ends at step 13 (a static
    # scene and a still camera: no events before it); the saccade it starts and the next
    # 13-step window outlast the 30 steps.
    decisions = by["agent act, decision steps"].calls
    assert by["proto-object, split (per decision)"].calls == decisions == 1
    assert by["proto-object, streamlined (same maps)"].calls == decisions
    assert loop.simulated_s == pytest.approx(0.3)
    assert loop.realtime_factor == pytest.approx(loop.simulated_s / loop.wall_s)
    # Beside each wall time, the process's CPU time and the load average around the run.
    assert loop.cpu_s > 0 and re.match(r"^\d+\.\d\d-\d+\.\d\d$", loop.load)
    # and the machine's speed just before (the DVS's frames/s on its calibration pattern)
    assert math.isfinite(loop.dvs_fps) and loop.dvs_fps > 0 and "dvs_fps" in LOOP_COLUMNS
    assert all(r.load == loop.load for r in rows)
    assert all(math.isfinite(r.cpu_median_ms) for r in rows if r.calls)


def test_pooled_quality() -> None:
    a = QualityRow(0, 10, 8, 6, 0.75, 0.9, 1.0, 2.0, 4, 2.0, 8.0)
    b = QualityRow(1, 5, 2, 2, 1.0, 0.8, 3.0, 4.0, 1, 2.0, 2.0)
    p = pooled([a, b], kept=[10, 30], seen=[100, 100])
    assert (p.seed, p.decisions, p.scored, p.hits, p.saccades) == ("all", 15, 10, 8, 5)
    assert (a.real_time_factor, p.simulated_s, p.wall_s, p.real_time_factor) == (0.25, 4, 10, 0.4)
    assert p.detection_accuracy == pytest.approx(0.8) and p.soms_suppression == pytest.approx(0.8)
    assert p.foveation_error_x_px == pytest.approx((4 * 1.0 + 3.0) / 5)
    # 95 % Wilson interval of 8 / 10: (0.490, 0.943); none without scored decisions.
    assert (p.detection_ci_low, p.detection_ci_high) == pytest.approx((0.4902, 0.9433), abs=1e-4)
    assert all(math.isnan(v) for v in detection_interval(0, 0))


def test_quality_json_reads_back_with_undefined_figures_as_nan(tmp_path: Path) -> None:
    """What ``wander evaluate`` writes (strict JSON: NaN as null) reads back through
    :func:`read_quality` with NaN where it wrote null: a seed whose sOMS saw no event."""
    from dataclasses import asdict

    from experiments.runs.folder import RunFolder

    a = QualityRow(0, 0, 0, 0, math.nan, math.nan, math.nan, math.nan, 0, 1.0, 2.0)
    p = pooled([a], kept=[0], seen=[0])
    assert math.isnan(p.soms_suppression)
    rec = {"rows": [asdict(a)], "pooled": asdict(p)}
    path = RunFolder(tmp_path).write_json("quality.json", rec)
    assert json.loads(path.read_text())["rows"][0]["soms_suppression"] is None
    q = read_quality(path, "quality")
    assert math.isnan(q["rows"][0]["soms_suppression"]) and q["rows"][0]["seed"] == 0
    assert math.isnan(q["pooled"]["detection_accuracy"]) and q["pooled"]["seed"] == "all"


@pytest.mark.slow
def test_evaluate_cli_two_seeds(tmp_path: Path) -> None:
    res = CliRunner().invoke(
        app,
        [
            "evaluate",
            "--out",
            str(tmp_path),
            "--scene",
            "shelf",
            "--seconds",
            "0.3",
            "--seeds",
            "0,1",
        ],
    )
    assert res.exit_code == 0, res.output
    q = json.loads((tmp_path / "quality.json").read_text())
    assert [r["seed"] for r in q["rows"]] == [0, 1] and q["pooled"]["seed"] == "all"
    assert q["pooled"]["decisions"] == sum(r["decisions"] for r in q["rows"])
    assert q["pooled"]["simulated_s"] == pytest.approx(0.6)
    # quality.csv: the same rows, one line each, the pooled one last
    table = read_csv(tmp_path / "quality.csv")
    assert [r["seed"] for r in table] == [0, 1, "all"]
    assert to_strict_json(table[:2]) == q["rows"]  # NaN there, null here
    assert table[2]["real_time_factor"] == q["pooled"]["real_time_factor"] > 0
    assert "real-time factor" in res.output and "quality.csv" in res.output
    assert (tmp_path / "seed-0" / "metrics.json").exists()
    bad = CliRunner().invoke(app, ["evaluate", "--seeds", "a,b"])
    assert bad.exit_code == 2
    assert "Invalid value for '--seeds': must be integers separated by commas" in bad.output
