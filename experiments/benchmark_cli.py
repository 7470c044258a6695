"""``wander benchmark``: the paper's detection / segmentation benchmark on real event data.

Commands (each writes ``results.csv``, ``results.md`` and ``run.json`` to ``--out``):

- ``evimo PATH`` — EVIMO / EVIMO2 NPZ releases (:mod:`experiments.datasets.evimo`);
- ``llevos PATH`` — LLE-VOS (:mod:`experiments.datasets.llevos`);
- ``events FILE --masks DIR`` — any event file + a folder of ``NNNNNN_T.png`` masks
  (:mod:`experiments.datasets.generic`), plus the sOMS event suppression on it;
- ``suppression PATH...`` — the fraction of events sOMS suppresses on recordings
  without masks (e.g. ego-motion only, where every kept event is a false positive).

The protocol is :mod:`experiments.benchmark_protocol`; the model is
:class:`agents.pipeline.SaliencyPipeline` (sOMS → proto-object saliency),
one step per dataset window. Registered in ``wander_env/cli.py`` as
``app.add_typer(benchmark_app, name="benchmark")``.
"""

from __future__ import annotations

import csv
import dataclasses
import itertools
import time
from collections.abc import Callable, Iterable, Iterator, Sequence
from contextlib import AbstractContextManager, nullcontext
from pathlib import Path
from typing import Annotated, Any

import typer

from experiments.benchmark_figure import WindowSampler

app = typer.Typer(
    help="Benchmarks on real event datasets: sOMS maps against masks (IoU, precision, SSIM), "
    "saliency argmax hit rate (8x8 box), sOMS event suppression.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)

EVENT_SUFFIXES = (".npz", ".h5", ".hdf5", ".npy", ".aedat4", ".aedat", ".raw", ".dat", ".es")
SUPPRESSION_COLUMNS = ("recording", "window", "t_start_us", "t_end_us", "events_in", "events_out")


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


def limit_windows(seq: Any, max_windows: int | None) -> Any:
    """``seq`` with only its first ``max_windows`` windows (noted), or ``seq`` unchanged."""
    if max_windows is None or len(seq.windows) <= max_windows:
        return seq
    note = f"limited to the first {max_windows} of {len(seq.windows)} windows"
    return dataclasses.replace(
        seq, windows=list(seq.windows[:max_windows]), notes=[*seq.notes, note]
    )


def default_name(path: Path) -> str:
    """A run name for an event file: its stem, or its folder's name for ``events*`` files.

    >>> default_name(Path("realdata/eed_ball_net/events_txyp.npy"))
    'eed_ball_net'
    """
    if path.stem.lower().startswith("events"):
        return path.resolve().parent.name or path.stem
    return path.stem


def event_files(paths: Sequence[Path]) -> list[Path]:
    """The event files named, or found (sorted, not recursing) in the folders named."""
    found: list[Path] = []
    for p in paths:
        if p.is_dir():
            files = sorted(f for f in p.iterdir() if f.suffix.lower() in EVENT_SUFFIXES)
            if not files:
                from experiments.datasets.base import DatasetLayoutError

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


# ----------------------------------------------------------------------------------------
# Running


def _fail(err: BaseException) -> typer.Exit:
    """One line on stderr (``wander benchmark NAME: error: ...``) and exit code 2."""
    from typer._click.globals import get_current_context

    ctx = get_current_context(silent=True)
    where = ctx.command_path if ctx is not None else "wander benchmark"
    typer.echo(f"{where}: error: {' '.join(str(err).split())}", err=True)
    return typer.Exit(code=2)


def _set_threads(threads: int | None) -> None:
    if threads is not None:
        import torch

        torch.set_num_threads(threads)


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


def _progress_context(show: bool) -> AbstractContextManager[Any]:
    if not show:
        return nullcontext(None)
    from wander_env.cli import _progress

    return _progress()


def run_sequences(
    sequences: Iterable[Any],
    n_sequences: int | None,
    what: str,
    model_config: Any,
    protocol: Any,
    max_windows: int | None,
    show_progress: bool = True,
    sampler: Any = None,
) -> tuple[list[Any], dict[str, list[str]], dict[str, float]]:
    """Stream each sequence through a fresh model (``model_config``, a
    :class:`experiments.benchmark_model.ModelConfig`) whose ``dt`` is the sequence's window.

    Returns the window rows, each sequence's notes and each sequence's model ``dt``;
    ``sampler`` (a :class:`experiments.benchmark_figure.WindowSampler`) keeps a few
    windows' maps for ``maps_vs_masks.png``.
    """
    from experiments.benchmark_model import nominal_dt_s
    from experiments.benchmark_protocol import evaluate_sequence

    rows: list[Any] = []
    notes: dict[str, list[str]] = {}
    dts: dict[str, float] = {}
    with _progress_context(show_progress) as progress:
        bars = _Bars(progress, what, n_sequences) if progress is not None else None
        for k, seq in enumerate(sequences):
            seq = limit_windows(seq, max_windows)
            key = f"{seq.subset}/{seq.name}"
            notes[key] = list(seq.notes)
            if not seq.windows:
                notes[key].append("no mask window: nothing scored")
                continue
            dt = nominal_dt_s(seq.windows)
            dts[key] = dt
            model = dataclasses.replace(model_config, dt=dt).pipeline()
            if sampler is not None:
                sampler.start_sequence(len(seq.windows))
            rows.extend(evaluate_sequence(seq, model, protocol, bars, k, n_sequences, sampler))
            if bars is not None:
                bars.sequence_done()
    return rows, notes, dts


def _write_summary_csv(summaries: Sequence[Any], path: Path) -> Path:
    from experiments.benchmark_protocol import summary_dicts

    dicts = summary_dicts(summaries)
    with path.open("w", newline="") as f:
        if dicts:
            w = csv.DictWriter(f, fieldnames=list(dicts[0]))
            w.writeheader()
            w.writerows(dicts)
    return path


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
    from experiments.benchmark_protocol import (
        render_markdown,
        summarize,
        summary_dicts,
        write_rows_csv,
    )
    from wander_env.runinfo import run_record, write_json

    out.mkdir(parents=True, exist_ok=True)
    write_rows_csv(rows, out / "results.csv")
    summaries = summarize(rows, std_over) if rows else []
    _write_summary_csv(summaries, out / "summary.csv")
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
    write_json(out / "run.json", record)
    if views:
        from experiments.benchmark_figure import plot_maps_vs_masks

        plot_maps_vs_masks(out / "maps_vs_masks.png", list(views), f"{title}: maps vs masks")
    return md


def _finish(out: Path, md: str, started: float) -> None:
    typer.echo(md)
    typer.echo(
        f"wrote {out}/results.csv, {out}/results.md, {out}/run.json"
        + (f", {out}/maps_vs_masks.png" if (out / "maps_vs_masks.png").is_file() else "")
        + " "
        f"({time.monotonic() - started:.1f} s)"
    )


def _suppression_rows(name: str, result: Any, t0: int) -> Iterator[list[Any]]:
    for k, (n_in, n_out) in enumerate(zip(result.events_in, result.events_out, strict=True)):
        a = t0 + k * result.window_us
        yield [name, k, a, a + result.window_us, int(n_in), int(n_out)]


def run_suppression(
    recordings: Sequence[tuple[str, Any, tuple[int, int, int]]],
    window_us: int,
    model_config: Any,
    show_progress: bool = True,
) -> list[Any]:
    """:func:`event_suppression` on each ``(name, events, sensor)`` with a fresh model
    (``model_config`` with the step ``window_us``)."""
    from experiments.benchmark_protocol import event_suppression

    results = []
    with _progress_context(show_progress) as progress:
        for name, events, sensor in recordings:
            cb: Callable[[Any], None] | None = None
            if progress is not None:
                task = progress.add_task(f"suppression {name}", total=None)
                cb = _suppression_callback(progress, task)
            model = dataclasses.replace(model_config, dt=window_us / 1e6).pipeline()
            results.append(event_suppression(events, sensor, model, window_us, cb, name))
    return results


def _suppression_callback(progress: Any, task: Any) -> Callable[[Any], None]:
    def cb(ev: Any) -> None:
        progress.update(task, completed=ev.window + 1, total=ev.n_windows)

    return cb


def suppression_markdown(names: Sequence[str], results: Sequence[Any]) -> str:
    """Per-recording tables (beside the paper's) and, for several, the pooled fraction."""
    from experiments.benchmark_protocol import render_suppression_markdown

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
    """Per-window events in / out of each ``(name, result, t_first_us)``."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(SUPPRESSION_COLUMNS)
        for name, result, t0 in items:
            w.writerows(_suppression_rows(name, result, t0))
    return path


# ----------------------------------------------------------------------------------------
# Options shared by the commands

OutOpt = Annotated[
    Path | None,
    typer.Option("--out", help="Output folder (default runs/benchmark-<name>)."),
]
MaxWindowsOpt = Annotated[
    int | None,
    typer.Option(
        "--max-windows",
        "--limit",
        min=1,
        help="Score only the first N windows of each sequence (a quick run; noted).",
    ),
]
StreamlinedOpt = Annotated[
    bool,
    typer.Option(
        "--streamlined/--split",
        help="Proto-object stage on V = V+ or V- (the paper's streamlined model) instead of "
        "one population per polarity line.",
    ),
]
AlphaOpt = Annotated[
    float | None,
    typer.Option(
        "--alpha",
        min=0.0,
        max=1.0,
        help="sOMS threshold α of Eq. (1) (default: the paper's table, 0.80).",
    ),
]
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


def _model_config(streamlined: bool, alpha: float | None) -> Any:
    """The benchmark model's :class:`ModelConfig` (``alpha`` None: the paper's 0.80)."""
    from experiments.benchmark_model import ModelConfig

    return ModelConfig(streamlined=streamlined, **({} if alpha is None else {"alpha": alpha}))


def _check_std_over(std_over: str) -> None:
    if std_over not in ("sequences", "windows"):
        raise typer.BadParameter(f"--std-over must be 'sequences' or 'windows', got {std_over!r}")


def _score_dataset(
    label: str,
    load: Callable[[], tuple[Iterable[Any], int]],
    model: Any,
    config: dict[str, Any],
    out: Path | None,
    max_windows: int | None,
    std_over: str,
    progress: bool,
    started: float,
) -> None:
    """Score a dataset's sequences (``load`` finds them) with ``model`` (a ``ModelConfig``)
    and write its results folder."""
    from experiments.benchmark_protocol import ProtocolConfig

    dataset = config["dataset"]
    out = out or Path(f"runs/benchmark-{dataset}")
    sampler = WindowSampler()
    try:
        seqs, n = load()
        rows, notes, dts = run_sequences(
            seqs, n, label, model, ProtocolConfig(), max_windows, progress, sampler
        )
    except (ValueError, OSError) as err:
        raise _fail(err) from None
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
    _finish(out, md, started)


# ----------------------------------------------------------------------------------------
# Commands


@app.command("evimo")
def evimo(
    path: Annotated[
        Path,
        typer.Argument(
            help="EVIMO root: PATH/<subset>/.../<sequence>.npz (EVIMO1, subsets box, fast, "
            "floor, table, tabletop, wall) and/or EVIMO2v2 sequence folders; or one .npz."
        ),
    ],
    out: OutOpt = None,
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
    max_sequences: Annotated[
        int | None, typer.Option(min=1, help="Only the first N sequences.")
    ] = None,
    max_windows: MaxWindowsOpt = None,
    streamlined: StreamlinedOpt = False,
    alpha: AlphaOpt = None,
    std_over: StdOverOpt = "sequences",
    threads: ThreadsOpt = None,
    progress: ProgressOpt = True,
) -> None:
    """EVIMO: per-subset accuracy, IoU, precision, SSIM beside the paper's Table."""
    from experiments.datasets.evimo import find_evimo_sequences, load_evimo_sequence

    _check_std_over(std_over)
    started = time.monotonic()
    _set_threads(threads)

    def load() -> tuple[Iterable[Any], int]:
        sources = find_evimo_sequences(path, subset)
        if max_sequences is not None:
            sources = sources[:max_sequences]
        return (load_evimo_sequence(s, window_mode, window_us) for s in sources), len(sources)

    model = _model_config(streamlined, alpha)
    config = {
        "dataset": "evimo",
        "path": str(path),
        "subsets": subset,
        "window_mode": window_mode,
        "window_us": window_us,
        "max_sequences": max_sequences,
        "max_windows": max_windows,
        "streamlined": streamlined,
        "alpha": model.alpha,
        "std_over": std_over,
    }
    _score_dataset("EVIMO", load, model, config, out, max_windows, std_over, progress, started)


@app.command("llevos")
def llevos(
    path: Annotated[
        Path,
        typer.Argument(
            help="LLE-VOS root holding Annotations/<seq>/<frame>.png and "
            "Lowlight_event/<seq>/<frame>.npz|.npy (or one folder above it)."
        ),
    ],
    out: OutOpt = None,
    sequence: Annotated[
        list[str] | None, typer.Option("--sequence", help="Only these sequences (repeatable).")
    ] = None,
    time_unit: Annotated[str, typer.Option(help="Unit of t in the event files.")] = "us",
    npy_columns: Annotated[str, typer.Option(help="Column order of (N, 4) event arrays.")] = "xytp",
    max_sequences: Annotated[
        int | None, typer.Option(min=1, help="Only the first N sequences.")
    ] = None,
    max_windows: MaxWindowsOpt = None,
    streamlined: StreamlinedOpt = False,
    alpha: AlphaOpt = None,
    std_over: StdOverOpt = "sequences",
    threads: ThreadsOpt = None,
    progress: ProgressOpt = True,
) -> None:
    """LLE-VOS: accuracy mean ± std over sequences beside the paper's 53.3 % ± 25.56."""
    from experiments.datasets.llevos import (
        LLEVOSConfig,
        find_llevos_root,
        list_llevos_sequences,
        load_llevos,
    )

    _check_std_over(std_over)
    started = time.monotonic()
    _set_threads(threads)

    def load() -> tuple[Iterable[Any], int]:
        cfg = LLEVOSConfig(time_unit=time_unit, npy_columns=npy_columns)
        names = sequence or list_llevos_sequences(find_llevos_root(path))
        n = len(names) if max_sequences is None else min(len(names), max_sequences)
        return itertools.islice(load_llevos(path, sequence, cfg), n), n

    model = _model_config(streamlined, alpha)
    config = {
        "dataset": "llevos",
        "path": str(path),
        "sequences": sequence,
        "time_unit": time_unit,
        "npy_columns": npy_columns,
        "max_sequences": max_sequences,
        "max_windows": max_windows,
        "streamlined": streamlined,
        "alpha": model.alpha,
        "std_over": std_over,
    }
    _score_dataset("LLE-VOS", load, model, config, out, max_windows, std_over, progress, started)


@app.command("events")
def events(
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
    out: OutOpt = None,
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
    max_windows: MaxWindowsOpt = None,
    streamlined: StreamlinedOpt = False,
    alpha: AlphaOpt = None,
    suppression: Annotated[
        bool,
        typer.Option(
            "--suppression/--no-suppression",
            help="Also measure the fraction of events sOMS suppresses (windows of the masks).",
        ),
    ] = True,
    threads: ThreadsOpt = None,
    progress: ProgressOpt = True,
) -> None:
    """Any event file + a mask folder: hit rate, IoU, precision, SSIM, sOMS suppression."""
    from experiments.benchmark_protocol import ProtocolConfig
    from experiments.datasets.generic import load_generic
    from wander_env.events import time_window

    started = time.monotonic()
    sensor_size = parse_sensor(sensor) if sensor else None
    offset = parse_offset(mask_offset) if mask_offset else None
    seq_name = name or default_name(file)
    out = out or Path(f"runs/benchmark-events-{seq_name}")
    _set_threads(threads)
    try:
        seq = load_generic(file, masks, sensor_size, window_us, name=seq_name, subset="events")
        seq = limit_windows(seq, max_windows)
        model = _model_config(streamlined, alpha)
        sampler = WindowSampler()
        rows, notes, dts = run_sequences(
            [seq], 1, "events", model, ProtocolConfig(mask_offset_xy=offset), None, progress,
            sampler,
        )  # fmt: skip
        extra_md, extra_rec = "", {}
        if suppression and seq.windows:
            win = round(dts[f"{seq.subset}/{seq.name}"] * 1e6)
            ev = seq.events
            if max_windows is not None:
                ev = time_window(ev, int(ev["t"][0]) if len(ev) else 0, seq.windows[-1].t_end_us)
            (res,) = run_suppression([(seq.name, ev, seq.sensor_size)], win, model, progress)
            t0 = int(ev["t"][0]) if len(ev) else 0
            write_suppression_csv(out / "suppression.csv", [(seq.name, res, t0)])
            extra_md = suppression_markdown([seq.name], [res])
            extra_rec = {"suppression": suppression_record([seq.name], [res])}
    except (ValueError, OSError) as err:
        raise _fail(err) from None
    config = {
        "dataset": "generic",
        "events": str(file),
        "masks": str(masks),
        "name": seq_name,
        "sensor": list(seq.sensor_size),
        "window_us": window_us,
        "mask_offset_xy": offset,
        "max_windows": max_windows,
        "streamlined": streamlined,
        "alpha": model.alpha,
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
    _finish(out, md, started)


@app.command("suppression")
def suppression(
    paths: Annotated[
        list[Path],
        typer.Argument(help="Event files, or folders whose event files are all read."),
    ],
    out: OutOpt = None,
    sensor: Annotated[
        str | None,
        typer.Option(help="Sensor WxH (default: the file's; a bare .npy infers it)."),
    ] = None,
    window_us: Annotated[
        int, typer.Option(min=1, help="Step length in µs (the paper counts per 2 ms).")
    ] = 2000,
    max_windows: Annotated[
        int | None,
        typer.Option("--max-windows", "--limit", min=1, help="Only the first N steps of each."),
    ] = None,
    streamlined: StreamlinedOpt = False,
    alpha: AlphaOpt = None,
    threads: ThreadsOpt = None,
    progress: ProgressOpt = True,
) -> None:
    """Fraction of events sOMS suppresses on recordings without masks (e.g. ego-motion only)."""
    from wander_env.event_io import read_events
    from wander_env.events import time_window
    from wander_env.runinfo import run_record, write_json

    started = time.monotonic()
    sensor_size = parse_sensor(sensor) if sensor else None
    out = out or Path("runs/benchmark-suppression")
    _set_threads(threads)
    notes: dict[str, list[str]] = {}
    try:
        files = event_files(paths)
        recs = []
        for f in files:
            rec = read_events(f, sensor_size)
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
        model = _model_config(streamlined, alpha)
        results = run_suppression(recs, window_us, model, progress)
    except (ValueError, OSError) as err:
        raise _fail(err) from None
    names = [n for n, _, _ in recs]
    t0s = [int(ev["t"][0]) if len(ev) else 0 for _, ev, _ in recs]
    write_suppression_csv(out / "results.csv", list(zip(names, results, t0s, strict=True)))
    md = suppression_markdown(names, results)
    config = {
        "paths": [str(p) for p in paths],
        "files": [str(f) for f in files],
        "sensor": {n: list(s) for n, _, s in recs},
        "window_us": window_us,
        "max_windows": max_windows,
        "streamlined": streamlined,
        "alpha": model.alpha,
    }
    md += "\n" + _config_markdown(config)
    notes_md = _notes_markdown(notes)
    if notes_md:
        md += "\n" + notes_md
    (out / "results.md").write_text(md)
    record = run_record("wander benchmark suppression", config, seed=None)
    record["seed_note"] = "the model is deterministic (draws no random numbers)"
    record["suppression"] = suppression_record(names, results)
    record["notes"] = notes
    record["elapsed_s"] = time.monotonic() - started
    write_json(out / "run.json", record)
    _finish(out, md, started)


def main() -> None:  # pragma: no cover - ``python -m experiments.benchmark_cli``
    app()


if __name__ == "__main__":  # pragma: no cover
    main()
