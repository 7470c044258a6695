"""Mechanics that move the optical axis away from the PTU's joint angles (the paper puts
the sAC's 11.76 px vertical error down to them): backlash (a play between motor and
camera, see :func:`backlash`) and the camera's offset from the tilt hinge (see
:func:`camera_position`).
"""

from __future__ import annotations

import math


def backlash(output: float, drive: float, width: float) -> float:
    """Play (backlash) operator: the output stays put until the drive takes up the play.

    The output is kept within ``width / 2`` of the drive on either side, so on a
    reversal the drive travels ``width`` before the output moves, and a target
    approached from below and from above leaves the output ``width`` apart.

    >>> y = backlash(0.0, 10.0, 4.0)  # drive moves up: output trails by 2
    >>> y, backlash(y, 7.0, 4.0), backlash(y, 5.0, 4.0)  # reversal: 4 of travel lost
    (8.0, 8.0, 7.0)
    """
    half = 0.5 * width
    return min(max(output, drive - half), drive + half)


def camera_position(
    tilt_deg: float, forward_m: float, up_m: float, pan_deg: float = 0.0
) -> tuple[float, float, float]:
    """Camera centre (x, y, z) in metres in the PTU frame (origin on the tilt hinge).

    The camera sits ``forward_m`` along the optical axis and ``up_m`` perpendicular
    to it (up at tilt 0) from the tilt hinge; tilting rotates that offset about the
    hinge (positive tilt raises the optical axis), panning rotates it about z
    (positive pan to the left, +y). The hinge is taken to lie on the pan axis.

    Examples:
        >>> [round(c, 6) + 0.0 for c in camera_position(90.0, forward_m=0.05, up_m=0.02)]
        [-0.02, 0.0, 0.05]
    """
    th, ph = math.radians(tilt_deg), math.radians(pan_deg)
    r = forward_m * math.cos(th) - up_m * math.sin(th)  # horizontal reach
    z = forward_m * math.sin(th) + up_m * math.cos(th)
    return r * math.cos(ph), r * math.sin(ph), z
