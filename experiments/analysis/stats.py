"""Statistics for the experiments: intervals, tests and effect sizes (pure functions).

What a reviewer asks of a figure made from repeats, in one place:

- :func:`mean_std`, :func:`bootstrap_ci` (seeded percentile-corrected BCa bootstrap of
  the mean, :func:`scipy.stats.bootstrap`) and :func:`wilson_interval` (a pooled hit
  rate, :func:`scipy.stats.binomtest`);
- :func:`paired_comparison`: two conditions run on the same seeds (the experiments'
  repeats: repeat ``r`` has seed ``seed + r`` in every condition, so the scene and the
  agent draw the same random numbers): an exact sign-flip permutation test of the
  mean difference (:func:`scipy.stats.permutation_test`, ``permutation_type="samples"``),
  the bootstrap interval of the difference, Cohen's ``d_z`` (mean difference over the
  standard deviation of the differences: the paired design's standardised effect) and
  the matched-pairs rank-biserial correlation (:func:`rank_biserial_paired`: no normality
  assumed, robust to the ties and bounds of rates in [0, 1]);
- :func:`independent_comparison`: two unpaired samples (different scenes, or seeds that
  do not match): a permutation test of the difference of means, Cohen's ``d`` (pooled
  standard deviation, ``ddof = 1``) and Cliff's delta (:func:`cliffs_delta`, equal to the
  Mann-Whitney rank-biserial correlation; again no normality assumed).

Every random draw is seeded (``seed``); NaN values (a trial with nothing to score) are
dropped before anything is computed, and a pair is dropped when either side is NaN.
Results are plain floats, never infinite: NaN where a quantity is undefined — fewer than
:data:`MIN_N` values (pairs; on each side when unpaired) for a spread, an interval or a
test, or no spread for a standardised effect. The texts (:meth:`Comparison2.text`,
:func:`ci_text`) say which: ``n too small`` below the minimum, ``no spread`` where the
values do not vary.

Examples:
    >>> a = [0.9, 0.8, 0.85, 0.95, 0.7, 0.9, 0.8, 0.75, 0.9, 0.85]
    >>> b = [0.5, 0.6, 0.4, 0.55, 0.5, 0.65, 0.45, 0.5, 0.6, 0.4]
    >>> r = paired_comparison(a, b, seed=0)
    >>> r.n, round(r.mean_diff, 3), round(r.p_value, 4), r.rank_biserial
    (10, 0.325, 0.002, 1.0)
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Sequence
from dataclasses import asdict, dataclass

import numpy as np
from scipy import stats as _st

__all__ = [
    "MIN_N",
    "Comparison2",
    "bootstrap_ci",
    "ci_text",
    "cliffs_delta",
    "cohens_d",
    "cohens_dz",
    "finite",
    "independent_comparison",
    "mean_ci",
    "mean_std",
    "number_text",
    "paired_comparison",
    "percent_text",
    "rank_biserial_paired",
    "real_time_factor",
    "wilson_interval",
]

CONFIDENCE = 0.95
N_RESAMPLES = 9999
MIN_N = 2  # values (pairs) a spread, an interval or a test needs


def finite(values: Iterable[float]) -> np.ndarray:
    """The finite values as float64 (NaN and ±inf dropped).

    >>> finite([1.0, float("nan"), 2]).tolist()
    [1.0, 2.0]
    """
    v = np.asarray(list(values), dtype=np.float64).ravel()
    return v[np.isfinite(v)]


def mean_std(values: Iterable[float], ddof: int = 0) -> tuple[float, float]:
    """Mean and standard deviation of the finite values (NaN are skipped).

    ``(nan, nan)`` without finite values; the std is ``nan`` when there are no more
    values than ``ddof``. (Equal values give a std of exactly 0, not a rounding residue.)

    >>> mean_std([1.0, 3.0, float("nan")])
    (2.0, 1.0)
    """
    v = finite(values)
    if v.size == 0:
        return math.nan, math.nan
    if v.size <= ddof:
        return float(np.mean(v)), math.nan
    std = 0.0 if np.all(v == v[0]) else float(np.std(v, ddof=ddof))
    return float(np.mean(v)), std


def wilson_interval(hits: int, n: int, confidence: float = CONFIDENCE) -> tuple[float, float]:
    """Wilson score interval of a proportion ``hits / n`` ((nan, nan) when ``n == 0``).

    >>> low, high = wilson_interval(124, 140)
    >>> round(low, 3), round(high, 3)
    (0.822, 0.928)
    """
    if n == 0:
        return math.nan, math.nan
    ci = _st.binomtest(int(hits), int(n)).proportion_ci(
        confidence_level=confidence, method="wilson"
    )
    return float(ci.low), float(ci.high)


def bootstrap_ci(
    values: Iterable[float],
    statistic: Callable[[np.ndarray], float] = np.mean,
    confidence: float = CONFIDENCE,
    seed: int = 0,
    n_resamples: int = N_RESAMPLES,
) -> tuple[float, float]:
    """Seeded BCa bootstrap interval of ``statistic`` over the finite values.

    (nan, nan) with fewer than :data:`MIN_N` values; (v, v) when all values are equal
    (the bootstrap distribution is a point).

    >>> bootstrap_ci([1.0, 1.0, 1.0])
    (1.0, 1.0)
    >>> lo, hi = bootstrap_ci(np.arange(20.0), seed=1)
    >>> bool(lo < 9.5 < hi), round(hi - lo, 1)
    (True, 5.0)
    """
    v = finite(values)
    if v.size < MIN_N:
        return math.nan, math.nan
    if np.all(v == v[0]):
        s = float(statistic(v))
        return s, s
    res = _st.bootstrap(
        (v,),
        lambda x, axis: statistic(x, axis=axis),
        confidence_level=confidence,
        n_resamples=n_resamples,
        method="BCa",
        rng=np.random.default_rng(seed),
        vectorized=True,
    )
    lo, hi = float(res.confidence_interval.low), float(res.confidence_interval.high)
    if not (math.isfinite(lo) and math.isfinite(hi)):  # BCa degenerate: percentile instead
        boot = res.bootstrap_distribution
        q = (1 - confidence) / 2
        lo, hi = float(np.quantile(boot, q)), float(np.quantile(boot, 1 - q))
    return lo, hi


def mean_ci(
    values: Iterable[float], seed: int = 0, confidence: float = CONFIDENCE
) -> tuple[float, float, float, int]:
    """(mean, low, high, n) of the finite values, the interval from :func:`bootstrap_ci`.

    >>> mean_ci([2.0, 2.0, float("nan")])
    (2.0, 2.0, 2.0, 2)
    """
    v = finite(values)
    lo, hi = bootstrap_ci(v, seed=seed, confidence=confidence)
    return (float(v.mean()) if v.size else math.nan), lo, hi, int(v.size)


def ci_text(summary: tuple[float, float, float, int], spec: str, unit: str = "") -> str:
    """A :func:`mean_ci` result as text, the numbers formatted by ``spec`` and ``unit``
    after the mean: ``m [lo, hi] (n = k)``; ``—`` without values; below :data:`MIN_N`
    the mean and ``n too small`` for an interval.

    >>> ci_text((0.5, 0.25, 0.75, 10), ".2f"), ci_text((0.5, math.nan, math.nan, 1), ".0%")
    ('0.50 [0.25, 0.75] (n = 10)', '50% (n = 1: n too small for an interval)')
    >>> ci_text((82.3, 81.4, 83.2, 10), ".1f", " %")
    '82.3 % [81.4, 83.2] (n = 10)'
    """
    m, lo, hi, n = summary
    if math.isnan(m):
        return "—"
    if n < MIN_N or math.isnan(lo) or math.isnan(hi):
        return f"{m:{spec}}{unit} (n = {n}: n too small for an interval)"
    return f"{m:{spec}}{unit} [{lo:{spec}}, {hi:{spec}}] (n = {n})"


def number_text(value: float | None, spec: str, unit: str = "") -> str:
    """``value`` formatted by ``spec``, then ``unit``; ``—`` where it is None or NaN.

    >>> number_text(0.25, ".2f"), number_text(math.nan, ".2f"), number_text(None, "g")
    ('0.25', '—', '—')
    >>> number_text(3.0, "g", " ms")
    '3 ms'
    """
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "—"
    return format(value, spec) + unit


def percent_text(fraction: float | None) -> str:
    """A fraction as a percentage with one decimal, ``12.5 %``; ``—`` where it is None or
    NaN.

    >>> percent_text(0.125), percent_text(math.nan), percent_text(None)
    ('12.5 %', '—', '—')
    """
    return number_text(None if fraction is None else 100 * fraction, ".1f", " %")


def real_time_factor(simulated_s: float, wall_s: float) -> float:
    """Simulated seconds per wall second (1.0 = real time); NaN when ``wall_s`` is not
    positive or ``simulated_s`` not finite.

    >>> real_time_factor(3.0, 6.0), real_time_factor(3.0, 0.0), real_time_factor(math.nan, 1.0)
    (0.5, nan, nan)
    """
    if not (wall_s > 0 and math.isfinite(simulated_s)):
        return math.nan
    return simulated_s / wall_s


# ----------------------------------------------------------------------------------------
# Effect sizes


def cohens_dz(diffs: Iterable[float]) -> float:
    """Paired effect size: mean of the differences over their std (``ddof = 1``).

    NaN with fewer than :data:`MIN_N` differences, and when all differences are equal and
    non-zero (no spread: the effect is not a finite number of standard deviations); 0
    when they are all zero.

    >>> cohens_dz([1.0, 2.0, 3.0]), cohens_dz([0.5, 0.5])
    (2.0, nan)
    """
    d = finite(diffs)
    if d.size < MIN_N:
        return math.nan
    m = float(np.mean(d))
    if np.all(d == d[0]):
        return 0.0 if m == 0 else math.nan
    return m / float(np.std(d, ddof=1))


def cohens_d(a: Iterable[float], b: Iterable[float]) -> float:
    """Unpaired effect size: difference of means over the pooled std (``ddof = 1``).

    NaN with fewer than :data:`MIN_N` values on a side, and when neither side varies but
    their means differ (no spread); 0 when all values are equal.

    >>> round(cohens_d([1.0, 2.0, 3.0], [2.0, 3.0, 4.0]), 3), cohens_d([1.0, 1.0], [2.0, 2.0])
    (-1.0, nan)
    """
    x, y = finite(a), finite(b)
    if x.size < MIN_N or y.size < MIN_N:
        return math.nan
    m = float(x.mean() - y.mean())
    if np.all(x == x[0]) and np.all(y == y[0]):
        return 0.0 if m == 0 else math.nan
    pooled = ((x.size - 1) * x.var(ddof=1) + (y.size - 1) * y.var(ddof=1)) / (x.size + y.size - 2)
    return m / math.sqrt(pooled)


def cliffs_delta(a: Iterable[float], b: Iterable[float]) -> float:
    """Cliff's delta: P(a > b) − P(a < b) over all pairs, in [−1, 1] (NaN if a side is
    empty). Equal to the Mann-Whitney rank-biserial correlation.

    >>> cliffs_delta([3, 4, 5], [1, 2, 3])
    0.8888888888888888
    """
    x, y = finite(a), finite(b)
    if x.size == 0 or y.size == 0:
        return math.nan
    diff = x[:, None] - y[None, :]
    return float((np.sum(diff > 0) - np.sum(diff < 0)) / diff.size)


def rank_biserial_paired(diffs: Iterable[float]) -> float:
    """Matched-pairs rank-biserial correlation: (rank sum of the positive differences −
    that of the negative ones) / the total rank sum, zeros dropped (Wilcoxon's ranks);
    in [−1, 1], NaN without a non-zero difference.

    >>> rank_biserial_paired([1.0, 2.0, -0.5, 3.0])
    0.8
    """
    d = finite(diffs)
    d = d[d != 0]
    if d.size == 0:
        return math.nan
    ranks = _st.rankdata(np.abs(d))
    return float((ranks[d > 0].sum() - ranks[d < 0].sum()) / ranks.sum())


# ----------------------------------------------------------------------------------------
# Tests


@dataclass(frozen=True)
class Comparison2:
    """Condition ``a`` against condition ``b``: ``n`` (pairs, or ``n_a + n_b``), the means,
    the difference ``a − b`` with its bootstrap interval, the permutation test's
    two-sided ``p_value``, the standardised effect (``d_z`` paired, Cohen's ``d``
    unpaired) and the rank effect (matched-pairs rank-biserial, or Cliff's delta)."""

    test: str
    n: int
    mean_a: float
    mean_b: float
    mean_diff: float
    diff_low: float
    diff_high: float
    p_value: float
    effect_d: float
    rank_biserial: float

    def as_dict(self, prefix: str = "") -> dict[str, float | int | str]:
        """The fields as a flat dict (keys prefixed), for a CSV row."""
        return {f"{prefix}{k}": v for k, v in asdict(self).items()}

    def text(self, fmt: str = ".3f") -> str:
        """One line: difference [interval], p, d, r; below :data:`MIN_N` pairs (values on
        a side, unpaired) the difference and ``n too small``; a standardised effect
        without spread ``— (no spread)``, a rank effect without a non-zero difference
        ``—``."""
        if self.n == 0 or math.isnan(self.mean_diff):
            return "no data"
        paired = self.test == "paired"
        delta = f"Δ = {self.mean_diff:{fmt}}"
        if math.isnan(self.p_value):  # only below the minimum: every test has a p
            need = f"{MIN_N} pairs" if paired else f"{MIN_N} values on each side"
            return f"{delta} (n = {self.n}: n too small for a test, which needs {need})"
        d_name = "d_z" if paired else "d"
        r_name = "r_rb" if paired else "Cliff's δ"
        d = "— (no spread)" if math.isnan(self.effect_d) else f"{self.effect_d:.2f}"
        r = "—" if math.isnan(self.rank_biserial) else f"{self.rank_biserial:.2f}"
        return (
            f"{delta} [{self.diff_low:{fmt}}, {self.diff_high:{fmt}}], "
            f"p = {self.p_value:.3g}, {d_name} = {d}, {r_name} = {r} (n = {self.n})"
        )


def _mean_diff(x: np.ndarray, y: np.ndarray, axis: int = -1) -> np.ndarray:
    return np.mean(x, axis=axis) - np.mean(y, axis=axis)


def paired_comparison(
    a: Sequence[float], b: Sequence[float], seed: int = 0, n_resamples: int = N_RESAMPLES
) -> Comparison2:
    """``a`` vs ``b`` measured on the same seeds (``a[i]`` with ``b[i]``); pairs with a NaN
    are dropped. The permutation test flips the signs of the differences (exact when
    ``2**n <= n_resamples``); the interval is the bootstrap of the mean difference."""
    x, y = np.asarray(a, np.float64).ravel(), np.asarray(b, np.float64).ravel()
    if x.shape != y.shape:
        raise ValueError(f"paired samples differ in length: {x.size} vs {y.size}")
    ok = np.isfinite(x) & np.isfinite(y)
    x, y = x[ok], y[ok]
    d = x - y
    n = int(d.size)
    mean_a = float(x.mean()) if n else math.nan
    mean_b = float(y.mean()) if n else math.nan
    if n < MIN_N:
        diff = float(d.mean()) if n else math.nan
        return Comparison2("paired", n, mean_a, mean_b, diff, *(math.nan,) * 5)
    if np.all(d == 0):
        p = 1.0
    else:
        p = _permutation_p(x, y, "samples", n_resamples, np.random.default_rng(seed))
    lo, hi = bootstrap_ci(d, seed=seed)
    return Comparison2(
        "paired",
        n,
        mean_a,
        mean_b,
        float(d.mean()),
        lo,
        hi,
        p,
        cohens_dz(d),
        rank_biserial_paired(d),
    )


def _permutation_p(
    x: np.ndarray, y: np.ndarray, kind: str, n_resamples: int, rng: np.random.Generator
) -> float:
    """Two-sided permutation p of the difference of means (``kind``: scipy's
    ``permutation_type``, "samples" for paired data, "independent" for two groups)."""
    res = _st.permutation_test(
        (x, y),
        _mean_diff,
        permutation_type=kind,
        vectorized=True,
        n_resamples=n_resamples,
        alternative="two-sided",
        rng=rng,
    )
    return float(res.pvalue)


def independent_comparison(
    a: Sequence[float], b: Sequence[float], seed: int = 0, n_resamples: int = N_RESAMPLES
) -> Comparison2:
    """Unpaired ``a`` vs ``b`` (NaN dropped on each side): a permutation test of the
    difference of means (labels reshuffled), its bootstrap interval (each side resampled
    on its own), Cohen's d and Cliff's delta."""
    x, y = finite(a), finite(b)
    n = int(x.size + y.size)
    mean_a = float(x.mean()) if x.size else math.nan
    mean_b = float(y.mean()) if y.size else math.nan
    if x.size < MIN_N or y.size < MIN_N:
        diff = mean_a - mean_b
        return Comparison2("independent", n, mean_a, mean_b, diff, *(math.nan,) * 5)
    both = np.concatenate([x, y])
    if np.all(both == both[0]):
        p, lo, hi = 1.0, 0.0, 0.0
    else:
        rng = np.random.default_rng(seed)
        p = _permutation_p(x, y, "independent", n_resamples, rng)
        boot = _st.bootstrap(
            (x, y),
            _mean_diff,
            confidence_level=CONFIDENCE,
            n_resamples=n_resamples,
            method="percentile",
            rng=rng,
            vectorized=True,
        )
        lo, hi = float(boot.confidence_interval.low), float(boot.confidence_interval.high)
    return Comparison2(
        "independent",
        n,
        mean_a,
        mean_b,
        mean_a - mean_b,
        lo,
        hi,
        p,
        cohens_d(x, y),
        cliffs_delta(x, y),
    )
