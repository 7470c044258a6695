"""Benchmark of the simulated environment: real-time factor (simulated s per wall s).

Run it as ``wander perf env``. The camera holds still while the scene's objects
move (zero actions), at 1 kHz rendering; one row per DVS preset and number of
environments (1 in-process; 2 and 4 as ``AsyncVectorEnv`` worker processes), with the
frame modes (``exact``, ``keyframes`` at a fixed interval, ``adaptive``: the env's
default keys) stepped in turns and their step-time ratio, then the exact and the
adaptive env each stepped alone (the same steps again from its reset): in turns, each
env's caches and the CPU's are shared with the others, and the default's render thread
draws its next step's keys ahead (:mod:`wander_env.frames.keyframes`) while the other
modes step, which in turns hides its work in their times; the alone columns (and their
speedup, exact alone / adaptive alone) are the figures to read.
The real-time factor of a vector row counts the simulated time of all its envs.
Beside each wall time, the process's CPU time of the same steps (NaN in a vector row:
its workers' time is not this process's) and the load average around the row
(:mod:`experiments.perf.clock`).

:func:`step_breakdown` splits one env's step into its parts (renders, DVS,
segmentation, posing the model, the rest) by timing those calls in place.

What runs is an :class:`EnvBenchConfig`: the env's block every row starts from (each row
sets its DVS preset and frame mode on it), the simulated seconds of a row and the seed;
``wander perf env`` builds it through the command line's one layered path
(:func:`experiments.cli.options.command_config`).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Annotated, Any

import gymnasium as gym
import numpy as np

import wander_env  # noqa: F401  (registers the environments)
from experiments.analysis.stats import real_time_factor
from experiments.perf.clock import LOAD_COLUMN, Clock, Measured, Timings, timed
from experiments.perf.dvs import CALIBRATION_COLUMN, calibration_fps
from experiments.studies.framework import MAX_SEED
from wander_env.env_config import WanderConfig
from wander_env.field_doc import field_doc

#: The env keys each row of ``wander perf env`` sets itself (not the config's to set).
ROW_KEYS = ("dvs", "frames")

# The columns of `wander perf env`'s tables (row field -> format spec).
BREAKDOWN_COLUMNS: dict[str, str] = {
    "dvs": "",
    "frames": "",
    "antialias_samples": "d",
    "ms_per_step": ".2f",
    "cpu_ms_per_step": ".2f",
    "renders_per_step": ".1f",
    "ms_per_render": ".2f",
    "render_ms": ".2f",
    "synth_ms": ".2f",
    "dvs_ms": ".2f",
    "segment_ms": ".2f",
    "pose_ms": ".2f",
    "other_ms": ".2f",
    **LOAD_COLUMN,
}
# `wander perf env`'s rows as three tables: real-time factors, times, counts.
ENV_COLUMNS: dict[str, str] = {
    "dvs": "",
    "envs": "d",
    "exact_rtf": ".2f",
    "keyframes_rtf": ".2f",
    "adaptive_rtf": ".2f",
    "adaptive_alone_rtf": ".2f",
    "exact_alone_rtf": ".2f",
    "speedup": ".2f",
    "adaptive_speedup": ".2f",
    "alone_speedup": ".2f",
    **CALIBRATION_COLUMN,
    **LOAD_COLUMN,
}
ENV_TIME_COLUMNS: dict[str, str] = {
    "dvs": "",
    "envs": "d",
    "exact_ms_per_step": ".1f",
    "exact_cpu_ms_per_step": ".1f",
    "keyframes_ms_per_step": ".1f",
    "keyframes_cpu_ms_per_step": ".1f",
    "adaptive_ms_per_step": ".1f",
    "adaptive_cpu_ms_per_step": ".1f",
    "adaptive_alone_ms_per_step": ".1f",
    "adaptive_alone_cpu_ms_per_step": ".1f",
    "exact_alone_ms_per_step": ".1f",
    **LOAD_COLUMN,
}
ENV_COUNT_COLUMNS: dict[str, str] = {
    "dvs": "",
    "envs": "d",
    "ground_truth": "",
    "keyframe_ms": "g",
    "exact_renders_per_step": ".1f",
    "keyframes_renders_per_step": ".1f",
    "adaptive_renders_per_step": ".1f",
    "events_diff_pct": "+.2f",
    "adaptive_events_diff_pct": "+.2f",
    "adaptive_alone_events_diff_pct": "+.2f",
}


@dataclass(frozen=True)
class EnvBenchRow(Measured):
    """One DVS preset and env count, both frame modes measured side by side."""

    scene: str
    dvs: str
    envs: int
    ground_truth: bool
    keyframe_ms: float
    exact_rtf: float  # real-time factor (simulated s / wall s) of frames="exact"
    keyframes_rtf: float
    speedup: float  # exact ms per step / keyframes ms per step
    exact_ms_per_step: float
    keyframes_ms_per_step: float
    exact_frames_per_step: float  # frames fed to the DVS (ticks + adaptive sub-frames)
    keyframes_frames_per_step: float
    events_diff_pct: float  # keyframes vs exact events over the run
    # Adaptive keys (WanderConfig.keyframe_px), measured in the same loop.
    keyframe_px: float = float("nan")
    adaptive_rtf: float = float("nan")
    adaptive_speedup: float = float("nan")  # exact ms per step / adaptive ms per step
    adaptive_ms_per_step: float = float("nan")
    adaptive_events_diff_pct: float = float("nan")
    exact_renders_per_step: float = float("nan")  # RGB renders (frames drawn)
    keyframes_renders_per_step: float = float("nan")
    adaptive_renders_per_step: float = float("nan")
    # CPU time of this process for the same steps (NaN for a vector env: its workers').
    exact_cpu_ms_per_step: float = float("nan")
    keyframes_cpu_ms_per_step: float = float("nan")
    adaptive_cpu_ms_per_step: float = float("nan")
    # The adaptive env stepped alone (the same steps again from its reset).
    adaptive_alone_rtf: float = float("nan")
    adaptive_alone_ms_per_step: float = float("nan")
    adaptive_alone_cpu_ms_per_step: float = float("nan")
    adaptive_alone_events_diff_pct: float = float("nan")  # against its events in turns
    # The exact env stepped alone too; exact alone ms per step / adaptive alone's.
    exact_alone_rtf: float = float("nan")
    exact_alone_ms_per_step: float = float("nan")
    alone_speedup: float = float("nan")
    dvs_fps: float = float("nan")  # the machine's speed just before the row (calibration_fps)


@dataclass(frozen=True)
class EnvBenchConfig:
    """What ``wander perf env`` measures: the env's block every row starts from (its
    scene, ground truth, antialiasing, ``keyframe_ms`` and the adaptive column's
    ``keyframe_px``; each row sets :data:`ROW_KEYS` itself), the simulated seconds each
    row steps, and the seed."""

    env: WanderConfig = field(default_factory=WanderConfig)
    seconds: Annotated[
        float, field_doc("Simulated seconds each row steps", unit="s", gt=0, le=86400)
    ] = 2.0
    seed: Annotated[int, field_doc("Seed of the envs' resets", ge=0, le=MAX_SEED)] = 0


def _make(env: WanderConfig):
    return lambda: gym.make("wander/Wander-v0", **env)


def _scene_name(env: WanderConfig) -> str:
    """The scene's name for the tables (a scene config's own name)."""
    return env.scene if isinstance(env.scene, str) else env.scene.name


def bench_env(
    config: EnvBenchConfig,
    presets: tuple[str, ...] = ("ideal", "speck"),
    env_counts: tuple[int, ...] = (1, 2, 4),
) -> list[EnvBenchRow]:
    """One row per preset and env count, each env the config's with the row's preset.

    The frame modes (exact, keyframes every ``env.keyframe_ms``, adaptive keys bounded by
    ``env.keyframe_px``) run in one process at once, stepped in turn (one step of each,
    the order rotated every step), so that a noisy machine slows all alike; each step is
    timed (wall and CPU). Then the exact and the adaptive env are each reset and stepped
    alone through the same steps.
    """
    base, seconds, seed = config.env, config.seconds, config.seed
    km, keyframe_px, ground_truth = base.keyframe_ms, base.keyframe_px, base.ground_truth
    modes = {
        "exact": {"frames": "exact"},
        "keyframes": {"frames": "keyframes", "keyframe_px": None},
        "adaptive": {"frames": "keyframes"},
    }
    rows = []
    for dvs in presets:
        for n in env_counts:
            dvs_fps = calibration_fps()
            envs = {}
            for mode, kw in modes.items():
                make = _make(replace(base, dvs=dvs, **kw))
                envs[mode] = (
                    make() if n == 1 else gym.vector.AsyncVectorEnv([make] * n, context="spawn")
                )
            period = base.control_period_s
            steps = round(seconds / period)
            action = np.zeros((n, 2) if n > 1 else 2, np.float32)
            clocks = {m: Clock() for m in modes}
            row_clock = Clock()
            frames = dict.fromkeys(modes, 0)
            renders = dict.fromkeys(modes, 0)
            events = dict.fromkeys(modes, 0)
            try:
                for env in envs.values():
                    env.reset(seed=seed)
                    env.step(action)  # warm-up: kernels compiled, contexts made
                order = list(envs.items())
                for k in range(steps):  # each step in a rotated order: none always first
                    j = k % len(order)
                    for mode, env in order[j:] + order[:j]:
                        with clocks[mode].span(), row_clock.span():
                            obs, _, _, _, info = env.step(action)
                        events[mode] += int(obs["events"].sum())
                        frames[mode] += int(np.sum(info["frames"]))
                        renders[mode] += _renders(env)
                alone = {m: Clock() for m in ("exact", "adaptive")}
                alone_events = 0
                for mode, clock in alone.items():
                    env = envs[mode]
                    env.reset(seed=seed)
                    env.step(action)  # as in turns: the warm-up step first
                    for _ in range(steps):
                        with clock.span(), row_clock.span():
                            obs = env.step(action)[0]
                        if mode == "adaptive":
                            alone_events += int(obs["events"].sum())
            finally:
                for env in envs.values():
                    env.close()
            wall = {m: c.wall_s for m, c in clocks.items()}
            sim_s = n * steps * period  # of all the envs
            ms = {m: 1e3 * wall[m] / steps for m in modes}
            cpu = {m: c.ms_per(steps)[1] if n == 1 else float("nan") for m, c in clocks.items()}

            def diff_pct(n: int, base: int) -> float:
                return 100.0 * (n / base - 1.0) if base else float("nan")

            rows.append(
                EnvBenchRow(
                    scene=_scene_name(base),
                    dvs=dvs,
                    envs=n,
                    ground_truth=ground_truth,
                    keyframe_ms=km,
                    exact_rtf=real_time_factor(sim_s, wall["exact"]),
                    keyframes_rtf=real_time_factor(sim_s, wall["keyframes"]),
                    speedup=ms["exact"] / ms["keyframes"],
                    exact_ms_per_step=ms["exact"],
                    keyframes_ms_per_step=ms["keyframes"],
                    exact_frames_per_step=frames["exact"] / (n * steps),
                    keyframes_frames_per_step=frames["keyframes"] / (n * steps),
                    events_diff_pct=diff_pct(events["keyframes"], events["exact"]),
                    keyframe_px=keyframe_px,
                    adaptive_rtf=real_time_factor(sim_s, wall["adaptive"]),
                    adaptive_speedup=ms["exact"] / ms["adaptive"],
                    adaptive_ms_per_step=ms["adaptive"],
                    adaptive_events_diff_pct=diff_pct(events["adaptive"], events["exact"]),
                    exact_renders_per_step=renders["exact"] / (n * steps),
                    keyframes_renders_per_step=renders["keyframes"] / (n * steps),
                    adaptive_renders_per_step=renders["adaptive"] / (n * steps),
                    exact_cpu_ms_per_step=cpu["exact"],
                    keyframes_cpu_ms_per_step=cpu["keyframes"],
                    adaptive_cpu_ms_per_step=cpu["adaptive"],
                    adaptive_alone_rtf=real_time_factor(sim_s, alone["adaptive"].wall_s),
                    adaptive_alone_ms_per_step=alone["adaptive"].ms_per(steps)[0],
                    adaptive_alone_cpu_ms_per_step=alone["adaptive"].ms_per(steps)[1]
                    if n == 1
                    else float("nan"),
                    adaptive_alone_events_diff_pct=diff_pct(alone_events, events["adaptive"]),
                    exact_alone_rtf=real_time_factor(sim_s, alone["exact"].wall_s),
                    exact_alone_ms_per_step=alone["exact"].ms_per(steps)[0],
                    alone_speedup=alone["exact"].wall_s / alone["adaptive"].wall_s,
                    dvs_fps=dvs_fps,
                    load=row_clock.load,
                )
            )
    return rows


def _renders(env: Any) -> int:
    """RGB renders of the last step, summed over a vector env's sub-envs."""
    if isinstance(env, gym.vector.VectorEnv):
        return int(sum(env.get_attr("renders_in_step")))
    return int(env.unwrapped.renders_in_step)


@dataclass(frozen=True)
class StepBreakdown(Measured):
    """Where one env's step goes: ms per step of each part, and per render call."""

    scene: str
    dvs: str
    frames: str
    antialias_samples: int
    ms_per_step: float
    cpu_ms_per_step: float  # the process's CPU time a step
    renders_per_step: float
    ms_per_render: float
    render_ms: float  # RGB frames: render ticks and sub-frames (exact), keyframes
    synth_ms: float  # in-between frames made from the keys (keyframes mode)
    dvs_ms: float  # frame -> log input, change check, emulator step
    segment_ms: float  # ground truth's masks and keys' layers + depth (drawn or ray cast)
    pose_ms: float  # PTU angles and objects into the model, kinematics
    other_ms: float  # the rest: PTU model, events to counts, info


def step_breakdown(env_config: WanderConfig, seconds: float, seed: int = 0) -> StepBreakdown:
    """Time the parts of :meth:`WanderEnv.step` in one env of ``env_config`` (zero
    actions, as bench_env) for ``seconds``; keyframes with a ``keyframe_px`` are adaptive
    keys (its row's ``frames`` reads ``adaptive``)."""
    frames, keyframe_px = env_config.frames, env_config.keyframe_px
    env = _make(env_config)()
    u = env.unwrapped
    keys = ("render", "dvs", "segment", "pose", "synth")
    acc = Timings()
    stage, renderer = u.stage, u.stage.renderer
    renderer.render = timed(renderer.render, acc, "render")
    renderer.segment = timed(renderer.segment, acc, "segment")
    renderer.segment_depth_current = timed(renderer.segment_depth_current, acc, "segment")
    if stage.caster is not None:  # ray-cast masks and key geometry (wander_env.frames.raycast)
        stage.caster.object_mask = timed(stage.caster.object_mask, acc, "segment")
        stage.caster.geometry = timed(stage.caster.geometry, acc, "segment")
    if hasattr(u.source, "synthesize"):  # in-between frames (keyframes)
        u.source.synthesize = timed(u.source.synthesize, acc, "synth")
    for name in ("prepare", "log_change", "step"):
        setattr(u.dvs, name, timed(getattr(u.dvs, name), acc, "dvs"))
    stage.pose = timed(stage.pose, acc, "pose")  # every full pose goes through it
    stage.camera_views = timed(stage.camera_views, acc, "pose")  # the camera alone
    env.reset(seed=seed)
    action = np.zeros(2, np.float32)
    env.step(action)  # warm-up
    acc.clear()
    steps = round(seconds / u.config.control_period_s)
    clock = Clock()
    for _ in range(steps):
        with clock.span():
            env.step(action)
    wall = clock.wall_s
    env.close()
    ms = {k: 1e3 * sum(acc.wall.get(k, [])) / steps for k in keys}
    n_renders = len(acc.wall.get("render", []))
    synth = ms["synth"]
    parts = ms["render"] + synth + ms["dvs"] + ms["segment"] + ms["pose"]
    return StepBreakdown(
        scene=_scene_name(env_config),
        dvs=env_config.dvs,
        frames="adaptive" if frames == "keyframes" and keyframe_px is not None else frames,
        antialias_samples=u.scene.camera.antialias_samples,
        ms_per_step=1e3 * wall / steps,
        cpu_ms_per_step=clock.ms_per(steps)[1],
        renders_per_step=n_renders / steps,
        ms_per_render=1e3 * sum(acc.wall.get("render", [])) / max(n_renders, 1),
        render_ms=ms["render"],
        synth_ms=synth,
        dvs_ms=ms["dvs"],
        segment_ms=ms["segment"],
        pose_ms=ms["pose"],
        other_ms=1e3 * wall / steps - parts,
        load=clock.load,
    )
