"""One shutdown path for every long command: SIGINT, SIGTERM and SIGHUP alike.

Schedulers (Slurm, systemd, Ray, ``docker stop``) send SIGTERM, a closed terminal
SIGHUP, Ctrl-C SIGINT. Inside :func:`handle_signals` each of them raises
:class:`SignalExit` in the main thread, a ``KeyboardInterrupt``, so the code that
already cleans up after Ctrl-C (halting the PTU, closing the camera, flushing and
closing the run's files, writing ``metrics.json`` with the error) runs for all three,
and a sleep or a wait in Python code wakes up. Further signals while that clean-up
runs are reported and ignored (it is bounded by the devices' timeouts); a third ends
the process at once. A signal that lands where Python drops exceptions (a ``__del__``,
a weakref callback) is delivered again.

A step loop does not take a signal where it lands: an exception raised inside foreign
code (a ctypes call into EGL, a C extension's callback, ffmpeg's pipe) can come out as
another exception (``ctypes.ArgumentError``) or leave the library half-way. Inside
:class:`DeferredSignals` (the loop owns it) a signal only sets a flag: the loop calls
:meth:`DeferredSignals.check` between steps, which raises it there through the handler
it deferred (:class:`SignalExit` under :func:`handle_signals`), and the end of the block
raises one that came after the loop (while the run folder was written), so the folder
is finished first. The waits in a step are bounded (device timeouts); a second signal
before the loop took up the first is raised at once, wherever the main thread waits, once
the first has waited ``wake_after_s`` (1 s) for the loop: one sent with it (``kill`` twice,
a scheduler and a terminal alike) lands in the same step's foreign code, and is only
reported. A signal that foreign code turned into another error anyway is what
:attr:`DeferredSignals.raised` records: the episode loop reports that, not the other error.

:func:`experiments.cli.errors.long_command` wraps a command in it; what a signal or a
failed write leaves in the run folder is :class:`experiments.runs.folder.RunFolder`'s
(``metrics.json``'s ``error`` and ``signal``, the ``INCOMPLETE`` marker), the one line and
the exit code are :mod:`experiments.runs.failure`'s.

Examples:
    >>> import os, signal
    >>> try:
    ...     with handle_signals():
    ...         os.kill(os.getpid(), signal.SIGTERM)
    ...         import time; time.sleep(5)
    ... except SignalExit as stop:
    ...     print(stop.name, stop.exit_code)
    SIGTERM 143
    >>> steps = []
    >>> try:
    ...     with handle_signals(), DeferredSignals() as signals:
    ...         for k in range(3):
    ...             signals.check()  # between steps
    ...             steps.append(k)
    ...             if k == 1:
    ...                 os.kill(os.getpid(), signal.SIGTERM)  # lands in step 1: only noted
    ... except SignalExit as stop:
    ...     print(stop.name, steps)
    SIGTERM [0, 1]
"""

from __future__ import annotations

import os
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

from wander_env.closing import Closing

SIGNALS: tuple[signal.Signals, ...] = tuple(
    getattr(signal, name) for name in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, name)
)


class SignalExit(KeyboardInterrupt):
    """A termination signal arrived: ``signum``, ``name``, ``exit_code`` (128 + signum)."""

    def __init__(self, signum: int) -> None:
        self.signum = int(signum)
        self.name = signal.Signals(signum).name
        self.exit_code = 128 + self.signum
        super().__init__(f"stopped by {self.name} (signal {self.signum})")


class Received:
    """The signals :func:`handle_signals` received, in order (``signums``)."""

    def __init__(self) -> None:
        self.signums: list[int] = []

    def first(self) -> SignalExit | None:
        """The first signal as a :class:`SignalExit` (``None``: none came)."""
        return SignalExit(self.signums[0]) if self.signums else None


def _repeated(signum: int, count: int) -> None:
    """The ``count``-th signal (2 or more) while shutting down: say so; the third ends the
    process at once."""
    name = signal.Signals(signum).name
    if count >= 3:
        os.write(2, f"{name} again: exiting without finishing the clean-up\n".encode())
        os._exit(128 + signum)
    os.write(2, f"{name}: already shutting down (a third signal exits at once)\n".encode())


@contextmanager
def handle_signals(signals: tuple[int, ...] = SIGNALS) -> Iterator[Received]:
    """Raise :class:`SignalExit` for ``signals`` inside the block (main thread only;
    elsewhere the block runs with the handlers as they are). Yields the
    :class:`Received` record of the signals that came."""
    received = Received()
    if threading.current_thread() is not threading.main_thread():
        yield received
        return
    seen = received.signums

    def handler(signum: int, frame: Any) -> None:
        seen.append(signum)
        if len(seen) == 1:
            raise SignalExit(signum)
        _repeated(signum, len(seen))

    hook = sys.unraisablehook

    def unraisable(info: Any) -> None:
        # The signal landed in a __del__ or weakref callback, where Python drops
        # exceptions: deliver it once more, so it reaches the command.
        if isinstance(info.exc_value, SignalExit) and len(seen) == 1:
            seen.clear()
            again = threading.Timer(0.02, os.kill, (os.getpid(), info.exc_value.signum))
            again.daemon = True  # from another thread: it lands after this callback
            again.start()
            return
        hook(info)

    previous = {s: signal.getsignal(s) for s in signals}
    for s in signals:
        signal.signal(s, handler)
    sys.unraisablehook = unraisable
    try:
        yield received
    finally:
        sys.unraisablehook = hook
        for s, h in previous.items():
            signal.signal(s, h if h is not None else signal.SIG_DFL)


class DeferredSignals(Closing):
    """Inside ``with DeferredSignals() as signals:`` a termination signal only sets a flag.

    The loop that owns the block calls :meth:`check` between steps: a signal that came is
    raised there, by the handler it deferred (:func:`handle_signals`' raises
    :class:`SignalExit`; Python's own SIGINT handler ``KeyboardInterrupt``). Leaving the
    block raises a signal that was not taken up yet (one that came after the loop, while
    its results were written), after the block's writes. Only signals with a Python
    handler are deferred (a signal left at its default still ends the process at once);
    outside the main thread the block defers nothing.

    A deferred signal does not wake a wait: every wait inside the block is bounded (a
    step's device reads and the devices' timeouts, the video's close). A second signal
    that comes before the first was taken up is raised at once, where the main thread is,
    to wake a wait that takes too long (the rig's PTU settling at ``reset``); one after it
    was taken up is reported and ignored; a third ends the process at once, as under
    :func:`handle_signals`.

    A second signal within ``wake_after_s`` of the first (two sent back to back) is
    reported and not raised: the loop takes the first up at the end of the step, and
    raising it inside the step's foreign code would turn it into another error.

    ``signum``: the first signal that came (``None``: none); ``pending``: it came and was
    not raised yet; ``raised``: the exception raised for it (``None``: not raised yet).
    """

    def __init__(self, signals: tuple[int, ...] = SIGNALS, wake_after_s: float = 1.0) -> None:
        self.signals = signals
        self.wake_after_s = wake_after_s
        self.signum: int | None = None
        self.raised: BaseException | None = None
        self._first_at = 0.0
        self._count = 0
        self._raised = False
        self._previous: dict[int, Callable[[int, Any], Any]] = {}

    @property
    def pending(self) -> bool:
        return self.signum is not None and not self._raised

    def __enter__(self) -> DeferredSignals:
        if threading.current_thread() is threading.main_thread():
            for s in self.signals:
                handler = signal.getsignal(s)
                if callable(handler):
                    self._previous[s] = handler
                    signal.signal(s, self._note)
        return self

    def _note(self, signum: int, frame: Any) -> None:
        self._count += 1
        if self._count == 1:
            self.signum = signum
            self._first_at = time.monotonic()
        elif self._raised:
            _repeated(signum, self._count)
        elif time.monotonic() - self._first_at >= self.wake_after_s:
            self.check()  # the first waited too long for the loop (a wait): raise it now
        else:  # sent with the first: the loop takes the first up at the end of this step
            name = signal.Signals(signum).name
            os.write(2, f"{name}: already stopping at the end of this step\n".encode())

    def check(self) -> None:
        """Raise the signal that came, if it was not raised yet (call between steps)."""
        if self.signum is not None and not self._raised:
            self._raised = True
            try:
                self._previous[self.signum](self.signum, None)
            except BaseException as exc:
                self.raised = exc
                raise

    def close(self) -> None:
        """Leave the block: the handlers put back, then a signal that came and was not
        raised yet raised (by the handler it deferred)."""
        for s, handler in self._previous.items():
            signal.signal(s, handler)
        self.check()


__all__ = [
    "SIGNALS",
    "DeferredSignals",
    "Received",
    "SignalExit",
    "handle_signals",
]
