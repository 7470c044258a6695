"""How far a camera frame's content can move between two views, from the poses alone,
and where a step's keys and the frames left to the DVS fall by that bound.

:func:`view_flow_bounds_px` bounds how far any pixel's content moves between two
:class:`~wander_env.frames.keyframe_maths.View` s (the camera's rotation measured at the
image's corners and edge midpoints; each moving layer a ball about its position);
:func:`adaptive_key_ticks` places a step's keys where that bound would pass a limit;
:func:`left_to_dvs` the ticks whose frames the DVS's own interpolation stands for.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numba
import numpy as np

from wander_env.frames.keyframe_maths import View

__all__ = ["adaptive_key_ticks", "flow_bound_px", "left_to_dvs", "view_flow_bounds_px"]


def view_flow_bounds_px(
    ref: View | Sequence[View],
    views: Sequence[View],
    k: np.ndarray,
    radii: np.ndarray,
    shape: tuple[int, int],
) -> np.ndarray:
    """Upper bounds (n,) in px on how far any pixel's content moves from the view
    ``ref`` (or from each of a sequence of views, one per view) to each of ``views``,
    from the poses alone (no key's geometry: each moving layer is taken as a ball).

    The camera's rotation is measured at the image's corners and edge midpoints; a
    moving layer (a ball of radius ``radii[layer]`` m about its position) adds
    ``f/near·(|t_xy| + |t_z|·r_max/f)`` (``near``: the ball's nearest depth in either
    view); both times 1.25. ``inf`` where the camera
    centre moves or a moving layer may reach the camera (or has no bounded radius).

    >>> from wander_env.camera import intrinsics
    >>> k = intrinsics(128, 128, 90.0)
    >>> still = View(np.eye(3), np.zeros(3), np.array([[0, 0, 0], [0, 0, 2.0]]))
    >>> moved = View(np.eye(3), np.zeros(3), np.array([[0, 0, 0], [0.01, 0, 2.0]]))
    >>> view_flow_bounds_px(still, [still, moved], k, np.array([np.inf, 0.1]), (128, 128))
    array([0.        , 0.42105263])
    """
    n = len(views)
    if n == 0:
        return np.zeros(0)
    refs = [ref] * n if isinstance(ref, View) else list(ref)
    if len(refs) != n:
        raise ValueError(f"{len(refs)} reference views for {n} views")
    out = np.empty(n)
    k = np.asarray(k, dtype=np.float64)
    radii = np.asarray(radii, dtype=np.float64)
    for i, (r, v) in enumerate(zip(refs, views, strict=True)):
        out[i] = flow_bound_px(r, v, k, radii, shape)
    return out


def flow_bound_px(
    ref: View, view: View, k: np.ndarray, radii: np.ndarray, shape: tuple[int, int]
) -> float:
    """:func:`view_flow_bounds_px` of one pair of views (``k`` and ``radii`` float64)."""
    return _flow_bound(
        k,
        radii,
        shape[0],
        shape[1],
        ref.rotation,
        ref.centre,
        ref.layer_positions,
        view.rotation,
        view.centre,
        view.layer_positions,
    )


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _flow_bound(k, radii, h, w, r_rot, r_centre, r_layers, rot, centre, layers):
    """See :func:`view_flow_bounds_px` (one pair of views)."""
    for j in range(3):
        if centre[j] != r_centre[j]:
            return np.inf
    fx, fy, cx, cy = k[0, 0], k[1, 1], k[0, 2], k[1, 2]
    out = 0.0
    if (rot != r_rot).any():
        rel = rot.T @ r_rot  # target-from-ref rotation
        worst = 0.0
        for x in (0.0, (w - 1) / 2, w - 1.0):
            for y in (0.0, (h - 1) / 2, h - 1.0):
                rx, ry = (x - cx) / fx, (y - cy) / fy
                m0 = rel[0, 0] * rx + rel[0, 1] * ry + rel[0, 2]
                m1 = rel[1, 0] * rx + rel[1, 1] * ry + rel[1, 2]
                m2 = rel[2, 0] * rx + rel[2, 1] * ry + rel[2, 2]
                worst = max(worst, abs(fx * m0 / m2 + cx - x), abs(fy * m1 / m2 + cy - y))
        out += 1.25 * worst
    r_max = math.hypot(w, h) / 2 + 1.0
    extra = 0.0
    for ll in range(len(layers)):
        s0 = layers[ll, 0] - r_layers[ll, 0]
        s1 = layers[ll, 1] - r_layers[ll, 1]
        s2 = layers[ll, 2] - r_layers[ll, 2]
        if s0 == 0 and s1 == 0 and s2 == 0:
            continue
        z = 0.0
        z_to = 0.0
        for j in range(3):
            z += (r_layers[ll, j] - r_centre[j]) * r_rot[j, 2]
            z_to += (layers[ll, j] - centre[j]) * rot[j, 2]
        near = min(z, z_to) - radii[ll]
        # the shift in the target camera's axes
        t0 = rot[0, 0] * s0 + rot[1, 0] * s1 + rot[2, 0] * s2
        t1 = rot[0, 1] * s0 + rot[1, 1] * s1 + rot[2, 1] * s2
        t2 = rot[0, 2] * s0 + rot[1, 2] * s1 + rot[2, 2] * s2
        if not near > 0.01:
            return np.inf
        extra = max(extra, (fx * math.hypot(t0, t1) + abs(t2) * r_max) / near)
    return out + 1.25 * extra


def adaptive_key_ticks(
    ref: View,
    views: Sequence[View],
    k: np.ndarray,
    radii: np.ndarray,
    shape: tuple[int, int],
    bound_px: float,
    max_ticks: int | None = None,
) -> list[int] | None:
    """Indices of the ticks of a step (``views``, the last one the step's end) to
    render as keys, after the key ``ref`` at the step's start.

    Between two consecutive keys no pixel's content moves more than ``bound_px``
    (:func:`view_flow_bounds_px`; each key as late as that allows; where one tick alone
    moves more, every tick is a key) and, with ``max_ticks``, where anything moves keys
    are no more than ``max_ticks`` ticks apart (spread evenly over the span the motion
    bound set); the step's end is a key, unless nothing moves at all: then there is none
    (``[]``; the key at the start is the frame all along). ``None`` when the motion has
    no finite bound (a moving camera centre, a layer without a bounded radius): the
    caller keeps a fixed interval.

    >>> from wander_env.camera import intrinsics
    >>> k = intrinsics(128, 128, 90.0)
    >>> v = [View(np.eye(3), np.zeros(3), np.array([[0, 0, 0], [0.002 * i, 0, 2.0]]))
    ...      for i in range(11)]
    >>> radii = np.array([np.inf, 0.1])
    >>> adaptive_key_ticks(v[0], v[1:], k, radii, (128, 128), 0.3)
    [2, 5, 8, 9]
    >>> adaptive_key_ticks(v[0], v[1:], k, radii, (128, 128), 10.0)
    [9]
    >>> adaptive_key_ticks(v[0], v[1:], k, radii, (128, 128), 10.0, max_ticks=4)
    [2, 6, 9]
    >>> adaptive_key_ticks(v[0], [v[0]] * 10, k, radii, (128, 128), 0.3, max_ticks=2)
    []
    """
    if not bound_px > 0:
        raise ValueError(f"bound_px must be > 0, got {bound_px!r}")
    if max_ticks is not None and max_ticks < 1:
        raise ValueError(f"max_ticks must be >= 1, got {max_ticks!r}")
    n = len(views)
    keys: list[int] = []
    parts: list[int] = []  # keys spread over the span ending at each key
    start = 0
    while start < n:
        bounds = view_flow_bounds_px(ref, views[start:], k, radii, shape)
        if not np.isfinite(bounds).all():
            return None
        if start == 0 and not bounds.any():
            return []
        over = np.flatnonzero(bounds > bound_px)
        j = n - 1 if not len(over) else start + max(int(over[0]) - 1, 0)
        moving = bool(bounds[: j - start + 1].max() > 0)
        span = j - start + 1
        parts.append(-(-span // max_ticks) if moving and max_ticks is not None else 1)
        keys.append(j)
        ref, start = views[j], j + 1
    spread: list[int] = []
    prev = -1
    for j, m in zip(keys, parts, strict=True):
        spread.extend(prev + round((j - prev) * i / m) for i in range(1, m))
        spread.append(j)
        prev = j
    return spread


def left_to_dvs(
    start: View,
    views: Sequence[View],
    fixed: Sequence[bool],
    k: np.ndarray,
    radii: np.ndarray,
    shape: tuple[int, int],
    bound_px: float,
) -> list[int]:
    """Indices of ``views`` (the frames a step would hand the DVS, in time order, after
    the frame of ``start``) whose frames the DVS may go without, interpolating between
    the frames on either side: in time order, each one not ``fixed`` where no pixel's
    content moves more than ``bound_px`` (:func:`flow_bound_px`) from the last frame
    kept to the next one. The last view is always kept.

    >>> from wander_env.camera import intrinsics
    >>> k = intrinsics(128, 128, 90.0)
    >>> v = [View(np.eye(3), np.zeros(3), np.array([[0, 0, 0], [0.004 * i, 0, 2.0]]))
    ...      for i in range(8)]
    >>> radii = np.array([np.inf, 0.1])
    >>> round(flow_bound_px(v[0], v[1], k, radii, (128, 128)), 3)  # px a view
    0.168
    >>> left_to_dvs(v[0], v[1:], [False] * 7, k, radii, (128, 128), 0.6)
    [0, 1, 3, 4]
    >>> left_to_dvs(v[0], v[1:], [False, True] + [False] * 5, k, radii, (128, 128), 0.6)
    [0, 2, 3, 5]
    """
    if not bound_px > 0:
        raise ValueError(f"bound_px must be > 0, got {bound_px!r}")
    if len(fixed) != len(views):
        raise ValueError(f"{len(fixed)} fixed flags for {len(views)} views")
    k = np.asarray(k, dtype=np.float64)
    radii = np.asarray(radii, dtype=np.float64)
    skipped: list[int] = []
    prev = start
    for i in range(len(views) - 1):
        if not fixed[i] and flow_bound_px(prev, views[i + 1], k, radii, shape) < bound_px:
            skipped.append(i)
        else:
            prev = views[i]
    return skipped
