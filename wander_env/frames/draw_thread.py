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
from concurrent.futures import Future, ThreadPoolExecutor
from typing import Any, TypeVar

__all__ = ["DrawThread"]

T = TypeVar("T")
_Work = tuple[Future, Callable[..., Any], tuple[Any, ...]]


class _Queues:
    """The two queues and their lock, shared by the owner and the thread's pumps (which
    never hold the :class:`DrawThread`: an owner dropped without closing still lets the
    executor's thread end)."""

    def __init__(self) -> None:
        self.now: deque[_Work] = deque()
        self.ahead: deque[_Work] = deque()
        self.lock = threading.Lock()
        self.closed = False

    def next(self) -> _Work | None:
        """The next piece of work: the step's first (None: nothing left)."""
        with self.lock:
            if self.now:
                return self.now.popleft()
            if self.ahead:
                return self.ahead.popleft()
            return None

    def cancel_ahead(self) -> None:
        with self.lock:
            for future, _, _ in self.ahead:
                future.cancel()
            self.ahead.clear()


def _pump(queues: _Queues) -> None:
    """(On the thread.) Run one piece of work, chosen now: one pump is queued on the
    executor per piece handed over, so every piece runs (or was cancelled)."""
    work = queues.next()
    if work is None:
        return
    future, fn, args = work
    if not future.set_running_or_notify_cancel():
        return
    try:
        future.set_result(fn(*args))
    except BaseException as e:  # raised where the result is read
        future.set_exception(e)


class DrawThread:
    """One thread (a one-worker ``ThreadPoolExecutor``: joined at the interpreter's exit,
    ended when dropped), the step's queue first, the work ahead when the step's is empty
    (see the module docstring). ``name`` prefixes the thread's name."""

    def __init__(self, name: str) -> None:
        self._q = _Queues()
        self._executor = ThreadPoolExecutor(1, thread_name_prefix=name)
        self.ident: int = self._executor.submit(threading.get_ident).result()

    def submit(self, fn: Callable[..., T], *args: Any, ahead: bool = False) -> Future[T]:
        """Queue ``fn(*args)``: the step's work, or with ``ahead`` work ahead of time."""
        work: _Work = (Future(), fn, args)
        q = self._q
        with q.lock:
            if q.closed:
                raise RuntimeError("the render thread is closed")
            (q.ahead if ahead else q.now).append(work)
        self._executor.submit(_pump, q)
        return work[0]

    def promote(self) -> None:
        """The work ahead that has not started joins the step's queue (in its order)."""
        q = self._q
        with q.lock:
            q.now.extend(q.ahead)
            q.ahead.clear()

    def cancel_ahead(self) -> None:
        """The work ahead that has not started is cancelled (never runs)."""
        self._q.cancel_ahead()

    def close(self) -> None:
        """Cancel the work ahead, run the step's work left, end the thread (idempotent)."""
        q = self._q
        q.cancel_ahead()
        with q.lock:
            q.closed = True
        self._executor.shutdown(wait=threading.get_ident() != self.ident)
