"""The ``wander`` command line: the app and every command group. ``wander --help`` lists
the commands; each group lives in its own module of :mod:`experiments.cli`.
"""

from __future__ import annotations

import typer

from experiments.cli import bench, benchmark, evaluate, experiment, rig, run
from experiments.cli.errors import OneLineErrors

__all__ = ["app", "main"]

app = typer.Typer(
    help="wander: a simulated active-vision laboratory for event cameras.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
    cls=OneLineErrors,
)
app.add_typer(bench.app, name="bench")
app.add_typer(benchmark.app, name="benchmark")
app.command()(run.demo)
app.command()(run.record)
app.command("run")(run.run_agent)
app.command()(evaluate.evaluate)
app.command()(run.view)
rig.register(app)
experiment.register(app)


def main() -> None:
    app(prog_name="wander")


if __name__ == "__main__":
    main()
