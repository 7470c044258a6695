"""The posed scene: a model and data, the episode's animator and the camera's renderer.

:class:`Stage` poses the world at a time and camera angles and draws what the camera
sees there: a colour frame, a frame's geometry (motion layers and depth) and the ground
truth's object mask. The env drives it through a few verbs (:meth:`Stage.begin_episode`
at each reset, :meth:`Stage.begin_step` at each step); what it counts
(:attr:`Stage.renders`, :attr:`Stage.geometry_draws`) and what it holds are read, never
written, by everyone else.

The renderer (an OpenGL context) is created on first use, in the process that renders;
in a process forked after that, drawing raises
:class:`~wander_env.gl_fork.ForkedGLError` (see :mod:`wander_env.gl_fork`).
"""

from __future__ import annotations

import math
import os
from typing import Literal

import mujoco
import numpy as np

from wander_env.camera import CAMERA_NAME, intrinsics, rotation_from_mujoco
from wander_env.entities import PAN_JOINT, TILT_JOINT
from wander_env.frames.keyframe_maths import View
from wander_env.frames.raycast import PrimitiveCaster, RaycastParams, unsupported_geoms
from wander_env.gl_fork import ForkedGLError, fork_error_message
from wander_env.mjcf import SceneAnimator, geom_layer_ids, geom_layer_radii
from wander_env.renderer import CameraRenderer, RenderParams
from wander_env.scene_config import SceneConfig

__all__ = ["Angles", "Stage"]

Angles = tuple[float, float]  # camera (pan, tilt) in degrees


class Stage:
    """A scene's model and data, its animator (set at each reset) and the camera's
    renderer: the world posed at a time and camera angles, and what the camera sees.
    Where every moving object is a primitive, :attr:`caster`
    (:mod:`wander_env.frames.raycast`) draws the object masks and the keys' layers and
    depth without a GL pass."""

    def __init__(
        self,
        model: mujoco.MjModel,
        scene: SceneConfig,
        params: RenderParams,
        raycast: RaycastParams | None = None,
    ) -> None:
        self.model, self.scene, self.params = model, scene, params
        self.data = mujoco.MjData(model)
        self.width, self.height = scene.camera.width, scene.camera.height
        self._pan_adr = int(model.joint(PAN_JOINT).qposadr[0])
        self._tilt_adr = int(model.joint(TILT_JOINT).qposadr[0])
        self._cam_id = int(model.camera(CAMERA_NAME).id)
        self.k = intrinsics(self.width, self.height, float(model.cam_fovy[self._cam_id]))
        self.layer_lut = geom_layer_ids(model)
        self._animator: SceneAnimator | None = None
        self._renderer: CameraRenderer | None = None  # created where it renders: .renderer
        self._renderer_pid: int | None = None
        self._posed: tuple[int, float, float] | None = None  # (t_us, pan, tilt) of the data
        self._renders = 0
        self._geometry_draws = 0
        # Ray casting: masks and key geometry without a GL pass where every moving geom is
        # a primitive; None: GL draws them.
        rc = raycast or RaycastParams()
        self.caster: PrimitiveCaster | None = None
        if (rc.ground_truth or rc.key_layers) and not unsupported_geoms(model):
            self.caster = PrimitiveCaster(
                model, self.width, self.height, rc, params.visible_geom_groups
            )
        self._cast_for: SceneAnimator | None = None  # the reset the caster's cube is of

    # -- the env's verbs --------------------------------------------------------------------
    def begin_episode(self, animator: SceneAnimator) -> None:
        """A reset: the objects' motion of the new episode; nothing posed, counters zero."""
        self._animator = animator
        self._posed = None
        self.begin_step()

    def begin_step(self) -> None:
        """A step's (or reset's) start: the draw counters back to zero."""
        self._renders = self._geometry_draws = 0

    def invalidate(self) -> None:
        """The data was moved outside :meth:`pose` (the next pose poses it again)."""
        self._posed = None

    # -- what it holds (read-only) ------------------------------------------------------------
    @property
    def animator(self) -> SceneAnimator | None:
        """The objects' motion of the episode (None before the first reset)."""
        return self._animator

    @property
    def posed(self) -> tuple[int, float, float] | None:
        """(t_us, pan, tilt) the data is posed at (None: not posed at one time)."""
        return self._posed

    @property
    def renders(self) -> int:
        """Colour frames rendered since the step's (or reset's) start."""
        return self._renders

    @property
    def geometry_draws(self) -> int:
        """Layer-and-depth draws since the step's (or reset's) start."""
        return self._geometry_draws

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
        """Bounding radius (m) of each motion layer about its position, 1 % beyond the
        geoms' reach (meshes included; inf: the static world or a sliding screen)."""
        return geom_layer_radii(self.model) * 1.01

    def camera_centre_moves(self) -> bool:
        """Whether the camera centre moves as the PTU turns (the scene's hinge offset)."""
        mount = self.scene.ptu
        return mount.camera_forward_m != 0 or mount.camera_up_m != 0

    # -- posing -------------------------------------------------------------------------------
    def pose(self, t_us: int, pan_deg: float, tilt_deg: float) -> None:
        """The camera at these angles and the objects at ``t_us`` into the model."""
        if self._posed == (t_us, pan_deg, tilt_deg):
            return
        self.data.qpos[self._pan_adr] = math.radians(pan_deg)
        self.data.qpos[self._tilt_adr] = math.radians(tilt_deg)
        self._animator.apply(self.data, t_us * 1e-6)
        mujoco.mj_kinematics(self.model, self.data)
        mujoco.mj_camlight(self.model, self.data)
        self._posed = (t_us, pan_deg, tilt_deg)

    def camera_view(self, t_us: int, pan_deg: float, tilt_deg: float) -> View:
        """The :class:`View` at ``t_us`` with the camera at these angles; only the PTU's
        joints and the camera are moved (the model is no longer posed at one time)."""
        return self.camera_views([t_us], [(pan_deg, tilt_deg)])[0]

    def camera_views(self, times_us: list[int], angles: list[Angles]) -> list[View]:
        """:meth:`camera_view` at each time and angles; the camera is posed again only
        where the angles change."""
        views, last = [], None
        for t, a in zip(times_us, angles, strict=True):
            if a != last:
                self.data.qpos[self._pan_adr] = math.radians(a[0])
                self.data.qpos[self._tilt_adr] = math.radians(a[1])
                mujoco.mj_kinematics(self.model, self.data)
                mujoco.mj_camlight(self.model, self.data)
                rotation = rotation_from_mujoco(self.data.cam_xmat[self._cam_id])
                centre, last = self.data.cam_xpos[self._cam_id].copy(), a
            views.append(View(rotation, centre, self._animator.layer_positions(t * 1e-6)))
        self._posed = None
        return views

    # -- drawing ------------------------------------------------------------------------------
    def render(self) -> np.ndarray:
        """RGB uint8 (H, W, 3) of the posed model."""
        self._renders += 1
        return self.renderer.render(self.data)

    def casts(self, what: Literal["ground_truth", "key_layers"]) -> bool:
        """Whether ray casting (:attr:`caster`) draws the object masks (``ground_truth``)
        or the keys' layers and depth (``key_layers``: the camera on its hinge only)."""
        c = self.caster
        if c is None or not getattr(c.params, what):
            return False
        return what == "ground_truth" or c.exact_depth

    def _ready_caster(self) -> PrimitiveCaster:
        """The caster, its static cube dropped at each reset (a new animator)."""
        if self._cast_for is not self._animator:
            self.caster.reset()
            self._cast_for = self._animator
        return self.caster

    def geometry(self) -> tuple[np.ndarray, np.ndarray]:
        """(motion layers int32, depth m) of the posed model, from one draw (or ray cast:
        not counted in :attr:`geometry_draws`)."""
        if self.casts("key_layers"):
            return self._ready_caster().geometry(self.data)
        self._geometry_draws += 1
        self.renderer.update(self.data)
        return self.renderer.segment_depth_current(self.layer_lut)

    def object_mask(self) -> np.ndarray:
        """Object ids (H, W) int32 of the posed model (0 = background)."""
        if self.casts("ground_truth"):
            return self._ready_caster().object_mask(self.data)
        return self.renderer.segment(self.data)

    def close(self) -> None:
        # Freeing is safe in a forked child too (only creating and drawing hang there).
        if self.caster is not None:
            self.caster.close()
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None
