"""Tests of the fixational eye movements (agents.fixation)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from agents.fixation import (
    FixationalMovements,
    FixationParams,
    draw_perturbations,
    positions_to_action,
)
from wander_env.actions import action_to_gaze_degrees, gaze_degrees_to_action
from wander_env.camera import focal_length_px, pixels_to_degrees

RES = 92.5714  # arcsec per PTU position (the paper's unit)


def _fixation(fix: FixationalMovements, after_saccade: bool = True) -> list:
    fix.start(after_saccade=after_saccade)
    steps = []
    while not fix.done:
        steps.append(fix.next_offset())
    return steps


# ----------------------------------------------------------------------------------------
# pure functions


def test_degrees_conversion_exact() -> None:
    fix = FixationalMovements(FixationParams(), np.random.default_rng(0))
    assert fix.params.deg_per_pos == (92.5714 / 3600, 92.5714 / 3600)
    steps = [s for _ in range(200) for s in _fixation(fix)]
    for s in steps:
        assert s.delta_deg == (s.delta_pos[0] * RES / 3600, s.delta_pos[1] * RES / 3600)
    at_60 = [s.delta_deg[0] for s in steps if s.delta_pos[0] == 60]
    assert at_60 and all(d == 60 * 92.5714 / 3600 for d in at_60)
    assert at_60[0] == pytest.approx(1.542857, abs=1e-6)


def test_action_degrees_roundtrip_and_pinhole() -> None:
    f = focal_length_px(128)
    for pan, tilt in ((1.5, -1.5), (-20.0, 7.0), (0.0, 0.0), (-56.0, 40.0)):
        a = gaze_degrees_to_action(pan, tilt)
        back = action_to_gaze_degrees(a)
        assert back == pytest.approx((pan, tilt), abs=1e-12)
        # pixel offset of the new gaze: d = f·tan(angle), signs: right/down positive
        assert a[0] * 64 == pytest.approx(-f * math.tan(math.radians(pan)))
        assert a[1] * 64 == pytest.approx(-f * math.tan(math.radians(tilt)))
    # the edge of the sensor is half the HFOV away
    assert action_to_gaze_degrees((1.0, 0.0))[0] == pytest.approx(-pixels_to_degrees(64, 128))
    # 60 positions to the left (positive pan) -> look left (negative action x)
    a = positions_to_action((60, 0))
    assert a[0] == pytest.approx(-f * math.tan(math.radians(60 * RES / 3600)) / 64)
    assert a[0] < 0 and a[1] == 0.0


def test_draw_perturbations_options() -> None:
    rng = np.random.default_rng(3)
    r = draw_perturbations(rng, 1000, 60)
    assert r.dtype.kind == "i" and r.shape == (1000, 2)
    shared = draw_perturbations(rng, 50, 60, shared_axes=True)
    assert np.array_equal(shared[:, 0], shared[:, 1])
    cont = draw_perturbations(rng, 1000, 60, integer=False)
    assert cont.dtype.kind == "f" and np.abs(cont).max() <= 60


# ----------------------------------------------------------------------------------------
# the walk


def test_exactly_n_steps_per_fixation() -> None:
    fix = FixationalMovements(FixationParams(), np.random.default_rng(0))
    assert fix.done  # nothing before start
    steps = _fixation(fix)
    assert len(steps) == 8 and fix.done
    assert [s.index for s in steps] == list(range(8))
    with pytest.raises(RuntimeError, match="fixation finished"):
        fix.next_offset()
    three = FixationalMovements(FixationParams(n_steps=3), np.random.default_rng(0))
    assert len(_fixation(three)) == 3
    assert fix.params.duration_s == pytest.approx(0.124)


def test_steps_uniform_within_60_positions() -> None:
    fix = FixationalMovements(FixationParams(), np.random.default_rng(42))
    deltas = np.array([s.delta_pos for _ in range(1000) for s in _fixation(fix)])  # 8000×2
    assert deltas.shape == (8000, 2)
    assert np.all(np.abs(deltas) <= 60)
    assert deltas.min() == -60 and deltas.max() == 60  # the bounds are reached
    assert np.all(deltas == np.round(deltas))  # whole positions
    # mean 0 (σ of the mean = 60·sqrt(1/3)/sqrt(8000) ≈ 0.39): allow 4σ
    assert np.abs(deltas.mean(axis=0)).max() < 1.6
    # uniform: variance (121² − 1)/12 = 1220 for integers in [−60, 60]
    assert deltas.var(axis=0) == pytest.approx([1220, 1220], rel=0.06)
    hist, _ = np.histogram(deltas[:, 0], bins=11, range=(-60.5, 60.5))
    assert hist.min() > 0.8 * hist.mean() and hist.max() < 1.2 * hist.mean()
    assert abs(np.corrcoef(deltas[:, 0], deltas[:, 1])[0, 1]) < 0.05  # independent axes


def test_walk_is_cumulative_sum_and_actions_match() -> None:
    fix = FixationalMovements(FixationParams(), np.random.default_rng(1))
    steps = _fixation(fix)
    cum = np.cumsum([s.delta_pos for s in steps], axis=0)
    assert np.array_equal(cum, [s.cumulative_pos for s in steps])
    assert np.array_equal(cum, np.cumsum(fix.sequence, axis=0))
    assert np.array_equal(fix.cumulative_pos, cum[-1])
    assert fix.cumulative_deg == pytest.approx(cum[-1] * RES / 3600)
    for s in steps:
        assert np.allclose(s.action, gaze_degrees_to_action(*s.delta_deg))
        assert np.all(np.abs(s.action) < 0.02)  # ≤ 1.54° ≈ 1.14 px of a 64 px half-width
    assert [s.t_s for s in steps] == pytest.approx([i * 0.0155 for i in range(8)])


def test_new_draw_each_fixation_and_walk_reset() -> None:
    fix = FixationalMovements(FixationParams(), np.random.default_rng(0))
    a = [s.delta_pos for s in _fixation(fix)]
    end_a = fix.cumulative_pos
    b = [s.delta_pos for s in _fixation(fix)]
    assert a != b
    assert b[0] == pytest.approx(fix.sequence[0].tolist())
    assert np.array_equal(np.sum(b, axis=0), fix.cumulative_pos)  # restarted at 0
    # continuing around the same point keeps the walk
    fix2 = FixationalMovements(FixationParams(), np.random.default_rng(0))
    _fixation(fix2)
    assert np.array_equal(fix2.cumulative_pos, end_a)
    c = _fixation(fix2, after_saccade=False)
    assert np.array_equal(fix2.cumulative_pos, end_a + np.sum([s.delta_pos for s in c], axis=0))


def test_same_seed_same_sequence() -> None:
    def run(seed: int) -> list:
        fix = FixationalMovements(FixationParams(), np.random.default_rng(seed))
        return [s.delta_pos for _ in range(5) for s in _fixation(fix)]

    assert run(11) == run(11)
    assert run(11) != run(12)


def test_bounded_walk_stays_within_bound() -> None:
    p = FixationParams(n_steps=64, max_excursion_pos=90)
    fix = FixationalMovements(p, np.random.default_rng(5))
    for _ in range(50):
        steps = _fixation(fix)
        cum = np.array([s.cumulative_pos for s in steps])
        assert np.abs(cum).max() <= 90
        assert np.array_equal(np.cumsum([s.delta_pos for s in steps], axis=0), cum)
        assert np.abs([s.delta_pos for s in steps]).max() <= 60  # folding never lengthens
        assert all(float(v).is_integer() for s in steps for v in s.cumulative_pos)


def test_due_schedule() -> None:
    fix = FixationalMovements(FixationParams(), np.random.default_rng(0))
    assert not fix.due(0.0)  # not started
    fix.start()
    issued = []
    for k in range(20):  # env control period 10 ms
        t = k * 0.01
        if fix.due(t):
            issued.append(round(t, 3))
            fix.next_offset()
    assert len(issued) == 8 and fix.done
    assert issued[0] == 0.0 and issued[-1] == 0.11  # step 7 due at 108.5 ms


def test_params_validate() -> None:
    with pytest.raises(ValueError, match="interval_s"):
        FixationParams(interval_s=0.0)
    with pytest.raises(ValueError, match="max_excursion_pos"):
        FixationParams(max_excursion_pos=-1)
    with pytest.raises(ValueError, match="n_steps"):
        FixationParams(n_steps=-1)
    p = FixationParams()
    assert (p.n_steps, p.max_step_pos, p.resolution_arcsec) == (8, 60, (92.5714, 92.5714))


def test_each_axis_moves_at_its_own_resolution() -> None:
    """A unit of finer pan steps (46.2857″) turns each pan position by half the angle."""
    params = FixationParams(resolution_arcsec=(46.2857, 92.5714))
    fix = FixationalMovements(params, np.random.default_rng(0))
    steps = _fixation(fix)
    assert params.deg_per_pos == (46.2857 / 3600, 92.5714 / 3600)
    for s in steps:
        assert s.delta_deg == (s.delta_pos[0] * 46.2857 / 3600, s.delta_pos[1] * 92.5714 / 3600)
        assert s.action.tolist() == gaze_degrees_to_action(*s.delta_deg).tolist()
    assert (
        fix.cumulative_deg.tolist()
        == (fix.cumulative_pos * [46.2857 / 3600, 92.5714 / 3600]).tolist()
    )


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        (
            {"resolution_arcsec": 92.5714},
            "FixationParams.resolution_arcsec: must be (pan, tilt) arc-seconds > 0, got 92.5714",
        ),
        (
            {"resolution_arcsec": (92.5714, 0.0)},
            "FixationParams.resolution_arcsec: must be (pan, tilt) arc-seconds > 0, "
            "got (92.5714, 0.0)",
        ),
        (
            {"resolution_arcsec": [92.5714, 92.5714]},
            "FixationParams.resolution_arcsec: must be (pan, tilt) arc-seconds > 0, "
            "got [92.5714, 92.5714]",
        ),
        (
            {"hfov_deg": 180.0},
            "FixationParams.hfov_deg: must be in (0, 180) degrees, got 180.0",
        ),
    ],
)
def test_params_refuse_a_bad_resolution_or_lens(kwargs: dict, message: str) -> None:
    with pytest.raises(ValueError) as info:
        FixationParams(**kwargs)
    assert str(info.value) == message
