"""The fast render path and the fused DVS input give exactly what the plain paths give.

:class:`~wander_env.renderer.CameraRenderer` drives ``mjr_render`` directly and draws
segmentation into a single-sample framebuffer; ``mujoco.Renderer`` is the reference.
(Batching the ticks of a step as tiles of one buffer was measured and dropped: on
llvmpipe it was slower, and tiles at an offset differ from a lone frame by ±1 grey
level at some edges.)
"""

from __future__ import annotations

import os

os.environ.setdefault("MUJOCO_GL", "egl")  # before mujoco is imported: headless rendering

import gymnasium as gym
import mujoco
import numpy as np
import pytest

import wander_env  # noqa: F401  (registers the environments)
from wander_env.camera import CAMERA_NAME
from wander_env.dvs import DVSEmulator, DVSParams, LogFrame
from wander_env.mjcf import SceneAnimator, compile_scene, geom_object_ids
from wander_env.renderer import CameraRenderer
from wander_env.scenes import load_scene_config


def _reference(model: mujoco.MjModel, data: mujoco.MjData) -> tuple[np.ndarray, np.ndarray]:
    """RGB and object-id mask through ``mujoco.Renderer`` with the same options."""
    r = mujoco.Renderer(model, 128, 128)
    try:
        for flag in ("SHADOW", "REFLECTION", "SKYBOX", "FOG", "HAZE"):
            r.scene.flags[getattr(mujoco.mjtRndFlag, f"mjRND_{flag}")] = 0
        opt = mujoco.MjvOption()
        opt.geomgroup[:] = [1, 1, 1, 0, 0, 0]
        r.update_scene(data, CAMERA_NAME, opt)
        rgb = r.render()
        r.enable_segmentation_rendering()
        seg = r.render()
    finally:
        r.close()
    lut = np.concatenate([[0], geom_object_ids(model)])
    is_geom = seg[..., 1] == int(mujoco.mjtObj.mjOBJ_GEOM)
    return rgb, np.where(is_geom, lut[np.where(is_geom, seg[..., 0], -1) + 1], 0)


def _poses(scene: str, samples: int | None = None):
    """(model, data) at a few times and camera angles; objects and gratings move."""
    cfg = load_scene_config(scene)
    model = compile_scene(cfg)
    if samples is not None:
        model.vis.quality.offsamples = samples
    data = mujoco.MjData(model)
    animator = SceneAnimator(model, cfg)
    for i, t in enumerate((0.0, 0.37, 1.1)):
        animator.apply(data, t)
        data.qpos[:2] = np.radians([7.0 * i, -3.0 * i])
        mujoco.mj_forward(model, data)
        yield model, data


@pytest.mark.parametrize(
    ("scene", "samples"), [("office", None), ("office", 0), ("gratings", None)]
)
def test_frames_and_masks_equal_mujoco_renderer(scene, samples):
    cam = None
    for model, data in _poses(scene, samples):
        cam = cam or CameraRenderer(model)
        rgb, mask = cam.render_with_mask(data)
        ref_rgb, ref_mask = _reference(model, data)
        assert rgb.dtype == np.uint8 and mask.dtype == np.int32
        assert np.array_equal(rgb, ref_rgb)
        assert np.array_equal(mask, ref_mask)
        assert np.array_equal(cam.render(data), rgb)  # a render after a mask: unchanged
    assert mask.any() and len(np.unique(rgb)) > 10  # the views show objects and texture
    cam.close()


def test_render_returns_a_fresh_top_down_array():
    model, data = next(_poses("office"))
    with CameraRenderer(model) as cam:
        a = cam.render(data)
        b = cam.render(data)
        assert a is not b and not np.shares_memory(a, b)
        assert a.flags.c_contiguous and a.shape == (128, 128, 3)
        a[:] = 0
        assert b.any()


def test_image_larger_than_the_offscreen_buffer_is_refused():
    model, _ = next(_poses("shelf"))
    with pytest.raises(ValueError, match="offscreen buffer"):
        CameraRenderer(model, width=model.vis.global_.offwidth + 1)


@pytest.mark.parametrize("preset", ["ideal", "speck"])
def test_prepared_frames_give_the_same_events_and_change(preset):
    rng = np.random.default_rng(0)
    a = DVSEmulator(32, 24, DVSParams.preset(preset), seed=1)
    b = DVSEmulator(32, 24, DVSParams.preset(preset), seed=1)
    base = rng.integers(0, 256, (24, 32, 3), dtype=np.uint8)
    a.reset(base, 0)
    b.reset(base, 0)
    for i in range(1, 40):
        frame = np.clip(base + rng.integers(-80, 80, base.shape), 0, 255).astype(np.uint8)
        frame[:4] //= 40  # below the linear-log knee
        prepared = a.prepare(frame)
        assert isinstance(prepared, LogFrame)
        change = a.log_change(prepared)
        assert change == b.log_change(frame)
        ev_a, ev_b = a.step(prepared, i * 1000), b.step(frame, i * 1000)
        assert np.array_equal(ev_a, ev_b) and len(ev_a) > 0  # every frame makes events
        assert change == a.max_log_change == b.max_log_change
    with pytest.raises(ValueError, match="sensor size"):
        a.step(DVSEmulator(4, 4).prepare(np.zeros((4, 4, 3), np.uint8)), 10**6)


def test_antialias_override_reaches_the_model():
    env = gym.make("wander/Wander-v0", scene="shelf", antialias_samples=0).unwrapped
    assert env.model.vis.quality.offsamples == 0
    assert env.scene.camera.antialias_samples == 0
    env.close()
    with pytest.raises(ValueError, match="antialias_samples"):
        gym.make("wander/Wander-v0", scene="shelf", antialias_samples=-1)


@pytest.mark.parametrize(("preset", "threads"), [(None, 1), ("2", 2)])
def test_importing_wander_env_keeps_opencv_on_the_calling_thread_unless_set(preset, threads):
    """OPENCV_FOR_THREADS_NUM defaults to 1 (wander_env/__init__.py); a user's value wins."""
    import subprocess
    import sys

    env = {k: v for k, v in os.environ.items() if k != "OPENCV_FOR_THREADS_NUM"}
    if preset is not None:
        env["OPENCV_FOR_THREADS_NUM"] = preset
    code = "import cv2, wander_env; print(cv2.getNumThreads())"
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    assert int(out.stdout) == threads
