"""The real-data benchmark's runner: stream sequences through a fresh model each, score
them by the protocol and write the results folder; the same for sOMS event suppression on
recordings. The ``wander benchmark`` commands (:mod:`experiments.cli.benchmark`) parse
the options and show progress bars through the ``progress`` callbacks.

Examples:
    >>> import numpy as np
    >>> from experiments.benchmark.datasets.base import MaskWindow, SequenceData
    >>> windows = [MaskWindow(t, t + 10, np.zeros((4, 4), np.int32)) for t in (0, 10, 20)]
    >>> seq = SequenceData("d", "s", "x", (4, 4, 2), np.zeros(0), windows)
    >>> short = limit_windows(seq, 2)
    >>> len(short.windows), short.notes
    (2, ['limited to the first 2 of 3 windows'])
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Callable, Iterable, Iterator, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from experiments.runs.folder import RunFolder
from experiments.runs.provenance import run_record
from experiments.runs.tables import write_csv

if TYPE_CHECKING:  # the protocol (numpy, scipy) is imported when a run starts
    from experiments.benchmark.protocol import ProgressEvent, ProgressFn

__all__ = [
    "EVENT_SUFFIXES",
    "SUPPRESSION_COLUMNS",
    "event_files",
    "limit_windows",
    "run_sequences",
    "run_suppression",
    "suppression_markdown",
    "suppression_record",
    "write_benchmark_outputs",
    "write_suppression_csv",
    "write_suppression_outputs",
]

EVENT_SUFFIXES = (".npz", ".h5", ".hdf5", ".npy", ".aedat4", ".aedat", ".raw", ".dat", ".es")
SUPPRESSION_COLUMNS = ("recording", "window", "t_start_us", "t_end_us", "events_in", "events_out")


def limit_windows(seq: Any, max_windows: int | None) -> Any:
    """``seq`` with only its first ``max_windows`` windows (noted), or ``seq`` unchanged."""
    if max_windows is None or len(seq.windows) <= max_windows:
        return seq
    note = f"limited to the first {max_windows} of {len(seq.windows)} windows"
    return dataclasses.replace(
        seq, windows=list(seq.windows[:max_windows]), notes=[*seq.notes, note]
    )


def event_files(paths: Sequence[Path]) -> list[Path]:
    """The event files named, or found (sorted, not recursing) in the folders named."""
    found: list[Path] = []
    for p in paths:
        if p.is_dir():
            files = sorted(f for f in p.iterdir() if f.suffix.lower() in EVENT_SUFFIXES)
            if not files:
                from experiments.benchmark.datasets.base import DatasetLayoutError

                listing = sorted(f.name for f in p.iterdir())[:8]
                raise DatasetLayoutError(
                    p,
                    f"no event file in this folder (found {listing or 'nothing'})",
                    f"event files ending in {', '.join(EVENT_SUFFIXES)}",
                )
            found.extend(files)
        else:
            found.append(p)
    return found


def run_sequences(
    sequences: Iterable[Any],
    n_sequences: int | None,
    model_config: Any,
    protocol: Any,
    max_windows: int | None,
    sampler: Any = None,
    progress: ProgressFn | None = None,
    sequence_done: Callable[[], None] | None = None,
) -> tuple[list[Any], dict[str, list[str]], dict[str, float]]:
    """Stream each sequence through a fresh model (``model_config``, a
    :class:`experiments.benchmark.model.ModelConfig`) whose ``dt`` is the sequence's window.

    Returns the window rows, each sequence's notes and each sequence's model ``dt``;
    ``sampler`` (a :class:`experiments.benchmark.figure.WindowSampler`) keeps a few
    windows' maps for ``maps_vs_masks.png``; ``progress`` sees every window
    (:class:`experiments.benchmark.protocol.ProgressEvent`), ``sequence_done`` is called
    after each scored sequence. A sensor larger than
    :data:`~wander_env.events.checks.MAX_SENSOR_PIXELS` is refused before the model
    allocates its maps (:class:`~wander_env.events.checks.EventFileError`).
    """
    from experiments.benchmark.model import nominal_dt_s
    from experiments.benchmark.protocol import evaluate_sequence
    from wander_env.events.checks import check_sensor_area

    rows: list[Any] = []
    notes: dict[str, list[str]] = {}
    dts: dict[str, float] = {}
    for k, seq in enumerate(sequences):
        seq = limit_windows(seq, max_windows)
        key = f"{seq.subset}/{seq.name}"
        notes[key] = list(seq.notes)
        if not seq.windows:
            notes[key].append("no mask window: nothing scored")
            continue
        check_sensor_area(seq.source or key, seq.sensor_size)  # before the model's maps
        dt = nominal_dt_s(seq.windows)
        dts[key] = dt
        model = dataclasses.replace(model_config, dt=dt).pipeline()
        if sampler is not None:
            sampler.start_sequence(len(seq.windows))
        rows.extend(evaluate_sequence(seq, model, protocol, progress, k, n_sequences, sampler))
        if sequence_done is not None:
            sequence_done()
    return rows, notes, dts


def _notes_markdown(notes: dict[str, list[str]]) -> str:
    lines = [f"- `{k}`: {'; '.join(v)}" for k, v in notes.items() if v]
    return "\n".join(["## Loader notes", "", *lines, ""]) if lines else ""


def _config_markdown(config: dict[str, Any]) -> str:
    items = ", ".join(f"{k}={v}" for k, v in config.items())
    return f"Run: {items}.\n"


def write_benchmark_outputs(
    out: Path,
    rows: Sequence[Any],
    dataset: str,
    title: str,
    command: str,
    config: dict[str, Any],
    notes: dict[str, list[str]],
    extra_markdown: str = "",
    extra_record: dict[str, Any] | None = None,
    std_over: str = "sequences",
    views: Sequence[Any] = (),
) -> str:
    """``results.csv`` (one row per window), ``summary.csv``, ``results.md``, ``run.json``
    and, with ``views`` (sampled windows), ``maps_vs_masks.png``.

    Returns the Markdown written to ``results.md``.
    """
    from experiments.benchmark.summary import (
        render_markdown,
        summarize,
        summary_dicts,
        write_rows_csv,
        write_summary_csv,
    )

    folder = RunFolder(out)
    folder.create()
    write_rows_csv(rows, out / "results.csv")
    summaries = summarize(rows, std_over) if rows else []
    write_summary_csv(summaries, out / "summary.csv")
    md = render_markdown(summaries, dataset, title)
    md += "\n" + _config_markdown(config)
    notes_md = _notes_markdown(notes)
    if notes_md:
        md += "\n" + notes_md
    if extra_markdown:
        md += "\n" + extra_markdown
    (out / "results.md").write_text(md)
    record = run_record(command, config, seed=None)
    record["seed_note"] = "the model is deterministic (draws no random numbers)"
    record["summaries"] = summary_dicts(summaries)
    record["sequence_notes"] = notes
    record.update(extra_record or {})
    folder.write_run(record)
    if views:
        from experiments.benchmark.figure import plot_maps_vs_masks

        plot_maps_vs_masks(out / "maps_vs_masks.png", list(views), f"{title}: maps vs masks")
    return md


def _suppression_rows(name: str, result: Any, t0: int) -> Iterator[dict[str, Any]]:
    for k, (n_in, n_out) in enumerate(zip(result.events_in, result.events_out, strict=True)):
        a = t0 + k * result.window_us
        cells = (name, k, a, a + result.window_us, int(n_in), int(n_out))
        yield dict(zip(SUPPRESSION_COLUMNS, cells, strict=True))


def run_suppression(
    recordings: Sequence[tuple[str, Any, tuple[int, int, int]]],
    window_us: int,
    model_config: Any,
    progress: Callable[[str, ProgressEvent], None] | None = None,
) -> list[Any]:
    """:func:`event_suppression` on each ``(name, events, sensor)`` with a fresh model
    (``model_config`` with the step ``window_us``); ``progress(name, event)`` sees every
    window."""
    from experiments.benchmark.suppression import event_suppression
    from wander_env.events.checks import check_sensor_area

    results = []
    for name, events, sensor in recordings:
        check_sensor_area(name, sensor)  # before the model's maps
        cb = None if progress is None else functools.partial(progress, name)
        model = dataclasses.replace(model_config, dt=window_us / 1e6).pipeline()
        results.append(event_suppression(events, sensor, model, window_us, cb, name))
    return results


def suppression_markdown(names: Sequence[str], results: Sequence[Any]) -> str:
    """Per-recording tables (beside the paper's) and, for several, the pooled fraction."""
    from experiments.benchmark.suppression import render_suppression_markdown

    parts = [render_suppression_markdown(r, n) for n, r in zip(names, results, strict=True)]
    if len(results) > 1:
        t_in = sum(r.total_in for r in results)
        t_out = sum(r.total_out for r in results)
        frac = 1.0 - t_out / t_in if t_in else float("nan")
        parts.append(
            f"Pooled over {len(results)} recordings: {t_in:,} events in, {t_out:,} OMS events "
            f"out, {100 * frac:.2f} % suppressed.\n"
        )
    return "\n".join(parts)


def suppression_record(names: Sequence[str], results: Sequence[Any]) -> dict[str, Any]:
    """The suppression figures for ``run.json``."""
    return {
        n: {
            "window_us": r.window_us,
            "n_windows": r.n_windows,
            "events_in": r.total_in,
            "events_out": r.total_out,
            "fraction_suppressed": r.fraction_suppressed,
            **r.per_window(),
        }
        for n, r in zip(names, results, strict=True)
    }


def write_suppression_csv(path: Path, items: Sequence[tuple[str, Any, int]]) -> Path:
    """Per-window events in / out of each ``(name, result, t_first_us)``, columns
    :data:`SUPPRESSION_COLUMNS` (:func:`experiments.runs.tables.write_csv`)."""
    rows = [row for name, result, t0 in items for row in _suppression_rows(name, result, t0)]
    return write_csv(rows, path, columns=SUPPRESSION_COLUMNS)


def write_suppression_outputs(
    out: Path,
    recordings: Sequence[tuple[str, Any, Any]],
    results: Sequence[Any],
    config: dict[str, Any],
    notes: dict[str, list[str]],
    elapsed_s: float,
) -> str:
    """``results.csv`` (events in / out per window of each recording), ``results.md`` and
    ``run.json`` of ``wander benchmark suppression``; ``recordings`` are the
    ``(name, events, sensor)`` that gave ``results``. Returns the Markdown."""
    names = [n for n, _, _ in recordings]
    t0s = [int(ev["t"][0]) if len(ev) else 0 for _, ev, _ in recordings]
    write_suppression_csv(out / "results.csv", list(zip(names, results, t0s, strict=True)))
    md = suppression_markdown(names, results)
    md += "\n" + _config_markdown(config)
    notes_md = _notes_markdown(notes)
    if notes_md:
        md += "\n" + notes_md
    (out / "results.md").write_text(md)
    record = run_record("wander benchmark suppression", config, seed=None)
    record["seed_note"] = "the model is deterministic (draws no random numbers)"
    record["suppression"] = suppression_record(names, results)
    record["notes"] = notes
    record["elapsed_s"] = elapsed_s
    RunFolder(out).write_run(record)
    return md
