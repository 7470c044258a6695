"""The floor of a simulated step on this machine: what one render of a key costs, what
the renders a step needs allow, and what a per-tick warp of a precomputed panorama would
cost instead (a measurement for the panorama route of the speed work).

Run it as ``wander perf floor``. Each part is timed in place on the env's own renderer
(the office key, the model posed at a new time and angles before each render, so that
nothing is reused between renders), each row the median of ``repeats`` runs of
``calls`` calls, wall time and the process's CPU time, with the load average around the
row's runs (:mod:`experiments.perf.clock`). The warps: an equirectangular panorama sampled through
OpenCV's ``remap`` (maps given, or computed from the rotation with NumPy), and a cube map
sampled along each pixel's rotated rays by the kernel the ``panorama`` frame source uses
(:func:`wander_env.frames.cube.cube_warp`) (one bilinear sample, or
``s × s`` nearest samples averaged: area sampling of a panorama rendered at ``s`` times
the sensor's resolution).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

import wander_env  # noqa: F401  (registers the environments)
from experiments.perf.clock import LOAD_COLUMN, Clock, Measured
from wander_env.frames.cube import cube_warp

FLOOR_COLUMNS: dict[str, str] = {
    "part": "",
    "ms_median": ".3f",
    "ms_best": ".3f",
    "cpu_ms_median": ".3f",
    **LOAD_COLUMN,
    "note": "",
}
BOUND_COLUMNS: dict[str, str] = {
    "step": "",
    "colour_renders": "g",
    "geometry_draws": "g",
    "gl_ms": ".2f",
    "gl_cpu_ms": ".2f",
    "rtf_bound": ".2f",
    **LOAD_COLUMN,
}


@dataclass(frozen=True)
class FloorRow(Measured):
    """One part: median and best of the runs' wall time and the median of their CPU
    time, ms per call; the load average around the runs."""

    part: str
    ms_median: float
    ms_best: float
    note: str = ""
    cpu_ms_median: float = float("nan")


@dataclass(frozen=True)
class BoundRow(Measured):
    """A step's GL passes alone and the real-time factor they leave room for."""

    step: str
    colour_renders: float
    geometry_draws: float
    gl_ms: float
    rtf_bound: float  # control period / GL ms: the RTF if everything else took no time
    gl_cpu_ms: float = float("nan")  # the same from the parts' CPU times


def _time(fn: Callable[[int], object], calls: int, repeats: int) -> tuple[float, float, float, str]:
    """(median, best wall, median CPU) ms per call of ``fn(i)`` over ``repeats`` runs of
    ``calls`` calls, and the load average around them."""
    fn(0)  # warm-up (compilation, first use)
    runs, cpus = [], []
    whole = Clock()
    for _ in range(repeats):
        clock = Clock()
        with clock.span(), whole.span():
            for i in range(calls):
                fn(i)
        wall, cpu = clock.ms_per(calls)
        runs.append(wall)
        cpus.append(cpu)
    return float(np.median(runs)), float(min(runs)), float(np.median(cpus)), whole.load


def _pan(deg: float) -> np.ndarray:
    a = math.radians(deg)
    return np.array([[math.cos(a), 0, math.sin(a)], [0, 1, 0], [-math.sin(a), 0, math.cos(a)]])


def render_floor(
    scene: str = "office", calls: int = 100, repeats: int = 5, seed: int = 0
) -> tuple[list[FloorRow], list[BoundRow]]:
    """The parts' costs (module docstring) and the bounds they set on a step."""
    import cv2
    import gymnasium as gym

    from wander_env.camera import focal_length_px
    from wander_env.dvs import DVSEmulator
    from wander_env.frames.keyframe_maths import _static_kernel, warp_keys

    # The renderer is driven from here, on this thread: no render thread.
    env = gym.make("wander/Wander-v0", scene=scene, render_thread=False)
    rows: list[FloorRow] = []
    cpu_of: dict[str, float] = {}
    whole = Clock()
    try:
        env.reset(seed=seed)
        u = env.unwrapped
        for _ in range(3):
            env.step(np.zeros(2, np.float32))
        stage, r = u.stage, u.stage.renderer
        pan, tilt, t0 = u.ptu.camera_pan_deg, u.ptu.camera_tilt_deg, u._t_us
        samples = u.scene.camera.antialias_samples

        def pose(i: int) -> None:  # a new time and angles each call: nothing reused
            stage.pose(t0 + 1000 * (i % 97 + 1), pan + 0.01 * (i % 13), tilt)

        def add(part: str, fn: Callable[[int], object], note: str = "") -> float:
            with whole.span():
                med, best, cpu, load = _time(fn, calls, repeats)
            rows.append(FloorRow(part, med, best, note, cpu, load=load))
            cpu_of[part] = cpu
            return med

        colour_part = f"colour key: pose, scene update, draw, read (MSAA {samples})"
        colour = add(colour_part, lambda i: (pose(i), stage.render()), "llvmpipe")
        geometry_part = "key geometry: layer ids + depth, one single-sample draw"
        caster, stage.caster = stage.caster, None  # GL draws it for this row
        try:
            geometry = add(geometry_part, lambda i: (pose(i), stage.geometry()), "llvmpipe")
        finally:
            stage.caster = caster
        if caster is not None:
            add(
                "key geometry by ray casting (wander_env.frames.raycast)",
                lambda i: (pose(i), caster.layers_depth(stage.data)),
                "numba, primitives",
            )
        ngeom = r._scene.ngeom

        def empty(i: int) -> None:
            r._scene.ngeom = 0
            try:
                r._draw(r._con)
            finally:
                r._scene.ngeom = ngeom

        add(f"empty scene (MSAA {samples}): clear, resolve, read", empty, "any GL pass's overhead")
        dvs = DVSEmulator(u.width, u.height)
        pose(1)
        rgb_a = stage.render()
        pose(6)
        rgb_b = stage.render()
        dvs.reset(rgb_a, 0)
        frames = (dvs.prepare(rgb_a), dvs.prepare(rgb_b))
        add("DVS: a key's sRGB to log input", lambda i: dvs.prepare(rgb_a))
        clock = [0]

        def dvs_step(i: int) -> None:
            clock[0] += 1000
            dvs.step(frames[i % 2], clock[0])

        add("DVS: one step (two keys 5 ms apart, alternately)", dvs_step)
        h, w = u.height, u.width
        rng = np.random.default_rng(seed)
        lum = tuple(rng.random((2, h, w)).astype(np.float32))
        out = np.empty((h, w), np.float32)
        hinv = np.stack([np.eye(3), np.eye(3)])
        hinv[1, 0, 2] = 0.3
        weights = np.array([0.5, 0.5])
        add(
            "in-between frame today: two keys' homography warp (static world)",
            lambda i: _static_kernel(out, weights, 0, lum, warp_keys(lum, hinv), hinv),
            "OpenCV cubic + numba blend",
        )
        # An equirectangular panorama at the sensor's centre resolution, through cv2.remap.
        f = focal_length_px(w, u.hfov_deg)
        pw, ph = int(2 * math.pi * f), int(math.pi * f)
        pano = rng.random((ph, pw)).astype(np.float32)
        ys, xs = np.mgrid[0:h, 0:w].astype(np.float64)
        rays = np.stack([(xs - (w - 1) / 2) / f, (ys - (h - 1) / 2) / f, np.ones_like(xs)], -1)

        def maps(rot: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            d = rays @ rot.T
            lon = np.arctan2(d[..., 0], d[..., 2])
            lat = np.arctan2(d[..., 1], np.hypot(d[..., 0], d[..., 2]))
            return ((lon + math.pi) * f).astype(np.float32), ((lat + math.pi / 2) * f).astype(
                np.float32
            )

        mx, my = maps(_pan(0.0))
        threads = cv2.getNumThreads()
        cv2.setNumThreads(1)
        try:
            add(
                f"panorama warp: cv2.remap bilinear, maps given ({pw}x{ph} equirect.)",
                lambda i: cv2.remap(pano, mx, my, cv2.INTER_LINEAR),
                "one thread",
            )
            add(
                "panorama warp: maps from the rotation (NumPy) + cv2.remap bilinear",
                lambda i: cv2.remap(pano, *maps(_pan(0.01 * i)), cv2.INTER_LINEAR),
                "one thread",
            )
        finally:
            cv2.setNumThreads(threads)
        for s, bilinear, what in ((1, True, "1 bilinear sample"), (2, False, "2x2 samples")):
            n = int(2 * f * s)
            faces = rng.random((6, n, n)).astype(np.float32)
            add(
                f"cube-map warp (faces {n}x{n}): {what} a pixel",
                lambda i, faces=faces, s=s, b=bilinear: cube_warp(
                    out, faces, _pan(0.01 * i), f, (w - 1) / 2, (h - 1) / 2, s, b
                ),
                "numba, rotation per tick",
            )
    finally:
        env.close()
    period_ms = 1e3 * u.config.control_period_s
    steps = [
        ("default, still camera, ground truth on", 2, 1),
        ("default, still camera, ground truth off", 2, 0),
        ("one key a step, ground truth on", 1, 1),
        ("default, moving camera (keys' geometry too)", 2, 2),
        ("exact (every tick and sub-frame: 10.2 renders)", 10.2, 1),
    ]
    bounds = []
    for name, n_colour, n_geom in steps:
        gl = n_colour * colour + n_geom * geometry
        gl_cpu = n_colour * cpu_of[colour_part] + n_geom * cpu_of[geometry_part]
        bounds.append(BoundRow(name, n_colour, n_geom, gl, period_ms / gl, gl_cpu, load=whole.load))
    return rows, bounds
