"""The PTU's serial link: one model of its command scheduling, for the sim and the rig.

The real unit talks ASCII at 9600 baud, so every command and position query costs
milliseconds on the serial line (:class:`PTULinkParams`, the ``flir`` preset of
:meth:`~wander_env.ptu.params.PTUParams.preset`; off in ``ideal``, the default).
:class:`LinkSchedule` is the scheduling, a pure state machine: a new target is queued
(replacing one not yet sent) and sent as ``PP<n>`` then ``TP<n>`` (only the axes that
changed), each answered ``*`` CR LF; between commands ``PP`` and ``TP`` are polled
(answers ``* <n>`` CR LF) every ``poll_s``. The rig's PTU thread (``hardware/rig_env.py``)
steps it in wall-clock time with the driver (``hardware/ptu_driver.py``) on the port;
:class:`CommandLink` steps it in simulated time: each byte costs
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

#: What may end a command on the line: a space (the FLIR default), CR or LF.
DELIMITERS = (" ", "\r", "\n")


def check_delimiter(delimiter: str, name: str) -> None:
    """ValueError unless ``delimiter`` (the field ``name``) is one of :data:`DELIMITERS`.

    >>> check_delimiter(";", "FlirPTUParams.delimiter")
    Traceback (most recent call last):
    ...
    ValueError: FlirPTUParams.delimiter must be a space, CR or LF, got ';'
    """
    if delimiter not in DELIMITERS:
        raise ValueError(f"{name} must be a space, CR or LF, got {delimiter!r}")


@dataclass(frozen=True)
class PTULinkParams:
    """The host-PTU serial link as the rig drives it (``hardware/ptu_driver.py``: terse
    feedback, echo off, commands ended by a space; replies ended by CR LF as the
    PTU-D48E writes them). The one home of the line's settings: the simulated unit's
    link (``PTUParams.link``), the emulator's
    line (``PTUEmulatorParams.ptu.link``: its eol, baud rate and turnaround), and the
    defaults of the driver's ``FlirPTUParams`` (``baudrate``, ``delimiter``) and of
    ``RigConfig.ptu_poll_s``.

    ``baudrate`` 9600 (the FLIR factory setting), 8N1 = ``bits_per_byte`` 10;
    ``poll_s`` the position polling period; ``delimiter`` what ends a command
    (:data:`DELIMITERS`), ``eol`` what ends a reply (CR LF, LF or CR); ``turnaround_s``
    the unit's time between a command's last byte and its reply (not documented by
    FLIR: 0).

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
        check_delimiter(self.delimiter, "PTULinkParams.delimiter")
        if self.eol not in ("\r\n", "\n", "\r"):
            raise ValueError(f"PTULinkParams.eol must be CR LF, LF or CR, got {self.eol!r}")

    @property
    def byte_s(self) -> float:
        """Seconds per byte on the line."""
        return self.bits_per_byte / self.baudrate


def command_word(axis: int, value: int | None) -> str:
    """A position command (``PP-500``) or query (``TP``) of axis 0 (pan) or 1 (tilt), as
    the driver sends it (without the delimiter).

    >>> command_word(0, -500), command_word(1, None)
    ('PP-500', 'TP')
    """
    return f"{'PT'[axis]}P{'' if value is None else value}"


def command_bytes(axis: int, value: int | None, link: PTULinkParams) -> int:
    """Bytes of a position command (``PP-500 ``) or query (``PP ``) for axis 0 (pan) or 1.

    >>> command_bytes(0, -500, PTULinkParams()), command_bytes(1, None, PTULinkParams())
    (7, 3)
    """
    return len(command_word(axis, value) + link.delimiter)


def reply_bytes(value: int | None, link: PTULinkParams) -> int:
    """Bytes of the unit's terse reply: ``*`` (a command) or ``* <value>`` (a query).

    >>> reply_bytes(None, PTULinkParams()), reply_bytes(-1234, PTULinkParams())
    (3, 9)
    """
    return len(("*" if value is None else f"* {value}") + link.eol)


Target = tuple[int, int]


@dataclass(frozen=True)
class Exchange:
    """One exchange on the line: a target's position commands (``PP<n>`` then ``TP<n>``,
    the changed axes only), or a position poll (``PP``, ``TP``).

    ``words``: (axis, value) in the order sent, value ``None`` for a query; ``target``: the
    target the commands send (``None``: a poll); ``submitted_s``: when that target was
    handed over (a poll: when it began); ``acked``: the acknowledged target when the
    exchange began (a poll's answer is judged against it).
    """

    words: tuple[tuple[int, int | None], ...]
    target: Target | None
    submitted_s: float
    acked: Target

    @property
    def is_poll(self) -> bool:
        """True for a position poll."""
        return self.target is None

    def text(self) -> list[str]:
        """The words as sent (``["PP100", "TP-50"]``, ``["PP", "TP"]``)."""
        return [command_word(axis, value) for axis, value in self.words]


class LinkSchedule:
    """The PTU link's command scheduling, a pure state machine in the caller's time.

    One exchange on the line at a time. A target handed over (:meth:`submit`) replaces one
    that waits, unsent; when the line is free (:meth:`due_s` has come) :meth:`begin` takes
    the waiting target as a command exchange (the axes that differ from the acknowledged
    target, pan first), or, with no target waiting (or one equal to the acknowledged
    target), a poll of both axes, ``poll_s`` after the previous poll ended (at once after
    a command). :meth:`end` takes the exchange's outcome. The simulated link
    (:class:`CommandLink`, byte timing in simulated time) and the rig's PTU thread
    (``hardware/rig_env.py``, the driver on a serial port, in wall-clock time) both step it.

    >>> s = LinkSchedule(0.01, (0, 0))
    >>> s.submit((100, 0), 0.0)
    >>> s.submit((100, -50), 0.001)         # replaces the unsent (100, 0)
    >>> ex = s.begin(0.002); ex.text()
    ['PP100', 'TP-50']
    >>> s.end(0.02); s.acked, s.latencies_s, s.due_s()   # a poll at once after a command
    ((100, -50), [0.019], 0.02)
    >>> ex = s.begin(0.02); ex.text(); s.end(0.03, (40, -20)); s.positions, s.due_s()
    ['PP', 'TP']
    ((40, -20), 0.04)
    """

    def __init__(self, poll_s: float, start: Target, t_s: float = 0.0) -> None:
        self.poll_s = poll_s
        self.acked: Target = tuple(start)  # the last target the unit acknowledged
        self.positions: Target = tuple(start)  # the last poll's answer
        self.poll_target: Target = tuple(start)  # the acknowledged target when it began
        self.want: Target | None = None  # the newest target not yet sent
        self.want_at = 0.0
        self.current: Exchange | None = None  # the exchange on the line
        self.latencies_s: list[float] = []
        self.counts = {"commands_sent": 0, "commands_replaced": 0, "polls": 0}
        self.next_poll = t_s + poll_s

    @property
    def latency_s(self) -> float:
        """The latest acknowledged command's latency (NaN before the first)."""
        return self.latencies_s[-1] if self.latencies_s else math.nan

    def copy(self) -> LinkSchedule:
        """An independent schedule in the same state."""
        twin = copy.copy(self)
        twin.latencies_s, twin.counts = list(self.latencies_s), dict(self.counts)
        return twin

    def submit(self, target: Target, t_s: float) -> None:
        """Hand over a new target (whole positions) at ``t_s``."""
        if self.want is not None:
            self.counts["commands_replaced"] += 1
        self.want, self.want_at = (int(target[0]), int(target[1])), t_s

    def discard(self) -> None:
        """Drop the target that waits, unsent (a halt)."""
        self.want = None

    def due_s(self) -> float:
        """When the next exchange begins: at once for a waiting target, else the next poll
        (never while an exchange is on the line)."""
        if self.current is not None:
            return math.inf
        return self.want_at if self.want is not None else self.next_poll

    def begin(self, t_s: float) -> Exchange:
        """Start the next exchange at ``t_s`` (the line is free) and return it."""
        if self.current is not None:
            raise RuntimeError("an exchange is already on the line")
        job, self.want = self.want, None
        if job is not None and job != self.acked:
            words = tuple((i, job[i]) for i in (0, 1) if job[i] != self.acked[i])
            self.current = Exchange(words, job, self.want_at, self.acked)
        else:
            self.current = Exchange(((0, None), (1, None)), None, t_s, self.acked)
        return self.current

    def end(self, t_s: float, polled: Target | None = None) -> None:
        """The exchange on the line ended at ``t_s``: its commands were acknowledged, or
        its poll answered ``polled`` (whole positions)."""
        ex, self.current = self.current, None
        if ex is None:
            raise RuntimeError("no exchange is on the line")
        if ex.target is not None:
            self.acked = ex.target
            self.latencies_s.append(t_s - ex.submitted_s)
            self.counts["commands_sent"] += 1
            self.next_poll = t_s  # poll right after a command
        else:
            if polled is None:
                raise ValueError("a poll ends with the polled positions")
            self.positions, self.poll_target = (int(polled[0]), int(polled[1])), ex.acked
            self.counts["polls"] += 1
            self.next_poll = t_s + self.poll_s

    def moving(self, target: Target) -> bool:
        """The rig's test: a target waits or is being sent, or the last poll (begun after
        ``target`` was acknowledged) did not find the unit on it."""
        sending = self.current is not None and not self.current.is_poll
        busy = self.want is not None or sending
        return busy or self.poll_target != tuple(target) or self.positions != tuple(target)


class LinkedUnit(Protocol):
    """What :class:`CommandLink` needs of the unit at its end of the line."""

    def step_counter(self, axis: int) -> int:
        """What a ``PP``/``TP`` query of axis 0/1 answers now."""
        ...

    def drive_axis(self, axis: int, pos: float) -> None:
        """Give axis 0/1 its new target now."""
        ...


class CommandLink:
    """The PTU link in simulated time: a :class:`LinkSchedule` whose exchanges take their
    bytes' time on the line, word by word (command, then the unit's reply).

    Driven by :class:`~wander_env.ptu.unit.PanTiltUnit` (:meth:`next_time`, :meth:`fire`);
    Its :attr:`schedule` holds the link's record: ``latencies_s``, each acknowledged
    command's latency (submission to the last ``*``), as the rig's
    ``info["command_latency_s"]`` measures it; ``counts``, commands sent and replaced,
    polls (as the rig's ``stats``); ``positions``, the last poll's answer.

    >>> link = CommandLink(PTULinkParams(), (0, 0))
    >>> link.submit((100, 0), 0.0)        # the line is idle: PP100 goes out at once
    >>> round(link.next_time() * 1e3, 3)  # ...and arrives after its 6 bytes
    6.25
    """

    def __init__(self, params: PTULinkParams, start: Target, t_s: float = 0.0) -> None:
        self.params = params
        self.schedule = LinkSchedule(params.poll_s, start, t_s)
        self._replying = False  # the unit's reply to the first of _tx is on the line
        self._tx: list[tuple[int, int | None]] = []  # the exchange's words not yet answered
        self._samples = list(start)
        self._reply: int | None = None
        self._next = self.schedule.due_s()

    def copy(self) -> CommandLink:
        """An independent link in the same state."""
        twin = copy.copy(self)
        twin.schedule = self.schedule.copy()
        twin._tx, twin._samples = list(self._tx), list(self._samples)
        return twin

    def moving(self, target: Target) -> bool:
        """:meth:`LinkSchedule.moving`."""
        return self.schedule.moving(target)

    def submit(self, target: Target, t_s: float) -> None:
        """Hand a new target (whole positions) to the link at ``t_s``."""
        self.schedule.submit(target, t_s)
        if self.schedule.current is None:  # the line is idle: it goes out now
            self._begin(t_s)

    def next_time(self) -> float:
        """When the next thing happens on the line (a byte string fully received)."""
        return self._next

    def fire(self, unit: LinkedUnit) -> None:
        """Do what happens at :meth:`next_time` (the unit's motion is advanced to it)."""
        t = self._next
        if self.schedule.current is None:  # the poll is due
            self._begin(t)
        elif not self._replying:  # the unit has the word: act, start the reply
            axis, value = self._tx[0]
            if value is None:
                self._reply = unit.step_counter(axis)
                self._samples[axis] = self._reply
            else:
                unit.drive_axis(axis, float(value))
                self._reply = None
            self._replying = True
            reply = reply_bytes(self._reply, self.params) * self.params.byte_s
            self._next = t + self.params.turnaround_s + reply
        else:  # the reply is in: the exchange's next word, or the exchange is over
            self._tx.pop(0)
            self._replying = False
            if self._tx:
                self._send_next(t)
            else:
                polled = tuple(self._samples) if self.schedule.current.is_poll else None
                self.schedule.end(t, polled)
                due = self.schedule.due_s()
                if due <= t:
                    self._begin(t)
                else:
                    self._next = due

    def _begin(self, t: float) -> None:
        self._tx = list(self.schedule.begin(t).words)
        self._send_next(t)

    def _send_next(self, t: float) -> None:
        axis, value = self._tx[0]
        self._next = t + command_bytes(axis, value, self.params) * self.params.byte_s
