"""Synthetic frame sequences for demos, benchmarks and tests (no renderer needed).

Examples:
    >>> from experiments.jobs.synthetic import drifting_texture
    >>> frames = drifting_texture(32, 24, n_frames=3, speed_px=0.5, seed=0)
    >>> frames.shape, frames.dtype.name
    ((3, 24, 32, 3), 'uint8')
"""

from __future__ import annotations

import cv2
import numpy as np

from wander_env.camera import principal_point


def smooth_texture(width: int, height: int, scale_px: int, seed: int) -> np.ndarray:
    """Random blobs of about ``scale_px`` pixels, grey levels in [0.2, 0.8] (float32)."""
    rng = np.random.default_rng(seed)
    coarse = rng.uniform(0.2, 0.8, (height // scale_px + 4, width // scale_px + 4))
    big = cv2.resize(
        coarse.astype(np.float32),
        (coarse.shape[1] * scale_px, coarse.shape[0] * scale_px),
        interpolation=cv2.INTER_CUBIC,
    )
    return np.clip(big[:height, :width], 0.0, 1.0)


def _to_rgb8(grey: np.ndarray) -> np.ndarray:
    g = (np.clip(grey, 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)
    return np.repeat(g[..., None], 3, axis=-1)


def drifting_texture(
    width: int,
    height: int,
    n_frames: int,
    speed_px: float,
    scale_px: int = 16,
    seed: int = 0,
) -> np.ndarray:
    """``n_frames`` sRGB frames ``(n, H, W, 3)`` of a texture drifting left by ``speed_px``
    pixels per frame (sub-pixel shifts by bilinear interpolation)."""
    span = int(np.ceil(abs(speed_px) * n_frames)) + 2
    tex = smooth_texture(width + span, height, scale_px, seed)
    out = np.empty((n_frames, height, width, 3), np.uint8)
    for i in range(n_frames):
        m = np.float32([[1, 0, -i * speed_px], [0, 1, 0]])
        out[i] = _to_rgb8(cv2.warpAffine(tex, m, (width, height), flags=cv2.INTER_LINEAR))
    return out


def disc_over_texture(
    width: int,
    height: int,
    n_frames: int,
    background_speed_px: float,
    disc_radius_px: float,
    orbit_px: float,
    orbit_frames: int,
    seed: int = 0,
) -> np.ndarray:
    """A drifting background with a bright textured disc circling the centre: a small
    ``eye+object`` stimulus (the camera drifts, the object moves on its own)."""
    frames = drifting_texture(width, height, n_frames, background_speed_px, seed=seed)
    disc_tex = _to_rgb8(0.5 + 0.5 * smooth_texture(width, height, 6, seed + 1))
    yy, xx = np.mgrid[0:height, 0:width]
    x0, y0 = principal_point(width, height)  # the disc orbits the sensor's centre
    for i in range(n_frames):
        a = 2 * np.pi * i / orbit_frames
        cx, cy = x0 + orbit_px * np.cos(a), y0 + orbit_px * np.sin(a)
        inside = (xx - cx) ** 2 + (yy - cy) ** 2 <= disc_radius_px**2
        frames[i][inside] = disc_tex[inside]
    return frames
