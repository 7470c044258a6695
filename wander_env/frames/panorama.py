"""The panorama source: the static world warped from a cube map rendered once per reset
(:mod:`wander_env.frames.cube`), the moving objects from a keyframe source's keys
composited over it by depth."""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Annotated, Literal

import numpy as np

from wander_env.config import check_annotated
from wander_env.dvs import DVSEmulator, LogFrame
from wander_env.field_doc import field_doc
from wander_env.frames.keyframe_maths import (
    Keyframe,
    KeyPair,
    View,
    grow_layers,
    layers_in_view,
    layers_over,
    make_keyframe,
)
from wander_env.frames.keyframes import KeyframeFrames, RenderedKey
from wander_env.frames.source import FrameParams, FrameSource
from wander_env.frames.stage import Angles, Stage
from wander_env.ptu.unit import Trajectory
from wander_env.renderer import CameraRenderer

__all__ = ["Headlight", "PanoramaFrames", "PanoramaParams"]

#: How :class:`PanoramaFrames` may light its faces (see :func:`wander_env.frames.cube.render_cube`).
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


class PanoramaFrames(FrameSource):
    """The static world from a panorama; the moving layers from keys, over it by depth.

    At reset the static world (every geom of motion layer 0; the moving layers hidden) is
    rendered once as a cube map from the camera centre
    (:func:`wander_env.frames.cube.render_cube`, faces of ``2·f·samples`` pixels, each
    with the scene's multisampling: ``samples²`` × MSAA samples a sensor pixel). Every
    frame's background is that cube warped by the camera's rotation at the frame's time,
    ``samples × samples`` rays a pixel averaged (:func:`~wander_env.frames.cube.cube_warp`),
    with its inverse depth from the cube's ray distances. Its :attr:`moving` keyframe
    source renders keys (the whole scene: an object's edge pixels blend with the real
    background) only while a moving layer may be in view
    (:func:`~wander_env.frames.keyframe_maths.layers_in_view` along the step); their
    moving layers are synthesised at each frame and composited over the background by
    depth (:func:`~wander_env.frames.keyframe_maths.layers_over`); outside the layers'
    boxes every pixel is the panorama's.

    Lighting: MuJoCo's headlight turns with the camera, as no room light does. The faces
    are lit by it held along the camera's axis at reset (``headlight="camera"``; see
    :func:`~wander_env.frames.cube.render_cube` for the others): the background is shaded
    as the sensor sees it at the reset's pose, and keeps that shading as the camera turns
    (a per-tick render's headlight turns with it).

    Where the camera centre moves (a hinge offset: the unit's ``PTUParams.camera_forward_m``
    or ``camera_up_m`` non-zero), a panorama from one centre is wrong (parallax): there
    :meth:`create` gives a :class:`KeyframeFrames` instead, and this class refuses the
    stage.

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
        if stage.camera_centre_moves():
            raise ValueError(
                "frames: a panorama needs a camera centre that stays put, but the scene's "
                "camera is offset from the tilt hinge (use PanoramaFrames.create)"
            )
        super().__init__(stage, dvs, params)
        self.panorama = panorama or PanoramaParams()
        # The keys of the moving layers, each composited at every frame near it.
        self.moving = KeyframeFrames(
            stage, dvs, params, geometry_at_keys=True, frames_on_draw_side=False
        )
        self._cube: tuple[np.ndarray, np.ndarray] | None = None
        self._rays: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None  # with the cube
        self._offset = 0.0
        self._face_renderer: CameraRenderer | None = None  # the cube's, on the draw side
        self._hide = stage.layer_lut != 0
        self._bg: dict[bytes, tuple[np.ndarray, np.ndarray | None]] = {}
        self._with_keys = False
        self._views: dict[int, View] = {}  # tick t_us -> its view (this step)
        self._still: set[int] = set()  # ticks the DVS interpolates over (no keys)
        self._grey_of: np.ndarray | None = None  # the background shown as camera_frame
        self._grey: np.ndarray | None = None  # ... as grey sRGB, once asked for
        self._edge_pairs: dict[tuple[int, int], KeyPair] = {}
        self._edge_keys: dict[int, tuple[RenderedKey, Keyframe]] = {}  # id(key) -> grown
        self._step_end: tuple[int, Angles, View] | None = None  # the last step's end

    @classmethod
    def create(cls, stage: Stage, dvs: DVSEmulator, params: FrameParams) -> FrameSource:
        """A panorama source, or where the camera centre moves a :class:`KeyframeFrames`."""
        if stage.camera_centre_moves():
            return KeyframeFrames(stage, dvs, params)
        return cls(stage, dvs, params)

    @property
    def with_keys(self) -> bool:
        """Whether a moving layer may be in view in this step (its keys are rendered)."""
        return self._with_keys

    @property
    def camera_frame(self) -> np.ndarray | None:
        """The latest colour key rendered; in a step without keys, the background at the
        step's end as grey sRGB."""
        if self._with_keys:
            return self.moving.camera_frame
        if self._grey is None and self._grey_of is not None:
            lum = np.clip(self._grey_of, 0.0, 1.0)
            srgb = np.where(lum <= 0.0031308, 12.92 * lum, 1.055 * lum ** (1 / 2.4) - 0.055)
            grey = np.rint(255 * srgb).astype(np.uint8)
            self._grey = np.repeat(grey[..., None], 3, axis=2)
        return self._grey

    def _show_background(self, lum: np.ndarray) -> None:
        self._grey_of, self._grey = lum, None

    def build(self, t_us: int, angles: Angles) -> None:
        """Render the panorama from the camera centre at ``t_us`` and ``angles``."""
        from wander_env.frames.cube import box_filter, face_px, pixel_rays, render_cube

        stage, pp = self.stage, self.panorama
        n = face_px(stage.k, pp.samples)

        def draw() -> tuple[np.ndarray, np.ndarray, np.ndarray, CameraRenderer]:
            stage.pose(t_us, *angles)
            faces = render_cube(
                stage.model, stage.draw_data, n, self._hide, pp.headlight, self._face_renderer
            )
            stage.invalidate()  # the camera was turned to the faces
            return faces

        lum, srgb, dist, self._face_renderer = stage.on_draw_side(draw)
        self._offset = 0.0
        if pp.srgb and pp.prefilter:
            srgb, self._offset = box_filter(srgb, pp.samples)
        self._cube = (srgb if pp.srgb else lum, dist)
        k = stage.k
        self._rays = pixel_rays(stage.width, stage.height, k[0, 0], k[0, 2], k[1, 2])
        self._bg = {}

    def background(
        self, rotation: np.ndarray, depth: bool = True
    ) -> tuple[np.ndarray, np.ndarray | None]:
        """(luminance, inverse depth (None unless ``depth``)) (H, W) of the static world
        for a camera rotation (kept for the rotations of the current step)."""
        from wander_env.frames.cube import cube_inverse_depth, cube_warp, cube_warp_srgb

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
                args = (f, cx, cy, s, bilinear, self.dvs.channel_luminance, self._offset)
                cube_warp_srgb(lum, faces, rotation, *args)
            else:
                args = (f, cx, cy, pp.samples, pp.bilinear)
                cube_warp(lum, faces, rotation, *args)
            got = self._bg[key] = (lum, None)
        if depth and got[1] is None:
            rho = np.empty((stage.height, stage.width), np.float64)
            cube_inverse_depth(rho, dist, rotation, *self._rays)
            got = self._bg[key] = (got[0], rho)
        return got

    def _in_view(self, views: list[View]) -> bool:
        stage = self.stage
        return layers_in_view(views, stage.k, self.moving.radii, (stage.height, stage.width))

    def reset(self, t_us: int, angles: Angles) -> LogFrame:
        self.build(t_us, angles)
        self._edge_pairs, self._edge_keys = {}, {}
        view = self.stage.camera_view(t_us, *angles)
        self._step_end = (t_us, angles, view)
        self._views, self._still = {}, set()
        self._with_keys = self._in_view([view])
        if self._with_keys:
            self.moving.reset(t_us, angles)
        else:
            self.moving.start_with([])
        first = self._composite(t_us, view)
        if not self._with_keys:
            self._show_background(first)
        return self.dvs.prepare(first)

    def plan(self, trajectory: Trajectory) -> None:
        stage = self.stage
        ticks = trajectory.t_us
        angles = [trajectory.angles(i) for i in range(len(ticks))]
        views = stage.camera_views(list(ticks), angles)
        self._views = dict(zip(ticks, views, strict=True))
        t0, a0, v0 = self._step_end
        self._bg = {k: v for k, v in self._bg.items() if k == v0.rotation.tobytes()}
        visible = self._in_view([v0, *views])
        self._edge_pairs = {}
        keys = self.moving.keys
        start = keys[-1] if keys else None
        self._edge_keys = {i: v for i, v in self._edge_keys.items() if v[0] is start}
        self._still = set()
        if visible:
            if not self._with_keys:  # a fresh key at the step's start
                self.moving.start_with([self.moving.render_key(t0, a0, v0)])
            self.moving.plan(trajectory)
        else:
            self.moving.start_with([])
            still = all((v.rotation == v0.rotation).all() for v in views)
            self._still = set(ticks) if still else set()
            self._show_background(self.background(views[-1].rotation, depth=False)[0])
        self._with_keys = visible
        self._step_end = (ticks[-1], angles[-1], views[-1])

    def interpolated(self, t_us: int) -> bool:
        if self._with_keys:
            return self.moving.interpolated(t_us)
        return t_us in self._still

    def frame(self, t_us: int, angles: Angles) -> LogFrame:
        view = self._views.get(t_us)
        if view is None:  # a sub-frame inside a tick
            view = self.stage.camera_view(t_us, *angles)
        return self.dvs.prepare(self._composite(t_us, view))

    def _composite(self, t_us: int, view: View) -> np.ndarray:
        """The background of ``view`` with the keys' moving layers over it by depth."""
        if not self._with_keys:
            return self.background(view.rotation, depth=False)[0]
        bg, rho = self.background(view.rotation)
        keys = self.moving.keys
        own = self.moving.key_at(t_us)
        if len(keys) == 1 or t_us <= keys[0].t_us:
            a = b = keys[0]
            w = 1.0
        elif own is not None:  # a key's own tick: that key alone
            a = b = own
            w = 1.0
        else:
            a, b = self.moving.pair(t_us)
            w = (t_us - a.t_us) / (b.t_us - a.t_us)
        pair = self._edge_pairs.get((a.t_us, b.t_us))
        if pair is None:
            kb = self._edge_key(b)
            ka = replace(kb, t_us=kb.t_us - 1) if a is b else self._edge_key(a)
            pair = self._edge_pairs[(a.t_us, b.t_us)] = KeyPair(
                ka, kb, self.stage.k, self.stage.k_inv
            )
        hinv, bvec, moving, boxes = pair.params(view)
        regions = pair.regions(boxes)
        if not len(regions):
            return bg
        out = bg.copy()
        weights = np.array([1.0 - w, w])
        layers_over(out, bg, rho, regions, weights, pair.kernel_args(hinv, bvec, moving, boxes))
        return out

    def _edge_key(self, key: RenderedKey) -> Keyframe:
        """``key``'s keyframe with each moving layer grown by ``edge_px`` pixels into the
        static world's (:func:`~wander_env.frames.keyframe_maths.grow_layers`): the
        object's edge pixels, which the render blended with the real background, move
        with it over the panorama."""
        kf = self.moving.keyframe(key)
        if self.panorama.edge_px == 0:
            return kf
        got = self._edge_keys.get(id(key))
        if got is not None and got[0] is key:
            return got[1]
        layers, inv = grow_layers(kf.layers, kf.inv_depth, self.panorama.edge_px)
        grown = make_keyframe(kf.t_us, kf.lum, kf.view, 1.0 / inv, layers)
        self._edge_keys[id(key)] = (key, grown)
        return grown

    def close(self) -> None:
        super().close()
        renderer, self._face_renderer = self._face_renderer, None
        if renderer is not None:
            self.stage.close_renderer(renderer)

    def finish(self, t_us: int, angles: Angles) -> None:
        super().finish(t_us, angles)
        self.moving.finish(t_us, angles)  # its keys' ground truth reads its own end

    def object_mask(self, t_us: int) -> np.ndarray:
        if self._with_keys:
            return self.moving.object_mask(t_us)
        # No moving layer may reach the image at the step's end: no object in it.
        return np.zeros((self.stage.height, self.stage.width), np.int32)
