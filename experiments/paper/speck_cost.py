"""What going on-chip costs (issue 35, item 5): the front end on Speck's cores
(:mod:`agents.speck_front`) beside the agent's float sOMS, same seeds, each figure a
mean with its 95 % interval.

Three sources, each from the command that measures it (docs/speck.md lists them):

- **hand trials** (:func:`hand_costs`): the ``results.csv`` of ``wander experiment
  event_suppression --set agent.soms=speck --set second_agent.soms=agent`` (both scored on the same
  recorded windows; the agent's in the ``second:`` columns); per trial the figures of
  :func:`experiments.paper.event_suppression_scoring.trial_figures`, the interval a bootstrap
  over trials;
- **the sOMS family** (:func:`family_costs`): the stimulus family of
  :mod:`experiments.paper.oms_stimuli` measured here per stimulus (the scorecard,
  ``wander experiment oms_scorecard --set compare=speck``, gives only means): eye-only
  suppression, eye+object and object-only precision and object kept, the share of
  background-faster stimuli where the object is still enhanced; intervals by bootstrap
  over stimuli;
- **detection** (:func:`detection_costs`): the ``quality.json`` of two ``wander evaluate``
  runs, ``--set agent.soms=speck`` and the default, same seeds: pooled detection accuracy
  (Wilson interval, as ``wander evaluate`` prints it) and the sOMS suppression (mean over
  seeds, bootstrap interval).

:func:`table` gives the markdown table, :func:`plot` the picture; :func:`write_costs` and
:func:`read_costs` keep figures as JSON, so a slow part (the family) is measured once.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from experiments.analysis.stats import ci_text, mean_ci
from experiments.jobs.evaluate_agent import read_quality
from experiments.paper.oms_family import Measure, group_of, measure
from experiments.paper.oms_stimuli import Stimulus
from experiments.runs.tables import Row
from wander_env.strict_json import dumps_strict
from wander_env.untrusted import read_json
from wander_env.viz import legend_below, pyplot, save_figure

__all__ = [
    "Cost",
    "detection_costs",
    "family_costs",
    "hand_costs",
    "plot",
    "read_costs",
    "table",
    "write_costs",
]

#: A figure's value: (mean, low, high, n).
Figure = tuple[float, float, float, int]


@dataclass(frozen=True)
class Cost:
    """One figure for both front ends: ``speck`` and ``host`` (the agent's float sOMS),
    each (mean, 95 % low, 95 % high, n) in ``unit``; ``over`` says what n counts."""

    source: str
    measure: str
    unit: str
    speck: Figure
    host: Figure
    over: str


_HAND = (
    ("suppressed", "events suppressed over a trial"),
    ("shake_suppressed", "shake-only events suppressed"),
    ("hand_kept", "hand's events kept (hand moving)"),
    ("background_kept", "background's events kept (hand moving)"),
    ("hit", "hand hit (hand-moving sOMS steps)"),
)


def hand_costs(rows: Sequence[Row]) -> list[Cost]:
    """The hand trials' figures from an ``event_suppression`` run with ``agent.soms=speck`` and
    ``second_agent.soms=agent`` (module docstring)."""
    from experiments.paper.event_suppression_scoring import trial_figures

    if not rows or not any(k.startswith("second:") for k in rows[0]):
        raise ValueError(
            "the rows have no second: columns (run with --set second_agent.soms=agent)"
        )
    second = [
        {"seed": r["seed"], "phase": r["phase"]}
        | {k.removeprefix("second:"): v for k, v in r.items() if k.startswith("second:")}
        for r in rows
    ]
    speck, host = trial_figures(rows), trial_figures(second)
    seeds = sorted(speck)
    return [
        Cost(
            "hand trials",
            label,
            "%",
            mean_ci(speck[s][name] for s in seeds),
            mean_ci(host[s][name] for s in seeds),
            "trials",
        )
        for name, label in _HAND
    ]


def _group_figures(items: Iterable[tuple[Stimulus, Measure]]) -> dict[str, list[float]]:
    """Per claim group, each stimulus's figures (%)."""
    out: dict[str, list[float]] = {}
    for s, m in items:
        g = group_of(s)
        if g == "eye-only":
            out.setdefault("eye-only: events suppressed", []).append(100 * m.suppressed)
        elif g in ("eye+object", "object-only"):
            out.setdefault(f"{g}: precision", []).append(100 * m.precision)
            out.setdefault(f"{g}: object's events kept", []).append(100 * m.object_kept_share)
        elif g == "background-faster":
            out.setdefault(f"{g}: object still enhanced", []).append(100.0 * m.enhanced)
    return out


def family_costs(stimuli: Sequence[Stimulus]) -> list[Cost]:
    """The family's figures for the Speck front end and the agent's sOMS, measured on
    ``stimuli`` (each rendered once, both variants on the same counts)."""
    from agents.attention import AGENT_SOMS
    from agents.speck_front import SpeckFrontParams

    speck, host = [], []
    for s in stimuli:
        m = measure(s, {"speck": SpeckFrontParams(), "host": AGENT_SOMS})
        speck.append((s, m["speck"]))
        host.append((s, m["host"]))
    a, b = _group_figures(speck), _group_figures(host)
    return [
        Cost("sOMS family", name, "%", mean_ci(a[name]), mean_ci(b[name]), "stimuli") for name in a
    ]


def detection_costs(speck_quality: Path, host_quality: Path) -> list[Cost]:
    """Detection accuracy and sOMS suppression from two ``wander evaluate`` folders'
    ``quality.json`` (``--set agent.soms=speck`` and the default; read by
    :func:`experiments.jobs.evaluate_agent.read_quality`, a null figure as NaN), which must
    name the same seeds (ValueError otherwise)."""
    data = [
        read_quality(p, key)
        for p, key in ((speck_quality, "speck_quality"), (host_quality, "host_quality"))
    ]
    seeds = [[r["seed"] for r in d["rows"]] for d in data]
    if seeds[0] != seeds[1]:
        raise ValueError(f"the evaluate runs have different seeds: {seeds[0]} and {seeds[1]}")

    def accuracy(d: Mapping) -> Figure:
        p = d["pooled"]
        return (
            100 * float(p["detection_accuracy"]),
            100 * float(p["detection_ci_low"]),
            100 * float(p["detection_ci_high"]),
            int(p["scored"]),
        )

    def suppression(d: Mapping) -> Figure:  # a seed whose sOMS saw no event: NaN, skipped
        return mean_ci(100 * float(r["soms_suppression"]) for r in d["rows"])

    return [
        Cost("wander evaluate", "detection accuracy", "%", *map(accuracy, data), "decisions"),
        Cost(
            "wander evaluate",
            "events suppressed by the sOMS",
            "%",
            *map(suppression, data),
            "seeds",
        ),
    ]


def write_costs(costs: Sequence[Cost], path: Path) -> Path:
    """``costs`` as a strict JSON list (NaN as null)."""
    path.write_text(dumps_strict([asdict(c) for c in costs], indent=1))
    return path


def read_costs(path: Path) -> list[Cost]:
    """The costs :func:`write_costs` wrote."""

    def fig(v: list) -> Figure:
        m, lo, hi, n = (math.nan if x is None else x for x in v)
        return float(m), float(lo), float(hi), int(n)

    return [
        Cost(**{**d, "speck": fig(d["speck"]), "host": fig(d["host"])}) for d in read_json(path)
    ]


def table(costs: Sequence[Cost]) -> str:
    """The costs as a markdown table: mean [95 % interval] (n) per front end."""
    lines = [
        "| source | measure | Speck front end | agent's float sOMS | n counts |",
        "|---|---|---|---|---|",
    ]
    for c in costs:
        lines.append(
            f"| {c.source} | {c.measure} ({c.unit}) | {ci_text(c.speck, '.1f')} | "
            f"{ci_text(c.host, '.1f')} | {c.over} |"
        )
    return "\n".join(lines)


def plot(costs: Sequence[Cost], path: Path, note: str = "") -> Path:
    """Both front ends' figures side by side with their 95 % intervals, one row each."""
    plt = pyplot()

    y = np.arange(len(costs))
    fig, ax = plt.subplots(figsize=(10, 0.45 * len(costs) + 1.8))
    handles = []
    for j, (attr, label, colour) in enumerate(
        (
            ("speck", "front end on Speck's cores (int8, IAF)", "tab:red"),
            ("host", "agent's float sOMS (host)", "tab:blue"),
        )
    ):
        figs = [getattr(c, attr) for c in costs]
        m = np.array([f[0] for f in figs])
        lo = np.array([f[1] if not math.isnan(f[1]) else f[0] for f in figs])
        hi = np.array([f[2] if not math.isnan(f[2]) else f[0] for f in figs])
        bars = ax.barh(
            y + (j - 0.5) * 0.38,
            m,
            0.38,
            xerr=np.vstack([m - lo, hi - m]),
            color=colour,
            label=label,
            capsize=2,
        )
        handles.append(bars)
    ax.set_yticks(y, [f"{c.source}: {c.measure}" for c in costs], fontsize=7)
    ax.invert_yaxis()
    ax.set(xlim=(0, 105), xlabel="percent (mean; bars: 95 % interval)")
    ax.set_title(
        "What going on-chip costs: Speck front end vs the agent's float sOMS" + note, fontsize=9
    )
    legend_below(fig, handles, 8)
    return save_figure(fig, path, rect=(0, 0.05, 1, 1))
