"""Scanpath pictures: fixations and saccades over the cumulative saliency of a run.

A pan-tilt camera's fixations live in world angles, not in one image, so the figure
puts every fixation's saliency map on a common angular grid (pan, tilt in degrees,
pinhole model: pixel ``x`` of a fixation at ``pan_i`` sees ``pan_i − atan((x − cx)/f)``),
keeps the maximum of the per-map normalised saliency, and draws the fixation points
(gaze at each window, marker size ∝ duration), the saccade lines between them and the
salient points ``P`` that triggered the saccades — the paper's scanpath figure on the
pan-tilt unit's sphere.

Example:
    >>> import numpy as np
    >>> grid = saliency_mosaic([np.ones((8, 8))], [(0.0, 0.0)], focal_px=4.0, step_deg=5.0)
    >>> grid.values.shape[0] > 0 and float(grid.values.max())
    1.0
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from experiments.framework import save_figure


@dataclass(frozen=True)
class AngularGrid:
    """A map on pan × tilt degrees: ``values[i, j]`` at ``tilt[i]``, ``pan[j]``."""

    pan: np.ndarray
    tilt: np.ndarray
    values: np.ndarray


def pixel_to_angles(
    xy: tuple[float, float],
    gaze_deg: tuple[float, float],
    focal_px: float,
    centre: tuple[float, float],
) -> tuple[float, float]:
    """World (pan, tilt) in degrees of pixel ``xy`` seen with the camera at ``gaze_deg``.

    >>> pixel_to_angles((63.5, 63.5), (10.0, -5.0), 42.5, (63.5, 63.5))
    (10.0, -5.0)
    """
    pan = gaze_deg[0] - math.degrees(math.atan((xy[0] - centre[0]) / focal_px))
    tilt = gaze_deg[1] - math.degrees(math.atan((xy[1] - centre[1]) / focal_px))
    return pan, tilt


def saliency_mosaic(
    maps: Sequence[np.ndarray],
    gazes_deg: Sequence[tuple[float, float]],
    focal_px: float,
    step_deg: float = 0.5,
) -> AngularGrid:
    """Max over fixations of each map normalised to its own peak, on an angular grid."""
    if len(maps) != len(gazes_deg):
        raise ValueError(f"{len(maps)} maps but {len(gazes_deg)} gaze directions")
    if not maps:
        raise ValueError("no saliency maps")
    h, w = maps[0].shape
    cx, cy = (w - 1) / 2.0, (h - 1) / 2.0
    half_w = math.degrees(math.atan((w / 2.0) / focal_px))
    half_h = math.degrees(math.atan((h / 2.0) / focal_px))
    g = np.asarray(gazes_deg, dtype=np.float64)
    pan = np.arange(g[:, 0].min() - half_w, g[:, 0].max() + half_w + step_deg, step_deg)
    tilt = np.arange(g[:, 1].min() - half_h, g[:, 1].max() + half_h + step_deg, step_deg)
    values = np.zeros((len(tilt), len(pan)))
    for m, (gp, gt) in zip(maps, g, strict=True):
        m = np.asarray(m, dtype=np.float64)
        peak = m.max()
        if not peak > 0:
            continue
        x = np.rint(cx + focal_px * np.tan(np.radians(gp - pan))).astype(int)
        y = np.rint(cy + focal_px * np.tan(np.radians(gt - tilt))).astype(int)
        ok_x = (np.abs(gp - pan) < 89.0) & (x >= 0) & (x < w)
        ok_y = (np.abs(gt - tilt) < 89.0) & (y >= 0) & (y < h)
        iy, ix = np.nonzero(ok_y)[0], np.nonzero(ok_x)[0]
        patch = np.clip(m[np.ix_(y[iy], x[ix])] / peak, 0.0, None)
        values[np.ix_(iy, ix)] = np.maximum(values[np.ix_(iy, ix)], patch)
    return AngularGrid(pan=pan, tilt=tilt, values=values)


def plot_scanpath(
    path: Path,
    maps: Sequence[np.ndarray],
    fixations: Sequence[dict],
    focal_px: float,
    gaze_trace: np.ndarray | None = None,
    title: str = "scanpath",
) -> Path:
    """Write the scanpath figure (PNG).

    ``fixations``: dicts with ``gaze_deg`` (pan, tilt at the window), ``duration_s``
    and ``target_deg`` (the salient point's world angles or None); ``maps`` the
    saliency map of each fixation (same order). ``gaze_trace`` (n, 3) = t, pan, tilt
    adds a panel with the gaze over time.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    panels = 2 if gaze_trace is not None and len(gaze_trace) else 1
    fig, axes = plt.subplots(1, panels, figsize=(6.5 * panels, 5.2), squeeze=False)
    ax = axes[0, 0]
    gazes = [f["gaze_deg"] for f in fixations]
    if maps:
        grid = saliency_mosaic(maps, gazes, focal_px)
        ax.imshow(
            grid.values,
            extent=(grid.pan[0], grid.pan[-1], grid.tilt[-1], grid.tilt[0]),
            cmap="magma",
            origin="upper",
            aspect="equal",
            interpolation="nearest",
        )
        ax.set_ylim(grid.tilt[0], grid.tilt[-1])
    if gazes:
        g = np.asarray(gazes)
        ax.plot(g[:, 0], g[:, 1], "-", color="gold", lw=1.5, label="saccades")
        sizes = [20 + 200 * f["duration_s"] for f in fixations]
        ax.scatter(g[:, 0], g[:, 1], s=sizes, c="cyan", edgecolors="k", zorder=3, label="fixations")
        for k, (p, t) in enumerate(g):
            ax.annotate(str(k), (p, t), color="white", fontsize=7, xytext=(3, 3),
                        textcoords="offset points")  # fmt: skip
        targets = [f["target_deg"] for f in fixations if f.get("target_deg") is not None]
        if targets:
            tg = np.asarray(targets)
            ax.scatter(tg[:, 0], tg[:, 1], marker="x", c="lime", s=30, zorder=4, label="P(x, y)")
    ax.invert_xaxis()  # positive pan turns left: left of the plot is left of the world
    ax.set_xlabel("pan (°, + = left)")
    ax.set_ylabel("tilt (°, + = up)")
    ax.set_title(title)
    ax.legend(loc="lower right", fontsize=7)
    if panels == 2:
        ax2 = axes[0, 1]
        ax2.plot(gaze_trace[:, 0], gaze_trace[:, 1], label="pan")
        ax2.plot(gaze_trace[:, 0], gaze_trace[:, 2], label="tilt")
        ax2.set_xlabel("time (s)")
        ax2.set_ylabel("gaze (°)")
        ax2.set_title("gaze over time")
        ax2.legend(fontsize=7)
    save_figure(fig, path)
    return path
