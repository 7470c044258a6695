"""detection: camera-speed levels, the pipeline model, and a short trial."""

from __future__ import annotations

import math

import numpy as np
import pytest

from agents.pipeline import SaliencyPipeline
from agents.proto_object import ProtoObjectParams
from agents.soms import SOMSParams
from experiments.paper.detection import (
    EXPERIMENT,
    DetectionConfig,
    SweepPolicy,
    compare,
    grid,
    ptu_for_speed,
)
from experiments.studies.framework import ConfigError, make_trials, resolve_config, run_spec
from wander_env.actions import action_to_gaze_degrees
from wander_env.ptu.params import PTUParams


def test_ptu_speed_levels_in_degrees_per_second():
    p = ptu_for_speed(30.0)
    assert p.pan_speed * p.pan_deg_per_pos == pytest.approx(30.0)
    assert p.tilt_speed == p.pan_speed
    assert p.pan_base_speed == PTUParams().pan_base_speed  # 1000 pos/s < 30 deg/s
    slow = ptu_for_speed(10.0)
    assert slow.pan_base_speed == slow.pan_speed  # start speed capped to the level
    assert p.pan_accel == pytest.approx(p.pan_speed / 0.05)  # full speed within 50 ms
    assert ptu_for_speed(0.0) == PTUParams()
    # 0 (still), or what the PTU can slew: PL 31 to PU 2902 positions/s
    for bad in (80.0, 0.5):
        message = (
            r"^camera_speeds_deg_s must be 0 \(still\) or in \[0\.80, 74\.6\] \(the PTU's PL, "
            rf"PU\), got \[{bad}\]$"
        )
        with pytest.raises(ValueError, match=message):
            DetectionConfig(camera_speeds_deg_s=(bad,))


@pytest.mark.parametrize(
    ("item", "message"),
    [
        ("box=0", "box: must be in [1, 4096] px, got 0"),
        ("box=-3", "box: must be in [1, 4096] px, got -3"),
        ("baseline_sigma_px=-1", "baseline_sigma_px: must be in (0, 128] px, got -1.0"),
        ("baseline_sigma_px=1000", "baseline_sigma_px: must be in (0, 128] px, got 1000.0"),
        ("sweep_amplitude_deg=-5", "sweep_amplitude_deg: must be in (0, 90) deg, got -5.0"),
        ("sweep_amplitude_deg=90", "sweep_amplitude_deg: must be in (0, 90) deg, got 90.0"),
        ("step_s=1e30", "step_s: must be a whole number of ms in (0, 1] s, got 1e+30"),
        ("step_s=0.0015", "step_s: must be a whole number of ms in (0, 1] s, got 0.0015"),
        (
            "step_s=0.5",  # with duration_s=0.3 below
            "step_s: must be <= duration_s (0.3: one window at least), got 0.5",
        ),
        ("scenes=[]", "scenes: must list at least one value, got []"),
        ("camera_speeds_deg_s=[]", "camera_speeds_deg_s: must list at least one value, got []"),
        (
            "scenes=[office, hand, office]",
            "scenes: must list each value once ('office' twice), got ['office', 'hand', 'office']",
        ),
        (
            "camera_speeds_deg_s=[0, 10, 0.0]",
            "camera_speeds_deg_s: must list each value once (0.0 twice), got [0.0, 10.0, 0.0]",
        ),
    ],
)
def test_config_refuses_values_a_trial_cannot_use(item, message):
    """Each is one line when the config is validated, before anything runs."""
    with pytest.raises(ConfigError) as err:
        resolve_config(EXPERIMENT, sets=["duration_s=0.3", item])
    assert str(err.value) == f"--set: {message}"
    assert DetectionConfig(step_s=1.0, box=4096, baseline_sigma_px=128.0).step_s == 1.0


def test_sweep_policy_targets_stay_within_the_amplitude():
    pol = SweepPolicy(20.0, 5.0, np.random.default_rng(0))
    total = np.zeros(2)
    for _ in range(50):
        a = pol.act({}, {"moving": False})
        pan, tilt = action_to_gaze_degrees(a)
        total += (pan, tilt)
        assert np.all(np.abs(total) <= 5.0 + 1e-6)
        assert np.allclose(total, pol.target, atol=1e-4)  # float32 actions
    assert not pol.act({}, {"moving": True}).any()  # waits while the PTU moves
    still = SweepPolicy(0.0, 5.0, np.random.default_rng(0))
    assert not still.act({}, {"moving": False}).any()


def test_grid_is_scenes_times_speeds():
    cfg = DetectionConfig(scenes=("office", "hand"), camera_speeds_deg_s=(0.0, 30.0))
    assert grid(cfg) == [
        {"scene": "office", "camera_speed_deg_s": 0.0},
        {"scene": "office", "camera_speed_deg_s": 30.0},
        {"scene": "hand", "camera_speed_deg_s": 0.0},
        {"scene": "hand", "camera_speed_deg_s": 30.0},
    ]


def _blob_events(step: int) -> np.ndarray:
    """A dense textured disc (radius 6 px) moving right 1 px per step, sparse noise."""
    rng = np.random.default_rng(step)
    ev = (rng.random((2, 64, 64)) < 0.01).astype(np.float32)
    yy, xx = np.mgrid[0:64, 0:64]
    disc = np.hypot(xx - (20 + step), yy - 30) <= 6
    ev[1][disc & (rng.random((64, 64)) < 0.8)] += 3
    return ev


def test_pipeline_points_at_the_dense_moving_blob_with_and_without_proto_objects():
    soms = SOMSParams(alpha=0.5, dt=0.02)
    proto = ProtoObjectParams(dt=0.02)
    baseline = SaliencyPipeline(soms, saliency="oms_density", density_sigma_px=2.0)
    for model in (SaliencyPipeline(soms, proto), baseline):
        model.reset()
        for k in range(8):
            maps = model.process(_blob_events(k), 0.02)
        x, y = maps.point_xy
        assert math.hypot(x - 27, y - 30) <= 7
        assert maps.oms.shape == maps.saliency.shape == (64, 64)
        assert maps.oms.dtype == bool


@pytest.mark.slow
def test_short_trial_scores_windows_after_the_warmup():
    sets = [
        "scenes=[office]",
        "camera_speeds_deg_s=[0]",
        "duration_s=0.3",
        "warmup_s=0.1",
        "repeats=1",
        "agent.soms.alpha=0.5",
    ]
    cfg = resolve_config(EXPERIMENT, sets=sets)
    (spec,) = make_trials(EXPERIMENT, cfg, 0)
    row = run_spec(spec)
    assert row["scene"] == "office" and row["camera_speed_measured_deg_s"] == 0.0
    assert row["scored_windows"] == 10  # 15 windows of 20 ms, the first 5 in the warm-up
    for k in ("accuracy_proto", "accuracy_oms_only", "iou", "precision", "ssim"):
        assert 0.0 <= row[k] <= 1.0, k
    assert row["precision"] >= 0.9  # a still camera: the OMS map is on the moving objects
    assert row["events_per_step"] > 0 and row["mask_pixels_mean"] > 0
    (comp,) = compare(cfg, [row])
    assert comp.result == "office, camera 0°/s (measured 0)"
    assert comp.paper.startswith("EVIMO accuracy: box 73.4 %")
    assert comp.ours.startswith(f"accuracy {100 * row['accuracy_proto']:.1f} % with")
