"""The FLIR pan-tilt unit's firmware: its ASCII command set as a state machine.

:class:`PTUFirmware` holds what the unit's controller holds: two axes moved by the motion
maths of :mod:`wander_env.ptu` (:func:`~wander_env.ptu.axis.axis_step`: trapezoidal
profile, base speed, on-the-fly target and speed changes) and the modes (echo, feedback,
slaved, speed control, limits). It answers one command at a time
(:meth:`PTUFirmware.execute`: ``"PP-500"`` → ``"*"``) and holds the answer of an ``A``
(await) or ``R`` (reset) until the axes allow it (:meth:`PTUFirmware.poll`). It does no
I/O and reads no clock: every call that moves the axes takes ``now`` (seconds, on any
monotonic clock). :class:`hardware.ptu_emulator.PTUEmulator` puts it on a pseudo-terminal
(the echo, line ends, the line's timing and the fault injection are the emulator's).

The replies are the firmware's texts as the FLIR manuals and public drivers give them
(sources in ``hardware/PTU_PROTOCOL.md``): ``*`` for success, ``* <value>`` (terse) or
``* <text>`` (verbose) for a query, ``! <message>`` for a failure.

Examples:
    >>> fw = PTUFirmware(PTUParams(), now=0.0)
    >>> fw.execute("PP500", now=0.0), fw.execute("A", now=0.0)
    ('*', None)
    >>> fw.advance(0.1); fw.poll(now=0.1), fw.execute("PP", now=0.1)   # on its way
    (None, '* Current Pan position is 110')
    >>> fw.advance(5.0); fw.poll(now=5.0), fw.execute("PP", now=5.0)
    ('*', '* Current Pan position is 500')
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable
from dataclasses import dataclass, field

from wander_env.ptu.axis import AxisState, axis_step, stopping_distance
from wander_env.ptu.params import PTUParams
from wander_env.ptu.units import SpeedOutOfRange, round_position, step_counter, whole_speed

__all__ = ["DEFAULT_FIRMWARE", "HALTS", "RESET_REPLY", "PTUFirmware", "command_letters"]

# The FLIR firmware text of a reset's limit hits (tilt twice, pan twice) and its ``*``.
RESET_REPLY = "!T!T!P!P*"
# A PTU-D46's ``V`` answer (PTU-D46 User's Manual v2.14.0, §4.5.5), marked as emulated.
DEFAULT_FIRMWARE = (
    "Pan-Tilt Controller v2.14.0 (wander emulator), (C)2006 Directed Perception, Inc., "
    "All Rights Reserved"
)
#: The halts, which go through while an ``A`` waits (so a driver can always stop the unit).
HALTS = ("H", "HP", "HT")
_TOKEN = re.compile(r"([A-Z@_]+)([-+]?\d+)?(.*)", re.DOTALL)


def command_letters(cmd: str) -> str:
    """The letters of an upper-cased command (``"PP-500"`` → ``"PP"``); the whole text
    when it is no command.

    >>> command_letters("PP-500"), command_letters("TS"), command_letters("#?")
    ('PP', 'TS', '#?')
    """
    m = _TOKEN.fullmatch(cmd)
    return m.group(1) if m else cmd


@dataclass
class _Axis:
    """Runtime state of one axis (positions, pos/s, pos/s²)."""

    name: str  # "Pan" / "Tilt", as in the firmware's verbose text
    resolution_arcsec: float
    min_pos: int
    max_pos: int
    speed: float
    accel: float
    base: float
    upper: float
    lower: float
    state: AxisState = field(default_factory=AxisState)
    target: float = 0.0
    pending: float | None = None  # slaved mode: executed by the next ``A``

    @property
    def reported(self) -> int:
        """The step counter (``PP``): whole steps taken so far.

        While moving the counter trails the continuous position, so it equals the
        target only once the axis has arrived.
        """
        return step_counter(self.state.position, self.state.velocity)

    @property
    def moving(self) -> bool:
        return self.state.velocity != 0.0 or self.state.position != self.target

    def advance(self, dt_s: float) -> None:
        if dt_s > 0 and self.moving:
            vmax = self.speed
            self.state = axis_step(
                self.state, self.target, dt_s, vmax, self.accel, min(self.base, vmax)
            )

    def stop_point(self) -> float:
        """The whole position where the axis can come to rest, braking from now."""
        p, v = self.state.position, self.state.velocity
        if v == 0.0:
            return float(round_position(p))
        d = stopping_distance(v, self.accel, min(self.base, self.speed))
        stop = p + math.copysign(d, v)
        whole = math.ceil(stop - 1e-9) if v > 0 else math.floor(stop + 1e-9)
        return float(min(max(whole, self.min_pos), self.max_pos))


def _axes_from(ptu: PTUParams) -> dict[str, _Axis]:
    axes = {}
    for letter, axis in (("P", "pan"), ("T", "tilt")):
        axes[letter] = _Axis(
            name=axis.capitalize(),
            resolution_arcsec=getattr(ptu, f"{axis}_resolution_arcsec"),
            min_pos=getattr(ptu, f"{axis}_min_pos"),
            max_pos=getattr(ptu, f"{axis}_max_pos"),
            speed=getattr(ptu, f"{axis}_speed"),
            accel=getattr(ptu, f"{axis}_accel"),
            base=getattr(ptu, f"{axis}_base_speed"),
            upper=getattr(ptu, f"{axis}_upper_speed"),
            lower=getattr(ptu, f"{axis}_lower_speed"),
        )
    return axes


def _fmt(value: float) -> str:
    """A number as the firmware prints it: integers bare, fractions to 4-6 places."""
    if float(value).is_integer():
        return str(int(value))
    return f"{value:.6f}".rstrip("0").rstrip(".")


class PTUFirmware:
    """The unit's controller: two axes and the modes, answering commands.

    ``ptu`` gives the axes' resolution (``PR``/``TR``), limits (``PN``/``PX``/``TN``/
    ``TX``), speeds (``PS``), accelerations (``PA``), base (``PB``), upper (``PU``) and
    lower (``PL``) speeds; ``firmware`` the ``V`` answer;
    ``reset_s`` how long ``R`` takes; ``echo`` and ``verbose`` the power-up modes;
    ``now`` the time the axes start at rest at home.

    The mode flags are plain attributes (the commands set them): ``echo`` (``EE``/
    ``ED``), ``verbose`` (``FV``/``FT``), ``slaved`` (``S``/``I``), ``velocity_mode``
    (``CV``/``CI``), ``limits_enabled`` (``LE``/``LD``). ``axes`` maps ``"P"`` and ``"T"``
    to the axes' state.
    """

    def __init__(
        self,
        ptu: PTUParams,
        firmware: str = DEFAULT_FIRMWARE,
        reset_s: float = 0.05,
        *,
        echo: bool = True,
        verbose: bool = True,
        now: float,
    ) -> None:
        self.ptu = ptu
        self.firmware, self.reset_s = firmware, reset_s
        self.axes = _axes_from(ptu)
        self.echo, self.verbose = echo, verbose
        self.slaved = False
        self.velocity_mode = False
        self.limits_enabled = True
        self._t = now
        self._now = now  # the time of the command being executed
        self._pending: Callable[[float], str | None] | None = None

    # -- time ---------------------------------------------------------------------------

    def advance(self, now: float) -> None:
        """Move the axes on to ``now``."""
        dt, self._t = now - self._t, now
        for axis in self.axes.values():
            axis.advance(dt)

    @property
    def moving(self) -> bool:
        """True until both axes rest on their targets."""
        return any(a.moving for a in self.axes.values())

    @property
    def waiting(self) -> bool:
        """True while an ``A`` or ``R`` holds its answer (:meth:`poll`)."""
        return self._pending is not None

    def poll(self, now: float) -> str | None:
        """The held answer of an ``A`` (the axes stopped) or ``R`` (the reset done) once it
        is due at ``now``, which ends the wait; None while it is not (or none is held).
        The axes are where the last :meth:`advance` left them."""
        if self._pending is None:
            return None
        reply = self._pending(now)
        if reply is not None:
            self._pending = None
        return reply

    # -- commands -----------------------------------------------------------------------

    def execute(self, cmd: str, now: float) -> str | None:
        """The reply to the upper-cased command ``cmd`` (without its line end) at ``now``;
        None for ``A`` and ``R``, whose answer :meth:`poll` gives."""
        self._now = now
        m = _TOKEN.fullmatch(cmd)
        if m is None:
            # Message from the PTU-D48E's own documentation of its replies
            # (Panthyr/panthyr_flir_ptu_d48e, d48e_connections.py).
            return "! Illegal Command Entered"
        name, number, rest = m.group(1), m.group(2), m.group(3)
        arg = int(number) if number is not None else None
        if name[0] in "PT" and name[1:] in _AXIS_COMMANDS:
            handler = _AXIS_COMMANDS[name[1:]]
            if rest:
                return "! Illegal argument"
            return handler(self, self.axes[name[0]], arg)
        handler0 = _UNIT_COMMANDS.get(name)
        if handler0 is None:
            return "! Illegal Command Entered"
        if rest or arg is not None:
            return "! Illegal argument"
        return handler0(self, arg)

    def query(self, value: float, text: str) -> str:
        """A query's answer: ``* <text>`` (verbose) or ``* <value>`` (terse)."""
        return f"* {text}" if self.verbose else f"* {_fmt(value)}"

    def halt(self, letters: str) -> str:
        """``H``/``HP``/``HT``: brake the axes ``letters`` to a stop on the nearest
        reachable whole position."""
        self.advance(self._now)
        for letter in letters:
            ax = self.axes[letter]
            ax.target, ax.pending = ax.stop_point(), None
        return "*"

    # axis commands: handler(self, axis, arg) -> reply

    def _position(self, ax: _Axis, arg: int | None) -> str:
        if arg is None:
            return self.query(ax.reported, f"Current {ax.name} position is {ax.reported}")
        return self._set_target(ax, float(arg))

    def _offset(self, ax: _Axis, arg: int | None) -> str:
        if arg is None:
            # PTU-D46 manual §4.3.2: the bare ``PO`` queries the desired position; the
            # verbose text is Miro's DpPanTilt table ("Target Pan position is ").
            desired = ax.pending if ax.pending is not None else ax.target
            return self.query(desired, f"Target {ax.name} position is {_fmt(desired)}")
        return self._set_target(ax, float(ax.reported + arg))

    def _set_target(self, ax: _Axis, pos: float) -> str:
        if self.limits_enabled and pos > ax.max_pos:
            return f"! Maximum allowable {ax.name} position is {ax.max_pos}"
        if self.limits_enabled and pos < ax.min_pos:
            return f"! Minimum allowable {ax.name} position is {ax.min_pos}"
        if self.velocity_mode:
            self.velocity_mode = False  # a position command returns to position control
        if self.slaved:
            ax.pending = pos
        else:
            ax.target = pos
        return "*"

    def _resolution(self, ax: _Axis, arg: int | None) -> str:
        if arg is not None:
            return "! Illegal argument"
        r = ax.resolution_arcsec
        return self.query(r, f"{_fmt(r)} seconds arc per position")

    def _speed(self, ax: _Axis, arg: int | None) -> str:
        if arg is None:
            return self.query(ax.speed, f"Target {ax.name} speed is {_fmt(ax.speed)} positions/sec")
        if self.velocity_mode:  # pure velocity: a signed speed drives the axis
            if arg == 0:
                ax.target = ax.stop_point()
                return "*"
            return self._set_speed(ax, abs(arg), ax.max_pos if arg > 0 else ax.min_pos)
        return self._set_speed(ax, arg)

    def _set_speed(self, ax: _Axis, speed: int, target: int | None = None) -> str:
        """Set the axis's speed (and, in pure velocity mode, its ``target``) if the
        bounds allow it (:func:`~wander_env.ptu.units.whole_speed`, the simulator's and
        the driver's rule); else the firmware's refusal."""
        try:
            ax.speed = float(whole_speed(ax.name.lower(), speed, ax.lower, ax.upper))
        except SpeedOutOfRange as err:
            # "PS3300 ! Pan speed cannot exceed 2902 positions/sec" (PTU-D46 manual §4.4.6);
            # the lower-bound text mirrors it (an assumption: no source shows it).
            bound = "exceed" if err.above else "be less than"
            return f"! {ax.name} speed cannot {bound} {_fmt(err.limit)} positions/sec"
        if target is not None:
            ax.target = float(target)
        return "*"

    def _delta(self, ax: _Axis, arg: int | None) -> str:
        # E series: ``PD`` queries the current (signed) speed, ``PD<n>`` offsets the speed.
        if arg is None:
            v = round_position(ax.state.velocity)
            return self.query(v, f"Current {ax.name} speed is {v} positions/sec")
        return self._speed(ax, round_position(ax.speed) + arg)

    # unit commands: handler(self, arg) -> reply

    def _await(self, arg: int | None) -> str | None:
        if self.slaved:
            for ax in self.axes.values():
                if ax.pending is not None:
                    ax.target, ax.pending = ax.pending, None
        self._pending = lambda now: None if self.moving else "*"
        return None

    def _reset(self, arg: int | None) -> None:
        done = self._now + self.reset_s
        for ax in self.axes.values():
            ax.target, ax.pending = ax.stop_point(), None

        def finished(now: float) -> str | None:
            if now < done:
                return None
            for ax in self.axes.values():  # recalibrated, back home
                ax.state, ax.target = AxisState(), 0.0
            return RESET_REPLY

        self._pending = finished

    def _independent(self, arg: int | None) -> str:
        if self.velocity_mode:
            for ax in self.axes.values():
                ax.target = ax.stop_point()
        self.velocity_mode = False
        return "*"

    def _version(self, arg: int | None) -> str:
        return f"* {self.firmware}"

    def _defaults(self, arg: int | None) -> str:
        return "*"

    def _factory(self, arg: int | None) -> str:
        fresh = _axes_from(self.ptu)
        for letter, ax in self.axes.items():
            for name in ("speed", "accel", "base", "upper", "lower"):
                setattr(ax, name, getattr(fresh[letter], name))
        return "*"


def _limit_handler(which: str) -> Callable[[PTUFirmware, _Axis, int | None], str]:
    """``PN``/``PX``/``TN``/``TX``: the position bounds (queries only)."""

    def handler(fw: PTUFirmware, ax: _Axis, arg: int | None) -> str:
        if arg is not None:
            return "! Illegal argument"
        value = ax.min_pos if which == "Minimum" else ax.max_pos
        return fw.query(value, f"{which} {ax.name} position is {value}")

    return handler


def _setting_handler(
    attr: str,
    text: str,
    valid: Callable[[_Axis, int], bool],
    then: Callable[[_Axis], None] | None = None,
) -> Callable[[PTUFirmware, _Axis, int | None], str]:
    """``PA``/``PB``/``PU``/``PL`` (and ``T…``): the bare command queries the axis setting
    ``attr`` (verbose ``text``, with ``{name}`` and ``{value}``); with an argument that
    passes ``valid`` it sets it (``then`` adjusts the others), else ``! Illegal argument``."""

    def handler(fw: PTUFirmware, ax: _Axis, arg: int | None) -> str:
        value = getattr(ax, attr)
        if arg is None:
            return fw.query(value, text.format(name=ax.name, value=_fmt(value)))
        if not valid(ax, arg):
            return "! Illegal argument"
        setattr(ax, attr, float(arg))
        if then is not None:
            then(ax)
        return "*"

    return handler


def _under_upper(ax: _Axis) -> None:
    """A new maximum speed caps the speed and the base speed."""
    ax.speed = min(ax.speed, ax.upper)
    ax.base = min(ax.base, ax.upper)


def _over_lower(ax: _Axis) -> None:
    """A new minimum speed raises the speed to it."""
    ax.speed = max(ax.speed, ax.lower)


def _halt_handler(letters: str) -> Callable[[PTUFirmware, int | None], str]:
    """``H``/``HP``/``HT``: :meth:`PTUFirmware.halt` the axes ``letters``."""

    def handler(fw: PTUFirmware, arg: int | None) -> str:
        return fw.halt(letters)

    return handler


def _mode_setter(flag: str, value: bool) -> Callable[[PTUFirmware, int | None], str]:
    """A unit command that sets the mode flag attribute ``flag`` (``EE``, ``FT``, ``LD``...)."""

    def handler(fw: PTUFirmware, arg: int | None) -> str:
        setattr(fw, flag, value)
        return "*"

    return handler


def _mode_query(flag: str, on: str, off: str) -> Callable[[PTUFirmware, int | None], str]:
    """A unit command that reports the mode flag attribute ``flag`` (``E``, ``F``, ``C``, ``L``)."""

    def handler(fw: PTUFirmware, arg: int | None) -> str:
        return f"* {on if getattr(fw, flag) else off}"

    return handler


_AXIS_COMMANDS: dict[str, Callable[..., str]] = {
    "P": PTUFirmware._position,
    "O": PTUFirmware._offset,
    "R": PTUFirmware._resolution,
    "N": _limit_handler("Minimum"),
    "X": _limit_handler("Maximum"),
    "S": PTUFirmware._speed,
    "D": PTUFirmware._delta,
    "A": _setting_handler(
        "accel", "{name} acceleration is {value} positions/sec^2", lambda ax, a: a > 0
    ),
    "B": _setting_handler(
        "base",
        "Current {name} base speed is {value} positions/sec",
        lambda ax, a: 0 <= a <= ax.upper,
    ),
    "U": _setting_handler(
        "upper",
        "Maximum {name} speed is {value} positions/sec",
        lambda ax, a: a >= max(ax.lower, 1.0),
        _under_upper,
    ),
    "L": _setting_handler(
        "lower",
        "Minimum {name} speed is {value} positions/sec",
        lambda ax, a: 0 <= a <= ax.upper,
        _over_lower,
    ),
}

_UNIT_COMMANDS: dict[str, Callable[..., str | None]] = {
    "A": PTUFirmware._await,
    "H": _halt_handler("PT"),
    "HP": _halt_handler("P"),
    "HT": _halt_handler("T"),
    "I": _mode_setter("slaved", False),
    "S": _mode_setter("slaved", True),
    "R": PTUFirmware._reset,
    "E": _mode_query("echo", "Echoing ON", "Echoing OFF"),
    "EE": _mode_setter("echo", True),
    "ED": _mode_setter("echo", False),
    "F": _mode_query("verbose", "ASCII verbose mode", "ASCII terse mode"),
    "FT": _mode_setter("verbose", False),
    "FV": _mode_setter("verbose", True),
    "C": _mode_query(
        "velocity_mode", "Pure velocity speed control mode", "Independent speed control mode"
    ),
    "CI": PTUFirmware._independent,
    "CV": _mode_setter("velocity_mode", True),
    "L": _mode_query(
        "limits_enabled",
        "Limit bounds are ENABLED (soft limits enabled)",
        "Limit bounds are DISABLED (hard limits only: use care)",
    ),
    "LE": _mode_setter("limits_enabled", True),
    "LD": _mode_setter("limits_enabled", False),
    "V": PTUFirmware._version,
    "DS": PTUFirmware._defaults,
    "DR": PTUFirmware._defaults,
    "DF": PTUFirmware._factory,
}
