"""Scoring an sOMS on the stimulus family (:mod:`experiments.paper.oms_stimuli`): pure
measures per stimulus, the claims of the paper over a set of stimuli, and the choice of
the ``"quantile"`` norm's parameters on the even-seed half.

A stimulus is rendered once (frames → DVS → event counts per 10 ms bin) and every
sOMS variant steps over the same counts. Per stimulus and variant: events in, events
kept (an event is kept when the OMS map fires at its pixel and polarity in its bin),
the object's events in and kept (the central window's mask): an
:class:`experiments.analysis.metrics.EventCounts`, from which the suppressed share, the
precision (object events kept / events kept, NaN when nothing is kept) and the share of
the object's events kept.

Examples:
    >>> from agents.soms import SOMSParams
    >>> from experiments.paper.oms_stimuli import Stimulus
    >>> s = Stimulus("sine", "patch", 16, "still", "ideal", duration_s=0.05)
    >>> m = measure(s, {"paper": SOMSParams()})["paper"]
    >>> m.events_in, m.kept
    (0, 0)
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, replace

import numpy as np
import torch

from agents.soms import SOMS, SOMSParams, oms_map, quantile_score
from agents.speck_front import SpeckFront, SpeckFrontParams
from agents.suppression import kept_events
from experiments.analysis.metrics import EventCounts, event_counts, reaches
from experiments.analysis.stats import mean_std
from experiments.paper.oms_stimuli import Recording, Stimulus, render

__all__ = [
    "CLAIM_GROUPS",
    "Measure",
    "family_claims",
    "group_of",
    "measure",
    "measure_recording",
    "oms_maps",
    "tune",
]

#: the family's claim groups and the motions in each
CLAIM_GROUPS: Mapping[str, tuple[str, ...]] = {
    "eye-only": ("eye-only",),
    "eye+object": ("ratio-2", "ratio-4"),
    "object-only": ("object-only",),
    "background-faster": ("ratio-0", "ratio-0.5", "opposite"),
}
#: eye-only: the share of events suppressed
SUPPRESS_BAR = 0.90
#: eye+object, object-only: the precision (object events kept / events kept) ...
PRECISION_BAR = 0.90
#: ... and the share of the object's events kept
OBJECT_KEPT_BAR = 0.30
#: background-faster: the most stimuli with the object still enhanced to fail as the paper
ENHANCED_BAR = 0.20


@dataclass(frozen=True)
class Measure(EventCounts):
    """Event counts of one variant on one stimulus."""

    @property
    def enhanced(self) -> bool:
        """The object stands out: precision > 0.5 and more of its events kept than of
        the background's (the test for the background-faster stimuli)."""
        ok, bk = self.object_kept_share, self.background_kept_share
        return bool(self.precision > 0.5 and ok > (0.0 if math.isnan(bk) else bk))


def group_of(s: Stimulus) -> str:
    """The claim group of a stimulus (``still`` has none: ``""``)."""
    for g, motions in CLAIM_GROUPS.items():
        if s.motion in motions:
            return g
    return ""


def _lif_key(p: SOMSParams) -> tuple:
    return (
        p.kernel_size,
        p.sigma_c,
        p.sigma_s,
        p.tau_mem,
        p.dt,
        p.spike_threshold,
        p.kernel_norm,
        p.conv,
    )


def oms_maps(
    counts: np.ndarray, bin_s: float, variants: Mapping[str, SOMSParams | SpeckFrontParams]
) -> Iterator[dict[str, np.ndarray]]:
    """Per bin of ``counts`` ``(n, 2, H, W)``, every variant's OMS map ``(2, H, W)``
    (bool), each variant stepped from rest with ``dt`` the bin ``bin_s``: bit for bit its
    own ``SOMS.step(bin).oms`` (a Speck front end, :class:`agents.speck_front.SpeckFrontParams`
    built for the sensor: its ``step(bin).oms``). Variants sharing the LIF stage share
    one run of it, and those sharing the pooling one pooling of its output."""
    h, w = counts.shape[-2:]
    params = {k: replace(p, dt=bin_s) for k, p in variants.items() if isinstance(p, SOMSParams)}
    fronts = {
        k: SpeckFront(replace(p, dt=bin_s, height_px=h, width_px=w))
        for k, p in variants.items()
        if isinstance(p, SpeckFrontParams)
    }
    groups: dict[tuple, list[str]] = {}
    for k, p in params.items():
        groups.setdefault(_lif_key(p), []).append(k)
    # built for the map size: a variant that only pools (never steps) gets its separable
    # FFT-mode pooling too, not the direct 37×37 conv2d (0.5 s a call)
    somses = {k: SOMS(p, h, w) for k, p in params.items()}
    with torch.no_grad():
        for c in counts:
            x = torch.from_numpy(c.astype(np.float32))
            maps = {k: front.step(x).oms > 0 for k, front in fronts.items()}
            for names in groups.values():
                diff = somses[names[0]].excess(x)  # the LIF state advances once per bin
                pooled: dict[tuple[float, str], torch.Tensor] = {}
                for k in names:
                    p = params[k]
                    if p.norm == "quantile":  # = SOMS.score(diff), the pooling shared
                        key = (p.pool_sigma, p.conv)
                        if key not in pooled:
                            pooled[key] = somses[k].pool(-diff)
                        score = quantile_score(
                            pooled[key], p.quantile, p.gain, p.floor_spikes, p.peak_ratio
                        )
                    else:
                        score = somses[k].score(diff)
                    maps[k] = oms_map(c, score.numpy(), p.alpha)  # = SOMS.step
            yield maps


def measure_recording(
    rec: Recording, variants: Mapping[str, SOMSParams | SpeckFrontParams]
) -> dict[str, Measure]:
    """Every variant's :func:`oms_maps` over the recording's counts (``dt`` its bin):
    the events in and kept (:func:`agents.suppression.kept_events`), all and on the
    object's mask."""
    acc = dict.fromkeys(variants, Measure(0, 0, 0, 0))
    for counts, maps in zip(
        rec.counts, oms_maps(rec.counts, rec.stimulus.bin_s, variants), strict=True
    ):
        for k, oms in maps.items():
            acc[k] += event_counts(counts, kept_events(counts, oms), rec.mask)
    return acc


def measure(
    s: Stimulus, variants: Mapping[str, SOMSParams | SpeckFrontParams]
) -> dict[str, Measure]:
    """Render ``s`` and measure every variant on it."""
    return measure_recording(render(s), variants)


def family_claims(
    items: Sequence[tuple[Stimulus, Measure]],
) -> dict[str, dict[str, float | bool | int]]:
    """The family's claims over ``items`` (means over the stimuli of each group where the
    figure is defined, NaN skipped; each stimulus weighs the same). ``pass`` per claim
    (:func:`experiments.analysis.metrics.reaches`: a NaN mean fails its bar, as does a
    stimulus's NaN figure in ``stimuli_passing``); background-faster: the share of
    stimuli where the object is still enhanced (the paper: fails in all)."""
    by: dict[str, list[Measure]] = {g: [] for g in CLAIM_GROUPS}
    for s, m in items:
        g = group_of(s)
        if g:
            by[g].append(m)
    out: dict[str, dict[str, float | bool | int]] = {}
    eo = by["eye-only"]
    supp = mean_std(m.suppressed for m in eo)[0]
    out["eye-only"] = {
        "n": len(eo),
        "suppressed": supp,
        "stimuli_passing": mean_std(float(reaches(m.suppressed, SUPPRESS_BAR)) for m in eo)[0],
        "pass": reaches(supp, SUPPRESS_BAR),
    }
    for g in ("eye+object", "object-only"):
        ms = by[g]
        prec = mean_std(m.precision for m in ms)[0]
        kept = mean_std(m.object_kept_share for m in ms)[0]
        passing = (
            reaches(m.precision, PRECISION_BAR) and reaches(m.object_kept_share, OBJECT_KEPT_BAR)
            for m in ms
        )
        out[g] = {
            "n": len(ms),
            "precision": prec,
            "object_kept": kept,
            "stimuli_passing": mean_std(float(p) for p in passing)[0],
            "pass": reaches(prec, PRECISION_BAR) and reaches(kept, OBJECT_KEPT_BAR),
        }
    bf = by["background-faster"]
    enhanced = mean_std(float(m.enhanced) for m in bf)[0]
    out["background-faster"] = {
        "n": len(bf),
        "enhanced": enhanced,
        "precision": mean_std(m.precision for m in bf)[0],
        "object_kept": mean_std(m.object_kept_share for m in bf)[0],
        "pass": bool(enhanced <= ENHANCED_BAR),  # fails as the paper
    }
    return out


def claims_passed(claims: Mapping[str, Mapping[str, float | bool | int]]) -> int:
    """How many of eye-only, eye+object and object-only pass."""
    return sum(bool(claims[g]["pass"]) for g in ("eye-only", "eye+object", "object-only"))


def margin(claims: Mapping[str, Mapping[str, float | bool | int]]) -> float:
    """The smallest relative margin over the three bars (negative: a bar missed)."""
    groups = ("eye+object", "object-only")
    parts = [
        float(claims["eye-only"]["suppressed"]) / SUPPRESS_BAR - 1.0,
        *(float(claims[g]["precision"]) / PRECISION_BAR - 1.0 for g in groups),
        *(float(claims[g]["object_kept"]) / OBJECT_KEPT_BAR - 1.0 for g in groups),
    ]
    return min(p if math.isfinite(p) else -1.0 for p in parts)


def candidates(
    base: SOMSParams,
    pool_sigmas: Sequence[float] = (6.0,),
    quantiles: Sequence[float] = (0.8, 0.9, 0.95),
    gains: Sequence[float] = (1.5, 2.0, 2.5, 3.0),
    peak_quantiles: Sequence[float] = (0.9, 0.95),
    peak_gains: Sequence[float] = (2.5, 3.0, 3.5),
    peak_ratios: Sequence[float] = (1.5, 1.75, 2.0, 2.25),
) -> dict[str, SOMSParams]:
    """The ``"quantile"``-norm settings searched by :func:`tune` (``alpha`` kept from
    ``base``): the plain norm (divisor ``gain`` × quantile) over ``quantiles`` ×
    ``gains``, and the peak-clipped one (``peak_ratio`` set) over ``peak_quantiles`` ×
    ``peak_gains`` × ``peak_ratios``; each for every ``pool_sigmas``.

    Examples:
        >>> len(candidates(SOMSParams()))
        36
    """
    out: dict[str, SOMSParams] = {}
    for s in pool_sigmas:
        for q, g in itertools.product(quantiles, gains):
            out[f"σ{s:g} q{q:g} g{g:g}"] = replace(
                base, norm="quantile", pool_sigma=s, quantile=q, gain=g
            )
        for q, g, r in itertools.product(peak_quantiles, peak_gains, peak_ratios):
            out[f"σ{s:g} q{q:g} g{g:g} peak {r:g}"] = replace(
                base, norm="quantile", pool_sigma=s, quantile=q, gain=g, peak_ratio=r
            )
    return out


def tune(
    stimuli: Sequence[Stimulus], grid: Mapping[str, SOMSParams]
) -> list[tuple[str, int, float, dict]]:
    """Every candidate of ``grid`` scored on ``stimuli`` (the even-seed half): rows
    ``(name, claims passed, margin, claims)``, best first (most claims, then the
    largest margin)."""
    per: dict[str, list[tuple[Stimulus, Measure]]] = {k: [] for k in grid}
    for s in stimuli:
        for k, m in measure(s, grid).items():
            per[k].append((s, m))
    rows = []
    for k, items in per.items():
        c = family_claims(items)
        rows.append((k, claims_passed(c), margin(c), c))
    rows.sort(key=lambda r: (-r[1], -r[2]))
    return rows
