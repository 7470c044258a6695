"""The interface every event source shares: a live Speck, a replayed file, later the rig.

A source produces events in the shared format of :mod:`wander_env.events` (fields
``x``, ``y``, ``t`` [µs], ``p`` [1 = ON], sorted by ``t``) in consecutive, disjoint
time windows. Time is the source's own clock in microseconds, starting at 0 when
:meth:`EventSource.start` runs (the Speck's stop watch is reset there; a replay
rebases its file there). Each ``read`` returns the events of the window
``[previous end, new end)``; the rig env calls it once per step::

    with ReplaySource("walk.aedat", realtime=True) as cam:
        while not cam.finished:
            events = cam.read(duration_us=10_000)   # one 10 ms step

Rules shared by all sources:

* ``read()`` before ``start()`` or after ``close()`` raises ``RuntimeError``;
* ``read(duration_us=d)`` ends the window at ``cursor + d``; ``read(until_t_us=T)``
  at ``T`` (not before the cursor); ``read()`` with neither returns what is
  available now;
* events that a source had to discard are never dropped silently: ``dropped``
  counts them and ``stats`` says why;
* ``close()`` is idempotent and also runs when the ``with`` block raises
  (``KeyboardInterrupt`` included).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from types import TracebackType
from typing import Any, Protocol, runtime_checkable

import numpy as np

from wander_env.closing import Closing
from wander_env.events import SensorSize


@runtime_checkable
class EventSource(Protocol):
    """What the rig env and the tools need from a camera-like source of events."""

    @property
    def sensor_size(self) -> SensorSize:
        """``(W, H, 2)``."""
        ...

    @property
    def dropped(self) -> int:
        """Events lost so far (queue overflow, late arrival, out of range)."""
        ...

    @property
    def stats(self) -> dict[str, Any]:
        """Counters for monitoring; keys are source specific."""
        ...

    @property
    def cursor_us(self) -> int:
        """End of the last window read (source time, µs)."""
        ...

    def now_us(self) -> int:
        """Source time the source has reached now (µs; a file played as fast as possible:
        the cursor). ``read(until_t_us=now_us())`` drains what is there without waiting."""
        ...

    def start(self) -> None:
        """Open the device or file and set the source clock to 0."""
        ...

    def read(self, duration_us: int | None = None, *, until_t_us: int | None = None) -> np.ndarray:
        """Events of the next window, shared event dtype, sorted by ``t``."""
        ...

    def close(self) -> None:
        """Release everything; safe to call more than once."""
        ...

    def __enter__(self) -> EventSource: ...

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None: ...


class EventSourceBase(Closing, ABC):
    """Context manager, state checks and window arithmetic shared by the sources."""

    def __init__(self, sensor_size: SensorSize) -> None:
        self._sensor_size = sensor_size
        self._started = False
        self._closed = False
        self._cursor_us = 0

    @property
    def sensor_size(self) -> SensorSize:
        """``(W, H, 2)``."""
        return self._sensor_size

    @property
    def cursor_us(self) -> int:
        return self._cursor_us

    @property
    def started(self) -> bool:
        return self._started and not self._closed

    @property
    def closed(self) -> bool:
        return self._closed

    @abstractmethod
    def now_us(self) -> int: ...

    @abstractmethod
    def start(self) -> None: ...

    @abstractmethod
    def close(self) -> None: ...

    def __enter__(self) -> EventSourceBase:
        try:
            self.start()
        except BaseException:
            self.close()
            raise
        return self

    def _check_running(self) -> None:
        name = type(self).__name__
        if self._closed:
            raise RuntimeError(f"{name} is closed; create a new one")
        if not self._started:
            raise RuntimeError(f"{name}.read() before start(); call start() or use `with`")

    def _window_end(self, duration_us: int | None, until_t_us: int | None) -> int | None:
        """End of the requested window (µs), or ``None`` for 'what is available now'."""
        if duration_us is not None and until_t_us is not None:
            raise ValueError("give duration_us or until_t_us, not both")
        if duration_us is not None:
            d = int(duration_us)
            if d != duration_us or d < 0:
                raise ValueError(f"duration_us must be a non-negative integer, got {duration_us!r}")
            return self._cursor_us + d
        if until_t_us is not None:
            end = int(until_t_us)
            if end != until_t_us:
                raise ValueError(f"until_t_us must be an integer, got {until_t_us!r}")
            if end < self._cursor_us:
                raise ValueError(
                    f"until_t_us={end} is before the end of the last window ({self._cursor_us})"
                )
            return end
        return None
