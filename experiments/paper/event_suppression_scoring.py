"""Scoring the hand trials: a row's figures from its windows, a trial's from its rows.

:func:`score` steps an sOMS map model (:func:`map_model`: the host's sOMS or the Speck
front end) on a row's event windows and counts the events in and out, the hand's and the
background's (on the hand's :func:`swept` mask), and the hand hit (:func:`hand_hit`);
:func:`trial_figures` pools a trial's phase rows; :func:`pooled_mean_std` pools per-row
means and stds. Used by :mod:`experiments.paper.event_suppression` and the experiments
that reuse its protocol.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import replace
from typing import Any, Protocol

import numpy as np
import torch
from scipy.ndimage import binary_dilation, gaussian_filter

from agents.proto_object import saliency_argmax
from agents.soms import SOMS, SOMSParams
from agents.speck_front import SpeckFront, SpeckFrontParams
from agents.suppression import kept_events
from experiments.analysis.metrics import EventCounts, detection_hit, event_counts
from experiments.analysis.stats import wilson_interval
from experiments.paper.event_suppression_protocol import HAND_PHASES
from experiments.runs.tables import Row

__all__ = [
    "HAND_BARS",
    "MapModel",
    "hand_hit",
    "map_model",
    "oms_point",
    "pooled_mean_std",
    "score",
    "swept",
    "trial_figures",
]

#: The hand trials' pass bars (%, issue 25) on :func:`trial_figures`' figures (means over
#: trials): the hand hit, the suppression over a trial, shake-only, the hand's events kept.
HAND_BARS = {"hit": 90.0, "suppressed": 75.0, "shake_suppressed": 90.0, "hand_kept": 50.0}


def oms_point(oms: np.ndarray, sigma_px: float) -> tuple[int, int] | None:
    """The OMS map's densest point ``(x, y)``: the argmax of its both-polarity sum
    smoothed by a Gaussian of ``sigma_px`` (zero outside the sensor); None when empty.

    >>> m = np.zeros((2, 16, 16), bool); m[1, 4:7, 9:12] = True; m[0, 14, 1] = True
    >>> oms_point(m, 2.0)
    (10, 5)
    """
    dens = gaussian_filter(np.asarray(oms, np.float32).sum(axis=0), sigma_px, mode="constant")
    return saliency_argmax(torch.from_numpy(dens))


def hand_hit(oms: np.ndarray, hand: np.ndarray, sigma_px: float, box: int = 8) -> bool:
    """The scorer of the hand claim for one sOMS step: the ``box``×``box`` square around
    the OMS map's densest point (:func:`oms_point`) touches the hand's mask
    (:func:`experiments.analysis.metrics.detection_hit`); an empty map is a miss (the hand's events
    did not survive).

    >>> m = np.zeros((2, 32, 32), bool); m[1, 20:24, 20:24] = True   # kept events
    >>> oms_point(m, 2.0)                         # box: x and y in [17, 24]
    (21, 21)
    >>> hand = np.zeros((32, 32), bool); hand[24:29, 24:29] = True
    >>> hand_hit(m, hand, 2.0), hand_hit(m, np.roll(hand, 1, axis=1), 2.0)
    (True, False)
    >>> hand_hit(np.zeros((2, 32, 32), bool), hand, 2.0)   # nothing kept: a miss
    False
    """
    point = oms_point(oms, sigma_px)
    return point is not None and detection_hit(point, hand, box)


def swept(masks: np.ndarray, margin_px: int = 0) -> np.ndarray:
    """Per window, the pixels the hand covered during it: its mask at the window's end
    or at the one before's (the first window: its own), grown by ``margin_px`` (a
    square neighbourhood).

    >>> m = np.zeros((3, 1, 5), bool); m[0, 0, 0] = m[1, 0, 1] = m[2, 0, 2] = True
    >>> swept(m)[:, 0].astype(int).tolist()
    [[1, 0, 0, 0, 0], [1, 1, 0, 0, 0], [0, 1, 1, 0, 0]]
    >>> swept(m, 1)[2, 0].astype(int).tolist()
    [1, 1, 1, 1, 0]
    """
    out = masks.copy()
    out[1:] |= masks[:-1]
    if margin_px:
        grow = np.ones((1, 3, 3), bool)
        out = binary_dilation(out, grow, iterations=margin_px)
    return out


class MapModel(Protocol):
    """What :func:`score` steps: :class:`agents.soms.SOMS` (``step(counts).oms``)."""

    def step(self, event_map: np.ndarray) -> Any: ...


def map_model(block: SOMSParams | SpeckFrontParams, height: int, width: int) -> MapModel:
    """What :func:`score` steps for ``block``: the sOMS, or the Speck front end built for
    an ``height`` × ``width`` sensor."""
    if isinstance(block, SpeckFrontParams):
        return SpeckFront(replace(block, height_px=height, width_px=width))
    return SOMS(block)


def score(
    counts: np.ndarray,
    masks: np.ndarray,
    model: MapModel,
    per_step: int,
    lead_steps: int,
    hand_moves: bool,
    sigma_px: float,
    margin_px: int = 0,
) -> dict[str, Any]:
    """One row's figures from its windows: ``counts`` (n, 2, H, W) events per window,
    ``masks`` (n, H, W) the hand's pixels at each window's end; the sOMS ``model`` steps
    on each ``per_step`` windows' sum, the first ``lead_steps`` steps only warm it up.
    A window's hand events are those on the pixels the hand covered during it (its mask
    at the window's start or end) and ``margin_px`` around (:func:`swept`).
    ``hand_moves``: score the hand hit (steps with the hand in view) on the masks
    themselves."""
    n = counts.shape[0]
    if n % per_step:
        raise ValueError(f"{n} windows are not whole sOMS steps of {per_step}")
    region = swept(masks, margin_px)
    ins, outs = [], []
    ev = EventCounts(0, 0, 0, 0)
    hits = steps = 0
    for k in range(n // per_step):
        win = slice(k * per_step, (k + 1) * per_step)
        c = counts[win].astype(np.float32)
        oms = np.asarray(model.step(c.sum(axis=0)).oms) > 0
        if k < lead_steps:
            continue
        kept = kept_events(c, oms)  # the step's map gates each of its windows
        ins.extend(c.sum(axis=(1, 2, 3)).tolist())
        outs.extend(kept.sum(axis=(1, 2, 3)).tolist())
        ev += event_counts(c, kept, region[win])
        hand = masks[win].any(axis=0)  # the hit: the box touches the hand itself
        if hand_moves and hand.any():
            steps += 1
            hits += hand_hit(oms, hand, sigma_px)
    i, o = np.asarray(ins, np.int64), np.asarray(outs, np.int64)
    lo, hi = wilson_interval(hits, steps)
    return {
        "windows": len(i),
        "events_in_mean": float(i.mean()),
        "events_in_std": float(i.std()),
        "events_out_mean": float(o.mean()),
        "events_out_std": float(o.std()),
        "events_in": ev.events_in,
        "events_out": ev.kept,
        "suppressed_pct": 100.0 * ev.suppressed,
        "object_events_in": ev.object_in,
        "object_events_out": ev.object_kept,
        "object_kept_pct": 100.0 * ev.object_kept_share,
        "background_events_in": ev.background_in,
        "background_events_out": ev.background_kept,
        "background_kept_pct": 100.0 * ev.background_kept_share,
        "hit_steps": steps,
        "hand_hits": hits,
        "hand_hit_pct": _pct(hits, steps),
        "hand_hit_ci_low": 100.0 * lo,
        "hand_hit_ci_high": 100.0 * hi,
        "_events_in": i,
        "_events_out": o,
    }


def trial_figures(rows: Sequence[Row]) -> dict[int, dict[str, float]]:
    """Per trial (seed), from its phase rows: ``suppressed`` (% over the trial), ``hit``
    (% of the scored steps of the hand-moving phases), ``hand_kept`` and
    ``background_kept`` (% over the hand-moving phases; the background's events are those
    not the hand's), ``shake_suppressed`` (%); the bars on them: :data:`HAND_BARS`.

    >>> rows = [
    ...     {"seed": 0, "phase": "shake", "events_in": 100, "events_out": 5, "hit_steps": 0,
    ...      "hand_hits": 0, "object_events_in": 0, "object_events_out": 0},
    ...     {"seed": 0, "phase": "hand", "events_in": 100, "events_out": 55, "hit_steps": 10,
    ...      "hand_hits": 9, "object_events_in": 80, "object_events_out": 50}]
    >>> list(trial_figures(rows)[0].values())  # suppressed, hit, hand, background, shake
    [70.0, 90.0, 62.5, 25.0, 95.0]
    """
    out: dict[int, dict[str, float]] = {}
    for seed in dict.fromkeys(int(r["seed"]) for r in rows):
        mine = [r for r in rows if int(r["seed"]) == seed]
        moving = [r for r in mine if r["phase"] in HAND_PHASES]
        shake = [r for r in mine if r["phase"] == "shake"]
        hand = _pooled(moving)
        out[seed] = {
            "suppressed": 100.0 * _pooled(mine).suppressed,
            "hit": _pct(_sum(moving, "hand_hits"), _sum(moving, "hit_steps")),
            "hand_kept": 100.0 * hand.object_kept_share,
            "background_kept": 100.0 * hand.background_kept_share,
            "shake_suppressed": 100.0 * _pooled(shake).suppressed,
        }
    return out


def _sum(rows: Sequence[Row], name: str) -> int:
    return sum(int(r[name]) for r in rows)


def _pooled(rows: Sequence[Row]) -> EventCounts:
    """The event counts of :func:`score`'s rows together."""
    return EventCounts(
        _sum(rows, "events_in"),
        _sum(rows, "events_out"),
        _sum(rows, "object_events_in"),
        _sum(rows, "object_events_out"),
    )


def _pct(a: int, b: int) -> float:
    """``100 a / b``, NaN when ``b`` is 0."""
    return 100.0 * a / b if b else math.nan


def pooled_mean_std(means: np.ndarray, stds: np.ndarray, sizes: np.ndarray) -> tuple[float, float]:
    """Mean and (population) std of the union of groups from their sizes, means and
    population stds.

    >>> pooled_mean_std(np.array([1.0, 3.0]), np.array([0.0, 0.0]), np.array([1, 3]))
    (2.5, 0.8660254037844386)
    """
    m, s, n = (np.asarray(a, float) for a in (means, stds, sizes))
    mean = float(np.sum(n * m) / n.sum())
    var = float(np.sum(n * (s**2 + m**2)) / n.sum()) - mean**2
    return mean, math.sqrt(max(var, 0.0))
