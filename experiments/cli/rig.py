"""The ``wander rig`` command: the attention agent on the rig (camera on a pan-tilt unit).

:func:`register` adds it to the main ``wander`` app. It runs
:func:`experiments.jobs.rig.run_rig` and writes the same run folder as ``wander run``. A
device failure prints one line on stderr (what failed, the port or device, the unit's
message; the run folder when the run had started) and exits with code 1; a bad option, or
a replayed event file that is refused (damaged, too many events, a sensor over the agent's
pixel budget), exits with code 2; Ctrl-C, SIGTERM or SIGHUP halt the PTU, leave the
folder with what was recorded (``metrics.json`` names the signal) and exit with 128 + the
signal (130, 143, 129).
"""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import Annotated, Any

import typer

from experiments.cli.console import console, step_progress
from experiments.cli.errors import long_command
from experiments.cli.options import (
    AGENT_OPTIONS,
    ConfigKey,
    ForceOpt,
    RunDirOpt,
    SetOpt,
    VideoOpt,
    command_config,
    config_flag,
    option,
    resolve_out,
    seconds_flag,
    seed_flag,
    with_options,
)
from experiments.runs.failure import exit_code
from experiments.runs.signals import SignalExit
from wander_env.events.checks import EventFileError


def _or_nan(value: Any) -> float:
    return math.nan if value is None else float(value)


def summary_line(metrics: dict[str, Any], out: Path) -> str:
    """The line printed after a run: decisions, saccades, events, drops, PTU latency."""
    rig = metrics.get("rig", {})
    # metrics.json is strict JSON: a latency never measured is null (None here).
    mean_ms = _or_nan(rig.get("command_latency_mean_s")) * 1e3
    max_ms = _or_nan(rig.get("command_latency_max_s")) * 1e3
    return (
        f"{metrics['decisions']} decisions, {metrics['saccades']} saccades, "
        f"{metrics['steps']} steps, {metrics['events']:,} events "
        f"({rig.get('dropped_events', 0):,} dropped), PTU command latency "
        f"mean {mean_ms:.1f} ms / max {max_ms:.1f} ms, real-time factor "
        f"{_or_nan(metrics['real_time_factor']):.2f} -> {out}"
    )


def dropped_warning(metrics: dict[str, Any]) -> str | None:
    """A warning when the camera lost events (queue overflow, late or off-sensor events)."""
    rig = metrics.get("rig", {})
    n = int(rig.get("dropped_events", 0))
    if n <= 0:
        return None
    camera = rig.get("camera") or {}
    parts = [
        f"{k.replace('_', ' ')} {camera[k]:,}"
        for k in ("dropped_overflow", "late", "out_of_range")
        if camera.get(k)
    ]
    detail = f" ({', '.join(parts)})" if parts else ""
    return (
        f"warning: the camera dropped {n:,} events{detail}; the agent did not see them "
        "(see metrics.json 'rig')"
    )


#: ``wander rig``'s own default (RigConfig's is "realtime"): a replay runs fast.
RIG_DEFAULTS = {"env.replay": "fast"}


@long_command("wander rig")
@with_options(
    AGENT_OPTIONS,
    (option("video", VideoOpt), option("force", ForceOpt, False), option("set_", SetOpt)),
)
def rig(
    ctx: typer.Context,
    ptu: Annotated[
        str,
        typer.Option(
            help="The PTU's serial port or pyserial URL (/dev/ttyUSB0, socket://host:4000), "
            "or 'emulate' for the protocol emulator."
        ),
        ConfigKey("env.ptu_port"),
    ],
    camera: Annotated[
        str,
        typer.Option(
            help="'speck', 'speck:<serial number>', or 'replay:<event file>' "
            "(.npz, .h5, .npy, .aedat4, .aedat)."
        ),
        ConfigKey("env.camera"),
    ],
    replay: config_flag(
        str,
        "env.replay",
        "Replay pacing: 'fast' (windows advance in stream time, so every step's "
        "events are fixed by the file; the default), 'stepped' (as 'fast', and the PTU's "
        "commands and polls run in stream time too: a step returns with its exchanges "
        "done) or "
        "'realtime' (paced by the wall clock, like a live camera). Ignored for a Speck.",
    ) = None,
    seconds: seconds_flag(
        "Run length in seconds of camera time (default: the config's, 10)."
    ) = None,
    hfov_deg: config_flag(
        float,
        "env.hfov_deg",
        "The lens's horizontal field of view in degrees (default: the Speck's, "
        "2·atan(5.12/3.4) = 112.8°). A recording from another camera (e.g. a DVS128) "
        "needs its own lens's; run.json records the value used.",
        "--hfov",
    ) = None,
    seed: seed_flag("Seed of the agent (walk, controller; default: 0).") = None,
    out: RunDirOpt = None,
    **shared: Any,
) -> None:
    """Run the attention agent closed-loop on the rig; write the run folder of `wander run`.
    Unset flags take RigRunConfig's values (`--set agent.KEY=VALUE` reaches every agent
    parameter)."""
    from agents.speck_limits import SpeckLimitError
    from experiments.jobs.rig import RigRunConfig, RigRunError, run_rig

    config = command_config(ctx, RigRunConfig, defaults=RIG_DEFAULTS)
    camera = config.env.camera
    replay_file = Path(camera[len("replay:") :]) if camera.startswith("replay:") else None
    if replay_file is not None and not replay_file.is_file():
        raise typer.BadParameter(
            f"no such event file: {str(replay_file)!r}", param_hint="'--camera'"
        )
    port = config.env.ptu_port
    # A path (not 'emulate', not a pyserial URL such as socket://host:4000) that is not
    # there is a typo, not a device fault (POSIX: a serial port is a device file).
    if os.name == "posix" and port != "emulate" and "://" not in port and not Path(port).exists():
        raise typer.BadParameter(
            f"no such serial port: {port!r} (is the PTU's USB-serial adapter plugged in? "
            "Give a device such as /dev/ttyUSB0, a pyserial URL such as socket://host:4000, "
            "or 'emulate')",
            param_hint="'--ptu'",
        )
    folder = resolve_out(ctx, out, "rig", shared["force"])
    out = folder.final
    try:
        with step_progress(
            f"agent on the rig ({camera})", round(config.seconds / config.env.control_period_s)
        ) as progress:
            result = run_rig(folder.path, config, progress=progress)
    except SpeckLimitError as err:  # the front end does not fit the chip: nothing was opened
        typer.echo(f"wander rig: agent.soms: {err}", err=True)
        raise typer.Exit(2) from err
    except RigRunError as err:
        typer.echo(f"wander rig: {err}", err=True)
        bad_file = isinstance(err.__cause__, EventFileError)  # a replay file refused: input
        raise typer.Exit(2 if bad_file else 1) from err
    except KeyboardInterrupt as err:  # Ctrl-C, SIGTERM, SIGHUP (experiments.runs.signals)
        folder.record_failure(err)
        what = str(err) if isinstance(err, SignalExit) else "interrupted"
        typer.echo(
            f"wander rig: {what}; the PTU was halted; if the run had started, "
            f"{str(out)!r} holds what was recorded",
            err=True,
        )
        raise typer.Exit(exit_code(err)) from None
    console.print(summary_line(result.metrics, out), soft_wrap=True)
    warning = dropped_warning(result.metrics)
    if warning is not None:
        console.print(f"[yellow]{warning}[/yellow]", soft_wrap=True)


def register(app: typer.Typer) -> None:
    """Add the ``rig`` command to ``app`` (the main ``wander`` app)."""
    app.command("rig")(rig)


__all__ = ["RIG_DEFAULTS", "dropped_warning", "register", "rig", "summary_line"]
