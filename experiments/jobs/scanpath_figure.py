"""Scanpath pictures: fixations and saccades over the cumulative saliency of a run.

A pan-tilt camera's fixations live in world angles, not in one image, so the figure
puts every fixation's saliency map on a common angular grid (pan, tilt in degrees; a
pixel's world direction is the gaze plus the exact pan-tilt rotation that brings it to
the fovea, :func:`wander_env.camera.pixel_to_rotation`, not ``atan`` per axis), keeps the
maximum of the per-map normalised saliency (colour bar), and draws the fixation points
(gaze at each window, marker size ∝ duration), the saccade lines between them, the
salient points ``P`` that triggered the saccades (those beyond the PTU's reach marked
and counted), the PTU's limits and, from ground truth, the moving objects' paths — the
paper's scanpath figure on the pan-tilt unit's sphere.

Examples:
    >>> import numpy as np
    >>> grid = saliency_mosaic([np.ones((8, 8))], [(0.0, 0.0)], focal_px=4.0, step_deg=5.0)
    >>> grid.values.shape[0] > 0 and float(grid.values.max())
    1.0
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from wander_env.camera import field_of_view_deg, principal_point, world_angles_to_pixels
from wander_env.viz import pyplot, save_figure


@dataclass(frozen=True)
class AngularGrid:
    """A map on pan × tilt degrees: ``values[i, j]`` at ``tilt[i]``, ``pan[j]``."""

    pan: np.ndarray
    tilt: np.ndarray
    values: np.ndarray


def note_box(ax: Any, note: str, edge: str, wrap: bool = False) -> None:
    """A white note on black in the axes' top left corner, framed in ``edge``."""
    ax.text(
        0.01,
        0.99,
        note,
        transform=ax.transAxes,
        va="top",
        fontsize=7,
        color="white",
        wrap=wrap,
        bbox={"facecolor": "black", "alpha": 0.6, "edgecolor": edge},
    )


def limits_box(limits_deg: Any, colour: str, label: str) -> Any:
    """The dashed box (a matplotlib ``Rectangle``) of the PTU's ((pan lo, hi), (tilt lo,
    hi)) limits, in degrees."""
    from matplotlib.patches import Rectangle

    (plo, phi), (tlo, thi) = limits_deg
    return Rectangle(
        (plo, tlo), phi - plo, thi - tlo, fill=False, ls="--", ec=colour, lw=1.0, label=label
    )


def saliency_mosaic(
    maps: Sequence[np.ndarray],
    gazes_deg: Sequence[tuple[float, float]],
    focal_px: float,
    step_deg: float = 0.5,
) -> AngularGrid:
    """Max over fixations of each map normalised to its own peak, on an angular grid
    (each cell sampled from the pixel that sees it,
    :func:`~wander_env.camera.world_angles_to_pixels`)."""
    if len(maps) != len(gazes_deg):
        raise ValueError(f"{len(maps)} maps but {len(gazes_deg)} gaze directions")
    if not maps:
        raise ValueError("no saliency maps")
    h, w = maps[0].shape
    centre = principal_point(w, h)
    half_w = field_of_view_deg(w, focal_px) / 2.0
    half_h = field_of_view_deg(h, focal_px) / 2.0
    g = np.asarray(gazes_deg, dtype=np.float64)
    pan = np.arange(g[:, 0].min() - half_w, g[:, 0].max() + half_w + step_deg, step_deg)
    tilt = np.arange(g[:, 1].min() - half_h, g[:, 1].max() + half_h + step_deg, step_deg)
    pan_grid, tilt_grid = np.meshgrid(pan, tilt)
    values = np.zeros((len(tilt), len(pan)))
    for m, (gp, gt) in zip(maps, g, strict=True):
        m = np.asarray(m, dtype=np.float64)
        peak = m.max()
        if not peak > 0:
            continue
        x, y = world_angles_to_pixels(pan_grid, tilt_grid, (gp, gt), focal_px, centre)
        ok = np.isfinite(x) & np.isfinite(y)
        xi = np.rint(np.where(ok, x, -1)).astype(int)
        yi = np.rint(np.where(ok, y, -1)).astype(int)
        ok &= (xi >= 0) & (xi < w) & (yi >= 0) & (yi < h)
        patch = np.clip(m[yi[ok], xi[ok]] / peak, 0.0, None)
        values[ok] = np.maximum(values[ok], patch)
    return AngularGrid(pan=pan, tilt=tilt, values=values)


def beyond_limits(
    angles_deg: np.ndarray, limits_deg: tuple[tuple[float, float], tuple[float, float]]
) -> np.ndarray:
    """Which (pan, tilt) rows lie outside the PTU's pan or tilt range (bool per row).

    >>> beyond_limits(np.array([[0.0, 0.0], [0.0, 30.0]]), ((-79.5, 79.5), (-23.3, 15.5)))
    array([False,  True])
    """
    a = np.asarray(angles_deg, dtype=np.float64).reshape(-1, 2)
    (plo, phi), (tlo, thi) = limits_deg
    return (a[:, 0] < plo) | (a[:, 0] > phi) | (a[:, 1] < tlo) | (a[:, 1] > thi)


def show_mosaic(
    ax: Any,
    values: np.ndarray,
    pan_deg: np.ndarray,
    tilt_deg: np.ndarray,
    label: str,
    fontsize: float = 8,
) -> None:
    """Draw a saliency mosaic (values in [0, 1], rows top-down) on ``ax`` in pan/tilt
    degrees (tilt axis upwards) with a colour bar labelled ``label``."""
    image = ax.imshow(
        values,
        extent=(pan_deg[0], pan_deg[-1], tilt_deg[-1], tilt_deg[0]),
        cmap="magma",
        origin="upper",
        aspect="equal",
        interpolation="nearest",
        vmin=0.0,
        vmax=1.0,
    )
    bar = ax.figure.colorbar(image, ax=ax, fraction=0.046, pad=0.02)
    bar.set_label(label, fontsize=fontsize)
    ax.set_ylim(tilt_deg[0], tilt_deg[-1])


def plot_scanpath(
    path: Path,
    maps: Sequence[np.ndarray],
    fixations: Sequence[dict],
    focal_px: float,
    gaze_trace: np.ndarray | None = None,
    title: str = "scanpath",
    object_paths: dict[str, np.ndarray] | None = None,
    limits_deg: tuple[tuple[float, float], tuple[float, float]] | None = None,
    fixed_view: str | None = None,
) -> Path:
    """Write the scanpath figure (PNG).

    ``fixations``: dicts with ``gaze_deg`` (pan, tilt at the window), ``duration_s``,
    ``target_deg`` (the salient point's world angles or None) and ``target_px`` (its
    pixel or None); ``maps`` the saliency map of each fixation (same order).
    ``gaze_trace`` (n, 3) = t, pan, tilt adds a panel with the gaze over time.
    ``object_paths``: name -> (n, 3) t, pan, tilt of each moving object from ground truth
    (drawn as its path). ``limits_deg``: the PTU's (pan, tilt) ranges of the gaze;
    salient points beyond them are marked, counted and said in a note. ``fixed_view``: a
    camera whose view does not follow the gaze (a replayed recording): the saliency and
    the salient points are drawn in the sensor's frame (:func:`draw_sensor_frame`),
    this text saying why.
    """
    plt = pyplot()

    panels = 2 if gaze_trace is not None and len(gaze_trace) else 1
    fig, axes = plt.subplots(1, panels, figsize=(7.2 * panels, 5.8), squeeze=False)
    if fixed_view is not None:
        draw_sensor_frame(axes[0, 0], maps, fixations, title, fixed_view)
    else:
        _draw_sphere(axes[0, 0], maps, fixations, focal_px, title, object_paths, limits_deg)
    if panels == 2:
        ax2 = axes[0, 1]
        ax2.plot(gaze_trace[:, 0], gaze_trace[:, 1], label="pan")
        ax2.plot(gaze_trace[:, 0], gaze_trace[:, 2], label="tilt")
        if limits_deg is not None:
            for lim in limits_deg[1]:
                ax2.axhline(lim, color="C1", ls=":", lw=0.8)
            ax2.plot([], [], color="C1", ls=":", lw=0.8, label="tilt limits")
        ax2.set_xlabel("simulated time (s)" if fixed_view is None else "time (s)")
        ax2.set_ylabel("gaze (°; + pan = left, + tilt = up)")
        ax2.set_title(
            "gaze over time"
            if fixed_view is None
            else "the PTU's gaze over time (the replayed view does not follow it)"
        )
        ax2.legend(fontsize=7)
    save_figure(fig, path)
    return path


def draw_sensor_frame(
    ax: Any, maps: Sequence[np.ndarray], fixations: Sequence[dict], title: str, note: str
) -> None:
    """The scanpath of a camera whose view stays fixed (a replayed recording): the
    saliency (max over decisions, each map over its peak) on the sensor's pixel grid, each
    salient point ``P`` at its pixel (numbered by fixation), the fovea, and ``note``."""
    h, w = np.asarray(maps[0]).shape if maps else (0, 0)
    if maps:
        peaks = [np.asarray(m, np.float64) / m.max() for m in maps if np.max(m) > 0]
        values = np.max(peaks, axis=0) if peaks else np.zeros((h, w))
        image = ax.imshow(
            values,
            cmap="magma",
            vmin=0.0,
            vmax=1.0,
            interpolation="nearest",
            extent=(-0.5, w - 0.5, h - 0.5, -0.5),
        )
        bar = ax.figure.colorbar(image, ax=ax, fraction=0.046, pad=0.02)
        bar.set_label("saliency (max over decisions, each map / its peak)", fontsize=8)
        ax.plot(
            *principal_point(w, h),
            "+",
            color="cyan",
            ms=12,
            mew=1.5,
            label="fovea (sensor centre)",
        )
    points = [(k, f["target_px"]) for k, f in enumerate(fixations) if f.get("target_px")]
    if points:
        xy = np.array([p for _, p in points], dtype=np.float64)
        ax.scatter(
            xy[:, 0],
            xy[:, 1],
            marker="x",
            c="lime",
            s=30,
            zorder=4,
            label=f"P(x, y), salient point ({len(points)})",
        )
        for k, (x, y) in points:
            ax.annotate(
                str(k), (x, y), color="white", fontsize=7, xytext=(3, 3), textcoords="offset points"
            )
    ax.set_xlabel("x (px, right)")
    ax.set_ylabel("y (px, down)")
    ax.set_title(f"{title}, in the sensor's frame", fontsize=10)
    if maps or points:
        ax.legend(loc="lower right", fontsize=6.5, framealpha=0.8)
    note_box(ax, note, "cyan", wrap=True)


def _draw_sphere(
    ax: Any,
    maps: Sequence[np.ndarray],
    fixations: Sequence[dict],
    focal_px: float,
    title: str,
    object_paths: dict[str, np.ndarray] | None,
    limits_deg: tuple[tuple[float, float], tuple[float, float]] | None,
) -> None:
    """The scanpath on the pan-tilt sphere: the saliency mosaic, the objects' paths, the
    PTU's limits, fixations, saccades and the salient points."""

    gazes = [f["gaze_deg"] for f in fixations]
    if maps:
        grid = saliency_mosaic(maps, gazes, focal_px)
        label = "saliency (max over fixations, each map / its peak)"
        show_mosaic(ax, grid.values, grid.pan, grid.tilt, label)
    for k, (name, track) in enumerate((object_paths or {}).items()):
        track = np.asarray(track, dtype=np.float64).reshape(-1, 3)
        if len(track):
            colour = f"C{k + 2}"
            ax.plot(
                track[:, 1],
                track[:, 2],
                "-",
                color=colour,
                lw=1.2,
                alpha=0.9,
                label=f"{name} (ground truth path)",
            )
            ax.plot(track[-1, 1], track[-1, 2], "o", color=colour, ms=4)
    if limits_deg is not None:
        (plo, phi), (tlo, thi) = limits_deg
        ax.add_patch(limits_box(limits_deg, "0.7", "PTU limits of the gaze"))
    note = ""
    if gazes:
        g = np.asarray(gazes)
        ax.plot(g[:, 0], g[:, 1], "-", color="gold", lw=1.5, label="saccades")
        sizes = [20 + 200 * f["duration_s"] for f in fixations]
        ax.scatter(
            g[:, 0],
            g[:, 1],
            s=sizes,
            c="cyan",
            edgecolors="k",
            zorder=3,
            label="fixations (size ∝ duration)",
        )
        for k, (p, t) in enumerate(g):
            ax.annotate(
                str(k), (p, t), color="white", fontsize=7, xytext=(3, 3), textcoords="offset points"
            )
        targets = [f["target_deg"] for f in fixations if f.get("target_deg") is not None]
        if targets:
            tg = np.asarray(targets, dtype=np.float64)
            out = (
                beyond_limits(tg, limits_deg) if limits_deg is not None else np.zeros(len(tg), bool)
            )
            ax.scatter(
                tg[~out, 0],
                tg[~out, 1],
                marker="x",
                c="lime",
                s=30,
                zorder=4,
                label="P(x, y), salient point",
            )
            if out.any():
                ax.scatter(
                    tg[out, 0],
                    tg[out, 1],
                    marker="X",
                    c="red",
                    s=45,
                    zorder=4,
                    edgecolors="white",
                    linewidths=0.5,
                    label=f"P beyond the PTU's reach ({int(out.sum())})",
                )
                (plo, phi), (tlo, thi) = limits_deg  # type: ignore[misc]
                note = (
                    f"{int(out.sum())} of {len(tg)} salient points lie beyond the PTU's range "
                    f"(pan {plo:.1f}…{phi:.1f}°, tilt {tlo:.1f}…{thi:.1f}°):\n"
                    "the saccades to them stop at the limit"
                )
    # Show everything drawn: the mosaic, the paths, every P (also those out of reach) and
    # the tilt limits; pan grows to the left (positive pan turns left).
    xs, ys = [], []
    if maps:
        xs += [grid.pan[0], grid.pan[-1]]
        ys += [grid.tilt[0], grid.tilt[-1]]
    for track in (object_paths or {}).values():
        track = np.asarray(track, dtype=np.float64).reshape(-1, 3)
        xs += track[:, 1].tolist()
        ys += track[:, 2].tolist()
    for f in fixations:
        for key in ("gaze_deg", "target_deg"):
            if f.get(key) is not None:
                xs.append(f[key][0])
                ys.append(f[key][1])
    if limits_deg is not None:
        ys += list(limits_deg[1])
    if xs:
        ax.set_xlim(max(xs) + 2.0, min(xs) - 2.0)
        ax.set_ylim(min(ys) - 2.0, max(ys) + 2.0)
    else:
        ax.invert_xaxis()
    ax.set_xlabel("pan (°, + = left)")
    ax.set_ylabel("tilt (°, + = up)")
    ax.set_title(title, fontsize=10)
    ax.legend(loc="lower right", fontsize=6.5, framealpha=0.8)
    if note:
        note_box(ax, note, "red")
