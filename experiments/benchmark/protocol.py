"""The detection / segmentation benchmark protocol of the paper, done right.

For each sequence (:class:`experiments.benchmark.datasets.SequenceData`) the model is reset and
then streamed the recording window by window, in time order:

1. the events of each ground-truth window — exactly the dataset's windows, half-open
   ``[t_start, t_end)`` — are binned into per-polarity counts ``(2, H, W)`` and given to
   ``model.process(counts, dt_s)`` with ``dt_s`` the window's length;
2. events *between* windows (ground-truth gaps, unannotated frames) are fed too, in
   unscored steps no longer than the next window (``feed_gaps``), so that the model's
   state sees the whole stream; events before the first window are not fed;
3. the model's maps must be on the sensor grid (pad, never stretch): an OMS map or a
   saliency map of another shape is an error. The *mask* is put on the sensor grid
   instead — nearest-neighbour resize, or unscaled placement at ``mask_offset_xy`` —
   and every window where that happened says so in its notes;
4. each window with a non-empty mask is scored: true IoU ``|O ∩ M| / |O ∪ M|``,
   precision ``|O ∩ M| / |O|`` (what the paper's public code called "IoU"; undefined
   when the OMS map is empty — noted, left out of the means), SSIM of the OMS map and
   the mask as float images in [0, 1] (:func:`experiments.analysis.metrics.ssim`, Gaussian 11×11,
   σ = 1.5), and the detection hit: the 8×8 box around the saliency argmax ``point_xy``
   touches the mask (:func:`experiments.analysis.metrics.detection_hit`; no point = a miss).

Windows are never dropped silently. Each gets a row; its ``notes`` say why it was not
scored or what to keep in mind:

- ``empty_mask`` — no object in the ground truth: counted, not scored (no IoU, SSIM or
  hit), and the sequence goes on;
- ``outside_recording`` — the window lies wholly before the first or after the last
  event of the recording: counted, not scored, the model is not run;
- ``no_events`` — no event inside the window (but within the recording): scored, since
  the model still has a state and the object is still there;
- ``no_point`` (scored as a miss), ``oms_empty`` (precision undefined),
  ``mask_resized …`` / ``mask_placed …`` (the mask was fitted to the sensor grid).

Summaries, the paper's figures and the output files are :mod:`experiments.benchmark.summary`;
the event-suppression measurement is :mod:`experiments.benchmark.suppression`.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, fields
from typing import Any, Protocol, runtime_checkable

import numpy as np

from experiments.analysis.metrics import detection_hit, iou, precision, ssim
from experiments.benchmark.datasets.base import SequenceData, check_windows_ordered
from experiments.benchmark.datasets.masks import fit_mask
from wander_env.events import SensorSize, check_sorted, time_window, to_frame

NOTE_EMPTY_MASK = "empty_mask"
NOTE_OUTSIDE = "outside_recording"
NOTE_NO_EVENTS = "no_events"
NOTE_NO_POINT = "no_point"
NOTE_OMS_EMPTY = "oms_empty"
NOTE_MASK_FIT = "mask_"  # prefix of "mask_resized …" / "mask_placed …"
SSIM_MIN_SIDE = 11


# ----------------------------------------------------------------------------------------
# The model interface


@runtime_checkable
class MapsLike(Protocol):
    """What ``model.process`` returns: maps on the sensor grid and the salient point."""

    oms: np.ndarray
    oms_polarity: np.ndarray
    saliency: np.ndarray
    point_xy: tuple[float, float] | None


@dataclass(frozen=True, eq=False)
class Maps:
    """A plain :class:`MapsLike`: the OMS map (bool ``(H, W)``: either polarity fired),
    per polarity (bool ``(2, H, W)``, channel 0 OFF, 1 ON: which events it keeps,
    :func:`agents.suppression.kept_events`), the saliency (float ``(H, W)``) and its argmax
    ``(x, y)`` (``None`` when there is none)."""

    oms: np.ndarray
    oms_polarity: np.ndarray
    saliency: np.ndarray
    point_xy: tuple[float, float] | None = None


class BenchmarkModel(Protocol):
    """A model the protocol can stream: reset per sequence, then one call per step."""

    def reset(self) -> None: ...

    def process(self, event_counts: np.ndarray, dt_s: float) -> MapsLike: ...


@dataclass(frozen=True)
class ProgressEvent:
    """Passed to the progress callback after each window (scored or not)."""

    sequence: str
    subset: str
    sequence_index: int
    n_sequences: int | None
    window: int
    n_windows: int


ProgressFn = Callable[[ProgressEvent], None]


@dataclass(frozen=True)
class ProtocolConfig:
    """Protocol options (see the module docstring)."""

    feed_gaps: bool = True
    box: int = 8
    mask_offset_xy: tuple[int, int] | None = None


# ----------------------------------------------------------------------------------------
# Per-window scoring (pure)


@dataclass
class WindowRow:
    """One window of one sequence: the tidy results table has one of these per row."""

    dataset: str
    subset: str
    sequence: str
    window: int
    t_start_us: int
    t_end_us: int
    n_events: int
    mask_pixels: int
    iou: float
    precision: float
    ssim: float
    hit: float  # 1.0 hit, 0.0 miss, nan not scored
    notes: str = ""

    def has_note(self, note: str) -> bool:
        return any(n.startswith(note) for n in self.notes.split(";") if n)

    @property
    def scored(self) -> bool:
        return not (self.has_note(NOTE_EMPTY_MASK) or self.has_note(NOTE_OUTSIDE))


ROW_COLUMNS = tuple(f.name for f in fields(WindowRow))


@dataclass(frozen=True)
class WindowScores:
    """Scores of one window with a non-empty mask."""

    iou: float
    precision: float
    ssim: float
    hit: float
    notes: tuple[str, ...] = ()


def score_window(
    oms: np.ndarray, point_xy: tuple[float, float] | None, mask: np.ndarray, box: int = 8
) -> WindowScores:
    """True IoU, precision, SSIM and the box hit of one OMS map / point against a mask.

    >>> m = np.zeros((16, 16), bool); m[4:8, 4:8] = True
    >>> o = np.zeros((16, 16), bool); o[4:8, 4:12] = True
    >>> s = score_window(o, (10.0, 10.0), m)
    >>> s.iou, s.precision, s.hit
    (0.5, 0.5, 1.0)
    """
    oms_b = np.asarray(oms, dtype=bool)
    mask_b = np.asarray(mask, dtype=bool)
    notes: list[str] = []
    prec = precision(oms_b, mask_b)
    if not oms_b.any():
        notes.append(NOTE_OMS_EMPTY)
    if min(mask_b.shape) >= SSIM_MIN_SIDE:
        s = ssim(oms_b.astype(np.float64), mask_b.astype(np.float64), data_range=1.0)
    else:
        s = math.nan
    if point_xy is None:
        notes.append(NOTE_NO_POINT)
        hit = 0.0
    else:
        hit = float(detection_hit(point_xy, mask_b, box=box))
    return WindowScores(iou(oms_b, mask_b), prec, s, hit, tuple(notes))


def check_maps(maps: MapsLike, hw: tuple[int, int], where: str) -> MapsLike:
    """``maps`` on the sensor grid ``hw`` (H, W): its OMS and saliency maps ``(H, W)``,
    its per-polarity OMS map ``(2, H, W)``; ValueError naming ``where`` otherwise."""
    for name, shape in (("oms", hw), ("oms_polarity", (2, *hw)), ("saliency", hw)):
        arr = np.asarray(getattr(maps, name))
        if arr.shape != shape:
            raise ValueError(
                f"{where}: the model's {name} map is {arr.shape}, the sensor grid needs "
                f"{shape}; maps must stay on the sensor grid (pad, never stretch)"
            )
    return maps


# ----------------------------------------------------------------------------------------
# Streaming a sequence through the model


def _feed(
    model: BenchmarkModel, events: np.ndarray, sensor: SensorSize, t0: int, t1: int, step: int
) -> None:
    """Unscored steps over ``[t0, t1)``, each at most ``step`` µs long."""
    t = t0
    while t < t1:
        end = min(t + step, t1)
        model.process(to_frame(time_window(events, t, end), sensor), (end - t) / 1e6)
        t = end


def _nan_row(
    seq: SequenceData, i: int, t0: int, t1: int, n: int, px: int, notes: list[str]
) -> WindowRow:
    nan = math.nan
    return WindowRow(
        seq.dataset, seq.subset, seq.name, i, t0, t1, n, px, nan, nan, nan, nan, ";".join(notes)
    )


def evaluate_sequence(
    seq: SequenceData,
    model: BenchmarkModel,
    config: ProtocolConfig | None = None,
    progress: ProgressFn | None = None,
    sequence_index: int = 0,
    n_sequences: int | None = None,
    observe: Callable[[WindowRow, np.ndarray, Any, np.ndarray], None] | None = None,
) -> list[WindowRow]:
    """Stream one sequence through ``model`` and score every window (module docstring).

    ``observe(row, counts, maps, mask)``, when given, sees every scored window: its
    row, the per-polarity event counts ``(2, H, W)``, the model's maps and the mask.
    """
    config = config or ProtocolConfig()
    where = f"{seq.dataset}/{seq.subset}/{seq.name}"
    check_windows_ordered(seq.windows, where)
    check_sorted(seq.events, where)
    sensor = seq.sensor_size
    hw = (int(sensor[1]), int(sensor[0]))
    events = seq.events
    has_events = len(events) > 0
    t_first = int(events["t"][0]) if has_events else 0
    t_last = int(events["t"][-1]) if has_events else -1
    model.reset()
    cursor: int | None = None
    rows: list[WindowRow] = []
    n_win = len(seq.windows)
    for i, win in enumerate(seq.windows):
        t0, t1 = int(win.t_start_us), int(win.t_end_us)
        notes: list[str] = []
        labels, fit = fit_mask(win.labels, sensor, config.mask_offset_xy)
        mask = labels > 0
        if fit.changed:
            verb = "placed" if fit.mode == "pad" else "resized"
            notes.append(f"{NOTE_MASK_FIT}{verb} {fit.describe()}")
        wev = time_window(events, t0, t1)
        n_ev, px = len(wev), int(mask.sum())
        if not has_events or t1 <= t_first or t0 > t_last:
            rows.append(_nan_row(seq, i, t0, t1, n_ev, px, [NOTE_OUTSIDE, *notes]))
        else:
            if config.feed_gaps and cursor is not None and t0 > cursor:
                _feed(model, events, sensor, cursor, t0, t1 - t0)
            counts = to_frame(wev, sensor)
            maps = model.process(counts, (t1 - t0) / 1e6)
            cursor = t1
            check_maps(maps, hw, f"{where} window {i}")
            if n_ev == 0:
                notes.insert(0, NOTE_NO_EVENTS)
            if px == 0:
                rows.append(_nan_row(seq, i, t0, t1, n_ev, px, [NOTE_EMPTY_MASK, *notes]))
            else:
                point = maps.point_xy
                s = score_window(
                    maps.oms, None if point is None else tuple(point), mask, config.box
                )
                rows.append(
                    WindowRow(
                        seq.dataset,
                        seq.subset,
                        seq.name,
                        i,
                        t0,
                        t1,
                        n_ev,
                        px,
                        s.iou,
                        s.precision,
                        s.ssim,
                        s.hit,
                        ";".join([*notes, *s.notes]),
                    )
                )
                if observe is not None:
                    observe(rows[-1], counts, maps, mask)
        if progress is not None:
            progress(ProgressEvent(seq.name, seq.subset, sequence_index, n_sequences, i, n_win))
    return rows
