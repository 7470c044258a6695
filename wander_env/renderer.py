"""Offscreen rendering of the event camera: RGB frames and object segmentation masks.

:class:`CameraRenderer` drives MuJoCo's OpenGL renderer (headless via EGL: ``MUJOCO_GL``
defaults to ``egl`` when this module is imported first) with shadows, reflections,
skybox, fog and haze off, and renders from the camera ``event_camera``:

- :meth:`CameraRenderer.render`: RGB uint8 (H, W, 3), row 0 at the top;
- :meth:`CameraRenderer.segment`: int32 (H, W) object ids: 0 background, k for the
  geoms of body ``object_k`` (see :func:`wander_env.mjcf.geom_object_ids`);
- :meth:`CameraRenderer.render_with_mask`: both from one scene update;
- :meth:`CameraRenderer.segment_depth_current`: ids and depth (metres) from one draw;
- :meth:`CameraRenderer.render_depth_current`: RGB and depth from one colour draw.

:func:`project_points` maps world points to pixel coordinates (x right, y down, pixel
centres at integers; the sensor centre is ((W-1)/2, (H-1)/2)).

Examples:
    >>> import mujoco
    >>> from wander_env.mjcf import compile_scene
    >>> from wander_env.scenes import load_scene_config
    >>> model = compile_scene(load_scene_config("shelf"))
    >>> data = mujoco.MjData(model)
    >>> mujoco.mj_forward(model, data)
    >>> with CameraRenderer(model) as cam:
    ...     rgb, mask = cam.render_with_mask(data)
    >>> rgb.shape, mask.shape, int(mask.max())
    ((128, 128, 3), (128, 128), 0)
"""

from __future__ import annotations

import contextlib
import os
import warnings
from dataclasses import dataclass

import mujoco
import numpy as np

from wander_env.camera import (
    CAMERA_NAME,
    intrinsics,
    linearise_depth,
    project,
    rotation_from_mujoco,
)
from wander_env.closing import Closing
from wander_env.gl_process import claim_gl, gl_lock
from wander_env.mjcf import geom_object_ids


@dataclass(frozen=True)
class RenderParams:
    """Render options; the defaults are the fast headless ones.

    On a CPU (Mesa llvmpipe) the 128 × 128 office view takes about 0.6 ms a frame without
    multisampling and 1.4 ms with the default 4 samples (``antialias_samples``).
    """

    shadows: bool = False
    reflections: bool = False
    skybox: bool = False
    fog: bool = False
    haze: bool = False
    visible_geom_groups: tuple[int, ...] = (0, 1, 2)  # the PTU's own geoms are group 3
    # Render s times the resolution and average s × s blocks (of the sRGB codes, as an
    # MSAA resolve does): with the scenes' 4 MSAA samples, 2 gives 16 samples a pixel.
    # Mesa's llvmpipe caps MSAA at 4 samples (16 renders the same pixels as 4), so this
    # is how the exact mode's finer-antialiased reference is made on a CPU.
    supersample: int = 1

    def __post_init__(self) -> None:
        s = self.supersample
        if isinstance(s, bool) or not isinstance(s, int) or s < 1:
            raise ValueError(f"RenderParams.supersample must be an int >= 1, got {s!r}")


class CameraRenderer(Closing):
    """RGB and segmentation frames from one camera of a model; close() when done.

    Create it in the process that renders: a process forked after GL was initialised
    cannot render, and this raises :class:`~wander_env.gl_process.ForkedGLError` there.
    Close it on the thread that draws with it: dropped without :meth:`close` (collected
    on whichever thread runs the garbage collector), it frees nothing through GL and
    warns (``ResourceWarning``); destroying its GL context frees what it held.

    Its GL calls run under the process's GL lock (:func:`~wander_env.gl_process.gl_lock`):
    renderers on different threads take turns.

    It drives MuJoCo's renderer directly (one GL context, ``mjv_updateScene``,
    ``mjr_render``, ``mjr_readPixels`` into a reused buffer): the same pixels as
    ``mujoco.Renderer``, without its per-frame Python overhead. Segmentation draws
    flat id colours with multisampling off, so when the model multisamples it is
    rendered into a second, single-sample framebuffer (same masks, no 4× clears and
    resolve).
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        width: int = 128,
        height: int = 128,
        camera: str | int = CAMERA_NAME,
        params: RenderParams | None = None,
    ) -> None:
        self.params = params if params is not None else RenderParams()
        if isinstance(camera, str):
            cam_id = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_CAMERA, camera)
            if cam_id < 0:
                raise ValueError(f"camera {camera!r} not found in the model")
        else:
            cam_id = int(camera)
            if not 0 <= cam_id < model.ncam:
                raise ValueError(f"camera id {cam_id} out of range [0, {model.ncam})")
        ss = self.params.supersample
        buf_w, buf_h = model.vis.global_.offwidth, model.vis.global_.offheight
        if ss > 1:  # the supersampled buffer: grow the model's offscreen buffer to fit
            model.vis.global_.offwidth = buf_w = max(buf_w, width * ss)
            model.vis.global_.offheight = buf_h = max(buf_h, height * ss)
        if width > buf_w or height > buf_h:
            raise ValueError(
                f"image {width}x{height} exceeds the model's offscreen buffer {buf_w}x{buf_h} "
                "(<visual><global offwidth=... offheight=.../></visual>)"
            )
        self.model = model
        self.camera_id = cam_id
        self.width, self.height = width, height
        self._gl: mujoco.GLContext | None = None
        self._con: mujoco.MjrContext | None = None
        self._seg_con: mujoco.MjrContext | None = None
        claim_gl()  # in a child forked after GL was initialised: ForkedGLError, not a hang
        try:
            with gl_lock():
                self._gl = mujoco.GLContext(width * ss, height * ss)
                self._gl.make_current()
                self._con = self._context(model.vis.quality.offsamples)
                self._seg_con = self._context(0) if model.vis.quality.offsamples > 0 else self._con
        except mujoco.FatalError as e:
            self.close()
            backend = os.environ.get("MUJOCO_GL", "")
            in_use = getattr(mujoco.GLContext, "__module__", "").rpartition(".")[2]
            if backend and in_use == backend:  # the right backend: the context itself failed
                hint = (
                    f"MUJOCO_GL={backend} is set; a {width}x{height} image may exceed what the "
                    "GL driver can allocate (try a smaller camera)"
                )
            else:
                hint = (
                    f"MuJoCo uses the {in_use or 'unknown'} GL backend, picked when it was "
                    "first imported: set MUJOCO_GL=egl "
                    "in the environment, or import wander_env.renderer (or wander_env.mjcf) "
                    "before mujoco"
                )
            raise RuntimeError(
                f"could not create a {width}x{height} OpenGL context ({e}); {hint}"
            ) from e
        self._scene = mujoco.MjvScene(model, maxgeom=10000)
        flags = self._scene.flags
        p = self.params
        flags[mujoco.mjtRndFlag.mjRND_SHADOW] = p.shadows
        flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = p.reflections
        flags[mujoco.mjtRndFlag.mjRND_SKYBOX] = p.skybox
        flags[mujoco.mjtRndFlag.mjRND_FOG] = p.fog
        flags[mujoco.mjtRndFlag.mjRND_HAZE] = p.haze
        self._option = mujoco.MjvOption()
        for g in range(len(self._option.geomgroup)):
            self._option.geomgroup[g] = int(g in p.visible_geom_groups)
        self._camera = mujoco.MjvCamera()
        self._camera.type = mujoco.mjtCamera.mjCAMERA_FIXED
        self._camera.fixedcamid = cam_id
        self._rect = mujoco.MjrRect(0, 0, width * ss, height * ss)
        self._rgb = np.empty((height * ss, width * ss, 3), np.uint8)  # GL rows: bottom first
        self._depth_buf = np.empty((height * ss, width * ss), np.float32)
        # seg id (geom id + 1; 0 = nothing) -> object id
        self._lut = np.concatenate([[0], geom_object_ids(model)]).astype(np.int32)

    def _context(self, samples: int) -> mujoco.MjrContext:
        """A MuJoCo render context (textures, offscreen framebuffer) with ``samples``."""
        q = self.model.vis.quality
        saved = q.offsamples
        q.offsamples = samples
        try:
            con = mujoco.MjrContext(self.model, mujoco.mjtFontScale.mjFONTSCALE_150)
        finally:
            q.offsamples = saved
        return con

    # -- rendering ------------------------------------------------------------------------

    def _draw(self, con: mujoco.MjrContext | None, depth: np.ndarray | None = None) -> np.ndarray:
        """Render the current scene with ``con``; the RGB buffer, bottom row first (and
        the raw depth buffer into ``depth`` when given)."""
        if con is None or self._gl is None:
            raise RuntimeError("CameraRenderer is closed")
        with gl_lock():
            self._gl.make_current()
            mujoco.mjr_setBuffer(mujoco.mjtFramebuffer.mjFB_OFFSCREEN, con)
            mujoco.mjr_render(self._rect, self._scene, con)
            mujoco.mjr_readPixels(self._rgb, depth, self._rect, con)
        return self._rgb

    def update(self, data: mujoco.MjData) -> None:
        """Take the scene from ``data`` (positions must be current: run mj_forward first)."""
        if self._con is None:
            raise RuntimeError("CameraRenderer is closed")
        mujoco.mjv_updateScene(
            self.model,
            data,
            self._option,
            None,
            self._camera,
            mujoco.mjtCatBit.mjCAT_ALL,
            self._scene,
        )

    def aim_headlight(self, direction: np.ndarray) -> None:
        """Point the headlight of the last :meth:`update`'s scene along ``direction``
        (world axes) for the draws until the next update."""
        scn = self._scene
        for j in range(scn.nlight):
            if scn.lights[j].headlight:
                scn.lights[j].dir[:] = direction

    def render_current(self) -> np.ndarray:
        """RGB uint8 (H, W, 3) of the last :meth:`update` (a new array)."""
        return self._resolved(self._draw(self._con))

    def render_depth_current(self) -> tuple[np.ndarray, np.ndarray]:
        """(RGB as :meth:`render_current`, depth (H, W) float64 in metres along the
        optical axis, each pixel's central sample) of the last :meth:`update`, from one
        colour draw."""
        rgb = self._resolved(self._draw(self._con, self._depth_buf))
        return rgb, self._depth_m()

    def _resolved(self, rgb: np.ndarray) -> np.ndarray:
        """The drawn buffer (bottom row first) as a new top-first (H, W, 3) image, each
        ``supersample²`` block averaged."""
        top = rgb[::-1]
        s = self.params.supersample
        if s == 1:
            return top.copy()
        blocks = top.reshape(self.height, s, self.width, s, 3).astype(np.float32)
        return np.rint(blocks.mean(axis=(1, 3))).astype(np.uint8)

    def _depth_m(self) -> np.ndarray:
        """The depth buffer of the last draw with depth: metres along the optical axis,
        each pixel's central sample."""
        m = self.model
        extent = m.stat.extent
        s = self.params.supersample
        top = self._depth_buf[::-1][s // 2 :: s, s // 2 :: s]
        return linearise_depth(top, m.vis.map.znear * extent, m.vis.map.zfar * extent)

    def segment_current(self, lut: np.ndarray | None = None) -> np.ndarray:
        """Object ids int32 (H, W) of the last :meth:`update`.

        ``lut`` (ngeom,) maps geom ids to the ids returned (default: object ids, see
        :func:`wander_env.mjcf.geom_object_ids`).
        """
        return self._segment(lut, None)

    def segment_depth_current(self, lut: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """(ids int32 (H, W), depth (H, W) float64 in metres along the optical axis) of
        the last :meth:`update`, from one single-sample draw: each pixel's id and depth
        belong to the same surface."""
        ids = self._segment(lut, self._depth_buf)
        return ids, self._depth_m()

    def _segment(self, lut: np.ndarray | None, depth: np.ndarray | None) -> np.ndarray:
        flags = self._scene.flags
        seg, idcolor = mujoco.mjtRndFlag.mjRND_SEGMENT, mujoco.mjtRndFlag.mjRND_IDCOLOR
        flags[seg] = flags[idcolor] = 1
        try:
            rgb = self._draw(self._seg_con, depth)
        finally:
            flags[seg] = flags[idcolor] = 0
        # A pixel's colour is the scene geom's segid + 1 (0: background).
        n = self._scene.ngeom
        top = rgb[::-1]
        ids = top[..., 0].astype(np.int32)
        if n >= 255:  # ids past 255 spill into green and blue
            ids |= (top[..., 1].astype(np.int32) << 8) | (top[..., 2].astype(np.int32) << 16)
        geom_lut = self._lut if lut is None else np.concatenate([[0], lut]).astype(np.int32)
        seg_lut = np.zeros(n + 1, np.int32)
        geom = int(mujoco.mjtObj.mjOBJ_GEOM)
        for g in self._scene.geoms[:n]:
            if g.segid >= 0 and g.objtype == geom:
                seg_lut[g.segid + 1] = geom_lut[g.objid + 1]
        s = self.params.supersample
        return seg_lut[ids[s // 2 :: s, s // 2 :: s]] if s > 1 else seg_lut[ids]

    def render(self, data: mujoco.MjData) -> np.ndarray:
        """RGB uint8 (H, W, 3) from ``data``."""
        self.update(data)
        return self.render_current()

    def segment(self, data: mujoco.MjData) -> np.ndarray:
        """Object-id mask int32 (H, W) from ``data``: 0 background, k object k."""
        self.update(data)
        return self.segment_current()

    def render_with_mask(self, data: mujoco.MjData) -> tuple[np.ndarray, np.ndarray]:
        """(RGB, object-id mask) from one scene update."""
        self.update(data)
        return self.render_current(), self.segment_current()

    # -- lifetime -------------------------------------------------------------------------

    def close(self) -> None:
        """Free the render contexts and the GL context (idempotent). Where the GL context
        cannot be made current (it is current on another thread), :meth:`abandon` s
        them instead."""
        if self._gl is None:
            self._con = self._seg_con = None
            return
        with gl_lock():
            try:
                self._gl.make_current()
            except Exception:  # (EGL_BAD_ACCESS: current on another thread)
                self.abandon()
                return
            for con in self._render_contexts():
                con.free()
            self._con = self._seg_con = None
            self._gl.free()
            self._gl = None

    def abandon(self) -> None:
        """Forget the GL objects without a GL call: in a process forked from the one that
        made them (they are the parent's), or on a thread where the GL context cannot be
        made current. Each render context's GL names are cleared first, so that freeing
        it (MuJoCo's ``mjr_freeContext``, run when it is dropped) deletes nothing in
        whatever GL context is current then: the same names there are another
        renderer's. Its EGL context is destroyed (EGL defers that while the context is
        current on another thread). Closing is then a no-op."""
        with gl_lock():
            for con in self._render_contexts():
                _forget_gl_names(con)
            gl, self._con, self._seg_con, self._gl = self._gl, None, None, None
            if gl is not None:
                gl.free()

    def _render_contexts(self) -> list[mujoco.MjrContext]:
        """The render contexts, each once (the two are one without multisampling)."""
        cons = {id(c): c for c in (self._con, self._seg_con) if c is not None}
        return list(cons.values())

    def __del__(self) -> None:
        if getattr(self, "_gl", None) is None:  # (closed, or failed in __init__)
            return
        with contextlib.suppress(Exception):  # interpreter shutdown: nothing to report to
            warnings.warn(
                f"CameraRenderer ({self.width}x{self.height}) dropped without close(): "
                "its GL objects are left to its GL context's destruction",
                ResourceWarning,
                stacklevel=2,
            )
        # Never a GL call here: the collector runs on any thread, maybe one drawing in a
        # GL context of its own, where freeing would delete that context's objects.
        with contextlib.suppress(Exception):
            self.abandon()


def _forget_gl_names(con: mujoco.MjrContext) -> None:
    """Clear the GL object names ``con`` holds (textures, render and frame buffers,
    display lists) without a GL call: ``mjr_freeContext`` then deletes none of them (it
    deletes by these names in the GL context current when it runs). A skinned model's
    skin buffers are the exception: their names are read-only tuples in Python, so they
    are still deleted by name there."""
    con.ntexture = 0
    for name in (
        "offColor",
        "offColor_r",
        "offDepthStencil",
        "offDepthStencil_r",
        "offFBO",
        "offFBO_r",
        "shadowTex",
        "shadowFBO",
        "rangePlane",
        "rangeMesh",
        "rangeHField",
        "rangeBuiltin",
        "rangeFont",
    ):
        setattr(con, name, 0)
    for names in (con.auxColor, con.auxColor_r, con.auxFBO, con.auxFBO_r):
        names[:] = 0


def project_points(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    points: np.ndarray,
    camera: str | int = CAMERA_NAME,
    width: int = 128,
    height: int = 128,
) -> np.ndarray:
    """World points (N, 3) -> pixel coordinates (N, 2) (x right, y down); NaN behind the camera.

    Pinhole model of a MuJoCo camera (square pixels, ``fovy`` vertical): run
    ``mj_forward`` first so that the camera pose is current.
    """
    cam_id = (
        mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_CAMERA, camera)
        if isinstance(camera, str)
        else int(camera)
    )
    k = intrinsics(width, height, float(model.cam_fovy[cam_id]))
    r_wc = rotation_from_mujoco(data.cam_xmat[cam_id])
    uv, _ = project(k, r_wc, data.cam_xpos[cam_id], points)
    return uv
