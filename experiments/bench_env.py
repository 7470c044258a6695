"""Benchmark of the simulated environment: real-time factor (simulated s per wall s).

Run it as ``wander bench env``. The camera holds still while the scene's objects
move (zero actions), at 1 kHz rendering; one row per DVS preset and number of
environments (1 in-process; 2 and 4 as ``AsyncVectorEnv`` worker processes).
The real-time factor of a vector row counts the simulated time of all its envs.

:func:`step_breakdown` splits one env's step into its parts (renders, DVS,
segmentation, posing the model, the rest) by timing those calls in place.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import gymnasium as gym
import numpy as np

import wander_env  # noqa: F401  (registers the environments)
from wander_env.wrappers import EventPacketInfo


@dataclass
class EnvBenchRow:
    scene: str
    dvs: str
    envs: int
    ground_truth: bool
    realtime_factor: float
    ms_per_step: float
    frames_per_s: float
    events_per_s: float


def _make(scene: str, dvs: str, ground_truth: bool, antialias_samples: int | None = None):
    kw = {} if antialias_samples is None else {"antialias_samples": antialias_samples}
    return lambda: EventPacketInfo(
        gym.make("wander/Wander-v0", scene=scene, dvs=dvs, ground_truth=ground_truth, **kw)
    )


def bench_env(
    scene: str = "office",
    seconds: float = 2.0,
    presets: tuple[str, ...] = ("ideal", "speck"),
    env_counts: tuple[int, ...] = (1, 2, 4),
    ground_truth: bool = True,
    seed: int = 0,
    antialias_samples: int | None = None,
) -> list[EnvBenchRow]:
    """One row per preset and env count; ``antialias_samples`` overrides the scene's."""
    rows = []
    for dvs in presets:
        make = _make(scene, dvs, ground_truth, antialias_samples)
        for n in env_counts:
            if n == 1:
                env = make()
            else:
                env = gym.vector.AsyncVectorEnv([make] * n, context="spawn")
            env.reset(seed=seed)
            period = env.unwrapped.config.control_period_s if n == 1 else 0.01
            steps = round(seconds / period)
            action = np.zeros((n, 2) if n > 1 else 2, np.float32)
            env.step(action)  # warm-up: kernels compiled, contexts made
            frames = events = 0
            t0 = time.perf_counter()
            for _ in range(steps):
                obs, _, _, _, info = env.step(action)
                events += int(obs["events"].sum())
                frames += int(np.sum(info["frames"]))
            wall = time.perf_counter() - t0
            env.close()
            rows.append(
                EnvBenchRow(
                    scene=scene,
                    dvs=dvs,
                    envs=n,
                    ground_truth=ground_truth,
                    realtime_factor=n * steps * period / wall,
                    ms_per_step=1e3 * wall / steps,
                    frames_per_s=frames / wall,
                    events_per_s=events / wall,
                )
            )
    return rows


@dataclass
class StepBreakdown:
    """Where one env's step goes: ms per step of each part, and per render call."""

    scene: str
    dvs: str
    antialias_samples: int
    ms_per_step: float
    frames_per_step: float
    ms_per_render: float
    render_ms: float  # RGB frames: the render ticks and the adaptive sub-frames
    dvs_ms: float  # frame -> log input, change check, emulator step
    segment_ms: float  # the ground-truth mask (one per step)
    pose_ms: float  # PTU angles and objects into the model, kinematics
    other_ms: float  # the rest: PTU model, events to counts, info


def timed(fn: Callable[..., Any], acc: dict[str, list[float]], key: str) -> Callable[..., Any]:
    """``fn`` wrapped so that each call's duration (s) is appended to ``acc[key]``."""

    def wrapper(*args: Any, **kwargs: Any) -> Any:
        t = time.perf_counter()
        try:
            return fn(*args, **kwargs)
        finally:
            acc[key].append(time.perf_counter() - t)

    return wrapper


def step_breakdown(
    scene: str = "office",
    dvs: str = "ideal",
    seconds: float = 2.0,
    antialias_samples: int | None = None,
    seed: int = 0,
) -> StepBreakdown:
    """Time the parts of :meth:`WanderEnv.step` in one env (zero actions, as bench_env)."""
    env = _make(scene, dvs, True, antialias_samples)()
    u = env.unwrapped
    acc: dict[str, list[float]] = {k: [] for k in ("render", "dvs", "segment", "pose")}
    u.renderer.render = timed(u.renderer.render, acc, "render")
    u.renderer.segment = timed(u.renderer.segment, acc, "segment")
    for name in ("prepare", "log_change", "step"):
        if hasattr(u.dvs, name):  # prepare: since the fused log input
            setattr(u.dvs, name, timed(getattr(u.dvs, name), acc, "dvs"))
    u._pose = timed(u._pose, acc, "pose")
    env.reset(seed=seed)
    action = np.zeros(2, np.float32)
    env.step(action)  # warm-up
    for v in acc.values():
        v.clear()
    steps = round(seconds / u.config.control_period_s)
    t0 = time.perf_counter()
    for _ in range(steps):
        env.step(action)
    wall = time.perf_counter() - t0
    env.close()
    ms = {k: 1e3 * sum(v) / steps for k, v in acc.items()}
    return StepBreakdown(
        scene=scene,
        dvs=dvs,
        antialias_samples=u.scene.camera.antialias_samples,
        ms_per_step=1e3 * wall / steps,
        frames_per_step=len(acc["render"]) / steps,
        ms_per_render=1e3 * sum(acc["render"]) / max(len(acc["render"]), 1),
        render_ms=ms["render"],
        dvs_ms=ms["dvs"],
        segment_ms=ms["segment"],
        pose_ms=ms["pose"],
        other_ms=1e3 * wall / steps - sum(ms.values()),
    )
