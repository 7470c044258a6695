"""A clock for tests that must not depend on the wall clock.

:class:`FakeClock` stands in for ``time.monotonic``/``time.sleep``: it moves only when it
is slept on, when the test moves it (``clock.t += ...``), or, with ``step``, by ``step``
seconds each time it is read (so a loop that polls it until a deadline ends after a
known number of reads, however slow the host). Code under test takes it through its
``clock``/``sleep`` arguments, or a test puts :meth:`FakeClock.module` in place of a
module's ``time``.
"""

from __future__ import annotations

from types import SimpleNamespace


class FakeClock:
    """A monotonic clock (seconds) that moves only when slept on, by hand, or by ``step``
    per reading; keeps the sleeps and counts the readings."""

    def __init__(self, step: float = 0.0) -> None:
        self.t = 0.0
        self.step = step
        self.reads = 0
        self.sleeps: list[float] = []

    def __call__(self) -> float:
        now = self.t
        self.t += self.step
        self.reads += 1
        return now

    def sleep(self, seconds: float) -> None:
        self.sleeps.append(seconds)
        self.t += seconds

    def module(self) -> SimpleNamespace:
        """A stand-in for the ``time`` module: ``monotonic`` and ``sleep`` on this clock."""
        return SimpleNamespace(monotonic=self, sleep=self.sleep)
