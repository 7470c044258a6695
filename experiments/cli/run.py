"""``wander demo``, ``wander record``, ``wander run`` and ``wander view``: one run of the
DVS demo, of a gaze policy or of the agent in a scene, each writing a run folder, and the
Rerun viewer on one. :mod:`experiments.cli.main` registers them.

``wander run --config FILE`` reads the run's settings from a YAML file of
:class:`~experiments.jobs.run_agent.RunConfig` keys, the format ``wander experiment
--config`` reads, e.g.::

    env:
      scene: shelf
      episode_seconds: 5.0
    agent:
      window_s: 0.05
      soms: {norm: minmax}

A flag given on the command line, then ``--set``, overrides the file's value
(:func:`experiments.cli.options.command_config`).
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import typer

from experiments.cli.checks import check_dvs, one_of
from experiments.cli.console import console, step_progress
from experiments.cli.errors import long_command
from experiments.cli.options import (
    AGENT_OPTIONS,
    FRAME_OPTIONS,
    DvsOpt,
    ForceOpt,
    RunDirOpt,
    SceneOpt,
    SecondsOpt,
    SetOpt,
    VideoOpt,
    command_config,
    config_flag,
    resolve_out,
    run_env_job,
    seconds_flag,
    seed_flag,
    with_options,
)

__all__ = ["demo", "record", "rerun", "run_agent", "view"]

#: The most frames a simulated second ``--video-fps`` takes (a step's frame repeated;
#: ``RunConfig.video_fps``'s bound, kept equal by
#: tests/integration/experiments/test_runs_writing.py).
MAX_VIDEO_FPS = 1000


@long_command("wander demo")
def demo(
    ctx: typer.Context,
    out: RunDirOpt = None,
    seconds: seconds_flag(
        "Simulated seconds of the stimulus (default: the config's, 1).", "seconds"
    ) = None,
    preset: config_flag(
        str,
        "preset",
        "DVS preset: ideal, paper or speck (default: the config's, paper).",
        check=check_dvs,
    ) = None,
    seed: seed_flag("Seed of the stimulus and the emulator's noise (default: 0).") = None,
    force: ForceOpt = False,
    set_: SetOpt = None,
) -> None:
    """Drive the DVS emulator with a synthetic moving pattern; write events and a picture.
    Unset flags take DemoConfig's values."""
    from experiments.jobs.demo import run_demo
    from experiments.jobs.dvs_demo import DemoConfig

    config = command_config(ctx, DemoConfig)
    folder = resolve_out(ctx, out, "demo", force)
    steps = round(config.seconds * config.frame_rate_hz)
    with step_progress("DVS demo", steps) as progress:
        summary = run_demo(folder.path, config, progress=progress)
    out = folder.final
    console.print(
        f"{summary['events']:,} events ({summary['events_per_frame']:.0f} per frame, "
        f"{summary['on_fraction']:.0%} ON) -> {out}/events.h5, {out}/events.png"
    )


#: ``--seed`` of the job commands (``run``, ``record``): the config's ``seed``.
JobSeedOpt = seed_flag("Seed of the env, the policy or walk, and the controller.")


@long_command("wander record")
@with_options(FRAME_OPTIONS)
def record(
    ctx: typer.Context,
    out: RunDirOpt = None,
    scene: SceneOpt = None,
    seconds: SecondsOpt = None,
    policy: config_flag(
        str,
        "policy",
        "still, fixational or saccades.",
        check=one_of(("still", "fixational", "saccades")),
    ) = None,
    dvs: DvsOpt = None,
    seed: JobSeedOpt = None,
    video: config_flag(bool, "video", "Write video.mp4 (camera | events).") = None,
    format: config_flag(
        str,
        "format",
        "Events as h5, aedat4 or evt3 (.raw); or evimo2: the EVIMO2v2 layout "
        "(events + per-step masks) that `wander benchmark evimo` scores.",
        "--format",
        check=one_of(("h5", "aedat4", "evt3", "evimo2")),
    ) = None,
    **shared: Any,
) -> None:
    """Record events, ground truth and a video of the env under a simple gaze policy.
    Unset flags take RecordConfig's values (5 s of the office, fixational, h5, video)."""
    from experiments.jobs.record import RecordConfig
    from experiments.jobs.record import record as run

    config = command_config(ctx, RecordConfig)
    title = f"record {config.env.scene}"
    out, summary = run_env_job(ctx, run, config, out, shared["force"], "record", title)
    console.print(f"{summary['events']:,} events over {summary['steps']} steps -> {out}")


def _check_video_fps(value: int | None) -> int | None:
    if value is not None and not 1 <= value <= MAX_VIDEO_FPS:
        raise typer.BadParameter(f"must be 1 to {MAX_VIDEO_FPS} frames a second, got {value}")
    return value


@long_command("wander run")
@with_options(AGENT_OPTIONS, FRAME_OPTIONS)
def run_agent(
    ctx: typer.Context,
    out: RunDirOpt = None,
    scene: SceneOpt = None,
    seconds: SecondsOpt = None,
    seed: JobSeedOpt = None,
    dvs: DvsOpt = None,
    video: VideoOpt = None,
    video_fps: config_flag(
        int,
        "video_fps",
        "run.mp4's frames per simulated second (a frame is composed only when "
        "due; default: the config's, 25).",
        check=_check_video_fps,
    ) = None,
    config: Annotated[
        Path | None,
        typer.Option(
            exists=True,
            dir_okay=False,
            help="A YAML file of the run's settings (RunConfig keys: env (scene, dvs, "
            "frames, episode_seconds, ...), seed, video, agent (window_s, soms, proto, "
            "...); the format of `wander experiment --config`). Flags given on the "
            "command line and --set override it.",
        ),
    ] = None,
    **shared: Any,
) -> None:
    """Run the attention agent closed-loop in a scene; write the run folder. Unset flags
    take RunConfig's values (10 s of the office, the paper's agent: `--set agent.KEY=VALUE`
    reaches every agent parameter)."""
    from experiments.jobs.run_agent import RunConfig
    from experiments.jobs.run_agent import run as run_loop

    config = command_config(ctx, RunConfig, config_file=config)
    title = f"agent in {config.env.scene}"
    out, result = run_env_job(ctx, run_loop, config, out, shared["force"], "run", title)
    m = result.metrics
    detection = (
        f"detection accuracy {m['detection_accuracy']:.0%} ({m['decisions_scored']} scored)"
        if m["decisions_scored"]
        else "no moving object in view to score"
    )
    console.print(
        f"{m['decisions']} decisions, {m['saccades']} saccades, {detection}, sOMS suppression "
        f"{m['soms_suppression']:.1%}, real-time factor {m['real_time_factor']:.2f} -> {out}"
    )


@long_command("wander rerun")
def rerun(
    ctx: typer.Context,
    run_dir: Annotated[Path, typer.Argument(help="A folder that `wander run` wrote.")],
    out: RunDirOpt = None,
    force: ForceOpt = False,
) -> None:
    """Run a `wander run` folder's run again from its run.json: its config, seed and the
    scene as it resolved; refused if a file the run read (scene, meshes, MJCF) changed."""
    from experiments.cli.errors import fail
    from experiments.jobs.run_agent import RunConfig
    from experiments.jobs.run_agent import run as run_loop
    from experiments.runs.provenance import rerun_config

    try:
        config = rerun_config(run_dir / "run.json", RunConfig, "wander run")
    except ValueError as err:
        raise fail(err, ctx) from None
    title = f"agent in {config.env.scene.name}, again"
    out, result = run_env_job(ctx, run_loop, config, out, force, "run", title)
    m = result.metrics
    console.print(f"{m['decisions']} decisions, {m['saccades']} saccades -> {out}")


def view(
    run_dir: Annotated[Path, typer.Argument(help="A run folder holding run.rrd.")],
) -> None:
    """Open a run folder's run.rrd in the Rerun viewer (headless: print the command)."""
    from experiments.runs.viewer import command_text
    from experiments.runs.viewer import view as open_view

    try:
        what, command = open_view(run_dir)
    except (FileNotFoundError, ValueError) as err:
        raise typer.BadParameter(str(err), param_hint="'RUN_DIR'") from None
    if what == "spawned":
        typer.echo(f"opened {run_dir / 'run.rrd'} in the Rerun viewer", err=True)
    else:
        rrd = command[-1]
        typer.echo("no display (DISPLAY unset); open the recording with:", err=True)
        typer.echo(command_text(command))
        typer.echo("or in a browser (the viewer prints the address to open):", err=True)
        typer.echo(command_text([*command[:-1], "--web-viewer", rrd]))
        typer.echo(
            f"or copy {rrd} to a machine with a display and open it there with: rerun run.rrd",
            err=True,
        )
