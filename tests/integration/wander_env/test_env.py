"""The Gymnasium environment: spaces, determinism, saccades, ground truth, vector envs."""

from __future__ import annotations

import math
import pickle
import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import wander_env  # noqa: F401  (registers the environments)
from wander_env.events import concatenate
from wander_env.events.packet import EventPacket
from wander_env.ptu.params import PTUParams

F_PX = 64 / math.tan(math.atan(5.12 / 3.4))  # focal length in pixels of the Speck optics


def make(scene: str = "shelf", **kw) -> gym.Env:
    return gym.make("wander/Wander-v0", scene=scene, **kw)


def run(env: gym.Env, actions: list[np.ndarray], seed: int) -> list[dict]:
    """The infos of a reset and the steps of ``actions``; ``env`` closed after."""
    try:
        _, info = env.reset(seed=seed)
        infos = [info]
        for a in actions:
            infos.append(env.step(a)[4])
        return infos
    finally:
        env.close()


def test_reset_gives_the_documented_spaces():
    env = make()
    obs, info = env.reset(seed=0)
    assert env.observation_space.contains(obs)
    assert obs["events"].shape == (2, 128, 128)
    assert obs["gaze"].tolist() == [0.0, 0.0]
    assert info["t"] == 0.0 and info["moving"] is False
    assert env.metadata["render_fps"] == 100
    env.close()


def test_check_env_passes_on_the_unwrapped_env():
    env = gym.make("wander/Wander-v0").unwrapped  # the default scene, no wrapper at all
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(env)
    # The one remark: event counts have no finite upper bound (the space says so).
    remarks = [str(w.message) for w in caught]
    assert len(remarks) == 1 and "maximum value is infinity" in remarks[0], remarks
    env.close()


def test_info_events_are_a_packet_of_every_event_of_the_step():
    env = make("office")
    _, info = env.reset(seed=2)
    assert isinstance(info["events"], EventPacket) and len(info["events"]) == 0
    for _ in range(3):
        obs, _, _, _, info = env.step(np.zeros(2, np.float32))
        packet = info["events"]
        assert isinstance(packet, EventPacket) and len(packet) > 0
        assert len(packet) == obs["events"].sum()  # nothing dropped
        ev = packet.events
        assert np.all(np.diff(ev["t"]) >= 0) and ev["t"][-1] <= round(info["t"] * 1e6)
    env.close()


def test_constructing_the_env_creates_no_renderer():
    env = make()
    assert env.unwrapped.stage._renderer is None  # what AsyncVectorEnv's parent builds: no GL
    env.reset(seed=0)
    assert env.unwrapped.stage._renderer is not None
    env.close()
    assert env.unwrapped.stage._renderer is None


def test_same_seed_same_events_and_ground_truth():
    actions = [np.array([0.3, -0.2], np.float32)] + [np.zeros(2, np.float32)] * 4
    a, b = (run(make("office"), actions, seed=5) for _ in range(2))
    ea = concatenate([i["events"].events for i in a])
    eb = concatenate([i["events"].events for i in b])
    assert len(ea) > 1000
    assert np.array_equal(ea, eb)
    assert np.array_equal(a[-1]["object_mask"], b[-1]["object_mask"])


def test_a_step_is_one_control_period_of_renders():
    """Exact frames: every 1 ms tick of a 20 ms step is rendered and handed to the DVS,
    plus the adaptive sub-frames (keyframes hand it fewer where nothing moves)."""
    env = make("office", control_period_s=0.02, frames="exact")
    env.reset(seed=0)
    info = env.step(np.zeros(2, np.float32))[4]
    assert info["t"] == pytest.approx(0.02)
    assert info["frames"] == 20 + info["extra_frames"]
    assert env.metadata["render_fps"] == 50
    env.close()


def test_a_step_ends_on_the_control_period_in_whole_us():
    """12.5 ms at 2 kHz: 25 ticks of 500 µs, the step ends at 12 500 µs, as the agent's
    step_s (0.0125 s) would, were it a whole number of the controller's 1 ms."""
    env = make(control_period_s=0.0125, render_rate_hz=2000.0, ground_truth=False)
    env.reset(seed=0)
    assert env.step(np.zeros(2, np.float32))[4]["t"] == 12_500 * 1e-6
    assert env.step(np.zeros(2, np.float32))[4]["t"] == 25_000 * 1e-6
    env.close()


def test_target_positions_in_info_round_halves_away_from_zero_as_the_link_does():
    env = make(ptu=PTUParams(quantise=False), ground_truth=False)
    env.reset(seed=0)
    env.unwrapped.ptu.set_target_positions(2.5, -2.5)
    info = env.step(np.zeros(2, np.float32))[4]
    assert env.unwrapped.ptu.target_positions == (2.5, -2.5)
    assert info["ptu_target_positions"] == (3, -3)
    env.close()


@pytest.mark.parametrize(
    ("action", "message"),
    [
        (np.array([np.nan, 0.0]), "finite"),
        (np.array([1.5, 0.0]), r"\[-1, 1\]"),
        (np.zeros(3), "shape"),
    ],
)
def test_bad_actions_are_rejected(action, message):
    env = make()
    env.reset(seed=0)
    with pytest.raises(ValueError, match=message):
        env.step(action)
    env.close()


def test_targets_beyond_the_limits_are_clipped_and_reported():
    env = make()
    env.reset(seed=0)
    # Each step adds atan(6.4 / f) = 8.56 degrees down; the third passes -907 positions.
    act = np.array([0.0, 0.1], np.float32)
    clipped = [env.step(act)[4]["target_clipped"] for _ in range(4)]
    assert clipped == [False, False, True, True]
    # tilt lower limit: -907 positions
    assert env.unwrapped.ptu.target_positions[1] == -907
    env.close()


@pytest.mark.parametrize("frames", ["exact", "keyframes"])
def test_saccade_of_20_degrees_lands_and_emits_events_all_along(frames):
    env = make("shelf", frames=frames)
    env.reset(seed=0)
    a = math.tan(math.radians(20.0)) * F_PX / 64  # 20 degrees to the right
    infos = [env.step(np.array([a, 0.0], np.float32))[4]]
    while infos[-1]["moving"] and len(infos) < 200:
        infos.append(env.step(np.zeros(2, np.float32))[4])
    gaze = env.unwrapped.ptu.camera_pan_deg
    assert gaze == pytest.approx(-20.0, abs=0.03)  # right is negative pan; 1 position
    events = concatenate([i["events"].events for i in infos])
    t_end = infos[-1]["t"] * 1e6
    moving = events[events["t"] < t_end - 10_000]
    assert len(moving) > 10_000
    assert np.diff(moving["t"]).max() <= 2000
    assert moving["t"][0] <= 2000
    env.close()


def test_ground_truth_masks_and_centres_agree():
    env = make("office")
    env.reset(seed=1)
    info = env.step(np.zeros(2, np.float32))[4]
    mask = info["object_mask"]
    assert set(np.unique(mask).tolist()) <= {0, 1, 2}
    for obj in info["objects"]:
        n = int(np.count_nonzero(mask == obj["id"]))
        assert obj["mask_pixels"] == n
        if n > 50:
            ys, xs = np.nonzero(mask == obj["id"])
            cx, cy = obj["centre_px"]
            assert xs.min() <= cx <= xs.max() and ys.min() <= cy <= ys.max()
    assert sum(o["visible"] for o in info["objects"]) >= 1
    env.close()


def test_render_rgb_array_is_camera_beside_events():
    env = make(render_mode="rgb_array")
    env.reset(seed=0)
    env.step(np.zeros(2, np.float32))
    img = env.render()
    # A 24-px header naming the panels, the 3x panels, a 24-px footer (time, key).
    assert img.shape == (24 + 384 + 24, 2 * 384 + 6, 3) and img.dtype == np.uint8
    camera = env.unwrapped.camera_frame
    assert np.array_equal(img[24 + 1, 1], camera[0, 0])  # the camera panel, upscaled 3x
    footer = img[24 + 384 :].reshape(-1, 3).tolist()
    assert [220, 30, 30] in footer and [30, 60, 220] in footer  # the ON/OFF key
    env.close()


def test_pickle_round_trip_keeps_the_config():
    env = make("gratings", control_period_s=0.005).unwrapped
    twin = pickle.loads(pickle.dumps(env))
    assert twin.config == env.config
    obs, _ = twin.reset(seed=0)
    assert obs["events"].shape == (2, 128, 128)
    twin.close()
    env.close()


def test_unknown_scene_and_preset_name_the_problem():
    with pytest.raises(ValueError, match="unknown DVS preset 'davis'"):
        make(dvs="davis")
    with pytest.raises(ValueError, match="control_period_s"):
        make(control_period_s=0.0105)


def test_ground_truth_objects_are_the_cameras_projection_and_the_masks_counts():
    """info["objects"]: each object's centre is project_points through the camera side's
    pose at the step's end, exactly, and its pixels the mask's count of its id."""
    from wander_env.renderer import project_points

    env = gym.make("wander/Wander-v0", scene="office")
    env.reset(seed=1)
    u = env.unwrapped
    for k in range(3):
        _, _, _, _, info = env.step(np.array([0.2 * (k == 0), -0.1], np.float32))
        positions = u.animator.object_positions(info["t"])
        centres = project_points(u.model, u.data, positions)
        assert len(info["objects"]) == len(positions) == 2
        for obj, centre in zip(info["objects"], centres, strict=True):
            assert obj["centre_px"] == (float(centre[0]), float(centre[1]))
            assert obj["mask_pixels"] == int(np.count_nonzero(info["object_mask"] == obj["id"]))
    assert any(obj["mask_pixels"] > 0 for obj in info["objects"])
    env.close()
