"""Tests for the benchmark protocol (experiments.benchmark.protocol) with a fake model."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import pytest

from experiments.analysis.metrics import ssim
from experiments.benchmark.datasets import MaskWindow, SequenceData
from experiments.benchmark.protocol import (
    BenchmarkModel,
    Maps,
    ProtocolConfig,
    evaluate_sequence,
    score_window,
)
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
        both = np.stack([self.oms, self.oms])  # the same map for either polarity
        return Maps(self.oms, both, np.zeros((H, W), np.float32), self.point)


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


def test_progress_callback_over_sequences():
    seen = []
    model: BenchmarkModel = FakeModel(OMS, (10.0, 10.0))
    seqs = [sequence(standard_windows(), name="a"), sequence(standard_windows(), name="b")]
    rows = [
        r for k, s in enumerate(seqs) for r in evaluate_sequence(s, model, None, seen.append, k, 2)
    ]
    assert len(rows) == 8 and model.resets == 2
    assert [(e.sequence, e.sequence_index, e.window, e.n_windows) for e in seen][-1] == (
        "b",
        1,
        3,
        4,
    )
    assert len(seen) == 8 and seen[0].n_sequences == 2
