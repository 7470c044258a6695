"""Frame sources (wander_env.frames): the registry, the key schedule in the env on a
still scene, a slow walk and a saccade (key counts stated), the DVS handed fewer frames
where nothing moves, and the sources against each other (exact expectations)."""

from __future__ import annotations

from dataclasses import replace

import gymnasium as gym
import numpy as np
import pytest

import wander_env  # noqa: F401  (registers the environments)
from wander_env.actions import gaze_degrees_to_action
from wander_env.env_config import FRAME_MODES
from wander_env.frames.exact import ExactFrames
from wander_env.frames.keyframes import KeyframeFrames
from wander_env.frames.panorama import PanoramaFrames
from wander_env.frames.registry import MODE_NAMES, REGISTRY, frame_modes_help
from wander_env.ptu.params import PTUParams

FAST_PTU = PTUParams().with_slew(2902.0, 1e5)  # the upper speed, 74.6 deg/s, in 29 ms


def _run(scene: str, steps: int, kind: str = "still", seed: int = 4, **kw):
    """(events, renders per step, frames per step) of a run: a still camera, a slow
    fixational walk (±0.1 degree a step) or a 20 degree saccade at the first step."""
    env = gym.make("wander/Wander-v0", scene=scene, **kw)
    try:
        env.reset(seed=seed)
        cam = env.unwrapped.scene.camera
        rng = np.random.default_rng(1)
        events, renders, frames = [], [], []
        for k in range(steps):
            deg = (0.0, 0.0)
            if kind == "walk":
                deg = tuple(rng.uniform(-0.1, 0.1, 2))
            elif kind == "saccade" and k == 0:
                deg = (20.0, 0.0)
            a = gaze_degrees_to_action(*deg, cam.width, cam.height, cam.hfov_deg)
            info = env.step(np.asarray(a, np.float32))[4]
            events.append(info["events"].events)
            renders.append(env.unwrapped.renders_in_step)
            frames.append(info["frames"])
        return np.concatenate(events), renders, frames
    finally:
        env.close()


def test_a_frame_mode_is_one_registered_class():
    assert FRAME_MODES == MODE_NAMES == tuple(REGISTRY) == ("keyframes", "exact", "panorama")
    classes = {name: mode.source_class() for name, mode in REGISTRY.items()}
    assert classes == {
        "keyframes": KeyframeFrames,
        "exact": ExactFrames,
        "panorama": PanoramaFrames,
    }
    help = frame_modes_help()
    assert help.startswith("keyframes (render keys where the image motion needs them")
    assert "); exact (render every frame" in help and "); panorama (warp a cube map" in help


def test_the_frames_help_lists_every_registered_mode_from_a_light_registry():
    """The --frames help names every registered mode; the registry (names,
    descriptions) imports neither MuJoCo nor numba: a fresh interpreter that imports it
    has neither loaded."""
    import subprocess
    import sys

    from experiments.cli.options import FramesOpt

    help = FramesOpt.__metadata__[0].help
    assert all(f"{name} (" in help for name in REGISTRY) and len(REGISTRY) == 3
    code = (
        "import sys\n"
        "import wander_env.frames.registry\n"
        "print('mujoco' in sys.modules, 'numba' in sys.modules)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.split() == ["False", "False"]


@pytest.mark.slow
def test_a_still_scene_renders_no_key_and_hands_the_dvs_one_frame_a_step():
    """Shelf (nothing moves), still camera: no render after reset (the reset's key is
    every step's end), one frame a step to the DVS; with fixed 2 ms keys (keyframe_px
    None) five renders and five frames a step (the ticks between keys are interpolated);
    no events either way."""
    ev_a, renders_a, frames_a = _run("shelf", 4)
    ev_f, renders_f, frames_f = _run("shelf", 4, keyframe_px=None)
    assert renders_a == [0, 0, 0, 0] and frames_a == [1, 1, 1, 1]
    assert renders_f == [5, 5, 5, 5] and frames_f == [5, 5, 5, 5]
    assert len(ev_a) == len(ev_f) == 0


@pytest.mark.slow
def test_a_slow_walk_renders_one_key_a_step():
    """Office, a fixational walk of ±0.1 degree a step at the default speed (under
    1.3 px of image motion a step), keys placed by motion alone (keyframe_max_ms None):
    one key a step, each step's end."""
    ev, renders, frames = _run("office", 6, "walk", keyframe_max_ms=None)
    assert renders == [1] * 6
    assert all(1 <= f <= 12 for f in frames)
    assert len(ev) > 1000


@pytest.mark.slow
def test_a_fast_saccade_takes_keys_where_the_image_moves_2_px():
    """A 20 degree saccade at the unit's upper speed (0.75 degree a step, up to 3.5 px at
    the image corners): two keys a step while it moves fast, one as it starts; the same
    seed gives the same events and keys (keys placed by motion alone)."""
    ev1, renders1, _ = _run("office", 6, "saccade", ptu=FAST_PTU, keyframe_max_ms=None)
    ev2, renders2, _ = _run("office", 6, "saccade", ptu=FAST_PTU, keyframe_max_ms=None)
    assert renders1 == [1, 2, 2, 2, 2, 2]
    assert renders1 == renders2 and np.array_equal(ev1, ev2)


@pytest.mark.slow
def test_keys_and_exact_frames_give_nearly_the_same_events():
    """Office, still camera and moving objects, 8 steps: one key a step within 5 % of
    the exact mode's events (measured: 3.4 % fewer), with a tenth of its renders; the
    default (keys at most 5 ms apart) within 3 %, with a fifth."""
    ev_k, renders_k, _ = _run("office", 8, frames="keyframes", keyframe_max_ms=None)
    ev_d, renders_d, _ = _run("office", 8)
    ev_e, renders_e, _ = _run("office", 8, frames="exact")
    assert abs(len(ev_k) / len(ev_e) - 1) < 0.05
    assert abs(len(ev_d) / len(ev_e) - 1) < 0.03
    assert sum(renders_k) == 8 and sum(renders_d) == 16 and sum(renders_e) >= 80


@pytest.mark.slow
def test_keyframe_max_ms_spaces_keys_while_anything_moves():
    """keyframe_max_ms=5: two keys a step in the office (its objects always move), still
    none on the shelf (nothing moves)."""
    _, renders, _ = _run("office", 3, keyframe_max_ms=5.0)
    _, still, _ = _run("shelf", 3, keyframe_max_ms=5.0)
    assert renders == [2, 2, 2] and still == [0, 0, 0]


def test_keyframe_max_ms_is_checked():
    from wander_env.env_config import WanderConfig

    assert WanderConfig().keyframe_max_ms == 5.0
    with pytest.raises(ValueError, match=r"^keyframe_max_ms: 2\.5 must be a whole number"):
        WanderConfig(keyframe_max_ms=2.5)
    with pytest.raises(
        ValueError, match=r"^keyframe_max_ms: input should be greater than 0, got 0.0$"
    ):
        WanderConfig(keyframe_max_ms=0.0)


def test_quality_fine_renders_16_samples_a_pixel():
    from wander_env.env_config import WanderConfig

    assert WanderConfig().quality == "fast" and WanderConfig().render_supersample == 1
    env = gym.make("wander/Wander-v0", quality="fine").unwrapped
    assert env.stage.params.supersample == 2 and env.scene.camera.antialias_samples == 4
    env.close()
    with pytest.raises(ValueError, match=r"^quality: expected one of .fast., .fine., got .best.$"):
        WanderConfig(quality="best")
    with pytest.raises(ValueError, match="not both"):
        WanderConfig(quality="fine", supersample=2)


@pytest.mark.slow
def test_a_keys_layers_and_depth_are_drawn_only_where_needed():
    """Office, still camera, default keys (two a step): the objects move under half a
    pixel a tick, so no frame is synthesised and only the step end's key draws its layers
    and depth, for the ground truth's mask (the mask a segmentation of the posed model
    gives); none with ground truth off, nor with the mask ray cast (the default where the
    objects are primitives: wander_env.frames.raycast). A small pan synthesises frames
    (a turned camera's ticks are never the keys' plain blend: the static world moves by
    its fraction of a pixel) whether every tick is handed to the DVS (interpolate_px=None)
    or not: the step's keys' geometry and its start's."""
    for gt, cast, draws in (
        (True, False, [1, 1, 1]),
        (True, True, [0, 0, 0]),
        (False, False, [0, 0, 0]),
    ):
        env = gym.make("wander/Wander-v0", scene="office", ground_truth=gt)
        try:
            stage, counts = env.unwrapped.stage, []
            if not cast:
                stage.caster = None  # GL draws the masks
            env.reset(seed=0)
            for _ in range(3):
                info = env.step(np.zeros(2, np.float32))[4]
                counts.append(stage.geometry_draws)
                assert env.unwrapped.renders_in_step == 2
                if gt:
                    u = env.unwrapped
                    end = (u.ptu.camera_pan_deg, u.ptu.camera_tilt_deg)
                    assert np.array_equal(info["object_mask"], stage.object_mask_at(u._t_us, end))
            assert counts == draws
        finally:
            env.close()
    for interpolate_px in (None, 1.0):
        env = gym.make("wander/Wander-v0", scene="office", ground_truth=False)
        try:
            u = env.unwrapped
            u.stage.caster = None  # GL draws the keys' geometry
            u.source.params = replace(u.source.params, interpolate_px=interpolate_px)
            env.reset(seed=0)
            env.step(np.array([0.05, 0.0], np.float32))
            assert u.renders_in_step == 2  # the step's keys and its start's
            assert u.stage.geometry_draws == u.renders_in_step + 1
        finally:
            env.close()


def test_a_still_scenes_end_keys_share_the_rendered_keys_geometry():
    """Shelf (nothing moves), ground truth off: every step's end key is the reset's key,
    whose geometry it shares directly (no chain through the steps), drawn once when asked."""
    env = gym.make("wander/Wander-v0", scene="shelf", ground_truth=False)
    try:
        env.unwrapped.stage.caster = None  # GL draws the geometry (counted)
        env.reset(seed=0)
        source = env.unwrapped.source
        first = source.keys[0]
        for _ in range(4):
            env.step(np.zeros(2, np.float32))
            assert source.keys[-1].same_as is first and env.unwrapped.stage.geometry_draws == 0
        end = source.keyframe(source.keys[-1])
        assert env.unwrapped.stage.geometry_draws == 1 and first.full is not None
        assert end.t_us == source.keys[-1].t_us and end.layers is first.full.layers
    finally:
        env.close()
