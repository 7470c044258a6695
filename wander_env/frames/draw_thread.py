"""The render thread: one thread that runs the draw side's work, in two queues.

The **step's** work (what the step being made needs) runs in the order handed over.
Work **ahead** of time (the next step's keys, drawn on a guess of its trajectory while
the main thread finishes this step and the agent decides) runs only while none of the
step's work waits, so a guess never delays what is needed now by more than the one
piece of work already running. Work ahead is either :meth:`DrawThread.promote` d to the
step's queue (the guess was right) or :meth:`DrawThread.cancel_ahead` ed (it was not:
what has not started never runs).

Each piece of work gets a :class:`~concurrent.futures.Future` (its result or its
exception, raised where the result is read). The GL context lives on this thread (an
EGL context belongs to the thread that made it current).
"""

from __future__ import annotations

import threading
from collections import deque
from collections.abc import Callable
from concurrent.futures import Future
from typing import Any, TypeVar

__all__ = ["DrawThread"]

T = TypeVar("T")
_Work = tuple[Future, Callable[..., Any], tuple[Any, ...]]


class DrawThread:
    """One thread, the step's queue first, the work ahead when the step's is empty (see
    the module docstring). ``name`` names the thread."""

    def __init__(self, name: str) -> None:
        self._now: deque[_Work] = deque()
        self._ahead: deque[_Work] = deque()
        self._wake = threading.Condition()
        self._closing = False
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)
        self._thread.start()

    @property
    def ident(self) -> int | None:
        """The thread's id."""
        return self._thread.ident

    def submit(self, fn: Callable[..., T], *args: Any, ahead: bool = False) -> Future[T]:
        """Queue ``fn(*args)``: the step's work, or with ``ahead`` work ahead of time."""
        work: _Work = (Future(), fn, args)
        with self._wake:
            if self._closing:
                raise RuntimeError("the render thread is closed")
            (self._ahead if ahead else self._now).append(work)
            self._wake.notify()
        return work[0]

    def promote(self) -> None:
        """The work ahead that has not started joins the step's queue (in its order)."""
        with self._wake:
            self._now.extend(self._ahead)
            self._ahead.clear()

    def cancel_ahead(self) -> None:
        """The work ahead that has not started is cancelled (never runs)."""
        with self._wake:
            for future, _, _ in self._ahead:
                future.cancel()
            self._ahead.clear()

    def close(self) -> None:
        """Cancel the work ahead, run the step's work left, end the thread (idempotent)."""
        self.cancel_ahead()
        with self._wake:
            self._closing = True
            self._wake.notify()
        if self._thread.ident != threading.get_ident():
            self._thread.join()

    def _run(self) -> None:
        while True:
            with self._wake:
                while not (self._now or self._ahead or self._closing):
                    self._wake.wait()
                if self._now:
                    future, fn, args = self._now.popleft()
                elif self._ahead:
                    future, fn, args = self._ahead.popleft()
                else:  # closing, nothing left
                    return
            if not future.set_running_or_notify_cancel():
                continue
            try:
                future.set_result(fn(*args))
            except BaseException as e:  # raised where the result is read
                future.set_exception(e)
