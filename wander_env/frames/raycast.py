"""Ground truth and key geometry by ray casting, where the moving objects are primitives.

Where every moving geom (motion layer >= 1, :func:`wander_env.mjcf.geom_layer_ids`) is a
MuJoCo box, sphere, capsule or cylinder, a frame's motion layers, depth and object mask
need no GL pass: each pixel's ray is intersected with the moving geoms (posed by
``data.geom_xpos`` / ``geom_xmat``, sizes ``model.geom_size``) in a compiled kernel
(:func:`cast_layers`), and the static world's occlusion comes from a cube map of its
ray distances rendered once per reset (:func:`wander_env.frames.cube.render_cube`, the
moving layers hidden) from the PTU's rotation centre (the tilt hinge): the camera only
rotates about it.

Pixel rays follow :func:`wander_env.camera.intrinsics` (pixel ``(x, y)``'s centre at
``((x - cx) / f, (y - cy) / f, 1)`` in the camera's OpenCV axes, as MuJoCo's
rasteriser samples a single-sample pixel at its centre), so a ray's parameter ``t``
is the depth along the optical axis; hits nearer than MuJoCo's near clip plane
(``vis.map.znear · stat.extent``) are left out, as GL clips them. The GL render
tessellates spheres, cylinders and capsules (the arena's 20 slices): their silhouettes
lie up to 1.2 % of the radius inside the true ones, so a mask differs from the GL mask
on rim pixels only.

The static world's depth for a camera rotation is the cube's distances sampled along
each pixel's central ray (:func:`wander_env.frames.cube.cube_inverse_depth`, kept for the
latest rotations). A hinge offset (the unit's ``PTUParams.camera_forward_m`` /
``camera_up_m``) puts the camera centre beside the cube's: an object's hit point, found
from the true camera centre, is then looked up in the cube along the ray from the
cube's centre (the point reprojected into a view from the hinge with the camera's
rotation), which is exact but where a static edge's parallax between the two centres
crosses the object (a rim of about ``offset · f / distance`` pixels). The static
world's own depth seen from an offset camera cannot be read from one cube: there
:meth:`PrimitiveCaster.geometry` is not offered (:attr:`PrimitiveCaster.exact_depth` is
False) and keys keep the GL pass; the object mask is offered in either case.

Meshes, ellipsoids, planes (the gratings' sliding screen) and anything else keep the GL
pass: :func:`unsupported_geoms` names them, and a :class:`PrimitiveCaster` is only
built for a model without any.

Examples:
    >>> import mujoco
    >>> from wander_env.mjcf import compile_scene
    >>> from wander_env.scenes import load_scene_config
    >>> model = compile_scene(load_scene_config("office"))
    >>> unsupported_geoms(model)
    []
    >>> unsupported_geoms(compile_scene(load_scene_config("gratings")))
    ['grating_screen (plane)']
"""

from __future__ import annotations

import math
import os
import threading
from dataclasses import dataclass
from typing import TYPE_CHECKING, Annotated

import mujoco
import numba
import numpy as np

from wander_env.camera import CAMERA_NAME, intrinsics, rotation_from_mujoco
from wander_env.config import check_annotated
from wander_env.entities import TILT_JOINT
from wander_env.field_doc import field_doc
from wander_env.gl_process import ForkedGLError, fork_error_message
from wander_env.mjcf import geom_layer_ids

if TYPE_CHECKING:
    from wander_env.renderer import CameraRenderer

__all__ = [
    "CAST_GEOM_TYPES",
    "PrimitiveCaster",
    "RaycastParams",
    "cast_layers",
    "unsupported_geoms",
]

_SPHERE = int(mujoco.mjtGeom.mjGEOM_SPHERE)
_CAPSULE = int(mujoco.mjtGeom.mjGEOM_CAPSULE)
_CYLINDER = int(mujoco.mjtGeom.mjGEOM_CYLINDER)
_BOX = int(mujoco.mjtGeom.mjGEOM_BOX)

#: The MuJoCo geom types :func:`cast_layers` intersects.
CAST_GEOM_TYPES: tuple[int, ...] = (_SPHERE, _CAPSULE, _CYLINDER, _BOX)


@dataclass(frozen=True)
class RaycastParams:
    """What a :class:`PrimitiveCaster` casts and how it samples the static world.

    - ``ground_truth`` True: the object mask by ray casting (the events do not change);
    - ``key_layers`` True: a key's layers and depth too, camera on its hinge only (the
      in-between frames are made from them: a rim pixel's layer or a depth may differ
      from GL's, so events may differ; ``wander perf fidelity`` measured the same
      events and L1 as with GL layers on hand walk, hand saccade and office walk, seed 0);
    - ``cube_samples`` 2: the static cube's faces are ``cube_samples × 2f`` pixels (its
      depth sampled at a quarter of a sensor pixel's width with 2).
    """

    ground_truth: Annotated[bool, field_doc("Object masks by ray casting")] = True
    key_layers: Annotated[bool, field_doc("Keys' layers and depth by ray casting")] = True
    cube_samples: Annotated[
        int, field_doc("Static cube face pixels a sensor pixel, along each axis", ge=1, le=4)
    ] = 2

    def __post_init__(self) -> None:
        check_annotated(self)


def unsupported_geoms(model: mujoco.MjModel) -> list[str]:
    """The moving geoms (motion layer >= 1) :func:`cast_layers` cannot intersect, as
    ``"name (type)"`` (an unnamed geom by its id)."""
    layers = geom_layer_ids(model)
    out = []
    for g in np.flatnonzero(layers):
        gtype = int(model.geom_type[g])
        if gtype not in CAST_GEOM_TYPES:
            name = model.geom(int(g)).name or f"geom {int(g)}"
            out.append(f"{name} ({mujoco.mjtGeom(gtype).name.removeprefix('mjGEOM_').lower()})")
    return out


# ----------------------------------------------------------------------------------------
# Kernels


@numba.njit(cache=True, nogil=True, inline="always")
def _nearer(t, best, tmin):
    """``t`` if it is a hit at or beyond ``tmin`` nearer than ``best``, else ``best``."""
    return t if tmin <= t < best else best


@numba.njit(cache=True, nogil=True)
def _hit(gtype, s0, s1, s2, o0, o1, o2, d0, d1, d2, tmin):
    """The nearest ``t >= tmin`` where the ray ``o + t·d`` (the geom's local frame) meets
    the surface of a geom of MuJoCo type ``gtype`` and size ``(s0, s1, s2)``; inf: none."""
    best = np.inf
    if gtype == _BOX:
        half = (s0, s1, s2)
        o = (o0, o1, o2)
        d = (d0, d1, d2)
        for i in range(3):
            if d[i] == 0.0:
                continue
            j, k = (i + 1) % 3, (i + 2) % 3
            for sign in (-1.0, 1.0):
                t = (sign * half[i] - o[i]) / d[i]
                if tmin <= t < best:
                    pj, pk = o[j] + t * d[j], o[k] + t * d[k]
                    if abs(pj) <= half[j] and abs(pk) <= half[k]:
                        best = t
        return best
    if gtype == _SPHERE:
        a = d0 * d0 + d1 * d1 + d2 * d2
        b = o0 * d0 + o1 * d1 + o2 * d2
        c = o0 * o0 + o1 * o1 + o2 * o2 - s0 * s0
        disc = b * b - a * c
        if disc >= 0.0:
            q = math.sqrt(disc)
            best = _nearer((-b - q) / a, best, tmin)
            best = _nearer((-b + q) / a, best, tmin)
        return best
    # Cylinder or capsule: radius s0, half-length s1 along the local z axis.
    r, h = s0, s1
    a = d0 * d0 + d1 * d1
    if a > 0.0:  # the side
        b = o0 * d0 + o1 * d1
        c = o0 * o0 + o1 * o1 - r * r
        disc = b * b - a * c
        if disc >= 0.0:
            q = math.sqrt(disc)
            for t in ((-b - q) / a, (-b + q) / a):
                if tmin <= t < best and abs(o2 + t * d2) <= h:
                    best = t
    if gtype == _CYLINDER:
        if d2 != 0.0:  # the flat caps
            for sign in (-1.0, 1.0):
                t = (sign * h - o2) / d2
                if tmin <= t < best:
                    px, py = o0 + t * d0, o1 + t * d1
                    if px * px + py * py <= r * r:
                        best = t
        return best
    # Capsule: the hemispheres about (0, 0, ±h), each beyond its end of the side.
    aa = a + d2 * d2
    for sign in (-1.0, 1.0):
        c2 = o2 - sign * h
        b = o0 * d0 + o1 * d1 + c2 * d2
        c = o0 * o0 + o1 * o1 + c2 * c2 - r * r
        disc = b * b - aa * c
        if disc >= 0.0:
            q = math.sqrt(disc)
            for t in ((-b - q) / aa, (-b + q) / aa):
                if tmin <= t < best and sign * (o2 + t * d2 - sign * h) >= 0.0:
                    best = t
    return best


@numba.njit(cache=True, nogil=True)
def cast_layers(
    layers,
    depth,
    rho_static,
    rot,
    centre,
    delta,
    f,
    cx,
    cy,
    znear,
    gtype,
    gsize,
    gpos,
    gmat,
    grb,
    glabel,
):
    """Fill ``layers`` (H, W) int32 and ``depth`` (H, W) float64 (m along the optical
    axis) of a camera view: per pixel the nearest hit of its ray with the geoms (MuJoCo
    ``gtype`` (G,), ``gsize`` (G, 3), world position ``gpos`` (G, 3) and orientation
    ``gmat`` (G, 3, 3), bounding radius ``grb`` (G,)), labelled ``glabel[g]``, where it
    is nearer than the static world; elsewhere label 0 and the static world's depth.

    The camera: world-from-camera rotation ``rot`` (OpenCV axes), centre ``centre``,
    focal length ``f`` px, principal point ``(cx, cy)``; hits nearer than ``znear`` (m
    along the axis) do not count. The static world: ``rho_static`` (H, W), its inverse
    depth seen with the camera's rotation from a centre ``delta`` (camera axes, m)
    behind the camera's (the cube's centre is ``centre - rot @ delta``): a hit point is
    occluded where, reprojected into that view (nearest pixel, clamped to the image),
    it lies at or beyond the static depth there. With ``delta`` non-zero the static
    pixels' depth is the cube centre's, not the camera's (see the module docstring).
    """
    h, w = layers.shape
    for y in range(h):
        for x in range(w):
            layers[y, x] = 0
            depth[y, x] = np.inf
    for g in range(len(gtype)):
        m = gmat[g]
        # The ray's origin and the camera's axes in the geom's local frame.
        e0, e1, e2 = centre[0] - gpos[g, 0], centre[1] - gpos[g, 1], centre[2] - gpos[g, 2]
        o0 = m[0, 0] * e0 + m[1, 0] * e1 + m[2, 0] * e2
        o1 = m[0, 1] * e0 + m[1, 1] * e1 + m[2, 1] * e2
        o2 = m[0, 2] * e0 + m[1, 2] * e1 + m[2, 2] * e2
        loc = np.zeros((3, 3))  # local-from-camera: m.T @ rot
        for i in range(3):
            for j in range(3):
                loc[i, j] = m[0, i] * rot[0, j] + m[1, i] * rot[1, j] + m[2, i] * rot[2, j]
        # The pixels its bounding sphere may cover (the corners of its box in camera axes).
        pc = np.zeros(3)
        for j in range(3):
            pc[j] = -(rot[0, j] * e0 + rot[1, j] * e1 + rot[2, j] * e2)
        r = grb[g]
        x0, x1, y0, y1 = 0, w, 0, h
        if pc[2] - r > znear:
            zs = (pc[2] - r, pc[2] + r)
            ux = min((pc[0] - r) / zs[0], (pc[0] - r) / zs[1])
            uX = max((pc[0] + r) / zs[0], (pc[0] + r) / zs[1])
            vy = min((pc[1] - r) / zs[0], (pc[1] - r) / zs[1])
            vY = max((pc[1] + r) / zs[0], (pc[1] + r) / zs[1])
            x0 = max(math.floor(f * ux + cx), 0)
            x1 = min(math.ceil(f * uX + cx) + 1, w)
            y0 = max(math.floor(f * vy + cy), 0)
            y1 = min(math.ceil(f * vY + cy) + 1, h)
        s0, s1, s2 = gsize[g, 0], gsize[g, 1], gsize[g, 2]
        for y in range(y0, y1):
            v = (y - cy) / f
            for x in range(x0, x1):
                u = (x - cx) / f
                d0 = loc[0, 0] * u + loc[0, 1] * v + loc[0, 2]
                d1 = loc[1, 0] * u + loc[1, 1] * v + loc[1, 2]
                d2 = loc[2, 0] * u + loc[2, 1] * v + loc[2, 2]
                t = _hit(gtype[g], s0, s1, s2, o0, o1, o2, d0, d1, d2, znear)
                if t < depth[y, x]:
                    depth[y, x] = t
                    layers[y, x] = glabel[g]
    for y in range(h):
        v = (y - cy) / f
        for x in range(w):
            if layers[y, x] != 0:
                t = depth[y, x]
                qz = t + delta[2]
                if qz > 0.0:
                    qx = (t * (x - cx) / f + delta[0]) / qz  # the hinge view
                    qy = (t * v + delta[1]) / qz
                    px = min(max(math.floor(f * qx + cx + 0.5), 0), w - 1)
                    py = min(max(math.floor(f * qy + cy + 0.5), 0), h - 1)
                    if qz * rho_static[py, px] >= 1.0:
                        layers[y, x] = 0
            if layers[y, x] == 0:
                depth[y, x] = 1.0 / rho_static[y, x]


# ----------------------------------------------------------------------------------------
# The thin class


class PrimitiveCaster:
    """A model's object mask, motion layers and depth by ray casting (see the module
    docstring); build it only for a model whose moving geoms are all primitives
    (:func:`unsupported_geoms` empty). Create and use it in the process that renders (its
    static cube is a GL render); :meth:`close` frees that renderer.

    Every method reads ``data`` as posed (``mj_kinematics`` and ``mj_camlight`` run).
    :meth:`reset` drops the static cube (the next call renders it again): call it at each
    episode's reset.
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        width: int,
        height: int,
        params: RaycastParams | None = None,
        visible_groups: tuple[int, ...] = (0, 1, 2),
    ) -> None:
        bad = unsupported_geoms(model)
        if bad:
            raise ValueError(f"ray casting cannot draw the moving geoms {', '.join(bad)}")
        self.model, self.width, self.height = model, width, height
        self.params = params or RaycastParams()
        self._cam = int(model.camera(CAMERA_NAME).id)
        self._tilt = int(model.joint(TILT_JOINT).id)
        self.k = intrinsics(width, height, float(model.cam_fovy[self._cam]))
        from wander_env.frames.cube import pixel_rays

        k = self.k
        self._rays = pixel_rays(width, height, float(k[0, 0]), float(k[0, 2]), float(k[1, 2]))
        self.layer_lut = geom_layer_ids(model)
        groups = np.isin(model.geom_group, visible_groups)
        self._geoms = np.flatnonzero((self.layer_lut != 0) & groups)
        self._gtype = np.asarray(model.geom_type[self._geoms], np.int64)
        self._label = np.asarray(self.layer_lut[self._geoms], np.int32)
        self.znear = float(model.vis.map.znear * model.stat.extent)
        self._cube: np.ndarray | None = None  # (6, n, n) static ray distances (m)
        self._cube_centre: np.ndarray | None = None
        self._renderer = None  # the cube's (created where it renders)
        self._renderer_pid: int | None = None
        self._static: dict[bytes, np.ndarray] = {}  # rotation -> static inverse depth
        self._static_lock = threading.Lock()
        data = mujoco.MjData(model)
        mujoco.mj_kinematics(model, data)
        mujoco.mj_camlight(model, data)
        #: Whether the camera's centre is its hinge's, so that the static world's depth
        #: seen from the cube's centre is the camera's own (:meth:`geometry` offered).
        offset = np.linalg.norm(data.cam_xpos[self._cam] - data.xanchor[self._tilt])
        self.exact_depth = bool(offset < 1e-9)

    def reset(self) -> None:
        """Forget the static cube (render it again on next use)."""
        self._cube, self._static = None, {}

    @property
    def cube_ready(self) -> bool:
        """Whether the static cube is rendered: casting then needs no GL, so any thread
        may cast (each with its own posed data)."""
        return self._cube is not None

    def cube_renderer(self) -> CameraRenderer:
        """(Where it renders.) The static cube's renderer, created on first use (a GL
        context of its own: about 0.1 s the first time in a process); a caller may make
        it ahead of the first cast (:meth:`wander_env.frames.Stage.warm_up`)."""
        from wander_env.frames.cube import cube_renderer, face_px

        if self._renderer is not None and self._renderer_pid != os.getpid():
            raise ForkedGLError(fork_error_message(self._renderer_pid, os.getpid()))
        n = face_px(self.k, self.params.cube_samples)
        self._renderer = cube_renderer(self.model, n, self._renderer)
        self._renderer_pid = os.getpid()
        return self._renderer

    def _static_rho(self, data: mujoco.MjData, rot: np.ndarray) -> np.ndarray:
        """The static world's inverse depth (H, W) with the camera's rotation ``rot``
        from the cube's centre (the cube rendered on first use after a reset)."""
        from wander_env.frames.cube import cube_inverse_depth, render_cube

        if self._cube is None:
            renderer = self.cube_renderer()
            saved = data.cam_xpos[self._cam].copy()
            self._cube_centre = data.xanchor[self._tilt].copy()
            data.cam_xpos[self._cam] = self._cube_centre
            try:
                _, _, dist, _ = render_cube(
                    self.model, data, renderer.width, self.layer_lut != 0, "off", renderer
                )
            finally:
                data.cam_xpos[self._cam] = saved
            self._cube, self._static = dist, {}
        key = rot.tobytes()
        with self._static_lock:  # (the main thread casts a key's geometry too)
            rho = self._static.get(key)
        if rho is None:
            rho = np.empty((self.height, self.width), np.float64)
            cube_inverse_depth(rho, self._cube, rot, *self._rays)
            with self._static_lock:
                if len(self._static) >= 8:
                    self._static.pop(next(iter(self._static)))
                self._static[key] = rho
        return rho

    def layers_depth(self, data: mujoco.MjData) -> tuple[np.ndarray, np.ndarray]:
        """(motion layers int32 (H, W), depth (H, W) float64 m along the optical axis) of
        the posed model; the static pixels' depth is the cube centre's (the camera's own
        where :attr:`exact_depth`)."""
        rot = rotation_from_mujoco(data.cam_xmat[self._cam])
        centre = np.asarray(data.cam_xpos[self._cam], np.float64)
        rho = self._static_rho(data, rot)
        delta = rot.T @ (centre - self._cube_centre)
        layers = np.empty((self.height, self.width), np.int32)
        depth = np.empty((self.height, self.width), np.float64)
        g = self._geoms
        k = self.k
        cast_layers(
            layers,
            depth,
            rho,
            rot,
            centre,
            delta,
            float(k[0, 0]),
            float(k[0, 2]),
            float(k[1, 2]),
            self.znear,
            self._gtype,
            np.asarray(self.model.geom_size[g], np.float64),
            np.asarray(data.geom_xpos[g], np.float64),
            np.asarray(data.geom_xmat[g], np.float64).reshape(-1, 3, 3),
            np.asarray(self.model.geom_rbound[g], np.float64),
            self._label,
        )
        return layers, depth

    def geometry(self, data: mujoco.MjData) -> tuple[np.ndarray, np.ndarray]:
        """(motion layers, depth) with :class:`~wander_env.frames.Stage`'s contract;
        only where :attr:`exact_depth` (else ValueError)."""
        if not self.exact_depth:
            raise ValueError(
                "ray-cast depth needs the camera on its hinge (env.ptu.camera_forward_m "
                "and camera_up_m 0): draw this key's geometry with GL"
            )
        return self.layers_depth(data)

    def object_mask(self, data: mujoco.MjData) -> np.ndarray:
        """Object ids (H, W) int32 of the posed model (0 = background)."""
        return self.layers_depth(data)[0]

    def close(self) -> None:
        """Free the cube's renderer (on the thread that drew it)."""
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None

    def abandon(self) -> None:
        """Forget the cube's renderer without freeing it (a forked child: it is the
        parent's)."""
        if self._renderer is not None:
            self._renderer.abandon()
            self._renderer = None
