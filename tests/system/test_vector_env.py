"""Vector envs without any user wrapper, and the env under ``fork``.

Every vector env (sync, async with the default start method, async with "spawn",
``make_vec`` in both modes) runs 2 envs x 20 steps with different actions per env and
must return exactly the events of the in-process ``make_vec(..., "sync")`` run: the same
packets, event for event (sha256), each as many events as its observation counts.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from locations import ROOT, SUPPORT
from vector_drive import NUM_ENVS, STEPS, WAIT_S, drive_and_close, make_env

import wander_env  # noqa: F401  (registers the environments)
from wander_env import gl_process
from wander_env.gl_process import ForkedGLError, claim_gl


def child_env() -> dict[str, str]:
    """The environment of a fresh Python process that imports this checkout."""
    path = os.pathsep.join(p for p in (str(ROOT), os.environ.get("PYTHONPATH")) if p)
    return {**os.environ, "PYTHONPATH": path}


@pytest.fixture(scope="module")
def sync_run() -> dict:
    return drive_and_close(
        gym.make_vec("wander/Wander-v0", num_envs=NUM_ENVS, vectorization_mode="sync")
    )


@pytest.mark.slow
def test_make_vec_sync_runs_diverging_envs_with_every_event(sync_run):
    rows = sync_run["rows"]
    assert len(rows) == STEPS
    for row in rows:
        assert row["types"] == ["EventPacket"] and row["masks"]
        assert row["counts"] == row["obs_sums"]  # nothing dropped, nothing padded
    # The envs diverge (what used to crash: "could not broadcast (484,) into (1936,)").
    assert sum(r["counts"][0] != r["counts"][1] for r in rows) >= STEPS // 2
    assert sum(sum(r["counts"]) for r in rows) > 10_000
    (pan0, tilt0), (pan1, tilt1) = sync_run["gaze"]
    # Image right/down is negative pan/tilt: env 0 turned right and down, env 1 left and up.
    assert pan0 < -1.0 < 1.0 < pan1 and tilt0 < -0.5 < 0.5 < tilt1, sync_run["gaze"]


@pytest.mark.slow
def test_async_vector_env_with_spawn_gives_the_same_events(sync_run):
    venv = gym.vector.AsyncVectorEnv([make_env] * NUM_ENVS, context="spawn")
    assert drive_and_close(venv) == sync_run


@pytest.mark.slow
def test_default_start_method_in_a_fresh_process_gives_the_same_events(sync_run):
    # The snippet (AsyncVectorEnv of lambdas) and make_vec(..., "async"), both with
    # the default start method, in a process that has rendered nothing.
    env = child_env()
    proc = subprocess.run(
        [sys.executable, str(SUPPORT / "vector_drive.py")],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=3 * WAIT_S,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    assert out["start_method"] == "fork"  # Linux's default: the case that used to hang
    assert out["async_default"] == sync_run
    assert out["make_vec_async"] == sync_run


@pytest.mark.slow
@pytest.mark.filterwarnings("ignore:.*(Worker|main process):UserWarning")  # gymnasium's log
def test_fork_after_rendering_in_the_parent_fails_at_once_naming_spawn():
    env = gym.make("wander/Wander-v0", scene="shelf")
    env.reset(seed=0)  # this process has now initialised OpenGL
    venv = gym.vector.AsyncVectorEnv(
        [lambda: gym.make("wander/Wander-v0", scene="shelf")] * NUM_ENVS, context="fork"
    )
    try:
        venv.reset_async(seed=0)
        with pytest.raises(ForkedGLError, match=r"context='spawn'"):
            venv.reset_wait(timeout=WAIT_S)  # an error, not a TimeoutError
    finally:
        venv.close(terminate=True)
        env.close()


def test_claim_gl_refuses_a_process_forked_after_gl(monkeypatch):
    monkeypatch.setitem(gl_process._GL_OWNER, "pid", os.getpid() + 1)  # as after a fork
    with pytest.raises(ForkedGLError, match=rf"initialised in process {os.getpid() + 1} "):
        claim_gl()
    monkeypatch.setitem(gl_process._GL_OWNER, "pid", None)
    claim_gl()
    assert gl_process.gl_owner_pid() == os.getpid()


def test_the_fork_hook_notes_an_egl_display_initialised_outside_claim_gl(monkeypatch):
    class FakeEGL:
        EGL_DISPLAY = object()

    monkeypatch.setitem(gl_process._GL_OWNER, "pid", None)
    monkeypatch.setitem(sys.modules, "mujoco.egl", FakeEGL)
    gl_process._note_inherited_gl()  # what runs in a forked child
    assert gl_process.gl_owner_pid() == os.getppid()
    monkeypatch.setitem(gl_process._GL_OWNER, "pid", None)
    FakeEGL.EGL_DISPLAY = None
    gl_process._note_inherited_gl()
    assert gl_process.gl_owner_pid() is None


def test_a_renderer_inherited_through_fork_is_refused(monkeypatch):
    env = gym.make("wander/Wander-v0", scene="office").unwrapped  # objects move: a key a step
    env.reset(seed=0)
    monkeypatch.setattr(env.stage, "_renderer_pid", os.getpid() + 1)  # as in a forked child
    with pytest.raises(ForkedGLError, match="spawn"):
        env.step(np.zeros(2, np.float32))
    monkeypatch.undo()
    env.close()


@pytest.mark.slow
def test_importing_and_constructing_creates_no_gl_and_no_thread():
    code = (
        "import os, sys\n"
        "def n(): return len(os.listdir('/proc/self/task'))\n"
        "import numpy, cv2, scipy.ndimage, torch\n"  # the libraries' own import-time threads
        "before = n()\n"
        "import gymnasium as gym, wander_env, wander_env.env, agents\n"
        "env = gym.make('wander/Wander-v0')\n"
        "egl = sys.modules.get('mujoco.egl')\n"
        "stage = env.unwrapped.stage\n"
        "print(n() - before, getattr(egl, 'EGL_DISPLAY', None) is None, stage._renderer)\n"
    )
    if not Path("/proc/self/task").is_dir():
        pytest.skip("needs Linux's /proc")
    env = child_env()
    proc = subprocess.run(
        [sys.executable, "-c", code],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=WAIT_S,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert proc.stdout.split() == ["0", "True", "None"]
