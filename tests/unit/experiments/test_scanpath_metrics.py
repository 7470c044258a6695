"""Scanpath comparison: MultiMatch (against its published MATLAB-checked example), AOI
strings, entropy, and the scanpath experiment's statistics over trials."""

from __future__ import annotations

import json
import math
from pathlib import Path

import locations
import numpy as np
import pytest

from experiments.analysis import scanpath_stats
from experiments.paper import scanpath, scanpath_analysis
from experiments.runs.tables import write_csv

DATA = locations.DATA / "multimatch"
# multimatch-gaze's test_compare2matlab: the MATLAB toolbox's results on these two files
MATLAB_NO_GROUPING = [0.99082, 0.69902, 0.98927, 0.94767, 0.65563]
MATLAB_GROUPING = [0.95076, 0.95638, 0.94082, 0.94491, 0.78261]


def _table(name: str) -> np.ndarray:
    """A published fixation file as our table (pan = −x, tilt = −y, start, duration)."""
    d = np.loadtxt(DATA / name, delimiter="\t", skiprows=1)
    start = np.concatenate([[0.0], np.cumsum(d[:-1, 2])])
    return np.stack([-d[:, 0], -d[:, 1], start, d[:, 2]], axis=1)


def test_multimatch_reproduces_the_published_matlab_values() -> None:
    a, b = _table("segment_10_sub-19.tsv"), _table("segment_10_sub-01.tsv")
    got = scanpath_stats.multimatch(a, b, (720, 1280))
    assert list(got) == list(scanpath_stats.MULTIMATCH_DIMENSIONS)
    assert list(got.values()) == pytest.approx(MATLAB_NO_GROUPING, abs=1e-5)
    grouped = scanpath_stats.multimatch(
        a, b, (720, 1280), grouping=True, t_dir_deg=45.0, t_dur_s=0.3, t_amp_deg=146.8
    )
    assert list(grouped.values()) == pytest.approx(MATLAB_GROUPING, abs=1e-5)


def test_multimatch_of_a_translated_scanpath_differs_only_in_position() -> None:
    fx = np.array([[0, 0, 0, 0.2], [-10, 0, 0.3, 0.2], [-10, -10, 0.6, 0.4], [0, -5, 1, 0.1]])
    got = scanpath_stats.multimatch(fx, fx + np.array([3, 4, 0, 0]), (30.0, 40.0))
    # every fixation 5° away; the "screen" diagonal is 50°
    assert got["position"] == pytest.approx(1 - 5 / 50)
    for k in ("vector", "direction", "length", "duration"):
        assert got[k] == pytest.approx(1.0)
    short = scanpath_stats.multimatch(fx[:2], fx, (30.0, 40.0))
    assert all(math.isnan(v) for v in short.values())


def test_aoi_strings_edit_distance_and_entropy() -> None:
    assert scanpath_stats.fixation_aois(["a", "a", "", "b"], [False, True, True, True]) == [
        "a",
        "-",
        "b",
    ]
    assert scanpath_stats.levenshtein(["a", "b", "c"], ["a", "c"]) == 1
    assert scanpath_stats.levenshtein(["a", "b"], ["b", "a"]) == 2
    assert scanpath_stats.levenshtein_similarity(["a", "b"], ["a", "b"]) == 1.0
    assert math.isnan(scanpath_stats.levenshtein_similarity([], []))
    # 3 of a, 1 of b: H = 0.811 bits, normalised by log2(2)
    assert scanpath_stats.stationary_entropy(["a", "a", "a", "b"]) == pytest.approx(0.811278, 1e-5)
    assert scanpath_stats.stationary_entropy(list("abcd")) == pytest.approx(1.0)
    assert scanpath_stats.transition_entropy(list("abab")) == 0.0
    # from a: to b twice (1 of 3 sources each), from b: a and c; from c: none
    h = scanpath_stats.transition_entropy(list("abacab"))
    # sources a (3: b, c, b), b (1: a), c (1: a): π = (3/5, 1/5, 1/5)
    pa = np.array([2 / 3, 1 / 3])
    expected = 3 / 5 * -(pa * np.log2(pa)).sum() / math.log2(3)
    assert h == pytest.approx(expected)


def _row(scene, condition, seed, fixations, aois, hit) -> dict:
    return {
        "scene": scene,
        "condition": condition,
        "seed": seed,
        "object_hit_rate": hit,
        "scanpath_json": json.dumps(np.asarray(fixations, float).tolist()),
        "aois_json": json.dumps(aois),
    }


def _rows() -> list[dict]:
    """Fixational: the same three-object tour every seed (hit 0.9 + 0.01·seed);
    saccades: a tour drifting with the seed (hit 0.3)."""
    base = np.array([[0, 0, 0, 0.3], [-10, 0, 0.4, 0.3], [-10, -8, 0.8, 0.3], [0, -8, 1.2, 0.3]])
    rows = []
    for seed in range(10):
        rows.append(
            _row("shelf", "fixational", seed, base, ["cup", "box", "can", "cup"], 0.9 + 0.01 * seed)
        )
        drift = base + [[2 * seed * (k % 2), -seed, 0, 0] for k in range(4)]
        aois = ["-", "cup" if seed % 2 else "-", "-", "box" if seed % 3 else "-"]
        rows.append(_row("shelf", "saccades", seed, drift, aois, 0.3))
    return rows


def test_condition_tests_pair_by_seed() -> None:
    tests = scanpath_analysis.condition_tests(_rows(), ["object_hit_rate"])
    t = tests[("shelf", "object_hit_rate")]
    assert t.n == 10 and t.mean_diff == pytest.approx(0.645)
    assert t.p_value == pytest.approx(2 / 1024) and t.rank_biserial == 1.0
    summ = scanpath_analysis.cell_summaries(_rows(), ["object_hit_rate"])
    m, lo, hi, n = summ[("shelf", "fixational", "object_hit_rate")]
    assert (n, m) == (10, pytest.approx(0.945)) and lo < m < hi


def test_similarity_within_and_between_conditions() -> None:
    table = scanpath_analysis.similarity_table(_rows(), (112.8, 112.8))
    by = {r["group"]: r for r in table}
    assert set(by) == {"within fixational", "within saccades", "between fixational and saccades"}
    fix = by["within fixational"]
    assert fix["vector_n"] == 45 and by["between fixational and saccades"]["vector_n"] == 100
    for k in scanpath_analysis.SIMILARITY_MEASURES:
        assert fix[k] == pytest.approx(1.0)  # identical scanpaths
    assert by["within saccades"]["position"] == pytest.approx(0.977015, abs=1e-6)  # drifting
    stab = scanpath_analysis.stability_tests(_rows(), (112.8, 112.8))
    pos = stab[("shelf", "position")]
    # fixational 1.0 against saccades' 0.977015; every pair the same sign: p = 2 / 2**10
    assert pos.n == 10 and pos.mean_diff == pytest.approx(1.0 - 0.977015, abs=1e-6)
    assert pos.p_value == pytest.approx(2 / 1024)


def test_scanpath_compare_reports_intervals_tests_and_multimatch() -> None:
    cfg = scanpath.ScanpathConfig(scenes=("shelf",))
    rows = [
        r | {k: 1.0 for _, k, _ in scanpath._metrics(cfg) if k != "object_hit_rate"}
        for r in _rows()
    ]
    comps = scanpath.compare(cfg, rows)
    hit = comps[0]
    assert hit.result == "shelf: object hit rate"
    assert "fixational 94% [" in hit.ours and "(n = 10)" in hit.ours
    assert hit.note.startswith("fixational − saccades: Δ = 0.645 [")
    assert "p = 0.00195" in hit.note and "d_z" in hit.note
    mm = [c for c in comps if "MultiMatch" in c.result]
    assert [c.result for c in mm] == [
        "shelf: MultiMatch, within fixational",
        "shelf: MultiMatch, within saccades",
        "shelf: MultiMatch, between fixational and saccades",
    ]
    assert "position 1.000 [1.000, 1.000]" in mm[0].ours


def test_statistics_figure_draws_the_intervals_and_the_test(tmp_path, monkeypatch) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    cfg = scanpath.ScanpathConfig(scenes=("shelf",))
    rows = _rows()
    m, lo, hi = scanpath.bar_intervals(rows, ["shelf", "office"], "fixational", "object_hit_rate")
    want = scanpath_analysis.cell_summaries(rows, ["object_hit_rate"])
    mean, low, high, n = want[("shelf", "fixational", "object_hit_rate")]
    assert n == 10 and m[0] == pytest.approx(0.945)
    assert (lo[0], hi[0]) == (pytest.approx(mean - low), pytest.approx(high - mean))
    assert lo[0] > 0 and hi[0] > 0 and math.isnan(m[1])  # no office rows
    captured = {}
    real_close = plt.close
    monkeypatch.setattr(plt, "close", lambda fig=None: captured.setdefault("fig", fig))
    rows = [r | {k: 1.0 for k, _ in scanpath._stat_panels(cfg)[1:]} for r in rows]
    path = scanpath.plot_statistics(cfg, rows, tmp_path / "stats.png")
    assert path.is_file() and path.stat().st_size > 10_000
    fig = captured["fig"]
    hit_ax = fig.axes[0]
    # one error bar per condition on the hit-rate panel; the test's line above the bars
    bars = [c for c in hit_ax.containers if type(c).__name__ == "ErrorbarContainer"]
    assert len(bars) == 2
    texts = [t.get_text() for t in hit_ax.texts]
    # Δ = 0.6 + 0.01·seed: mean 0.645, sd 0.01·sd(0..9, ddof 1) = 0.030277 → d_z 21.30;
    # all ten positive: p = 2/1024
    assert texts == ["fix − sac: Δ = +0.64\np = 0.002, d_z = 21.30"]
    assert "10 seeded repeats" in fig._suptitle.get_text()
    real_close(fig)


# ----------------------------------------------------------------------------------------
# The fixation table


def test_times_start_at_zero_and_are_rounded_to_the_microsecond() -> None:
    assert scanpath_stats.fixation_times(-0.01, 0.13) == (0.0, 0.12)  # the end is kept
    assert scanpath_stats.fixation_times(0.7100000000000001, 0.9099999999999999) == (0.71, 0.91)
    got = scanpath_stats.normalise_fixations(
        np.array([[1.23456789, -0.5, -0.01, 0.13], [-2.0, 3.0, 0.5, 0.2]])
    )
    assert got.tolist() == [[1.234568, -0.5, 0.0, 0.12], [-2.0, 3.0, 0.5, 0.2]]


def test_fixation_rows_write_the_four_columns_then_the_extra_ones(tmp_path: Path) -> None:
    fx = np.array([[10.0, 5.0, -0.01, 0.26], [-3.0, 0.0, 0.25, 0.5]])
    columns, rows = scanpath_stats.fixation_rows(fx, {"aoi": ["mug", "-"], "hit": [1, None]})
    path = write_csv(rows, tmp_path / "f.csv", columns=columns)
    assert path.read_text() == (
        "pan_deg,tilt_deg,t_start_s,duration_s,aoi,hit\n"
        "10.0,5.0,0.0,0.25,mug,1\n"
        "-3.0,0.0,0.25,0.5,-,\n"
    )
    # no fixation: the header alone
    columns, rows = scanpath_stats.fixation_rows(np.zeros((0, 4)), {"aoi": []})
    path = write_csv(rows, tmp_path / "empty.csv", columns=columns)
    assert path.read_text() == "pan_deg,tilt_deg,t_start_s,duration_s,aoi\n"
    with pytest.raises(ValueError, match="column 'aoi' has 1 values for 2 rows"):
        scanpath_stats.fixation_rows(fx, {"aoi": ["mug"]})


# ----------------------------------------------------------------------------------------
# Windows merged into fixations, and the statistics of wander run and the experiment


def test_merge_windows_joins_the_windows_between_saccades() -> None:
    w = np.array(
        [[0, 0, 0.0, 0.1], [0, 0, 0.1, 0.1], [9, 2, 0.6, 0.1], [3, 3, 1.0, 0.1], [3, 3, 1.1, 0.1]]
    )
    got = scanpath_stats.merge_windows(w, [False, True, True, False, False])
    want = [[0, 0, 0.0, 0.2], [9, 2, 0.6, 0.1], [3, 3, 1.0, 0.2]]
    np.testing.assert_allclose(got, want, atol=1e-12)
    assert scanpath_stats.merge_windows(np.zeros((0, 4)), []).shape == (0, 4)
    with pytest.raises(ValueError, match="3 windows but 2 flags"):
        scanpath_stats.merge_windows(w[:3], [True, True])


def test_scanpath_summary_counts_a_fixation_over_windows_once() -> None:
    """Two windows without a saccade between them are one fixation of 0.2 s; the one
    saccade, (0, 0) → (5°, 1°), is the amplitude (per window it was 3 fixations of
    0.1 s and amplitudes 0 and 5.10°, mean 2.55°)."""
    windows = np.array([[0, 0, 0.0, 0.1], [0, 0, 0.1, 0.1], [5, 1, 0.5, 0.1]])
    s = scanpath_stats.scanpath_summary(windows, [False, True, True], np.array([[0, 0, 5, 1]]))
    # the great circle from (0, 0) to pan 5°, tilt 1°: cos d = cos 1° cos 5°
    amplitude = math.degrees(math.acos(math.cos(math.radians(1)) * math.cos(math.radians(5))))
    assert list(s) == [
        "fixations",
        "fixation_duration_mean_s",
        "fixation_duration_std_s",
        "saccade_amplitude_mean_deg",
        "saccade_amplitude_std_deg",
        "revisits",
        "coverage_deg2",
    ]
    assert (s["fixations"], s["fixation_duration_mean_s"], s["fixation_duration_std_s"]) == (
        2,
        0.15,
        0.05,
    )
    assert s["saccade_amplitude_mean_deg"] == pytest.approx(amplitude, abs=1e-9)
    assert round(s["saccade_amplitude_mean_deg"], 2) == 5.10
    assert (s["saccade_amplitude_std_deg"], s["revisits"]) == (0.0, 0)
    # coverage: the 1° grid points within 5° of (0, 0) or (5, 1)
    near = {
        (p, t)
        for p in range(-5, 11)
        for t in range(-5, 7)
        if math.hypot(p, t) <= 5 or math.hypot(p - 5, t - 1) <= 5
    }
    assert s["coverage_deg2"] == float(len(near)) == 130.0
    # every window ending its fixation: three fixations of 0.1 s
    each = scanpath_stats.scanpath_summary(windows, [True, True, True], np.zeros((0, 4)))
    assert (each["fixations"], each["fixation_duration_mean_s"]) == (3, 0.1)
    assert math.isnan(each["saccade_amplitude_mean_deg"])
    with pytest.raises(ValueError, match=r"saccades_deg must be \(m, 4\)"):
        scanpath_stats.scanpath_summary(windows, [True] * 3, np.zeros((1, 2)))
