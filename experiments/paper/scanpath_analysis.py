"""The scanpath experiment's statistics over its trials (pure functions over result rows).

Each :mod:`experiments.paper.scanpath` row carries its scanpath (``scanpath_json``: the merged
fixations ``[pan, tilt, start, duration]``) and the AOI of each fixation (``aois_json``:
the scene object under the fovea, ``-`` for none), so everything here works from
``results.csv`` alone:

- :func:`cell_summaries`: per scene, condition and metric the mean over repeats with its
  seeded bootstrap 95 % interval (:func:`experiments.analysis.stats.mean_ci`);
- :func:`condition_tests`: the two conditions against each other per scene and metric,
  paired by seed (repeat ``r`` runs seed ``seed + r`` in both conditions):
  :func:`experiments.analysis.stats.paired_comparison` (sign-flip permutation test, ``d_z``,
  matched-pairs rank-biserial);
- :func:`similarity_table`: MultiMatch (five dimensions) and the normalised Levenshtein
  similarity of the AOI strings over pairs of trials, within each condition (pairs of
  different seeds) and between the conditions (every pair). Pairs share trials, so their
  intervals are descriptive; the test of "more stable" is :func:`stability_tests`: per
  trial its mean similarity to the other seeds of its condition, paired by seed across
  the conditions.
"""

from __future__ import annotations

import itertools
import json
import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from experiments.analysis.scanpath_stats import (
    MULTIMATCH_DIMENSIONS,
    levenshtein_similarity,
    multimatch,
)
from experiments.analysis.stats import Comparison2, mean_ci, mean_std, paired_comparison

__all__ = [
    "SIMILARITY_MEASURES",
    "cell_summaries",
    "cells",
    "condition_tests",
    "pair_similarities",
    "similarity_table",
    "stability_tests",
]

SIMILARITY_MEASURES = (*MULTIMATCH_DIMENSIONS, "aoi_levenshtein")
Row = dict[str, Any]


def cells(rows: Sequence[Row]) -> dict[tuple[str, str], list[Row]]:
    """Rows grouped by (scene, condition), in first-appearance order, sorted by seed."""
    out: dict[tuple[str, str], list[Row]] = {}
    for r in rows:
        out.setdefault((str(r["scene"]), str(r["condition"])), []).append(r)
    return {k: sorted(v, key=lambda r: int(r["seed"])) for k, v in out.items()}


def _f(row: Row, key: str) -> float:
    v = row.get(key, math.nan)
    try:
        return float(v)
    except (TypeError, ValueError):
        return math.nan


def cell_summaries(
    rows: Sequence[Row], metrics: Sequence[str], seed: int = 0
) -> dict[tuple[str, str, str], tuple[float, float, float, int]]:
    """``{(scene, condition, metric): (mean, low, high, n)}`` over the repeats."""
    return {
        (s, c, m): mean_ci([_f(r, m) for r in rs], seed=seed)
        for (s, c), rs in cells(rows).items()
        for m in metrics
    }


def _paired_by_seed(a: Sequence[Row], b: Sequence[Row], key: str) -> tuple[list, list]:
    bs = {int(r["seed"]): r for r in b}
    pairs = [(_f(r, key), _f(bs[int(r["seed"])], key)) for r in a if int(r["seed"]) in bs]
    return [p[0] for p in pairs], [p[1] for p in pairs]


def condition_tests(
    rows: Sequence[Row],
    metrics: Sequence[str],
    a: str = "fixational",
    b: str = "saccades",
    seed: int = 0,
) -> dict[tuple[str, str], Comparison2]:
    """``{(scene, metric): a vs b}`` paired by seed, for every scene holding both."""
    groups = cells(rows)
    scenes = dict.fromkeys(s for s, _ in groups)
    out = {}
    for s in scenes:
        if (s, a) not in groups or (s, b) not in groups:
            continue
        for m in metrics:
            x, y = _paired_by_seed(groups[(s, a)], groups[(s, b)], m)
            out[(s, m)] = paired_comparison(x, y, seed=seed)
    return out


def _scanpath(row: Row) -> np.ndarray:
    return np.asarray(json.loads(str(row["scanpath_json"])), np.float64).reshape(-1, 4)


def _aois(row: Row) -> list[str]:
    return [str(a) for a in json.loads(str(row["aois_json"]))]


def pair_similarities(a: Row, b: Row, screen_deg: tuple[float, float]) -> dict[str, float]:
    """MultiMatch's five similarities and the AOI strings' Levenshtein similarity of two
    trials."""
    out = multimatch(_scanpath(a), _scanpath(b), screen_deg)
    out["aoi_levenshtein"] = levenshtein_similarity(_aois(a), _aois(b))
    return out


def _pairs(rows: Sequence[Row]) -> list[tuple[str, str, Row, Row]]:
    """(scene, group, row, row): within a condition (different seeds), between two."""
    groups = cells(rows)
    out = []
    for (s, c), rs in groups.items():
        for x, y in itertools.combinations(rs, 2):
            out.append((s, f"within {c}", x, y))
    for (s1, c1), (s2, c2) in itertools.combinations(groups, 2):
        if s1 != s2:
            continue
        for x in groups[(s1, c1)]:
            for y in groups[(s2, c2)]:
                out.append((s1, f"between {c1} and {c2}", x, y))
    return out


def similarity_table(
    rows: Sequence[Row], screen_deg: tuple[float, float], seed: int = 0
) -> list[dict[str, Any]]:
    """One row per (scene, group) with, for each of :data:`SIMILARITY_MEASURES`, the mean
    over pairs, its bootstrap interval and the pairs scored (``<measure>``,
    ``<measure>_low``, ``<measure>_high``, ``<measure>_n``)."""
    acc: dict[tuple[str, str], dict[str, list[float]]] = {}
    for s, g, x, y in _pairs(rows):
        sims = pair_similarities(x, y, screen_deg)
        d = acc.setdefault((s, g), {k: [] for k in SIMILARITY_MEASURES})
        for k in SIMILARITY_MEASURES:
            d[k].append(sims[k])
    table = []
    for (s, g), d in acc.items():
        row: dict[str, Any] = {"scene": s, "group": g}
        for k in SIMILARITY_MEASURES:
            m, lo, hi, n = mean_ci(d[k], seed=seed)
            row |= {k: m, f"{k}_low": lo, f"{k}_high": hi, f"{k}_n": n}
        table.append(row)
    return table


def stability_tests(
    rows: Sequence[Row],
    screen_deg: tuple[float, float],
    measures: Sequence[str] = ("position", "vector", "aoi_levenshtein"),
    a: str = "fixational",
    b: str = "saccades",
    seed: int = 0,
) -> dict[tuple[str, str], Comparison2]:
    """``{(scene, measure): a vs b}``: each trial's mean similarity to the other seeds of
    its condition, paired by seed across the two conditions (is ``a`` more repeatable?)."""
    groups = cells(rows)
    out = {}
    for s in dict.fromkeys(s for s, _ in groups):
        if (s, a) not in groups or (s, b) not in groups:
            continue
        per: dict[str, dict[int, dict[str, float]]] = {}
        for c in (a, b):
            rs = groups[(s, c)]
            sims = {
                (i, j): pair_similarities(rs[i], rs[j], screen_deg)
                for i, j in itertools.combinations(range(len(rs)), 2)
            }
            per[c] = {}
            for i, r in enumerate(rs):
                mine = [v for (p, q), v in sims.items() if i in (p, q)]
                per[c][int(r["seed"])] = {k: mean_std(v[k] for v in mine)[0] for k in measures}
        common = sorted(set(per[a]) & set(per[b]))
        for k in measures:
            out[(s, k)] = paired_comparison(
                [per[a][sd][k] for sd in common], [per[b][sd][k] for sd in common], seed=seed
            )
    return out
