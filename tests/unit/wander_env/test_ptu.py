"""Tests for the pan-tilt unit model (wander_env.ptu)."""

from __future__ import annotations

import dataclasses
import itertools
import math

import pytest

from wander_env.ptu.axis import (
    AxisState,
    axis_path,
    axis_step,
    move_duration,
    peak_speed,
    stopping_distance,
)
from wander_env.ptu.mechanics import backlash, camera_position
from wander_env.ptu.params import PTUParams
from wander_env.ptu.unit import PanTiltUnit
from wander_env.ptu.units import (
    SpeedOutOfRange,
    degrees_to_positions,
    positions_to_degrees,
    round_position,
    whole_position,
    whole_speed,
)

DEG_PER_POS = 92.5714 / 3600.0


def run_axis(state, target, dt, n, vmax, amax, vbase=0.0):
    """States after each of ``n`` steps."""
    out = []
    for _ in range(n):
        state = axis_step(state, target, dt, vmax, amax, vbase)
        out.append(state)
    return out


def steps_to_arrive(state, target, dt, vmax, amax, vbase=0.0, limit=10**6):
    """Number of steps until the axis rests exactly on ``target``."""
    for n in range(1, limit):
        state = axis_step(state, target, dt, vmax, amax, vbase)
        if state.position == target and state.velocity == 0.0:
            return n
    raise AssertionError("never arrived")


# ----------------------------------------------------------------------------------------
# Conversions


def test_resolution_is_the_papers():
    assert positions_to_degrees(1) == pytest.approx(0.025714, abs=1e-6)
    assert PTUParams().pan_deg_per_pos == DEG_PER_POS
    assert PTUParams().tilt_deg_per_pos == DEG_PER_POS


def test_flir_manual_example_21_3_deg_left_is_828_positions():
    assert round_position(degrees_to_positions(21.3)) == 828


def test_integer_positions_round_trip_exactly_over_the_whole_range():
    for k in range(-3090, 3091):
        assert round_position(degrees_to_positions(positions_to_degrees(k))) == k


@pytest.mark.parametrize("deg", [-79.4, -12.345, 0.0, 1e-3, 33.3, 79.4])
def test_degrees_round_trip(deg):
    assert positions_to_degrees(degrees_to_positions(deg)) == pytest.approx(deg, abs=1e-12)


def test_round_position_is_symmetric_half_away_from_zero():
    assert [round_position(v) for v in (-1.5, -0.5, -0.49, 0.0, 0.49, 0.5, 1.5)] == [
        -2,
        -1,
        0,
        0,
        0,
        1,
        2,
    ]


def test_whole_position_rounds_halves_away_from_zero_and_refuses_non_finite():
    # 0.5 and -0.5 positions, as degrees: round_position's halves, not Python's round.
    assert whole_position("pan", 0.5 * DEG_PER_POS, 92.5714) == 1
    assert whole_position("pan", -0.5 * DEG_PER_POS, 92.5714) == -1
    assert whole_position("tilt", -23.32, 92.5714) == -907
    with pytest.raises(ValueError, match=r"^pan value must be a finite number, got inf$"):
        whole_position("pan", math.inf, 92.5714)


@pytest.mark.parametrize(
    ("pos_s", "expected"),
    [(30.5, 31), (31.0, 31), (500.4, 500), (500.5, 501), (2902.4, 2902), (2902.0, 2902)],
)
def test_whole_speed_rounds_into_the_bounds(pos_s, expected):
    assert whole_speed("pan", pos_s, 31.0, 2902.0) == expected


@pytest.mark.parametrize(
    ("pos_s", "lower", "message", "limit", "above"),
    [
        (
            30.49,
            31.0,
            "pan speed must round to 31…2902 positions/s, got 30.49 positions/s",
            31,
            False,
        ),
        (
            2902.5,
            31.0,
            "pan speed must round to 31…2902 positions/s, got 2902.5 positions/s",
            2902,
            True,
        ),
        # Whatever PL says, a speed is at least one whole position/s.
        (0.49, 0.0, "pan speed must round to 1…2902 positions/s, got 0.49 positions/s", 1, False),
        (
            -40.0,
            31.0,
            "pan speed must round to 31…2902 positions/s, got -40 positions/s",
            31,
            False,
        ),
    ],
)
def test_whole_speed_refuses_a_speed_outside_the_bounds(pos_s, lower, message, limit, above):
    with pytest.raises(SpeedOutOfRange) as err:
        whole_speed("pan", pos_s, lower, 2902.0)
    assert (str(err.value), err.value.limit, err.value.above) == (message, limit, above)


def test_whole_speed_refuses_non_finite():
    with pytest.raises(
        ValueError, match=r"^tilt speed must be a finite number, got nan positions/s$"
    ):
        whole_speed("tilt", math.nan, 31.0, 2902.0)


# ----------------------------------------------------------------------------------------
# Parameters


def test_default_limits_are_flir_factory_limits():
    p = PTUParams()
    assert (p.pan_min_pos, p.pan_max_pos, p.tilt_min_pos, p.tilt_max_pos) == (
        -3090,
        3090,
        -907,
        604,
    )
    assert p.pan_limits_deg == pytest.approx((-3090 * DEG_PER_POS, 3090 * DEG_PER_POS))
    assert p.tilt_limits_deg == pytest.approx((-907 * DEG_PER_POS, 604 * DEG_PER_POS))


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("pan_resolution_arcsec", 0.0),
        ("tilt_resolution_arcsec", float("nan")),
        ("pan_speed", -1.0),
        ("tilt_speed", 0.0),
        ("pan_accel", 0.0),
        ("tilt_accel", float("inf")),
        ("pan_base_speed", -5.0),
        ("tilt_upper_speed", 0.0),
        ("pan_lower_speed", -1.0),
        ("tilt_lower_speed", float("nan")),
        ("pan_backlash_pos", -1.0),
        ("tilt_backlash_pos", float("nan")),
        ("camera_forward_m", float("inf")),
        ("pan_min_pos", 1.5),
        ("tilt_max_pos", True),
        ("quantise", 1),
        ("pan_speed", "fast"),
    ],
)
def test_params_reject_bad_fields_naming_field_and_value(field, value):
    with pytest.raises(ValueError, match=rf"PTUParams\.{field}\b") as err:
        PTUParams(**{field: value})
    assert repr(value) in str(err.value)


def test_params_reject_inverted_limits_and_speeds_above_upper():
    with pytest.raises(ValueError, match="tilt_min_pos"):
        PTUParams(tilt_min_pos=10, tilt_max_pos=10)
    with pytest.raises(ValueError, match="pan_speed must be <= pan_upper_speed"):
        PTUParams(pan_speed=3000.0)
    with pytest.raises(ValueError, match="tilt_base_speed must be <= tilt_upper_speed"):
        PTUParams(tilt_base_speed=3000.0)
    with pytest.raises(ValueError) as err:
        PTUParams(pan_lower_speed=3000.0)
    assert (
        str(err.value)
        == "PTUParams.pan_lower_speed must be <= pan_upper_speed (2902.0), got 3000.0"
    )
    with pytest.raises(ValueError) as err:
        PTUParams(tilt_speed=30.0)
    assert str(err.value) == "PTUParams.tilt_speed must be >= tilt_lower_speed (31.0), got 30.0"


def test_default_speed_bounds_are_the_flir_manuals():
    p = PTUParams()
    assert (p.pan_lower_speed, p.pan_upper_speed) == (31.0, 2902.0)
    assert (p.tilt_lower_speed, p.tilt_upper_speed) == (31.0, 2902.0)


def test_camera_offsets_may_be_negative():
    assert PTUParams(camera_forward_m=-0.01, camera_up_m=-0.02).camera_up_m == -0.02


# ----------------------------------------------------------------------------------------
# Analytic profile


def test_move_duration_trapezoid_is_exact():
    # 0.5 s ramp (250 pos) + 500 pos cruise at 1000 pos/s + 0.5 s ramp.
    assert move_duration(1000, vmax=1000, amax=2000) == 1.5
    assert move_duration(-1000, vmax=1000, amax=2000) == 1.5


def test_move_duration_triangle_and_zero():
    assert move_duration(100, 1000, 2000) == pytest.approx(2 * math.sqrt(100 / 2000))
    assert move_duration(500, 1000, 2000) == pytest.approx(1.0)  # just reaches vmax
    assert move_duration(0, 1000, 2000) == 0.0


def test_move_duration_with_base_speed():
    # Speed jumps to base speed, ramps above it, and drops to zero from base speed.
    assert move_duration(10, vmax=2000, amax=2000, vbase=1000) == pytest.approx(
        2 * (math.sqrt(1000**2 + 2000 * 10) - 1000) / 2000
    )
    # Slew speed equal to base speed: no ramp at all.
    assert move_duration(10, vmax=1000, amax=2000, vbase=1000) == pytest.approx(0.01)
    # Triangle truncated at base speed: peak sqrt(vb² + a·d).
    vp = math.sqrt(1000**2 + 2000 * 1000)
    assert peak_speed(1000, 2000, 2000, 1000) == pytest.approx(vp)
    assert move_duration(1000, 2000, 2000, 1000) == pytest.approx(2 * (vp - 1000) / 2000)
    # Base speed above vmax: the whole move at vmax.
    assert move_duration(100, vmax=500, amax=2000, vbase=1000) == pytest.approx(0.2)


def test_stopping_distance():
    assert stopping_distance(1000, 2000) == 250.0
    assert stopping_distance(-1000, 2000) == 250.0
    assert stopping_distance(1000, 2000, 1000) == 0.0
    assert stopping_distance(2000, 2000, 1000) == pytest.approx(750.0)


@pytest.mark.parametrize(
    ("vmax", "amax", "vbase", "field"),
    [(0, 1, 0, "vmax"), (1, -1, 0, "amax"), (1, 1, -1, "vbase")],
)
def test_move_duration_rejects_bad_limits(vmax, amax, vbase, field):
    with pytest.raises(ValueError, match=f"^{field} must be a finite number"):
        move_duration(10, vmax, amax, vbase)


# ----------------------------------------------------------------------------------------
# Stepped axis


def test_stepped_move_arrives_within_one_step_of_the_analytic_duration():
    dt = 1e-3
    states = run_axis(AxisState(), 1000.0, dt, 1500, vmax=1000, amax=2000)
    assert states[1498].position < 1000.0
    assert states[1499] == AxisState(1000.0, 0.0)  # after 1500 steps = 1.5 s
    # Monotone, never past the target, speed within the limit.
    pos = [s.position for s in states]
    assert all(b >= a for a, b in itertools.pairwise(pos))
    assert max(pos) == 1000.0
    assert max(s.velocity for s in states) <= 1000.0
    # Velocity profile: 500 pos/s at 0.25 s, cruising at 1 s, 500 pos/s at 1.25 s.
    assert states[249].velocity == pytest.approx(500.0)
    assert states[249].position == pytest.approx(62.5)
    assert states[999].velocity == pytest.approx(1000.0)
    assert states[1249].velocity == pytest.approx(500.0)


@pytest.mark.parametrize(
    ("distance", "vmax", "amax", "vbase", "dt"),
    [
        (1000.0, 1000.0, 2000.0, 0.0, 0.0007),
        (-777.0, 2000.0, 2000.0, 1000.0, 0.001),
        (60.0, 2000.0, 2000.0, 1000.0, 0.001),  # a fixational move: base speed only
        (3.0, 500.0, 50.0, 0.0, 0.01),
        (6180.0, 2902.0, 2000.0, 1000.0, 0.02),
    ],
)
def test_arrival_matches_move_duration(distance, vmax, amax, vbase, dt):
    t = move_duration(distance, vmax, amax, vbase)
    n = steps_to_arrive(AxisState(), distance, dt, vmax, amax, vbase)
    assert t <= n * dt + 1e-12 < t + dt + 1e-12


def test_integration_is_independent_of_step_size():
    coarse = axis_step(AxisState(), 1000.0, 0.3, 1000, 2000)
    fine = run_axis(AxisState(), 1000.0, 0.001, 300, 1000, 2000)[-1]
    assert coarse.position == pytest.approx(fine.position, abs=1e-9)
    assert coarse.velocity == pytest.approx(fine.velocity, abs=1e-9)
    assert coarse.position == pytest.approx(0.5 * 2000 * 0.3**2)


def test_retarget_further_while_accelerating():
    dt = 1e-3
    s = run_axis(AxisState(), 1000.0, dt, 250, 1000, 2000)[-1]  # 0.25 s: v = 500
    n = steps_to_arrive(s, 2000.0, dt, 1000, 2000)
    # Same as a rest-to-rest 2000 move: 0.5 + 1.5 + 0.5 = 2.5 s in all.
    assert (250 + n) * dt == pytest.approx(move_duration(2000, 1000, 2000), abs=dt)


def test_retarget_backwards_brakes_reverses_and_stops_exactly():
    dt = 1e-3
    s = run_axis(AxisState(), 1000.0, dt, 750, 1000, 2000)[-1]  # cruising at 500
    assert s.position == pytest.approx(500.0)
    states = run_axis(s, 0.0, dt, 2000, 1000, 2000)
    pos = [x.position for x in states]
    assert max(pos) == pytest.approx(750.0, abs=1e-6)  # 250 pos of braking
    n = next(i for i, x in enumerate(states) if x == AxisState(0.0, 0.0)) + 1
    # 0.5 s braking + a rest-to-rest 750 move (1.25 s).
    expected = 0.5 + move_duration(750, 1000, 2000)
    assert expected <= n * dt + 1e-9 < expected + dt
    assert min(pos) == 0.0  # no overshoot on the way back


def test_retarget_inside_braking_distance_overshoots_by_the_unavoidable_amount():
    dt = 1e-3
    s = run_axis(AxisState(), 1000.0, dt, 750, 1000, 2000)[-1]  # at 500, v = 1000
    states = run_axis(s, 600.0, dt, 2000, 1000, 2000)
    pos = [x.position for x in states]
    assert max(pos) == pytest.approx(750.0, abs=1e-6)  # stop distance 250 > 100
    assert states[-1] == AxisState(600.0, 0.0)
    n = next(i for i, x in enumerate(states) if x == AxisState(600.0, 0.0)) + 1
    expected = 0.5 + move_duration(150, 1000, 2000)
    assert expected <= n * dt + 1e-9 < expected + dt


def test_retarget_to_current_position_while_moving():
    s = AxisState(100.0, 1000.0)
    end = run_axis(s, 100.0, 1e-3, 3000, 1000, 2000)[-1]
    assert end == AxisState(100.0, 0.0)


def test_phase_path_is_monotone_between_points():
    # A reversal inside one step shows up as an extreme point in the path.
    s = AxisState(500.0, 1000.0)
    end, path = axis_path(s, 0.0, 2.0, 1000, 2000, 0.0)
    assert max(path) == pytest.approx(750.0)
    assert end == AxisState(0.0, 0.0)


def test_axis_step_rejects_bad_dt():
    with pytest.raises(ValueError, match="dt_s"):
        axis_step(AxisState(), 1.0, -1e-3, 1, 1)


# ----------------------------------------------------------------------------------------
# The unit


def ideal(**kw):
    """An ideal unit with a 1000 pos/s, 2000 pos/s² trapezoid and no base speed."""
    base = dict(pan_speed=1000.0, tilt_speed=1000.0, pan_base_speed=0.0, tilt_base_speed=0.0)
    return PanTiltUnit(PTUParams(**{**base, **kw}))


def test_unit_move_and_state():
    ptu = ideal()
    assert not ptu.moving
    ptu.set_target(pan_deg=1000 * DEG_PER_POS, tilt_deg=-500 * DEG_PER_POS)
    assert ptu.moving
    assert ptu.target_positions == (1000.0, -500.0)
    ptu.step(0.25)
    assert ptu.pan_velocity_deg_s == pytest.approx(500 * DEG_PER_POS)
    assert ptu.tilt_velocity_deg_s == pytest.approx(-500 * DEG_PER_POS)
    for _ in range(1249):
        ptu.step(0.001)
    assert ptu.moving  # 1.499 s
    ptu.step(0.001)
    assert not ptu.moving
    assert ptu.positions == (1000, -500)
    assert isinstance(ptu.positions[0], int)
    assert ptu.pan_deg == pytest.approx(1000 * DEG_PER_POS)
    assert ptu.velocities_deg_s == (0.0, 0.0)
    assert ptu.time_s == pytest.approx(1.5)


def test_set_target_none_keeps_the_other_axis():
    ptu = ideal()
    ptu.set_target(pan_deg=1.0, tilt_deg=2.0)
    ptu.set_target(tilt_deg=-3.0)
    assert ptu.target_deg[0] == pytest.approx(round_position(1.0 / DEG_PER_POS) * DEG_PER_POS)
    assert ptu.target_deg[1] == pytest.approx(round_position(-3.0 / DEG_PER_POS) * DEG_PER_POS)


def test_quantise_puts_targets_and_angles_on_whole_positions():
    q = ideal()
    q.set_target(pan_deg=10.3 * DEG_PER_POS)
    assert q.target_positions[0] == 10.0
    q.step(0.05)  # mid-move: 2.5 positions travelled
    assert q.pan_deg == pytest.approx(3 * DEG_PER_POS)
    c = ideal(quantise=False)
    c.set_target(pan_deg=10.3 * DEG_PER_POS)
    assert c.target_positions[0] == pytest.approx(10.3)
    c.step(0.05)
    assert c.pan_deg == pytest.approx(2.5 * DEG_PER_POS)
    assert c.positions == (3, 0)  # the unit reports whole positions either way


def test_targets_outside_limits_raise_naming_the_limit():
    ptu = PanTiltUnit()
    with pytest.raises(ValueError, match="pan_max_pos = 3090"):
        ptu.set_target(pan_deg=80.0)
    with pytest.raises(ValueError, match="pan_min_pos = -3090"):
        ptu.set_target(pan_deg=-80.0)
    with pytest.raises(ValueError, match="tilt_min_pos = -907"):
        ptu.set_target(tilt_deg=-24.0)
    with pytest.raises(ValueError, match="tilt_max_pos = 604"):
        ptu.set_target_positions(tilt_pos=605)
    with pytest.raises(ValueError, match="finite"):
        ptu.set_target(pan_deg=float("nan"))
    with pytest.raises(ValueError, match="pan_max_pos"):
        ptu.reset(pan_deg=90.0)
    assert ptu.target_positions == (0.0, 0.0)  # nothing was accepted


def test_targets_exactly_on_the_limits_are_accepted():
    ptu = PanTiltUnit(PTUParams(quantise=False))
    lo, hi = ptu.params.pan_limits_deg
    ptu.set_target(pan_deg=hi, tilt_deg=ptu.params.tilt_limits_deg[0])
    assert ptu.target_positions == (3090.0, -907.0)
    ptu.set_target(pan_deg=lo)
    assert ptu.target_positions[0] == -3090.0


def test_clip_target():
    ptu = PanTiltUnit()
    (plo, phi), (tlo, thi) = ptu.params.pan_limits_deg, ptu.params.tilt_limits_deg
    assert ptu.clip_target(100.0, -100.0) == (phi, tlo)
    assert ptu.clip_target(-100.0, 100.0) == (plo, thi)
    assert ptu.clip_target(1.5, -2.5) == (1.5, -2.5)
    ptu.set_target(*ptu.clip_target(1e6, 1e6))  # a clipped target is always accepted
    assert ptu.target_positions == (3090.0, 604.0)


def test_set_speed_on_the_fly():
    ptu = ideal()
    ptu.set_target(pan_deg=3000 * DEG_PER_POS)
    ptu.step(1.0)  # cruising at 1000 pos/s
    ptu.set_speed(pan_deg_s=500 * DEG_PER_POS)
    ptu.step(0.25)  # ramps down at 2000 pos/s²
    assert ptu.pan_velocity_deg_s == pytest.approx(500 * DEG_PER_POS)
    assert ptu.speeds == (500.0, 1000.0)
    with pytest.raises(ValueError) as err:
        ptu.set_speed(pan_deg_s=3000 * DEG_PER_POS)
    assert str(err.value) == "pan speed must round to 31…2902 positions/s, got 3000 positions/s"
    with pytest.raises(ValueError) as err:
        ptu.set_speed(tilt_deg_s=0.0)
    assert str(err.value) == "tilt speed must round to 31…2902 positions/s, got 0 positions/s"
    assert ptu.speeds == (500.0, 1000.0)


def test_set_speed_takes_whole_positions_per_second_and_refuses_all_or_nothing():
    ptu = PanTiltUnit()
    ptu.set_speed(pan_deg_s=10.0, tilt_deg_s=30.6 * DEG_PER_POS)  # 388.89 and 30.6 pos/s
    assert ptu.speeds == (389.0, 31.0)
    with pytest.raises(ValueError) as err:  # the pan half is good: neither changes
        ptu.set_speed(pan_deg_s=1000 * DEG_PER_POS, tilt_deg_s=0.5)
    assert str(err.value) == "tilt speed must round to 31…2902 positions/s, got 19.4445 positions/s"
    assert ptu.speeds == (389.0, 31.0)
    with pytest.raises(ValueError) as err:
        ptu.set_speed(pan_deg_s=math.nan)
    assert str(err.value) == "pan speed must be a finite number, got nan positions/s"


def test_step_rejects_negative_dt():
    with pytest.raises(ValueError, match="dt_s"):
        PanTiltUnit().step(-0.1)


def test_units_share_no_state():
    a, b = PanTiltUnit(), PanTiltUnit()
    a.set_target(pan_deg=10.0)
    a.step(0.1)
    assert b.positions == (0, 0) and not b.moving
    with pytest.raises(dataclasses.FrozenInstanceError):
        a.params.pan_speed = 1.0  # type: ignore[misc]


# ----------------------------------------------------------------------------------------
# Backlash


def test_backlash_operator():
    assert backlash(0.0, 10.0, 4.0) == 8.0
    assert backlash(8.0, 6.0, 4.0) == 8.0  # reversal, play not yet taken up
    assert backlash(8.0, 5.0, 4.0) == 7.0
    assert backlash(3.0, 3.0, 0.0) == 3.0


def test_no_backlash_camera_follows_the_motor():
    ptu = PanTiltUnit()
    ptu.set_target(pan_deg=3.0, tilt_deg=-2.0)
    for _ in range(20):
        ptu.step(0.013)
        assert ptu.camera_pan_deg == ptu.pan_deg
        assert ptu.camera_tilt_deg == ptu.tilt_deg


def test_backlash_camera_tilt_lags_by_exactly_the_backlash_after_a_reversal():
    b = 10
    ptu = PanTiltUnit(PTUParams(tilt_backlash_pos=float(b)))
    ptu.set_target_positions(tilt_pos=200)
    ptu.step(2.0)
    cam_up = ptu.camera_tilt_deg
    assert cam_up == pytest.approx((200 - b / 2) * DEG_PER_POS)
    # Reverse: the camera holds still for exactly b positions of motor travel.
    ptu.set_target_positions(tilt_pos=200 - b)
    ptu.step(1.0)
    assert ptu.positions[1] == 190
    assert ptu.camera_tilt_deg == cam_up
    ptu.set_target_positions(tilt_pos=200 - b - 1)
    ptu.step(1.0)
    assert ptu.camera_tilt_deg == pytest.approx(cam_up - DEG_PER_POS)
    # The same joint angle approached from above and from below: b apart.
    ptu.set_target_positions(tilt_pos=100)
    ptu.step(2.0)
    other = PanTiltUnit(PTUParams(tilt_backlash_pos=float(b)))
    other.set_target_positions(tilt_pos=100)
    other.step(2.0)
    assert ptu.tilt_deg == other.tilt_deg
    assert ptu.camera_tilt_deg - other.camera_tilt_deg == pytest.approx(b * DEG_PER_POS)
    # Pan has no backlash by default.
    assert ptu.camera_pan_deg == ptu.pan_deg


def test_backlash_sees_a_reversal_inside_a_single_step():
    params = PTUParams(
        tilt_backlash_pos=20.0, tilt_speed=1000.0, tilt_base_speed=0.0, quantise=False
    )
    coarse, fine = PanTiltUnit(params), PanTiltUnit(params)
    for ptu in (coarse, fine):
        ptu.set_target_positions(tilt_pos=600)
        ptu.step(0.75)  # 250 positions up, cruising at 1000 pos/s
        ptu.set_target_positions(tilt_pos=300)  # inside the braking distance
    coarse.step(3.0)  # up to 500, back down to 300 in one step
    for _ in range(3000):
        fine.step(0.001)
    assert coarse.tilt_deg == pytest.approx(fine.tilt_deg)
    assert coarse.camera_tilt_deg == pytest.approx(fine.camera_tilt_deg)
    assert coarse.camera_tilt_deg == pytest.approx(310 * DEG_PER_POS)


# ----------------------------------------------------------------------------------------
# Camera offset from the tilt hinge


def test_camera_position_geometry():
    f, u = 0.05, 0.02
    assert camera_position(0.0, f, u) == pytest.approx((f, 0.0, u))
    assert camera_position(90.0, f, u) == pytest.approx((-u, 0.0, f))
    assert camera_position(-90.0, f, u) == pytest.approx((u, 0.0, -f))
    assert camera_position(0.0, f, u, pan_deg=90.0) == pytest.approx((0.0, f, u))
    for tilt in (-23.0, 0.0, 7.5, 15.0):
        x, y, z = camera_position(tilt, f, u, pan_deg=33.0)
        assert math.sqrt(x * x + y * y + z * z) == pytest.approx(math.hypot(f, u))
    assert camera_position(12.0, 0.0, 0.0) == (0.0, 0.0, 0.0)


def test_unit_camera_position_uses_camera_angles():
    params = PTUParams(camera_forward_m=0.03, camera_up_m=0.04)
    ptu = PanTiltUnit(params)
    assert ptu.camera_position_m == pytest.approx((0.03, 0.0, 0.04))
    ptu.set_target(pan_deg=10.0, tilt_deg=-10.0)
    ptu.step(2.0)
    assert ptu.camera_position_m == pytest.approx(
        camera_position(ptu.camera_tilt_deg, 0.03, 0.04, ptu.camera_pan_deg)
    )


@pytest.mark.parametrize(
    ("module", "examples"),
    [("units", 10), ("link", 14), ("params", 4), ("axis", 7), ("mechanics", 3), ("unit", 17)],
)
def test_docstring_examples_run(module, examples):
    import doctest
    import importlib

    result = doctest.testmod(importlib.import_module(f"wander_env.ptu.{module}"))
    assert (result.failed, result.attempted) == (0, examples)  # all ran, none failed


@pytest.mark.parametrize(
    "params", [PTUParams(), PTUParams.preset("flir"), PTUParams(tilt_backlash_pos=12.0)]
)
def test_trajectory_equals_stepping_the_unit_tick_by_tick(params):
    """A 20 degree pan and a tilt reversal: the trajectory's angles at every tick and the
    unit it leaves behind are those of stepping a twin 1 ms at a time; the angles inside a
    tick are those of a twin stepped from the tick's start."""
    unit, twin = PanTiltUnit(params), PanTiltUnit(params)
    angles, ends = [], []
    for u in (unit, twin):
        u.set_target(20.0, 2.0)
    for step in range(6):
        if step == 3:
            unit.set_target(20.0, -1.0)
            twin.set_target(20.0, -1.0)
        t0 = step * 10_000
        tr = unit.trajectory(t0, t0 + 10_000, 1000)
        assert tr.t_us == tuple(range(t0 + 1000, t0 + 10_001, 1000))
        for i in range(10):
            start = twin.copy()
            twin.step(1e-3)
            assert tr.angles(i) == (twin.camera_pan_deg, twin.camera_tilt_deg)
            if i == 4:  # three sub-frames inside the tick
                times = [t0 + 4000 + 250 * j for j in (1, 2, 3)]
                inside = []
                for _ in range(3):
                    start.step(250e-6)
                    inside.append((start.camera_pan_deg, start.camera_tilt_deg))
                assert tr.at(times) == inside
            angles.append(tr.angles(i))
        ends.append((unit.positions, twin.positions, unit.time_s, twin.time_s))
    assert all(a == b and ta == tb for a, b, ta, tb in ends)
    assert len(set(angles)) > 50  # it moved all along
    with pytest.raises(ValueError, match="tick_us > 0"):
        unit.trajectory(0, 0, 1000)
    with pytest.raises(ValueError, match="not inside"):
        tr.at([tr.t0_us])


def test_trajectory_at_a_ticks_end_is_the_trajectorys_angles():
    """At a tick's end (reached from its start) the angles are the trajectory's own,
    exactly; times inside a tick, and a tick's end after one of them, step a copy of
    the unit from the tick's start, as stepping it by hand does."""
    ptu = PanTiltUnit()
    ptu.set_target(pan_deg=3.0, tilt_deg=-1.0)
    tr = ptu.trajectory(0, 4000, 1000)
    assert tr.at([1000, 3000, 4000]) == [tr.angles(0), tr.angles(2), tr.angles(3)]
    got = tr.at([1500, 2000, 2250])
    unit = tr.starts[1].copy()
    unit.step(0.5e-3)
    mid = (unit.camera_pan_deg, unit.camera_tilt_deg)
    unit.step(0.5e-3)
    end = (unit.camera_pan_deg, unit.camera_tilt_deg)
    unit = tr.starts[2].copy()
    unit.step(0.25e-3)
    assert got == [mid, end, (unit.camera_pan_deg, unit.camera_tilt_deg)]
