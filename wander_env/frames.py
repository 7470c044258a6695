"""Where the camera's frames come from: the posed scene (:class:`Stage`) and the frame
sources that read one PTU trajectory per step.

:class:`Stage` owns what draws: the MuJoCo model and data, the scene's animator and the
camera's renderer (created in the process that renders). It poses the world at a time and
camera angles, renders a colour frame, a frame's geometry (motion layers and depth) and
the ground truth's object mask.

A :class:`FrameSource` turns a step's :class:`~wander_env.ptu.Trajectory` (the PTU stepped
once per tick, computed once per step) into the frames the DVS sees:

- :meth:`~FrameSource.plan` at the step's start, with the whole trajectory (a source
  may render its keys there: everything it needs is known, nothing waits for later);
- :meth:`~FrameSource.frame` at each render tick and adaptive sub-frame, with that
  time's camera angles;
- :meth:`~FrameSource.object_mask` at the step's end (ground truth).

:class:`ExactFrames` renders every frame. :class:`KeyframeFrames` renders keys and makes
the frames between them from the keys' geometry (:mod:`wander_env.keyframes`). A new
frame mode is one more subclass, named in :data:`FRAME_SOURCES`.
"""

from __future__ import annotations

import math
import os
from abc import ABC, abstractmethod
from dataclasses import dataclass

import mujoco
import numpy as np

from wander_env.camera import CAMERA_NAME, intrinsics, rotation_from_mujoco
from wander_env.dvs import DVSEmulator, LogFrame
from wander_env.entities import PAN_JOINT, TILT_JOINT
from wander_env.gl_fork import ForkedGLError, fork_error_message
from wander_env.keyframes import (
    Keyframe,
    KeyframeSource,
    View,
    adaptive_key_ticks,
    make_keyframe,
    view_flow_bounds_px,
)
from wander_env.mjcf import SceneAnimator, geom_layer_ids
from wander_env.ptu import Trajectory
from wander_env.renderer import CameraRenderer, RenderParams
from wander_env.scene_config import SceneConfig

__all__ = [
    "FRAME_SOURCES",
    "ExactFrames",
    "FrameParams",
    "FrameSource",
    "KeyframeFrames",
    "Stage",
]

Angles = tuple[float, float]  # camera (pan, tilt) in degrees


class Stage:
    """A scene's model and data, its animator (set at each reset) and the camera's
    renderer: the world posed at a time and camera angles, and what the camera sees."""

    def __init__(self, model: mujoco.MjModel, scene: SceneConfig, params: RenderParams) -> None:
        self.model, self.scene, self.params = model, scene, params
        self.data = mujoco.MjData(model)
        self.width, self.height = scene.camera.width, scene.camera.height
        self._pan_adr = int(model.joint(PAN_JOINT).qposadr[0])
        self._tilt_adr = int(model.joint(TILT_JOINT).qposadr[0])
        self._cam_id = int(model.camera(CAMERA_NAME).id)
        self.k = intrinsics(self.width, self.height, float(model.cam_fovy[self._cam_id]))
        self.layer_lut = geom_layer_ids(model)
        self.animator: SceneAnimator | None = None
        self._renderer: CameraRenderer | None = None  # created where it renders: .renderer
        self._renderer_pid: int | None = None
        self.posed: tuple[int, float, float] | None = None  # (t_us, pan, tilt) of the model
        self.renders = 0  # colour frames rendered since the counter was last zeroed

    @property
    def renderer(self) -> CameraRenderer:
        """The camera's renderer, created on first use in this process."""
        r = self._renderer
        if r is None:
            r = self._renderer = CameraRenderer(
                self.model, self.width, self.height, params=self.params
            )
            self._renderer_pid = os.getpid()
        elif self._renderer_pid != os.getpid():
            raise ForkedGLError(fork_error_message(self._renderer_pid, os.getpid()))
        return r

    def layer_radii(self) -> np.ndarray:
        """Bounding radius (m) of each motion layer about its position (inf: a screen)."""
        radii = np.full(int(self.layer_lut.max(initial=0)) + 1, np.inf)
        if self.scene.gratings is None:
            for k, obj in enumerate(self.scene.moving_objects, 1):
                radii[k] = 0.5 * math.hypot(*obj.size) * 1.01
        return radii

    def pose(self, t_us: int, pan_deg: float, tilt_deg: float) -> None:
        """The camera at these angles and the objects at ``t_us`` into the model."""
        if self.posed == (t_us, pan_deg, tilt_deg):
            return
        self.data.qpos[self._pan_adr] = math.radians(pan_deg)
        self.data.qpos[self._tilt_adr] = math.radians(tilt_deg)
        self.animator.apply(self.data, t_us * 1e-6)
        mujoco.mj_kinematics(self.model, self.data)
        mujoco.mj_camlight(self.model, self.data)
        self.posed = (t_us, pan_deg, tilt_deg)

    def camera_view(self, t_us: int, pan_deg: float, tilt_deg: float) -> View:
        """The :class:`View` at ``t_us`` with the camera at these angles; only the PTU's
        joints and the camera are moved (the model is no longer posed at one time)."""
        self.data.qpos[self._pan_adr] = math.radians(pan_deg)
        self.data.qpos[self._tilt_adr] = math.radians(tilt_deg)
        mujoco.mj_kinematics(self.model, self.data)
        mujoco.mj_camlight(self.model, self.data)
        self.posed = None
        return self.view(t_us)

    def view(self, t_us: int) -> View:
        """The camera pose of the model and the motion layers at ``t_us``."""
        return View(
            rotation_from_mujoco(self.data.cam_xmat[self._cam_id]),
            self.data.cam_xpos[self._cam_id].copy(),
            self.animator.layer_positions(t_us * 1e-6),
        )

    def render(self) -> np.ndarray:
        """RGB uint8 (H, W, 3) of the posed model."""
        self.renders += 1
        return self.renderer.render(self.data)

    def geometry(self) -> tuple[np.ndarray, np.ndarray]:
        """(motion layers int32, depth m) of the last frame drawn, from one draw."""
        return self.renderer.segment_depth_current(self.layer_lut)

    def geometry_at(self, t_us: int, pan_deg: float, tilt_deg: float) -> tuple[np.ndarray, ...]:
        """(depth m, motion layers) of the model posed at ``t_us`` and these angles."""
        self.pose(t_us, pan_deg, tilt_deg)
        self.renderer.update(self.data)
        layers, depth = self.geometry()
        return depth, layers

    def object_mask(self) -> np.ndarray:
        """Object ids (H, W) int32 of the posed model (0 = background)."""
        return self.renderer.segment(self.data)

    def close(self) -> None:
        # Freeing is safe in a forked child too (only creating and drawing hang there).
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None


@dataclass(frozen=True)
class FrameParams:
    """What a frame source needs of the env's configuration (see ``WanderConfig``)."""

    tick_us: int = 1000
    keyframe_us: int = 2000
    keyframe_px: float | None = 2.0
    ground_truth: bool = True


class FrameSource(ABC):
    """The camera frames of a stream (see the module docstring).

    ``dvs`` is the emulator the frames are for: a source that converts a frame to its
    input anyway (:meth:`DVSEmulator.prepare`) hands back the :class:`LogFrame`.
    """

    def __init__(self, stage: Stage, dvs: DVSEmulator, params: FrameParams) -> None:
        self.stage, self.dvs, self.params = stage, dvs, params
        self.camera_frame: np.ndarray | None = None  # the latest colour frame rendered

    @abstractmethod
    def reset(self, t_us: int, angles: Angles) -> np.ndarray:
        """Start a stream at ``t_us``; the first frame (for the DVS's reset)."""

    @abstractmethod
    def plan(self, trajectory: Trajectory) -> None:
        """A step's start: the camera's trajectory through the step."""

    @abstractmethod
    def frame(self, t_us: int, angles: Angles) -> np.ndarray | LogFrame:
        """The frame at ``t_us`` (a tick of the planned step or a time inside one)."""

    def finish(self, t_us: int, angles: Angles) -> None:
        """The step's end: the model posed there (ground truth reads it)."""
        self.stage.pose(t_us, *angles)

    def object_mask(self, t_us: int) -> np.ndarray:
        """Object ids (H, W) int32 at the step's end ``t_us``."""
        return self.stage.object_mask()


class ExactFrames(FrameSource):
    """Every frame rendered: the reference."""

    def reset(self, t_us: int, angles: Angles) -> np.ndarray:
        self._latest_us = t_us
        return self.frame(t_us, angles)

    def plan(self, trajectory: Trajectory) -> None:
        pass

    def frame(self, t_us: int, angles: Angles) -> np.ndarray:
        self.stage.pose(t_us, *angles)
        rgb = self.stage.render()
        if t_us >= self._latest_us:
            self._latest_us, self.camera_frame = t_us, rgb
        return rgb


class KeyframeFrames(FrameSource):
    """Keys rendered at the step's start along the trajectory (each step's end, and where
    motion asks: :func:`~wander_env.keyframes.adaptive_key_ticks`, else every
    ``keyframe_us``); frames between them synthesised (:mod:`wander_env.keyframes`)."""

    def __init__(self, stage: Stage, dvs: DVSEmulator, params: FrameParams) -> None:
        super().__init__(stage, dvs, params)
        self.keys = KeyframeSource(stage.k, stage.layer_radii(), self._key_geometry)
        self._key_angles: dict[int, Angles] = {}  # key t_us -> camera angles
        self._key_inputs: dict[int, LogFrame] = {}  # key t_us -> its prepared DVS input
        self._tick_views: dict[int, View] = {}  # tick t_us -> its view (this step)
        self._tick_bounds: dict[int, float] = {}  # t_us -> flow bound from its two keys
        self._key_mask: tuple[int, np.ndarray] | None = None  # (t_us, object mask) of a key
        self._t0_us = 0

    def _key_geometry(self, key: Keyframe) -> tuple[np.ndarray, np.ndarray]:
        """(depth, layers) of a key rendered earlier, drawn again at its pose."""
        return self.stage.geometry_at(key.t_us, *self._key_angles[key.t_us])

    def reset(self, t_us: int, angles: Angles) -> np.ndarray:
        self.keys.reset()
        self._key_inputs, self._key_angles, self._tick_views = {}, {}, {}
        self._t0_us = t_us
        self.stage.pose(t_us, *angles)
        self._render_key(t_us, angles, self.stage.view(t_us), self.params.ground_truth)
        return self.keys.keys[0].lum

    def _render_key(self, t_us: int, angles: Angles, view: View, geometry: bool) -> None:
        """Render a key of the posed model; with ``geometry`` its layers and depth too
        (else they are drawn when a frame needs them)."""
        stage = self.stage
        rgb = stage.render()
        prepared = self.dvs.prepare(rgb)
        self._key_inputs = {t: p for t, p in self._key_inputs.items() if t >= self._t0_us}
        self._key_inputs[t_us] = prepared  # the DVS input of the key's own tick
        self._key_angles = {t: a for t, a in self._key_angles.items() if t >= self._t0_us}
        self._key_angles[t_us] = angles
        lum = prepared.lum.reshape(stage.height, stage.width)
        if geometry:
            layers, depth = stage.geometry()
            self.keys.add(make_keyframe(t_us, lum, view, depth, layers))
            mask = np.where(layers <= stage.scene.num_objects, layers, 0).astype(np.int32)
            self._key_mask = (t_us, mask)
        else:
            self.keys.add(make_keyframe(t_us, lum, view))
        self.camera_frame = rgb

    def plan(self, trajectory: Trajectory) -> None:
        """The step's keys: at its end and every ``keyframe_us`` (or, with
        ``keyframe_px``, where the predicted motion asks); each tick's view is kept."""
        p, stage = self.params, self.stage
        self._t0_us = trajectory.t0_us
        t1 = trajectory.t_us[-1]
        ticks = trajectory.t_us
        angles = [trajectory.angles(i) for i in range(len(ticks))]
        views = [stage.camera_view(t, *a) for t, a in zip(ticks, angles, strict=True)]
        self._tick_views = dict(zip(ticks, views, strict=True))
        shape = (stage.height, stage.width)
        k, radii = self.keys.k, self.keys.radii
        chosen = None
        if p.keyframe_px is not None:
            ref = self.keys.keys[-1].view  # the key at t0 (the last step's end)
            idx = adaptive_key_ticks(
                ref, views, k, radii, shape, p.keyframe_px,
                max_ticks=max(p.keyframe_us // p.tick_us, 1),
            )  # fmt: skip
            chosen = None if idx is None else {ticks[i] for i in idx}
        if chosen is None:
            chosen = {t for t in ticks if t == t1 or t % p.keyframe_us == 0}
        for t, a, view in zip(ticks, angles, views, strict=True):
            if t in chosen:
                stage.pose(t, *a)
                self._render_key(t, a, view, geometry=t == t1 and p.ground_truth)
        # Each synthesised tick's flow bound from its two keys, for all ticks at once.
        between = [(t, v) for t, v in zip(ticks, views, strict=True) if t not in chosen]
        self._tick_bounds = {}
        if between:
            pairs = [self.keys.neighbours(t) for t, _ in between]
            tv = [v for _, v in between]
            ba = view_flow_bounds_px([q[0].view for q in pairs], tv, k, radii, shape)
            bb = view_flow_bounds_px([q[1].view for q in pairs], tv, k, radii, shape)
            both = zip(between, np.maximum(ba, bb), strict=True)
            self._tick_bounds = {t: float(b) for (t, _), b in both}

    def frame(self, t_us: int, angles: Angles) -> np.ndarray | LogFrame:
        prepared = self._key_inputs.get(t_us)
        if prepared is not None:  # a key's own tick
            return prepared
        view = self._tick_views.get(t_us)
        if view is not None:
            return self.keys.frame(t_us, view, bound_px=self._tick_bounds.get(t_us))
        return self.keys.frame(t_us, self.stage.camera_view(t_us, *angles))

    def object_mask(self, t_us: int) -> np.ndarray:
        km = self._key_mask
        if km is not None and km[0] == t_us:
            return km[1]
        return super().object_mask(t_us)


#: The frame sources by ``WanderConfig.frames`` name.
FRAME_SOURCES: dict[str, type[FrameSource]] = {"keyframes": KeyframeFrames, "exact": ExactFrames}
