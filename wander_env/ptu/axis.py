"""One PTU axis's motion, pure maths, in positions, positions/s and positions/s².

Motion model, per axis (the FLIR controller's, from its manuals): speeds up to the
base speed ``vb`` change instantly (a stepper can start and stop there without
losing synchrony); above it the speed ramps at ``accel`` up to ``speed``, and down
again at the same rate, so a rest-to-rest move is a trapezoid (a triangle when the
move is short), truncated at ``vb``. The target may change at any time: the axis
brakes, reverses if needed, and stops exactly on the new target; it overshoots
only when the new target lies inside its braking distance, and then by exactly
the unavoidable amount. The state is integrated *exactly* (phase by phase, in
closed form), so timings do not depend on the step size.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

# Relative tolerance on distances (positions) and absolute one on speeds (pos/s) and
# on phase ends (s); they absorb float rounding of a closed-form phase end only.
REL_TOL = 1e-9
_VEL_TOL = 1e-9
_TIME_TOL = 1e-12
# A step is at most a handful of phases (away-brake, reverse, accelerate, cruise, brake).
_MAX_PHASES = 64


@dataclass(frozen=True)
class AxisState:
    """Position (positions, fractional) and signed velocity (positions/s) of one axis."""

    position: float = 0.0
    velocity: float = 0.0


def stopping_distance(speed: float, accel: float, base_speed: float = 0.0) -> float:
    """Distance needed to stop from ``speed``: ramp down to ``base_speed``, then stop.

    >>> stopping_distance(1000.0, 2000.0)
    250.0
    """
    s = abs(speed)
    return (s * s - base_speed * base_speed) / (2.0 * accel) if s > base_speed else 0.0


def peak_speed(distance: float, vmax: float, amax: float, vbase: float = 0.0) -> float:
    """Highest speed reached by a rest-to-rest move of ``distance`` positions.

    >>> peak_speed(1000, 1000, 2000), peak_speed(100, 1000, 2000)
    (1000.0, 447.21359549995793)
    """
    _check_limits(vmax, amax, vbase)
    d = abs(distance)
    if d == 0:
        return 0.0
    vb = min(vbase, vmax)
    return float(min(vmax, math.sqrt(vb * vb + amax * d)))


def move_duration(distance: float, vmax: float, amax: float, vbase: float = 0.0) -> float:
    """Duration (s) of a rest-to-rest move of ``distance`` positions.

    Trapezoidal velocity profile (triangular when the move is too short to reach
    ``vmax``); speeds up to ``vbase`` are reached and left instantly.

    >>> move_duration(1000, vmax=1000, amax=2000)  # 0.5 s up, 0.5 s cruise, 0.5 s down
    1.5
    >>> move_duration(100, vmax=1000, amax=2000)  # triangle: 2·sqrt(d/a)
    0.4472135954999579
    """
    _check_limits(vmax, amax, vbase)
    d = abs(distance)
    if d == 0:
        return 0.0
    vb = min(vbase, vmax)
    vp = math.sqrt(vb * vb + amax * d)
    if vp <= vmax:  # triangle
        return 2.0 * (vp - vb) / amax
    ramp = (vmax * vmax - vb * vb) / (2.0 * amax)  # distance of each ramp
    return 2.0 * (vmax - vb) / amax + (d - 2.0 * ramp) / vmax


def axis_step(
    state: AxisState,
    target: float,
    dt_s: float,
    vmax: float,
    amax: float,
    vbase: float = 0.0,
) -> AxisState:
    """Advance one axis by ``dt_s`` toward ``target`` (positions), exactly.

    The axis follows the time-optimal profile under the speed and acceleration
    limits from whatever state it is in, and stops exactly on ``target``.

    >>> s = AxisState()
    >>> for _ in range(15):
    ...     s = axis_step(s, 1000.0, 0.1, vmax=1000.0, amax=2000.0)
    >>> s
    AxisState(position=1000.0, velocity=0.0)
    """
    return axis_path(state, target, dt_s, vmax, amax, vbase)[0]


def _check_limits(vmax: float, amax: float, vbase: float) -> None:
    for name, v in (("vmax", vmax), ("amax", amax)):
        if not (math.isfinite(v) and v > 0):
            raise ValueError(f"{name} must be a finite number > 0, got {v!r}")
    if not (math.isfinite(vbase) and vbase >= 0):
        raise ValueError(f"vbase must be a finite number >= 0, got {vbase!r}")


def axis_path(
    state: AxisState, target: float, dt_s: float, vmax: float, amax: float, vbase: float
) -> tuple[AxisState, list[float]]:
    """:func:`axis_step`, plus the positions at the ends of its phases.

    Within a phase the acceleration is constant and the velocity keeps its sign, so
    the path between consecutive returned positions is monotone (what an exact
    backlash update needs).
    """
    _check_limits(vmax, amax, vbase)
    if not (math.isfinite(dt_s) and dt_s >= 0):
        raise ValueError(f"dt_s must be a finite number >= 0, got {dt_s!r}")
    a = amax
    vb = min(vbase, vmax)
    p, v, x = float(state.position), float(state.velocity), float(target)
    tau = float(dt_s)
    path: list[float] = []
    for _ in range(_MAX_PHASES):
        d = x - p
        dist = abs(d)
        tol = REL_TOL * max(dist, 1.0)
        if dist <= tol and abs(v) <= vb + _VEL_TOL:
            p, v = x, 0.0  # on target, at a speed it can stop from instantly
            break
        if tau <= 0.0:
            break
        s = 1.0 if d > 0 else -1.0 if d < 0 else math.copysign(1.0, v)
        if vb > 0 and abs(v) <= vb + _VEL_TOL:
            v = s * vb  # at or below base speed: start (or reverse) instantly
        u = v * s  # speed toward the target
        lands = False
        if u < 0:  # moving away: brake at full rate down to base speed
            acc, t, u_end = a, (-u - vb) / a, -vb
        else:
            ds = stopping_distance(u, a, vb)
            if ds > dist + tol:  # inside the braking distance: brake fully, overshoot
                acc, t, u_end = -a, (u - vb) / a, vb
            elif ds >= dist - tol:  # on the braking curve: land exactly on the target
                lands = True
                if u <= vb + _VEL_TOL:
                    acc, t, u_end = 0.0, 0.0, 0.0
                else:
                    acc = -(u * u - vb * vb) / (2.0 * dist)
                    t, u_end = 2.0 * dist / (u + vb), vb
            elif u < vmax - _VEL_TOL:  # accelerate to vmax or to the braking point
                acc = a
                t_vmax = (vmax - u) / a
                vp = math.sqrt(0.5 * (u * u + vb * vb) + a * dist)
                t_brake = (vp - u) / a
                t, u_end = (t_vmax, vmax) if t_vmax <= t_brake else (t_brake, vp)
            elif u > vmax + _VEL_TOL:  # speed lowered on the fly: ramp down to it
                acc, t, u_end = -a, (u - vmax) / a, vmax
            else:  # cruise to the braking point
                u = vmax
                acc, t, u_end = 0.0, (dist - stopping_distance(vmax, a, vb)) / vmax, vmax
        t = max(t, 0.0)
        if t <= tau + _TIME_TOL:  # the phase ends within this step: land on its end state
            h = t
            if lands:
                p, v = x, 0.0
            else:
                p += s * (u * h + 0.5 * acc * h * h)
                v = s * u_end
        else:
            h = tau
            p += s * (u * h + 0.5 * acc * h * h)
            v = s * (u + acc * h)
        tau -= h
        path.append(p)
    return AxisState(p, v), path
