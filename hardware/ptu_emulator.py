"""A protocol-exact FLIR pan-tilt unit (PTU-D46/E46/D48E) emulator on a pseudo-terminal.

The emulator speaks the FLIR ASCII protocol on the master side of a pty; its
:attr:`PTUEmulator.port` is the slave device path, which a real ``serial.Serial(port)``
(or :func:`serial.serial_for_url`) opens like a USB-serial adapter. A background
thread reads commands and hands them, in real time, to the unit's firmware
(:class:`~hardware.ptu_firmware.PTUFirmware`: the command set, the modes and the axes
moved by the motion maths of :mod:`wander_env.ptu`); this module is the line: the pty,
the echo and line ends, the baud rate's timing, the power-up banner and the faults a
test injects.

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

import os
import select
import threading
import time
import tty
from dataclasses import dataclass, field
from typing import Any

from hardware.ptu_firmware import DEFAULT_FIRMWARE, HALTS, PTUFirmware, command_letters
from wander_env.config import check_fields
from wander_env.ptu.link import DELIMITERS, PTULinkParams
from wander_env.ptu.params import PTUParams


@dataclass(frozen=True)
class PTUEmulatorParams:
    """Parameters of the emulated unit.

    ``ptu`` (the unit's :class:`~wander_env.ptu.params.PTUParams`) holds resolution
    (``PR``/``TR``), limits (``PN``/``PX``/``TN``/``TX``), speeds (``PS``), accelerations
    (``PA``), base (``PB``), upper (``PU``) and lower (``PL``) speeds, and the serial line
    (``ptu.link``, a :class:`~wander_env.ptu.link.PTULinkParams`, as the simulated unit's):
    with one (the ``flir`` preset) the line is paced as a UART at its ``baudrate`` would
    be: each byte in either direction takes its ``byte_s``, a command is executed once its
    last byte has arrived, its echo and reply leave ``turnaround_s`` later and are
    readable once their last byte has been sent; without one (``ideal``, the default) it
    is instant, as a pty is. Replies end with the link's ``eol`` (:attr:`eol`). ``echo``
    and ``verbose`` are the power-up modes (on, as a factory unit). ``banner`` (``None``:
    the firmware line and ``Initializing...``) is printed ``banner_delay_s`` after start.
    ``reset_s`` is how long ``R`` takes. ``silent_after``: stop answering after that many
    commands (fault injection for timeouts). ``poll_s`` is the thread's poll period while
    a reply waits on motion.
    """

    ptu: PTUParams = field(default_factory=PTUParams)
    firmware: str = DEFAULT_FIRMWARE
    banner: str | None = None
    banner_delay_s: float = 0.0
    echo: bool = True
    verbose: bool = True
    reset_s: float = 0.05
    silent_after: int | None = None
    poll_s: float = 0.001

    def __post_init__(self) -> None:
        check_fields(self, ("banner_delay_s", "reset_s"), minimum=0)
        check_fields(self, ("poll_s",), positive=True)
        check_fields(self, ("silent_after",), integer=True, minimum=0, allow_none=True)

    @property
    def eol(self) -> str:
        """What ends every reply: ``ptu.link``'s ``eol`` (without a link, its default: CR LF).

        >>> PTUEmulatorParams(ptu=PTUParams(link=PTULinkParams(eol="\\r"))).eol
        '\\r'
        """
        return self.ptu.link.eol if self.ptu.link is not None else PTULinkParams.eol

    @property
    def banner_text(self) -> str:
        """The power-up text (without a final line end added)."""
        if self.banner is not None:
            return self.banner
        return f"{self.firmware}{self.eol}Initializing...{self.eol}"


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
        p = self.params
        self._firmware = PTUFirmware(
            p.ptu,
            p.firmware,
            p.reset_s,
            echo=p.echo,
            verbose=p.verbose,
            now=time.monotonic(),
        )
        self._rx = ""
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
            return self._firmware.moving

    @property
    def speeds(self) -> tuple[float, float]:
        """(pan, tilt) commanded speeds (``PS``/``TS``), pos/s."""
        return self._both_axes("speed")

    @property
    def accelerations(self) -> tuple[float, float]:
        """(pan, tilt) accelerations (``PA``/``TA``), pos/s²."""
        return self._both_axes("accel")

    @property
    def modes(self) -> dict[str, bool]:
        """The firmware's mode flags: ``echo`` (``EE``/``ED``), ``verbose`` feedback
        (``FV``/``FT``), ``slaved`` position execution (``S``/``I``), ``velocity_mode``
        (pure velocity ``CV``, independent ``CI``) and ``limits_enabled`` (``LE``/``LD``)."""
        f = self._firmware
        with self._lock:
            return {
                "echo": f.echo,
                "verbose": f.verbose,
                "slaved": f.slaved,
                "velocity_mode": f.velocity_mode,
                "limits_enabled": f.limits_enabled,
            }

    def _both_axes(self, attr: str, *, advance: bool = False) -> tuple[Any, Any]:
        """(pan, tilt) values of the axes' ``attr``, read under the lock (after bringing
        the motion up to now when ``advance``)."""
        with self._lock:
            if advance:
                self._advance()
            axes = self._firmware.axes
            return getattr(axes["P"], attr), getattr(axes["T"], attr)

    # -- the thread -------------------------------------------------------------------

    def _run(self) -> None:
        if self._stop.wait(self.params.banner_delay_s):
            return
        with self._lock:
            self._write(self.params.banner_text)
            self._banner_sent.set()
        while not self._stop.is_set():
            timeout = self.params.poll_s if self._firmware.waiting else 0.01
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
        link = self.params.ptu.link
        now = time.monotonic()
        if text and link is not None:
            self._rx_free = max(now, self._rx_free) + len(text) * link.byte_s
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
        link = self.params.ptu.link
        if link is not None:
            if self._clock is not None:  # an answer: after the unit's turnaround
                now = self._clock + link.turnaround_s
            else:
                now = time.monotonic()
            self._tx_free = max(now, self._tx_free) + len(data) * link.byte_s
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
        self._firmware.advance(time.monotonic())

    def _service(self) -> None:
        """Answer a finished ``A``/``R``, then execute buffered commands in order."""
        while True:
            if self._firmware.waiting:
                reply = self._firmware.poll(time.monotonic())
                if reply is None:
                    token = self._next_token(peek=True)
                    if token is None or token.upper() not in HALTS:
                        return
                    self._handle(self._next_token())  # a halt goes through (ends an ``A``)
                    self._advance()
                    continue
                self._reply(reply)
            token = self._next_token()
            if token is None:
                return
            self._handle(token)

    def _next_token(self, peek: bool = False) -> str | None:
        rx = self._rx.lstrip("".join(DELIMITERS))
        ends = [i for i in (rx.find(c) for c in DELIMITERS) if i >= 0]
        if not ends:
            self._rx = rx
            return None
        end = min(ends)
        self._rx = rx if peek else rx[end + 1 :]
        return rx[:end]

    # -- a command, through the faults a test injected, to the firmware ---------------

    def _handle(self, token: str) -> None:
        cmd = token.upper()
        self._commands.append(cmd)
        self._n_commands += 1
        if self._silent_after is not None and self._n_commands > self._silent_after:
            return  # a dead unit: neither echo nor reply nor action
        if self._firmware.echo:
            self._write(token + " ")
        name = command_letters(cmd)
        if self._garbage:
            self._write(self._garbage.pop(0) + self.params.eol)
            return
        for i, (key, message) in enumerate(self._errors):
            if key is None or key == name:
                del self._errors[i]
                self._reply(f"! {message}")
                return
        reply = self._firmware.execute(cmd, time.monotonic())
        if reply is not None:
            self._reply(reply)
