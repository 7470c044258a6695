"""The panorama frame source against the others: ms per step and the headlight's effect.

``wander perf panorama --scene SCENE --steps N`` prints two tables (:func:`step_rows`,
:func:`headlight_rows`):

- ms per step (median of ``steps`` steps after 3 still ones, seed 0; the variants'
  envs stepped in turns, one step of each, the order rotated every step, so that a
  burst of load slows all alike), still camera (zero actions) and a walk (actions
  drawn N(0, 0.02) per axis each step, the same for every variant), for the
  default keyframes, exact (4 and 16 samples a pixel) and the panorama (its defaults,
  and 4 × 4 bilinear rays a pixel without the box filter), with the ratio to the default
  in the same run and the reset's time (the panorama renders its cube map there);
- the panorama's background at reset against the exact render at the same pose, on
  the static world's pixels (``|Δ ln lum|``: median, mean, 95th percentile, mean
  luminance of both), with the faces lit by the headlight held along the camera's axis
  (the default), turned with each face, and off (the render's headlight off too).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

import wander_env  # noqa: F401  (registers the environments)

#: name -> (env keywords, fields of the panorama's PanoramaParams)
VARIANTS: dict[str, tuple[dict[str, Any], dict[str, Any]]] = {
    "keyframes (default)": ({}, {}),
    "exact": ({"frames": "exact"}, {}),
    "exact, 16 samples": ({"frames": "exact", "supersample": 2}, {}),
    "panorama": ({"frames": "panorama"}, {}),
    "panorama, 4x4 bilinear rays": ({"frames": "panorama"}, {"prefilter": False}),
}


def step_ms(scene: str, motion: str, steps: int) -> dict[str, tuple[float, float]]:
    """Per variant: (median ms per step, reset s), the variants stepped in turns (one
    step of each, the order rotated every step) on the same actions."""
    import gymnasium as gym

    envs, reset_s = {}, {}
    for name, (kw, attrs) in VARIANTS.items():
        env = envs[name] = gym.make("wander/Wander-v0", scene=scene, **kw)
        if attrs:  # on this env's source only, before its reset
            source = env.unwrapped.source
            source.panorama = replace(source.panorama, **attrs)
        t = time.perf_counter()
        env.reset(seed=0)
        reset_s[name] = time.perf_counter() - t
    try:
        for env in envs.values():
            for _ in range(3):
                env.step(np.zeros(2, np.float32))
        rng = np.random.default_rng(0)
        times: dict[str, list[float]] = {name: [] for name in envs}
        order = list(envs.items())
        for i in range(steps):
            a = rng.normal(0, 0.02, 2) if motion == "walk" else np.zeros(2)
            j = i % len(order)
            for name, env in order[j:] + order[:j]:
                t = time.perf_counter()
                env.step(a.astype(np.float32))
                times[name].append(time.perf_counter() - t)
    finally:
        for env in envs.values():
            env.close()
    return {n: (1e3 * float(np.median(times[n])), reset_s[n]) for n in envs}


@dataclass(frozen=True)
class StepRow:
    """A frame mode's step time in one run, and its ratio to the default's."""

    motion: str
    frames: str
    ms_per_step: float
    x_default: float
    reset_ms: float


def step_rows(scene: str, steps: int) -> list[StepRow]:
    """:func:`step_ms` for a still camera and a walk, each mode against the default."""
    rows = []
    for motion in ("still", "walk"):
        res = step_ms(scene, motion, steps)
        base = res["keyframes (default)"][0]
        for name, (ms, reset_s) in res.items():
            rows.append(StepRow(motion, name, ms, ms / base, 1e3 * reset_s))
    return rows


@dataclass(frozen=True)
class HeadlightRow:
    """The panorama's background at reset against a render at the same pose:
    ``|Δ ln lum|`` over the static world's pixels, and both mean luminances."""

    headlight: str
    median: float
    mean: float
    p95: float
    lum_panorama: float
    lum_render: float


def background_error(scene: str, headlight: str) -> tuple[np.ndarray, tuple[float, float]]:
    """``|Δ ln lum|`` over the static world's pixels between the panorama's background at
    reset and a render at the same pose, its faces lit with ``headlight`` (``"off"``:
    the render's headlight off too); and (mean lum panorama, mean lum render) there."""
    import gymnasium as gym

    env = gym.make("wander/Wander-v0", scene=scene, frames="panorama")
    try:
        u = env.unwrapped
        u.source.panorama = replace(u.source.panorama, headlight=headlight)
        env.reset(seed=0)
        stage = u.stage
        if headlight == "off":
            u.model.vis.headlight.active = 0
        pan, tilt = u.ptu.camera_pan_deg, u.ptu.camera_tilt_deg
        bg, _ = u.source.background(stage.camera_view(0, pan, tilt).rotation, depth=False)
        stage.invalidate()
        stage.pose(0, pan, tilt)
        lum = u.dvs.prepare(stage.render()).lum.reshape(bg.shape)
        static = stage.geometry()[0] == 0
    finally:
        env.close()
    d = np.abs(np.log(np.maximum(bg, 1e-3)) - np.log(np.maximum(lum, 1e-3)))[static]
    return d, (float(bg[static].mean()), float(lum[static].mean()))


def headlight_rows(scene: str) -> list[HeadlightRow]:
    """One :class:`HeadlightRow` per way of lighting the faces: the headlight held along
    the camera's axis (the default), turned with each face, and off."""
    rows = []
    for headlight in ("camera", "face", "off"):
        d, (lum_panorama, lum_render) = background_error(scene, headlight)
        median, mean, p95 = float(np.median(d)), float(d.mean()), float(np.percentile(d, 95))
        rows.append(HeadlightRow(headlight, median, mean, p95, lum_panorama, lum_render))
    return rows
