"""The ``wander experiment``, ``wander sweep`` and ``wander report`` commands.

``register(app)`` adds them to the main Typer app (``experiments/cli/main.py``).
"""

from __future__ import annotations

import json
import shlex
import sys
from pathlib import Path
from typing import Annotated

import typer

from experiments.cli.checks import check_wait, check_workers, one_of, out_path
from experiments.cli.console import console, print_markdown, progress_bars
from experiments.cli.errors import current_run, fail, long_command
from experiments.cli.options import (
    ForceOpt,
    SeedOpt,
    SetOpt,
    command_config,
    folder_problem,
    own_folder,
)
from experiments.runs.folder import RESULTS, SWEEPS, RunFolder
from experiments.studies.registry import EXPERIMENT_NAMES

__all__ = ["register"]


def _command_line() -> str:
    return "wander " + " ".join(shlex.quote(a) for a in sys.argv[1:])


@long_command("wander experiment")
def experiment(
    ctx: typer.Context,
    name: Annotated[str, typer.Argument(help=f"One of: {', '.join(EXPERIMENT_NAMES)}.")],
    set_: SetOpt = None,
    config: Annotated[
        Path | None,
        typer.Option(help="Config file (default: experiments/paper/configs/NAME.yaml)."),
    ] = None,
    seed: SeedOpt = 0,
    out: Annotated[
        Path | None,
        typer.Option(
            parser=out_path,
            help="Result folder (default: a new results/NAME/DATE-TIME-seedN). A folder where "
            "the same command stopped (same config and seed; without --out the newest under "
            "results/NAME) is resumed, its finished trials kept; any other non-empty folder "
            "needs --force, which starts afresh.",
        ),
    ] = None,
    force: ForceOpt = False,
    workers: Annotated[
        int, typer.Option(callback=check_workers, help="Worker processes (1 = this process).")
    ] = 1,
    show_config: Annotated[
        bool, typer.Option("--show-config", help="Print the resolved config and stop.")
    ] = False,
) -> None:
    """Run one experiment: a results table, plots, config, seed and git revision. Its
    config: the experiment's defaults <- the config file <- --set items."""

    from experiments.studies.framework import (
        ConfigError,
        default_config_file,
        get_experiment,
        make_trials,
        run_experiment,
        unfinished_folder,
    )
    from experiments.studies.sweep import TrialCrashed, local_executor
    from wander_env.config import to_plain
    from wander_env.strict_json import dumps_strict

    try:
        exp = get_experiment(name)
    except ConfigError as e:
        raise fail(e, ctx) from None
    cfg = command_config(ctx, exp.config_type, config_file=config or default_config_file(exp))
    try:
        n = len(make_trials(exp, cfg, seed))
        resume = None if show_config or force else unfinished_folder(name, cfg, seed, out)
    except ConfigError as e:
        raise fail(e, ctx) from None
    if show_config:
        console.print_json(dumps_strict(to_plain(cfg)))
        return
    if resume is not None:  # the same command stopped there: its finished trials are kept
        run = RunFolder(resume, current_run(ctx))
    else:
        run = own_folder(
            ctx, lambda now: RunFolder.for_experiment(name, seed, out, force, current=now)
        )
    folder = run.path

    streams: list = []

    def executor(specs):  # type: ignore[no-untyped-def]
        streams.append(local_executor(specs, workers))
        return streams[-1]

    with progress_bars() as bar:
        task = bar.add_task(name, total=n)
        try:
            rows, files = run_experiment(
                name,
                cfg,
                seed,
                folder,
                command=_command_line(),
                executor=executor if workers > 1 else None,
                progress=lambda i, total: bar.update(task, completed=i, total=total),
            )
        except ConfigError as e:  # another run holds the folder: not this run's to mark
            raise fail(e, ctx) from None
        except TrialCrashed as e:
            run.record_failure(e)
            raise fail(f"{e} ({folder})", ctx) from None
        except BaseException as e:  # any error, also one no signal or write: the folder says so
            run.record_failure(e)
            raise
        finally:
            for stream in streams:
                stream.close()  # the workers end now, not when their trials do
    timing = json.loads((folder / "run.json").read_text())["timing"]
    kept = f", {timing['resumed']} kept from the stopped run" if timing["resumed"] else ""
    console.print(f"{len(rows)} trials{kept} -> {run.final}/results.csv ({len(files)} files)")
    print_markdown((folder / "summary.md").read_text())
    _print_rtf(timing.get("real_time_factor"))


def _print_rtf(rtf: float | None) -> None:
    """The real-time factor line (nothing when the work simulated no time)."""
    if rtf is not None:
        console.print(f"real-time factor: {rtf:.3g} (simulated seconds per wall second)")


def _check_backend(value: str) -> str:
    """One of the sweep backends (:data:`experiments.studies.sweep.BACKENDS`)."""
    from experiments.studies.sweep import BACKENDS

    return one_of(BACKENDS)(value)


def _check_address(value: str | None) -> str | None:
    """A Ray cluster address as ``ray.init`` takes it: ``auto``, ``HOST:PORT`` or
    ``ray://HOST:PORT`` (a port 1 to 65535); None: unset.

    >>> _check_address("ray://head:10001"), _check_address("10.0.0.2:6379")
    ('ray://head:10001', '10.0.0.2:6379')
    """
    if value is None or value == "auto":
        return value
    host, _, port = value.removeprefix("ray://").rpartition(":")
    if not (host and port.isascii() and port.isdigit() and 1 <= int(port) <= 65535):
        raise typer.BadParameter(
            f"must be auto, HOST:PORT or ray://HOST:PORT (a port 1 to 65535), got {value!r}"
        )
    return value


@long_command("wander sweep")
def sweep(
    ctx: typer.Context,
    config: Annotated[Path, typer.Argument(help="Sweep file (see experiments/paper/configs/).")],
    backend: Annotated[
        str, typer.Option(callback=_check_backend, help="serial, local or ray.")
    ] = "local",
    workers: Annotated[
        int | None,
        typer.Option(
            callback=check_workers, help="Processes (local) or CPUs of a local Ray instance."
        ),
    ] = None,
    address: Annotated[
        str | None,
        typer.Option(
            callback=_check_address,
            help="Ray cluster address (--backend ray): auto, HOST:PORT or ray://HOST:PORT "
            "(default: start a local Ray).",
        ),
    ] = None,
    out: Annotated[
        Path | None,
        typer.Option(parser=out_path, help="Sweep folder (default: results/sweeps/NAME)."),
    ] = None,
    timeout: Annotated[
        float,
        typer.Option(
            callback=check_wait,
            help="Seconds to wait for the next trial to finish before giving up.",
        ),
    ] = 6 * 3600.0,
) -> None:
    """Run a grid of (experiment, parameters, seeds); reruns skip finished trials."""
    from experiments.studies.framework import ConfigError
    from experiments.studies.sweep import BackendFailed, TrialCrashed, expand, load_sweep, run_sweep

    if address is not None and backend != "ray":
        raise typer.BadParameter(
            f"a Ray cluster's address, only with --backend ray, got --backend {backend}",
            param_hint="'--address'",
        )
    try:
        sw = load_sweep(config)
        n = len(expand(sw))
    except ConfigError as e:
        raise fail(e, ctx) from None
    path = out or RESULTS / SWEEPS / sw.name
    run = own_folder(ctx, lambda now: RunFolder.for_sweep(path, now))
    folder = run.path
    with progress_bars() as bar:
        task = bar.add_task(f"sweep {sw.name}", total=n)
        try:
            res = run_sweep(
                sw,
                folder,
                backend=backend,
                workers=workers,
                address=address,
                progress=lambda i, total: bar.update(task, completed=i, total=total),
                command=_command_line(),
                timeout_s=timeout,
            )
        except ConfigError as e:
            raise fail(e, ctx) from None
        except TimeoutError as e:
            run.record_failure(e)
            raise fail(f"{e} ({folder}: rerun to resume)", ctx) from None
        except (TrialCrashed, BackendFailed) as e:
            run.record_failure(e)
            raise fail(f"{e} ({folder})", ctx) from None
        except BaseException as e:  # a signal: the folder says so; the workers are ended
            run.record_failure(e)
            raise
    console.print(
        f"{len(res.rows)} trials ({res.ran} run, {res.skipped} already done) -> "
        f"{folder}/results.csv"
    )
    _print_rtf(res.real_time_factor)


def report(
    ctx: typer.Context,
    results: Annotated[Path, typer.Option(help="Folder of result folders.")] = RESULTS,
    out: Annotated[
        str,
        typer.Option(
            help="Report file, or a folder to hold REPORT.md (an existing one, or a name "
            "ending with /); its figures go to report_figures/ beside the report."
        ),
    ] = "REPORT.md",
    force: Annotated[bool, typer.Option("--force", help="Overwrite an existing report.")] = False,
) -> None:
    """Build REPORT.md (and its figures) from the latest results of each experiment.

    An existing report is never overwritten without --force.

    A damaged result file is named on one line; nothing is then written.
    """
    from experiments.paper.report import build_report, report_path

    if not results.is_dir():
        raise typer.BadParameter(
            f"no results folder {str(results)!r}: run `wander experiment NAME` first, or "
            "give the folder that holds its results",
            param_hint="'--results'",
        )
    if report_path(out).exists() and not force:
        raise typer.BadParameter(
            f"{str(report_path(out))!r} exists: pass --force to overwrite it, or --out "
            "another file",
            param_hint="'--out'",
        )
    try:
        path = build_report(results, out)
    except ValueError as err:  # ReportInputError, ConfigError: a damaged result file
        raise fail(err, ctx) from None
    except OSError as err:  # --out under a file, in /proc, a name too long
        raise typer.BadParameter(folder_problem(err), param_hint="'--out'") from None
    console.print(f"-> {path}")


def register(app: typer.Typer) -> None:
    """Add ``experiment``, ``sweep`` and ``report`` to ``app``."""
    app.command("experiment")(experiment)
    app.command("sweep")(sweep)
    app.command("report")(report)
