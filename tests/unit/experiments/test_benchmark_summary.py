"""Tests for the benchmark's summaries and files (experiments.benchmark.summary)."""

from __future__ import annotations

import csv
import math

import numpy as np
import pytest
from test_benchmark_protocol import OMS, FakeModel, evaluate_sequence, sequence, standard_windows

from experiments.benchmark.protocol import ROW_COLUMNS, WindowRow
from experiments.benchmark.summary import (
    SUMMARY_COLUMNS,
    render_markdown,
    summarize,
    write_rows_csv,
    write_summary_csv,
)
from experiments.runs.tables import read_csv


def row(seq, subset, hit, iou=0.5, prec=0.5, s=0.9, notes="", dataset="evimo"):
    return WindowRow(dataset, subset, seq, 0, 0, 1, 1, 1, iou, prec, s, hit, notes)


def hand_rows():
    nan = math.nan
    return [
        row("a", "box", 1.0, iou=0.5),
        row("a", "box", 0.0, iou=0.5),
        row("a", "box", 1.0, iou=1.0),
        row("a", "box", 1.0, iou=0.0),
        row("a", "box", nan, iou=nan, prec=nan, s=nan, notes="empty_mask"),
        row("b", "box", 1.0),
        row("b", "box", 0.0),
        row("c", "wall", 1.0, prec=nan, notes="oms_empty"),
        row("c", "wall", nan, iou=nan, prec=nan, s=nan, notes="outside_recording"),
    ]


def test_summary_mean_std_exact():
    sums = summarize(hand_rows())
    by = {(s.level, s.subset, s.sequence): s for s in sums}
    a = by[("sequence", "box", "a")]
    assert (a.n_windows, a.n_scored, a.n_empty_mask) == (5, 4, 1)
    assert a.accuracy_mean == 0.75 and a.accuracy_std == math.sqrt(0.1875)
    assert a.iou_mean == 0.5 and a.iou_std == math.sqrt(0.125)
    box_ = by[("subset", "box", "")]
    assert (box_.n_sequences, box_.n_windows, box_.n_scored) == (2, 7, 6)
    assert (box_.accuracy_mean, box_.accuracy_std) == (0.625, 0.125)
    wall = by[("subset", "wall", "")]
    assert (wall.n_outside, wall.n_oms_empty, wall.accuracy_mean) == (1, 1, 1.0)
    assert math.isnan(wall.precision_mean)
    allr = by[("all", "all", "")]
    assert allr.n_sequences == 3 and allr.accuracy_mean == 0.75
    assert allr.accuracy_std == pytest.approx(math.sqrt(0.125 / 3), abs=1e-15)
    pooled = {(s.level, s.subset): s for s in summarize(hand_rows(), std_over="windows")}
    hits = np.array([1, 0, 1, 1, 1, 0], float)
    assert pooled[("subset", "box")].accuracy_mean == hits.mean()
    assert pooled[("subset", "box")].accuracy_std == hits.std()
    sample = {(s.level, s.subset): s for s in summarize(hand_rows(), ddof=1)}
    assert sample[("subset", "box")].accuracy_std == np.std([0.75, 0.5], ddof=1)


def test_csv_and_markdown_written(tmp_path):
    model = FakeModel(OMS, (10.0, 10.0))
    rows = evaluate_sequence(sequence(standard_windows()), model)
    csv_path = write_rows_csv(rows + hand_rows(), tmp_path / "out" / "results.csv")
    with csv_path.open() as f:
        table = list(csv.reader(f))
    assert (
        tuple(table[0])
        == ROW_COLUMNS
        == (
            "dataset",
            "subset",
            "sequence",
            "window",
            "t_start_us",
            "t_end_us",
            "n_events",
            "mask_pixels",
            "iou",
            "precision",
            "ssim",
            "hit",
            "notes",
        )
    )
    assert len(table) == 1 + len(rows) + len(hand_rows())
    assert table[1][:8] == ["evimo", "box", "seq", "0", "0", "1000", "2", "16"]
    assert table[2][8:] == ["", "", "", "", "empty_mask"]
    assert float(table[1][8]) == rows[0].iou
    md = render_markdown(summarize(rows + hand_rows()), "evimo")
    # box: 3 sequences (seq, a, b), accuracy over sequences mean(0.5, 0.75, 0.5) ± std
    assert "| box | 3 | 11 | 8 | 2 | 1 | 0 | 58.3 ± 11.79 | 73.4 ± 21.61 |" in md
    assert "88.8 ± 5.32" in md and "| 82.2 |" in md and "| 96 |" in md
    assert 'paper "IoU"' in md and "## Per sequence" in md
    assert "| box | a | 5 | 4 | 1 | 0 | 0 | 0 | 0 | 75.0 ± 43.30 |" in md
    lle = render_markdown(summarize([row("00011", "all", 1.0, dataset="llevos")]), "llevos")
    assert "53.3 ± 25.56" in lle


def test_write_rows_csv_nan_cells(tmp_path):
    path = write_rows_csv([row("a", "box", math.nan, iou=math.nan)], tmp_path / "r.csv")
    assert path.read_text() == (
        "dataset,subset,sequence,window,t_start_us,t_end_us,n_events,mask_pixels,iou,"
        "precision,ssim,hit,notes\nevimo,box,a,0,0,1,1,1,,0.5,0.9,,\n"
    )
    (back,) = read_csv(path)
    assert list(back) == list(ROW_COLUMNS) and back["window"] == 0 and back["ssim"] == 0.9
    assert math.isnan(back["iou"]) and math.isnan(back["hit"])


def test_summary_csv_is_the_house_table(tmp_path):
    summaries = summarize(hand_rows())
    back = read_csv(write_summary_csv(summaries, tmp_path / "summary.csv"))
    assert len(back) == len(summaries) and list(back[0]) == list(SUMMARY_COLUMNS)
    by = {(r["level"], r["subset"], r["sequence"]): r for r in back if r["level"] == "sequence"}
    a = by[("sequence", "box", "a")]
    assert (a["n_windows"], a["n_scored"], a["accuracy_mean"]) == (5, 4, 0.75)
    assert a["accuracy_std"] == math.sqrt(0.1875)
    (wall,) = [r for r in back if r["level"] == "subset" and r["subset"] == "wall"]
    assert math.isnan(wall["precision_mean"])  # NaN: an empty cell, read back as NaN
    assert math.isnan(wall["sequence"])  # "" too: the house table reads an empty cell as NaN
    # no summaries: the header alone
    empty = write_summary_csv([], tmp_path / "empty.csv")
    assert empty.read_text() == ",".join(SUMMARY_COLUMNS) + "\n"
