"""The ``wander`` command line: the app and every command group. ``wander --help`` lists
the commands; each group lives in its own module of :mod:`experiments.cli`;
``wander --version`` prints the version and the git revision.
"""

from __future__ import annotations

import faulthandler
from typing import Annotated

import typer

from experiments.cli import benchmark, evaluate, experiment, perf, rig, run
from experiments.cli.errors import OneLineErrors

__all__ = ["app", "main", "version_text"]

app = typer.Typer(
    help="wander: a simulated active-vision laboratory for event cameras.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
    cls=OneLineErrors,
)


def version_text() -> str:
    """``wander <version> (git <revision>)``: the installed distribution's version and the
    checkout's commit (``-dirty`` with uncommitted changes; ``unknown`` outside git)."""
    from experiments.runs.provenance import git_revision, package_versions

    return f"wander {package_versions(('wander',))['wander']} (git {git_revision()})"


def _print_version(value: bool) -> None:
    if value:
        typer.echo(version_text())
        raise typer.Exit()


@app.callback()
def _options(
    version: Annotated[
        bool,
        typer.Option(
            "--version",
            callback=_print_version,
            is_eager=True,
            help="Print the version and the git revision, and exit.",
        ),
    ] = False,
) -> None:
    """The options before a command (``wander --version``); a crash in native code from
    here on prints every thread's Python stack (:func:`_report_crashes`)."""
    _report_crashes()


def _report_crashes() -> None:
    """A fatal signal in native code (a driver's or a kernel's segfault) prints the Python
    stack of every thread on stderr before the process dies (:mod:`faulthandler`), where
    stderr is a file and nothing (pytest) enabled it already."""
    if faulthandler.is_enabled():
        return
    try:
        faulthandler.enable(all_threads=True)
    except (RuntimeError, AttributeError, ValueError):  # no stderr, or one without a descriptor
        return


def _bench_is_perf() -> None:
    """``wander bench``, the former name of ``wander perf``: a notice, then the command."""
    typer.echo("wander bench is now wander perf", err=True)


app.add_typer(perf.app, name="perf")
app.add_typer(perf.app, name="bench", hidden=True, callback=_bench_is_perf)
app.add_typer(benchmark.app, name="benchmark")
app.command()(run.demo)
app.command()(run.record)
app.command("run")(run.run_agent)
app.command()(run.rerun)
app.command()(evaluate.evaluate)
app.command()(run.view)
rig.register(app)
experiment.register(app)


def main() -> None:
    app(prog_name="wander")


if __name__ == "__main__":
    main()
