"""The speed study's response surfaces: time to foveate and detection over two factors.

From the rows of a factorial ``saccade_speed`` run (``--set design=factorial``) or of
the ``speed`` sweep (``experiments/paper/configs/sweep_speed.yaml``; its ``results.csv`` has the
same columns), :func:`surface` averages a measure over the repeats and the other factors
for every pair of levels of two factors (the marginal response surface of the design),
and :func:`plot_surfaces` draws them: time to foveate over PTU speed × acceleration and
over fixational step × count, detection accuracy over the same pairs and over window ×
fixational count; each panel's cells carry their mean, its 95 % bootstrap interval
over the cell's trials and their number.

Examples:
    >>> rows = [{"a": 1, "b": 10, "y": 0.5}, {"a": 1, "b": 10, "y": 1.5}]
    >>> rows.append({"a": 2, "b": 10, "y": 3.0})
    >>> s = surface(rows, "a", "b", "y")
    >>> s.x.tolist(), s.y.tolist(), s.mean.tolist(), s.n.tolist()
    ([1.0, 2.0], [10.0], [[1.0, 3.0]], [[2, 1]])
    >>> s.low.tolist()  # one trial has no interval
    [[0.5, nan]]
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from experiments.analysis.stats import mean_ci
from wander_env.viz import pyplot, save_figure

__all__ = ["PANELS", "Surface", "plot_surfaces", "surface"]

# (measure, its label with units, x factor, y factor)
PANELS = (
    ("time_to_foveate_s", "time to foveate (s)", "speed_pos_s", "accel_pos_s2"),
    ("time_to_foveate_s", "time to foveate (s)", "fixational_step_pos", "fixational_n_steps"),
    ("detection_accuracy", "detection accuracy (fraction)", "speed_pos_s", "accel_pos_s2"),
    ("detection_accuracy", "detection accuracy (fraction)", "window_s", "fixational_n_steps"),
)
AXIS_LABELS = {
    "speed_pos_s": "PTU speed (positions/s; 1 = 0.0257°)",
    "accel_pos_s2": "PTU acceleration (positions/s²)",
    "fixational_step_pos": "fixational step, max (positions)",
    "fixational_n_steps": "fixational steps per window",
    "window_s": "integration window t_w (s)",
    "object_speed_scale": "object speed (× the scene's)",
}


@dataclass(frozen=True)
class Surface:
    """``mean[i, j]``, its 95 % bootstrap interval ``low[i, j]``..``high[i, j]`` and
    ``n[i, j]`` trials at ``y[i]``, ``x[j]`` (NaN, 0 where no trial; no interval for
    fewer than two)."""

    x: np.ndarray
    y: np.ndarray
    mean: np.ndarray
    n: np.ndarray
    low: np.ndarray
    high: np.ndarray


def _num(v: Any) -> float:
    try:
        return float(v)
    except (TypeError, ValueError):
        return math.nan


def _column(row: dict[str, Any], key: str) -> Any:
    """A factor's value: the trial parameter, or a sweep's ``cfg.<key>`` column."""
    return row[key] if key in row else row.get(f"cfg.{key}")


def surface(rows: Sequence[dict[str, Any]], x: str, y: str, measure: str) -> Surface:
    """The mean of ``measure`` (finite values) per level pair of factors ``x`` and ``y``,
    with its seeded bootstrap interval over the pair's trials."""
    xs = sorted({_num(_column(r, x)) for r in rows} - {math.nan})
    ys = sorted({_num(_column(r, y)) for r in rows} - {math.nan})
    cells: dict[tuple[int, int], list[float]] = {}
    for r in rows:
        v, vx, vy = _num(r.get(measure)), _num(_column(r, x)), _num(_column(r, y))
        if math.isfinite(v) and vx in xs and vy in ys:
            cells.setdefault((ys.index(vy), xs.index(vx)), []).append(v)
    stats = np.full((4, len(ys), len(xs)), np.nan)  # mean, low, high, n
    stats[3] = 0
    for (i, j), values in cells.items():
        stats[:, i, j] = mean_ci(values)
    mean, low, high, n = stats
    return Surface(np.asarray(xs), np.asarray(ys), mean, n.astype(int), low, high)


def plot_surfaces(rows: Sequence[dict[str, Any]], path: Path, title: str = "") -> Path:
    """The :data:`PANELS` as heat maps (a colour bar each; in each cell its mean, 95 %
    bootstrap interval and trial count), into ``path``."""
    plt = pyplot()

    fig, axes = plt.subplots(2, 2, figsize=(11.5, 9.0), squeeze=False)
    for ax, (measure, label, fx, fy) in zip(axes.ravel(), PANELS, strict=True):
        s = surface(rows, fx, fy, measure)
        if s.mean.size == 0:
            ax.set_axis_off()
            ax.set_title(f"{label}: no data", fontsize=9)
            continue
        cmap = "viridis_r" if measure == "time_to_foveate_s" else "viridis"
        im = ax.imshow(s.mean, origin="lower", cmap=cmap, aspect="auto")
        ax.set_xticks(range(len(s.x)), [f"{v:g}" for v in s.x])
        ax.set_yticks(range(len(s.y)), [f"{v:g}" for v in s.y])
        ax.set_xlabel(AXIS_LABELS.get(fx, fx))
        ax.set_ylabel(AXIS_LABELS.get(fy, fy))
        ax.set_title(
            f"{label}\nmean [95 % bootstrap interval] over repeats and the other factors",
            fontsize=9,
        )
        finite = s.mean[np.isfinite(s.mean)]
        mid = float(np.mean(finite)) if finite.size else 0.0
        for i in range(len(s.y)):
            for j in range(len(s.x)):
                m = s.mean[i, j]
                lo, hi = s.low[i, j], s.high[i, j]
                ci = "" if math.isnan(lo) else f"\n[{lo:.3g}, {hi:.3g}]"
                text = "—" if math.isnan(m) else f"{m:.3g}{ci}\nn={s.n[i, j]}"
                colour = (
                    "white"
                    if (not math.isnan(m) and (m < mid) != (cmap == "viridis_r"))
                    else "black"
                )
                ax.text(j, i, text, ha="center", va="center", fontsize=7, color=colour)
        fig.colorbar(im, ax=ax, label=label)
    fig.suptitle(title or "saccade_speed: response surfaces (factorial design)")
    return save_figure(fig, path)
