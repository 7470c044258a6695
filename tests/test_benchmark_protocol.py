"""Tests for the benchmark protocol (experiments.benchmark.protocol) with a fake model."""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass, field

import numpy as np
import pytest

from experiments.benchmark.datasets import MaskWindow, SequenceData
from experiments.benchmark.protocol import (
    ROW_COLUMNS,
    BenchmarkModel,
    Maps,
    ProtocolConfig,
    WindowRow,
    evaluate_sequence,
    event_suppression,
    mean_std,
    read_rows_csv,
    render_markdown,
    render_suppression_markdown,
    run_benchmark,
    score_window,
    summarize,
    write_results,
    write_rows_csv,
)
from experiments.metrics import ssim
from wander_env.events import make_events

W, H = 32, 24
SENSOR = (W, H, 2)


def box(y0, y1, x0, x1, shape=(H, W)):
    m = np.zeros(shape, dtype=bool)
    m[y0:y1, x0:x1] = True
    return m


@dataclass
class FakeModel:
    """Returns the same OMS map and point every call; records what it was given."""

    oms: np.ndarray
    point: tuple[float, float] | None
    calls: list[tuple[float, float]] = field(default_factory=list)  # (events, dt_s)
    resets: int = 0

    def reset(self) -> None:
        self.resets += 1

    def process(self, event_counts: np.ndarray, dt_s: float) -> Maps:
        assert event_counts.shape == (2, H, W)
        self.calls.append((float(event_counts.sum()), dt_s))
        return Maps(self.oms, np.zeros((H, W), np.float32), self.point)


MASK_A = box(4, 8, 4, 8)  # 16 px
MASK_B = box(16, 20, 20, 28)  # 32 px
OMS = box(4, 8, 4, 12)  # 32 px; covers MASK_A, misses MASK_B


def sequence(windows, events=None, name="seq", subset="box", sensor=SENSOR):
    if events is None:
        # 2 events in [0, 1000), 1 in [1000, 2000), 1 in the gap, 3 in [3000, 4000)
        events = make_events(
            x=[1, 2, 3, 4, 5, 6, 7],
            y=[1, 1, 1, 1, 1, 1, 1],
            t=[100, 900, 1500, 2500, 3000, 3500, 3999],
            p=[1, 0, 1, 1, 0, 1, 1],
        )
    return SequenceData("evimo", subset, name, sensor, events, windows)


def standard_windows():
    return [
        MaskWindow(0, 1000, MASK_A.astype(np.uint8)),
        MaskWindow(1000, 2000, np.zeros((H, W), np.uint8)),  # empty mask
        MaskWindow(3000, 4000, MASK_B.astype(np.uint8) * 2),  # after a gap [2000, 3000)
        MaskWindow(5000, 6000, MASK_A.astype(np.uint8)),  # after the last event
    ]


def test_score_window_by_hand():
    s = score_window(OMS, (10, 10), MASK_A)
    assert (s.iou, s.precision, s.hit) == (16 / 32, 16 / 32, 1.0)
    assert s.ssim == ssim(OMS.astype(float), MASK_A.astype(float))
    s = score_window(np.zeros((H, W), bool), None, MASK_A)
    assert s.iou == 0.0 and math.isnan(s.precision) and s.hit == 0.0
    assert s.notes == ("oms_empty", "no_point")


def test_protocol_rows_exact():
    model = FakeModel(OMS, (10.0, 10.0))
    rows = evaluate_sequence(sequence(standard_windows()), model)
    assert model.resets == 1
    assert [r.window for r in rows] == [0, 1, 2, 3]
    assert [(r.t_start_us, r.t_end_us) for r in rows] == [
        (0, 1000),
        (1000, 2000),
        (3000, 4000),
        (5000, 6000),
    ]
    assert [r.n_events for r in rows] == [2, 1, 3, 0]
    assert [r.mask_pixels for r in rows] == [16, 0, 32, 16]
    r0, r1, r2, r3 = rows
    assert (r0.iou, r0.precision, r0.hit, r0.notes) == (0.5, 0.5, 1.0, "")
    assert r0.ssim == ssim(OMS.astype(float), MASK_A.astype(float))
    assert r1.notes == "empty_mask" and math.isnan(r1.iou) and math.isnan(r1.hit)
    assert (r2.iou, r2.precision, r2.hit) == (0.0, 0.0, 0.0)  # the empty mask did not stop it
    assert r3.notes == "outside_recording" and math.isnan(r3.ssim)
    # model calls: w0, w1, the gap [2000, 3000) fed in one 1000 µs step, w2; not w3
    assert model.calls == [(2.0, 0.001), (1.0, 0.001), (1.0, 0.001), (3.0, 0.001)]
    assert [r.scored for r in rows] == [True, False, True, False]


def test_gap_feeding_can_be_turned_off_and_chunks():
    model = FakeModel(OMS, (10.0, 10.0))
    evaluate_sequence(sequence(standard_windows()), model, ProtocolConfig(feed_gaps=False))
    assert len(model.calls) == 3
    wins = [MaskWindow(0, 400, MASK_A), MaskWindow(1400, 1800, MASK_A)]  # 1000 µs gap
    model = FakeModel(OMS, (10.0, 10.0))
    evaluate_sequence(sequence(wins), model)
    assert [c[1] for c in model.calls] == [0.0004, 0.0004, 0.0004, 0.0002, 0.0004]
    assert sum(c[0] for c in model.calls) == 3  # t = 100, 900, 1500


def test_no_events_window_is_scored_and_no_point_is_a_miss():
    wins = [MaskWindow(0, 1000, MASK_A), MaskWindow(2000, 2400, MASK_A)]
    rows = evaluate_sequence(sequence(wins), FakeModel(OMS, None))
    assert rows[1].n_events == 0 and rows[1].notes == "no_events;no_point"
    assert rows[1].iou == 0.5 and rows[1].hit == 0.0


def test_mask_at_other_resolution_is_resized_and_said():
    half = np.zeros((H // 2, W // 2), np.uint8)
    half[2:4, 2:4] = 1  # -> [4:8, 4:8] on the sensor grid
    rows = evaluate_sequence(sequence([MaskWindow(0, 1000, half)]), FakeModel(OMS, (10, 10)))
    assert rows[0].mask_pixels == 16 and rows[0].iou == 0.5
    assert rows[0].notes.startswith("mask_resized mask 12x16 (HxW) resized nearest-neighbour")


def test_maps_must_be_on_the_sensor_grid():
    model = FakeModel(np.zeros((H, W + 2), bool), (1, 1))
    with pytest.raises(ValueError, match="pad, never stretch"):
        evaluate_sequence(sequence([MaskWindow(0, 1000, MASK_A)]), model)


def test_overlapping_windows_are_refused():
    wins = [MaskWindow(0, 1000, MASK_A), MaskWindow(900, 2000, MASK_A)]
    with pytest.raises(ValueError, match="must not overlap"):
        evaluate_sequence(sequence(wins), FakeModel(OMS, (1, 1)))


def test_progress_callback_and_run_benchmark():
    seen = []
    model: BenchmarkModel = FakeModel(OMS, (10.0, 10.0))
    seqs = [sequence(standard_windows(), name="a"), sequence(standard_windows(), name="b")]
    rows = run_benchmark(iter(seqs), model, progress=seen.append, n_sequences=2)
    assert len(rows) == 8 and model.resets == 2
    assert [(e.sequence, e.sequence_index, e.window, e.n_windows) for e in seen][-1] == (
        "b",
        1,
        3,
        4,
    )
    assert len(seen) == 8 and seen[0].n_sequences == 2


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
    assert mean_std([0.75, 0.5]) == (0.625, 0.125)
    assert mean_std([1.0], ddof=1)[1] != mean_std([1.0], ddof=1)[1]  # nan
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
    csv_path, md_path = write_results(rows + hand_rows(), tmp_path / "out", "evimo")
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
    back = read_rows_csv(csv_path)
    assert [(r.sequence, r.window, r.n_events, r.notes) for r in back] == [
        (r.sequence, r.window, r.n_events, r.notes) for r in rows + hand_rows()
    ]
    assert back[0].iou == rows[0].iou and math.isnan(back[1].iou)
    md = md_path.read_text()
    # box: 3 sequences (seq, a, b), accuracy over sequences mean(0.5, 0.75, 0.5) ± std
    assert "| box | 3 | 11 | 8 | 2 | 1 | 0 | 58.3 ± 11.79 | 73.4 ± 21.61 |" in md
    assert "88.8 ± 5.32" in md and "| 82.2 |" in md and "| 96 |" in md
    assert 'paper "IoU"' in md and "## Per sequence" in md
    assert "| box | a | 5 | 4 | 1 | 0 | 0 | 0 | 0 | 75.0 ± 43.30 |" in md
    lle = render_markdown(summarize([row("00011", "all", 1.0, dataset="llevos")]), "llevos")
    assert "53.3 ± 25.56" in lle


def test_write_rows_csv_nan_cells(tmp_path):
    path = write_rows_csv([row("a", "box", math.nan, iou=math.nan)], tmp_path / "r.csv")
    assert path.read_text().splitlines()[1].split(",")[8] == ""


def test_event_suppression_counts():
    # static scene: events everywhere, OMS active on a 4 x 8 patch only
    events = make_events(
        x=[5, 6, 20, 5, 30, 31, 4, 4],
        y=[5, 5, 5, 6, 20, 20, 4, 4],
        t=[0, 100, 500, 1999, 2000, 2500, 4000, 4001],
        p=[1, 0, 1, 1, 0, 1, 1, 0],
    )
    model = FakeModel(OMS, None)
    res = event_suppression(events, SENSOR, model, window_us=2000)
    assert res.n_windows == 3
    assert res.events_in.tolist() == [4, 2, 2]
    assert res.events_out.tolist() == [3, 0, 2]
    assert (res.total_in, res.total_out) == (8, 5)
    assert res.fraction_suppressed == 1 - 5 / 8
    assert res.per_window()["events_in_mean"] == 8 / 3
    assert [c[1] for c in model.calls] == [0.002] * 3
    md = render_suppression_markdown(res, "poster")
    assert "37.50 %" in md and "85.16 %" in md
