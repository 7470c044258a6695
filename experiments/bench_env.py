"""Benchmark of the simulated environment: real-time factor (simulated s per wall s).

Run it as ``wander bench env``. The camera holds still while the scene's objects
move (zero actions), at 1 kHz rendering; one row per DVS preset and number of
environments (1 in-process; 2 and 4 as ``AsyncVectorEnv`` worker processes).
The real-time factor of a vector row counts the simulated time of all its envs.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

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


def _make(scene: str, dvs: str, ground_truth: bool):
    return lambda: EventPacketInfo(
        gym.make("wander/Wander-v0", scene=scene, dvs=dvs, ground_truth=ground_truth)
    )


def bench_env(
    scene: str = "office",
    seconds: float = 2.0,
    presets: tuple[str, ...] = ("ideal", "speck"),
    env_counts: tuple[int, ...] = (1, 2, 4),
    ground_truth: bool = True,
    seed: int = 0,
) -> list[EnvBenchRow]:
    rows = []
    for dvs in presets:
        for n in env_counts:
            if n == 1:
                env = _make(scene, dvs, ground_truth)()
            else:
                env = gym.vector.AsyncVectorEnv(
                    [_make(scene, dvs, ground_truth)] * n, context="spawn"
                )
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
