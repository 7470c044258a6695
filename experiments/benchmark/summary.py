"""Summaries of the benchmark's window rows
(:class:`~experiments.benchmark.protocol.WindowRow`), the paper's figures beside them, and
the files they go to.

Statistics (:func:`summarize`): per sequence, means over its scored windows (std over
windows); per subset and over all, mean ± std **over sequences** of the per-sequence
means by default — the paper's Table of EVIMO accuracies (e.g. Box 73.4 % ± 21.61 over
its 6 sequences) and its LLE-VOS figure (53.3 % ± 25.56 over sub-datasets) are spreads
across sequences — or pooled over windows (``std_over="windows"``). Population standard
deviations (``ddof=0``, NumPy's default) unless asked otherwise.

Output: one tidy row per window (:func:`write_rows_csv`), one per summary
(:func:`write_summary_csv`) and a Markdown summary with the paper's figures beside ours
(:func:`render_markdown`).
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from dataclasses import asdict, dataclass, fields
from pathlib import Path

from experiments.analysis.stats import mean_std
from experiments.benchmark.protocol import (
    NOTE_EMPTY_MASK,
    NOTE_MASK_FIT,
    NOTE_NO_EVENTS,
    NOTE_NO_POINT,
    NOTE_OMS_EMPTY,
    NOTE_OUTSIDE,
    ROW_COLUMNS,
    WindowRow,
)
from experiments.runs.tables import write_csv

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


SUMMARY_COLUMNS = tuple(f.name for f in fields(Summary))


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


#: What a subset's and the overall std is over: sequences (the paper's tables) or windows.
STD_OVER = ("sequences", "windows")


def check_std_over(std_over: str) -> str:
    """``std_over`` if it is one of :data:`STD_OVER`, else a ``ValueError`` naming it."""
    if std_over not in STD_OVER:
        raise ValueError(f"std_over must be 'sequences' or 'windows', got {std_over!r}")
    return std_over


def summarize(
    rows: Sequence[WindowRow], std_over: str = "sequences", ddof: int = 0
) -> list[Summary]:
    """Per-sequence, per-subset and overall summaries, for each dataset in ``rows``.

    Order: for each dataset, its sequences (in order of appearance), then its subsets
    (sorted), then ``subset="all"``.
    """
    check_std_over(std_over)
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


def write_rows_csv(rows: Sequence[WindowRow], path: str | os.PathLike) -> Path:
    """The tidy per-window table, columns :data:`ROW_COLUMNS`
    (:func:`experiments.runs.tables.write_csv`: NaN as empty cells)."""
    return write_csv([asdict(r) for r in rows], Path(path), columns=ROW_COLUMNS)


def write_summary_csv(summaries: Sequence[Summary], path: str | os.PathLike) -> Path:
    """The summaries, one row each, columns :data:`SUMMARY_COLUMNS`
    (:func:`experiments.runs.tables.write_csv`: NaN as empty cells; the header without
    summaries)."""
    return write_csv(summary_dicts(summaries), Path(path), columns=SUMMARY_COLUMNS)


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


def summary_dicts(summaries: Sequence[Summary]) -> list[dict[str, object]]:
    """Summaries as plain dicts (for JSON)."""
    return [asdict(s) for s in summaries]
