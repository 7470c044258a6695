"""The pan-tilt unit (PTU): a FLIR PTU-E46/D46-like two-axis stepper positioner.

Public angles are in degrees; inside, each axis works in PTU *positions* (motor
steps, ``resolution_arcsec`` arc-seconds each: 92.5714″ = 0.025714° on the paper's
unit), as the FLIR firmware's ASCII protocol does (``PP``/``TP`` targets, ``PS``
speed, ``PA`` acceleration, ``PB`` base speed, ``PU`` upper speed, ``PN``/``PX``
limits).

Motion model, per axis (the FLIR controller's, from its manuals): speeds up to the
base speed ``vb`` change instantly (a stepper can start and stop there without
losing synchrony); above it the speed ramps at ``accel`` up to ``speed``, and down
again at the same rate, so a rest-to-rest move is a trapezoid (a triangle when the
move is short), truncated at ``vb``. The target may change at any time: the axis
brakes, reverses if needed, and stops exactly on the new target; it overshoots
only when the new target lies inside its braking distance, and then by exactly
the unavoidable amount. The state is integrated *exactly* (phase by phase, in
closed form), so timings do not depend on the step size.

Mechanics that move the optical axis away from the joint angles (the paper puts the
sAC's 11.76 px vertical error down to them): backlash (a play of ``*_backlash_pos``
between motor and camera, see :func:`backlash`) and the camera's offset from the tilt
hinge (see :func:`camera_position`).

Command latency (:class:`PTULinkParams`, the ``flir`` preset of :meth:`PTUParams.preset`;
off in ``ideal``, the default): the real unit talks ASCII at 9600 baud, so every command
and position query costs milliseconds on the serial line. :class:`CommandLink` replays, in
simulated time, what the rig's PTU thread (``hardware/rig_env.py``) does with the
driver (``hardware/ptu_driver.py``): a new target is queued (replacing one not yet sent)
and sent as ``PP<n>`` then ``TP<n>`` (only the axes that changed), each answered ``*``
CR LF; between commands the thread polls ``PP`` and ``TP`` (answers ``* <n>`` CR LF)
every ``poll_s``. Each byte costs ``bits_per_byte / baudrate`` (8N1: 10 bits); an axis
takes its new target when the unit has received the command's last byte; the position
a query reports is the unit's step counter when the query arrived. With a link,
:attr:`PanTiltUnit.moving` is the rig's: true until a poll that began after the
latest target was acknowledged found the unit on it.

Conventions: positive pan turns the camera left (counter-clockwise seen from above;
FLIR: ``PO828`` pans 21.3° left); positive tilt raises it. The PTU frame has its
origin on the tilt hinge, x forward (optical axis at pan = tilt = 0), y left, z up.

Examples:
    >>> from wander_env.ptu import PanTiltUnit, PTUParams
    >>> ptu = PanTiltUnit(PTUParams(pan_base_speed=0.0, pan_speed=1000.0))
    >>> ptu.set_target(pan_deg=1000 * ptu.params.pan_deg_per_pos, tilt_deg=0.0)
    >>> for _ in range(1500):
    ...     ptu.step(0.001)
    >>> ptu.positions, ptu.moving
    ((1000, 0), False)
"""

from __future__ import annotations

import bisect
import copy
import math
from collections.abc import Mapping
from dataclasses import dataclass, fields, replace

from wander_env.config import check_fields

ARCSEC_PER_DEG = 3600.0
# FLIR PTU-D46/E46 resolution as reported by ``PR``/``TR`` on the paper's unit.
FLIR_RESOLUTION_ARCSEC = 92.5714

# Relative tolerance on distances (positions) and absolute one on speeds (pos/s) and
# on phase ends (s); they absorb float rounding of a closed-form phase end only.
_REL_TOL = 1e-9
_VEL_TOL = 1e-9
_TIME_TOL = 1e-12
# A step is at most a handful of phases (away-brake, reverse, accelerate, cruise, brake).
_MAX_PHASES = 64


# ----------------------------------------------------------------------------------------
# Unit conversions


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


# ----------------------------------------------------------------------------------------
# The serial link (command latency)


@dataclass(frozen=True)
class PTULinkParams:
    """The host-PTU serial link as the rig drives it (``hardware/ptu_driver.py``: terse
    feedback, echo off, commands ended by a space; replies ended by CR LF as the
    emulator and the PTU-D48E write them).

    ``baudrate`` 9600 (the FLIR factory setting, ``FlirPTUParams.baudrate``), 8N1 =
    ``bits_per_byte`` 10; ``poll_s`` the rig's position polling period
    (``RigConfig.ptu_poll_s``); ``turnaround_s`` the unit's time between a command's
    last byte and its reply (not documented by FLIR: 0).

    >>> round(PTULinkParams().byte_s * 1e3, 4)
    1.0417
    """

    baudrate: int = 9600
    bits_per_byte: int = 10
    poll_s: float = 0.01
    delimiter: str = " "
    eol: str = "\r\n"
    turnaround_s: float = 0.0

    def __post_init__(self) -> None:
        check_fields(self, ("baudrate", "bits_per_byte"), integer=True, positive=True)
        check_fields(self, ("poll_s", "turnaround_s"), minimum=0)
        if self.delimiter not in (" ", "\r", "\n"):
            raise ValueError(
                f"PTULinkParams.delimiter must be a space, CR or LF, got {self.delimiter!r}"
            )
        if self.eol not in ("\r\n", "\n", "\r"):
            raise ValueError(f"PTULinkParams.eol must be CR LF, LF or CR, got {self.eol!r}")

    @property
    def byte_s(self) -> float:
        """Seconds per byte on the line."""
        return self.bits_per_byte / self.baudrate


def command_bytes(axis: int, value: int | None, link: PTULinkParams) -> int:
    """Bytes of a position command (``PP-500 ``) or query (``PP ``) for axis 0 (pan) or 1.

    >>> command_bytes(0, -500, PTULinkParams()), command_bytes(1, None, PTULinkParams())
    (7, 3)
    """
    letter = "PT"[axis]
    return len(f"{letter}P{'' if value is None else value}{link.delimiter}")


def reply_bytes(value: int | None, link: PTULinkParams) -> int:
    """Bytes of the unit's terse reply: ``*`` (a command) or ``* <value>`` (a query).

    >>> reply_bytes(None, PTULinkParams()), reply_bytes(-1234, PTULinkParams())
    (3, 9)
    """
    return len(("*" if value is None else f"* {value}") + link.eol)


def exchange_s(axis: int, value: int | None, reply: int | None, link: PTULinkParams) -> float:
    """Seconds of one command/reply exchange on an idle line.

    >>> round(exchange_s(0, 1000, None, PTULinkParams()) * 1e3, 2)  # PP1000 + *
    10.42
    """
    n = command_bytes(axis, value, link) + reply_bytes(reply, link)
    return n * link.byte_s + link.turnaround_s


# ----------------------------------------------------------------------------------------
# Parameters


@dataclass(frozen=True)
class PTUParams:
    """Pan-tilt unit parameters; positions, positions/s and positions/s² per axis.

    Defaults are those of a FLIR PTU-D46/E46 at the paper's resolution:

    - resolution 92.5714″/position on both axes (the paper's ``PR``/``TR``);
    - limits ``PN``/``PX`` = ∓3090, ``TN``/``TX`` = −907/+604 (FLIR factory limits);
    - ``accel`` 2000 pos/s² (what the FLIR manuals' ``PA`` query examples report) and
      ``base_speed`` 1000 pos/s (the ``PB``/``TB`` default in the PTU-D46 manual);
    - ``speed`` 2000 pos/s ≈ 51.4°/s, a typical configured ``PS``/``TS`` (an
      assumption: the paper does not give its speed), below ``upper_speed`` 2902 pos/s
      (the ``PU`` in the manual's example), which bounds :meth:`PanTiltUnit.set_speed`.
      With these, a 1000-position (25.7°) saccade takes 0.73 s and a 60-position
      fixational step 0.058 s (see :func:`move_duration`).

    ``*_backlash_pos`` (play between motor and camera, 0 = ideal) and the camera's
    offset from the tilt hinge (``camera_forward_m`` along the optical axis,
    ``camera_up_m`` perpendicular to it, up at tilt 0) default to an ideal unit.
    ``quantise`` keeps targets and reported angles on whole positions, as the
    stepper does.
    """

    pan_resolution_arcsec: float = FLIR_RESOLUTION_ARCSEC
    tilt_resolution_arcsec: float = FLIR_RESOLUTION_ARCSEC
    pan_min_pos: int = -3090
    pan_max_pos: int = 3090
    tilt_min_pos: int = -907
    tilt_max_pos: int = 604
    pan_speed: float = 2000.0
    tilt_speed: float = 2000.0
    pan_accel: float = 2000.0
    tilt_accel: float = 2000.0
    pan_base_speed: float = 1000.0
    tilt_base_speed: float = 1000.0
    pan_upper_speed: float = 2902.0
    tilt_upper_speed: float = 2902.0
    pan_backlash_pos: float = 0.0
    tilt_backlash_pos: float = 0.0
    camera_forward_m: float = 0.0
    camera_up_m: float = 0.0
    quantise: bool = True
    link: PTULinkParams | None = None

    @classmethod
    def preset(cls, name: str) -> PTUParams:
        """``"ideal"`` (the defaults: commands act at once) or ``"flir"`` (the same unit
        behind its 9600-baud serial link, :class:`PTULinkParams`).

        >>> PTUParams.preset("flir").link.baudrate, PTUParams.preset("ideal").link
        (9600, None)
        """
        if name == "ideal":
            return cls()
        if name == "flir":
            return cls(link=PTULinkParams())
        raise ValueError(f"unknown PTU preset {name!r}; expected 'ideal' or 'flir'")

    def __post_init__(self) -> None:
        if isinstance(self.link, Mapping):  # from asdict() (pickling, JSON configs)
            object.__setattr__(self, "link", PTULinkParams(**self.link))
        if self.link is not None and not isinstance(self.link, PTULinkParams):
            raise ValueError(f"PTUParams.link must be PTULinkParams or None, got {self.link!r}")
        ints = ("pan_min_pos", "pan_max_pos", "tilt_min_pos", "tilt_max_pos")
        positive = (
            "pan_resolution_arcsec",
            "tilt_resolution_arcsec",
            "pan_speed",
            "tilt_speed",
            "pan_accel",
            "tilt_accel",
            "pan_upper_speed",
            "tilt_upper_speed",
        )
        signed = ("camera_forward_m", "camera_up_m")
        if not isinstance(self.quantise, bool):
            raise ValueError(f"PTUParams.quantise must be a bool, got {self.quantise!r}")
        check_fields(self, ints, integer=True)
        check_fields(self, positive, positive=True)
        check_fields(self, signed)
        named = {*ints, *positive, *signed, "quantise", "link"}
        check_fields(self, [f.name for f in fields(self) if f.name not in named], minimum=0)
        for axis in ("pan", "tilt"):
            lo, hi = getattr(self, f"{axis}_min_pos"), getattr(self, f"{axis}_max_pos")
            if lo >= hi:
                raise ValueError(f"PTUParams.{axis}_min_pos ({lo}) must be < {axis}_max_pos ({hi})")
            upper = getattr(self, f"{axis}_upper_speed")
            for name in (f"{axis}_speed", f"{axis}_base_speed"):
                if getattr(self, name) > upper:
                    raise ValueError(
                        f"PTUParams.{name} must be <= {axis}_upper_speed ({upper}), "
                        f"got {getattr(self, name)!r}"
                    )

    @property
    def pan_deg_per_pos(self) -> float:
        """Degrees per pan position (0.025714 by default)."""
        return positions_to_degrees(1.0, self.pan_resolution_arcsec)

    @property
    def tilt_deg_per_pos(self) -> float:
        """Degrees per tilt position."""
        return positions_to_degrees(1.0, self.tilt_resolution_arcsec)

    @property
    def pan_limits_deg(self) -> tuple[float, float]:
        """(min, max) pan angle in degrees (≈ ±79.46° by default)."""
        r = self.pan_resolution_arcsec
        return positions_to_degrees(self.pan_min_pos, r), positions_to_degrees(self.pan_max_pos, r)

    @property
    def tilt_limits_deg(self) -> tuple[float, float]:
        """(min, max) tilt angle in degrees (≈ −23.32°…+15.53° by default)."""
        r = self.tilt_resolution_arcsec
        return (
            positions_to_degrees(self.tilt_min_pos, r),
            positions_to_degrees(self.tilt_max_pos, r),
        )

    def clip_deg(self, pan_deg: float, tilt_deg: float) -> tuple[float, float]:
        """Clip a (pan, tilt) target in degrees into the limits.

        >>> PTUParams().clip_deg(100.0, -5.0)[0] == PTUParams().pan_limits_deg[1]
        True
        """
        plo, phi = self.pan_limits_deg
        tlo, thi = self.tilt_limits_deg
        return min(max(pan_deg, plo), phi), min(max(tilt_deg, tlo), thi)

    def with_slew(self, speed_pos_s: float, accel_pos_s2: float) -> PTUParams:
        """These parameters with both axes' slew speed and acceleration set (positions/s,
        positions/s²) and the start speed capped to the slew speed.

        >>> p = PTUParams().with_slew(500.0, 4000.0)
        >>> p.tilt_speed, p.pan_base_speed, p.tilt_accel
        (500.0, 500.0, 4000.0)
        """
        return replace(
            self,
            pan_speed=speed_pos_s,
            tilt_speed=speed_pos_s,
            pan_base_speed=min(self.pan_base_speed, speed_pos_s),
            tilt_base_speed=min(self.tilt_base_speed, speed_pos_s),
            pan_accel=accel_pos_s2,
            tilt_accel=accel_pos_s2,
        )


# ----------------------------------------------------------------------------------------
# One axis: pure motion maths


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
    return _advance(state, target, dt_s, vmax, amax, vbase)[0]


def _check_limits(vmax: float, amax: float, vbase: float) -> None:
    for name, v in (("vmax", vmax), ("amax", amax)):
        if not (math.isfinite(v) and v > 0):
            raise ValueError(f"{name} must be a finite number > 0, got {v!r}")
    if not (math.isfinite(vbase) and vbase >= 0):
        raise ValueError(f"vbase must be a finite number >= 0, got {vbase!r}")


def _advance(
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
        tol = _REL_TOL * max(dist, 1.0)
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


# ----------------------------------------------------------------------------------------
# Mechanics between the motor and the camera


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


# ----------------------------------------------------------------------------------------
# The link thread, in simulated time


class CommandLink:
    """The rig's PTU thread (``hardware/rig_env.py`` ``_PTULink``) replayed in simulated
    time: one exchange on the line at a time; a submitted target waits for the exchange
    in progress, replaces a queued one not yet sent, then goes out as ``PP<n>``/``TP<n>``
    (changed axes only); when no target waits, ``PP``/``TP`` are polled ``poll_s`` after
    the previous poll ended (at once after a command).

    Driven by :class:`PanTiltUnit` (:meth:`next_time`, :meth:`fire`); ``latencies_s``
    holds each acknowledged command's latency (submission to the last ``*``), as the
    rig's ``info["command_latency_s"]`` measures it.

    >>> link = CommandLink(PTULinkParams(), (0, 0))
    >>> link.submit((100, 0), 0.0)        # the line is idle: PP100 goes out at once
    >>> round(link.next_time() * 1e3, 3)  # ...and arrives after its 6 bytes
    6.25
    """

    def __init__(self, params: PTULinkParams, start: tuple[int, int], t_s: float = 0.0) -> None:
        self.params = params
        self.acked = tuple(start)
        self.positions = tuple(start)  # the last poll's answer
        self.poll_target = tuple(start)  # the acknowledged target when that poll began
        self.want: tuple[int, int] | None = None
        self.want_at = 0.0
        self.latencies_s: list[float] = []
        self.counts = {"commands_sent": 0, "commands_replaced": 0, "polls": 0}
        self._next_poll = t_s + params.poll_s
        self._stage = "idle"  # idle | sending (command on the line) | replying
        self._next = self._next_poll
        self._tx: list[tuple[int, int | None]] = []  # (axis, value or None = query)
        self._job: tuple[int, int] | None = None
        self._job_at = 0.0
        self._poll_acked = self.acked
        self._samples = list(start)
        self._reply: int | None = None

    @property
    def latency_s(self) -> float:
        """The latest acknowledged command's latency (NaN before the first)."""
        return self.latencies_s[-1] if self.latencies_s else math.nan

    def copy(self) -> CommandLink:
        """An independent link in the same state."""
        twin = copy.copy(self)
        twin.latencies_s, twin.counts = list(self.latencies_s), dict(self.counts)
        twin._tx, twin._samples = list(self._tx), list(self._samples)
        return twin

    def moving(self, target: tuple[int, int]) -> bool:
        """The rig's test: a target is queued or being sent, or the last poll (begun after
        ``target`` was acknowledged) did not find the unit on it."""
        busy = self.want is not None or (self._stage != "idle" and self._job is not None)
        return busy or self.poll_target != tuple(target) or self.positions != tuple(target)

    def submit(self, target: tuple[int, int], t_s: float) -> None:
        """Hand a new target (whole positions) to the thread at ``t_s``."""
        if self.want is not None:
            self.counts["commands_replaced"] += 1
        self.want, self.want_at = tuple(target), t_s
        if self._stage == "idle":
            self._begin(t_s)

    def next_time(self) -> float:
        """When the next thing happens on the line (a byte string fully received)."""
        return self._next

    def fire(self, unit: PanTiltUnit) -> None:
        """Do what happens at :meth:`next_time` (the unit's motion is advanced to it)."""
        t = self._next
        if self._stage == "idle":  # the poll is due
            self._begin(t)
        elif self._stage == "sending":  # the unit has the command: act, start the reply
            axis, value = self._tx[0]
            if value is None:
                self._reply = unit.step_counter(axis)
                self._samples[axis] = self._reply
            else:
                unit.drive_axis(axis, float(value))
                self._reply = None
            self._stage = "replying"
            self._next = (
                t
                + self.params.turnaround_s
                + reply_bytes(self._reply, self.params) * (self.params.byte_s)
            )
        else:  # the reply is in: next command of the exchange, or the exchange is over
            self._tx.pop(0)
            if self._tx:
                self._send_next(t)
            else:
                self._finish(t)

    def _begin(self, t: float) -> None:
        job, self.want = self.want, None
        if job is not None and job != self.acked:
            self._job, self._job_at = job, self.want_at
            self._tx = [(i, job[i]) for i in (0, 1) if job[i] != self.acked[i]]
        else:
            self._job = None
            self._poll_acked = self.acked
            self._tx = [(0, None), (1, None)]
        self._send_next(t)

    def _send_next(self, t: float) -> None:
        axis, value = self._tx[0]
        self._stage = "sending"
        self._next = t + command_bytes(axis, value, self.params) * self.params.byte_s

    def _finish(self, t: float) -> None:
        if self._job is not None:
            self.acked = self._job
            self.latencies_s.append(t - self._job_at)
            self.counts["commands_sent"] += 1
            self._next_poll = t  # poll right after a command
            self._job = None
        else:
            self.positions, self.poll_target = tuple(self._samples), self._poll_acked
            self.counts["polls"] += 1
            self._next_poll = t + self.params.poll_s
        if self.want is not None or self._next_poll <= t:
            self._begin(t)
        else:
            self._stage, self._next = "idle", self._next_poll


# ----------------------------------------------------------------------------------------
# The stateful unit


@dataclass(frozen=True)
class Trajectory:
    """The camera's angles over one span of ticks, from :meth:`PanTiltUnit.trajectory`.

    ``t_us[i]`` is the end of tick ``i`` (tick 0 starts at ``t0_us``) and ``pan_deg[i]``,
    ``tilt_deg[i]`` the camera's angles there (after backlash); ``starts[i]`` is the unit
    as it was at the start of tick ``i`` (a copy, never stepped), from which
    :meth:`at` evaluates angles at times inside the span (adaptive sub-frames).
    """

    t0_us: int
    t_us: tuple[int, ...]
    pan_deg: tuple[float, ...]
    tilt_deg: tuple[float, ...]
    starts: tuple[PanTiltUnit, ...]

    def angles(self, i: int) -> tuple[float, float]:
        """Camera (pan, tilt) in degrees at the end of tick ``i``."""
        return self.pan_deg[i], self.tilt_deg[i]

    def at(self, times_us: list[int]) -> list[tuple[float, float]]:
        """Camera (pan, tilt) at increasing ``times_us`` inside the span (adaptive
        sub-frames): per tick, a copy of the unit at its start stepped from one time to
        the next (the unit that made the trajectory is not touched)."""
        out = []
        tick, unit, t_prev = -1, self.starts[0], self.t0_us
        for t in times_us:
            i = bisect.bisect_left(self.t_us, t)
            if not (i < len(self.t_us) and (self.t_us[i - 1] if i else self.t0_us) < t):
                raise ValueError(f"t={t} µs is not inside ({self.t0_us}, {self.t_us[-1]}]")
            if i != tick:
                tick, unit = i, self.starts[i].copy()
                t_prev = self.t_us[i - 1] if i else self.t0_us
            unit.step((t - t_prev) * 1e-6)
            t_prev = t
            out.append((unit.camera_pan_deg, unit.camera_tilt_deg))
        return out


class PanTiltUnit:
    """A two-axis PTU: targets in degrees, :meth:`step` advances the motion model.

    Targets outside the limits raise ``ValueError`` (as the FLIR unit answers
    ``!`` and does not move); :meth:`clip_target` clips one into range first.

    >>> ptu = PanTiltUnit(PTUParams(tilt_backlash_pos=10.0))
    >>> ptu.set_target(tilt_deg=5.0)
    >>> ptu.step(1.0)
    >>> round(ptu.tilt_deg, 3), round(ptu.tilt_deg - ptu.camera_tilt_deg, 4)
    (4.989, 0.1286)
    """

    def __init__(self, params: PTUParams | None = None) -> None:
        self.params = params if params is not None else PTUParams()
        self.reset()

    # -- commands ---------------------------------------------------------------------

    def reset(self, pan_deg: float = 0.0, tilt_deg: float = 0.0) -> None:
        """Place the unit at rest at (pan, tilt), camera on the motor (play centred)."""
        pan = self._to_pos("pan", pan_deg)
        tilt = self._to_pos("tilt", tilt_deg)
        self._pan = AxisState(pan, 0.0)
        self._tilt = AxisState(tilt, 0.0)
        self._target = [pan, tilt]  # commanded (what target_deg reports)
        self._drive = [pan, tilt]  # what the axes move to (the unit's target)
        self._speed = [self.params.pan_speed, self.params.tilt_speed]
        self._camera = [self._motor(pan), self._motor(tilt)]
        self._time_s = 0.0
        link = self.params.link
        self.link = (
            CommandLink(link, (round_position(pan), round_position(tilt)))
            if link is not None
            else None
        )

    def copy(self) -> PanTiltUnit:
        """An independent unit in the same state."""
        twin = copy.copy(self)
        twin._target, twin._drive, twin._speed, twin._camera = (
            list(self._target),
            list(self._drive),
            list(self._speed),
            list(self._camera),
        )
        twin.link = self.link.copy() if self.link is not None else None
        return twin

    def set_target(self, pan_deg: float | None = None, tilt_deg: float | None = None) -> None:
        """Command an absolute target in degrees; ``None`` keeps that axis's target.

        Raises ``ValueError`` naming the limit when a target is out of range. With a
        :attr:`link` a changed target is handed to it (it reaches the axes later).
        """
        pan = self._to_pos("pan", pan_deg) if pan_deg is not None else None
        tilt = self._to_pos("tilt", tilt_deg) if tilt_deg is not None else None
        self._command(pan, tilt)

    def _command(self, pan: float | None, tilt: float | None) -> None:
        old = tuple(self._target)
        if pan is not None:
            self._target[0] = pan
        if tilt is not None:
            self._target[1] = tilt
        if self.link is None:
            self._drive = list(self._target)
        elif tuple(self._target) != old:
            whole = (round_position(self._target[0]), round_position(self._target[1]))
            self.link.submit(whole, self._time_s)

    def set_target_positions(
        self, pan_pos: float | None = None, tilt_pos: float | None = None
    ) -> None:
        """As :meth:`set_target`, in PTU positions (for a FLIR protocol front end)."""
        pan = self._check_pos("pan", pan_pos) if pan_pos is not None else None
        tilt = self._check_pos("tilt", tilt_pos) if tilt_pos is not None else None
        self._command(pan, tilt)

    def drive_axis(self, axis: int, pos: float) -> None:
        """Give axis 0 (pan) or 1 (tilt) its new target now (the link's command has
        arrived at the unit)."""
        self._drive[axis] = float(pos)

    def step_counter(self, axis: int) -> int:
        """What a ``PP``/``TP`` query of axis 0/1 answers now (:func:`step_counter`)."""
        state = self._pan if axis == 0 else self._tilt
        return step_counter(state.position, state.velocity)

    def clip_target(self, pan_deg: float, tilt_deg: float) -> tuple[float, float]:
        """(pan, tilt) in degrees clipped into the limits; see :meth:`PTUParams.clip_deg`."""
        return self.params.clip_deg(pan_deg, tilt_deg)

    def set_speed(self, pan_deg_s: float | None = None, tilt_deg_s: float | None = None) -> None:
        """Change the slew speed on the fly (FLIR ``PS``/``TS``), in degrees per second.

        Must be > 0 and at most the axis's ``upper_speed``; ``None`` keeps it.
        """
        for i, (axis, value) in enumerate((("pan", pan_deg_s), ("tilt", tilt_deg_s))):
            if value is None:
                continue
            pos_s = degrees_to_positions(value, getattr(self.params, f"{axis}_resolution_arcsec"))
            upper = getattr(self.params, f"{axis}_upper_speed")
            if not (math.isfinite(pos_s) and 0 < pos_s <= upper * (1 + _REL_TOL)):
                raise ValueError(
                    f"{axis} speed must be in (0, {axis}_upper_speed = {upper} pos/s], "
                    f"got {value!r} deg/s = {pos_s:.6g} pos/s"
                )
            self._speed[i] = min(pos_s, upper)

    def step(self, dt_s: float) -> None:
        """Advance the motion model by ``dt_s`` seconds (with a :attr:`link`, stopping at
        each of its events: the split does not change the exact motion)."""
        if not (math.isfinite(dt_s) and dt_s >= 0):
            raise ValueError(f"dt_s must be a finite number >= 0, got {dt_s!r}")
        if self.link is None:
            self._advance(dt_s)
            return
        t_end = self._time_s + dt_s
        while self.link.next_time() <= t_end:
            self._advance(max(self.link.next_time() - self._time_s, 0.0))
            self.link.fire(self)
        self._advance(max(t_end - self._time_s, 0.0))
        self._time_s = t_end

    def trajectory(self, t0_us: int, t1_us: int, tick_us: int) -> Trajectory:
        """Step the unit from ``t0_us`` to ``t1_us`` once per tick of ``tick_us`` (the last
        tick ends at ``t1_us``) and return the camera's angles at every tick's end: the
        one motion of a control step, which every frame source reads.

        >>> ptu = PanTiltUnit()
        >>> ptu.set_target(pan_deg=1.0)
        >>> tr = ptu.trajectory(0, 3000, 1000)
        >>> tr.t_us, round(tr.pan_deg[-1], 6) == round(ptu.camera_pan_deg, 6)
        ((1000, 2000, 3000), True)
        """
        if tick_us <= 0 or t1_us <= t0_us:
            raise ValueError(f"need tick_us > 0 and t1_us > t0_us, got {tick_us}, {t0_us}, {t1_us}")
        times, pans, tilts, starts = [], [], [], []
        t = t0_us
        while t < t1_us:
            t_next = min(t + tick_us, t1_us)
            starts.append(self.copy())
            self.step((t_next - t) * 1e-6)
            t = t_next
            times.append(t)
            pans.append(self.camera_pan_deg)
            tilts.append(self.camera_tilt_deg)
        return Trajectory(t0_us, tuple(times), tuple(pans), tuple(tilts), tuple(starts))

    def _advance(self, dt_s: float) -> None:
        p = self.params
        axes = (
            (self._pan, p.pan_accel, p.pan_base_speed, p.pan_backlash_pos),
            (self._tilt, p.tilt_accel, p.tilt_base_speed, p.tilt_backlash_pos),
        )
        new = []
        for i, (state, accel, base, play) in enumerate(axes):
            vb = min(base, self._speed[i])
            nxt, path = _advance(state, self._drive[i], dt_s, self._speed[i], accel, vb)
            for q in [*path, nxt.position]:
                self._camera[i] = backlash(self._camera[i], self._motor(q), play)
            new.append(nxt)
        self._pan, self._tilt = new
        self._time_s += dt_s

    # -- state ------------------------------------------------------------------------

    @property
    def time_s(self) -> float:
        """Seconds of motion simulated since :meth:`reset`."""
        return self._time_s

    @property
    def pan_deg(self) -> float:
        """Pan joint angle reached (degrees; on whole positions when ``quantise``)."""
        return positions_to_degrees(
            self._motor(self._pan.position), self.params.pan_resolution_arcsec
        )

    @property
    def tilt_deg(self) -> float:
        """Tilt joint angle reached (degrees; on whole positions when ``quantise``)."""
        return positions_to_degrees(
            self._motor(self._tilt.position), self.params.tilt_resolution_arcsec
        )

    @property
    def camera_pan_deg(self) -> float:
        """Pan of the optical axis after backlash (degrees)."""
        return positions_to_degrees(self._camera[0], self.params.pan_resolution_arcsec)

    @property
    def camera_tilt_deg(self) -> float:
        """Tilt of the optical axis after backlash (degrees)."""
        return positions_to_degrees(self._camera[1], self.params.tilt_resolution_arcsec)

    @property
    def camera_position_m(self) -> tuple[float, float, float]:
        """Camera centre in the PTU frame (m), from the camera angles and hinge offset."""
        return camera_position(
            self.camera_tilt_deg,
            self.params.camera_forward_m,
            self.params.camera_up_m,
            self.camera_pan_deg,
        )

    @property
    def positions(self) -> tuple[int, int]:
        """(pan, tilt) motor positions as the unit reports them (``PP``/``TP``)."""
        return round_position(self._pan.position), round_position(self._tilt.position)

    @property
    def target_positions(self) -> tuple[float, float]:
        """(pan, tilt) targets in positions (whole numbers when ``quantise``)."""
        return self._target[0], self._target[1]

    @property
    def target_deg(self) -> tuple[float, float]:
        """(pan, tilt) targets in degrees."""
        return (
            positions_to_degrees(self._target[0], self.params.pan_resolution_arcsec),
            positions_to_degrees(self._target[1], self.params.tilt_resolution_arcsec),
        )

    @property
    def pan_velocity_deg_s(self) -> float:
        """Signed pan velocity (degrees/s)."""
        return positions_to_degrees(self._pan.velocity, self.params.pan_resolution_arcsec)

    @property
    def tilt_velocity_deg_s(self) -> float:
        """Signed tilt velocity (degrees/s)."""
        return positions_to_degrees(self._tilt.velocity, self.params.tilt_resolution_arcsec)

    @property
    def velocities_deg_s(self) -> tuple[float, float]:
        """(pan, tilt) signed velocities (degrees/s)."""
        return self.pan_velocity_deg_s, self.tilt_velocity_deg_s

    @property
    def moving(self) -> bool:
        """True until both axes are at rest on their targets; with a :attr:`link`, as
        the rig sees it (:meth:`CommandLink.moving`)."""
        if self.link is not None:
            return self.link.moving(
                (round_position(self._target[0]), round_position(self._target[1]))
            )
        return any(
            s.velocity != 0.0 or s.position != t
            for s, t in ((self._pan, self._drive[0]), (self._tilt, self._drive[1]))
        )

    @property
    def command_latency_s(self) -> float:
        """The latest command's latency on the :attr:`link` (NaN without one or before
        the first acknowledged command)."""
        return self.link.latency_s if self.link is not None else math.nan

    # -- helpers ----------------------------------------------------------------------

    def _motor(self, pos: float) -> float:
        """The motor's position as it stands: on a whole step when ``quantise``."""
        return float(round_position(pos)) if self.params.quantise else pos

    def _to_pos(self, axis: str, deg: float) -> float:
        if not math.isfinite(deg):
            raise ValueError(f"{axis} target must be a finite angle in degrees, got {deg!r}")
        pos = degrees_to_positions(deg, getattr(self.params, f"{axis}_resolution_arcsec"))
        return self._check_pos(axis, pos, deg)

    def _check_pos(self, axis: str, pos: float, deg: float | None = None) -> float:
        if not math.isfinite(pos):
            raise ValueError(f"{axis} target must be finite, got {pos!r}")
        if self.params.quantise:
            pos = float(round_position(pos))
        lo = getattr(self.params, f"{axis}_min_pos")
        hi = getattr(self.params, f"{axis}_max_pos")
        tol = _REL_TOL * max(abs(pos), 1.0)
        if pos < lo - tol or pos > hi + tol:
            lo_d, hi_d = getattr(self.params, f"{axis}_limits_deg")
            shown = f"{deg!r}° = {pos:g} positions" if deg is not None else f"{pos:g} positions"
            bound = f"{axis}_min_pos = {lo}" if pos < lo else f"{axis}_max_pos = {hi}"
            raise ValueError(
                f"{axis} target {shown} is outside the limit {bound} "
                f"(range {lo_d:.4f}°…{hi_d:.4f}°); use clip_target to clip it"
            )
        return min(max(pos, float(lo)), float(hi))
