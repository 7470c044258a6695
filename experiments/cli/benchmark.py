"""``wander benchmark``: the paper's detection / segmentation benchmark on real event data.

Commands (each writes ``results.csv``, ``results.md`` and ``run.json`` to ``--out``):

- ``evimo PATH`` — EVIMO / EVIMO2 NPZ releases (:mod:`experiments.benchmark.datasets.evimo`);
- ``llevos PATH`` — LLE-VOS (:mod:`experiments.benchmark.datasets.llevos`);
- ``events FILE --masks DIR`` — any event file + a folder of ``NNNNNN_T.png`` masks
  (:mod:`experiments.benchmark.datasets.generic`), plus the sOMS event suppression on it;
- ``suppression PATH...`` — the fraction of events sOMS suppresses on recordings
  without masks (e.g. ego-motion only, where every kept event is a false positive).

The protocol is :mod:`experiments.benchmark.protocol`; the model is
:class:`agents.pipeline.SaliencyPipeline` (sOMS → proto-object saliency),
one step per dataset window. Registered in ``experiments/cli/main.py`` as
``app.add_typer(benchmark_app, name="benchmark")``.
"""

from __future__ import annotations

import itertools
import time
from collections.abc import Callable, Iterable, Sequence
from contextlib import AbstractContextManager, nullcontext
from pathlib import Path
from typing import Annotated, Any

import typer

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
from experiments.cli.console import progress_bars
from experiments.cli.errors import fail
from experiments.cli.options import (
    AgentAlphaOpt,
    ForceOpt,
    RunDirOpt,
    SetOpt,
    StreamlinedOpt,
    command_config,
    option,
    resolve_out,
    with_options,
)
from experiments.runs.folder import RunFolder

app = typer.Typer(
    help="Benchmarks on real event datasets: sOMS maps against masks (IoU, precision, SSIM), "
    "saliency argmax hit rate (8x8 box), sOMS event suppression.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)


# ----------------------------------------------------------------------------------------
# Small pure helpers


def parse_sensor(text: str) -> tuple[int, int, int]:
    """``"WxH"`` → sensor size ``(W, H, 2)``.

    >>> parse_sensor("240x180")
    (240, 180, 2)
    """
    parts = text.lower().replace("×", "x").split("x")
    try:
        w, h = (int(v) for v in parts)
    except ValueError:
        raise typer.BadParameter(f"--sensor {text!r}: expected WxH, e.g. 240x180") from None
    if w <= 0 or h <= 0:
        raise typer.BadParameter(f"--sensor {text!r}: width and height must be > 0")
    return w, h, 2


def parse_offset(text: str) -> tuple[int, int]:
    """``"X,Y"`` → ``(x, y)`` pixel offset of the masks inside the sensor.

    >>> parse_offset("25,0")
    (25, 0)
    """
    try:
        x, y = (int(v) for v in text.split(","))
    except ValueError:
        raise typer.BadParameter(f"--mask-offset {text!r}: expected X,Y, e.g. 25,0") from None
    return x, y


def default_name(path: Path) -> str:
    """A run name for an event file: its stem, or its folder's name for ``events*`` files.

    >>> default_name(Path("realdata/eed_ball_net/events_txyp.npy"))
    'eed_ball_net'
    """
    if path.stem.lower().startswith("events"):
        return path.resolve().parent.name or path.stem
    return path.stem


# ----------------------------------------------------------------------------------------
# Running (with progress bars; the runner is experiments.benchmark.runner)


class _Bars:
    """Rich progress bars: one for the sequences, one per sequence's windows."""

    def __init__(self, progress: Any, what: str, n_sequences: int | None) -> None:
        self.progress = progress
        self.outer = progress.add_task(what, total=n_sequences)
        self.tasks: dict[int, Any] = {}

    def __call__(self, ev: Any) -> None:
        task = self.tasks.get(ev.sequence_index)
        if task is None:
            task = self.progress.add_task(f"  {ev.subset}/{ev.sequence}", total=ev.n_windows)
            self.tasks[ev.sequence_index] = task
        self.progress.update(task, completed=ev.window + 1)

    def sequence_done(self) -> None:
        self.progress.advance(self.outer)


def _run_sequences(
    sequences: Iterable[Any],
    n_sequences: int | None,
    what: str,
    model_config: Any,
    protocol: Any,
    max_windows: int | None,
    show_progress: bool,
    sampler: Any = None,
) -> tuple[list[Any], dict[str, list[str]], dict[str, float]]:
    """:func:`~experiments.benchmark.runner.run_sequences` with progress bars."""
    with _progress_context(show_progress) as progress:
        bars = _Bars(progress, what, n_sequences) if progress is not None else None
        return run_sequences(
            sequences,
            n_sequences,
            model_config,
            protocol,
            max_windows,
            sampler,
            bars,
            None if bars is None else bars.sequence_done,
        )


def _run_suppression(
    recordings: Sequence[tuple[str, Any, tuple[int, int, int]]],
    window_us: int,
    model_config: Any,
    show_progress: bool,
) -> list[Any]:
    """:func:`~experiments.benchmark.runner.run_suppression` with a bar per recording."""
    with _progress_context(show_progress) as progress:
        tasks: dict[str, Any] = {}

        def tick(name: str, ev: Any) -> None:
            if name not in tasks:
                tasks[name] = progress.add_task(f"suppression {name}", total=None)
            progress.update(tasks[name], completed=ev.window + 1, total=ev.n_windows)

        callback = tick if progress is not None else None
        return run_suppression(recordings, window_us, model_config, callback)


def _progress_context(show: bool) -> AbstractContextManager[Any]:
    return progress_bars() if show else nullcontext(None)


def _finish(folder: RunFolder, md: str, started: float) -> None:
    """Print the results and the files written (named where the folder ends)."""
    typer.echo(md)
    out, maps = folder.final, (folder.path / "maps_vs_masks.png").is_file()
    typer.echo(
        f"wrote {out}/results.csv, {out}/results.md, {out}/run.json"
        + (f", {out}/maps_vs_masks.png" if maps else "")
        + " "
        f"({time.monotonic() - started:.1f} s)"
    )


# ----------------------------------------------------------------------------------------
# Options shared by the commands

MaxWindowsOpt = Annotated[
    int | None,
    typer.Option(
        min=1, help="Score only the first N windows of each sequence (a quick run; noted)."
    ),
]
MaxSequencesOpt = Annotated[int | None, typer.Option(min=1, help="Only the first N sequences.")]
ThreadsOpt = Annotated[
    int | None, typer.Option("--threads", min=1, help="torch CPU threads (default: torch's).")
]
ProgressOpt = Annotated[bool, typer.Option("--progress/--no-progress", help="Progress bars.")]
StdOverOpt = Annotated[
    str,
    typer.Option(
        "--std-over",
        help="Subset/overall std over 'sequences' (the paper's tables) or pooled 'windows'.",
    ),
]


# The flags of the benchmark model (every command), of the run (every command) and of the
# dataset commands (evimo, llevos; in the order run.json lists them, threads and
# progress aside).
MAX_WINDOWS = option("max_windows", MaxWindowsOpt, None)
MODEL_OPTIONS = (
    option("streamlined", StreamlinedOpt),
    option("alpha", AgentAlphaOpt),
    option("set_", SetOpt),
)
RUN_OPTIONS = (
    option("threads", ThreadsOpt, None),
    option("progress", ProgressOpt, True),
    option("force", ForceOpt, False),
)
DATASET_OPTIONS = (
    option("max_sequences", MaxSequencesOpt, None),
    MAX_WINDOWS,
    *MODEL_OPTIONS,
    option("std_over", StdOverOpt, "sequences"),
)


def _model_config(ctx: typer.Context) -> Any:
    """The benchmark model's :class:`ModelConfig` of the command line: its defaults (the
    paper's pipeline) <- ``--streamlined``, ``--alpha`` <- ``--set`` (e.g.
    ``agent.soms.alpha=0.5``), through :func:`experiments.cli.options.command_config`."""
    from experiments.benchmark.model import ModelConfig

    return command_config(ctx, ModelConfig)


def _model_record(model: Any) -> dict[str, Any]:
    """run.json's record of the model: the agent's block (the step ``dt`` is each
    sequence's, ``model_dt_s``)."""
    from wander_env.config import to_plain

    return {"agent": to_plain(model.agent)}


def _begin(
    ctx: typer.Context, out: Path | None, name: str, shared: dict[str, Any]
) -> tuple[Any, RunFolder]:
    """A command's model config (:func:`_model_config`: a bad flag stops the command
    before anything is written), torch's CPU threads (``--threads``) and its results
    folder ``name`` (``--out``, ``--force``)."""
    model = _model_config(ctx)
    if shared["threads"] is not None:
        import torch

        torch.set_num_threads(shared["threads"])
    return model, resolve_out(ctx, out, name, shared["force"])


def _check_std_over(std_over: str) -> None:
    if std_over not in ("sequences", "windows"):
        raise typer.BadParameter(f"--std-over must be 'sequences' or 'windows', got {std_over!r}")


def _score_dataset(
    ctx: typer.Context,
    label: str,
    dataset: str,
    load: Callable[[int | None], tuple[Iterable[Any], int]],
    flags: dict[str, Any],
    options: dict[str, Any],
) -> None:
    """Score a dataset's sequences with the benchmark model and write its results folder.

    ``flags`` are the command's (``path``, ``out`` and the shared :data:`DATASET_OPTIONS`
    and :data:`RUN_OPTIONS`); ``options`` its own, for
    ``run.json``; ``load(max_sequences)`` finds the sequences and counts them.
    """
    from experiments.benchmark.figure import WindowSampler
    from experiments.benchmark.protocol import ProtocolConfig

    std_over, max_windows, progress = flags["std_over"], flags["max_windows"], flags["progress"]
    _check_std_over(std_over)
    started = time.monotonic()
    model, folder = _begin(ctx, flags["out"], f"benchmark-{dataset}", flags)
    out = folder.path
    config = {"dataset": dataset, "path": str(flags["path"]), **options}
    config.update({p.name: flags[p.name] for p in DATASET_OPTIONS if p not in MODEL_OPTIONS})
    config.update(_model_record(model))
    sampler = WindowSampler()
    try:
        seqs, n = load(flags["max_sequences"])
        rows, notes, dts = _run_sequences(
            seqs, n, label, model, ProtocolConfig(), max_windows, progress, sampler
        )
    except (ValueError, OSError) as err:
        raise fail(err, ctx) from None
    md = write_benchmark_outputs(
        out,
        rows,
        dataset,
        f"Benchmark: {label}",
        f"wander benchmark {dataset}",
        {**config, "model_dt_s": dts},
        notes,
        extra_record={"elapsed_s": time.monotonic() - started},
        std_over=std_over,
        views=sampler.views,
    )
    _finish(folder, md, started)


# ----------------------------------------------------------------------------------------
# Commands


@app.command("evimo")
@with_options(DATASET_OPTIONS, RUN_OPTIONS)
def evimo(
    ctx: typer.Context,
    path: Annotated[
        Path,
        typer.Argument(
            help="EVIMO root: PATH/<subset>/.../<sequence>.npz (EVIMO1, subsets box, fast, "
            "floor, table, tabletop, wall) and/or EVIMO2v2 sequence folders; or one .npz."
        ),
    ],
    out: RunDirOpt = None,
    subset: Annotated[
        list[str] | None, typer.Option("--subset", help="Only these subsets (repeatable).")
    ] = None,
    window_mode: Annotated[
        str,
        typer.Option(help="Mask window around each mask time: preceding, following, centered."),
    ] = "preceding",
    window_us: Annotated[
        int | None,
        typer.Option(min=1, help="Window length in µs (default: median mask spacing)."),
    ] = None,
    **shared: Any,
) -> None:
    """EVIMO: per-subset accuracy, IoU, precision, SSIM beside the paper's Table."""
    from experiments.benchmark.datasets.evimo import find_evimo_sequences, load_evimo_sequence

    def load(max_sequences: int | None) -> tuple[Iterable[Any], int]:
        sources = find_evimo_sequences(path, subset)
        if max_sequences is not None:
            sources = sources[:max_sequences]
        return (load_evimo_sequence(s, window_mode, window_us) for s in sources), len(sources)

    options = {"subsets": subset, "window_mode": window_mode, "window_us": window_us}
    _score_dataset(ctx, "EVIMO", "evimo", load, {"path": path, "out": out, **shared}, options)


@app.command("llevos")
@with_options(DATASET_OPTIONS, RUN_OPTIONS)
def llevos(
    ctx: typer.Context,
    path: Annotated[
        Path,
        typer.Argument(
            help="LLE-VOS root holding Annotations/<seq>/<frame>.png and "
            "Lowlight_event/<seq>/<frame>.npz|.npy (or one folder above it)."
        ),
    ],
    out: RunDirOpt = None,
    sequence: Annotated[
        list[str] | None, typer.Option("--sequence", help="Only these sequences (repeatable).")
    ] = None,
    time_unit: Annotated[str, typer.Option(help="Unit of t in the event files.")] = "us",
    npy_columns: Annotated[str, typer.Option(help="Column order of (N, 4) event arrays.")] = "xytp",
    **shared: Any,
) -> None:
    """LLE-VOS: accuracy mean ± std over sequences beside the paper's 53.3 % ± 25.56."""
    from experiments.benchmark.datasets.llevos import (
        LLEVOSConfig,
        find_llevos_root,
        list_llevos_sequences,
        load_llevos,
    )

    def load(max_sequences: int | None) -> tuple[Iterable[Any], int]:
        cfg = LLEVOSConfig(time_unit=time_unit, npy_columns=npy_columns)
        names = sequence or list_llevos_sequences(find_llevos_root(path))
        n = len(names) if max_sequences is None else min(len(names), max_sequences)
        return itertools.islice(load_llevos(path, sequence, cfg), n), n

    options = {"sequences": sequence, "time_unit": time_unit, "npy_columns": npy_columns}
    _score_dataset(ctx, "LLE-VOS", "llevos", load, {"path": path, "out": out, **shared}, options)


@app.command("events")
@with_options((MAX_WINDOWS, *MODEL_OPTIONS), RUN_OPTIONS)
def events(
    ctx: typer.Context,
    file: Annotated[
        Path, typer.Argument(help="Event file: .npz, .h5, .npy (x, y, t µs, p), .aedat4, .aedat.")
    ],
    masks: Annotated[
        Path,
        typer.Option(
            "--masks",
            help="Folder of per-window masks NNNNNN_T.png (T = window end, µs); "
            "mask k covers T - window <= t < T.",
        ),
    ],
    out: RunDirOpt = None,
    name: Annotated[
        str | None,
        typer.Option(help="Sequence name (default: file stem, or the folder for events*)."),
    ] = None,
    sensor: Annotated[
        str | None,
        typer.Option(help="Sensor WxH (default: the file's; for a bare .npy the masks')."),
    ] = None,
    window_us: Annotated[
        int | None,
        typer.Option(min=1, help="Mask window in µs (default: smallest step of the names)."),
    ] = None,
    mask_offset: Annotated[
        str | None,
        typer.Option(help="X,Y: place masks unscaled at this offset (default: resize)."),
    ] = None,
    suppression: Annotated[
        bool,
        typer.Option(
            "--suppression/--no-suppression",
            help="Also measure the fraction of events sOMS suppresses (windows of the masks).",
        ),
    ] = True,
    **shared: Any,
) -> None:
    """Any event file + a mask folder: hit rate, IoU, precision, SSIM, sOMS suppression."""
    from experiments.benchmark.datasets.generic import load_generic
    from experiments.benchmark.figure import WindowSampler
    from experiments.benchmark.protocol import ProtocolConfig
    from wander_env.events import time_window

    max_windows, progress = shared["max_windows"], shared["progress"]
    started = time.monotonic()
    sensor_size = parse_sensor(sensor) if sensor else None
    offset = parse_offset(mask_offset) if mask_offset else None
    seq_name = name or default_name(file)
    model, folder = _begin(ctx, out, f"benchmark-events-{seq_name}", shared)
    out = folder.path
    try:
        seq = load_generic(file, masks, sensor_size, window_us, name=seq_name, subset="events")
        seq = limit_windows(seq, max_windows)
        sampler = WindowSampler()
        rows, notes, dts = _run_sequences(
            [seq],
            1,
            "events",
            model,
            ProtocolConfig(mask_offset_xy=offset),
            None,
            progress,
            sampler,
        )
        extra_md, extra_rec = "", {}
        if suppression and seq.windows:
            win = round(dts[f"{seq.subset}/{seq.name}"] * 1e6)
            ev = seq.events
            if max_windows is not None:
                ev = time_window(ev, int(ev["t"][0]) if len(ev) else 0, seq.windows[-1].t_end_us)
            (res,) = _run_suppression([(seq.name, ev, seq.sensor_size)], win, model, progress)
            t0 = int(ev["t"][0]) if len(ev) else 0
            write_suppression_csv(out / "suppression.csv", [(seq.name, res, t0)])
            extra_md = suppression_markdown([seq.name], [res])
            extra_rec = {"suppression": suppression_record([seq.name], [res])}
    except (ValueError, OSError) as err:
        raise fail(err, ctx) from None
    config = {
        "dataset": "generic",
        "events": str(file),
        "masks": str(masks),
        "name": seq_name,
        "sensor": list(seq.sensor_size),
        "window_us": window_us,
        "mask_offset_xy": offset,
        "max_windows": max_windows,
        **_model_record(model),
        "suppression": suppression,
        "model_dt_s": dts,
    }
    md = write_benchmark_outputs(
        out,
        rows,
        "generic",
        f"Benchmark: {seq_name} ({file.name} + {masks.name}/)",
        "wander benchmark events",
        config,
        notes,
        extra_markdown=extra_md,
        extra_record={**extra_rec, "elapsed_s": time.monotonic() - started},
        views=sampler.views,
    )
    _finish(folder, md, started)


@app.command("suppression")
@with_options(MODEL_OPTIONS, RUN_OPTIONS)
def suppression(
    ctx: typer.Context,
    paths: Annotated[
        list[Path],
        typer.Argument(help="Event files, or folders whose event files are all read."),
    ],
    out: RunDirOpt = None,
    sensor: Annotated[
        str | None,
        typer.Option(help="Sensor WxH (default: the file's; a bare .npy infers it)."),
    ] = None,
    window_us: Annotated[
        int, typer.Option(min=1, help="Step length in µs (the paper counts per 2 ms).")
    ] = 2000,
    max_windows: Annotated[
        int | None,
        typer.Option(min=1, help="Only the first N steps of each."),
    ] = None,
    **shared: Any,
) -> None:
    """Fraction of events sOMS suppresses on recordings without masks (e.g. ego-motion only)."""
    from wander_env.events import time_window
    from wander_env.events.checks import check_sensor_area
    from wander_env.events.io import read_events

    started = time.monotonic()
    sensor_size = parse_sensor(sensor) if sensor else None
    model, folder = _begin(ctx, out, "benchmark-suppression", shared)
    out = folder.path
    notes: dict[str, list[str]] = {}
    try:
        files = event_files(paths)
        recs = []
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
            recs.append((f.stem, ev, rec.sensor_size))
        results = _run_suppression(recs, window_us, model, shared["progress"])
    except (ValueError, OSError) as err:
        raise fail(err, ctx) from None
    config = {
        "paths": [str(p) for p in paths],
        "files": [str(f) for f in files],
        "sensor": {n: list(s) for n, _, s in recs},
        "window_us": window_us,
        "max_windows": max_windows,
        **_model_record(model),
    }
    md = write_suppression_outputs(
        out, recs, results, config, notes, elapsed_s=time.monotonic() - started
    )
    _finish(folder, md, started)


def main() -> None:  # pragma: no cover - ``python -m experiments.cli.benchmark``
    app()


if __name__ == "__main__":  # pragma: no cover
    main()
