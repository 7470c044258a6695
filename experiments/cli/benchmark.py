"""``wander benchmark``: the paper's detection / segmentation benchmark on real event data.

Commands (each writes ``results.csv``, ``results.md`` and ``run.json`` to ``--out``):

- ``evimo PATH`` — EVIMO / EVIMO2 NPZ releases (:mod:`experiments.benchmark.datasets.evimo`);
- ``llevos PATH`` — LLE-VOS (:mod:`experiments.benchmark.datasets.llevos`);
- ``events FILE --masks DIR`` — any event file + a folder of ``NNNNNN_T.png`` masks
  (:mod:`experiments.benchmark.datasets.generic`), plus the sOMS event suppression on it;
- ``suppression PATH...`` — the fraction of events sOMS suppresses on recordings
  without masks (e.g. ego-motion only, where every kept event is a false positive).

Each command parses its flags, builds the model's config and folder and passes the flags
by name to its job (:mod:`experiments.benchmark.jobs`), showing the job's progress as
bars. The protocol is :mod:`experiments.benchmark.protocol`; the model is
:class:`agents.pipeline.SaliencyPipeline` (sOMS → proto-object saliency), one step per
dataset window. Registered in ``experiments/cli/main.py`` as
``app.add_typer(benchmark_app, name="benchmark")``.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from contextlib import nullcontext
from pathlib import Path
from typing import Annotated, Any

import typer

from experiments.cli.checks import int_range
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
# Running (the jobs are experiments.benchmark.jobs)


class _Bars:
    """A job's progress as rich bars: one for the sequences, one per sequence's windows,
    one per recording's suppression steps."""

    def __init__(self, progress: Any) -> None:
        self.progress = progress
        self.outer: Any = None
        self.tasks: dict[Any, Any] = {}

    def sequences(self, what: str, n_sequences: int | None) -> None:
        self.outer = self.progress.add_task(what, total=n_sequences)

    def window(self, ev: Any) -> None:
        self._show(ev.sequence_index, f"  {ev.subset}/{ev.sequence}", ev)

    def sequence_done(self) -> None:
        self.progress.advance(self.outer)

    def recording(self, name: str, ev: Any) -> None:
        self._show(name, f"suppression {name}", ev)

    def _show(self, key: Any, label: str, ev: Any) -> None:
        task = self.tasks.get(key)
        if task is None:
            task = self.tasks[key] = self.progress.add_task(label, total=ev.n_windows)
        self.progress.update(task, completed=ev.window + 1, total=ev.n_windows)


class _Command:
    """A command's model config and results folder; :meth:`run` runs its job there."""

    def __init__(
        self, ctx: typer.Context, model: Any, folder: RunFolder, shared: dict[str, Any]
    ) -> None:
        self.ctx, self.model, self.folder, self.shared = ctx, model, folder, shared
        self.started = time.monotonic()

    def run(self, job: Callable[..., str], *args: Any, **flags: Any) -> None:
        """``job(folder, model, *args, progress=..., **flags)`` (progress bars with
        ``--progress``); its bad input as one line (exit 2); then its results and the
        files written."""
        folder = self.folder
        try:
            with progress_bars() if self.shared["progress"] else nullcontext(None) as bars:
                progress = None if bars is None else _Bars(bars)
                md = job(folder.path, self.model, *args, progress=progress, **flags)
        except (ValueError, OSError) as err:
            raise fail(err, self.ctx) from None
        typer.echo(md)
        out, maps = folder.final, (folder.path / "maps_vs_masks.png").is_file()
        typer.echo(
            f"wrote {out}/results.csv, {out}/results.md, {out}/run.json"
            + (f", {out}/maps_vs_masks.png" if maps else "")
            + " "
            f"({time.monotonic() - self.started:.1f} s)"
        )


# ----------------------------------------------------------------------------------------
# Options shared by the commands


def _check_std_over(value: str) -> str:
    from experiments.benchmark.summary import check_std_over

    try:
        return check_std_over(value)
    except ValueError as err:
        raise typer.BadParameter(str(err)) from None


#: The most torch CPU threads ``--threads`` may ask for (torch crashes or hangs with
#: thousands).
MAX_THREADS = 256

MaxWindowsOpt = Annotated[
    int | None,
    typer.Option(
        callback=int_range(1),
        help="Score only the first N windows of each sequence (a quick run; noted).",
    ),
]
MaxSequencesOpt = Annotated[
    int | None, typer.Option(callback=int_range(1), help="Only the first N sequences.")
]
ThreadsOpt = Annotated[
    int | None,
    typer.Option(
        "--threads",
        callback=int_range(1, MAX_THREADS),
        help=f"torch CPU threads, 1 to {MAX_THREADS} (default: torch's).",
    ),
]
ProgressOpt = Annotated[bool, typer.Option("--progress/--no-progress", help="Progress bars.")]
StdOverOpt = Annotated[
    str,
    typer.Option(
        "--std-over",
        callback=_check_std_over,
        help="Subset/overall std over 'sequences' (the paper's tables) or pooled 'windows'.",
    ),
]


# The flags of the benchmark model (every command), of the run (every command) and of the
# dataset commands (evimo, llevos).
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


def _begin(ctx: typer.Context, out: Path | None, name: str, shared: dict[str, Any]) -> _Command:
    """A command's model config (:class:`~experiments.benchmark.model.ModelConfig`'s
    defaults, the paper's pipeline, <- ``--streamlined``, ``--alpha`` <- ``--set``, e.g.
    ``agent.soms.alpha=0.5``: a bad flag stops the command before anything is written),
    torch's CPU threads (``--threads``) and its results folder ``name`` (``--out``,
    ``--force``)."""
    from experiments.benchmark.model import ModelConfig

    model = command_config(ctx, ModelConfig)
    if shared["threads"] is not None:
        import torch

        torch.set_num_threads(shared["threads"])
    return _Command(ctx, model, resolve_out(ctx, out, name, shared["force"]), shared)


def _dataset_flags(shared: dict[str, Any]) -> dict[str, Any]:
    """The shared flags of the dataset commands that their jobs pass on to
    :func:`~experiments.benchmark.jobs.score_dataset`."""
    return {k: shared[k] for k in ("max_sequences", "max_windows", "std_over")}


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
        typer.Option(
            callback=int_range(1), help="Window length in µs (default: median mask spacing)."
        ),
    ] = None,
    **shared: Any,
) -> None:
    """EVIMO: per-subset accuracy, IoU, precision, SSIM beside the paper's Table."""
    from experiments.benchmark.jobs import score_evimo

    options = {"subsets": subset, "window_mode": window_mode, "window_us": window_us}
    job = _begin(ctx, out, "benchmark-evimo", shared)
    job.run(score_evimo, path, **options, **_dataset_flags(shared))


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
    from experiments.benchmark.jobs import score_llevos

    options = {"sequences": sequence, "time_unit": time_unit, "npy_columns": npy_columns}
    job = _begin(ctx, out, "benchmark-llevos", shared)
    job.run(score_llevos, path, **options, **_dataset_flags(shared))


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
        typer.Option(
            callback=int_range(1), help="Mask window in µs (default: smallest step of the names)."
        ),
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
    from experiments.benchmark.jobs import score_events

    sensor_size = parse_sensor(sensor) if sensor else None
    offset = parse_offset(mask_offset) if mask_offset else None
    seq_name = name or default_name(file)
    _begin(ctx, out, f"benchmark-events-{seq_name}", shared).run(
        score_events,
        file,
        masks,
        name=seq_name,
        sensor_size=sensor_size,
        window_us=window_us,
        mask_offset=offset,
        max_windows=shared["max_windows"],
        suppression=suppression,
    )


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
        int,
        typer.Option(callback=int_range(1), help="Step length in µs (the paper counts per 2 ms)."),
    ] = 2000,
    max_windows: Annotated[
        int | None,
        typer.Option(callback=int_range(1), help="Only the first N steps of each."),
    ] = None,
    **shared: Any,
) -> None:
    """Fraction of events sOMS suppresses on recordings without masks (e.g. ego-motion only)."""
    from experiments.benchmark.jobs import measure_suppression

    sensor_size = parse_sensor(sensor) if sensor else None
    options = {"sensor_size": sensor_size, "window_us": window_us, "max_windows": max_windows}
    _begin(ctx, out, "benchmark-suppression", shared).run(measure_suppression, paths, **options)


def main() -> None:  # pragma: no cover - ``python -m experiments.cli.benchmark``
    app()


if __name__ == "__main__":  # pragma: no cover
    main()
