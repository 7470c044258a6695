"""Adaptive keyframe intervals (``WanderConfig.keyframe_px``): the motion bound between
views and the key schedule it gives, alone and in the env (exact expectations)."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

import wander_env  # noqa: F401  (registers the environments)
from wander_env.actions import gaze_degrees_to_action
from wander_env.camera import intrinsics, project
from wander_env.frames.flow_bounds import adaptive_key_ticks, view_flow_bounds_px
from wander_env.frames.keyframe_maths import View

K = intrinsics(128, 128, 90.0)  # f = 64 px
SHAPE = (128, 128)
RADII = np.array([np.inf, 0.1])


def pan(deg: float) -> np.ndarray:
    """World-from-camera rotation of a camera panned by ``deg`` about its y axis."""
    a = math.radians(deg)
    return np.array([[math.cos(a), 0, math.sin(a)], [0, 1, 0], [-math.sin(a), 0, math.cos(a)]])


def view(pan_deg: float = 0.0, obj=(0.0, 0.0, 2.0), centre=(0.0, 0.0, 0.0)) -> View:
    return View(pan(pan_deg), np.array(centre, float), np.array([[0, 0, 0], obj], float))


def test_bound_is_zero_when_nothing_moves_and_exact_for_a_sliding_object():
    still = view()
    b = view_flow_bounds_px(still, [still, view(obj=(0.02, 0.0, 2.0))], K, RADII, SHAPE)
    # 1.25 * f * |t| / (z - r) = 1.25 * 64 * 0.02 / 1.9
    assert b[0] == 0.0
    assert b[1] == pytest.approx(1.25 * 64 * 0.02 / 1.9, rel=1e-12)


def test_bound_covers_the_rotation_flow_at_every_pixel_and_the_object_centre():
    ref, moved = view(0.0, (0.1, 0.05, 2.0)), view(1.5, (0.13, 0.05, 2.0))
    bound = float(view_flow_bounds_px(ref, [moved], K, RADII, SHAPE)[0])
    # every pixel of the static world: the rotation homography's displacement
    ys, xs = np.mgrid[0:128, 0:128]
    pts = np.stack([xs.ravel(), ys.ravel(), np.ones(xs.size)], axis=1)
    m = pts @ (K @ moved.rotation.T @ ref.rotation @ np.linalg.inv(K)).T
    rot_flow = np.abs(m[:, :2] / m[:, 2:] - pts[:, :2]).max()
    assert rot_flow <= bound
    # the object's centre, projected in both views
    (a,), _ = project(K, ref.rotation, ref.centre, ref.layer_positions[1:])
    (b,), _ = project(K, moved.rotation, moved.centre, moved.layer_positions[1:])
    assert np.abs(b - a).max() <= bound
    assert bound < 4 * max(rot_flow, np.abs(b - a).max())  # and not wildly above


def test_bound_is_infinite_for_a_moving_centre_or_an_object_at_the_camera():
    ref = view()
    b = view_flow_bounds_px(
        ref, [view(centre=(0.0, 0.0, 0.01)), view(obj=(0.0, 0.0, 0.05))], K, RADII, SHAPE
    )
    assert np.isinf(b).all()


def test_one_reference_per_view_gives_the_same_bounds_as_one_at_a_time():
    refs = [view(0.0), view(0.5, (0.01, 0, 2.0)), view(1.0, (0.02, 0, 2.5))]
    views = [view(0.2, (0.0, 0.01, 2.0)), view(0.5, (0.03, 0, 2.0)), view(2.0, (0.02, 0, 2.5))]
    both = view_flow_bounds_px(refs, views, K, RADII, SHAPE)
    pairs = zip(refs, views, strict=True)
    one = [float(view_flow_bounds_px(r, [v], K, RADII, SHAPE)[0]) for r, v in pairs]
    assert np.allclose(both, one, rtol=1e-12, atol=0)
    with pytest.raises(ValueError, match="2 reference views for 3 views"):
        view_flow_bounds_px(refs[:2], views, K, RADII, SHAPE)


def test_still_camera_and_still_objects_give_no_key():
    ticks = [view()] * 10
    assert adaptive_key_ticks(view(), ticks, K, RADII, SHAPE, 2.0) == []


def test_slow_motion_gives_one_key_a_step_and_fast_motion_keys_at_the_bound():
    # an object sliding 0.1 mm a tick (0.004 px): one key, the step's end
    slow = [view(obj=(1e-4 * (i + 1), 0.0, 2.0)) for i in range(10)]
    assert adaptive_key_ticks(view(), slow, K, RADII, SHAPE, 2.0) == [9]
    # a pan of 0.3 degrees a tick: keys wherever the bound would be passed
    fast = [view(0.3 * (i + 1)) for i in range(10)]
    keys = adaptive_key_ticks(view(), fast, K, RADII, SHAPE, 2.0)
    assert keys == [1, 3, 5, 7, 9]  # 0.84 px a tick (corners, times 1.25): keys 2 apart
    prev = view()
    for j in keys:  # between consecutive keys the bound holds
        assert view_flow_bounds_px(prev, [fast[j]], K, RADII, SHAPE)[0] <= 2.0
        prev = fast[j]
    # a tick that alone moves more than the bound: every tick a key
    jump = [view(3.0 * (i + 1)) for i in range(4)]
    assert adaptive_key_ticks(view(), jump, K, RADII, SHAPE, 2.0) == [0, 1, 2, 3]


def test_unbounded_motion_has_no_schedule_and_bad_bounds_are_refused():
    ticks = [view(obj=(0.01 * i, 0.0, 2.0)) for i in range(1, 4)]
    assert adaptive_key_ticks(view(), ticks, K, np.array([np.inf, np.inf]), SHAPE, 2.0) is None
    with pytest.raises(ValueError, match="bound_px must be > 0"):
        adaptive_key_ticks(view(), ticks, K, RADII, SHAPE, 0.0)


def test_keyframe_px_is_checked():
    from wander_env.env_config import WanderConfig

    for bad in (0.0, -1.0, float("nan"), float("inf"), True, "2"):
        with pytest.raises(ValueError, match=r"^keyframe_px: (input should be|expected) "):
            WanderConfig(keyframe_px=bad)
    assert WanderConfig(keyframe_px=2).keyframe_px == 2


def _run(scene: str, steps: int, saccade_deg: float = 0.0, **kw):
    env = gym.make("wander/Wander-v0", scene=scene, frames="keyframes", **kw)
    try:
        env.reset(seed=4)
        cam = env.unwrapped.scene.camera
        events, renders = [], []
        for k in range(steps):
            a = np.zeros(2, np.float32)
            if k == 0 and saccade_deg:
                a = gaze_degrees_to_action(saccade_deg, 0.0, cam.width, cam.height, cam.hfov_deg)
            info = env.step(a.astype(np.float32))[4]
            events.append(info["events"].events)
            renders.append(env.unwrapped.renders_in_step)
        return np.concatenate(events), renders
    finally:
        env.close()


@pytest.mark.slow
def test_env_saccade_takes_short_keys_and_same_seed_gives_same_events():
    """A 20 degree pan with a 0.3 px bound: more keys than 2 ms keys give during the
    move, and two runs with the same seed give identical events."""
    ev1, renders1 = _run("office", 4, saccade_deg=20.0, keyframe_px=0.3)
    ev2, renders2 = _run("office", 4, saccade_deg=20.0, keyframe_px=0.3)
    assert max(renders1) > 5
    assert renders1 == renders2 and np.array_equal(ev1, ev2)


@pytest.mark.slow
def test_a_second_episode_in_the_same_env_repeats_the_first():
    """Nothing of one episode's keys (prepared inputs, PTU states, views) leaks into the
    next: reset with the same seed gives the same events and renders again."""
    env = gym.make("wander/Wander-v0", scene="office", frames="keyframes", keyframe_px=0.3)
    try:
        cam = env.unwrapped.scene.camera
        saccade = gaze_degrees_to_action(20.0, 0.0, cam.width, cam.height, cam.hfov_deg)
        runs = []
        for _ in range(2):
            env.reset(seed=5)
            evs, renders = [], []
            for k in range(4):
                a = saccade if k == 0 else np.zeros(2)
                evs.append(env.step(a.astype(np.float32))[4]["events"].events)
                renders.append(env.unwrapped.renders_in_step)
            runs.append((np.concatenate(evs), renders))
        assert len(runs[0][0]) > 100
        assert runs[0][1] == runs[1][1] and np.array_equal(runs[0][0], runs[1][0])
    finally:
        env.close()
