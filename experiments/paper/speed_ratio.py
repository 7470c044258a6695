"""Where the sOMS stops separating the hand from the shake: the speed-ratio curve.

The paper's characterisation: the sOMS enhances the object "in all Eye+Object cases where
the foreground speed is greater than the background speed (s_F > s_B)" and fails where
the background is faster. Here the same finding is measured as a curve on a scene with a
room: the ``both`` phase of the hand trials (:mod:`experiments.paper.event_suppression`)
with the hand's image speed set to ``hand_ratio`` times the shake's (both in px/s at the
sensor centre), at two shake amplitudes of the same speed, for the agent's sOMS and the
paper-literal one scored on the same events (``second_agent``).

The rows come from the sweep ``experiments/paper/configs/sweep_speed_ratio.yaml``; this
module reads its ``results.csv`` and gives, per sOMS, amplitude and ratio, the hand hit
rate, the events suppressed, the background's and the hand's events kept (means over the
seeds with 95 % bootstrap intervals), the ratios where the hit rate crosses 50 % and 90 %
(:func:`crossing`), a markdown table and a figure; ``wander report`` puts both in its
report for every sweep whose rows carry a ``cfg.hand_ratio`` column::

    wander sweep experiments/paper/configs/sweep_speed_ratio.yaml --workers 1
    wander report
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from experiments.analysis.stats import mean_ci
from experiments.runs.tables import Row
from wander_env.viz import pyplot, save_figure

__all__ = ["RATIO", "VARIANTS", "Point", "crossing", "curve", "plot", "table"]

#: The two sOMS of the sweep: label -> column prefix (the second one's ``second:``).
VARIANTS: dict[str, str] = {
    "agent's sOMS (quantile norm)": "",
    "paper-literal sOMS (min-max)": "second:",
}
RATIO, AMPLITUDE = "cfg.hand_ratio", "cfg.shake.amplitude_deg"
#: The measures drawn: column, label.
MEASURES: tuple[tuple[str, str], ...] = (
    ("hand_hit_pct", "hand hit (% of sOMS steps)"),
    ("suppressed_pct", "events suppressed (%)"),
    ("background_kept_pct", "background's events kept (%)"),
    ("object_kept_pct", "hand's events kept (%)"),
)
LEVELS = (50.0, 90.0)


@dataclass(frozen=True)
class Point:
    """One point of a curve: the mean over seeds and its 95 % bootstrap interval."""

    ratio: float
    mean: float
    low: float
    high: float
    n: int


def curve(rows: Sequence[Row], prefix: str, column: str, amplitude: float) -> list[Point]:
    """The curve of ``prefix + column`` over the hand ratio at ``amplitude``.

    >>> rows = [{"cfg.hand_ratio": r, "cfg.shake.amplitude_deg": 1.0, "x": v}
    ...         for r, v in ((1.0, 10.0), (2.0, 50.0), (1.0, 20.0))]
    >>> [(p.ratio, p.mean, p.n) for p in curve(rows, "", "x", 1.0)]
    [(1.0, 15.0, 2), (2.0, 50.0, 1)]
    """
    mine = [r for r in rows if float(r[AMPLITUDE]) == amplitude]
    out = []
    for ratio in sorted({float(r[RATIO]) for r in mine}):
        values = [float(r[prefix + column]) for r in mine if float(r[RATIO]) == ratio]
        m, lo, hi, n = mean_ci(values)
        out.append(Point(ratio, m, lo, hi, n))
    return out


def crossing(ratios: Sequence[float], values: Sequence[float], level: float) -> float:
    """The smallest ratio where ``values`` reach ``level`` and stay there for the larger
    ratios, interpolated linearly in log ratio from the point before; the first ratio
    when they start there; NaN when the last value is below.

    >>> round(crossing([1, 2, 4, 8], [0, 20, 60, 95], 50), 6)   # between 2 and 4: 2 ** 1.75
    3.363586
    >>> crossing([1, 2], [60, 40], 50), crossing([1, 2], [70, 80], 50)
    (nan, 1)
    """
    r, v = list(ratios), list(values)
    if not v or not v[-1] >= level:
        return math.nan
    i = len(v) - 1
    while i > 0 and v[i - 1] >= level:
        i -= 1
    if i == 0:
        return r[0]
    a, b = math.log(r[i - 1]), math.log(r[i])
    f = (level - v[i - 1]) / (v[i] - v[i - 1])
    return math.exp(a + f * (b - a))


def crossings(points: Sequence[Point], level: float) -> tuple[float, float, float]:
    """(crossing of the mean curve, of its upper interval bound, of its lower one): the
    ratio where the hit rate reaches ``level`` and the interval of that ratio."""
    ratios = [p.ratio for p in points]
    return (
        crossing(ratios, [p.mean for p in points], level),
        crossing(ratios, [p.high for p in points], level),
        crossing(ratios, [p.low for p in points], level),
    )


def _ratio_text(c: tuple[float, float, float]) -> str:
    mean, early, late = c
    if math.isnan(mean):
        return "not reached"
    bounds = f"{early:.2f}–{late:.2f}" if not math.isnan(late) else f"{early:.2f}–beyond"
    return f"{mean:.2f} ({bounds})"


def table(rows: Sequence[Row]) -> str:
    """The README table: per sOMS and amplitude, each ratio's hit, suppression and
    background kept (mean [95 % interval] over seeds); then the crossing ratios."""
    amps = sorted({float(r[AMPLITUDE]) for r in rows})
    ratios = sorted({float(r[RATIO]) for r in rows})
    seeds = len({int(r["seed"]) for r in rows})
    head = "| sOMS | shake | measure | " + " | ".join(f"{x:g}" for x in ratios) + " |"
    lines = [
        f"Hand image speed / shake image speed (columns), `both` phase, {seeds} seeds a "
        "point, mean [95 % bootstrap interval]:",
        "",
        head,
        "|" + "---|" * (3 + len(ratios)),
    ]
    for label, prefix in VARIANTS.items():
        for amp in amps:
            for column, name in MEASURES[:3]:
                pts = curve(rows, prefix, column, amp)
                cells = [f"{p.mean:.1f} [{p.low:.1f}, {p.high:.1f}]" for p in pts]
                short = name.split(" (")[0]
                lines.append(f"| {label} | ±{amp:g}° | {short} | " + " | ".join(cells) + " |")
    lines += [
        "",
        "Ratio where the hand hit reaches 50 % / 90 % (mean curve; in brackets where the "
        "upper and the lower interval bound reach it):",
        "",
        "| sOMS | shake | 50 % | 90 % |",
        "|---|---|---|---|",
    ]
    for label, prefix in VARIANTS.items():
        for amp in amps:
            pts = curve(rows, prefix, "hand_hit_pct", amp)
            cells = [_ratio_text(crossings(pts, level)) for level in LEVELS]
            lines.append(f"| {label} | ±{amp:g}° | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def plot(rows: Sequence[Row], path: Path, shake_px_s: float) -> Path:
    """Hit rate, suppression, background's and hand's events kept against the ratio (log
    axis), both sOMS and both amplitudes, 95 % intervals; ratio 1 and the 50 / 90 % levels
    marked."""
    plt = pyplot()

    amps = sorted({float(r[AMPLITUDE]) for r in rows})
    ratios = sorted({float(r[RATIO]) for r in rows})
    seeds = len({int(r["seed"]) for r in rows})
    fig, axes = plt.subplots(1, len(MEASURES), figsize=(17, 4.4))
    colours = {label: c for label, c in zip(VARIANTS, ("tab:blue", "tab:red"), strict=True)}
    styles = dict(zip(amps, ("-", "--", ":"), strict=False))
    for ax, (column, name) in zip(axes, MEASURES, strict=True):
        for label, prefix in VARIANTS.items():
            for amp in amps:
                pts = curve(rows, prefix, column, amp)
                x = np.array([p.ratio for p in pts])
                m = np.array([p.mean for p in pts])
                ax.plot(
                    x,
                    m,
                    styles[amp],
                    color=colours[label],
                    marker="o",
                    ms=3,
                    label=f"{label}, shake ±{amp:g}°",
                )
                lo = np.array([p.low for p in pts])
                hi = np.array([p.high for p in pts])
                ax.fill_between(x, lo, hi, color=colours[label], alpha=0.12, lw=0)
        ax.axvline(1.0, color="k", lw=0.8, ls=":")
        ax.set_xscale("log", base=2)
        ax.set_xticks(ratios, [f"{t:g}" for t in ratios], fontsize=7)
        ax.minorticks_off()
        ax.set(xlabel="hand / shake image speed (px/s over px/s)", ylabel=name)
        ax.set_title(name, fontsize=9)
        if column == "hand_hit_pct":
            ax.set_ylim(-2, 102)
            for level in LEVELS:
                ax.axhline(level, color="0.5", lw=0.8, ls="--")
    axes[0].text(1.03, 60, "equal speeds", fontsize=7, rotation=90)
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=4, fontsize=8, bbox_to_anchor=(0.5, 0.0))
    fig.suptitle(
        "The hand against the shake: the sOMS on the hand scene's `both` phase as the hand's "
        f"image speed goes from {ratios[0]:g} to {ratios[-1]:g} × the shake's ({shake_px_s:.1f} "
        "px/s at the centre); "
        f"{seeds} seeds a point, mean and 95 % interval; dashed: 50 % and 90 %",
        fontsize=10,
    )
    return save_figure(fig, path, rect=(0, 0.08, 1, 1))
