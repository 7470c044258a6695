"""What a speed table says beside its wall times: the process's CPU time and the load
average while it was measured.

Wall time on a shared machine moves with its load; the process's CPU time
(``time.process_time``: every thread of this process, not its children) moves far less.
A :class:`Clock` accumulates both over the spans it times and keeps the 1-minute load
average when its first span began and its last ended; :func:`timed` wraps a function so
that each call is such a span (its wall and CPU seconds kept per call, for percentiles).
Every speed table of ``wander perf env|agent|floor|dvs`` has, beside its wall-time
columns, the CPU time of the same spans and a ``load`` column (:data:`LOAD_COLUMN`,
``start-end``): its rows are :class:`Measured`.

Examples:
    >>> clock = Clock()
    >>> with clock.span():
    ...     _ = sum(range(1000))
    >>> clock.spans, clock.wall_s > 0, clock.cpu_s >= 0, len(clock.load.split("-"))
    (1, True, True, 2)
    >>> Clock().load
    '–'
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any

__all__ = ["LOAD_COLUMN", "Clock", "Measured", "Timings", "timed"]

#: The ``load`` column of a speed table (row field -> format spec).
LOAD_COLUMN: dict[str, str] = {"load": ""}


@dataclass(frozen=True, kw_only=True)
class Measured:
    """A speed table's row: ``load``, the 1-minute load average around its measurement
    (:attr:`Clock.load`, ``start-end``; ``–`` where none was taken), given by keyword
    after the row's own fields."""

    load: str = "–"


@dataclass
class Clock:
    """Wall and process CPU seconds summed over timed spans, and the 1-minute load average
    at the first span's start and the last span's end."""

    wall_s: float = 0.0
    cpu_s: float = 0.0
    spans: int = 0
    load_start: float = float("nan")
    load_end: float = float("nan")

    @contextmanager
    def span(self) -> Iterator[None]:
        """Time the ``with`` block into the sums."""
        if self.spans == 0:
            self.load_start = os.getloadavg()[0]
        w, c = time.perf_counter(), time.process_time()
        try:
            yield
        finally:
            self.add(time.perf_counter() - w, time.process_time() - c)

    def add(self, wall_s: float, cpu_s: float) -> None:
        """One span measured elsewhere (its end is now)."""
        if math.isnan(self.load_start):
            self.load_start = os.getloadavg()[0]
        self.wall_s += wall_s
        self.cpu_s += cpu_s
        self.spans += 1
        self.load_end = os.getloadavg()[0]

    def ms_per(self, n: int) -> tuple[float, float]:
        """(wall, CPU) milliseconds per one of ``n`` (steps, calls)."""
        return 1e3 * self.wall_s / n, 1e3 * self.cpu_s / n

    @property
    def load(self) -> str:
        """``start-end`` 1-minute load averages (``–`` before any span)."""
        if self.spans == 0:
            return "–"
        return f"{self.load_start:.2f}-{self.load_end:.2f}"


@dataclass
class Timings:
    """Per key, each timed call's wall and CPU seconds."""

    wall: dict[str, list[float]] = field(default_factory=dict)
    cpu: dict[str, list[float]] = field(default_factory=dict)

    def add(self, key: str, wall_s: float, cpu_s: float) -> None:
        self.wall.setdefault(key, []).append(wall_s)
        self.cpu.setdefault(key, []).append(cpu_s)

    def clear(self) -> None:
        """Forget every call (after a warm-up)."""
        self.wall, self.cpu = {}, {}


def timed(fn: Callable[..., Any], timings: Timings, key: str) -> Callable[..., Any]:
    """``fn`` wrapped so that each call's wall and CPU seconds go to ``timings`` under
    ``key``."""

    def wrapper(*args: Any, **kwargs: Any) -> Any:
        w, c = time.perf_counter(), time.process_time()
        try:
            return fn(*args, **kwargs)
        finally:
            timings.add(key, time.perf_counter() - w, time.process_time() - c)

    return wrapper
