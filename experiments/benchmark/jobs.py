"""The ``wander benchmark`` jobs, one function a command.

Each scores its recordings with the benchmark model and writes its results folder ``out``
(``results.csv``, ``results.md``, ``run.json``; ``maps_vs_masks.png`` where windows were
scored, ``suppression.csv`` where :func:`score_events` measures suppression too), and
returns the results' Markdown:

- :func:`score_evimo`, :func:`score_llevos`: a dataset's sequences (:func:`score_dataset`);
- :func:`score_events`: one event file and a folder of masks;
- :func:`measure_suppression`: the events sOMS suppresses on recordings without masks.

The command line (:mod:`experiments.cli.benchmark`) parses the flags, builds the model's
config, makes the folder and shows what a job reports to its :class:`BenchmarkProgress`.
Bad input raises ``ValueError`` or ``OSError`` naming the file, before the model
allocates its maps.
"""

from __future__ import annotations

import itertools
import time
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

from experiments.benchmark.runner import (
    event_files,
    limit_windows,
    run_sequences,
    run_suppression,
    suppression_markdown,
    suppression_record,
    write_benchmark_outputs,
    write_suppression_csv,
    write_suppression_outputs,
)

if TYPE_CHECKING:  # numpy, scipy and torch load when a job runs
    from experiments.benchmark.model import ModelConfig
    from experiments.benchmark.protocol import ProgressEvent

__all__ = [
    "BenchmarkProgress",
    "measure_suppression",
    "score_dataset",
    "score_events",
    "score_evimo",
    "score_llevos",
]

#: ``load(max_sequences)``: a dataset's sequences (loaded as they are read) and their count.
SequenceLoader = Callable[[int | None], tuple[Iterable[Any], int]]


class BenchmarkProgress(Protocol):
    """What a job reports as it goes (the command line's progress bars)."""

    def sequences(self, what: str, n_sequences: int | None) -> None:
        """A run over ``n_sequences`` sequences (``what``) begins."""

    def window(self, event: ProgressEvent) -> None:
        """A window of a sequence was scored (or passed over)."""

    def sequence_done(self) -> None:
        """A sequence was scored."""

    def recording(self, name: str, event: ProgressEvent) -> None:
        """A step of recording ``name`` went through the suppression model."""


def _model_record(model: ModelConfig) -> dict[str, Any]:
    """run.json's record of the model: the agent's block (the step ``dt`` is each
    sequence's, ``model_dt_s``)."""
    from wander_env.config import to_plain

    return {"agent": to_plain(model.agent)}


def _score(
    sequences: Iterable[Any],
    n_sequences: int | None,
    what: str,
    model: ModelConfig,
    max_windows: int | None,
    progress: BenchmarkProgress | None,
    mask_offset: tuple[int, int] | None = None,
) -> tuple[list[Any], dict[str, list[str]], dict[str, float], Any]:
    """:func:`~experiments.benchmark.runner.run_sequences` reporting to ``progress``;
    returns its rows, notes and model steps, and the windows kept for the figure."""
    from experiments.benchmark.figure import WindowSampler
    from experiments.benchmark.protocol import ProtocolConfig

    sampler = WindowSampler()
    if progress is not None:
        progress.sequences(what, n_sequences)
    rows, notes, dts = run_sequences(
        sequences,
        n_sequences,
        model,
        ProtocolConfig(mask_offset_xy=mask_offset),
        max_windows,
        sampler,
        None if progress is None else progress.window,
        None if progress is None else progress.sequence_done,
    )
    return rows, notes, dts, sampler.views


def _suppression(
    recordings: list[tuple[str, Any, tuple[int, int, int]]],
    window_us: int,
    model: ModelConfig,
    progress: BenchmarkProgress | None,
) -> list[Any]:
    callback = None if progress is None else progress.recording
    return run_suppression(recordings, window_us, model, callback)


def score_dataset(
    out: Path,
    model: ModelConfig,
    dataset: str,
    label: str,
    path: Path,
    load: SequenceLoader,
    options: dict[str, Any],
    *,
    max_sequences: int | None = None,
    max_windows: int | None = None,
    std_over: str = "sequences",
    progress: BenchmarkProgress | None = None,
) -> str:
    """Score a dataset's sequences (``load``, at most ``max_sequences``, each at most
    ``max_windows`` windows) into ``out``; ``options`` are the dataset's own settings for
    ``run.json``; ``std_over``: the subsets' std over ``"sequences"`` (the paper's tables)
    or pooled ``"windows"``."""
    from experiments.benchmark.summary import check_std_over

    check_std_over(std_over)  # before an hour of scoring
    started = time.monotonic()
    config = {
        "dataset": dataset,
        "path": str(path),
        **options,
        "max_sequences": max_sequences,
        "max_windows": max_windows,
        "std_over": std_over,
        **_model_record(model),
    }
    sequences, n = load(max_sequences)
    rows, notes, dts, views = _score(sequences, n, label, model, max_windows, progress)
    return write_benchmark_outputs(
        out,
        rows,
        dataset,
        f"Benchmark: {label}",
        f"wander benchmark {dataset}",
        {**config, "model_dt_s": dts},
        notes,
        extra_record={"elapsed_s": time.monotonic() - started},
        std_over=std_over,
        views=views,
    )


def score_evimo(
    out: Path,
    model: ModelConfig,
    path: Path,
    *,
    subsets: list[str] | None = None,
    window_mode: str = "preceding",
    window_us: int | None = None,
    **shared: Any,
) -> str:
    """EVIMO / EVIMO2 sequences below ``path`` (only ``subsets`` where given), each mask's
    window ``window_mode`` of it and ``window_us`` long (default: the median mask spacing);
    ``shared``: :func:`score_dataset`'s keywords."""
    from experiments.benchmark.datasets.evimo import find_evimo_sequences, load_evimo_sequence

    def load(max_sequences: int | None) -> tuple[Iterable[Any], int]:
        sources = find_evimo_sequences(path, subsets)
        if max_sequences is not None:
            sources = sources[:max_sequences]
        return (load_evimo_sequence(s, window_mode, window_us) for s in sources), len(sources)

    options = {"subsets": subsets, "window_mode": window_mode, "window_us": window_us}
    return score_dataset(out, model, "evimo", "EVIMO", path, load, options, **shared)


def score_llevos(
    out: Path,
    model: ModelConfig,
    path: Path,
    *,
    sequences: list[str] | None = None,
    time_unit: str = "us",
    npy_columns: str = "xytp",
    **shared: Any,
) -> str:
    """LLE-VOS sequences below ``path`` (only ``sequences`` where given), their event
    files' times in ``time_unit`` and ``(N, 4)`` columns ``npy_columns``; ``shared``:
    :func:`score_dataset`'s keywords."""
    from experiments.benchmark.datasets.llevos import (
        LLEVOSConfig,
        find_llevos_root,
        list_llevos_sequences,
        load_llevos,
    )

    def load(max_sequences: int | None) -> tuple[Iterable[Any], int]:
        cfg = LLEVOSConfig(time_unit=time_unit, npy_columns=npy_columns)
        names = sequences or list_llevos_sequences(find_llevos_root(path))
        n = len(names) if max_sequences is None else min(len(names), max_sequences)
        return itertools.islice(load_llevos(path, sequences, cfg), n), n

    options = {"sequences": sequences, "time_unit": time_unit, "npy_columns": npy_columns}
    return score_dataset(out, model, "llevos", "LLE-VOS", path, load, options, **shared)


def score_events(
    out: Path,
    model: ModelConfig,
    file: Path,
    masks: Path,
    *,
    name: str,
    sensor_size: tuple[int, int, int] | None = None,
    window_us: int | None = None,
    mask_offset: tuple[int, int] | None = None,
    max_windows: int | None = None,
    suppression: bool = True,
    progress: BenchmarkProgress | None = None,
) -> str:
    """One event file against a folder of masks (``NNNNNN_T.png``, each the window up to
    ``T``; ``window_us`` long, default the smallest step of the names), placed unscaled at
    ``mask_offset`` where given (else resized), the sequence called ``name``; with
    ``suppression``, the fraction of events sOMS suppresses over the masks' windows too
    (``suppression.csv``)."""
    from experiments.benchmark.datasets.generic import load_generic
    from wander_env.events import time_window

    started = time.monotonic()
    seq = load_generic(file, masks, sensor_size, window_us, name=name, subset="events")
    seq = limit_windows(seq, max_windows)
    rows, notes, dts, views = _score([seq], 1, "events", model, None, progress, mask_offset)
    extra_md, extra_rec = "", {}
    if suppression and seq.windows:
        win = round(dts[f"{seq.subset}/{seq.name}"] * 1e6)
        ev = seq.events
        if max_windows is not None:
            ev = time_window(ev, int(ev["t"][0]) if len(ev) else 0, seq.windows[-1].t_end_us)
        (res,) = _suppression([(seq.name, ev, seq.sensor_size)], win, model, progress)
        t0 = int(ev["t"][0]) if len(ev) else 0
        write_suppression_csv(out / "suppression.csv", [(seq.name, res, t0)])
        extra_md = suppression_markdown([seq.name], [res])
        extra_rec = {"suppression": suppression_record([seq.name], [res])}
    config = {
        "dataset": "generic",
        "events": str(file),
        "masks": str(masks),
        "name": name,
        "sensor": list(seq.sensor_size),
        "window_us": window_us,
        "mask_offset_xy": mask_offset,
        "max_windows": max_windows,
        **_model_record(model),
        "suppression": suppression,
        "model_dt_s": dts,
    }
    return write_benchmark_outputs(
        out,
        rows,
        "generic",
        f"Benchmark: {name} ({file.name} + {masks.name}/)",
        "wander benchmark events",
        config,
        notes,
        extra_markdown=extra_md,
        extra_record={**extra_rec, "elapsed_s": time.monotonic() - started},
        views=views,
    )


def measure_suppression(
    out: Path,
    model: ModelConfig,
    paths: list[Path],
    *,
    sensor_size: tuple[int, int, int] | None = None,
    window_us: int = 2000,
    max_windows: int | None = None,
    progress: BenchmarkProgress | None = None,
) -> str:
    """The fraction of events sOMS suppresses, per step of ``window_us``, on the event
    files of ``paths`` (files, or folders whose event files are all read), at most
    ``max_windows`` steps of each."""
    from wander_env.events import time_window
    from wander_env.events.checks import check_sensor_area
    from wander_env.events.io import read_events

    started = time.monotonic()
    notes: dict[str, list[str]] = {}
    files = event_files(paths)
    recordings = []
    for f in files:
        rec = read_events(f, sensor_size)
        check_sensor_area(f, rec.sensor_size)  # before the next file is read
        ev = rec.events
        notes[f.stem] = []
        if rec.metadata.get("sensor_size_inferred"):
            notes[f.stem].append(
                f"sensor size {rec.sensor_size[0]}x{rec.sensor_size[1]} inferred from the "
                "largest coordinates (give --sensor WxH)"
            )
        if max_windows is not None and len(ev):
            t0 = int(ev["t"][0])
            ev = time_window(ev, t0, t0 + max_windows * window_us)
            notes[f.stem].append(f"limited to the first {max_windows} windows")
        recordings.append((f.stem, ev, rec.sensor_size))
    results = _suppression(recordings, window_us, model, progress)
    config = {
        "paths": [str(p) for p in paths],
        "files": [str(f) for f in files],
        "sensor": {n: list(s) for n, _, s in recordings},
        "window_us": window_us,
        "max_windows": max_windows,
        **_model_record(model),
    }
    return write_suppression_outputs(
        out, recordings, results, config, notes, elapsed_s=time.monotonic() - started
    )
