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
   the mask as float images in [0, 1] (:func:`experiments.metrics.ssim`, Gaussian 11×11,
   σ = 1.5), and the detection hit: the 8×8 box around the saliency argmax ``point_xy``
   touches the mask (:func:`experiments.metrics.detection_hit`; no point = a miss).

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

Statistics (:func:`summarize`): per sequence, means over its scored windows (std over
windows); per subset and over all, mean ± std **over sequences** of the per-sequence
means by default — the paper's Table of EVIMO accuracies (e.g. Box 73.4 % ± 21.61 over
its 6 sequences) and its LLE-VOS figure (53.3 % ± 25.56 over sub-datasets) are spreads
across sequences — or pooled over windows (``std_over="windows"``). Population standard
deviations (``ddof=0``, NumPy's default) unless asked otherwise.

Output: one tidy row per window (:class:`WindowRow`, :func:`write_rows_csv`) and a
Markdown summary with the paper's figures beside ours (:func:`render_markdown`).

:func:`event_suppression` measures the fraction of events the OMS stage removes on a
recording with no independently moving object (e.g. ``uzh_poster_egomotion``).
"""

from __future__ import annotations

import csv
import math
import os
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import asdict, dataclass, fields
from pathlib import Path
from types import MappingProxyType
from typing import Any, Protocol, runtime_checkable

import numpy as np

from experiments.benchmark.datasets.base import SequenceData, check_windows_ordered
from experiments.benchmark.datasets.masks import fit_mask
from experiments.metrics import detection_hit, iou, precision, ssim
from experiments.stats import mean_std
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
    saliency: np.ndarray
    point_xy: tuple[float, float] | None


@dataclass(frozen=True, eq=False)
class Maps:
    """A plain :class:`MapsLike`: OMS map (bool ``(H, W)``), saliency (float ``(H, W)``)
    and the saliency argmax ``(x, y)`` (``None`` when there is none)."""

    oms: np.ndarray
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


def _check_maps(maps: MapsLike, hw: tuple[int, int], where: str) -> MapsLike:
    for name in ("oms", "saliency"):
        arr = np.asarray(getattr(maps, name))
        if arr.shape != hw:
            raise ValueError(
                f"{where}: the model's {name} map is {arr.shape}, the sensor grid is {hw} "
                f"(H, W); maps must stay on the sensor grid (pad, never stretch)"
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
            _check_maps(maps, hw, f"{where} window {i}")
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


def run_benchmark(
    sequences: Iterable[SequenceData],
    model: BenchmarkModel,
    config: ProtocolConfig | None = None,
    progress: ProgressFn | None = None,
    n_sequences: int | None = None,
) -> list[WindowRow]:
    """:func:`evaluate_sequence` over every sequence (loaded lazily if an iterator)."""
    rows: list[WindowRow] = []
    for k, seq in enumerate(sequences):
        rows.extend(evaluate_sequence(seq, model, config, progress, k, n_sequences))
    return rows


# ----------------------------------------------------------------------------------------
# Statistics


METRICS = ("iou", "precision", "ssim", "accuracy")


@dataclass
class Summary:
    """Mean ± std of each metric for one sequence, one subset, or all sequences.

    ``accuracy`` is the detection hit rate (fraction of scored windows whose 8×8 box
    touches the mask). For ``level="sequence"`` the std is over windows; for
    ``"subset"``/``"all"`` it is over sequences or windows as ``std_over`` says.
    """

    level: str
    dataset: str
    subset: str
    sequence: str
    std_over: str
    n_sequences: int
    n_windows: int
    n_scored: int
    n_empty_mask: int
    n_outside: int
    n_no_events: int
    n_no_point: int
    n_oms_empty: int
    n_mask_fitted: int
    iou_mean: float = math.nan
    iou_std: float = math.nan
    precision_mean: float = math.nan
    precision_std: float = math.nan
    ssim_mean: float = math.nan
    ssim_std: float = math.nan
    accuracy_mean: float = math.nan
    accuracy_std: float = math.nan


def _metric(row: WindowRow, name: str) -> float:
    return row.hit if name == "accuracy" else float(getattr(row, name))


def _counts(rows: Sequence[WindowRow]) -> dict[str, int]:
    return {
        "n_windows": len(rows),
        "n_scored": sum(r.scored for r in rows),
        "n_empty_mask": sum(r.has_note(NOTE_EMPTY_MASK) for r in rows),
        "n_outside": sum(r.has_note(NOTE_OUTSIDE) for r in rows),
        "n_no_events": sum(r.has_note(NOTE_NO_EVENTS) for r in rows),
        "n_no_point": sum(r.has_note(NOTE_NO_POINT) for r in rows),
        "n_oms_empty": sum(r.has_note(NOTE_OMS_EMPTY) for r in rows),
        "n_mask_fitted": sum(r.has_note(NOTE_MASK_FIT) for r in rows),
    }


def _sequence_summary(rows: Sequence[WindowRow], ddof: int) -> Summary:
    r0 = rows[0]
    s = Summary("sequence", r0.dataset, r0.subset, r0.sequence, "windows", 1, **_counts(rows))
    scored = [r for r in rows if r.scored]
    for m in METRICS:
        mean, std = mean_std((_metric(r, m) for r in scored), ddof)
        setattr(s, f"{m}_mean", mean)
        setattr(s, f"{m}_std", std)
    return s


def _group_summary(
    level: str,
    subset: str,
    seqs: Sequence[Summary],
    rows: Sequence[WindowRow],
    std_over: str,
    ddof: int,
) -> Summary:
    s = Summary(level, seqs[0].dataset, subset, "", std_over, len(seqs), **_counts(rows))
    scored = [r for r in rows if r.scored]
    for m in METRICS:
        if std_over == "sequences":
            mean, std = mean_std((getattr(q, f"{m}_mean") for q in seqs), ddof)
        else:
            mean, std = mean_std((_metric(r, m) for r in scored), ddof)
        setattr(s, f"{m}_mean", mean)
        setattr(s, f"{m}_std", std)
    return s


def summarize(
    rows: Sequence[WindowRow], std_over: str = "sequences", ddof: int = 0
) -> list[Summary]:
    """Per-sequence, per-subset and overall summaries, for each dataset in ``rows``.

    Order: for each dataset, its sequences (in order of appearance), then its subsets
    (sorted), then ``subset="all"``.
    """
    if std_over not in ("sequences", "windows"):
        raise ValueError(f"std_over must be 'sequences' or 'windows', got {std_over!r}")
    by_seq: dict[tuple[str, str, str], list[WindowRow]] = {}
    for r in rows:
        by_seq.setdefault((r.dataset, r.subset, r.sequence), []).append(r)
    out: list[Summary] = []
    for dataset in dict.fromkeys(k[0] for k in by_seq):
        keys = [k for k in by_seq if k[0] == dataset]
        seq_sums = {k: _sequence_summary(by_seq[k], ddof) for k in keys}
        out.extend(seq_sums.values())
        for subset in sorted({k[1] for k in keys}):
            ks = [k for k in keys if k[1] == subset]
            sub_rows = [r for k in ks for r in by_seq[k]]
            out.append(
                _group_summary(
                    "subset", subset, [seq_sums[k] for k in ks], sub_rows, std_over, ddof
                )
            )
        all_rows = [r for k in keys for r in by_seq[k]]
        out.append(_group_summary("all", "all", list(seq_sums.values()), all_rows, std_over, ddof))
    return out


# ----------------------------------------------------------------------------------------
# The paper's figures


@dataclass(frozen=True)
class PaperFigure:
    """A figure reported in the paper, in percent (``None`` where it reports none)."""

    accuracy_mean: float | None = None
    accuracy_std: float | None = None
    precision_mean: float | None = None  # the paper's "IoU" (really a precision)
    ssim_mean: float | None = None
    where: str = ""


def paper_reference(dataset: str) -> dict[str, PaperFigure]:
    """The paper's figures for ``dataset`` (``"evimo"``, ``"llevos"``), keyed by subset."""
    if dataset == "evimo":
        acc = {
            "box": (73.4, 21.61),
            "fast": (70.9, 17.85),
            "floor": (81.0, 5.88),
            "table": (68.1, 23.57),
            "tabletop": (87.9, 16.77),
            "wall": (88.8, 5.32),
        }
        ref = {k: PaperFigure(m, s, where="Table (accuracy)") for k, (m, s) in acc.items()}
        ref["all"] = PaperFigure(precision_mean=82.2, ssim_mean=96.0, where="abstract, discussion")
        return ref
    if dataset == "llevos":
        return {"all": PaperFigure(53.3, 25.56, where="LLE-VOS benchmark text")}
    return {}


# Event suppression, the paper's Table: 10 trials, counts per 2 ms window.
PAPER_SUPPRESSION: Mapping[str, float] = MappingProxyType(
    {
        "events_in_mean": 14747.03,
        "events_in_std": 2029.17,
        "events_out_mean": 2189.15,
        "events_out_std": 385.57,
        "suppressed_pct": 85.16,
    }
)


# ----------------------------------------------------------------------------------------
# Files


def _fmt(v: object) -> str:
    if isinstance(v, float):
        if math.isnan(v):
            return ""
        return repr(v)
    return str(v)


def write_rows_csv(rows: Sequence[WindowRow], path: str | os.PathLike) -> Path:
    """The tidy per-window table (columns :data:`ROW_COLUMNS`; NaN as empty cells)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(ROW_COLUMNS)
        for r in rows:
            w.writerow([_fmt(getattr(r, c)) for c in ROW_COLUMNS])
    return path


def read_rows_csv(path: str | os.PathLike) -> list[WindowRow]:
    """Read back a table written by :func:`write_rows_csv`."""
    types = {f.name: f.type for f in fields(WindowRow)}
    rows: list[WindowRow] = []
    with Path(path).open(newline="") as f:
        reader = csv.DictReader(f)
        if tuple(reader.fieldnames or ()) != ROW_COLUMNS:
            raise ValueError(f"{path}: columns {reader.fieldnames}, expected {list(ROW_COLUMNS)}")
        for rec in reader:
            kw: dict[str, object] = {}
            for k, v in rec.items():
                t = types[k]
                if t == "int":
                    kw[k] = int(v)
                elif t == "float":
                    kw[k] = float(v) if v != "" else math.nan
                else:
                    kw[k] = v
            rows.append(WindowRow(**kw))  # type: ignore[arg-type]
    return rows


def _pct(mean: float, std: float | None = None) -> str:
    if mean is None or (isinstance(mean, float) and math.isnan(mean)):
        return "—"
    text = f"{100 * mean:.1f}"
    if std is not None and not math.isnan(std):
        text += f" ± {100 * std:.2f}"
    return text


def _paper(mean: float | None, std: float | None = None) -> str:
    if mean is None:
        return "—"
    return f"{mean:g}" + (f" ± {std:g}" if std is not None else "")


def render_markdown(
    summaries: Sequence[Summary], dataset: str, title: str | None = None, ddof: int = 0
) -> str:
    """A Markdown report: per-subset table with the paper's figures, per-sequence table."""
    ref = paper_reference(dataset)
    groups = [s for s in summaries if s.dataset == dataset and s.level != "sequence"]
    seqs = [s for s in summaries if s.dataset == dataset and s.level == "sequence"]
    std_over = groups[0].std_over if groups else "sequences"
    lines = [
        f"# {title or f'Benchmark: {dataset}'}",
        "",
        f"Percent, mean ± std over {std_over} (ddof={ddof}). Accuracy = fraction of scored "
        "windows whose 8×8 box around the saliency argmax touches the mask. IoU is the true "
        '|O∩M|/|O∪M|; precision |O∩M|/|O| is what the paper (and its code) called "IoU". '
        "Windows with an empty mask or outside the recording are counted, not scored.",
        "",
        "| subset | seq. | windows | scored | empty mask | outside | no events | "
        'accuracy | paper accuracy | IoU | precision | paper "IoU" | SSIM | paper SSIM |',
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for g in groups:
        p = ref.get(g.subset, PaperFigure())
        lines.append(
            f"| {g.subset} | {g.n_sequences} | {g.n_windows} | {g.n_scored} | {g.n_empty_mask} "
            f"| {g.n_outside} | {g.n_no_events} | {_pct(g.accuracy_mean, g.accuracy_std)} "
            f"| {_paper(p.accuracy_mean, p.accuracy_std)} | {_pct(g.iou_mean, g.iou_std)} "
            f"| {_pct(g.precision_mean, g.precision_std)} | {_paper(p.precision_mean)} "
            f"| {_pct(g.ssim_mean, g.ssim_std)} | {_paper(p.ssim_mean)} |"
        )
    lines += [
        "",
        "## Per sequence (std over windows)",
        "",
        "| subset | sequence | windows | scored | empty mask | outside | no events | no point "
        "| mask fitted | accuracy | IoU | precision | SSIM |",
        "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for s in seqs:
        lines.append(
            f"| {s.subset} | {s.sequence} | {s.n_windows} | {s.n_scored} | {s.n_empty_mask} "
            f"| {s.n_outside} | {s.n_no_events} | {s.n_no_point} | {s.n_mask_fitted} "
            f"| {_pct(s.accuracy_mean, s.accuracy_std)} | {_pct(s.iou_mean, s.iou_std)} "
            f"| {_pct(s.precision_mean, s.precision_std)} | {_pct(s.ssim_mean, s.ssim_std)} |"
        )
    if any(s.n_mask_fitted for s in seqs):
        lines += [
            "",
            "Some masks were not on the sensor grid and were fitted to it (nearest-neighbour "
            "resize or unscaled placement; the maps were never stretched): see the `notes` "
            "column of the CSV.",
        ]
    return "\n".join(lines) + "\n"


def write_markdown(
    summaries: Sequence[Summary],
    path: str | os.PathLike,
    dataset: str,
    title: str | None = None,
    ddof: int = 0,
) -> Path:
    """Write :func:`render_markdown` to ``path``."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(render_markdown(summaries, dataset, title, ddof))
    return path


def write_results(
    rows: Sequence[WindowRow],
    out_dir: str | os.PathLike,
    dataset: str,
    std_over: str = "sequences",
    ddof: int = 0,
) -> tuple[Path, Path]:
    """``out_dir/windows.csv`` and ``out_dir/summary.md``; returns their paths."""
    out_dir = Path(out_dir)
    csv_path = write_rows_csv(rows, out_dir / "windows.csv")
    md_path = write_markdown(
        summarize(rows, std_over, ddof), out_dir / "summary.md", dataset, ddof=ddof
    )
    return csv_path, md_path


def summary_dicts(summaries: Sequence[Summary]) -> list[dict[str, object]]:
    """Summaries as plain dicts (for JSON)."""
    return [asdict(s) for s in summaries]


# ----------------------------------------------------------------------------------------
# Event suppression


def oms_active_events(events: np.ndarray, oms: np.ndarray) -> int:
    """How many of ``events`` fall on pixels where the OMS map is active.

    >>> from wander_env.events import make_events
    >>> o = np.zeros((2, 3), bool); o[1, 2] = True
    >>> oms_active_events(make_events([2, 2, 0], [1, 1, 0], [0, 1, 2], [1, 0, 1]), o)
    2
    """
    if len(events) == 0:
        return 0
    return int(np.count_nonzero(np.asarray(oms, dtype=bool)[events["y"], events["x"]]))


@dataclass(frozen=True, eq=False)
class SuppressionResult:
    """Events into the OMS stage and OMS-active events out, per window."""

    window_us: int
    events_in: np.ndarray
    events_out: np.ndarray

    @property
    def n_windows(self) -> int:
        return len(self.events_in)

    @property
    def total_in(self) -> int:
        return int(np.sum(self.events_in))

    @property
    def total_out(self) -> int:
        return int(np.sum(self.events_out))

    @property
    def fraction_suppressed(self) -> float:
        """``1 − out / in`` over the whole recording (the paper's 85.16 %)."""
        return 1.0 - self.total_out / self.total_in if self.total_in else math.nan

    def per_window(self, ddof: int = 0) -> dict[str, float]:
        """Mean ± std of events in / out per window (the paper's Table layout)."""
        mi, si = mean_std(self.events_in.astype(float), ddof)
        mo, so = mean_std(self.events_out.astype(float), ddof)
        return {
            "events_in_mean": mi,
            "events_in_std": si,
            "events_out_mean": mo,
            "events_out_std": so,
        }


def event_suppression(
    events: np.ndarray,
    sensor_size: SensorSize,
    model: BenchmarkModel,
    window_us: int = 2000,
    progress: ProgressFn | None = None,
    name: str = "recording",
) -> SuppressionResult:
    """Stream a recording in ``window_us`` steps; count events in and OMS-active out.

    Meant for a recording with no independently moving object, where every event the
    OMS stage keeps is a false positive. Windows tile ``[t_first, t_last]``; each
    window's events are counted as *out* when they fall on a pixel active in the OMS
    map the model returns for that window.
    """
    if window_us <= 0:
        raise ValueError(f"window_us must be > 0, got {window_us}")
    check_sorted(events, name)
    hw = (int(sensor_size[1]), int(sensor_size[0]))
    model.reset()
    if len(events) == 0:
        return SuppressionResult(window_us, np.zeros(0, np.int64), np.zeros(0, np.int64))
    t0, t_last = int(events["t"][0]), int(events["t"][-1])
    n = (t_last - t0) // window_us + 1
    ins = np.zeros(n, np.int64)
    outs = np.zeros(n, np.int64)
    for k in range(n):
        a = t0 + k * window_us
        wev = time_window(events, a, a + window_us)
        maps = _check_maps(
            model.process(to_frame(wev, sensor_size), window_us / 1e6), hw, f"{name} window {k}"
        )
        ins[k] = len(wev)
        outs[k] = oms_active_events(wev, maps.oms)
        if progress is not None:
            progress(ProgressEvent(name, "", 0, 1, k, n))
    return SuppressionResult(window_us, ins, outs)


def render_suppression_markdown(result: SuppressionResult, name: str, ddof: int = 0) -> str:
    """A Markdown table of :func:`event_suppression` beside the paper's Table."""
    pw = result.per_window(ddof)
    ref = PAPER_SUPPRESSION
    return "\n".join(
        [
            f"# Event suppression: {name}",
            "",
            f"Counts per {result.window_us / 1000:g} ms window, mean ± std over "
            f"{result.n_windows} windows (ddof={ddof}); suppressed = 1 − out/in over the "
            "recording.",
            "",
            "| | events in | OMS events out | suppressed |",
            "|---|---:|---:|---:|",
            f"| ours | {pw['events_in_mean']:.2f} ± {pw['events_in_std']:.2f} "
            f"| {pw['events_out_mean']:.2f} ± {pw['events_out_std']:.2f} "
            f"| {100 * result.fraction_suppressed:.2f} % |",
            f"| paper (10 trials, 2 ms) | {ref['events_in_mean']} ± {ref['events_in_std']} "
            f"| {ref['events_out_mean']} ± {ref['events_out_std']} | {ref['suppressed_pct']} % |",
            "",
        ]
    )
