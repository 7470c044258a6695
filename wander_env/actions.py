"""Gaze actions: what a relative action means, shared by every env with the ``wander``
contract (the simulated ``wander/Wander-v0`` and the rig's ``wander/Rig-v0``).

An action is a gaze offset ``(x, y)`` in units of the half sensor (``x`` right, ``y``
down): the pixel offset ``d = a·(W/2, H/2)`` is turned into the PTU rotation
``atan(d / f)`` per axis with the pinhole focal length ``f``, in PTU signs (positive
pan turns left, positive tilt looks up).

Examples:
    >>> check_action([0.5, -0.25]).tolist()
    [0.5, -0.25]
    >>> pan, tilt = action_to_gaze_degrees((0.5, 0.0))
    >>> round(pan, 3), tilt
    (-36.978, 0.0)
"""

from __future__ import annotations

import math

import numpy as np

from wander_env.camera import SPECK_HFOV_DEG, focal_length_px

__all__ = ["action_to_gaze_degrees", "check_action", "gaze_degrees_to_action"]


def check_action(action: np.ndarray | tuple[float, float]) -> np.ndarray:
    """The action as a float64 ``(2,)`` array; ``ValueError`` for a wrong shape, a NaN or
    infinite value, or a value outside ``[-1, 1]`` (half the field of view)."""
    a = np.asarray(action, dtype=np.float64)
    if a.shape != (2,):
        raise ValueError(f"action must have shape (2,), got {a.shape}")
    if not np.isfinite(a).all():
        raise ValueError(f"action must be finite, got {a.tolist()}")
    if np.abs(a).max() > 1.0 + 1e-6:
        raise ValueError(f"action must lie in [-1, 1] (half the field of view), got {a.tolist()}")
    return a


def gaze_degrees_to_action(
    pan_deg: float,
    tilt_deg: float,
    width_px: int = 128,
    height_px: int = 128,
    hfov_deg: float = SPECK_HFOV_DEG,
) -> np.ndarray:
    """Relative PTU rotation (degrees, PTU signs) -> env action units ``(x, y)``.

    ``x = f·tan(−pan) / (W/2)``, ``y = f·tan(−tilt) / (H/2)`` with ``f`` the pinhole
    focal length in pixels (square pixels: the same ``f`` on both axes). Not clipped.

    >>> a = gaze_degrees_to_action(-1.0, 0.0)  # pan right by 1° -> look right
    >>> round(float(a[0]), 6), float(a[1])
    (0.011591, 0.0)
    """
    f = focal_length_px(width_px, hfov_deg)
    dx = f * math.tan(math.radians(-pan_deg))
    dy = f * math.tan(math.radians(-tilt_deg))
    return np.array([dx / (width_px / 2.0), dy / (height_px / 2.0)]) + 0.0  # no -0.0


def action_to_gaze_degrees(
    action: np.ndarray | tuple[float, float],
    width_px: int = 128,
    height_px: int = 128,
    hfov_deg: float = SPECK_HFOV_DEG,
) -> tuple[float, float]:
    """Env action units ``(x, y)`` -> relative ``(pan_deg, tilt_deg)`` in PTU signs.

    The pixel offset ``d = a·(W/2, H/2)`` is the angle ``atan(d / f)``; look right
    (x > 0) is a negative pan, look down (y > 0) a negative tilt.

    >>> pan, tilt = action_to_gaze_degrees((1.0, 0.0))  # to the right edge: half the HFOV
    >>> round(pan, 4), tilt
    (-56.4134, 0.0)
    """
    ax, ay = (float(v) for v in np.asarray(action, dtype=np.float64).reshape(2))
    f = focal_length_px(width_px, hfov_deg)
    pan = -math.degrees(math.atan(ax * (width_px / 2.0) / f)) + 0.0  # no -0.0
    tilt = -math.degrees(math.atan(ay * (height_px / 2.0) / f)) + 0.0
    return pan, tilt
