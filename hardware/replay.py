"""Play a recorded event file as if it were a camera.

:class:`ReplaySource` reads any file :func:`wander_env.events.io.read_events` reads
(``.npz``, HDF5, ``.npy``, AEDAT4, AEDAT 2.0) or takes an
:class:`~wander_env.events.io.EventRecording`, rebases the timestamps so that the
replay starts at 0 µs (the original offset is kept in ``metadata["t_offset_us"]``)
and hands out consecutive windows through the :class:`~hardware.event_source.EventSource`
interface. In real-time mode a ``read`` returns when the wall clock has reached the
end of its window (``speed`` > 1 plays faster; the wall clock and the sleep are
injectable, ``clock``/``sleep``, so that a test can check the pacing without waiting);
otherwise it returns at once. At the
end of the file reads return empty arrays and ``finished`` is true, unless
``loop`` is set: then the recording repeats, each lap shifted by the recording's
length so that timestamps keep increasing.

What it plays feeds the agent, whose maps take about 1.2 KB a pixel: a sensor larger than
:data:`~wander_env.events.checks.MAX_SENSOR_PIXELS` is refused, and a file is read within
the event limit of :func:`~wander_env.events.io.read_events`
(:data:`~wander_env.events.checks.MAX_EVENTS`), both with an
:class:`~wander_env.events.checks.EventFileError` naming the file.

Examples:
    >>> from wander_env.events import make_events
    >>> from wander_env.events.io import EventRecording
    >>> ev = make_events(x=[1, 2, 3], y=[0, 0, 0], t=[100, 150, 400], p=[1, 0, 1])
    >>> rec = EventRecording(ev, (4, 4, 2))
    >>> with ReplaySource(rec) as cam:
    ...     [cam.read(duration_us=100)["t"].tolist() for _ in range(4)], cam.finished
    ([[0, 50], [], [], [300]], True)
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from hardware.event_source import EventSourceBase
from wander_env.events import EVENT_DTYPE, empty_events, time_window
from wander_env.events.checks import check_sensor_area
from wander_env.events.io import EventRecording, read_events


@dataclass(frozen=True)
class ReplayParams:
    """How a recording is played back.

    ``realtime``: pace reads by the wall clock; ``speed``: event-time µs per
    wall-clock µs in real-time mode; ``loop``: repeat at the end; ``t0_us``: the
    original timestamp that becomes 0 (default: the first event's); events before
    it are skipped.
    """

    realtime: bool = False
    speed: float = 1.0
    loop: bool = False
    t0_us: int | None = None

    def __post_init__(self) -> None:
        if not (math.isfinite(self.speed) and self.speed > 0):
            raise ValueError(f"speed must be a positive finite number, got {self.speed!r}")
        if self.t0_us is not None and int(self.t0_us) != self.t0_us:
            raise ValueError(f"t0_us must be an integer (µs), got {self.t0_us!r}")


class ReplaySource(EventSourceBase):
    """A recorded event stream behind the :class:`EventSource` interface."""

    def __init__(
        self,
        source: str | os.PathLike[str] | EventRecording,
        realtime: bool = False,
        speed: float = 1.0,
        loop: bool = False,
        t0_us: int | None = None,
        *,
        clock: Callable[[], float] = time.monotonic,
        sleep: Callable[[float], None] = time.sleep,
    ) -> None:
        self.params = ReplayParams(realtime=realtime, speed=speed, loop=loop, t0_us=t0_us)
        self._clock = clock  # the wall clock of real-time mode (s), and its sleep
        self._sleep = sleep
        if isinstance(source, EventRecording):
            recording, origin = source, "EventRecording"
        else:
            recording, origin = read_events(source), str(Path(source))
        check_sensor_area(origin, recording.sensor_size)
        events = np.asarray(recording.events).astype(EVENT_DTYPE, copy=False)
        if t0_us is not None:
            offset = int(t0_us)
        else:
            offset = int(events["t"][0]) if len(events) else 0
        skipped = int(np.searchsorted(events["t"], offset, side="left"))
        # A file's events are this replay's own: rebased in place; a caller's are copied.
        own = events is not recording.events or not isinstance(source, EventRecording)
        self._events = events[skipped:] if own else events[skipped:].copy()
        self._events["t"] -= offset
        self._period_us = int(self._events["t"][-1]) + 1 if len(self._events) else 0
        super().__init__(tuple(int(v) for v in recording.sensor_size))  # type: ignore[arg-type]
        self.metadata: dict[str, Any] = {
            **recording.metadata,
            "source": origin,
            "t_offset_us": offset,
            "skipped_before_t0": skipped,
        }
        self._t_start_wall = 0.0
        self._windows = 0
        self._delivered = 0
        self._max_lateness_s = 0.0

    # -- EventSource ---------------------------------------------------------------

    @property
    def dropped(self) -> int:
        """A replay never loses events."""
        return 0

    @property
    def duration_us(self) -> int:
        """Length of one pass through the recording: last rebased timestamp + 1 µs."""
        return self._period_us

    @property
    def n_events(self) -> int:
        """Events in one pass."""
        return len(self._events)

    @property
    def finished(self) -> bool:
        """True once every event has been handed out (never while looping a non-empty file)."""
        if self.params.loop and self._period_us > 0:
            return False
        return self._cursor_us >= self._period_us

    @property
    def stats(self) -> dict[str, Any]:
        return {
            "windows": self._windows,
            "delivered": self._delivered,
            "laps": self._cursor_us // self._period_us if self._period_us else 0,
            "cursor_us": self._cursor_us,
            "finished": self.finished,
            "dropped": 0,
            "max_lateness_s": self._max_lateness_s,
        }

    def now_us(self) -> int:
        """Source time that the wall clock has reached (real-time mode), else the cursor."""
        if not self.params.realtime or not self._started:
            return self._cursor_us
        return int((self._clock() - self._t_start_wall) * 1e6 * self.params.speed)

    def start(self) -> None:
        """Set the replay clock to 0 (the wall clock starts here in real-time mode)."""
        if self._closed:
            raise RuntimeError("ReplaySource is closed; create a new one")
        if not self._started:
            self._started = True
            self._t_start_wall = self._clock()

    def read(self, duration_us: int | None = None, *, until_t_us: int | None = None) -> np.ndarray:
        """Events with ``cursor <= t < end``; see :mod:`hardware.event_source`.

        Without a window: in real-time mode the events up to now, otherwise the rest
        of the file (an error when looping, which has no end).
        """
        self._check_running()
        end = self._window_end(duration_us, until_t_us)
        if end is None:
            if self.params.realtime:
                end = max(self._cursor_us, self.now_us())
            elif self.params.loop and self._period_us > 0:
                raise ValueError("a looping replay has no end: give duration_us or until_t_us")
            else:
                end = max(self._cursor_us, self._period_us)
        if self.params.realtime:
            self._sleep_until(end)
        out = self._slice(self._cursor_us, end)
        self._cursor_us = end
        self._windows += 1
        self._delivered += len(out)
        return out

    def close(self) -> None:
        """Nothing to release; marks the source closed (idempotent)."""
        self._closed = True

    # -- internals -----------------------------------------------------------------

    def _sleep_until(self, end_us: int) -> None:
        target = self._t_start_wall + end_us / (1e6 * self.params.speed)
        remaining = target - self._clock()
        if remaining > 0:
            self._sleep(remaining)
        else:
            self._max_lateness_s = max(self._max_lateness_s, -remaining)

    def _slice(self, a: int, b: int) -> np.ndarray:
        """Events in ``[a, b)`` of the (possibly looped) stream, as a new array."""
        period = self._period_us
        if b <= a or period == 0:
            return empty_events()
        if not self.params.loop:
            return time_window(self._events, a, b).copy()
        parts = []
        for lap in range(a // period, (b - 1) // period + 1):
            shift = lap * period
            seg = time_window(self._events, max(a - shift, 0), min(b - shift, period)).copy()
            seg["t"] += shift
            parts.append(seg)
        return np.concatenate(parts) if parts else empty_events()
