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
import weakref
from collections import deque
from collections.abc import Callable
from concurrent.futures import Future
from typing import Any, TypeVar

__all__ = ["DrawThread"]

T = TypeVar("T")
_Work = tuple[Future, Callable[..., Any], tuple[Any, ...]]


class _Queues:
    """What the thread and its owner share: the two queues, their lock and whether the
    thread is to end (the thread holds this, never the :class:`DrawThread`, so an owner
    dropped without :meth:`DrawThread.close` still ends it)."""

    def __init__(self) -> None:
        self.now: deque[_Work] = deque()
        self.ahead: deque[_Work] = deque()
        self.wake = threading.Condition()
        self.closing = False

    def end(self) -> None:
        """Cancel the work ahead; the thread ends once the step's work left has run."""
        with self.wake:
            for future, _, _ in self.ahead:
                future.cancel()
            self.ahead.clear()
            self.closing = True
            self.wake.notify()


def _serve(queues: _Queues) -> None:
    """The thread's loop: the step's work first, then the work ahead, until it ends."""
    while (work := _next(queues)) is not None:
        _run(work)
        del work  # hold nothing of the work while waiting for the next


def _next(queues: _Queues) -> _Work | None:
    """The next piece of work, waited for (None: the thread is to end)."""
    with queues.wake:
        while not (queues.now or queues.ahead or queues.closing):
            queues.wake.wait()
        if queues.now:
            return queues.now.popleft()
        if queues.ahead:
            return queues.ahead.popleft()
        return None  # closing, nothing left


def _run(work: _Work) -> None:
    future, fn, args = work
    if not future.set_running_or_notify_cancel():
        return
    try:
        future.set_result(fn(*args))
    except BaseException as e:  # raised where the result is read
        future.set_exception(e)


class DrawThread:
    """One thread, the step's queue first, the work ahead when the step's is empty (see
    the module docstring). ``name`` names the thread. Dropped without :meth:`close`, it
    still ends its thread (as a ``ThreadPoolExecutor`` does)."""

    def __init__(self, name: str) -> None:
        self._q = _Queues()
        self._thread = threading.Thread(target=_serve, args=(self._q,), name=name, daemon=True)
        self._thread.start()
        weakref.finalize(self, self._q.end)

    @property
    def ident(self) -> int | None:
        """The thread's id."""
        return self._thread.ident

    def submit(self, fn: Callable[..., T], *args: Any, ahead: bool = False) -> Future[T]:
        """Queue ``fn(*args)``: the step's work, or with ``ahead`` work ahead of time."""
        work: _Work = (Future(), fn, args)
        q = self._q
        with q.wake:
            if q.closing:
                raise RuntimeError("the render thread is closed")
            (q.ahead if ahead else q.now).append(work)
            q.wake.notify()
        return work[0]

    def promote(self) -> None:
        """The work ahead that has not started joins the step's queue (in its order)."""
        q = self._q
        with q.wake:
            q.now.extend(q.ahead)
            q.ahead.clear()

    def cancel_ahead(self) -> None:
        """The work ahead that has not started is cancelled (never runs)."""
        q = self._q
        with q.wake:
            for future, _, _ in q.ahead:
                future.cancel()
            q.ahead.clear()

    def close(self) -> None:
        """Cancel the work ahead, run the step's work left, end the thread (idempotent)."""
        self._q.end()
        if self._thread.ident != threading.get_ident():
            self._thread.join()
