"""The PTU's command latency: the 9600-baud serial link between host and unit.

The real unit talks ASCII at 9600 baud, so every command and position query costs
milliseconds on the serial line (:class:`PTULinkParams`, the ``flir`` preset of
:meth:`~wander_env.ptu.params.PTUParams.preset`; off in ``ideal``, the default).
:class:`CommandLink` replays, in simulated time, what the rig's PTU thread
(``hardware/rig_env.py``) does with the driver (``hardware/ptu_driver.py``): a new target
is queued (replacing one not yet sent) and sent as ``PP<n>`` then ``TP<n>`` (only the axes
that changed), each answered ``*`` CR LF; between commands the thread polls ``PP`` and
``TP`` (answers ``* <n>`` CR LF) every ``poll_s``. Each byte costs
``bits_per_byte / baudrate`` (8N1: 10 bits); an axis takes its new target when the unit
has received the command's last byte; the position a query reports is the unit's step
counter when the query arrived. With a link,
:attr:`~wander_env.ptu.unit.PanTiltUnit.moving` is the rig's: true until a poll that began
after the latest target was acknowledged found the unit on it.
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass
from typing import Protocol

from wander_env.config import check_fields


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


class LinkedUnit(Protocol):
    """What :class:`CommandLink` needs of the unit at its end of the line."""

    def step_counter(self, axis: int) -> int:
        """What a ``PP``/``TP`` query of axis 0/1 answers now."""
        ...

    def drive_axis(self, axis: int, pos: float) -> None:
        """Give axis 0/1 its new target now."""
        ...


class CommandLink:
    """The rig's PTU thread (``hardware/rig_env.py`` ``_PTULink``) replayed in simulated
    time: one exchange on the line at a time; a submitted target waits for the exchange
    in progress, replaces a queued one not yet sent, then goes out as ``PP<n>``/``TP<n>``
    (changed axes only); when no target waits, ``PP``/``TP`` are polled ``poll_s`` after
    the previous poll ended (at once after a command).

    Driven by :class:`~wander_env.ptu.unit.PanTiltUnit` (:meth:`next_time`, :meth:`fire`);
    ``latencies_s`` holds each acknowledged command's latency (submission to the last
    ``*``), as the rig's ``info["command_latency_s"]`` measures it.

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

    def fire(self, unit: LinkedUnit) -> None:
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
