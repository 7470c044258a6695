"""Benchmark of the DVS emulator: frames/s and events/s by sensor, scene and noise.

Run it as ``wander bench dvs``. Frames are made before timing starts; the first
call compiles the kernels and is not timed. Each row is the median of
``repeats`` runs over ``n_frames`` frames at 1 kHz.
"""

from __future__ import annotations

import statistics
import time
import tracemalloc
from dataclasses import dataclass

import numpy as np

from wander_env.dvs import DVSEmulator, DVSParams
from wander_env.synthetic import drifting_texture

# Drift speeds (px/frame) that give about 1,000 and 4,000 events per frame with `ideal`.
SENSORS = {(128, 128): 0.25, (346, 260): 0.2}
NOISE_PRESET = "speck"  # every noise term on: mismatch, low-pass, refractory, latency,
# jitter, leak, shot noise and hot pixels


@dataclass
class DVSBenchRow:
    sensor: str
    scene: str
    noise: str
    frames_per_s: float
    mev_per_s: float
    events_per_frame: float
    on_frame_time_pct: float  # events stamped exactly on a frame time (interpolation check)
    peak_mib: float


def _run(emu: DVSEmulator, frames: np.ndarray) -> tuple[float, int, int]:
    """Seconds taken, events, and events stamped exactly on a frame time."""
    emu.reset(frames[0], 0)
    n = on_frame = 0
    t = time.perf_counter()
    for i in range(1, len(frames)):
        ev = emu.step(frames[i], i * 1000)
        n += len(ev)
        on_frame += int(np.count_nonzero(ev["t"] % 1000 == 0))
    return time.perf_counter() - t, n, on_frame


def bench_dvs(n_frames: int = 1000, repeats: int = 3, seed: int = 0) -> list[DVSBenchRow]:
    rows = []
    for (w, h), speed in SENSORS.items():
        moving = drifting_texture(w, h, n_frames + 1, speed, seed=seed)
        static = np.repeat(moving[:1], n_frames + 1, axis=0)
        for scene, frames in (("static", static), ("moving", moving)):
            noises = (("ideal", DVSParams()), ("all on", DVSParams.preset(NOISE_PRESET)))
            for noise, params in noises:
                emu = DVSEmulator(w, h, params, seed=seed)
                _run(emu, frames[:3])  # compile
                times, count, on_frame = [], 0, 0
                for _ in range(repeats):
                    dt, count, on_frame = _run(emu, frames)
                    times.append(dt)
                dt = statistics.median(times)
                # Peak memory from a separate run: tracing allocations slows them down.
                tracemalloc.start()
                _run(emu, frames)
                peak = tracemalloc.get_traced_memory()[1] / 2**20
                tracemalloc.stop()
                rows.append(
                    DVSBenchRow(
                        sensor=f"{w}x{h}",
                        scene=scene,
                        noise=noise,
                        frames_per_s=n_frames / dt,
                        mev_per_s=count / dt / 1e6,
                        events_per_frame=count / n_frames,
                        on_frame_time_pct=100 * on_frame / max(count, 1),
                        peak_mib=peak,
                    )
                )
    return rows
