"""The agent experiments: sac_accuracy, scanpath and saccade_speed (pure parts and tiny
trials)."""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from typer.testing import CliRunner

import wander_env  # noqa: F401
from experiments.analysis import scanpath_stats
from experiments.cli.main import app
from experiments.paper import ptu_main_sequence, sac_accuracy, saccade_speed, scanpath
from experiments.runs.tables import read_csv
from experiments.studies.framework import make_trials, resolve_config, run_experiment, run_spec
from wander_env.camera import cast_pixel
from wander_env.ptu.params import PTUParams
from wander_env.renderer import project_points
from wander_env.scenes import load_scene_config

# ----------------------------------------------------------------------------------------
# sac_accuracy


def test_draw_target_stays_within_the_ranges():
    rng = np.random.default_rng(0)
    pts = np.array([sac_accuracy.draw_target(rng, 24.0, 10.0) for _ in range(500)])
    assert pts[:, 0].min() == 40 and pts[:, 0].max() == 87
    assert pts[:, 1].min() == 54 and pts[:, 1].max() == 73


def test_conditions_set_the_ptu_mechanics():
    cfg = sac_accuracy.SacAccuracyConfig()
    assert sac_accuracy.ptu_for_condition(cfg, "ideal") == PTUParams()
    real = sac_accuracy.ptu_for_condition(cfg, "backlash_offset")
    assert (real.pan_backlash_pos, real.tilt_backlash_pos) == (4.0, 20.0)
    assert (real.camera_forward_m, real.camera_up_m) == (0.03, 0.05)
    with pytest.raises(ValueError, match="unknown condition"):
        sac_accuracy.ptu_for_condition(cfg, "worn")


def test_cast_pixel_finds_the_point_that_projects_back_onto_the_pixel():
    env = gym.make("wander/Wander-v0", scene="shelf", ground_truth=False)
    try:
        env.reset(seed=0)
        base = env.unwrapped
        point, depth, name = cast_pixel(base.model, base.data, (80, 66))
        back = project_points(base.model, base.data, point[None])[0]
    finally:
        env.close()
    assert back == pytest.approx([80.0, 66.0], abs=1e-6)
    assert name == "book_4" and 1.0 < depth < 1.5  # on the shelf, whose front is 1 m away


def test_ideal_ptu_foveates_within_two_pixels():
    cfg = resolve_config(sac_accuracy.EXPERIMENT, sets=["repeats=1", "conditions=[ideal]"])
    (spec,) = make_trials(sac_accuracy.EXPERIMENT, cfg, 0)
    row = run_spec(spec)
    assert (row["target_x_px"], row["target_y_px"]) == (80, 66)
    assert row["displacement_px"] < 2.0 and not row["clipped"]
    # With the camera on the rotation axes and the exact pan-tilt rotation, the reached
    # angles explain the whole displacement, in x and in y.
    assert row["dx_px"] == pytest.approx(row["angle_error_x_px"], abs=0.01)
    assert row["dy_px"] == pytest.approx(row["angle_error_y_px"], abs=0.01)


@pytest.mark.slow
def test_tilt_backlash_shifts_the_target_vertically_by_half_the_play():
    """Tilt play of 60 positions (1.54°), none in pan, no hinge offset: the same commands
    as with the ideal PTU, but the camera trails the tilt motor by 30 positions (0.77°,
    0.57 px at the fovea), so the vertical displacement is the larger."""
    sets = ["repeats=1", "tilt_backlash_pos=60", "pan_backlash_pos=0"]
    sets += ["camera_forward_m=0", "camera_up_m=0"]
    cfg = resolve_config(sac_accuracy.EXPERIMENT, sets=sets)
    ideal, real = (run_spec(s) for s in make_trials(sac_accuracy.EXPERIMENT, cfg, 2))
    assert (ideal["condition"], real["condition"]) == ("ideal", "backlash_offset")
    assert (real["target_x_px"], real["target_y_px"]) == (
        ideal["target_x_px"],
        ideal["target_y_px"],
    )
    lag_px = 42.5 * np.tan(np.radians(30 * PTUParams().tilt_deg_per_pos))
    assert abs(real["dy_px"] - ideal["dy_px"]) == pytest.approx(lag_px, abs=0.02)
    assert real["dx_px"] == pytest.approx(ideal["dx_px"], abs=0.01)
    assert real["abs_dy_px"] > real["abs_dx_px"]


@pytest.mark.slow
def test_same_seed_gives_the_same_table_bytes(tmp_path):
    exp = sac_accuracy.EXPERIMENT
    cfg = resolve_config(exp, sets=["repeats=1", "conditions=[backlash_offset]"])
    run_experiment("sac_accuracy", cfg, 3, tmp_path / "a")
    run_experiment("sac_accuracy", cfg, 3, tmp_path / "b")
    a, b = ((tmp_path / d / "results.csv").read_bytes() for d in "ab")
    assert a == b and a.count(b"\n") == 2
    assert (tmp_path / "a" / "sac_accuracy.png").is_file()
    comps = exp.compare(cfg, [run_spec(s) for s in make_trials(exp, cfg, 3)])
    assert [c.paper for c in comps][:2] == ["4.64 ± 1.49 px", "11.76 ± 2.58 px"]
    assert comps[2].result == "sources of the error, backlash_offset PTU"


# ----------------------------------------------------------------------------------------
# scanpath


@pytest.mark.slow
def test_scanpath_trial_exports_one_row_per_fixation(tmp_path):
    sets = ["scenes=[shelf]", "conditions=[fixational]", "duration_s=1.2", "repeats=1"]
    cfg = resolve_config(scanpath.EXPERIMENT, sets=sets)
    (row,), files = run_experiment("scanpath", cfg, 0, tmp_path)
    # 13-step (130 ms) windows and the saccades between them: two decisions in 1.2 s, the
    # saccade between them a 19° one that ends at 0.58 s (three before the frames between
    # keys sampled the static world by cubic convolution: a walking camera's sub-pixel
    # motion now reaches the DVS, and the sOMS sees other events under the walk)
    assert (row["decisions"], row["fixations"], row["saccades"]) == (2, 2, 1)
    # the first window starts at the reset (t = 0, not one step before), then 130 ms each;
    # times to the microsecond
    assert row["fixation_duration_mean_s"] == 0.125
    scanpath_rows = json.loads(row["scanpath_json"])
    assert scanpath_rows[0][2:] == [0.0, 0.12] and scanpath_rows[1][2:] == [0.58, 0.13]
    # the agent's sOMS suppresses much of the still shelf under fixational motion
    # (eye-only): one of the two decisions lands on an object
    assert row["object_hit_rate"] == pytest.approx(1 / 2) and row["objects_visited"] == 1
    # the scanpath and its AOIs travel in the row (for MultiMatch and the user's analysis)
    assert len(scanpath_rows) == 2
    assert json.loads(row["aois_json"]) == ["box_b", "box_a"]
    with (tmp_path / "fixations" / "shelf_fixational_seed0.csv").open() as fh:
        table = list(csv.DictReader(fh))
    assert list(table[0]) == [*scanpath_stats.FIXATION_COLUMNS, "aoi"]
    assert len(table) == row["fixations"]
    assert [[float(f[k]) for k in scanpath_stats.FIXATION_COLUMNS] for f in table] == json.loads(
        row["scanpath_json"]
    )
    assert [f["aoi"] for f in table] == json.loads(row["aois_json"])
    assert {p.name for p in files} >= {"scanpath.png", "scanpath_stats.png", "results.csv"}


def test_the_saccades_condition_has_a_10_ms_window_and_the_walk():
    cfg = scanpath.ScanpathConfig()
    env = gym.make("wander/Wander-v0", scene="shelf", ground_truth=False)
    try:
        sac = scanpath.agent_params(cfg, "saccades", env)
        fix = scanpath.agent_params(cfg, "fixational", env)
    finally:
        env.close()
    assert (sac.window_steps, sac.fixational) == (1, True)
    assert (fix.window_steps, fix.fixational) == (13, True)
    assert scanpath.grid(cfg) == [
        {"scene": s, "condition": c}
        for s in ("shelf", "office")
        for c in ("saccades", "fixational")
    ]


# ----------------------------------------------------------------------------------------
# saccade_speed


def test_grid_varies_one_factor_at_a_time_around_the_paper_values():
    rows = saccade_speed.grid(saccade_speed.SaccadeSpeedConfig())
    # baseline, 2 values of each of six numeric factors, the ideal (latency-free) PTU
    assert len(rows) == 14 and rows[0]["factor"] == "baseline"
    assert rows[0] | {"factor": 0} == {
        "factor": 0,
        "speed_pos_s": 2000.0,
        "accel_pos_s2": 2000.0,
        "fixational_step_pos": 60,
        "fixational_n_steps": 8,
        "window_s": 0.124,
        "object_speed_scale": 1.0,
        "ptu_preset": "flir",
        "main_sequence": True,
    }
    speeds = [r["speed_pos_s"] for r in rows if r["factor"] == "ptu_speed"]
    assert speeds == [1000.0, 2902.0]
    for r in rows[1:]:
        changed = {
            k for k in rows[0] if k not in ("factor", "main_sequence") and r[k] != rows[0][k]
        }
        assert len(changed) == 1
    # one main sequence per PTU setting: baseline, 2 speeds, 2 accelerations, ideal
    assert [r["factor"] for r in rows if r["main_sequence"]] == [
        "baseline",
        "ptu_speed",
        "ptu_speed",
        "ptu_accel",
        "ptu_accel",
        "ptu_link",
    ]


def test_factorial_grid_is_the_product_of_the_five_factors():
    cfg = saccade_speed.SaccadeSpeedConfig(design="factorial")
    rows = saccade_speed.grid(cfg)
    assert len(rows) == 3**5 and {r["factor"] for r in rows} == {"factorial"}
    keys = {
        (
            r["speed_pos_s"],
            r["accel_pos_s2"],
            r["fixational_step_pos"],
            r["fixational_n_steps"],
            r["window_s"],
        )
        for r in rows
    }
    assert len(keys) == 243
    assert sum(r["main_sequence"] for r in rows) == 9  # speed × acceleration


@pytest.mark.parametrize("speed", [20.0, 3000.0])
def test_speeds_are_what_the_ptu_can_slew(speed):
    """PL 31 to PU 2902 positions/s: a trial at 20 would fail when its PTU is built."""
    with pytest.raises(
        ValueError, match=rf"^speeds_pos_s must be in \[31, 2902\] \(PL, PU\), got \({speed},\)$"
    ):
        saccade_speed.SaccadeSpeedConfig(speeds_pos_s=(speed,))


def test_theory_main_sequence_saturates_at_the_slew_speed():
    amps = np.array([1.0, 5.0, 20.0, 40.0, 60.0])
    v, t = ptu_main_sequence.theory_main_sequence(amps, PTUParams())
    assert np.all(np.diff(v) >= 0) and np.all(np.diff(t) > 0)
    assert v[-1] == pytest.approx(2000 * PTUParams().pan_deg_per_pos)


def test_scaled_trajectory_runs_faster():
    class Line:
        def position(self, t: float) -> np.ndarray:
            return np.array([t, 0.0, 0.0])

    assert saccade_speed.ScaledTrajectory(Line(), 2.0).position(0.3)[0] == pytest.approx(0.6)


@pytest.mark.slow
def test_main_sequence_durations_grow_with_amplitude():
    sets = [
        "duration_s=0.3",
        "speeds_pos_s=[2000]",
        "accels_pos_s2=[2000]",
        "fixational_steps_pos=[60]",
        "fixational_counts=[8]",
        "object_speed_scales=[1.0]",
        "windows_s=[0.124]",
        "ptu_presets=[ideal]",
        "ptu_preset=ideal",
        "repeats=1",
        "main_sequence_amplitudes_deg=[2, 10, 30]",
    ]
    cfg = resolve_config(saccade_speed.EXPERIMENT, sets=sets)
    (spec,) = make_trials(saccade_speed.EXPERIMENT, cfg, 0)
    row = run_spec(spec)
    amp, vel, dur = row["_ms_amplitude_deg"], row["_ms_peak_velocity_deg_s"], row["_ms_duration_s"]
    assert amp == pytest.approx([2, 10, 30], abs=0.7)
    assert np.all(np.diff(dur) > 0) and np.all(np.diff(vel) > 0)
    theory_v, theory_t = ptu_main_sequence.theory_main_sequence(amp, PTUParams())
    assert vel == pytest.approx(theory_v, abs=1.0)
    assert np.all(dur >= theory_t - 0.01) and np.all(dur <= theory_t + 0.1)
    assert row["events_per_s"] > 0 and row["factor"] == "baseline"
    # three amplitudes fit the two-parameter curves but leave one residual degree of
    # freedom: no intervals, and the summary says why
    assert row["ms_amplitudes"] == 3 and math.isfinite(row["ms_v_vmax"])
    assert math.isnan(row["ms_v_vmax_low"]) and math.isnan(row["ms_d_k_high"])
    text = ptu_main_sequence.fits_text(row)
    assert text.endswith("; n too small for an interval (3 amplitudes; an interval needs ≥ 4)")
    assert "∞" not in text and "nan" not in text


def test_main_sequence_summary_says_when_there_are_too_few_amplitudes():
    two = {"ms_amplitudes": 2, "ms_v_vmax": math.nan, "ms_d_k": math.nan}
    assert (
        ptu_main_sequence.fits_text(two) == "n too small for a fit (2 amplitudes; a fit needs ≥ 3)"
    )
    assert ptu_main_sequence.fits_text({"ms_v_vmax": math.nan}) == ""  # no main sequence run


# ----------------------------------------------------------------------------------------
# One naming and one sign convention: wander run and the scanpath experiment


def _csv(path: Path) -> list[dict[str, str]]:
    with path.open() as fh:
        return list(csv.DictReader(fh))


@pytest.fixture(scope="module")
def folders(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """One short ``wander run`` and one short scanpath experiment, office, seed 4."""
    root = tmp_path_factory.mktemp("naming")
    run, exp = root / "run", root / "exp"
    args = ["run", "--out", str(run), "--seconds", "1.5", "--seed", "4", "--no-video"]
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 0, result.output
    sets = ["scenes=[office]", "conditions=[fixational]", "repeats=1", "duration_s=1.5"]
    args = ["experiment", "scanpath", "--out", str(exp), "--seed", "4"]
    result = CliRunner().invoke(app, args + [x for s in sets for x in ("--set", s)])
    assert result.exit_code == 0, result.output
    return run, exp


@pytest.mark.slow
def test_run_and_experiment_share_names_signs_and_units(folders: tuple[Path, Path]) -> None:
    run, exp = folders
    scene = load_scene_config("office")
    names = {o.name for o in (*scene.static_objects, *scene.moving_objects)}
    moving = {o.name for o in scene.moving_objects}
    assert moving == {"cube", "beach_ball"}

    run_rows = _csv(run / "fixations.csv")
    exp_rows = _csv(exp / "fixations" / "office_fixational_seed4.csv")
    (result,) = _csv(exp / "results.csv")
    assert list(run_rows[0])[:4] == list(exp_rows[0])[:4] == list(scanpath_stats.FIXATION_COLUMNS)
    assert list(exp_rows[0]) == [*scanpath_stats.FIXATION_COLUMNS, "aoi"]

    # Object names: the scene file's, in every file (never the model's object_k).
    run_objects = [r["target_object"] for r in run_rows]
    exp_aois = [r["aoi"] for r in exp_rows]
    assert exp_aois == json.loads(result["aois_json"]) == ["-", "cube"]
    assert run_objects == ["cube", "beach_ball"]
    assert set(run_objects) | set(exp_aois) <= names | {"-"}

    # One sign convention and the same units: the same agent and seed give the same
    # fixations in both files and in results.csv (each window here ended in a saccade).
    table = [[float(r[k]) for k in scanpath_stats.FIXATION_COLUMNS] for r in exp_rows]
    assert table == [[float(r[k]) for k in scanpath_stats.FIXATION_COLUMNS] for r in run_rows]
    assert table == json.loads(result["scanpath_json"])
    assert table == [[0.0, 0.0, 0.0, 0.12], [28.465706, 1.054285, 0.83, 0.13]]
    # + pan = left, + tilt = up: a P left of / above the fovea lies at a larger pan / tilt.
    for r in run_rows:
        x, y = float(r["target_x_px"]), float(r["target_y_px"])
        dpan = float(r["target_pan_deg"]) - float(r["pan_deg"])
        dtilt = float(r["target_tilt_deg"]) - float(r["tilt_deg"])
        assert (x < 63.5) == (dpan > 0) and (y < 63.5) == (dtilt > 0)
    # Times to the microsecond in results.csv too (no 9e-17 spread of equal durations).
    assert (result["fixation_duration_mean_s"], result["fixation_duration_std_s"]) == (
        "0.125",
        "0.005",
    )
    # wander run's metrics.json "scanpath" holds the experiment's statistics: one rule
    stats = json.loads((run / "metrics.json").read_text())["scanpath"]
    assert list(stats) == [
        "fixations",
        "fixation_duration_mean_s",
        "fixation_duration_std_s",
        "saccade_amplitude_mean_deg",
        "saccade_amplitude_std_deg",
        "revisits",
        "coverage_deg2",
    ]
    (typed,) = read_csv(exp / "results.csv")
    assert stats == {k: typed[k] for k in stats}
    assert (stats["fixations"], stats["fixation_duration_mean_s"]) == (2, 0.125)
