"""PTU units: degrees ↔ PTU *positions* (motor steps of ``resolution_arcsec`` arc-seconds
each, 92.5714″ = 0.025714° on the paper's unit), and the whole position a unit reports.
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


def round_position(pos: float) -> int:
    """Nearest integer position, halves away from zero (symmetric about home).

    >>> round_position(2.5), round_position(-2.5), round_position(-2.4)
    (3, -3, -2)
    """
    return int(math.copysign(math.floor(abs(pos) + 0.5), pos))


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
