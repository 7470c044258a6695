"""Where the camera's frames come from: the posed scene (:class:`Stage`) and the frame
sources that read one PTU trajectory per step.

:class:`Stage` owns what draws: the MuJoCo model and data, the scene's animator and the
camera's renderer (created in the process that renders). It poses the world at a time and
camera angles, renders a colour frame, a frame's geometry (motion layers and depth) and
the ground truth's object mask.

A :class:`FrameSource` turns a step's :class:`~wander_env.ptu.unit.Trajectory` (the PTU stepped
once per tick, computed once per step) into the frames the DVS sees:

- :meth:`~FrameSource.plan` at the step's start, with the whole trajectory (a source
  may render its keys there: everything it needs is known, nothing waits for later);
- :meth:`~FrameSource.frame` at each render tick and adaptive sub-frame, with that
  time's camera angles;
- :meth:`~FrameSource.object_mask` at the step's end (ground truth).

:class:`ExactFrames` renders every frame. :class:`KeyframeFrames` renders keys and makes
the frames between them from the keys' geometry (:mod:`wander_env.keyframes`).
:class:`PanoramaFrames` warps a cube map of the static world rendered once per reset
(:mod:`wander_env.panorama`) and composites the keys' moving layers over it. A new
frame mode is one more subclass, named in :data:`FRAME_SOURCES` and in
:data:`wander_env.env_config.FrameMode`.
"""

from __future__ import annotations

import bisect
import math
import os
from abc import ABC, abstractmethod
from dataclasses import dataclass, replace
from typing import Annotated, Literal

import mujoco
import numpy as np

from wander_env.camera import CAMERA_NAME, intrinsics, rotation_from_mujoco
from wander_env.config import check_annotated
from wander_env.dvs import DVSEmulator, LogFrame
from wander_env.entities import PAN_JOINT, TILT_JOINT
from wander_env.field_doc import field_doc
from wander_env.gl_fork import ForkedGLError, fork_error_message
from wander_env.keyframes import (
    SUBPIXEL_PX,
    Keyframe,
    KeyPair,
    View,
    adaptive_key_ticks,
    blend,
    make_keyframe,
    view_flow_bounds_px,
)
from wander_env.mjcf import SceneAnimator, geom_layer_ids, geom_layer_radii
from wander_env.ptu.unit import Trajectory
from wander_env.raycast import PrimitiveCaster, RaycastParams, unsupported_geoms
from wander_env.renderer import CameraRenderer, RenderParams
from wander_env.scene_config import SceneConfig

__all__ = [
    "FRAME_SOURCES",
    "ExactFrames",
    "FrameParams",
    "FrameSource",
    "KeyframeFrames",
    "PanoramaFrames",
    "PanoramaParams",
    "RenderedKey",
    "Stage",
]

Angles = tuple[float, float]  # camera (pan, tilt) in degrees


class Stage:
    """A scene's model and data, its animator (set at each reset) and the camera's
    renderer: the world posed at a time and camera angles, and what the camera sees.
    Where every moving object is a primitive, :attr:`caster` (:mod:`wander_env.raycast`)
    draws the object masks and the keys' layers and depth without a GL pass."""

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
        self.animator: SceneAnimator | None = None
        self._renderer: CameraRenderer | None = None  # created where it renders: .renderer
        self._renderer_pid: int | None = None
        self.posed: tuple[int, float, float] | None = None  # (t_us, pan, tilt) of the model
        self.renders = 0  # colour frames rendered since the counter was last zeroed
        self.geometry_draws = 0  # layer-and-depth draws since the counter was last zeroed
        # -- ray casting (wander_env.raycast): masks and key geometry without a GL pass where
        # every moving geom is a primitive; None: GL draws them (set it to None for GL).
        rc = raycast or RaycastParams()
        self.caster: PrimitiveCaster | None = None
        if (rc.ground_truth or rc.key_layers) and not unsupported_geoms(model):
            self.caster = PrimitiveCaster(
                model, self.width, self.height, rc, params.visible_geom_groups
            )
        self._cast_for: SceneAnimator | None = None  # the reset the caster's cube is of

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
            views.append(View(rotation, centre, self.animator.layer_positions(t * 1e-6)))
        self.posed = None
        return views

    def render(self) -> np.ndarray:
        """RGB uint8 (H, W, 3) of the posed model."""
        self.renders += 1
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
        if self._cast_for is not self.animator:
            self.caster.reset()
            self._cast_for = self.animator
        return self.caster

    def geometry(self) -> tuple[np.ndarray, np.ndarray]:
        """(motion layers int32, depth m) of the posed model, from one draw (or ray cast:
        not counted in :attr:`geometry_draws`)."""
        if self.casts("key_layers"):
            return self._ready_caster().geometry(self.data)
        self.geometry_draws += 1
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


@dataclass(frozen=True)
class FrameParams:
    """What a frame source needs of the env's configuration (see ``WanderConfig``)."""

    tick_us: int = 1000
    keyframe_us: int = 2000
    keyframe_px: float | None = 2.0
    key_max_ticks: int | None = None  # keys no more ticks apart while anything moves
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

    def interpolated(self, t_us: int) -> bool:
        """Whether the DVS may go without the frame of this tick of the planned step and
        interpolate over it (nothing in it moves but by a fraction of a pixel)."""
        return False

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


@dataclass(eq=False)
class RenderedKey:
    """A key as rendered: its colour's DVS input and luminance at ``t_us`` from the camera
    at ``angles`` (``view``). Its geometry (layers and depth, one more draw) is made only
    when something asks for it (:meth:`KeyframeFrames.keyframe`): a synthesised frame
    between it and a neighbour, or the ground truth's mask. ``same_as``: an earlier key
    whose geometry this one shares (nothing moved between them)."""

    t_us: int
    angles: Angles
    view: View
    prepared: LogFrame
    lum: np.ndarray  # (H, W) float32 linear luminance (a view of ``prepared.lum``)
    same_as: RenderedKey | None = None
    full: Keyframe | None = None  # with its geometry, once made


class KeyframeFrames(FrameSource):
    """Keys rendered at the step's start along the trajectory where the predicted image
    motion asks for them (:func:`~wander_env.keyframes.adaptive_key_ticks`: as few as one
    a step, none while nothing moves; every ``keyframe_us`` where the motion has no
    bound); the frames between them synthesised (:class:`~wander_env.keyframes.KeyPair`),
    and none where nothing moves by half a pixel: the DVS interpolates there.

    A key's geometry (layers and depth: a second, single-sample draw) is drawn when first
    needed, with the model posed again at the key's time and angles (the same pixels as
    drawing it with the colour): a synthesised frame needs both its keys', the ground
    truth's mask the step end's; a still camera over slow objects, or ground truth off,
    needs fewer or none."""

    def __init__(self, stage: Stage, dvs: DVSEmulator, params: FrameParams) -> None:
        super().__init__(stage, dvs, params)
        self.radii = stage.layer_radii()
        self.keys: list[RenderedKey] = []  # the key at the step's start, then the step's
        self._key_at: dict[int, RenderedKey] = {}  # key t_us -> key (this step)
        self._views: dict[int, View] = {}  # tick t_us -> its view (this step)
        self._interpolated: set[int] = set()  # ticks the DVS interpolates over
        self._pairs: dict[int, KeyPair] = {}  # later key's t_us -> the pair ending there

    def _render_key(self, t_us: int, angles: Angles, view: View) -> RenderedKey:
        """Render the colour of a key of the model posed at ``t_us`` and ``angles``."""
        stage = self.stage
        stage.pose(t_us, *angles)
        rgb = stage.render()
        prepared = self.dvs.prepare(rgb)
        lum = prepared.lum.reshape(stage.height, stage.width)
        self.camera_frame = rgb
        return RenderedKey(t_us, angles, view, prepared, lum)

    def keyframe(self, key: RenderedKey) -> Keyframe:
        """``key`` with its geometry: its layers and depth drawn on first use (the model
        posed again at the key's time and angles), then kept."""
        if key.full is None:
            if key.same_as is not None:
                key.full = replace(self.keyframe(key.same_as), t_us=key.t_us, view=key.view)
            else:
                stage = self.stage
                stage.pose(key.t_us, *key.angles)
                layers, depth = stage.geometry()
                key.full = make_keyframe(key.t_us, key.lum, key.view, depth, layers)
        return key.full

    def reset(self, t_us: int, angles: Angles) -> np.ndarray:
        self._views, self._pairs, self._interpolated = {}, {}, set()
        key = self._render_key(t_us, angles, self.stage.camera_view(t_us, *angles))
        self.keys, self._key_at = [key], {t_us: key}
        return key.lum

    def plan(self, trajectory: Trajectory) -> None:
        p, stage = self.params, self.stage
        ticks = trajectory.t_us
        angles = [trajectory.angles(i) for i in range(len(ticks))]
        views = stage.camera_views(list(ticks), angles)
        self._views = dict(zip(ticks, views, strict=True))
        ref = self.keys[-1]
        self.keys, self._pairs = [ref], {}
        shape, k = (stage.height, stage.width), stage.k
        idx = None
        if p.keyframe_px is not None:
            idx = adaptive_key_ticks(
                ref.view, views, k, self.radii, shape, p.keyframe_px, p.key_max_ticks
            )
        if idx is None:
            idx = [i for i, t in enumerate(ticks) if t == ticks[-1] or t % p.keyframe_us == 0]
        if not idx:  # nothing moves: the start's key is the step's end too (its geometry
            # that of the key it was rendered as, however many still steps ago)
            root = ref if ref.same_as is None else ref.same_as
            self.keys.append(replace(ref, t_us=ticks[-1], view=views[-1], same_as=root, full=None))
        for i in idx:
            self.keys.append(self._render_key(ticks[i], angles[i], views[i]))
        self._key_at = {key.t_us: key for key in self.keys}
        # The ticks between keys whose content moves by less than half a pixel from both.
        between = [(t, v) for t, v in zip(ticks, views, strict=True) if t not in self._key_at]
        self._interpolated = set()
        if between:
            pairs = [self._pair(t) for t, _ in between]
            tv = [v for _, v in between]
            refs = [a.view for a, _ in pairs] + [b.view for _, b in pairs]
            both = view_flow_bounds_px(refs, tv + tv, k, self.radii, shape)
            bounds = np.maximum(both[: len(tv)], both[len(tv) :])
            self._interpolated = {
                t for (t, _), b in zip(between, bounds, strict=True) if b < SUBPIXEL_PX
            }

    def _pair(self, t_us: int) -> tuple[RenderedKey, RenderedKey]:
        """The keys just before and at-or-after ``t_us`` (inside the planned step)."""
        i = bisect.bisect_left([key.t_us for key in self.keys], t_us)
        return self.keys[i - 1], self.keys[i]

    def _keypair(self, a: RenderedKey, b: RenderedKey) -> KeyPair:
        """The keys' :class:`KeyPair` (with their geometry), made once a step."""
        pair = self._pairs.get(b.t_us)
        if pair is None:
            pair = self._pairs[b.t_us] = KeyPair(self.keyframe(a), self.keyframe(b), self.stage.k)
        return pair

    def interpolated(self, t_us: int) -> bool:
        return t_us in self._interpolated

    def frame(self, t_us: int, angles: Angles) -> np.ndarray | LogFrame:
        """A key's own input at its tick; the keys' blend where nothing moves by half a
        pixel; else a synthesised frame."""
        key = self._key_at.get(t_us)
        if key is not None:
            return key.prepared
        a, b = self._pair(t_us)
        w = (t_us - a.t_us) / (b.t_us - a.t_us)
        if t_us in self._interpolated:
            return blend(a.lum, b.lum, w)
        view = self._views.get(t_us)
        if view is None:  # a sub-frame inside a tick
            view = self.stage.camera_view(t_us, *angles)
            shape, k = (self.stage.height, self.stage.width), self.stage.k
            bound = view_flow_bounds_px([a.view, b.view], [view, view], k, self.radii, shape)
            if bound.max() < SUBPIXEL_PX:
                return blend(a.lum, b.lum, w)
        return self.synthesize(self._keypair(a, b), view, w)

    def synthesize(self, pair: KeyPair, view: View, w: float) -> np.ndarray:
        """An in-between frame (a method of its own, for profiling)."""
        return pair.frame(view, w)

    def object_mask(self, t_us: int) -> np.ndarray:
        key = self._key_at.get(t_us)
        if key is None or (key.full is None and self.stage.casts("ground_truth")):
            return super().object_mask(t_us)  # ray cast (a key's layers made: those)
        layers = self.keyframe(key).layers
        return np.where(layers <= self.stage.scene.num_objects, layers, 0).astype(np.int32)


def _shifted(a: np.ndarray, dy: int, dx: int, fill: float) -> np.ndarray:
    """``a`` moved by (dy, dx) pixels (``out[y, x] = a[y - dy, x - dx]``), ``fill`` where
    nothing moves in (no wrap-around)."""
    out = np.full_like(a, fill)
    h, w = a.shape
    out[max(dy, 0) : h + min(dy, 0), max(dx, 0) : w + min(dx, 0)] = a[
        max(-dy, 0) : h + min(-dy, 0), max(-dx, 0) : w + min(-dx, 0)
    ]
    return out


def layers_in_view(
    views: list[View],
    k: np.ndarray,
    radii: np.ndarray,
    shape: tuple[int, int],
    margin_px: float = 4.0,
) -> bool:
    """Whether any moving layer (a ball of ``radii[layer]`` m about its position; ``inf``:
    always) may reach the image (widened by ``margin_px``) in any of ``views``."""
    h, w = shape
    f = float(k[0, 0])
    cx, cy = float(k[0, 2]), float(k[1, 2])
    # Inward normals of the frustum's side planes (camera axes), unit length.
    normals = np.array(
        [
            [f, 0, cx + 0.5 + margin_px],
            [-f, 0, w - 0.5 - cx + margin_px],
            [0, f, cy + 0.5 + margin_px],
            [0, -f, h - 0.5 - cy + margin_px],
        ]
    )
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    for view in views:
        pos = view.layer_positions[1:]
        r = np.asarray(radii, float)[1 : 1 + len(pos)]
        if not np.isfinite(r).all():
            return True
        p = (pos - view.centre) @ view.rotation  # camera axes
        inside = (p[:, 2] > -r) & ((p @ normals.T) > -r[:, None]).all(axis=1)
        if inside.any():
            return True
    return False


#: How :class:`PanoramaFrames` may light its faces (see :func:`wander_env.panorama.render_cube`).
Headlight = Literal["camera", "face", "off"]


@dataclass(frozen=True)
class PanoramaParams:
    """How :class:`PanoramaFrames` renders and samples its panorama: the defaults are the
    faster of the two variants measured closer to the world than the default keyframes
    (docs/fidelity.md, "The panorama").

    - ``samples`` 4: the faces are ``samples × 2f`` pixels, each with the scene's MSAA;
    - ``prefilter`` True: the faces box-filtered (``samples × samples``) once, then one
      bilinear sample a sensor pixel; False: ``samples × samples`` rays a pixel;
    - ``bilinear`` True: without ``prefilter``, each ray samples bilinearly (False: the
      nearest face pixel);
    - ``srgb`` True: average sRGB codes, as a supersampled render's resolve does (False:
      linear light);
    - ``edge_px`` 1: the moving layers grown by this many pixels over the panorama (an
      object's edge pixels, which the key blended with the real background, move with it);
    - ``headlight`` ``"camera"``: the faces lit by the headlight held along the camera's
      axis at reset (``"face"``: turned with each face; ``"off"``).
    """

    samples: Annotated[
        int, field_doc("Face pixels a sensor pixel, along each axis", ge=1, le=8)
    ] = 4
    prefilter: Annotated[
        bool, field_doc("Box-filter the faces once, one bilinear sample a pixel")
    ] = True
    bilinear: Annotated[bool, field_doc("Without prefilter: bilinear rays, else nearest")] = True
    srgb: Annotated[bool, field_doc("Average sRGB codes, not linear light")] = True
    edge_px: Annotated[int, field_doc("Growth of the moving layers", unit="px", ge=0, le=4)] = 1
    headlight: Headlight = "camera"

    def __post_init__(self) -> None:
        check_annotated(self)


class PanoramaFrames(KeyframeFrames):
    """The static world from a panorama; the moving layers from keys, over it by depth.

    At reset the static world (every geom of motion layer 0; the moving layers hidden) is
    rendered once as a cube map from the camera centre (:func:`wander_env.panorama.render_cube`,
    faces of ``2·f·samples`` pixels, each with the scene's multisampling: ``samples²`` ×
    MSAA samples a sensor pixel). Every frame's background is that cube warped by the
    camera's rotation at the frame's time, ``samples × samples`` rays a pixel averaged
    (:func:`~wander_env.panorama.cube_warp`), with its inverse depth from the cube's ray
    distances. Keys are rendered as :class:`KeyframeFrames` renders them (the whole
    scene: an object's edge pixels blend with the real background) only while a moving
    layer may be in view (:func:`layers_in_view` along the step); their moving layers
    are synthesised at each frame and composited over the background by depth
    (:func:`~wander_env.panorama.layers_over`); outside the layers' boxes every pixel is
    the panorama's.

    Lighting: MuJoCo's headlight turns with the camera, as no room light does. The faces
    are lit by it held along the camera's axis at reset (``headlight="camera"``; see
    :func:`~wander_env.panorama.render_cube` for the others): the background is shaded as
    the sensor sees it at the reset's pose, and keeps that shading as the camera turns
    (a per-tick render's headlight turns with it).

    Where the camera centre moves (a hinge offset: the scene's ``ptu.camera_forward_m`` or
    ``camera_up_m`` non-zero), a panorama from one centre is wrong (parallax): the
    source then is :class:`KeyframeFrames` for the whole stream.

    The way it renders and samples the panorama is :attr:`panorama`, a
    :class:`PanoramaParams` (the measured variants; set it before the reset).
    """

    def __init__(
        self,
        stage: Stage,
        dvs: DVSEmulator,
        params: FrameParams,
        panorama: PanoramaParams | None = None,
    ) -> None:
        self._grey_of: np.ndarray | None = None  # a background to show as camera_frame
        super().__init__(stage, dvs, params)
        self.panorama = panorama or PanoramaParams()
        mount = stage.scene.ptu
        self.fallback = mount.camera_forward_m != 0 or mount.camera_up_m != 0
        self._cube: tuple[np.ndarray, np.ndarray] | None = None
        self._face_renderer = None
        self._hide = stage.layer_lut != 0
        self._wlut = dvs._wlut  # per channel and code: its share of the linear luminance
        self._bg: dict[bytes, tuple[np.ndarray, np.ndarray]] = {}
        self._with_keys = False
        self._edge_pairs: dict[tuple[int, int], KeyPair] = {}
        self._edge_keys: dict[int, tuple[RenderedKey, Keyframe]] = {}  # id(key) -> grown
        self._end: tuple[int, Angles, View] | None = None  # the last step's end

    @property
    def camera_frame(self) -> np.ndarray | None:
        """The latest colour frame rendered; in a step without keys, the background at
        the step's end as grey sRGB."""
        if self._grey_of is not None:
            lum = np.clip(self._grey_of, 0.0, 1.0)
            srgb = np.where(lum <= 0.0031308, 12.92 * lum, 1.055 * lum ** (1 / 2.4) - 0.055)
            grey = np.rint(255 * srgb).astype(np.uint8)
            self._camera_frame, self._grey_of = np.repeat(grey[..., None], 3, axis=2), None
        return self._camera_frame

    @camera_frame.setter
    def camera_frame(self, rgb: np.ndarray | None) -> None:
        self._camera_frame, self._grey_of = rgb, None

    def build(self, t_us: int, angles: Angles) -> None:
        """Render the panorama from the camera centre at ``t_us`` and ``angles``."""
        from wander_env.panorama import box_filter, render_cube

        stage, pp = self.stage, self.panorama
        stage.pose(t_us, *angles)
        n = round(2 * float(stage.k[0, 0]) * pp.samples)
        lum, srgb, dist, self._face_renderer = render_cube(
            stage.model, stage.data, n, self._hide, pp.headlight, self._face_renderer
        )
        stage.posed = None  # the camera was turned to the faces
        self._offset = 0.0
        if pp.srgb and pp.prefilter:
            srgb, self._offset = box_filter(srgb, pp.samples)
        self._cube = (srgb if pp.srgb else lum, dist)
        self._bg = {}

    def background(
        self, rotation: np.ndarray, depth: bool = True
    ) -> tuple[np.ndarray, np.ndarray | None]:
        """(luminance, inverse depth (None unless ``depth``)) (H, W) of the static world
        for a camera rotation (kept for the rotations of the current step)."""
        from wander_env.panorama import (
            FACE_ROTATIONS,
            cube_inverse_depth,
            cube_warp,
            cube_warp_srgb,
        )

        key = rotation.tobytes()
        stage, (faces, dist) = self.stage, self._cube
        k = stage.k
        f, cx, cy = float(k[0, 0]), float(k[0, 2]), float(k[1, 2])
        got = self._bg.get(key)
        if got is None:
            lum = np.empty((stage.height, stage.width), np.float32)
            pp = self.panorama
            if pp.srgb:  # prefiltered: one bilinear sample of the box-filtered faces
                s, bilinear = (1, True) if pp.prefilter else (pp.samples, pp.bilinear)
                args = (f, cx, cy, s, bilinear, self._wlut, self._offset)
                cube_warp_srgb(lum, faces, FACE_ROTATIONS, rotation, *args)
            else:
                args = (f, cx, cy, pp.samples, pp.bilinear)
                cube_warp(lum, faces, FACE_ROTATIONS, rotation, *args)
            got = self._bg[key] = (lum, None)
        if depth and got[1] is None:
            rho = np.empty((stage.height, stage.width), np.float64)
            cube_inverse_depth(rho, dist, FACE_ROTATIONS, rotation, f, cx, cy)
            got = self._bg[key] = (got[0], rho)
        return got

    def reset(self, t_us: int, angles: Angles) -> np.ndarray:
        if self.fallback:
            return super().reset(t_us, angles)
        self.build(t_us, angles)
        self._edge_pairs, self._edge_keys = {}, {}
        view = self.stage.camera_view(t_us, *angles)
        self._end = (t_us, angles, view)
        self._with_keys = layers_in_view([view], self.stage.k, self.radii, self._shape)
        if self._with_keys:
            super().reset(t_us, angles)
        else:
            self.keys, self._key_at, self._pairs = [], {}, {}
            self._views, self._interpolated = {}, set()
        first = self._composite(t_us, view)
        if not self._with_keys:
            self._grey_of = first
        return first

    @property
    def _shape(self) -> tuple[int, int]:
        return self.stage.height, self.stage.width

    def plan(self, trajectory: Trajectory) -> None:
        if self.fallback:
            return super().plan(trajectory)
        stage = self.stage
        ticks = trajectory.t_us
        angles = [trajectory.angles(i) for i in range(len(ticks))]
        views = stage.camera_views(list(ticks), angles)
        t0, a0, v0 = self._end
        self._bg = {k: v for k, v in self._bg.items() if k == v0.rotation.tobytes()}
        visible = layers_in_view([v0, *views], stage.k, self.radii, self._shape)
        self._edge_pairs = {}
        start = self.keys[-1] if self.keys else None
        self._edge_keys = {i: v for i, v in self._edge_keys.items() if v[0] is start}
        if visible:
            if not self._with_keys:  # a fresh key at the step's start
                key = self._render_key(t0, a0, v0)
                self.keys, self._key_at = [key], {t0: key}
            super().plan(trajectory)
        else:
            self.keys, self._key_at, self._pairs = [], {}, {}
            self._views = dict(zip(ticks, views, strict=True))
            still = all((v.rotation == v0.rotation).all() for v in views)
            self._interpolated = set(ticks) if still else set()
            self._grey_of = self.background(views[-1].rotation, depth=False)[0]
        self._with_keys = visible
        self._end = (ticks[-1], angles[-1], views[-1])

    def frame(self, t_us: int, angles: Angles) -> np.ndarray | LogFrame:
        if self.fallback:
            return super().frame(t_us, angles)
        view = self._views.get(t_us)
        if view is None:  # a sub-frame inside a tick
            view = self.stage.camera_view(t_us, *angles)
        return self._composite(t_us, view)

    def _composite(self, t_us: int, view: View) -> np.ndarray:
        """The background of ``view`` with the keys' moving layers over it by depth."""
        from wander_env.panorama import layers_over

        if not self._with_keys:
            return self.background(view.rotation, depth=False)[0]
        bg, rho = self.background(view.rotation)
        if len(self.keys) == 1 or t_us <= self.keys[0].t_us:
            a = b = self.keys[0]
            w = 1.0
        elif t_us in self._key_at:  # a key's own tick: that key alone
            a = b = self._key_at[t_us]
            w = 1.0
        else:
            a, b = self._pair(t_us)
            w = (t_us - a.t_us) / (b.t_us - a.t_us)
        pair = self._edge_pairs.get((a.t_us, b.t_us))
        if pair is None:
            kb = self._edge_key(b)
            ka = replace(kb, t_us=kb.t_us - 1) if a is b else self._edge_key(a)
            pair = self._edge_pairs[(a.t_us, b.t_us)] = KeyPair(ka, kb, self.stage.k)
        hinv, bvec, moving, boxes = pair.params(view)
        regions = pair.regions(boxes)
        if not len(regions):
            return bg
        out = bg.copy()
        weights = np.array([1.0 - w, w])
        layers_over(out, bg, rho, regions, weights, *pair.kernel_args(hinv, bvec, moving, boxes))
        return out

    def _edge_key(self, key: RenderedKey) -> Keyframe:
        """``key``'s keyframe with each moving layer grown by ``edge_px`` pixels into the
        static world's (each such pixel takes its nearest neighbour's layer and depth):
        the object's edge pixels, which the render blended with the real background,
        move with it over the panorama."""
        kf = self.keyframe(key)
        if self.panorama.edge_px == 0:
            return kf
        got = self._edge_keys.get(id(key))
        if got is not None and got[0] is key:
            return got[1]
        layers, inv = kf.layers.copy(), kf.inv_depth.copy()
        for _ in range(self.panorama.edge_px):
            grown_l, grown_i = layers.copy(), inv.copy()
            for dy, dx in ((-1, 0), (1, 0), (0, -1), (0, 1), (-1, -1), (-1, 1), (1, -1), (1, 1)):
                nl, ni = _shifted(layers, dy, dx, 0), _shifted(inv, dy, dx, 0.0)
                take = (layers == 0) & (nl != 0) & (ni > np.where(grown_l == 0, 0.0, grown_i))
                grown_l[take], grown_i[take] = nl[take], ni[take]
            layers, inv = grown_l, grown_i
        grown = make_keyframe(kf.t_us, kf.lum, kf.view, 1.0 / inv, layers)
        self._edge_keys[id(key)] = (key, grown)
        return grown

    def object_mask(self, t_us: int) -> np.ndarray:
        if self.fallback or self._with_keys:
            return super().object_mask(t_us)
        # No moving layer may reach the image at the step's end: no object in it.
        return np.zeros((self.stage.height, self.stage.width), np.int32)


#: The frame sources by ``WanderConfig.frames`` name.
FRAME_SOURCES: dict[str, type[FrameSource]] = {
    "keyframes": KeyframeFrames,
    "exact": ExactFrames,
    "panorama": PanoramaFrames,
}
