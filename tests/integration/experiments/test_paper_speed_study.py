"""The speed study: main-sequence fits, response surfaces, and its factorial sweep
resuming and agreeing on the local and Ray backends."""

from __future__ import annotations

import math

import numpy as np
import pytest

from experiments.paper import ptu_main_sequence, saccade_speed
from experiments.paper.main_sequence import fit_linear, fit_saturating, saturating
from experiments.paper.speed_study import plot_surfaces, surface
from experiments.runs.tables import read_csv
from experiments.studies.sweep import load_sweep, run_sweep, sweep_from_dict
from wander_env.ptu.params import PTUParams


def test_saturating_fit_recovers_noisy_parameters_with_honest_intervals() -> None:
    rng = np.random.default_rng(0)
    a = np.repeat([1.0, 2, 4, 7, 10, 15, 20, 30, 40], 3)
    v = saturating(a, 45.0, 6.0) + rng.normal(0, 1.0, a.size)
    fit = fit_saturating(a, v)
    lo, hi = fit.intervals["vmax"]
    assert lo < 45.0 < hi and hi - lo < 3.0
    lo, hi = fit.intervals["c"]
    assert lo < 6.0 < hi
    assert fit.n == 27 and fit.r2 > 0.98 and fit.rmse == pytest.approx(1.0, abs=0.3)
    assert "vmax = " in fit.text({"vmax": "°/s"})


def test_linear_fit_and_too_few_points() -> None:
    a = np.array([1.0, 5.0, 10.0, 20.0])
    fit = fit_linear(a, 0.1 + 0.02 * a)
    assert fit.params["d0"] == pytest.approx(0.1) and fit.params["k"] == pytest.approx(0.02)
    assert fit.r2 == pytest.approx(1.0)
    short = fit_linear([1.0, 2.0], [0.1, 0.2])
    assert short.n == 2 and math.isnan(short.params["k"]) and math.isnan(short.r2)
    cols = fit.as_dict("ms_d_")
    assert set(cols) == {
        "ms_d_d0",
        "ms_d_d0_low",
        "ms_d_d0_high",
        "ms_d_k",
        "ms_d_k_low",
        "ms_d_k_high",
        "ms_d_r2",
        "ms_d_rmse",
    }


def test_trapezoid_main_sequence_under_the_standard_forms() -> None:
    """The FLIR defaults' rest-to-rest trapezoid (theory): a stepper starts at its base
    speed (1000 pos/s = 25.7 °/s) and its peak grows as sqrt(vb² + a·d) up to the slew
    speed, so the eye's saturating exponential fits it badly, the linear duration well."""
    amps = np.array([1.0, 2, 4, 7, 10, 15, 20, 30, 40])
    v, d = ptu_main_sequence.theory_main_sequence(amps, PTUParams())
    vf, df = fit_saturating(amps, v), fit_linear(amps, d)
    assert v[0] == pytest.approx(26.7, abs=0.1) and v[-1] == pytest.approx(51.43, abs=0.01)
    assert vf.r2 < 0.6 and v[0] < vf.params["vmax"] < v[-1]
    assert df.r2 > 0.98 and df.params["k"] == pytest.approx(0.0255, abs=0.001)


def test_surface_marginal_means_and_figure(tmp_path) -> None:
    rows = []
    for s in (1000.0, 2000.0):
        for acc in (1000.0, 8000.0):
            for step in (20, 120):
                for seed in range(3):
                    rows.append(
                        {
                            "speed_pos_s": s,
                            "accel_pos_s2": acc,
                            "fixational_step_pos": step,
                            "fixational_n_steps": 8,
                            "cfg.window_s": 0.124,
                            "time_to_foveate_s": 1000.0 / s + 1000.0 / acc + 0.01 * seed,
                            "detection_accuracy": 0.5 + step / 1000.0,
                        }
                    )
    sf = surface(rows, "speed_pos_s", "accel_pos_s2", "time_to_foveate_s")
    assert sf.x.tolist() == [1000.0, 2000.0] and sf.y.tolist() == [1000.0, 8000.0]
    assert sf.n.tolist() == [[6, 6], [6, 6]]
    assert sf.mean[0, 0] == pytest.approx(2.01) and sf.mean[1, 1] == pytest.approx(0.635)
    # the cell's 6 trials are 2.00, 2.01, 2.02 twice: the interval lies inside their range
    assert 2.0 <= sf.low[0, 0] < 2.01 < sf.high[0, 0] <= 2.02
    # a sweep's cfg.<key> column is found as the factor
    w = surface(rows, "window_s", "fixational_n_steps", "detection_accuracy")
    assert w.mean.tolist() == [[pytest.approx(0.57)]]
    path = plot_surfaces(rows, tmp_path / "rs.png")
    assert path.stat().st_size > 10_000


def test_speed_sweep_files_are_valid() -> None:
    from experiments.studies.framework import configs_dir

    full = load_sweep(configs_dir() / "sweep_speed.yaml")
    quick = load_sweep(configs_dir() / "sweep_speed_quick.yaml")
    assert full.experiments[0].set["design"] == "factorial"
    assert full.experiments[0].grid == {"ptu_preset": ["flir", "ideal"]}
    assert quick.experiments[0].set["repeats"] == 10


TINY = {
    "name": "tiny_speed",
    "seeds": [0],
    "experiments": [
        {
            "experiment": "saccade_speed",
            "set": {
                "design": "factorial",
                "duration_s": 0.05,
                "repeats": 1,
                "speeds_pos_s": [2000.0],
                "accels_pos_s2": [2000.0],
                "fixational_steps_pos": [60],
                "fixational_counts": [8],
                "windows_s": [0.05],
                "main_sequence_amplitudes_deg": [5.0],
            },
            "grid": {"ptu_preset": ["flir", "ideal"]},
        }
    ],
}


@pytest.mark.slow  # five ~10 s trials plus worker and Ray start-up; 8 min at load 28 on 2 cores
def test_factorial_sweep_resumes_and_local_and_ray_agree(tmp_path, ray_instance) -> None:
    sweep = sweep_from_dict(TINY)
    local = tmp_path / "local"
    res = run_sweep(sweep, local, backend="local", workers=2)
    assert (res.ran, res.skipped) == (2, 0)
    table = (local / "results.csv").read_bytes()
    victim = sorted((local / "trials").glob("*.json"))[0]
    victim.unlink()
    res = run_sweep(sweep, local, backend="local", workers=2)
    assert (res.ran, res.skipped) == (1, 1)
    assert (local / "results.csv").read_bytes() == table
    res = run_sweep(sweep, tmp_path / "ray", backend="ray", workers=2)
    assert res.ran == 2
    assert (tmp_path / "ray" / "results.csv").read_bytes() == table
    rows = read_csv(local / "results.csv")
    assert [r["cfg.ptu_preset"] for r in rows] == ["flir", "ideal"]
    flir, ideal = rows
    assert flir["command_latency_mean_s"] > 0.009 and ideal["command_latency_mean_s"] == 0.0
    # the serial link delays the move: command to standstill is longer on the FLIR unit
    assert flir["ms_duration_max_s"] > ideal["ms_duration_max_s"]


def test_one_at_a_time_figure_has_intervals_and_main_sequence_fits(tmp_path, monkeypatch) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from experiments.studies.framework import save_artifacts

    cfg = saccade_speed.SaccadeSpeedConfig(repeats=3)
    grid = saccade_speed.grid(cfg)
    rows = []
    for k, p in enumerate(grid):
        for r in range(3):
            rows.append(
                {
                    "trial": len(rows),
                    "trial_id": f"t{len(rows)}",
                    "repeat": r,
                    "seed": r,
                    **p,
                    "time_to_foveate_s": 0.3 + 0.01 * r + 0.001 * k,
                    "detection_accuracy": 0.5,
                    "foveation_error_x_px": 1.0 + r,
                    "foveation_error_y_px": 2.0,
                    "events_per_s": 1e4,
                }
            )
    amps = np.array(cfg.main_sequence_amplitudes_deg)
    v, d = ptu_main_sequence.theory_main_sequence(amps, PTUParams())
    vf, df = fit_saturating(amps, v), fit_linear(amps, d)
    rows[0] |= vf.as_dict("ms_v_") | df.as_dict("ms_d_")
    arrays = {"ms_amplitude_deg": amps, "ms_peak_velocity_deg_s": v, "ms_duration_s": d}
    save_artifacts(tmp_path, "t0", arrays)
    # factor_intervals: the baseline's x errors 1, 2, 3 px: mean 2, a bootstrap interval
    m, lo, hi = saccade_speed.factor_intervals(
        rows[:3], "window_s", "foveation_error_x_px", [0.124]
    )
    assert m.tolist() == [2.0] and 0 < lo[0] <= 1.0 and 0 < hi[0] <= 1.0
    figs = []
    real_close = plt.close
    monkeypatch.setattr(plt, "close", lambda fig=None: figs.append(fig))
    paths = saccade_speed.plot(cfg, rows, tmp_path, tmp_path / "fig")
    assert [p.name for p in paths] == ["main_sequence.png", "saccade_speed.png"]
    ms_fig, oat_fig = figs
    labels = [line.get_label() for line in ms_fig.axes[0].lines]
    vmax, c = vf.params["vmax"], vf.params["c"]
    assert f"fit: Vmax {vmax:.1f} °/s, C {c:.2f}° (R² {vf.r2:.3f})" in labels
    assert any(lb.startswith("fit: D0 ") for lb in (x.get_label() for x in ms_fig.axes[1].lines))
    # every panel of the one-at-a-time figure draws its means with error bars (x and y
    # foveation errors: two)
    per_panel = [
        sum(type(cn).__name__ == "ErrorbarContainer" for cn in ax.containers) for ax in oat_fig.axes
    ]
    n_factors = len(saccade_speed.NUMERIC_FACTORS)
    assert per_panel == [1] * n_factors + [2] * n_factors + [1] * 2 * n_factors
    assert "mean over 3 seeded repeats" in oat_fig._suptitle.get_text()
    for f in figs:
        real_close(f)


def test_saturating_fit_of_a_constant_peak_leaves_c_undefined() -> None:
    """A unit slewing at its base speed at every amplitude (1000 pos/s: 25.7 °/s):
    Vmax is that speed, C is not identifiable (was a spurious 0.04 [0.04, 0.04]°)."""
    amps = np.array([1.0, 2, 4, 7, 10, 15, 20, 30, 40])
    fit = fit_saturating(amps, np.full(amps.size, 25.714))
    assert fit.params["vmax"] == 25.714 and fit.intervals["vmax"] == (25.714, 25.714)
    assert math.isnan(fit.params["c"]) and all(math.isnan(x) for x in fit.intervals["c"])
    assert fit.n == 9 and fit.rmse == 0.0 and math.isnan(fit.r2)
    row = fit.as_dict("ms_v_") | fit_linear(amps, 0.1 + 0.0374 * amps).as_dict("ms_d_")
    row["ms_amplitudes"] = fit.n
    text = ptu_main_sequence.fits_text(row)
    assert text.startswith("V = Vmax(1 − e^(−A/C)): Vmax 25.7 [25.7, 25.7] °/s, ")
    assert "C — (not identifiable) (R² —)" in text and "k 0.0374 [0.0374, 0.0374] s/°" in text
