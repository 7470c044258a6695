"""A renderer closed or dropped on a thread other than the one it draws on leaves the GL
objects of the renderer drawing there intact.

Two renderers of one model hold the same GL object names, each in its own GL context.
MuJoCo frees a render context by those names in whatever GL context is current when it
runs, so a renderer freed on a thread drawing with another deleted that renderer's
buffers, textures and display lists (seen: its masks read garbage ids).

Renderers on different threads draw one at a time (the process's GL lock), and a child
forked while a thread of its parent held that lock gets a lock of its own.
"""

from __future__ import annotations

import os

os.environ.setdefault("MUJOCO_GL", "egl")  # before mujoco is imported: headless rendering

import gc
import threading
import time
import warnings
from collections.abc import Iterator

import mujoco
import numpy as np
import pytest

from wander_env.gl_process import gl_lock
from wander_env.mjcf import compile_scene
from wander_env.renderer import CameraRenderer
from wander_env.scenes import load_scene_config


@pytest.fixture(scope="module")
def posed() -> tuple[mujoco.MjModel, mujoco.MjData]:
    model = compile_scene(load_scene_config("office"))
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    return model, data


@pytest.fixture
def elsewhere(posed) -> Iterator[dict[str, CameraRenderer]]:
    """A renderer made and drawn on a thread of its own, which stays alive (its GL context
    current there) until the test ends."""
    model, data = posed
    held: dict[str, CameraRenderer] = {}
    made, done = threading.Event(), threading.Event()

    def draw_there() -> None:
        held["renderer"] = CameraRenderer(model)
        held["renderer"].render(data)
        made.set()
        done.wait(60)

    thread = threading.Thread(target=draw_there, daemon=True)
    thread.start()
    assert made.wait(60)
    yield held
    done.set()
    thread.join(60)


def test_a_renderer_dropped_here_without_close_frees_nothing_of_this_threads(posed, elsewhere):
    model, data = posed
    with CameraRenderer(model) as here:
        rgb, mask = here.render_with_mask(data)
        assert int(mask.max()) == 2 and len(np.unique(rgb)) > 10
        with pytest.warns(ResourceWarning, match=r"CameraRenderer \(128x128\) dropped"):
            del elsewhere["renderer"]
            gc.collect()
        rgb_after, mask_after = here.render_with_mask(data)
    assert np.array_equal(rgb_after, rgb)
    assert np.array_equal(mask_after, mask)


def test_closing_a_renderer_current_on_another_thread_forgets_it(posed, elsewhere):
    """Its GL context cannot be made current here: close() forgets its GL objects (no
    error, closed after) and this thread's renderer draws the same frames."""
    model, data = posed
    there = elsewhere["renderer"]
    with CameraRenderer(model) as here:
        rgb, mask = here.render_with_mask(data)
        there.close()
        with pytest.raises(RuntimeError, match="closed"):
            there.render(data)
        rgb_after, mask_after = here.render_with_mask(data)
    assert np.array_equal(rgb_after, rgb)
    assert np.array_equal(mask_after, mask)


def test_a_renderer_closed_on_its_own_thread_is_freed_there(posed):
    """The usual path: closed where it draws, it frees its GL objects, warns nothing,
    and a renderer made after draws the same frames as one made before."""
    model, data = posed
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        with CameraRenderer(model) as before:
            expected = before.render_with_mask(data)
        del before
        gc.collect()
        with CameraRenderer(model) as again:
            got = again.render_with_mask(data)
    assert [w for w in caught if issubclass(w.category, ResourceWarning)] == []
    assert np.array_equal(got[0], expected[0]) and np.array_equal(got[1], expected[1])


def test_abandoning_a_skinned_models_renderer_clears_its_names_and_raises_nothing():
    """A skin's buffer names cannot be cleared from Python (read-only); abandoning still
    clears every other name and forgets the renderer (as in a forked child)."""
    xml = """<mujoco><worldbody><body name="b"><geom type="sphere" size="0.1"/></body>
      <camera name="event_camera" pos="0 0 1"/></worldbody>
      <deformable><skin name="s" vertex="0 0 0 1 0 0 0 1 0 0 0 1"
        face="0 1 2 0 2 3 0 3 1 1 3 2"><bone body="b" bindpos="0 0 0" bindquat="1 0 0 0"
        vertid="0 1 2 3" vertweight="1 1 1 1"/></skin></deformable></mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    renderer = CameraRenderer(model, 64, 64)
    con = renderer._con
    assert con.nskin == 1 and con.offFBO > 0 and con.rangeBuiltin > 0
    renderer.abandon()
    assert (con.offFBO, con.rangeBuiltin, con.ntexture) == (0, 0, 0)
    assert renderer._con is None and renderer._gl is None
    renderer.close()  # (a no-op now)


def test_renderers_on_two_threads_draw_one_at_a_time(posed, monkeypatch):
    """Each draw (``mjr_render`` made slow here, 2 ms) runs while no other thread draws:
    of 2 × 15 draws on two threads, at most one is ever inside ``mjr_render``, and each
    thread's frames are the ones a lone renderer draws."""
    model, data = posed
    inside, most = [0], [0]
    count = threading.Lock()
    render = mujoco.mjr_render

    def slow_render(*args):
        with count:
            inside[0] += 1
            most[0] = max(most[0], inside[0])
        time.sleep(0.002)
        render(*args)
        with count:
            inside[0] -= 1

    with CameraRenderer(model) as lone:
        expected = lone.render(data)
    monkeypatch.setattr(mujoco, "mjr_render", slow_render)
    frames: dict[int, list[np.ndarray]] = {0: [], 1: []}
    start = threading.Barrier(2)

    def draw(k: int) -> None:
        with CameraRenderer(model) as renderer:
            start.wait(60)
            frames[k] = [renderer.render(data) for _ in range(15)]

    threads = [threading.Thread(target=draw, args=(k,)) for k in (0, 1)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(120)
    assert most[0] == 1
    assert [len(f) for f in frames.values()] == [15, 15]
    assert all(np.array_equal(rgb, expected) for f in frames.values() for rgb in f)


@pytest.mark.skipif(not hasattr(os, "fork"), reason="needs fork")
def test_a_child_forked_while_a_thread_holds_the_gl_lock_gets_a_free_one():
    """The parent's lock is held by another thread at the fork; the child takes its own
    at once (exit status 0) instead of waiting for a thread it does not have."""
    held, release = threading.Event(), threading.Event()

    def hold() -> None:
        with gl_lock():
            held.set()
            release.wait(60)

    holder = threading.Thread(target=hold)
    holder.start()
    assert held.wait(60)
    try:
        pid = os.fork()
        if pid == 0:  # the child: exit at once, without the parent's cleanup
            os._exit(0 if gl_lock().acquire(timeout=10) else 1)
        _, status = os.waitpid(pid, 0)
    finally:
        release.set()
        holder.join(60)
    assert os.waitstatus_to_exitcode(status) == 0
    assert gl_lock().acquire(blocking=False)  # and the parent's is free again
    gl_lock().release()
