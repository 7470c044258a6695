"""The render thread (``WanderConfig.render_thread``): the same seed gives the same events,
ground truth, camera frames and draw counts with and without it in every frame mode, and
the same actions and decisions in the closed loop; an error on the thread is raised in
the caller; a process forked after drawing refuses to draw; ``close`` joins the thread."""

from __future__ import annotations

import os
import signal
import threading

import gymnasium as gym
import numpy as np
import pytest

import wander_env  # noqa: F401  (registers the environments)
from wander_env.gl_process import ForkedGLError

ACTIONS = [np.array([0.5, -0.3], np.float32)] + [
    np.array([0.01 * ((k * 7) % 5 - 2), 0.01 * ((k * 3) % 5 - 2)], np.float32) for k in range(9)
]


def _render_threads() -> set[threading.Thread]:
    """The render threads alive now, this test's and any other's: an env another test
    dropped without closing ends its thread only when the garbage collector gets to it,
    so each test compares with the set it started with."""
    return {t for t in threading.enumerate() if t.name.startswith("wander-render")}


def _trace(frames: str, render_thread: bool, warm_up: bool = False) -> list[tuple]:
    before = _render_threads()
    env = gym.make("wander/Wander-v0", scene="office", frames=frames, render_thread=render_thread)
    u = env.unwrapped
    if warm_up:
        u.warm_up()
    try:
        _, info = env.reset(seed=2)
        out = [(info["object_mask"].tobytes(), u.renders_in_step, u.camera_frame.tobytes())]
        for a in ACTIONS:
            obs, _, _, _, info = env.step(a)
            out.append(
                (
                    info["events"].events.tobytes(),
                    obs["events"].tobytes(),
                    info["object_mask"].tobytes(),
                    repr(info["objects"]),
                    info["frames"],
                    info["extra_frames"],
                    u.renders_in_step,
                    u.stage.geometry_draws,
                    u.camera_frame.tobytes(),
                )
            )
        assert (len(_render_threads() - before) == 1) == render_thread
        return out
    finally:
        env.close()


@pytest.mark.slow
@pytest.mark.parametrize("frames", ["keyframes", "exact", "panorama"])
def test_the_render_thread_changes_nothing_but_where_the_drawing_runs(frames: str) -> None:
    """A saccade then a fixational walk, 10 steps: every step's events, counts, mask,
    objects, frame counts, draw counts and camera frame identical, byte for byte."""
    before = _render_threads()
    off, on = _trace(frames, False), _trace(frames, True)
    assert sum(len(s[0]) for s in off[1:]) > 0  # events were made
    assert on == off
    assert _render_threads() <= before  # close() joined it


def test_warm_up_makes_the_gl_contexts_before_the_reset_and_changes_no_event(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """``warm_up`` makes both GL contexts (the renderer's, the caster's cube's) on the
    render thread before the first reset, which then makes none (nor does any other
    thread: only the render thread draws); every step's events, mask, counts and camera
    frame are those of an env not warmed up, byte for byte."""
    from wander_env.renderer import CameraRenderer

    made: list[tuple[int, int, str]] = []
    init = CameraRenderer.__init__

    def counted(self, model, width, height, *args, **kwargs) -> None:
        init(self, model, width, height, *args, **kwargs)
        made.append((width, height, threading.current_thread().name))

    monkeypatch.setattr(CameraRenderer, "__init__", counted)
    env = gym.make("wander/Wander-v0", scene="office")
    try:
        env.unwrapped.warm_up()
        env.unwrapped.stage.drain()
        stage = env.unwrapped.stage  # the cube's faces: cube_samples x 2f a side
        n = round(2 * stage.k[0, 0] * stage.caster.params.cube_samples)
        assert made == [(128, 128, "wander-render"), (n, n, "wander-render")]
        env.reset(seed=2)
        env.step(ACTIONS[0])
        assert len(made) == 2
    finally:
        env.close()
    assert _trace("keyframes", True, warm_up=True) == _trace("keyframes", True)


def _ahead_trace(actions: list[np.ndarray], draw_ahead: bool) -> tuple[list, list, int, int]:
    """Per step: events, mask and renders; and the keys drawn ahead adopted, dropped."""
    env = gym.make("wander/Wander-v0", scene="office", episode_seconds=len(actions) * 0.01)
    u = env.unwrapped
    if not draw_ahead:
        u.source.plan_ahead = lambda trajectory: None
    try:
        env.reset(seed=4)
        steps, renders = [], []
        for a in actions:
            _, _, _, truncated, info = env.step(a)
            steps.append((info["events"].events.tobytes(), info["object_mask"].tobytes()))
            renders.append(u.renders_in_step)
        assert truncated  # the episode ends with the last action: nothing drawn beyond it
        return steps, renders, u.source.keys_ahead_adopted, u.source.keys_ahead_dropped
    finally:
        env.close()


def test_keys_drawn_ahead_on_the_left_alone_guess_are_adopted_and_change_nothing() -> None:
    """A still gaze (zero actions), 12 steps over office's moving objects: from the second
    step on, every step's keys were drawn during the step before (none dropped); the
    events, masks and render counts are those made without drawing ahead."""
    still = [np.zeros(2, np.float32)] * 12
    on, off = _ahead_trace(still, True), _ahead_trace(still, False)
    steps, renders, adopted, dropped = on
    assert (steps, renders) == off[:2] and off[2:] == (0, 0)
    assert sum(len(e) for e, _ in steps) > 0 and min(renders) >= 1
    assert (adopted, dropped) == (sum(renders[1:]), 0)


def test_keys_drawn_ahead_on_a_wrong_guess_are_dropped_and_change_nothing() -> None:
    """A saccade ordered at the third step: the keys drawn for that step on the guess
    of a still gaze are dropped and it draws its own; the saccade's later steps (the move
    going on, as guessed) adopt theirs; the steps are those made without drawing ahead."""
    actions = [np.zeros(2, np.float32)] * 12
    actions[2] = np.array([0.3, -0.2], np.float32)
    on, off = _ahead_trace(actions, True), _ahead_trace(actions, False)
    steps, renders, adopted, dropped = on
    assert (steps, renders) == off[:2]
    assert dropped >= 1 and adopted == sum(renders[1:]) - renders[2]


@pytest.mark.slow
def test_the_closed_loop_takes_the_same_actions_with_the_render_thread() -> None:
    """The attention agent on office, 40 steps: the same actions and decisions."""
    from agents.attention import AgentParams, AttentionAgent

    def loop(render_thread: bool) -> tuple[list, list]:
        env = gym.make("wander/Wander-v0", scene="office", render_thread=render_thread)
        agent = AttentionAgent(AgentParams.for_env(env), seed=3)
        actions, decisions = [], []
        try:
            obs, info = env.reset(seed=3)
            for k in range(40):
                a = agent.act(obs, info)
                actions.append(a.tobytes())
                if agent.decided:
                    decisions.append((k, agent.target, agent.fixations[-1].peak))
                obs, _, _, _, info = env.step(a)
        finally:
            agent.close()
            env.close()
        return actions, decisions

    assert loop(True) == loop(False)


def test_an_error_on_the_render_thread_is_raised_in_the_step() -> None:
    before = _render_threads()
    env = gym.make("wander/Wander-v0", scene="office", render_thread=True)
    u = env.unwrapped
    try:
        env.reset(seed=0)
        where = []

        def broken(data: object) -> np.ndarray:
            where.append(threading.current_thread().name)
            raise RuntimeError("the driver fell over")

        u.stage.renderer.render = broken  # the office's objects move: a key a step
        with pytest.raises(RuntimeError, match=r"^the driver fell over$"):
            env.step(np.zeros(2, np.float32))
        assert where and all(name.startswith("wander-render") for name in where)
    finally:
        env.close()
    assert _render_threads() <= before


def test_close_joins_the_render_thread_and_a_closed_env_opens_it_again() -> None:
    before = _render_threads()
    env = gym.make("wander/Wander-v0", scene="office", render_thread=True)
    assert _render_threads() <= before  # constructing starts nothing
    env.reset(seed=0)
    assert len(_render_threads() - before) == 1
    env.close()
    assert _render_threads() <= before
    env.close()  # idempotent


@pytest.mark.skipif(not hasattr(os, "fork"), reason="needs fork")
def test_a_process_forked_after_drawing_on_the_thread_refuses_to_draw() -> None:
    """The parent drew on its render thread; a forked child (which has no such thread)
    raises ForkedGLError at its next step instead of waiting on a thread that is not
    there, and closes without touching the parent's GL state."""
    env = gym.make("wander/Wander-v0", scene="office", render_thread=True)
    env.reset(seed=0)
    try:
        pid = os.fork()
        if pid == 0:  # the child: report by exit status, never return into pytest
            code = 3
            try:
                signal.alarm(30)  # a hang fails the test instead of blocking it
                try:
                    env.step(np.zeros(2, np.float32))
                    code = 1
                except ForkedGLError:
                    code = 0
                env.close()
            finally:
                os._exit(code)
        _, status = os.waitpid(pid, 0)
        assert os.WIFEXITED(status) and os.WEXITSTATUS(status) == 0, status
        env.step(np.zeros(2, np.float32))  # the parent draws on
    finally:
        env.close()


@pytest.mark.slow
def test_a_process_that_never_closes_its_env_exits_cleanly() -> None:
    """The render thread with work ahead queued, the env never closed: the interpreter
    joins the thread at its exit (no crash in GL at teardown), three times in three."""
    import subprocess
    import sys

    script = (
        "import numpy as np, gymnasium as gym, wander_env\n"
        "env = gym.make('wander/Wander-v0', scene='office')\n"
        "env.reset(seed=0)\n"
        "for _ in range(5): env.step(np.zeros(2, np.float32))\n"
    )
    for _ in range(3):
        done = subprocess.run([sys.executable, "-c", script], capture_output=True, timeout=300)
        assert done.returncode == 0, done.stderr.decode()[-500:]


def test_a_draw_from_outside_between_steps_draws_what_it_posed_and_drops_the_work_ahead() -> None:
    """Between two steps (the next step's keys queued ahead), posing and rendering from
    the main thread one call at a time: the render is the pose's (work ahead would move
    the draw data between the calls, so it is dropped); a ``*_at`` call is one piece of
    work and drops nothing; the next step draws its keys afresh, its events unchanged."""
    still = [np.zeros(2, np.float32)] * 3
    reference = _ahead_trace(still, False)[0]
    env = gym.make("wander/Wander-v0", scene="office", episode_seconds=0.03)
    u = env.unwrapped
    try:
        env.reset(seed=4)
        events = [env.step(still[0])[4]["events"].events.tobytes()]
        stage, end = u.stage, (u.ptu.camera_pan_deg, u.ptu.camera_tilt_deg)
        whole = stage.colour_at(u._t_us + 3000, end)  # one piece of work
        epoch = stage.ahead_epoch
        stage.pose(u._t_us + 3000, *end)
        assert stage.ahead_epoch == epoch + 1  # the work ahead dropped
        assert stage.render().tobytes() == whole.tobytes()
        for a in still[1:]:
            events.append(env.step(a)[4]["events"].events.tobytes())
        assert u.source.keys_ahead_dropped >= 1
        assert events == [e for e, _ in reference]
    finally:
        env.close()


def _held(stage) -> threading.Event:
    """A new step whose first work holds the render thread until the event is set."""
    gate = threading.Event()
    stage.begin_step()
    stage.submit(gate.wait, 60)
    return gate


def test_the_render_thread_makes_a_geometry_queued_behind_the_work_that_needs_it() -> None:
    """Work on the render thread (a frame drawn ahead) that needs a key's geometry queued
    behind it (asked for when the step adopted the frame) draws it there and then, and
    the queued drawing finds the key made: one draw, no wait for work that cannot run
    yet."""
    env = gym.make("wander/Wander-v0", scene="office", ground_truth=False)
    u = env.unwrapped
    try:
        env.reset(seed=0)
        u.stage.caster = None  # GL draws the geometry: the draws are counted
        source, stage = u.source, u.stage
        key = source.keys[-1]
        assert key.full is None and key.geometry is None
        gate = _held(stage)
        needs = stage.submit(source.keyframe, key)  # runs before the drawing it asks for
        source.request_geometry(key)
        queued = key.geometry
        gate.set()
        made = needs.result(timeout=60)
        assert made is key.full and made.layers.shape == (128, 128)
        assert queued.result(timeout=60) is None  # the queued drawing found the key made
        assert stage.geometry_draws == 1
    finally:
        env.close()


@pytest.fixture
def office():
    """The office env (render thread on) reset with seed 0; closed after the test."""
    env = gym.make("wander/Wander-v0", scene="office")
    try:
        env.reset(seed=0)
        yield env.unwrapped
    finally:
        env.close()


def test_a_key_geometry_the_render_thread_has_not_started_is_cast_by_the_thread_that_needs_it(
    office,
):
    """A key's geometry queued behind other work: the main thread, needing the key, casts
    it itself (no GL: office's moving objects are primitives) and cancels the queued
    drawing; the layers and depth are those the draw side casts for the same pose."""
    source, stage = office.source, office.stage
    start = source.keys[-1]
    t_us = start.t_us + 5000
    key = source.render_key(t_us, start.angles, stage.camera_view(t_us, *start.angles))
    assert key.geometry is None and stage.casts_here()
    gate = _held(stage)
    source.request_geometry(key)
    queued = key.geometry
    made = source.keyframe(key)  # the render thread waits at the gate meanwhile
    assert queued.cancelled() and made is key.full
    gate.set()
    layers, depth = stage.on_draw_side(stage.geometry_at, key.t_us, key.angles)
    assert np.array_equal(made.layers, layers) and np.array_equal(made.inv_depth, 1 / depth)
    assert stage.geometry_draws == 0 and int((layers > 0).sum()) > 0


def test_only_a_thread_off_the_render_thread_casts_and_not_in_the_gratings():
    """casts_here: the main thread of office, once its cube is rendered; not the render
    thread itself; not gratings (its screen is a plane: GL draws its geometry)."""
    for scene, expected in (("office", True), ("gratings", False)):
        env = gym.make("wander/Wander-v0", scene=scene)
        try:
            env.reset(seed=0)
            stage = env.unwrapped.stage
            assert stage.casts_here() is expected, scene
            assert stage.on_draw_side(stage.casts_here) is False
        finally:
            env.close()


def test_a_keys_dvs_input_is_made_once_by_the_thread_that_first_reads_it(office):
    """The render thread draws a key's colour only; the key's DVS input is made when first
    read, there, and kept."""
    source, stage = office.source, office.stage
    calls: list[str] = []
    prepare = source.dvs.prepare
    source.dvs.prepare = lambda rgb: calls.append(threading.current_thread().name) or prepare(rgb)
    start = source.keys[-1]
    t_us = start.t_us + 5000
    key = source.render_key(t_us, start.angles, stage.camera_view(t_us, *start.angles))
    rgb = key.drawn.result(timeout=60)
    assert calls == [] and rgb.shape == (128, 128, 3)
    made = key.prepared
    assert key.prepared is made and calls == [threading.current_thread().name]
    assert np.array_equal(made.lum, prepare(rgb).lum)


def test_the_mask_at_a_step_end_key_is_the_casters_mask_at_its_pose():
    """With ray-cast layers the ground truth's mask at a step's last key is that key's
    layers (one cast for both): equal, step by step, to the caster's mask at the key's
    time and angles."""
    env = gym.make("wander/Wander-v0", scene="office")
    u = env.unwrapped
    try:
        env.reset(seed=1)
        stage, hits = u.stage, 0
        for a in ACTIONS:
            _, _, _, _, info = env.step(a)
            key = u.source.keys[-1]
            expected = stage.on_draw_side(stage.object_mask_at, key.t_us, key.angles)
            assert np.array_equal(info["object_mask"], expected)
            hits += int((expected > 0).sum())
        assert hits > 0
    finally:
        env.close()
