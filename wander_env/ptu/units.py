"""PTU units: degrees ↔ PTU *positions* (motor steps of ``resolution_arcsec`` arc-seconds
each, 92.5714″ = 0.025714° on the paper's unit), the whole position a unit reports, and
the whole positions and slew speeds it takes (the one rule of the simulator, the FLIR
driver and the firmware emulator).
"""

from __future__ import annotations

import math

ARCSEC_PER_DEG = 3600.0
# FLIR PTU-D46/E46 resolution as reported by ``PR``/``TR`` on the paper's unit.
FLIR_RESOLUTION_ARCSEC = 92.5714


def degrees_to_positions(deg: float, resolution_arcsec: float = FLIR_RESOLUTION_ARCSEC) -> float:
    """Degrees -> (fractional) PTU positions.

    >>> round(degrees_to_positions(21.3), 1)
    828.3
    """
    return deg * ARCSEC_PER_DEG / resolution_arcsec


def positions_to_degrees(pos: float, resolution_arcsec: float = FLIR_RESOLUTION_ARCSEC) -> float:
    """PTU positions -> degrees.

    >>> round(positions_to_degrees(1), 6)
    0.025714
    """
    return pos * resolution_arcsec / ARCSEC_PER_DEG


def clip_to_limits(
    pan_deg: float,
    tilt_deg: float,
    pan_limits: tuple[float, float],
    tilt_limits: tuple[float, float],
) -> tuple[float, float]:
    """A (pan, tilt) target in degrees clipped into the axes' (low, high) limits: the sim's
    (:meth:`~wander_env.ptu.params.PTUParams.clip_deg`) and the rig's, read from the unit.

    >>> clip_to_limits(100.0, -5.0, (-159.0, 159.0), (-31.0, 31.0))
    (100.0, -5.0)
    >>> clip_to_limits(200.0, -40.0, (-159.0, 159.0), (-31.0, 31.0))
    (159.0, -31.0)
    """
    (plo, phi), (tlo, thi) = pan_limits, tilt_limits
    return min(max(pan_deg, plo), phi), min(max(tilt_deg, tlo), thi)


def round_position(pos: float) -> int:
    """Nearest integer position, halves away from zero (symmetric about home).

    >>> round_position(2.5), round_position(-2.5), round_position(-2.4)
    (3, -3, -2)
    """
    return int(math.copysign(math.floor(abs(pos) + 0.5), pos))


def whole_position(axis: str, deg: float, resolution_arcsec: float) -> int:
    """An angle (or a rate in degrees per second) of ``axis`` as the whole positions a
    unit takes: :func:`round_position` of :func:`degrees_to_positions`; ``ValueError``
    naming the axis for a value that is not finite.

    >>> whole_position("pan", 21.3, FLIR_RESOLUTION_ARCSEC)
    828
    >>> whole_position("tilt", float("nan"), FLIR_RESOLUTION_ARCSEC)
    Traceback (most recent call last):
    ...
    ValueError: tilt value must be a finite number, got nan
    """
    if not math.isfinite(deg):
        raise ValueError(f"{axis} value must be a finite number, got {deg!r}")
    return round_position(degrees_to_positions(deg, resolution_arcsec))


class SpeedOutOfRange(ValueError):
    """A slew speed outside an axis's bounds (:func:`whole_speed`): ``limit`` is the bound
    it crosses (positions/s), ``above`` whether that is the upper one."""

    def __init__(self, message: str, limit: float, above: bool) -> None:
        super().__init__(message)
        self.limit, self.above = limit, above


def whole_speed(axis: str, pos_s: float, lower: float, upper: float) -> int:
    """The slew speed ``pos_s`` (positions/s) of ``axis`` as a FLIR unit takes it
    (``PS``/``TS``): whole positions/s (:func:`round_position`) within the unit's bounds,
    at least ``lower`` (``PL``) and one, at most ``upper`` (``PU``).

    Raises ``ValueError`` for a value that is not finite and :class:`SpeedOutOfRange`
    (a ``ValueError``) for one that rounds outside the bounds.

    >>> whole_speed("pan", 30.5, 31.0, 2902.0), whole_speed("pan", 2902.4, 31.0, 2902.0)
    (31, 2902)
    >>> try:
    ...     whole_speed("pan", 19.44, 31.0, 2902.0)
    ... except SpeedOutOfRange as err:
    ...     print(err, err.limit, err.above)
    pan speed must round to 31…2902 positions/s, got 19.44 positions/s 31.0 False
    """
    if not math.isfinite(pos_s):
        raise ValueError(f"{axis} speed must be a finite number, got {pos_s!r} positions/s")
    lowest = max(lower, 1.0)
    whole = round_position(pos_s)
    if not lowest <= whole <= upper:
        raise SpeedOutOfRange(
            f"{axis} speed must round to {lowest:g}…{upper:g} positions/s, "
            f"got {pos_s:.6g} positions/s",
            upper if whole > upper else lowest,
            whole > upper,
        )
    return whole


def step_counter(position: float, velocity: float) -> int:
    """The position a FLIR unit reports (``PP``): whole steps taken so far. While moving
    the counter trails the continuous position (floor moving up, ceil moving down), so
    it equals the target only on arrival; at rest the nearest whole position.

    >>> step_counter(10.7, 5.0), step_counter(-10.7, -5.0), step_counter(10.7, 0.0)
    (10, -10, 11)
    """
    if velocity > 0:
        return math.floor(position + 1e-9)
    if velocity < 0:
        return math.ceil(position - 1e-9)
    return round_position(position)
