"""``wander perf ...``: the speed benchmarks, each printing tables (speed is measured
here, never in tests): ``dvs``, ``env``, ``agent``, ``floor``, ``panorama``, ``fidelity``,
``formats``.
:mod:`experiments.cli.main` adds :data:`app` as ``perf`` (and as ``bench``, its former name,
with a notice).
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path
from typing import Annotated

import typer

from experiments.cli.checks import (
    MAX_WORKERS,
    check_scene,
    comma_list,
    int_list,
    int_range,
    one_of,
    seed_list,
)
from experiments.cli.console import console, print_table
from experiments.cli.options import (
    ConfigFileOpt,
    KeyframeMsOpt,
    SceneOpt,
    SeedsOpt,
    SetOpt,
    command_config,
    config_flag,
    seconds_flag,
    seed_flag,
)

__all__ = ["app"]

app = typer.Typer(
    help="Speed and fidelity tables of the simulator and the agent (speed is measured "
    "here, not in tests)."
)

#: The most timed runs a row of a timing table may ask for.
MAX_REPEATS = 100
#: The most frames a ``wander perf dvs`` run may ask for: its frames are held in memory
#: (about 0.75 MB each at 346x260, every input path's copy).
MAX_DVS_FRAMES = 5000
#: The longest ``wander perf fidelity`` run (simulated seconds per seed; the reference
#: renders every tick at up to 256 samples a pixel).
MAX_FIDELITY_SECONDS = 60.0
#: The fastest render ticks of ``wander perf fidelity``'s reference.
MAX_REFERENCE_HZ = 100_000.0

#: ``--repeats`` of the timing tables (its default is each table's).
TimedRepeatsOpt = Annotated[
    int,
    typer.Option(
        callback=int_range(1, MAX_REPEATS),
        help=f"Timed runs per row (1 to {MAX_REPEATS}); the median is shown.",
    ),
]


@app.command("dvs")
def bench_dvs(
    frames: Annotated[
        int,
        typer.Option(
            callback=int_range(1, MAX_DVS_FRAMES),
            help=f"Frames per timed run (1 kHz; 1 to {MAX_DVS_FRAMES}: they are held in memory).",
        ),
    ] = 1000,
    repeats: TimedRepeatsOpt = 3,
    peers: Annotated[
        bool, typer.Option(help="Also run evlib's ESIM and v2e on the same frames.")
    ] = False,
) -> None:
    """Frames/s and Mev/s of the DVS emulator at 128x128 and 346x260."""
    from experiments.perf.dvs import (
        DVS_COLUMNS,
        INPUT_COLUMNS,
        NOISE_PRESET,
        PEER_COLUMNS,
        PEER_THRESHOLD,
        bench_dvs,
        bench_inputs,
        bench_peers,
    )

    rows = bench_dvs(n_frames=frames, repeats=repeats)
    print_table(
        f"DVS emulator ('all on' = the {NOISE_PRESET} preset, every noise term)",
        rows,
        DVS_COLUMNS,
    )
    print_table(
        "Input paths, moving pattern, ideal (time ratio = time per frame / float32 linear's)",
        bench_inputs(n_frames=frames, repeats=repeats),
        INPUT_COLUMNS,
    )
    if peers:
        print_table(
            f"Peers on the same linear frames (moving pattern, threshold {PEER_THRESHOLD}, "
            "no noise, one torch thread; wander speedup = their time / wander's)",
            bench_peers(n_frames=frames, repeats=repeats),
            PEER_COLUMNS,
        )


@app.command("env")
def bench_env(
    ctx: typer.Context,
    scene: SceneOpt = None,
    seconds: seconds_flag(
        "Simulated seconds per row (default: the config's, 2).", "seconds"
    ) = None,
    ground_truth: config_flag(
        bool, "env.ground_truth", "Render segmentation masks too (default: the config's, yes)."
    ) = None,
    antialias: config_flag(
        int, "env.antialias_samples", "MSAA samples (overrides the scene's; 0 = off)."
    ) = None,
    breakdown: Annotated[bool, typer.Option(help="Also time the parts of one env's step.")] = True,
    keyframe_ms: KeyframeMsOpt = None,
    envs: Annotated[
        str,
        typer.Option(
            help=f"Comma-separated env counts (each 1 to {MAX_WORKERS} env processes, none twice)."
        ),
    ] = "1,2,4",
    keyframe_px: config_flag(
        float,
        "env.keyframe_px",
        "Motion bound (px) of the adaptive keys' column (default: the config's, 2).",
    ) = None,
    config: ConfigFileOpt = None,
    set_: SetOpt = None,
) -> None:
    """Real-time factor of the environment: exact, keyframe and adaptive-keyframe frames
    side by side. Unset flags take EnvBenchConfig's values; each row sets the env's dvs
    (ideal, speck) and frames itself."""
    from experiments.cli.errors import fail
    from experiments.perf.env import (
        BREAKDOWN_COLUMNS,
        ENV_COLUMNS,
        ENV_COUNT_COLUMNS,
        ENV_TIME_COLUMNS,
        ROW_KEYS,
        EnvBenchConfig,
        step_breakdown,
    )
    from experiments.perf.env import bench_env as run

    counts = tuple(int_list(envs, "--envs", "env count", 1, MAX_WORKERS))
    bench = command_config(ctx, EnvBenchConfig, config_file=config)
    default = EnvBenchConfig().env
    given = [k for k in ROW_KEYS if getattr(bench.env, k) != getattr(default, k)]
    if given:
        set_here = ", ".join(f"env.{k}={getattr(bench.env, k)!r}" for k in given)
        raise fail(f"{set_here}: each row sets {', '.join(ROW_KEYS)} itself", ctx)
    base, scene = bench.env, bench.env.scene
    if breakdown:
        parts = [
            step_breakdown(
                replace(base, dvs=d, frames=f, keyframe_px=px), bench.seconds, bench.seed
            )
            for d in ("ideal", "speck")
            for f, px in (("exact", None), ("keyframes", None), ("keyframes", base.keyframe_px))
        ]
        print_table(
            f"One env's step, scene '{scene}' (ms per step unless named)",
            parts,
            BREAKDOWN_COLUMNS,
        )
    rows = run(bench, env_counts=counts)
    bound = "no bound" if base.keyframe_px is None else f"{base.keyframe_px:g} px"
    modes = (
        f"exact, keyframe and adaptive-keyframe frames ({bound}) stepped in turn, "
        "then the adaptive env (the default keys) stepped alone through the same steps"
    )
    print_table(
        f"Environment, scene '{scene}': {modes} (real-time factor = simulated s / wall s; "
        "speedup = exact / keyframes step time; dvs fps: the machine's speed just before, "
        "`wander perf dvs`'s 128x128 moving row; load: the 1-minute load average at "
        "start-end)",
        rows,
        ENV_COLUMNS,
    )
    print_table(
        "The same steps' wall and CPU time (ms per step; cpu: this process's, NaN with "
        "worker processes)",
        rows,
        ENV_TIME_COLUMNS,
    )
    print_table(
        "The same steps' renders and events (diff: keyframes and adaptive against exact; "
        "alone against in turn)",
        rows,
        ENV_COUNT_COLUMNS,
    )


@app.command("agent")
def bench_agent(
    ctx: typer.Context,
    scene: SceneOpt = None,
    seconds: seconds_flag("Simulated seconds of closed loop (default: the config's, 5).") = None,
    seed: seed_flag("Seed of the env and the agent (default: the config's, 0).") = None,
    keyframe_ms: KeyframeMsOpt = None,
    config: ConfigFileOpt = None,
    set_: SetOpt = None,
) -> None:
    """Per-step latency of sOMS, proto-object, sAC and the whole agent; closed-loop RTF
    with exact and keyframe frames side by side. Unset flags take AgentBenchConfig's
    values (`--set agent.KEY=VALUE` reaches every agent parameter)."""
    from experiments.perf.agent import (
        LATENCY_COLUMNS,
        LOOP_COLUMNS,
        MODES_COLUMNS,
        AgentBenchConfig,
        loop_modes,
    )
    from experiments.perf.agent import bench_agent as run

    bench = command_config(ctx, AgentBenchConfig, config_file=config)
    rows, loop = run(bench)
    print_table("Agent latency at 128x128 (ms per call)", rows, LATENCY_COLUMNS)
    print_table(
        "Closed loop (env + agent, the env's default frames; real-time factor = simulated s "
        "/ wall s; dvs fps: the machine's speed just before, `wander perf dvs`'s 128x128 "
        "moving row)",
        [loop],
        LOOP_COLUMNS,
    )
    both = loop_modes(bench)
    print_table(
        "Closed loop, exact vs keyframe frames stepped alternately (speedup = keyframes RTF / "
        "exact RTF)",
        [both],
        MODES_COLUMNS,
    )


@app.command("floor")
def bench_floor(
    scene: SceneOpt = "office",
    calls: Annotated[int, typer.Option(callback=int_range(1), help="Calls per timed run.")] = 100,
    repeats: TimedRepeatsOpt = 5,
) -> None:
    """What one render of a key costs here, the real-time factor the renders a step need
    leave room for, and a per-tick panorama warp (a prototype) against them."""
    import os
    import time

    from experiments.perf.floor import BOUND_COLUMNS, FLOOR_COLUMNS, render_floor

    t0 = time.perf_counter()
    rows, bounds = render_floor(scene=scene, calls=calls, repeats=repeats)
    print_table(f"The parts of a step, scene '{scene}' (ms per call)", rows, FLOOR_COLUMNS)
    print_table(
        "GL passes a step needs and the real-time factor they allow (control period / GL ms)",
        bounds,
        BOUND_COLUMNS,
    )
    load = ", ".join(f"{v:.2f}" for v in os.getloadavg())
    console.print(f"{time.perf_counter() - t0:.0f} s; load average {load}")


@app.command("panorama")
def bench_panorama(
    scene: SceneOpt = "office",
    steps: Annotated[
        int, typer.Option(callback=int_range(1), help="Timed steps per mode and motion.")
    ] = 20,
) -> None:
    """The panorama frame source against the default, exact and 16 samples a pixel (ms a
    step, modes stepped in turns), and its background against a render by headlight."""
    import os

    from experiments.perf.panorama import headlight_rows, step_rows

    load = os.getloadavg()[0]
    rows = step_rows(scene, steps)
    print_table(
        f"ms a step in '{scene}', seed 0, the modes stepped in turns (x default: ratio to "
        f"the default in this run; load average {load:.2f} -> {os.getloadavg()[0]:.2f})",
        rows,
        {"motion": "", "frames": "", "ms_per_step": ".1f", "x_default": ".2f", "reset_ms": ".0f"},
    )
    print_table(
        f"The panorama's background at reset against a render at the same pose, '{scene}' "
        "(|d ln lum| over the static world's pixels)",
        headlight_rows(scene),
        {
            "headlight": "",
            "median": ".4f",
            "mean": ".4f",
            "p95": ".3f",
            "lum_panorama": ".4f",
            "lum_render": ".4f",
        },
    )


def _check_fidelity_seconds(value: float) -> float:
    """``wander perf fidelity --seconds``: a whole number (>= 1) of the env's control
    periods, at most :data:`MAX_FIDELITY_SECONDS`."""
    from wander_env.env_config import WanderConfig

    period = WanderConfig.control_period_s
    steps = value / period
    if not (
        math.isfinite(value)
        and 1 <= round(steps)
        and abs(steps - round(steps)) < 1e-9
        and value <= MAX_FIDELITY_SECONDS
    ):
        raise typer.BadParameter(
            f"must be a whole number of {period:g} s control periods in [{period:g}, "
            f"{MAX_FIDELITY_SECONDS:g}] seconds, got {value!r}"
        )
    return value


def _check_reference_hz(value: float) -> float:
    """``wander perf fidelity --reference-hz``: finite, at most :data:`MAX_REFERENCE_HZ`,
    a rate the env takes (:class:`wander_env.env_config.WanderConfig`'s checks: a whole
    number of ticks a control period, keys on ticks)."""
    from wander_env.env_config import WanderConfig

    if not (math.isfinite(value) and 0 < value <= MAX_REFERENCE_HZ):
        raise typer.BadParameter(
            f"must be a finite number of Hz in (0, {MAX_REFERENCE_HZ:g}], got {value!r}"
        )
    try:
        WanderConfig(render_rate_hz=value)
    except ValueError as err:
        raise typer.BadParameter(str(err)) from None
    return value


@app.command("fidelity")
def bench_fidelity(
    scenes: Annotated[
        str, typer.Option(help="Comma-separated scenes (or scene files), none twice.")
    ] = "office,hand,shelf,gratings",
    motions: Annotated[
        str, typer.Option(help="Comma-separated, none twice: still, walk, saccade.")
    ] = "still,walk,saccade",
    seeds: SeedsOpt = "0,1,2",
    seconds: Annotated[
        float,
        typer.Option(
            callback=_check_fidelity_seconds,
            help="Simulated seconds per run: a whole number of control periods (10 ms), at "
            f"most {MAX_FIDELITY_SECONDS:g}.",
        ),
    ] = 0.1,
    reference_hz: Annotated[
        float,
        typer.Option(
            callback=_check_reference_hz,
            help="Render ticks per second of the reference: a whole number of ticks a 10 ms "
            f"control period, at most {MAX_REFERENCE_HZ:g}.",
        ),
    ] = 4000.0,
    reference_supersample: Annotated[
        int,
        typer.Option(
            callback=int_range(1, 8),
            help="Supersampling of the reference, 1 to 8 (x the scenes' MSAA).",
        ),
    ] = 4,
) -> None:
    """Every frame mode (exact, 16 samples, the default, the default at quality fine, one
    key a step, the panorama) against a fine reference on the same seeds: events,
    count-map L1, matched events, saccade gaps, renders; and the default's bar against
    exact, with fine's L1 bar."""
    import os
    import time

    from experiments.perf.fidelity import (
        BAR_COLUMNS,
        MODE_COLUMNS,
        MOTIONS,
        bar_cells,
        mode_cells,
    )
    from experiments.perf.fidelity import bench_fidelity as run

    scene_names = comma_list(scenes, "--scenes", "scene", "office,hand", check_scene)
    names = comma_list(motions, "--motions", "motion", "still,walk", one_of(MOTIONS))
    seed_values = seed_list(seeds)
    t0 = time.perf_counter()
    rows = run(
        scenes=tuple(scene_names),
        motions=tuple(names),
        seeds=tuple(seed_values),
        seconds=seconds,
        reference_hz=reference_hz,
        reference_supersample=reference_supersample,
        progress=lambda msg: console.print(f"  {msg}", style="dim"),
    )
    wall = time.perf_counter() - t0
    samples = 4 * reference_supersample**2
    print_table(
        f"Frame modes against the reference ({samples} samples a pixel at "
        f"{reference_hz:g} Hz ticks), {seconds:g} s per run, seeds {seeds}; each cell: "
        "events vs the reference / per-step count-map L1 over the reference's events / "
        "matched (share of the reference's events with one at the same pixel and polarity "
        "within 1 ms) / longest event gap in a saccade, ms / RGB renders a step",
        [mode_cells(r) for r in rows],
        MODE_COLUMNS,
    )
    print_table(
        "The bar, default frames against exact (|events dev| <= exact's + 2 points; L1 <= "
        "1.1 x exact's; matched >= exact's - 3 points; no gap > 2 ms in a saccade); "
        "default vs exact pct: the old comparison, exact's events the default matches; fine "
        "l1: quality fine's L1 <= 0.75 x exact's",
        [bar_cells(r) for r in rows],
        BAR_COLUMNS,
    )
    console.print(
        f"{len(rows)} rows in {wall:.0f} s wall, load average "
        + " ".join(f"{x:.2f}" for x in os.getloadavg())
        + f" ({os.cpu_count()} cores)"
    )


@app.command("formats")
def bench_formats(
    files: Annotated[
        list[Path] | None,
        typer.Argument(help="Event files (.aedat4 .raw .dat .es); default: ../shared/realdata."),
    ] = None,
    repeats: Annotated[
        int, typer.Option(callback=int_range(1), help="Timed decodes per row (median).")
    ] = 3,
) -> None:
    """Decode real event files with every installed library: speed and agreement."""
    from experiments.perf.formats import COLUMNS, default_files
    from experiments.perf.formats import bench_formats as run

    paths = files or default_files(Path(__file__).resolve().parents[3] / "shared" / "realdata")
    try:
        rows, skipped = run(paths, repeats)
    except (ValueError, OSError) as err:
        console.print(f"wander perf formats: {err}", markup=False)
        raise typer.Exit(2) from None
    print_table(
        "Event-file decoders (differ: events that disagree with the reference"
        + (f"; not installed: {', '.join(skipped)}" if skipped else "")
        + ")",
        rows,
        COLUMNS,
    )
