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

import atexit
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
    """The two queues, their lock and whether the thread is to end, shared by the owner
    and the thread (which never holds the :class:`DrawThread`: an owner dropped without
    closing still ends it)."""

    def __init__(self) -> None:
        self.now: deque[_Work] = deque()
        self.ahead: deque[_Work] = deque()
        self.wake = threading.Condition()
        self.closing = False

    def cancel_ahead(self) -> None:
        with self.wake:
            for future, _, _ in self.ahead:
                future.cancel()
            self.ahead.clear()

    def end(self) -> None:
        """Cancel the work ahead; the thread ends once the step's work left has run."""
        with self.wake:  # (a re-entrant lock: cancel_ahead takes it again)
            self.cancel_ahead()
            self.closing = True
            self.wake.notify()

    def next(self) -> _Work | None:
        """The next piece of work, waited for: the step's first (None: the thread ends)."""
        with self.wake:
            while not (self.now or self.ahead or self.closing):
                self.wake.wait()
            if self.now:
                return self.now.popleft()
            if self.ahead:
                return self.ahead.popleft()
            return None


def _serve(queues: _Queues) -> None:
    """The thread's loop (holds nothing of a piece of work while it waits)."""
    while (work := queues.next()) is not None:
        _run(work)
        del work


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
    the module docstring); ``name`` names the thread. Handing work over takes only this
    object's own lock (no lock another thread's fork waits on: a ``ThreadPoolExecutor``'s
    submit holds the lock its fork hook takes). Ended when closed, when dropped, or at
    the interpreter's exit."""

    def __init__(self, name: str) -> None:
        self._q = _Queues()
        self._thread = threading.Thread(target=_serve, args=(self._q,), name=name, daemon=True)
        self._thread.start()
        self._at_exit = _AtExit(self._q, self._thread)
        atexit.register(self._at_exit)
        # Dropped without close: the thread ends, and the exit hook goes with it.
        weakref.finalize(self, self._at_exit.drop)

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
        self._q.cancel_ahead()

    def settle(self) -> None:
        """Wait until the step's work handed over so far, and the piece running now, have
        run (work ahead still queued runs after; not from the thread itself)."""
        self.submit(lambda: None).result()

    def close(self) -> None:
        """Cancel the work ahead, run the step's work left, end the thread (idempotent)."""
        self._at_exit.drop()
        self._at_exit.join()


class _AtExit:
    """The exit hook of one thread: ends and joins it (once); :meth:`drop` ends it
    without waiting and unregisters the hook."""

    def __init__(self, queues: _Queues, thread: threading.Thread) -> None:
        self.queues, self.thread = queues, thread

    def __call__(self) -> None:
        self.queues.end()
        self.join()

    def join(self) -> None:
        """Wait for the thread to end (unless called on it)."""
        if self.thread.ident != threading.get_ident():
            self.thread.join()

    def drop(self) -> None:
        self.queues.end()
        atexit.unregister(self)
