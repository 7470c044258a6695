"""A protocol-exact FLIR pan-tilt unit (PTU-D46/E46/D48E) emulator on a pseudo-terminal.

The emulator speaks the FLIR ASCII protocol on the master side of a pty; its
:attr:`PTUEmulator.port` is the slave device path, which a real ``serial.Serial(port)``
(or :func:`serial.serial_for_url`) opens like a USB-serial adapter. A background
thread reads commands, answers them and moves the axes in real time with the motion
maths of :mod:`wander_env.ptu` (:func:`~wander_env.ptu.axis.axis_step`: trapezoidal
profile, base speed, on-the-fly target and speed changes).

Protocol, as the FLIR manuals and public drivers describe it (sources in
``hardware/PTU_PROTOCOL.md``):

- a command is letters plus an optional signed integer (``PP-500``), ended by a space,
  CR or LF; case does not matter; the bare letters are a query (``PP `` → position);
- success is ``*``, a query answers ``* <value>`` (terse, ``FT``) or ``* <text>``
  (verbose, ``FV``: ``* Current Pan position is -500``), a failure ``! <message>``
  (``! Maximum allowable Pan position is 3090``); replies end with CR LF;
- with echo on (``EE``, the power-up default) the command is echoed before its
  reply, on the same line (``PP * 22``);
- the unit prints a banner at power up; ``R`` (reset) answers ``!T!T!P!P*`` once the
  axes have recalibrated (each ``!T``/``!P`` is a limit hit during the reset).

``A`` answers only when the axes have stopped; commands that arrive meanwhile are
kept, in order, for after it, except the halts ``H``/``HP``/``HT``, which the
emulator lets through (so a driver can always stop the unit). In slaved mode (``S``)
position commands are stored and executed by the next ``A``.

Examples:
    >>> import serial
    >>> quiet = PTUEmulatorParams(banner="")  # no power-up banner to read past
    >>> with PTUEmulator(quiet) as emu, serial.Serial(emu.port, timeout=1) as port:
    ...     _ = port.write(b"ED FT PR ")
    ...     for _ in range(3):
    ...         line = port.readline()
    ...     line
    b'* 92.5714\\r\\n'
"""

from __future__ import annotations

import math
import os
import re
import select
import threading
import time
import tty
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from wander_env.ptu.axis import AxisState, axis_step, stopping_distance
from wander_env.ptu.params import PTUParams
from wander_env.ptu.units import round_position, step_counter

# The FLIR firmware text of a reset's limit hits (tilt twice, pan twice) and its ``*``.
RESET_REPLY = "!T!T!P!P*"
# A PTU-D46's ``V`` answer (PTU-D46 User's Manual v2.14.0, §4.5.5), marked as emulated.
DEFAULT_FIRMWARE = (
    "Pan-Tilt Controller v2.14.0 (wander emulator), (C)2006 Directed Perception, Inc., "
    "All Rights Reserved"
)
_DELIMITERS = " \r\n"
_HALTS = ("H", "HP", "HT")
_TOKEN = re.compile(r"([A-Z@_]+)([-+]?\d+)?(.*)", re.DOTALL)


@dataclass(frozen=True)
class PTUEmulatorParams:
    """Parameters of the emulated unit.

    ``ptu`` (the unit's :class:`~wander_env.ptu.params.PTUParams`) holds resolution
    (``PR``/``TR``), limits (``PN``/``PX``/``TN``/``TX``), speeds (``PS``), accelerations
    (``PA``), base (``PB``) and upper (``PU``) speeds;
    ``lower_speed`` is ``PL``/``TL`` (pos/s). ``echo`` and ``verbose`` are the power-up
    modes (on, as a factory unit). ``banner`` (``None``: the firmware line and
    ``Initializing...``) is printed ``banner_delay_s`` after start. ``eol`` ends every
    reply. ``reset_s`` is how long ``R`` takes. ``silent_after``: stop answering after
    that many commands (fault injection for timeouts). ``poll_s`` is the thread's poll
    period while a reply waits on motion. ``baudrate`` (``None``: instant, as a pty is)
    paces the line as a UART at that rate would: each byte in either direction takes
    ``bits_per_byte / baudrate`` seconds (8N1: 10 bits), a command is executed once its
    last byte has arrived, and a reply is readable once its last byte has been sent.
    """

    ptu: PTUParams = field(default_factory=PTUParams)
    lower_speed: float = 31.0
    firmware: str = DEFAULT_FIRMWARE
    banner: str | None = None
    banner_delay_s: float = 0.0
    echo: bool = True
    verbose: bool = True
    eol: str = "\r\n"
    reset_s: float = 0.05
    silent_after: int | None = None
    poll_s: float = 0.001
    baudrate: int | None = None
    bits_per_byte: int = 10

    def __post_init__(self) -> None:
        if self.baudrate is not None and not (
            isinstance(self.baudrate, int)
            and not isinstance(self.baudrate, bool)
            and self.baudrate > 0
        ):
            raise ValueError(f"baudrate must be an int > 0 or None, got {self.baudrate!r}")
        if not (isinstance(self.bits_per_byte, int) and self.bits_per_byte > 0):
            raise ValueError(f"bits_per_byte must be an int > 0, got {self.bits_per_byte!r}")
        if not (math.isfinite(self.lower_speed) and self.lower_speed >= 0):
            raise ValueError(f"lower_speed must be >= 0, got {self.lower_speed!r}")
        for name in ("banner_delay_s", "reset_s"):
            if not getattr(self, name) >= 0:
                raise ValueError(f"{name} must be >= 0, got {getattr(self, name)!r}")
        if not self.poll_s > 0:
            raise ValueError(f"poll_s must be > 0, got {self.poll_s!r}")
        if self.eol not in ("\r\n", "\n", "\r"):
            raise ValueError(f"eol must be CR LF, LF or CR, got {self.eol!r}")
        if self.silent_after is not None and self.silent_after < 0:
            raise ValueError(f"silent_after must be >= 0, got {self.silent_after!r}")
        for axis in ("pan", "tilt"):
            speed = getattr(self.ptu, f"{axis}_speed")
            if speed < self.lower_speed:
                raise ValueError(
                    f"ptu.{axis}_speed ({speed}) is below lower_speed ({self.lower_speed})"
                )

    @property
    def byte_s(self) -> float:
        """Seconds per byte on the line (0 without a baud rate)."""
        return self.bits_per_byte / self.baudrate if self.baudrate else 0.0

    @property
    def banner_text(self) -> str:
        """The power-up text (without a final line end added)."""
        if self.banner is not None:
            return self.banner
        return f"{self.firmware}{self.eol}Initializing...{self.eol}"


@dataclass
class _Axis:
    """Runtime state of one emulated axis (positions, pos/s, pos/s²)."""

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


def _axes_from(params: PTUEmulatorParams) -> dict[str, _Axis]:
    m = params.ptu
    axes = {}
    for letter, axis in (("P", "pan"), ("T", "tilt")):
        axes[letter] = _Axis(
            name=axis.capitalize(),
            resolution_arcsec=getattr(m, f"{axis}_resolution_arcsec"),
            min_pos=getattr(m, f"{axis}_min_pos"),
            max_pos=getattr(m, f"{axis}_max_pos"),
            speed=getattr(m, f"{axis}_speed"),
            accel=getattr(m, f"{axis}_accel"),
            base=getattr(m, f"{axis}_base_speed"),
            upper=getattr(m, f"{axis}_upper_speed"),
            lower=params.lower_speed,
        )
    return axes


def _fmt(value: float) -> str:
    """A number as the firmware prints it: integers bare, fractions to 4-6 places."""
    if float(value).is_integer():
        return str(int(value))
    return f"{value:.6f}".rstrip("0").rstrip(".")


def _mode_view(flag: str, doc: str) -> property:
    """A read-only view of the mode flag attribute ``flag`` (a bool), the same flags
    :func:`_mode_setter` sets and :func:`_mode_query` reports."""
    return property(lambda emu: getattr(emu, flag), doc=doc)


class PTUEmulator:
    """A FLIR PTU on a pseudo-terminal, answering in a background thread.

    Use as a context manager (or call :meth:`close`); the thread and both pty file
    descriptors are released on exit.

    >>> with PTUEmulator() as emu:
    ...     emu.port.startswith("/dev/")
    True
    """

    def __init__(self, params: PTUEmulatorParams | None = None) -> None:
        self.params = params if params is not None else PTUEmulatorParams()
        self._lock = threading.RLock()
        self._stop = threading.Event()
        self._closed = False
        self._axes = _axes_from(self.params)
        self._echo = self.params.echo
        self._verbose = self.params.verbose
        self._slaved = False
        self._velocity_mode = False
        self._limits_enabled = True
        self._t = time.monotonic()
        self._rx = ""
        self._pending: Callable[[], str | None] | None = None
        self._commands: list[str] = []
        self._n_commands = 0
        self._silent_after = self.params.silent_after
        self._errors: list[tuple[str | None, str]] = []
        self._garbage: list[str] = []
        self._banner_sent = threading.Event()
        # Baud-rate pacing: bytes on the line, each chunk with the time its last byte lands.
        self._rx_line: list[tuple[float, str]] = []
        self._tx_line: list[tuple[float, bytes]] = []
        self._rx_free = self._tx_free = 0.0
        self._clock: float | None = None  # the line time of the command being answered
        self._master, self._slave = os.openpty()
        try:
            # Raw slave: no kernel echo or CR/LF translation of what the emulator writes
            # before a host opens the port (pyserial sets its own raw mode on open).
            tty.setraw(self._slave)
            os.set_blocking(self._master, False)
            self.port: str = os.ttyname(self._slave)
            self._thread = threading.Thread(target=self._run, name="PTUEmulator", daemon=True)
            self._thread.start()
        except BaseException:
            os.close(self._master)
            os.close(self._slave)
            raise

    # -- life cycle -------------------------------------------------------------------

    def close(self) -> None:
        """Stop the thread and close the pty; safe to call twice."""
        if self._closed:
            return
        self._closed = True
        self._stop.set()
        self._thread.join(timeout=5.0)
        for fd in (self._master, self._slave):
            if fd < 0:
                continue
            try:
                os.close(fd)
            except OSError:
                pass

    def __enter__(self) -> PTUEmulator:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- fault injection ----------------------------------------------------------------

    def stop_answering(self, after: int = 0) -> None:
        """Go silent (no echo, no reply, no action) after ``after`` more commands."""
        with self._lock:
            self._silent_after = self._n_commands + after

    def resume_answering(self) -> None:
        """Answer commands again."""
        with self._lock:
            self._silent_after = None

    def inject_garbage(self, text: str = "\x00\xff#garbage", count: int = 1) -> None:
        """Answer ``text`` (no ``*`` or ``!``; a line noise burst) instead of executing the
        next ``count`` commands."""
        with self._lock:
            self._garbage.extend([text] * count)

    def hang_up(self) -> None:
        """Unplug the unit: the thread stops and the pty's master side is closed, so the
        host's next read or flush of the port fails with EIO (as a pulled USB adapter)."""
        with self._lock:
            self._stop.set()
        self._thread.join(timeout=5.0)
        try:
            os.close(self._master)
        except OSError:
            pass
        self._master = -1

    def stall(self) -> None:
        """Wedge the line: the thread stops reading (the pty stays open) and the pty's
        buffer towards the unit is filled, so the host's next write blocks, as on a link
        held by flow control or a hung USB-serial adapter. Only a bounded write timeout
        gets the host out."""
        with self._lock:
            self._stop.set()
        self._thread.join(timeout=5.0)
        blocking = os.get_blocking(self._slave)
        os.set_blocking(self._slave, False)
        try:
            # The kernel moves a pty's buffered bytes on in the background: fill until
            # three rounds 20 ms apart take nothing more.
            idle = 0
            while idle < 3:
                wrote = 0
                try:
                    while True:
                        wrote += os.write(self._slave, b"\x00" * 1024)
                except BlockingIOError:
                    pass
                idle = idle + 1 if wrote == 0 else 0
                time.sleep(0.02)
        finally:
            os.set_blocking(self._slave, blocking)

    def inject_error(self, message: str, command: str | None = None, count: int = 1) -> None:
        """Answer ``! <message>`` instead of executing the next ``count`` commands.

        ``command`` restricts it to commands whose letters equal it (``"PS"``).
        """
        with self._lock:
            key = command.upper() if command is not None else None
            self._errors.extend([(key, message)] * count)

    # -- state, for tests -------------------------------------------------------------

    @property
    def commands(self) -> list[str]:
        """Every command received, upper-cased, in order (answered or not)."""
        with self._lock:
            return list(self._commands)

    def clear_commands(self) -> None:
        """Forget the received commands."""
        with self._lock:
            self._commands.clear()

    @property
    def banner_sent(self) -> bool:
        """True once the power-up banner has been written."""
        return self._banner_sent.is_set()

    @property
    def positions(self) -> tuple[int, int]:
        """(pan, tilt) step counters, as ``PP``/``TP`` report them."""
        return self._both_axes("reported", advance=True)

    @property
    def target_positions(self) -> tuple[float, float]:
        """(pan, tilt) desired positions."""
        return self._both_axes("target")

    @property
    def moving(self) -> bool:
        """True until both axes rest on their targets."""
        with self._lock:
            self._advance()
            return any(a.moving for a in self._axes.values())

    @property
    def speeds(self) -> tuple[float, float]:
        """(pan, tilt) commanded speeds (``PS``/``TS``), pos/s."""
        return self._both_axes("speed")

    @property
    def accelerations(self) -> tuple[float, float]:
        """(pan, tilt) accelerations (``PA``/``TA``), pos/s²."""
        return self._both_axes("accel")

    echo = _mode_view("_echo", "Echo mode (``EE``/``ED``).")
    verbose = _mode_view("_verbose", "Feedback mode: True verbose (``FV``), False terse (``FT``).")
    slaved = _mode_view(
        "_slaved", "Position execution mode: True slaved (``S``), False immediate (``I``)."
    )
    velocity_mode = _mode_view(
        "_velocity_mode",
        "Speed control mode: True pure velocity (``CV``), False independent (``CI``).",
    )

    def _both_axes(self, attr: str, *, advance: bool = False) -> tuple[Any, Any]:
        """(pan, tilt) values of the axes' ``attr``, read under the lock (after bringing
        the motion up to now when ``advance``)."""
        with self._lock:
            if advance:
                self._advance()
            return getattr(self._axes["P"], attr), getattr(self._axes["T"], attr)

    # -- the thread -------------------------------------------------------------------

    def _run(self) -> None:
        if self._stop.wait(self.params.banner_delay_s):
            return
        with self._lock:
            self._write(self.params.banner_text)
            self._banner_sent.set()
        while not self._stop.is_set():
            timeout = self.params.poll_s if self._pending is not None else 0.01
            due = [t for t, _ in self._rx_line[:1] + self._tx_line[:1]]
            if due:
                timeout = max(0.0, min(timeout, min(due) - time.monotonic()))
            try:
                ready, _, _ = select.select([self._master], [], [], timeout)
            except (OSError, ValueError):
                return
            data = b""
            if ready:
                try:
                    data = os.read(self._master, 4096)
                except BlockingIOError:
                    pass
                except OSError:  # no reader/writer on the slave side yet
                    time.sleep(timeout)
            with self._lock:
                self._receive(data.decode("ascii", errors="replace"))
                self._advance()
                self._service()
                self._clock = None
                self._flush_line()

    def _receive(self, text: str) -> None:
        """Bytes read from the pty: usable now, or once the line has carried them."""
        byte_s = self.params.byte_s
        now = time.monotonic()
        if text and byte_s:
            self._rx_free = max(now, self._rx_free) + len(text) * byte_s
            self._rx_line.append((self._rx_free, text))
        elif text:
            self._rx += text
        while self._rx_line and self._rx_line[0][0] <= now:
            # Replies to these bytes leave from when they arrived (not from when this
            # thread got round to them), as a unit answering at once would send them.
            self._clock, text = self._rx_line.pop(0)
            self._rx += text

    def _flush_line(self) -> None:
        """Write the replies whose last byte has gone out on the line."""
        now = time.monotonic()
        while self._tx_line and self._tx_line[0][0] <= now:
            self._write_now(self._tx_line.pop(0)[1])

    def _write(self, text: str) -> None:
        data = text.encode("ascii", errors="replace")
        byte_s = self.params.byte_s
        if byte_s:
            now = self._clock if self._clock is not None else time.monotonic()
            self._tx_free = max(now, self._tx_free) + len(data) * byte_s
            self._tx_line.append((self._tx_free, data))
            return
        self._write_now(data)

    def _write_now(self, data: bytes) -> None:
        deadline = time.monotonic() + 0.5
        while data and not self._stop.is_set():
            try:
                data = data[os.write(self._master, data) :]
            except BlockingIOError:  # nobody reads: drop after a while, as a full UART would
                if time.monotonic() > deadline:
                    return
                time.sleep(0.001)
            except OSError:
                return

    def _reply(self, text: str) -> None:
        self._write(text + self.params.eol)

    def _advance(self) -> None:
        now = time.monotonic()
        dt, self._t = now - self._t, now
        for axis in self._axes.values():
            axis.advance(dt)

    def _service(self) -> None:
        """Answer a finished ``A``/``R``, then execute buffered commands in order."""
        while True:
            if self._pending is not None:
                reply = self._pending()
                if reply is None:
                    token = self._next_token(peek=True)
                    if token is None or token.upper() not in _HALTS:
                        return
                    self._handle(self._next_token())  # a halt goes through (ends an ``A``)
                    self._advance()
                    continue
                self._pending = None
                self._reply(reply)
            token = self._next_token()
            if token is None:
                return
            self._handle(token)

    def _next_token(self, peek: bool = False) -> str | None:
        rx = self._rx.lstrip(_DELIMITERS)
        ends = [i for i in (rx.find(c) for c in _DELIMITERS) if i >= 0]
        if not ends:
            self._rx = rx
            return None
        end = min(ends)
        self._rx = rx if peek else rx[end + 1 :]
        return rx[:end]

    # -- commands ---------------------------------------------------------------------

    def _handle(self, token: str) -> None:
        cmd = token.upper()
        self._commands.append(cmd)
        self._n_commands += 1
        if self._silent_after is not None and self._n_commands > self._silent_after:
            return  # a dead unit: neither echo nor reply nor action
        if self._echo:
            self._write(token + " ")
        m = _TOKEN.fullmatch(cmd)
        name = m.group(1) if m else cmd
        if self._garbage:
            self._write(self._garbage.pop(0) + self.params.eol)
            return
        for i, (key, message) in enumerate(self._errors):
            if key is None or key == name:
                del self._errors[i]
                self._reply(f"! {message}")
                return
        reply = self._execute(cmd)
        if reply is not None:
            self._reply(reply)

    def _execute(self, cmd: str) -> str | None:
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
            return handler(self, self._axes[name[0]], arg)
        handler0 = _UNIT_COMMANDS.get(name)
        if handler0 is None:
            return "! Illegal Command Entered"
        if rest or arg is not None:
            return "! Illegal argument"
        return handler0(self, arg)

    def _query(self, value: float, text: str) -> str:
        return f"* {text}" if self._verbose else f"* {_fmt(value)}"

    # axis commands: handler(self, axis, arg) -> reply

    def _position(self, ax: _Axis, arg: int | None) -> str:
        if arg is None:
            return self._query(ax.reported, f"Current {ax.name} position is {ax.reported}")
        return self._set_target(ax, float(arg))

    def _offset(self, ax: _Axis, arg: int | None) -> str:
        if arg is None:
            # PTU-D46 manual §4.3.2: the bare ``PO`` queries the desired position; the
            # verbose text is Miro's DpPanTilt table ("Target Pan position is ").
            desired = ax.pending if ax.pending is not None else ax.target
            return self._query(desired, f"Target {ax.name} position is {_fmt(desired)}")
        return self._set_target(ax, float(ax.reported + arg))

    def _set_target(self, ax: _Axis, pos: float) -> str:
        if self._limits_enabled and pos > ax.max_pos:
            return f"! Maximum allowable {ax.name} position is {ax.max_pos}"
        if self._limits_enabled and pos < ax.min_pos:
            return f"! Minimum allowable {ax.name} position is {ax.min_pos}"
        if self._velocity_mode:
            self._velocity_mode = False  # a position command returns to position control
        if self._slaved:
            ax.pending = pos
        else:
            ax.target = pos
        return "*"

    def _resolution(self, ax: _Axis, arg: int | None) -> str:
        if arg is not None:
            return "! Illegal argument"
        r = ax.resolution_arcsec
        return self._query(r, f"{_fmt(r)} seconds arc per position")

    def _speed(self, ax: _Axis, arg: int | None) -> str:
        if arg is None:
            return self._query(
                ax.speed, f"Target {ax.name} speed is {_fmt(ax.speed)} positions/sec"
            )
        if self._velocity_mode:  # pure velocity: a signed speed drives the axis
            if arg == 0:
                ax.target = ax.stop_point()
                return "*"
            error = self._check_speed(ax, abs(arg))
            if error:
                return error
            ax.speed = float(abs(arg))
            ax.target = float(ax.max_pos if arg > 0 else ax.min_pos)
            return "*"
        error = self._check_speed(ax, arg)
        if error:
            return error
        ax.speed = float(arg)
        return "*"

    def _check_speed(self, ax: _Axis, speed: int) -> str | None:
        # "PS3300 ! Pan speed cannot exceed 2902 positions/sec" (PTU-D46 manual §4.4.6).
        if speed > ax.upper:
            return f"! {ax.name} speed cannot exceed {_fmt(ax.upper)} positions/sec"
        # The lower-bound text mirrors the upper one (an assumption: no source shows it).
        if speed < max(ax.lower, 1.0):
            return f"! {ax.name} speed cannot be less than {_fmt(max(ax.lower, 1.0))} positions/sec"
        return None

    def _delta(self, ax: _Axis, arg: int | None) -> str:
        # E series: ``PD`` queries the current (signed) speed, ``PD<n>`` offsets the speed.
        if arg is None:
            v = round(ax.state.velocity)
            return self._query(v, f"Current {ax.name} speed is {v} positions/sec")
        return self._speed(ax, int(ax.speed) + arg)

    # unit commands: handler(self, arg) -> reply

    def _await(self, arg: int | None) -> str | None:
        if self._slaved:
            for ax in self._axes.values():
                if ax.pending is not None:
                    ax.target, ax.pending = ax.pending, None
        self._pending = lambda: None if any(a.moving for a in self._axes.values()) else "*"
        return None

    def _reset(self, arg: int | None) -> None:
        done = time.monotonic() + self.params.reset_s
        for ax in self._axes.values():
            ax.target, ax.pending = ax.stop_point(), None

        def finished() -> str | None:
            if time.monotonic() < done:
                return None
            for ax in self._axes.values():  # recalibrated, back home
                ax.state, ax.target = AxisState(), 0.0
            return RESET_REPLY

        self._pending = finished

    def _independent(self, arg: int | None) -> str:
        if self._velocity_mode:
            for ax in self._axes.values():
                ax.target = ax.stop_point()
        self._velocity_mode = False
        return "*"

    def _version(self, arg: int | None) -> str:
        return f"* {self.params.firmware}"

    def _defaults(self, arg: int | None) -> str:
        return "*"

    def _factory(self, arg: int | None) -> str:
        fresh = _axes_from(self.params)
        for letter, ax in self._axes.items():
            for name in ("speed", "accel", "base", "upper", "lower"):
                setattr(ax, name, getattr(fresh[letter], name))
        return "*"


def _limit_handler(which: str) -> Callable[[PTUEmulator, _Axis, int | None], str]:
    """``PN``/``PX``/``TN``/``TX``: the position bounds (queries only)."""

    def handler(emu: PTUEmulator, ax: _Axis, arg: int | None) -> str:
        if arg is not None:
            return "! Illegal argument"
        value = ax.min_pos if which == "Minimum" else ax.max_pos
        return emu._query(value, f"{which} {ax.name} position is {value}")

    return handler


def _setting_handler(
    attr: str,
    text: str,
    valid: Callable[[_Axis, int], bool],
    then: Callable[[_Axis], None] | None = None,
) -> Callable[[PTUEmulator, _Axis, int | None], str]:
    """``PA``/``PB``/``PU``/``PL`` (and ``T…``): the bare command queries the axis setting
    ``attr`` (verbose ``text``, with ``{name}`` and ``{value}``); with an argument that
    passes ``valid`` it sets it (``then`` adjusts the others), else ``! Illegal argument``."""

    def handler(emu: PTUEmulator, ax: _Axis, arg: int | None) -> str:
        value = getattr(ax, attr)
        if arg is None:
            return emu._query(value, text.format(name=ax.name, value=_fmt(value)))
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


def _halt_handler(letters: str) -> Callable[[PTUEmulator, int | None], str]:
    """``H``/``HP``/``HT``: brake to a stop on the nearest reachable whole position."""

    def handler(emu: PTUEmulator, arg: int | None) -> str:
        emu._advance()
        for letter in letters:
            ax = emu._axes[letter]
            ax.target, ax.pending = ax.stop_point(), None
        return "*"

    return handler


def _mode_setter(flag: str, value: bool) -> Callable[[PTUEmulator, int | None], str]:
    """A unit command that sets the mode flag attribute ``flag`` (``EE``, ``FT``, ``LD``...)."""

    def handler(emu: PTUEmulator, arg: int | None) -> str:
        setattr(emu, flag, value)
        return "*"

    return handler


def _mode_query(flag: str, on: str, off: str) -> Callable[[PTUEmulator, int | None], str]:
    """A unit command that reports the mode flag attribute ``flag`` (``E``, ``F``, ``C``, ``L``)."""

    def handler(emu: PTUEmulator, arg: int | None) -> str:
        return f"* {on if getattr(emu, flag) else off}"

    return handler


_AXIS_COMMANDS: dict[str, Callable[..., str]] = {
    "P": PTUEmulator._position,
    "O": PTUEmulator._offset,
    "R": PTUEmulator._resolution,
    "N": _limit_handler("Minimum"),
    "X": _limit_handler("Maximum"),
    "S": PTUEmulator._speed,
    "D": PTUEmulator._delta,
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
    "A": PTUEmulator._await,
    "H": _halt_handler("PT"),
    "HP": _halt_handler("P"),
    "HT": _halt_handler("T"),
    "I": _mode_setter("_slaved", False),
    "S": _mode_setter("_slaved", True),
    "R": PTUEmulator._reset,
    "E": _mode_query("_echo", "Echoing ON", "Echoing OFF"),
    "EE": _mode_setter("_echo", True),
    "ED": _mode_setter("_echo", False),
    "F": _mode_query("_verbose", "ASCII verbose mode", "ASCII terse mode"),
    "FT": _mode_setter("_verbose", False),
    "FV": _mode_setter("_verbose", True),
    "C": _mode_query(
        "_velocity_mode", "Pure velocity speed control mode", "Independent speed control mode"
    ),
    "CI": PTUEmulator._independent,
    "CV": _mode_setter("_velocity_mode", True),
    "L": _mode_query(
        "_limits_enabled",
        "Limit bounds are ENABLED (soft limits enabled)",
        "Limit bounds are DISABLED (hard limits only: use care)",
    ),
    "LE": _mode_setter("_limits_enabled", True),
    "LD": _mode_setter("_limits_enabled", False),
    "V": PTUEmulator._version,
    "DS": PTUEmulator._defaults,
    "DR": PTUEmulator._defaults,
    "DF": PTUEmulator._factory,
}
