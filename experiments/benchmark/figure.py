"""``maps_vs_masks.png`` of ``wander benchmark``: the model's maps beside the masks.

:class:`WindowSampler` keeps a few scored windows while a benchmark streams (spread over
each sequence, from the first sequences); :func:`plot_maps_vs_masks` draws one row per
window: the window's events (ON/OFF), the sOMS output, the saliency map with P and its
8×8 box, and the mask with the same box — hit or miss, IoU and precision in the titles.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from experiments.analysis.metrics import hit_box
from wander_env.viz import event_image, legend_below, polarity_patches, pyplot, save_figure

__all__ = ["WindowSampler", "WindowView", "plot_maps_vs_masks"]


@dataclass(frozen=True)
class WindowView:
    """What the figure shows of one window."""

    sequence: str
    window: int
    t_start_us: int
    t_end_us: int
    counts: np.ndarray  # (2, H, W)
    oms: np.ndarray  # (H, W) bool
    saliency: np.ndarray  # (H, W)
    point_xy: tuple[float, float] | None
    mask: np.ndarray  # (H, W) bool
    hit: float
    iou: float
    precision: float


@dataclass
class WindowSampler:
    """Keeps up to ``n`` scored windows, spread evenly over each sequence in turn.

    >>> s = WindowSampler(n=2)
    >>> s.start_sequence(10)
    >>> s.wanted
    [3, 6]
    """

    n: int = 4
    views: list[WindowView] = field(default_factory=list)
    wanted: list[int] = field(default_factory=list)

    def start_sequence(self, n_windows: int) -> None:
        """A new sequence of ``n_windows``: the window indices still wanted from it."""
        need = self.n - len(self.views)
        if need <= 0 or n_windows <= 0:
            self.wanted = []
            return
        spots = np.linspace(0, n_windows - 1, need + 2)[1:-1]
        self.wanted = sorted({round(float(x)) for x in spots})

    def __call__(self, row: Any, counts: np.ndarray, maps: Any, mask: np.ndarray) -> None:
        if not self.wanted or row.window < self.wanted[0] or len(self.views) >= self.n:
            return
        self.wanted.pop(0)
        point = None if maps.point_xy is None else tuple(map(float, maps.point_xy))
        self.views.append(
            WindowView(
                f"{row.subset}/{row.sequence}" if row.subset else row.sequence,
                row.window,
                row.t_start_us,
                row.t_end_us,
                np.asarray(counts).copy(),
                np.asarray(maps.oms, bool).copy(),
                np.asarray(maps.saliency, np.float64).copy(),
                point,
                np.asarray(mask, bool).copy(),
                row.hit,
                row.iou,
                row.precision,
            )
        )


def _box(
    ax: Any, point: tuple[float, float] | None, shape: tuple[int, int], box: int, colour: str
) -> None:
    """P and the pixels of its :func:`~experiments.analysis.metrics.hit_box` (pixel
    ``i`` spans ``[i − 0.5, i + 0.5]``)."""
    from matplotlib.patches import Rectangle

    if point is None:
        return
    x0, x1, y0, y1 = hit_box(point, shape, box)
    ax.add_patch(Rectangle((x0 - 0.5, y0 - 0.5), x1 - x0, y1 - y0, fill=False, ec=colour, lw=1.2))
    ax.plot(*point, "+", color=colour, ms=6)


def plot_maps_vs_masks(path: Path, views: list[WindowView], title: str, box: int = 8) -> Path:
    """Write the figure (one row per window) to ``path``."""
    plt = pyplot()
    from matplotlib.patches import Patch

    if not views:
        raise ValueError("no windows to draw")
    fig, axes = plt.subplots(len(views), 4, figsize=(12, 3.0 * len(views) + 0.9), squeeze=False)
    for r, v in enumerate(views):
        h, w = v.mask.shape
        ext = (-0.5, w - 0.5, h - 0.5, -0.5)
        span = f"{v.t_start_us / 1e3:.1f}–{v.t_end_us / 1e3:.1f} ms"
        a0, a1, a2, a3 = axes[r]
        a0.imshow(event_image(v.counts), extent=ext, interpolation="nearest")
        a0.set_title(
            f"{v.sequence} window {v.window}\nevents {span} ({int(v.counts.sum()):,})", fontsize=8
        )
        a1.imshow(v.oms, cmap="gray_r", extent=ext, interpolation="nearest", vmin=0, vmax=1)
        a1.set_title(f"sOMS output ({int(v.oms.sum()):,} px kept)", fontsize=8)
        im = a2.imshow(v.saliency, cmap="magma", extent=ext, interpolation="nearest")
        bar = fig.colorbar(im, ax=a2, fraction=0.046, pad=0.02)
        bar.ax.tick_params(labelsize=6)
        bar.set_label("saliency", fontsize=7)
        _box(a2, v.point_xy, v.mask.shape, box, "lime")
        a2.set_title("saliency, P and its 8×8 box", fontsize=8)
        a3.imshow(v.mask, cmap="Greens", extent=ext, interpolation="nearest", vmin=0, vmax=1.6)
        a3.imshow(
            np.ma.masked_where(~v.oms, v.oms),
            cmap="autumn",
            extent=ext,
            alpha=0.6,
            interpolation="nearest",
        )
        _box(a3, v.point_xy, v.mask.shape, box, "magenta")
        verdict = "hit" if v.hit == 1.0 else "miss" if v.hit == 0.0 else "not scored"
        a3.set_title(f"mask: {verdict}, IoU {v.iou:.1%}, precision {v.precision:.1%}", fontsize=8)
        for a in (a0, a1, a2, a3):
            a.tick_params(labelsize=6)
            a.set_xlabel("x (px)", fontsize=7)
        a0.set_ylabel("y (px)", fontsize=7)
    fig.suptitle(title, fontsize=10)
    handles = [
        *polarity_patches("ON event", "OFF event"),
        Patch(color="black", label="sOMS kept"),
        Patch(color=plt.get_cmap("Greens")(0.6), label="object mask"),
        Patch(color=plt.get_cmap("autumn")(0.0), alpha=0.6, label="sOMS on the mask panel"),
        Patch(facecolor="none", edgecolor="magenta", label="P's 8×8 box (hit: touches mask)"),
    ]
    legend_below(fig, handles, fontsize=7)
    return save_figure(fig, path, rect=(0, 0.03, 1, 1))
