"""The render thread's two queues (:mod:`wander_env.frames.draw_thread`): the step's work in
the order handed over and before any work ahead; work ahead promoted keeps its order,
cancelled never runs; an error is raised where the result is read; close runs the step's
work left and ends the thread."""

from __future__ import annotations

import threading

import pytest

from wander_env.frames.draw_thread import DrawThread


def _blocked(thread: DrawThread) -> threading.Event:
    """Hold the thread on a first piece of work until the returned event is set."""
    go = threading.Event()
    thread.submit(go.wait)
    return go


def test_the_steps_work_runs_before_the_work_ahead_and_each_in_its_order() -> None:
    thread, ran = DrawThread("test-draw"), []
    try:
        go = _blocked(thread)
        ahead = [thread.submit(ran.append, f"ahead{k}", ahead=True) for k in range(2)]
        now = [thread.submit(ran.append, f"now{k}") for k in range(3)]
        go.set()
        for f in [*now, *ahead]:
            f.result(timeout=60)
        assert ran == ["now0", "now1", "now2", "ahead0", "ahead1"]
    finally:
        thread.close()


def test_promoted_work_joins_the_steps_queue_in_order_and_cancelled_work_never_runs() -> None:
    thread, ran = DrawThread("test-draw"), []
    try:
        go = _blocked(thread)
        first = [thread.submit(ran.append, f"a{k}", ahead=True) for k in range(2)]
        thread.promote()
        later = thread.submit(ran.append, "now")
        dropped = [thread.submit(ran.append, f"b{k}", ahead=True) for k in range(2)]
        thread.cancel_ahead()
        go.set()
        later.result(timeout=60)
        thread.submit(lambda: None).result(timeout=60)
        assert ran == ["a0", "a1", "now"]
        assert all(f.cancelled() for f in dropped) and not any(f.cancelled() for f in first)
    finally:
        thread.close()


def test_an_error_is_raised_where_the_result_is_read() -> None:
    thread = DrawThread("test-draw")
    try:
        bad = thread.submit(int, "not a number")
        with pytest.raises(ValueError, match="not a number"):
            bad.result(timeout=60)
        assert thread.submit(int, "7").result(timeout=60) == 7
    finally:
        thread.close()


def test_close_runs_the_steps_work_left_cancels_the_work_ahead_and_ends_the_thread() -> None:
    thread, ran = DrawThread("test-draw"), []
    go = _blocked(thread)
    now = thread.submit(ran.append, "now")
    ahead = thread.submit(ran.append, "ahead", ahead=True)
    closer = threading.Thread(target=thread.close)
    closer.start()
    go.set()
    closer.join(timeout=60)
    assert not closer.is_alive()
    assert ran == ["now"] and now.done() and ahead.cancelled()
    assert not any(t.name.startswith("test-draw") for t in threading.enumerate())
    with pytest.raises(RuntimeError, match="closed"):
        thread.submit(ran.append, "late")


def test_a_thread_dropped_without_close_ends() -> None:
    """Its owner gone (an env never closed), the thread ends once its work has run."""
    import gc

    thread = DrawThread("test-dropped")
    assert thread.submit(int, "3").result(timeout=60) == 3
    worker = next(t for t in threading.enumerate() if t.name.startswith("test-dropped"))
    del thread
    gc.collect()
    worker.join(timeout=60)
    assert not worker.is_alive()
