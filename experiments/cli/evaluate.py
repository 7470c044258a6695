"""``wander evaluate``: the agent's quality in simulation over seeds (a table, and one run
folder per seed). :mod:`experiments.cli.main` registers it.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import typer

from experiments.cli.checks import out_path, seed_list
from experiments.cli.console import console, print_table, progress_bars
from experiments.cli.errors import long_command
from experiments.cli.options import (
    AGENT_OPTIONS,
    FRAME_OPTIONS,
    DvsOpt,
    SceneOpt,
    SeedsOpt,
    command_config,
    resolve_out,
    seconds_flag,
    with_options,
)

__all__ = ["evaluate"]


@long_command("wander evaluate")
@with_options(AGENT_OPTIONS, FRAME_OPTIONS)
def evaluate(
    ctx: typer.Context,
    out: Annotated[
        Path | None,
        typer.Option(
            parser=out_path,
            help="Folder for one run folder per seed (default: a new time-stamped "
            "runs/evaluate-DATE-TIME/; an existing non-empty folder needs --force).",
        ),
    ] = None,
    scene: SceneOpt = None,
    seconds: seconds_flag("Simulated seconds per seed (default: the config's, 20).") = None,
    seeds: SeedsOpt = "0,1,2",
    dvs: DvsOpt = None,
    **shared: Any,
) -> None:
    """The agent's quality in simulation: detection accuracy, suppression, foveation error.
    Unset flags take EvaluateConfig's values (RunConfig's, but 20 s a seed and no video)."""
    from experiments.jobs.evaluate_agent import EvaluateConfig
    from experiments.jobs.evaluate_agent import evaluate as run_eval

    seed_values = seed_list(seeds)
    config = command_config(ctx, EvaluateConfig)
    folder = resolve_out(ctx, out, "evaluate", shared["force"])
    with progress_bars() as bar:
        steps = round(config.seconds / config.env.control_period_s)
        task = bar.add_task("evaluate", total=steps * len(seed_values))
        done = {s: 0 for s in seed_values}

        def tick(seed: int, i: int, n: int) -> None:
            done[seed] = i
            bar.update(task, completed=sum(done.values()))

        rows = run_eval(folder.path, config, seed_values, progress=tick)
    print_table(
        f"Agent quality in {config.env.scene!r} ({config.seconds:g} s per seed; all = the "
        "seeds pooled)",
        rows,
        {
            "seed": "",
            "decisions": "d",
            "scored": "d",
            "hits": "d",
            "detection_accuracy": ".1%",
            "detection_ci_low": ".1%",
            "detection_ci_high": ".1%",
            "soms_suppression": ".2%",
            "foveation_error_x_px": ".2f",
            "foveation_error_y_px": ".2f",
            "saccades": "d",
            "real_time_factor": ".2f",
        },
    )
    total, out = rows[-1], folder.final
    console.print(
        f"{total.simulated_s:g} simulated s in {total.wall_s:.1f} wall s: real-time factor "
        f"{total.real_time_factor:.2f} -> {out}/quality.csv, {out}/quality.json"
    )
