"""``wander record --format``: events in the field's formats, and the EVIMO2v2 layout that
``wander benchmark evimo`` scores with the real dataset's protocol."""

from __future__ import annotations

import csv
import json

import h5py
import numpy as np
import pytest
from typer.testing import CliRunner

from experiments.benchmark.datasets.evimo import find_evimo_sequences, load_evimo_sequence
from experiments.cli.benchmark import app as benchmark_app
from experiments.jobs.record import RecordConfig, record
from wander_env.camera import focal_length_px
from wander_env.env_config import WanderConfig
from wander_env.events.io import read_events

STEP_US = 10_000  # the env's control period: one mask per step


@pytest.mark.slow
def test_recorded_evimo2_sequence_is_scored_by_the_evimo_benchmark(tmp_path):
    rec_dir, out = tmp_path / "rec", tmp_path / "bench"
    cfg = RecordConfig(
        WanderConfig(scene="office", episode_seconds=0.1),
        policy="still",
        video=False,
        format="evimo2",
    )
    summary = record(rec_dir, cfg)
    assert {"dataset_events_t.npy", "dataset_mask.npz", "dataset_info.npz"} <= set(summary["files"])
    t_us = np.rint(np.load(rec_dir / "dataset_events_t.npy") * 1e6).astype(np.int64)
    assert len(t_us) == summary["events"] > 0
    with h5py.File(rec_dir / "ground_truth.h5") as f:
        truth_masks = f["object_mask"][()]
        truth_t = f["t"][()]
    steps = len(truth_t)
    assert steps == 10

    # The loader sees one EVIMO2v2 sequence: our events, one window per step.
    (src,) = find_evimo_sequences(rec_dir)
    assert (src.format, src.subset, src.name) == ("evimo2v2_npz", "evimo2", "rec")
    seq = load_evimo_sequence(src)
    assert seq.sensor_size == (128, 128, 2) and len(seq.events) == len(t_us)
    assert [(w.t_start_us, w.t_end_us) for w in seq.windows] == [
        (k * STEP_US, (k + 1) * STEP_US) for k in range(steps)
    ]
    for w, m in zip(seq.windows, truth_masks, strict=True):
        np.testing.assert_array_equal(w.labels, m)  # object ids survive id × 1000
    with np.load(rec_dir / "dataset_info.npz", allow_pickle=True) as info:
        assert info["K"][0, 0] == pytest.approx(focal_length_px(128))
        assert info["meta"].item()["meta"]["res_x"] == 128

    result = CliRunner().invoke(
        benchmark_app, ["evimo", str(rec_dir), "--out", str(out), "--no-progress"]
    )
    assert result.exit_code == 0, result.output
    rows = list(csv.DictReader((out / "results.csv").open()))
    assert len(rows) == steps
    # Counts the benchmark must find, computed here from the recording itself.
    pixels = truth_masks.reshape(steps, -1).astype(bool).sum(axis=1)
    t_first, t_last = int(t_us[0]), int(t_us[-1])
    outside = [(k + 1) * STEP_US <= t_first or k * STEP_US > t_last for k in range(steps)]
    n_empty = sum(1 for k in range(steps) if pixels[k] == 0 and not outside[k])
    n_scored = sum(1 for k in range(steps) if pixels[k] > 0 and not outside[k])
    assert n_scored == steps - n_empty - sum(outside) > 0
    for k, row in enumerate(rows):
        assert (int(row["t_start_us"]), int(row["t_end_us"])) == (k * STEP_US, (k + 1) * STEP_US)
        in_window = np.count_nonzero((t_us >= k * STEP_US) & (t_us < (k + 1) * STEP_US))
        assert int(row["n_events"]) == in_window
        assert int(row["mask_pixels"]) == pixels[k]
    scored = [r for r in rows if r["hit"] != ""]
    assert len(scored) == n_scored
    for r in scored:
        assert 0.0 <= float(r["iou"]) <= 1.0 and 0.0 <= float(r["ssim"]) <= 1.0
        assert r["hit"] in ("0.0", "1.0")
        assert r["precision"] == "" or 0.0 <= float(r["precision"]) <= 1.0
    accuracy = sum(float(r["hit"]) for r in scored) / n_scored
    md = (out / "results.md").read_text()
    assert f"| evimo2 | 1 | {steps} | {n_scored} | {n_empty} | {sum(outside)} |" in md
    assert f"| {100 * accuracy:.1f} ± 0.00 |" in md
    run = json.loads((out / "run.json").read_text())
    assert run["config"]["model_dt_s"] == {"evimo2/rec": 0.01}


@pytest.mark.parametrize(("fmt", "name"), [("aedat4", "events.aedat4"), ("evt3", "events.raw")])
def test_record_writes_events_in_the_chosen_format(tmp_path, fmt, name):
    summary = record(
        tmp_path, RecordConfig(WanderConfig(episode_seconds=0.05), video=False, format=fmt)
    )
    assert name in summary["files"] and "events.h5" not in summary["files"]
    rec = read_events(tmp_path / name)
    assert rec.sensor_size == (128, 128, 2)
    assert len(rec.events) == summary["events"] > 0
    assert rec.events["t"].max() <= 50_000  # a step's events lie in (t0, t1]


def test_unknown_record_format_is_named():
    with pytest.raises(
        ValueError, match=r"^format: expected one of 'h5', 'aedat4', 'evt3', 'evimo2', got 'mp4'$"
    ):
        RecordConfig(format="mp4")
