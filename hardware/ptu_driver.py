"""Driver for a FLIR (Directed Perception) pan-tilt unit over its ASCII serial protocol.

:class:`FlirPTU` opens any pyserial URL (a device path, a pty path, ``socket://host:port``
for a PTU behind a serial-to-TCP bridge or an E-series unit's TCP port, ``loop://``),
flushes the power-up banner, sets terse feedback (``FT``), echo off (``ED``),
independent speed control (``CI``) and immediate execution (``I``), and *queries* the
resolution (``PR``/``TR``, arc-seconds per position) and the limits (``PN``/``PX``/
``TN``/``TX``, ``PL``/``PU``/``TL``/``TU``) from the unit; nothing about the unit is
hard-coded. Every public angle is in degrees; PTU positions stay inside this module.

Replies (FLIR manuals, §4.2 of the PTU-D46 manual; see ``hardware/PTU_PROTOCOL.md``):
``*`` success, ``* <value>`` a query's answer (``* <text>`` in verbose mode), ``! <message>``
an error, raised as :class:`PTUError` carrying the unit's message and the command.
Lines may end in CR LF, LF or CR; an echoed command before its reply (echo on) and the
asynchronous limit-hit markers ``!P``/``!T`` are stripped; other lines (banner) are
skipped. No reply in time raises :class:`PTUTimeout`.

Safe by construction: commands are serialised by a lock; moves outside the queried
limits raise ``ValueError`` before anything is sent; :meth:`FlirPTU.close` (also on
leaving a ``with`` block through an exception or ``KeyboardInterrupt``) halts the unit,
optionally returns it home, and is idempotent.

Example (against the emulator of :mod:`hardware.ptu_emulator`):
    >>> from hardware.ptu_emulator import PTUEmulator
    >>> with PTUEmulator() as emu, FlirPTU(emu.port, FlirPTUParams(banner_quiet_s=0.02)) as ptu:
    ...     pan, tilt = ptu.move_to(pan_deg=2.0, tilt_deg=-1.0)
    ...     ptu.await_motion()
    ...     round(ptu.pan_deg, 4) == round(pan, 4), emu.positions
    (True, (78, -39))
"""

from __future__ import annotations

import errno
import logging
import math
import re
import threading
import time
from dataclasses import dataclass
from typing import Any

import serial

from wander_env.closing import Closing
from wander_env.config import check_fields
from wander_env.config_messages import SHOWN_CHARS, shown

try:  # the serial layer's own errors: termios.error (EIO of an unplugged adapter) is no OSError
    import termios

    SERIAL_ERRORS: tuple[type[BaseException], ...] = (
        serial.SerialException,
        OSError,
        termios.error,
    )
except ImportError:  # pragma: no cover - not POSIX
    SERIAL_ERRORS = (serial.SerialException, OSError)
from wander_env.ptu.link import PTULinkParams, check_delimiter
from wander_env.ptu.units import (
    degrees_to_positions,
    positions_to_degrees,
    whole_position,
    whole_speed,
)

# A standalone number: not glued to a letter, ``^`` or ``.`` (so "sec^2" or "v2.14" don't count).
_NUMBER = re.compile(r"(?<![\w^.])[-+]?\d+(?:\.\d+)?(?![\w.])")
# Asynchronous limit hits ("!P", "!T"; a reset prints "!T!T!P!P*"). Errors are "! <msg>".
_LIMIT_HITS = re.compile(r"^(?:![PT])+")
_AXES = ("pan", "tilt")
# The longest reply line kept: the FLIR replies are tens of bytes; a unit (or a wrong baud
# rate) that floods bytes with no line end fails with :class:`PTUFlood` past this many.
MAX_LINE_BYTES = 4096


class PTUError(RuntimeError):
    """The unit answered ``! <message>`` (or the exchange failed); ``command`` is what was sent."""

    def __init__(self, message: str, command: str | None = None) -> None:
        self.message = message
        self.command = command
        super().__init__(f"{message} (command {command!r})" if command is not None else message)


class PTUTimeout(PTUError):
    """No (complete) reply within the timeout."""


class PTUPortError(PTUError):
    """The serial port could not be opened (missing, busy, no permission) or is closed."""


class PTUFlood(PTUError):
    """More than :data:`MAX_LINE_BYTES` bytes arrived with no line end (wrong baud rate,
    a unit babbling); the message quotes the last characters only."""


@dataclass(frozen=True)
class Reply:
    """One parsed reply line: ``ok`` for ``*``, else an ``!`` error; ``text`` after the mark."""

    ok: bool
    text: str


def parse_reply(line: str, command: str | None = None) -> Reply | None:
    """Parse one reply line; ``None`` for a line that is no reply (banner, bare echo).

    An echo of ``command`` at the start and limit-hit markers are removed first.

    >>> parse_reply("PP * Current Pan position is -500", "PP")
    Reply(ok=True, text='Current Pan position is -500')
    >>> parse_reply("! Maximum allowable Pan position is 3090")
    Reply(ok=False, text='Maximum allowable Pan position is 3090')
    >>> parse_reply("!T!T!P!P*"), parse_reply("Initializing...")
    (Reply(ok=True, text=''), None)
    """
    text = line.strip()
    if command and text.upper().startswith(command.upper()):
        text = text[len(command) :].lstrip()
    text = _LIMIT_HITS.sub("", text)
    if text.startswith("*"):
        return Reply(True, text[1:].strip())
    if text.startswith("!"):
        return Reply(False, text[1:].strip())
    return None


def reply_number(text: str, command: str | None = None) -> float:
    """The first standalone number of a query's answer (terse or verbose).

    >>> reply_number("92.5714 seconds arc per position"), reply_number("-3090")
    (92.5714, -3090.0)
    >>> reply_number("Pan acceleration is 2000 positions/sec^2")
    2000.0
    """
    m = _NUMBER.search(text)
    if m is None:
        raise PTUError(f"no number in the unit's answer {text!r}", command)
    return float(m.group())


def _tail(value: str | list[str]) -> str:
    """``value``'s end (of each line of a list), quoted in at most :data:`SHOWN_CHARS`
    characters.

    >>> _tail("x" * 5000 + "end") == repr("x" * 195 + "end")
    True
    >>> _tail(["a", "b"])
    "['a', 'b']"
    """
    if isinstance(value, str):
        return shown(value[2 - SHOWN_CHARS :])
    return shown([v[2 - SHOWN_CHARS :] for v in value])


class PTUProtocol:
    """Command/reply exchange over an open pyserial port; knows nothing of the unit's state.

    Not thread-safe by itself (:class:`FlirPTU` serialises it).

    >>> port = serial.serial_for_url("loop://", timeout=0.01)
    >>> proto = PTUProtocol(port)
    >>> proto.send("PP")                  # loop:// returns "PP " like an echoing unit...
    >>> _ = port.write(b"* 22\\r\\n")     # ...and this is the unit's answer
    >>> proto.read_reply("PP", timeout_s=0.5)
    '22'
    """

    def __init__(self, port: serial.SerialBase, delimiter: str = PTULinkParams.delimiter) -> None:
        check_delimiter(delimiter, "PTUProtocol delimiter")
        self.port = port
        self.delimiter = delimiter
        self.last_latency_s = float("nan")
        self._rx = bytearray()
        self._sent_at = time.monotonic()

    def send(self, command: str) -> None:
        """Write ``command`` and the delimiter."""
        if not command or any(c in command for c in " \r\n"):
            raise ValueError(f"a PTU command is one word, got {command!r}")
        self._sent_at = time.monotonic()
        self.port.write((command + self.delimiter).encode("ascii"))
        self.port.flush()

    def read_reply(self, command: str, timeout_s: float) -> str:
        """Read until ``command``'s reply; its text on ``*``, :class:`PTUError` on ``!``,
        :class:`PTUTimeout` after ``timeout_s``, :class:`PTUFlood` once more than
        :data:`MAX_LINE_BYTES` bytes arrive with no line end."""
        deadline = time.monotonic() + timeout_s
        skipped: list[str] = []
        while True:
            line = self._pop_line(command)
            if line is not None:
                reply = parse_reply(line, command)
                if reply is None:
                    logging.getLogger(__name__).debug("PTU: skipped %s", shown(line))
                    if line.strip():
                        skipped.append(line)
                    continue
                self.last_latency_s = time.monotonic() - self._sent_at
                if not reply.ok:
                    raise PTUError(reply.text, command)
                return reply.text
            if time.monotonic() >= deadline:
                pending = self._rx.decode("ascii", errors="replace")
                noise = f"; lines that are no reply: {_tail(skipped[-3:])}" if skipped else ""
                raise PTUTimeout(
                    f"no reply from the PTU within {timeout_s:.3g} s "
                    f"(received {_tail(pending)}{noise})",
                    command,
                )
            self._rx += self.port.read(max(1, self.port.in_waiting))

    def transact(self, command: str, timeout_s: float) -> str:
        """Discard stale input, send ``command`` and return its reply's text."""
        self.discard_input()
        self.send(command)
        return self.read_reply(command, timeout_s)

    def discard_input(self) -> None:
        """Drop unread input (stale replies after a timeout, asynchronous markers)."""
        self._rx.clear()
        self.port.reset_input_buffer()

    def drain(self, quiet_s: float, max_s: float) -> bytes:
        """Read and return whatever arrives until the line is quiet for ``quiet_s``."""
        got = bytearray(self._rx)
        self._rx.clear()
        start = last = time.monotonic()
        while True:
            now = time.monotonic()
            if now - last >= quiet_s or now - start >= max_s:
                return bytes(got)
            chunk = self.port.read(max(1, self.port.in_waiting))
            if chunk:
                got += chunk
                last = time.monotonic()

    def _pop_line(self, command: str | None = None) -> str | None:
        """The first whole line of the input (its end taken off), ``None`` if none has
        come yet; :class:`PTUFlood` (and the input dropped) when the line would be longer
        than :data:`MAX_LINE_BYTES`."""
        ends = [i for i in (self._rx.find(b"\n"), self._rx.find(b"\r")) if i >= 0]
        end = min(ends) if ends else None  # LF or CR: either ends a line (D46: CR alone)
        if end is None and len(self._rx) <= MAX_LINE_BYTES:
            return None
        if end is None or end > MAX_LINE_BYTES:
            flood = self._rx[: MAX_LINE_BYTES + 1].decode("ascii", errors="replace")
            self._rx.clear()
            raise PTUFlood(
                f"the PTU sent more than {MAX_LINE_BYTES} bytes without a line end "
                f"(wrong baud rate?), ending {_tail(flood)}",
                command,
            )
        line = self._rx[:end].decode("ascii", errors="replace")
        del self._rx[: end + 1]
        return line


@dataclass(frozen=True)
class FlirPTUParams:
    """Connection and safety parameters of :class:`FlirPTU`.

    ``timeout_s`` bounds each ordinary reply, ``await_timeout_s`` an ``A`` (motion),
    ``reset_timeout_s`` an ``R``, ``halt_timeout_s`` the halt sent on close. The
    power-up banner is drained until the line is quiet for ``banner_quiet_s`` (at most
    ``banner_timeout_s``). ``exclusive`` locks a device port against other processes;
    ``home_on_close`` returns the unit to (0°, 0°) after the halt on close.
    ``read_poll_s`` is the serial read granularity; ``delimiter`` ends each command
    (a space, CR or LF).
    ``write_timeout_s`` bounds each write (a stuck link: flow control, a hung adapter):
    past it the command fails with :class:`PTUPortError`, the device-fault path.
    """

    baudrate: int = PTULinkParams.baudrate
    timeout_s: float = 1.0
    await_timeout_s: float = 60.0
    reset_timeout_s: float = 120.0
    halt_timeout_s: float = 0.5
    banner_quiet_s: float = 0.2
    banner_timeout_s: float = 3.0
    exclusive: bool = True
    home_on_close: bool = False
    read_poll_s: float = 0.01
    delimiter: str = PTULinkParams.delimiter
    write_timeout_s: float = 1.0

    def __post_init__(self) -> None:
        timeouts = (
            "timeout_s",
            "await_timeout_s",
            "reset_timeout_s",
            "halt_timeout_s",
            "banner_timeout_s",
            "read_poll_s",
            "write_timeout_s",
        )
        check_fields(self, timeouts, positive=True)
        check_fields(self, ("banner_quiet_s",), minimum=0)
        check_delimiter(self.delimiter, "FlirPTUParams.delimiter")


def open_port(url: str, params: FlirPTUParams | None = None) -> serial.SerialBase:
    """Open ``url`` with pyserial (8N1, ``params.baudrate``); :class:`PTUPortError` naming it.

    >>> open_port("/dev/no-such-ptu")  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    hardware.ptu_driver.PTUPortError: PTU port '/dev/no-such-ptu' does not exist ...
    """
    p = params if params is not None else FlirPTUParams()
    kwargs: dict[str, Any] = {
        "baudrate": p.baudrate,
        "timeout": p.read_poll_s,
        "write_timeout": p.write_timeout_s,
    }
    if "://" not in url:  # a device path: lock it (flock) so no other process talks to the unit
        kwargs["exclusive"] = p.exclusive
    try:
        return serial.serial_for_url(url, **kwargs)
    except serial.SerialException as exc:
        code = exc.errno if isinstance(exc.errno, int) else None
        if "exclusively lock" in str(exc) or code in (errno.EAGAIN, errno.EWOULDBLOCK):
            why = "is busy: another process holds it open exclusively"
        elif code == errno.ENOENT:
            why = "does not exist (is the PTU's USB-serial adapter plugged in?)"
        elif code in (errno.EACCES, errno.EPERM):
            why = "is not accessible (permission denied: is the user in the 'dialout' group?)"
        elif code == errno.EBUSY:
            why = "is busy"
        else:
            why = "could not be opened"
        raise PTUPortError(f"PTU port {url!r} {why} ({exc})") from exc
    except ValueError as exc:  # unknown URL scheme
        raise PTUPortError(f"PTU port {url!r} could not be opened ({exc})") from exc


class FlirPTU(Closing):
    """A FLIR PTU on a serial port; angles in degrees, speeds in °/s, accelerations in °/s².

    Opening initialises the unit (terse, no echo, independent speed control, immediate
    execution) and queries resolution and limits. Use it as a context manager; on exit
    (normal, exception or ``KeyboardInterrupt``) the unit is halted.
    """

    def __init__(self, url: str, params: FlirPTUParams | None = None) -> None:
        self.url = url
        self.params = params if params is not None else FlirPTUParams()
        self._lock = threading.RLock()
        self._closed = True
        self._port = open_port(url, self.params)
        self._closed = False
        self._proto = PTUProtocol(self._port, self.params.delimiter)
        try:
            self._initialise()
        except SERIAL_ERRORS as exc:
            self._close_port()
            raise PTUPortError(f"PTU port {url!r} failed while opening: {exc!r}") from exc
        except BaseException:
            self._close_port()
            raise

    # -- set-up -----------------------------------------------------------------------

    def _initialise(self) -> None:
        banner = self._proto.drain(self.params.banner_quiet_s, self.params.banner_timeout_s)
        if banner:
            logging.getLogger(__name__).info("PTU banner: %r", banner.decode("ascii", "replace"))
        self._proto.discard_input()
        for command in ("FT", "ED", "CI", "I"):
            self._command(command)
        self._query_unit()

    def _query_unit(self) -> None:
        """Resolution, position limits and speed bounds, as the unit reports them."""
        res = {axis: self._number(f"{axis[0].upper()}R") for axis in _AXES}
        if not all(r > 0 for r in res.values()):
            raise PTUError(f"the unit reported a non-positive resolution {res}")
        self._res_arcsec = res
        self._limits_pos = {
            axis: (
                int(self._number(f"{axis[0].upper()}N")),
                int(self._number(f"{axis[0].upper()}X")),
            )
            for axis in _AXES
        }
        self._speed_bounds_pos: dict[str, tuple[float, float] | None] = {}
        for axis in _AXES:
            a = axis[0].upper()
            try:
                self._speed_bounds_pos[axis] = (self._number(f"{a}L"), self._number(f"{a}U"))
            except PTUTimeout:
                raise
            except PTUError:  # a unit without speed-bound queries: the unit checks alone
                self._speed_bounds_pos[axis] = None

    # -- low level --------------------------------------------------------------------

    def send(self, command: str, timeout_s: float | None = None) -> str:
        """Send one raw command (``"PP"``, ``"PS1000"``) and return the reply's text.

        Raises :class:`PTUError` on ``!`` and :class:`PTUTimeout` without a reply.
        Raw commands bypass the limit checks and the degree conversions.
        """
        return self._command(command.strip().upper(), timeout_s)

    def _command(self, command: str, timeout_s: float | None = None) -> str:
        with self._lock:
            if self._closed:
                raise PTUPortError(f"PTU port {self.url!r} is closed", command)
            try:
                return self._proto.transact(command, timeout_s or self.params.timeout_s)
            except serial.SerialTimeoutException as exc:  # the write did not go out in time
                raise PTUPortError(
                    f"PTU port {self.url!r} failed: writing {command!r} timed out after "
                    f"{self.params.write_timeout_s:g} s (the serial link is stuck: flow "
                    f"control, a hung adapter) ({exc!r})",
                    command,
                ) from exc
            except SERIAL_ERRORS as exc:  # unplugged, hung up, I/O error: a device failure
                raise PTUPortError(f"PTU port {self.url!r} failed: {exc!r}", command) from exc

    def _number(self, command: str) -> float:
        return reply_number(self._command(command), command)

    @property
    def last_latency_s(self) -> float:
        """Seconds from writing the last command to parsing its reply (NaN before any)."""
        return self._proto.last_latency_s

    @property
    def is_open(self) -> bool:
        """True until :meth:`close`."""
        return not self._closed

    # -- unit geometry (queried at start) -----------------------------------------------

    @property
    def resolution_arcsec(self) -> tuple[float, float]:
        """(pan, tilt) arc-seconds per position, from ``PR``/``TR``."""
        return self._res_arcsec["pan"], self._res_arcsec["tilt"]

    @property
    def deg_per_position(self) -> tuple[float, float]:
        """(pan, tilt) degrees per position."""
        return self._deg(1, "pan"), self._deg(1, "tilt")

    @property
    def pan_limits_deg(self) -> tuple[float, float]:
        """(min, max) pan in degrees, from ``PN``/``PX``."""
        lo, hi = self._limits_pos["pan"]
        return self._deg(lo, "pan"), self._deg(hi, "pan")

    @property
    def tilt_limits_deg(self) -> tuple[float, float]:
        """(min, max) tilt in degrees, from ``TN``/``TX``."""
        lo, hi = self._limits_pos["tilt"]
        return self._deg(lo, "tilt"), self._deg(hi, "tilt")

    @property
    def speed_bounds_deg_s(self) -> tuple[tuple[float, float] | None, tuple[float, float] | None]:
        """(pan, tilt) (lower, upper) speed bounds in °/s (``PL``/``PU``), None if unknown."""
        out = []
        for axis in _AXES:
            b = self._speed_bounds_pos[axis]
            out.append(None if b is None else (self._deg(b[0], axis), self._deg(b[1], axis)))
        return out[0], out[1]

    def _deg(self, pos: float, axis: str) -> float:
        return positions_to_degrees(pos, self._res_arcsec[axis])

    def _pos(self, deg: float, axis: str) -> int:
        return whole_position(axis, deg, self._res_arcsec[axis])

    def _check_position(self, pos: int, axis: str, what: str) -> None:
        lo, hi = self._limits_pos[axis]
        if not lo <= pos <= hi:
            lo_d, hi_d = self._deg(lo, axis), self._deg(hi, axis)
            raise ValueError(
                f"{axis} {what} {self._deg(pos, axis):.4f}° ({pos} positions) is outside the "
                f"unit's limits {lo_d:.4f}°…{hi_d:.4f}° ({lo}…{hi}); nothing was sent"
            )

    # -- motion -----------------------------------------------------------------------

    def move_to(
        self, pan_deg: float | None = None, tilt_deg: float | None = None
    ) -> tuple[float | None, float | None]:
        """Command absolute angles (``PP``/``TP``) and return once the unit acknowledged.

        Does not wait for the motion (see :meth:`await_motion`, :meth:`moving`); ``None``
        leaves an axis alone. Returns the commanded angles, on whole positions.
        Raises ``ValueError`` (nothing sent) when a target is outside the limits.
        """
        targets = {}
        for axis, deg in (("pan", pan_deg), ("tilt", tilt_deg)):
            if deg is not None:
                targets[axis] = self._pos(deg, axis)
                self._check_position(targets[axis], axis, "target")
        with self._lock:
            for axis, pos in targets.items():
                self._command(f"{axis[0].upper()}P{pos}")
        pan = self._deg(targets["pan"], "pan") if "pan" in targets else None
        tilt = self._deg(targets["tilt"], "tilt") if "tilt" in targets else None
        return pan, tilt

    def move_by(self, pan_deg: float = 0.0, tilt_deg: float = 0.0) -> tuple[float, float]:
        """Command a relative move from the current position (``PO``/``TO``), without waiting.

        The resulting targets are checked against the limits first (from a ``PP``/``TP``
        query; the unit checks again). Returns the offsets sent, on whole positions.
        """
        offsets = {"pan": self._pos(pan_deg, "pan"), "tilt": self._pos(tilt_deg, "tilt")}
        with self._lock:
            current = self._positions()
            for axis, off in offsets.items():
                if off:
                    self._check_position(current[axis] + off, axis, "target")
            for axis, off in offsets.items():
                if off:
                    self._command(f"{axis[0].upper()}O{off}")
        return self._deg(offsets["pan"], "pan"), self._deg(offsets["tilt"], "tilt")

    def goto(self, pan_deg: float | None = None, tilt_deg: float | None = None) -> None:
        """:meth:`move_to`, then :meth:`await_motion`."""
        with self._lock:
            self.move_to(pan_deg, tilt_deg)
            self.await_motion()

    def await_motion(self, timeout_s: float | None = None) -> None:
        """Block until both axes have stopped (``A``; in slaved mode it starts the move).

        If the motion outlasts ``timeout_s`` (default ``params.await_timeout_s``) the unit
        is halted (``H``), the pending replies are collected so the exchange stays in
        step, and :class:`PTUTimeout` is raised. To wait without blocking, poll
        :meth:`moving`.
        """
        with self._lock:
            try:
                self._command("A", timeout_s or self.params.await_timeout_s)
            except PTUTimeout:
                self._halt_after_await()
                raise

    def _halt_after_await(self) -> None:
        """After an ``A`` timed out: halt, then read the ``*`` of both ``H`` and ``A``."""
        try:
            self._proto.send("H")
            for command in ("H", "A"):
                self._proto.read_reply(command, self.params.timeout_s)
        except (PTUError, *SERIAL_ERRORS) as exc:  # the next command discards stale input
            logging.getLogger(__name__).warning("PTU %s: halt after await: %s", self.url, exc)

    def halt(self, axis: str | None = None) -> None:
        """Stop both axes, decelerating (``H``), or one: ``"pan"`` (``HP``), ``"tilt"`` (``HT``)."""
        if axis is None:
            self._command("H")
        elif axis in _AXES:
            self._command(f"H{axis[0].upper()}")
        else:
            raise ValueError(f"axis must be 'pan', 'tilt' or None, got {axis!r}")

    def home(self) -> None:
        """Move to (0°, 0°) and wait."""
        self.goto(0.0, 0.0)

    def reset(self) -> None:
        """Recalibrate the axes (``R``: the unit finds its limits, returns home); re-query them."""
        with self._lock:
            self._command("R", self.params.reset_timeout_s)
            self._query_unit()

    def moving(self) -> bool:
        """True while either axis is away from its desired position (``PP`` vs ``PO`` query)."""
        with self._lock:
            current = self._positions()
            desired = {a: int(self._number(f"{a[0].upper()}O")) for a in _AXES}
        return current != desired

    # -- state ------------------------------------------------------------------------

    def _positions(self) -> dict[str, int]:
        return {a: int(self._number(f"{a[0].upper()}P")) for a in _AXES}

    @property
    def pan_deg(self) -> float:
        """Current pan angle (``PP``), degrees."""
        return self._deg(self._number("PP"), "pan")

    @property
    def tilt_deg(self) -> float:
        """Current tilt angle (``TP``), degrees."""
        return self._deg(self._number("TP"), "tilt")

    def position(self) -> tuple[float, float]:
        """Current (pan, tilt) in degrees."""
        with self._lock:
            p = self._positions()
        return self._deg(p["pan"], "pan"), self._deg(p["tilt"], "tilt")

    def target(self) -> tuple[float, float]:
        """Desired (pan, tilt) in degrees (``PO``/``TO`` queries)."""
        with self._lock:
            return self._deg(self._number("PO"), "pan"), self._deg(self._number("TO"), "tilt")

    # -- speed and acceleration -------------------------------------------------------------

    def set_speed(self, pan_deg_s: float | None = None, tilt_deg_s: float | None = None) -> None:
        """Set the slew speeds (``PS``/``TS``, on the fly): whole positions/s within the
        unit's ``PL``/``PU`` (:func:`~wander_env.ptu.units.whole_speed`, the simulator's
        rule); a speed outside raises ``ValueError`` and nothing is sent."""
        values = {}
        for axis, value in (("pan", pan_deg_s), ("tilt", tilt_deg_s)):
            if value is None:
                continue
            # A unit without PL/PU queries checks alone; whole_speed keeps the floor of 1.
            lower, upper = self._speed_bounds_pos[axis] or (0.0, math.inf)
            pos_s = degrees_to_positions(value, self._res_arcsec[axis])
            values[axis] = whole_speed(axis, pos_s, lower, upper)
        with self._lock:
            for axis, v in values.items():
                self._command(f"{axis[0].upper()}S{v}")

    def set_acceleration(
        self, pan_deg_s2: float | None = None, tilt_deg_s2: float | None = None
    ) -> None:
        """Set the accelerations (``PA``/``TA``), whole positions/s², at least one; the
        FLIR manual asks for axes at rest."""
        values = {}
        for axis, value in (("pan", pan_deg_s2), ("tilt", tilt_deg_s2)):
            if value is None:
                continue
            values[axis] = self._pos(value, axis)
            if values[axis] < 1:
                raise ValueError(
                    f"{axis} acceleration must be at least one position/s², got {value!r}"
                )
        with self._lock:
            for axis, v in values.items():
                self._command(f"{axis[0].upper()}A{v}")

    def speed(self) -> tuple[float, float]:
        """(pan, tilt) commanded speeds (``PS``/``TS``), °/s."""
        with self._lock:
            return self._deg(self._number("PS"), "pan"), self._deg(self._number("TS"), "tilt")

    def acceleration(self) -> tuple[float, float]:
        """(pan, tilt) accelerations (``PA``/``TA``), °/s²."""
        with self._lock:
            return self._deg(self._number("PA"), "pan"), self._deg(self._number("TA"), "tilt")

    def base_speed(self) -> tuple[float, float]:
        """(pan, tilt) base (start-up) speeds (``PB``/``TB``), °/s."""
        with self._lock:
            return self._deg(self._number("PB"), "pan"), self._deg(self._number("TB"), "tilt")

    # -- life cycle -------------------------------------------------------------------

    def close(self) -> None:
        """Halt the unit (and home it with ``home_on_close``), then close the port.

        Never raises for an unresponsive unit (it logs); safe to call twice. Waits for
        a command in progress in another thread (the lock) before halting.
        """
        log = logging.getLogger(__name__)
        with self._lock:
            if self._closed:
                return
            try:
                try:
                    self._command("H", self.params.halt_timeout_s)
                except (PTUError, OSError) as exc:
                    log.warning("PTU %s: halt on close failed: %s", self.url, exc)
                else:
                    if self.params.home_on_close:
                        try:
                            self.home()
                        except (PTUError, OSError) as exc:
                            log.warning("PTU %s: return home on close failed: %s", self.url, exc)
            finally:
                self._close_port()

    def _close_port(self) -> None:
        """Close the serial port; a port that already failed is logged, not raised."""
        self._closed = True
        try:
            self._port.close()
        except SERIAL_ERRORS as exc:
            logging.getLogger(__name__).warning("PTU %s: closing the port: %r", self.url, exc)

    def __repr__(self) -> str:
        state = "open" if self.is_open else "closed"
        return f"FlirPTU({self.url!r}, {state})"
