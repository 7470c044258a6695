"""Benchmark of the DVS emulator: frames/s and events/s by sensor, scene and noise; the
8-bit sRGB input path against the linear one; and, with ``--peers``, other emulators on
the same frames.

Run it as ``wander perf dvs [--peers]``. Frames are made before timing starts; the
first call compiles the kernels and is not timed. Each row is the median of ``repeats``
runs over ``n_frames`` frames at 1 kHz. Rows compared by a ratio are timed in turns,
frame by frame (frame i through every emulator, then frame i + 1), and a row's time is
the sum over frames of the median over the repeats: a stall of this shared machine
falls on one sample of one row, not on its total. Beside each frame rate (wall time),
the rate by the process's CPU time and the load average around the row's runs
(:mod:`experiments.perf.clock`).

Input paths (:func:`bench_inputs`): the moving pattern as uint8 sRGB, as its grey
channel (uint8) and as float32 linear luminance — the emulator's own luminance of the
sRGB frames, so the sRGB and linear rows must give the same events.

Peers (:func:`bench_peers`): the same linear-luminance frames of the moving pattern go
through wander's emulator, evlib's ESIM (``evlib.simulation.ESIMSimulator``, PyPI
``evlib``) and v2e's ``EventEmulator`` (``v2ecore.emulator``; v2e is not on PyPI: it
is found when importable, e.g. installed from its GitHub repository), all with
threshold 0.2 ON and OFF and every noise term, low-pass and refractory period off, on
one torch thread. A peer that cannot be imported gets a row saying why.

Examples:
    >>> rows = bench_inputs(n_frames=5, repeats=1)  # doctest: +SKIP
"""

from __future__ import annotations

import logging
import statistics
import time
import tracemalloc
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from experiments.jobs.synthetic import drifting_texture
from experiments.perf.clock import LOAD_COLUMN, Clock, Measured
from wander_env.dvs import DVSEmulator, DVSParams

# Drift speeds (px/frame) that give about 1,000 and 4,000 events per frame with `ideal`.
SENSORS = {(128, 128): 0.25, (346, 260): 0.2}
NOISE_PRESET = "speck"  # every noise term on: mismatch, low-pass, refractory, latency,
# jitter, leak, shot noise and hot pixels
PEER_THRESHOLD = 0.2  # the contrast threshold every emulator gets in the peer comparison


#: The column of a speed table that gives the hour's machine speed (:func:`calibration_fps`).
CALIBRATION_COLUMN: dict[str, str] = {"dvs_fps": ",.0f"}

# The columns of `wander perf dvs`'s tables (row field -> format spec).
DVS_COLUMNS: dict[str, str] = {
    "sensor": "",
    "scene": "",
    "noise": "",
    "frames_per_s": ",.0f",
    "cpu_frames_per_s": ",.0f",
    "mev_per_s": ".2f",
    "events_per_frame": ",.0f",
    "on_frame_time_pct": ".1f",
    "peak_mib": ".1f",
    **LOAD_COLUMN,
}
INPUT_COLUMNS: dict[str, str] = {
    "sensor": "",
    "input": "",
    "frames_per_s": ",.0f",
    "cpu_frames_per_s": ",.0f",
    "events": ",d",
    "time_ratio": ".2f",
    **LOAD_COLUMN,
}
PEER_COLUMNS: dict[str, str] = {
    "sensor": "",
    "emulator": "",
    "frames_per_s": ",.0f",
    "cpu_frames_per_s": ",.0f",
    "wander_speedup": ".2f",
    "events": ",d",
    "events_diff_pct": "+.2f",
    **LOAD_COLUMN,
    "note": "",
}


@dataclass(frozen=True)
class DVSBenchRow(Measured):
    sensor: str
    scene: str
    noise: str
    frames_per_s: float
    mev_per_s: float
    events_per_frame: float
    on_frame_time_pct: float  # events stamped exactly on a frame time (interpolation check)
    peak_mib: float
    cpu_frames_per_s: float = float("nan")  # by the process's CPU time


@dataclass(frozen=True)
class InputPathRow(Measured):
    """One input format of the same moving pattern; ``time_ratio`` is this row's time per
    frame over the linear float32 row's (1.00: as fast)."""

    sensor: str
    input: str
    frames_per_s: float
    events: int
    time_ratio: float
    cpu_frames_per_s: float = float("nan")  # by the process's CPU time


@dataclass(frozen=True)
class PeerRow(Measured):
    """One emulator on the peer frames. ``wander_speedup`` = this emulator's time per
    frame / wander's; ``events_diff_pct`` = (events − wander's) / wander's, in %. The
    numbers are None (printed "–") when the emulator could not be run; ``note`` says why."""

    sensor: str
    emulator: str
    frames_per_s: float | None
    wander_speedup: float | None
    events: int | None
    events_diff_pct: float | None
    note: str
    cpu_frames_per_s: float | None = None  # by the process's CPU time


def _run(emu: DVSEmulator, frames: np.ndarray, clock: Clock | None = None) -> tuple[int, int]:
    """Events, and events stamped exactly on a frame time; the steps timed into
    ``clock``."""
    emu.reset(frames[0], 0)
    n = on_frame = 0
    with (clock or Clock()).span():
        for i in range(1, len(frames)):
            ev = emu.step(frames[i], i * 1000)
            n += len(ev)
            on_frame += int(np.count_nonzero(ev["t"] % 1000 == 0))
    return n, on_frame


def _timed_runs(
    emu: DVSEmulator, frames: np.ndarray, repeats: int, whole: Clock | None = None
) -> tuple[list[Clock], int, int]:
    """``repeats`` timed runs of ``frames`` after an untimed call on their first 3 (it
    compiles the kernels, or loads the cached ones): each run's clock (each also added to
    ``whole``), and the last run's events and events stamped on a frame time."""
    _run(emu, frames[:3])
    clocks: list[Clock] = []
    count = on_frame = 0
    for _ in range(repeats):
        clock = Clock()
        count, on_frame = _run(emu, frames, clock)
        if whole is not None:
            whole.add(clock.wall_s, clock.cpu_s)
        clocks.append(clock)
    return clocks, count, on_frame


def bench_dvs(n_frames: int = 1000, repeats: int = 3, seed: int = 0) -> list[DVSBenchRow]:
    rows = []
    for (w, h), speed in SENSORS.items():
        moving = drifting_texture(w, h, n_frames + 1, speed, seed=seed)
        static = np.repeat(moving[:1], n_frames + 1, axis=0)
        for scene, frames in (("static", static), ("moving", moving)):
            noises = (("ideal", DVSParams()), ("all on", DVSParams.preset(NOISE_PRESET)))
            for noise, params in noises:
                emu = DVSEmulator(w, h, params, seed=seed)
                whole = Clock()
                clocks, count, on_frame = _timed_runs(emu, frames, repeats, whole)
                dt = statistics.median(c.wall_s for c in clocks)
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
                        cpu_frames_per_s=n_frames
                        / max(statistics.median(c.cpu_s for c in clocks), 1e-12),
                        load=whole.load,
                    )
                )
    return rows


def calibration_fps(n_frames: int = 1000, repeats: int = 3, seed: int = 0) -> float:
    """The machine's speed at the hour of a measurement: the DVS emulator's frames/s
    (wall time, the median of ``repeats`` runs of ``n_frames`` frames) on the 128×128
    moving pattern with ideal pixels, the workload of :func:`bench_dvs`'s ``128x128
    moving ideal`` row. ``wander perf env`` and ``wander perf agent`` print it beside their
    real-time factors (column :data:`CALIBRATION_COLUMN`): this machine's speed drifts by
    up to 35 % within hours, on every part, while a real-time factor divided by this
    rate moved by about 6 % (``docs/benchmarks.md``)."""
    (w, h), speed = (128, 128), SENSORS[(128, 128)]
    frames = drifting_texture(w, h, n_frames + 1, speed, seed=seed)
    clocks, _, _ = _timed_runs(DVSEmulator(w, h, DVSParams(), seed=seed), frames, repeats)
    return n_frames / statistics.median(c.wall_s for c in clocks)


def linear_frames(frames: np.ndarray) -> np.ndarray:
    """The emulator's own linear luminance ``(n, H, W)`` float32 of uint8 sRGB frames
    ``(n, H, W, 3)``: fed back as float frames, they give the same events."""
    h, w = frames.shape[1:3]
    emu = DVSEmulator(w, h)
    return np.stack([emu.prepare(f).lum.reshape(h, w) for f in frames])


# A stepper: ``start(frames)`` resets an emulator on ``frames[0]`` and returns
# ``step(i) -> events`` for frame i >= 1.
Stepper = Callable[[], Callable[[int], int]]


def _wander_stepper(emu: DVSEmulator, frames: np.ndarray) -> Stepper:
    """Steps of ``emu`` through ``frames`` (1 kHz); the kernels are compiled first."""
    _run(emu, frames[:3])

    def start() -> Callable[[int], int]:
        emu.reset(frames[0], 0)
        return lambda i: len(emu.step(frames[i], i * 1000))

    return start


def _interleaved(steppers: dict[str, Stepper], n_frames: int, repeats: int):
    """Seconds per run of ``n_frames`` frames (wall, and the process's CPU), the events
    of each stepper and the load average around the runs, timed frame by frame in turns
    (frame i of every stepper, then frame i + 1): a run's time is the sum over frames of
    the median over ``repeats`` of that frame's time, so a stall of the machine lands on
    one sample of one stepper, not on its total."""
    times = {k: np.empty((repeats, n_frames)) for k in steppers}
    cpus = {k: np.empty((repeats, n_frames)) for k in steppers}
    events: dict[str, int] = {}
    whole = Clock()
    for r in range(repeats):
        steps = {k: start() for k, start in steppers.items()}
        counts = dict.fromkeys(steppers, 0)
        for i in range(1, n_frames + 1):
            for k, step in steps.items():
                t, c = time.perf_counter(), time.process_time()
                counts[k] += step(i)
                times[k][r, i - 1] = time.perf_counter() - t
                cpus[k][r, i - 1] = time.process_time() - c
                whole.add(times[k][r, i - 1], cpus[k][r, i - 1])
        events = counts

    def total(v: dict[str, np.ndarray]) -> dict[str, float]:
        return {k: float(np.median(a, axis=0).sum()) for k, a in v.items()}

    return total(times), total(cpus), events, whole.load


def bench_inputs(n_frames: int = 1000, repeats: int = 3, seed: int = 0) -> list[InputPathRow]:
    """The moving pattern (ideal pixels) as uint8 sRGB, uint8 grey and float32 linear."""
    rows = []
    for (w, h), speed in SENSORS.items():
        srgb = drifting_texture(w, h, n_frames + 1, speed, seed=seed)
        inputs = {
            "uint8 sRGB": srgb,
            "uint8 grey": np.ascontiguousarray(srgb[..., 1]),
            "float32 linear": linear_frames(srgb),
        }
        steppers = {
            k: _wander_stepper(DVSEmulator(w, h, DVSParams(), seed=seed), f)
            for k, f in inputs.items()
        }
        med, cpu, events, load = _interleaved(steppers, n_frames, repeats)
        for k in inputs:
            rows.append(
                InputPathRow(
                    sensor=f"{w}x{h}",
                    input=k,
                    frames_per_s=n_frames / med[k],
                    events=events[k],
                    time_ratio=med[k] / med["float32 linear"],
                    cpu_frames_per_s=n_frames / max(cpu[k], 1e-12),
                    load=load,
                )
            )
    return rows


# -- peers ---------------------------------------------------------------------------------


def _wander_peer(frames: np.ndarray, seed: int) -> Stepper:
    h, w = frames.shape[1:]
    p = PEER_THRESHOLD
    emu = DVSEmulator(w, h, DVSParams(threshold_on=p, threshold_off=p), seed=seed)
    return _wander_stepper(emu, frames)


def _evlib_peer(frames: np.ndarray, seed: int) -> Stepper:
    from evlib.simulation import ESIMConfig, ESIMSimulator

    # ESIM reads a frame as intensity / 255; its log floor is our linear segment's knee.
    dn = [f.astype(np.float64) * 255.0 for f in frames]
    cfg = ESIMConfig(
        positive_threshold=PEER_THRESHOLD,
        negative_threshold=PEER_THRESHOLD,
        refractory_period_ms=0.0,
        log_floor=DVSParams().linlog_intensity,
        device="cpu",
        dtype="float32",
    )

    def start() -> Callable[[int], int]:
        sim = ESIMSimulator(cfg)
        sim.process_frame(dn[0], 0.0)
        return lambda i: len(sim.process_frame(dn[i], i * 1e-3)[0])

    return start


def _v2e_peer(frames: np.ndarray, seed: int) -> Stepper:
    from v2ecore.emulator import EventEmulator

    logging.getLogger("v2ecore.emulator").setLevel(logging.ERROR)  # "no events" per frame
    dn = [f.astype(np.float64) * 255.0 for f in frames]  # v2e takes linear 8-bit DN

    def start() -> Callable[[int], int]:
        emu = EventEmulator(
            pos_thres=PEER_THRESHOLD,
            neg_thres=PEER_THRESHOLD,
            sigma_thres=0.0,
            cutoff_hz=0.0,
            leak_rate_hz=0.0,
            refractory_period_s=0.0,
            shot_noise_rate_hz=0.0,
            seed=seed,
            device="cpu",
        )
        emu.generate_events(dn[0], 0.0)

        def step(i: int) -> int:
            ev = emu.generate_events(dn[i], i * 1e-3)
            return 0 if ev is None else len(ev)

        return step

    return start


PEERS: dict[str, Callable[[np.ndarray, int], Stepper]] = {
    "wander": _wander_peer,
    "evlib ESIM": _evlib_peer,
    "v2e EventEmulator": _v2e_peer,
}


def _version(emulator: str) -> str:
    from importlib.metadata import PackageNotFoundError, version

    dist = {"wander": "wander", "evlib ESIM": "evlib", "v2e EventEmulator": "v2e"}[emulator]
    try:
        return version(dist)
    except PackageNotFoundError:
        return "source" if emulator != "wander" else "worktree"


def bench_peers(n_frames: int = 1000, repeats: int = 3, seed: int = 0) -> list[PeerRow]:
    """wander, evlib's ESIM and v2e on the same frames (module doc); wander first."""
    import torch

    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        rows = []
        for (w, h), speed in SENSORS.items():
            frames = linear_frames(drifting_texture(w, h, n_frames + 1, speed, seed=seed))
            runs, notes = {}, {}
            for name, make in PEERS.items():
                try:
                    runs[name] = make(frames, seed)
                    notes[name] = _version(name)
                except ImportError as e:
                    notes[name] = f"not installed ({e})"
            med, cpu, events, load = _interleaved(runs, n_frames, repeats)
            base_t, base_n = med["wander"], events["wander"]
            for name in PEERS:
                if name not in runs:
                    rows.append(PeerRow(f"{w}x{h}", name, None, None, None, None, notes[name]))
                    continue
                rows.append(
                    PeerRow(
                        sensor=f"{w}x{h}",
                        emulator=name,
                        frames_per_s=n_frames / med[name],
                        wander_speedup=med[name] / base_t,
                        events=events[name],
                        events_diff_pct=100.0 * (events[name] - base_n) / max(base_n, 1),
                        note=notes[name],
                        cpu_frames_per_s=n_frames / max(cpu[name], 1e-12),
                        load=load,
                    )
                )
        return rows
    finally:
        torch.set_num_threads(threads)
