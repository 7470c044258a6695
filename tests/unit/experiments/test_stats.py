"""experiments.analysis.stats: intervals, tests and effect sizes against hand-computed values."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats as st

from experiments.analysis.stats import (
    bootstrap_ci,
    ci_text,
    cliffs_delta,
    cohens_d,
    cohens_dz,
    independent_comparison,
    mean_ci,
    mean_std,
    number_text,
    paired_comparison,
    percent_text,
    rank_biserial_paired,
    real_time_factor,
    wilson_interval,
)


def test_bootstrap_interval_is_seeded_and_covers_the_mean() -> None:
    v = np.random.default_rng(3).normal(10.0, 2.0, 40)
    a, b = bootstrap_ci(v, seed=5), bootstrap_ci(v, seed=5)
    assert a == b
    assert a != bootstrap_ci(v, seed=6)
    lo, hi = a
    assert lo < v.mean() < hi
    # close to the normal-theory interval (se = s / sqrt(n)) for normal data
    half = 1.96 * v.std(ddof=1) / math.sqrt(len(v))
    assert hi - lo == pytest.approx(2 * half, rel=0.2)


def test_bootstrap_degenerate_cases() -> None:
    assert all(math.isnan(x) for x in bootstrap_ci([1.0]))
    assert bootstrap_ci([2.0, 2.0, float("nan")]) == (2.0, 2.0)
    m, lo, hi, n = mean_ci([1.0, 2.0, 3.0, float("nan")], seed=0)
    assert (m, n) == (2.0, 3) and lo <= 2.0 <= hi


def test_effect_sizes_by_hand() -> None:
    assert cohens_dz([1.0, 2.0, 3.0]) == pytest.approx(2.0)
    # no spread: undefined (NaN), never infinite; no effect at all: 0
    assert math.isnan(cohens_dz([0.5, 0.5])) and cohens_dz([0.0, 0.0]) == 0.0
    assert math.isnan(cohens_d([1.0, 1.0], [2.0, 2.0])) and cohens_d([1.0, 1.0], [1.0, 1.0]) == 0
    assert math.isnan(cohens_dz([0.5])) and math.isnan(cohens_d([1.0], [2.0, 3.0]))
    # pooled sd of [1,2,3] and [3,4,5] is 1: d = -2
    assert cohens_d([1, 2, 3], [3, 4, 5]) == pytest.approx(-2.0)
    # 9 pairs: 8 a > b, 0 a < b, one tie (3 vs 3)
    assert cliffs_delta([3, 4, 5], [1, 2, 3]) == pytest.approx(8 / 9)
    # Cliff's delta equals the Mann-Whitney rank-biserial 2U/(n m) − 1
    a, b = [0.2, 0.5, 0.9, 0.4], [0.1, 0.3, 0.3, 0.8, 0.6]
    u = st.mannwhitneyu(a, b).statistic
    assert cliffs_delta(a, b) == pytest.approx(2 * u / (len(a) * len(b)) - 1)
    # ranks of |d| = 1, 2, 3 (+, -, +): (1 + 3 - 2) / 6
    assert rank_biserial_paired([0.1, -0.2, 0.3, 0.0]) == pytest.approx(1 / 3)


def test_paired_permutation_test_is_exact_for_ten_pairs() -> None:
    a = np.arange(10.0) + 1.0
    b = np.zeros(10)
    r = paired_comparison(a, b, seed=0)
    # all ten differences positive: 2 of the 2^10 sign patterns are as extreme
    assert r.p_value == pytest.approx(2 / 1024)
    assert (r.n, r.mean_diff, r.rank_biserial) == (10, 5.5, 1.0)
    assert r.effect_d == pytest.approx(5.5 / np.std(a, ddof=1))
    assert r.diff_low < 5.5 < r.diff_high
    # a NaN drops its pair
    r2 = paired_comparison([1.0, np.nan, 3.0], [0.0, 1.0, 1.0])
    assert r2.n == 2 and r2.mean_diff == 1.5
    with pytest.raises(ValueError, match="differ in length"):
        paired_comparison([1.0], [1.0, 2.0])
    same = paired_comparison([1.0, 2.0], [1.0, 2.0])
    assert same.p_value == 1.0 and same.mean_diff == 0.0


def test_comparison_text_says_undefined_quantities_without_nan() -> None:
    one = paired_comparison([1.0], [0.5])
    assert one.text(".3g") == "Δ = 0.5 (n = 1: n too small for a test, which needs 2 pairs)"
    same = paired_comparison([1.0, 2.0], [1.0, 2.0])
    assert same.text(".2f") == "Δ = 0.00 [0.00, 0.00], p = 1, d_z = 0.00, r_rb = — (n = 2)"
    shift = paired_comparison([2.0, 3.0, 4.0], [1.0, 2.0, 3.0])
    assert (
        shift.text()
        == "Δ = 1.000 [1.000, 1.000], p = 0.25, d_z = — (no spread), r_rb = 1.00 (n = 3)"
    )
    lone = independent_comparison([1.0], [2.0, 3.0])
    text = lone.text(".1f")
    assert text == "Δ = -1.5 (n = 3: n too small for a test, which needs 2 values on each side)"
    texts = " ".join(x.text() for x in (one, same, shift, lone))
    assert "nan" not in texts and "inf" not in texts and "∞" not in texts


def test_ci_text_says_when_n_is_too_small() -> None:
    assert ci_text(mean_ci([1.0, 2.0, 3.0, 4.0]), ".2f").endswith("(n = 4)")
    assert ci_text(mean_ci([0.25]), ".0%") == "25% (n = 1: n too small for an interval)"
    assert ci_text(mean_ci([float("nan")]), ".1f") == "—"
    assert mean_std([0.13, 0.13, 0.13]) == (0.13, 0.0)  # no 9e-17 spread of equal values


def test_ci_text_puts_the_unit_after_the_mean() -> None:
    assert ci_text((82.3, 81.4, 83.2, 10), ".1f", " %") == "82.3 % [81.4, 83.2] (n = 10)"
    assert ci_text((82.3, math.nan, math.nan, 1), ".1f", " %") == (
        "82.3 % (n = 1: n too small for an interval)"
    )
    assert ci_text((math.nan, math.nan, math.nan, 0), ".1f", " %") == "—"


def test_number_and_percent_text_mark_a_missing_number_with_one_dash() -> None:
    assert number_text(1.25, ".1f", " ms") == "1.2 ms"
    assert number_text(None, ".1f", " ms") == number_text(np.float64("nan"), ".1f") == "—"
    assert percent_text(0.8516) == "85.2 %"
    assert percent_text(None) == percent_text(math.nan) == "—"


def test_real_time_factor_is_nan_without_a_positive_wall_time() -> None:
    assert real_time_factor(4.0, 10.0) == 0.4
    assert math.isnan(real_time_factor(4.0, 0.0))
    assert math.isnan(real_time_factor(4.0, -1.0))
    assert math.isnan(real_time_factor(math.inf, 1.0))
    assert math.isnan(real_time_factor(1.0, math.nan))


def test_independent_permutation_test_matches_a_t_test_on_separated_samples() -> None:
    rng = np.random.default_rng(1)
    a, b = rng.normal(1.0, 1.0, 30), rng.normal(0.0, 1.0, 30)
    r = independent_comparison(a, b, seed=2)
    t = st.ttest_ind(a, b)
    assert r.p_value == pytest.approx(t.pvalue, abs=0.01)
    assert r.effect_d == pytest.approx(cohens_d(a, b))
    assert r.diff_low < a.mean() - b.mean() < r.diff_high
    assert "Cliff's δ" in r.text()


def test_moved_helpers_keep_their_behaviour() -> None:
    assert mean_std([1.0, 3.0, float("nan")]) == (2.0, 1.0)
    assert mean_std([0.75, 0.5]) == (0.625, 0.125)
    assert math.isnan(mean_std([1.0], ddof=1)[1])
    low, high = wilson_interval(124, 140)
    assert (round(low, 3), round(high, 3)) == (0.822, 0.928)
    assert all(math.isnan(x) for x in wilson_interval(0, 0))
