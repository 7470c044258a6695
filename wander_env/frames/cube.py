"""A panorama of the static world from the camera centre: a cube map rendered once,
sampled per tick along the sensor's rays turned by the camera's rotation.

A cube map is six square faces of ``n × n`` pixels, each a 90° pinhole view from the
same centre along one world axis (:data:`FACE_ROTATIONS`, world-from-face rotations in
OpenCV axes: x right, y down, z forward; face ``i`` looks along ``+x, -x, +y, -y, +z, -z``).
A world direction ``d`` falls on the face of its largest ``|d_j|`` and there on the face
pixel ``n/2·(c_x/c_z + 1) - 1/2`` (``c``: ``d`` in the face's axes).

:func:`cube_warp` fills a sensor frame from the faces: per pixel, ``s × s`` sub-pixel rays
turned by the camera's rotation (world-from-camera), one sample each (nearest, or
bilinear), averaged: with faces rendered at ``s`` times the sensor's focal length
(``n = 2·f·s``) that is an area average over the pixel (each face pixel being itself the
renderer's multisampled average). :func:`cube_inverse_depth` gives each sensor pixel's
inverse depth (along the sensor's optical axis) from a cube of ray distances, and
:func:`render_cube` renders a model's static world into both from a MuJoCo camera's
centre (:func:`wander_env.frames.keyframe_maths.layers_over` composites moving layers of
two keys over such a background by depth).

Examples:
    >>> import numpy as np
    >>> faces = np.stack([np.full((4, 4), i, np.float32) for i in range(6)])
    >>> out = np.empty((3, 3), np.float32)
    >>> cube_warp(out, faces, np.eye(3), 1.0, 1.0, 1.0, 1, False)
    >>> int(out[1, 1])  # the centre ray looks along the camera's +z: face 4
    4
"""

from __future__ import annotations

import math

import mujoco
import numba
import numpy as np

from wander_env.camera import CAMERA_NAME
from wander_env.dvs import luminance_tables
from wander_env.renderer import CameraRenderer, RenderParams

__all__ = [
    "FACE_ROTATIONS",
    "box_filter",
    "cube_inverse_depth",
    "cube_renderer",
    "cube_warp",
    "cube_warp_srgb",
    "face_px",
    "pixel_rays",
    "render_cube",
]


def _face_rotations() -> np.ndarray:
    """World-from-face rotations (6, 3, 3): columns x (right), y (down), z (forward)."""
    axes = np.eye(3)
    out = []
    for j in range(3):
        for sign in (1.0, -1.0):
            z = sign * axes[j]
            # A "down" direction not along z: -world z, or +world y for the vertical faces.
            down = np.array([0.0, 0.0, -1.0]) if j != 2 else np.array([0.0, sign, 0.0])
            x = np.cross(down, z)
            x /= np.linalg.norm(x)
            y = np.cross(z, x)
            out.append(np.stack([x, y, z], axis=1))
    return np.array(out)


#: World-from-face rotations (OpenCV axes) of the faces ``+x, -x, +y, -y, +z, -z``.
FACE_ROTATIONS: np.ndarray = _face_rotations()


@numba.njit(cache=True, nogil=True, inline="always")
def _face_pixel(d0, d1, d2, half):
    """(face, x, y) of the world direction ``d`` on a cube of faces ``2·half`` wide:
    ``c``, ``d`` in the face's axes (``FACE_ROTATIONS[face].T @ d``), written out per face
    (each rotation only permutes and negates axes, so this is the same arithmetic)."""
    a0, a1, a2 = abs(d0), abs(d1), abs(d2)
    if a0 >= a1 and a0 >= a2:
        if d0 > 0:
            face, c0, c1, c2 = 0, -d1, -d2, d0
        else:
            face, c0, c1, c2 = 1, d1, -d2, -d0
    elif a1 >= a2:
        if d1 > 0:
            face, c0, c1, c2 = 2, d0, -d2, d1
        else:
            face, c0, c1, c2 = 3, -d0, -d2, -d1
    elif d2 > 0:
        face, c0, c1, c2 = 4, d0, d1, d2
    else:
        face, c0, c1, c2 = 5, d0, -d1, -d2
    return face, half * (c0 / c2 + 1.0) - 0.5, half * (c1 / c2 + 1.0) - 0.5


@numba.njit(cache=True, nogil=True, inline="always")
def _ray_face(x, y, i, j, s, f, cx, cy, rot, half):
    """(face, x, y) on the cube where sub-pixel ray ``(i, j)`` of the ``s × s`` rays of
    sensor pixel ``(x, y)``, turned by ``rot``, lands."""
    v = (y - 0.5 + (j + 0.5) / s - cy) / f
    u = (x - 0.5 + (i + 0.5) / s - cx) / f
    d0 = rot[0, 0] * u + rot[0, 1] * v + rot[0, 2]
    d1 = rot[1, 0] * u + rot[1, 1] * v + rot[1, 2]
    d2 = rot[2, 0] * u + rot[2, 1] * v + rot[2, 2]
    return _face_pixel(d0, d1, d2, half)


@numba.njit(cache=True, nogil=True, inline="always")
def _bilinear_at(fx, fy, n):
    """The top-left face pixel of a bilinear sample at ``(fx, fy)`` and its weights."""
    ix = min(max(math.floor(fx), 0), n - 2)
    iy = min(max(math.floor(fy), 0), n - 2)
    return ix, iy, min(max(fx - ix, 0.0), 1.0), min(max(fy - iy, 0.0), 1.0)


@numba.njit(cache=True, nogil=True, inline="always")
def _nearest_at(fx, fy, n):
    """The face pixel nearest ``(fx, fy)``."""
    return min(max(math.floor(fx + 0.5), 0), n - 1), min(max(math.floor(fy + 0.5), 0), n - 1)


@numba.njit(cache=True, nogil=True)
def cube_warp(out, faces, rot, f, cx, cy, s, bilinear):
    """Fill ``out`` (H, W) from the cube ``faces`` (6, n, n) (the faces of
    :data:`FACE_ROTATIONS`): per sensor pixel the average over its ``s × s`` sub-pixel rays turned
    by ``rot`` (world-from-camera; focal length ``f`` px, centre ``cx, cy``), one
    bilinear or nearest sample a ray."""
    h, w = out.shape
    n = faces.shape[1]
    half = 0.5 * n
    inv = 1.0 / (s * s)
    for y in range(h):
        for x in range(w):
            acc = 0.0
            for j in range(s):
                for i in range(s):
                    face, fx, fy = _ray_face(x, y, i, j, s, f, cx, cy, rot, half)
                    if bilinear:
                        ix, iy, tx, ty = _bilinear_at(fx, fy, n)
                        row0, row1 = faces[face, iy], faces[face, iy + 1]
                        top = (1 - tx) * row0[ix] + tx * row0[ix + 1]
                        bottom = (1 - tx) * row1[ix] + tx * row1[ix + 1]
                        acc += (1 - ty) * top + ty * bottom
                    else:
                        ix, iy = _nearest_at(fx, fy, n)
                        acc += faces[face, iy, ix]
            out[y, x] = acc * inv


@numba.njit(cache=True, nogil=True)
def cube_warp_srgb(out, faces, rot, f, cx, cy, s, bilinear, wlut, offset=0.0):
    """:func:`cube_warp` of sRGB faces (6, n, n, 3) (codes, uint8 or float): per sensor
    pixel each channel's codes averaged over its ``s × s`` rays and rounded (as a
    supersampled render's resolve averages them), then its linear luminance
    ``Σ_c wlut[c, code_c]``. ``offset`` (face pixels) is added to every face position
    (a box-filtered face of even width is centred half a pixel off its index)."""
    h, w = out.shape
    n = faces.shape[1]
    half = 0.5 * n
    inv = 1.0 / (s * s)
    acc = np.zeros(3)
    for y in range(h):
        for x in range(w):
            acc[:] = 0.0
            for j in range(s):
                for i in range(s):
                    face, fx, fy = _ray_face(x, y, i, j, s, f, cx, cy, rot, half)
                    fx += offset
                    fy += offset
                    if bilinear:
                        ix, iy, tx, ty = _bilinear_at(fx, fy, n)
                        for c in range(3):
                            top = (1 - tx) * faces[face, iy, ix, c] + tx * faces[
                                face, iy, ix + 1, c
                            ]
                            bot = (1 - tx) * faces[face, iy + 1, ix, c] + tx * faces[
                                face, iy + 1, ix + 1, c
                            ]
                            acc[c] += (1 - ty) * top + ty * bot
                    else:
                        ix, iy = _nearest_at(fx, fy, n)
                        for c in range(3):
                            acc[c] += faces[face, iy, ix, c]
            lum = 0.0
            for c in range(3):
                code = min(max(math.floor(acc[c] * inv + 0.5), 0), 255)
                lum += wlut[c, code]
            out[y, x] = lum


def pixel_rays(
    width: int, height: int, f: float, cx: float, cy: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each sensor pixel's central ray ``(u, v, 1)`` in camera axes: ``u`` (W,) and
    ``v`` (H,), and its length ``sqrt(u² + v² + 1)`` (H, W), for
    :func:`cube_inverse_depth` (made once per camera: per call, the division and the root
    were a third of that kernel's time).

    >>> u, v, norm = pixel_rays(2, 1, 1.0, 0.5, 0.0)
    >>> u.tolist(), v.tolist(), norm.round(4).tolist()
    ([-0.5, 0.5], [0.0], [[1.118, 1.118]])
    """
    u = (np.arange(width) - cx) / f
    v = (np.arange(height) - cy) / f
    norm = np.sqrt(u[None, :] * u[None, :] + v[:, None] * v[:, None] + 1.0)
    return u, v, norm


@numba.njit(cache=True, nogil=True)
def cube_inverse_depth(out, dist, rot, u, v, norm):
    """Fill ``out`` (H, W) with each sensor pixel's inverse depth (1/m along the
    optical axis) from the cube of ray distances ``dist`` (6, n, n), nearest sample of
    the pixel's central ray (``u``, ``v``, ``norm``: :func:`pixel_rays`) turned by
    ``rot`` (as :func:`cube_warp`)."""
    h, w = out.shape
    n = dist.shape[1]
    half = 0.5 * n
    for y in range(h):
        vy = v[y]
        for x in range(w):
            ux = u[x]
            d0 = rot[0, 0] * ux + rot[0, 1] * vy + rot[0, 2]
            d1 = rot[1, 0] * ux + rot[1, 1] * vy + rot[1, 2]
            d2 = rot[2, 0] * ux + rot[2, 1] * vy + rot[2, 2]
            face, fx, fy = _face_pixel(d0, d1, d2, half)
            ix, iy = _nearest_at(fx, fy, n)
            out[y, x] = norm[y, x] / dist[face, iy, ix]


def box_filter(faces: np.ndarray, k: int) -> tuple[np.ndarray, float]:
    """Each face (6, n, n, C) averaged over ``k × k`` pixel boxes (clamped at the face's
    edge), float32, and the offset (face pixels) that centres a sample on its box:
    one bilinear sample of the result at a sensor pixel's centre is the ``k × k`` rays'
    average that :func:`cube_warp_srgb` would take on the unfiltered faces."""
    import cv2

    out = np.empty(faces.shape, np.float32)
    for i in range(len(faces)):
        out[i] = cv2.blur(faces[i].astype(np.float32), (k, k), borderType=cv2.BORDER_REPLICATE)
    return out, k // 2 - (k - 1) / 2


def _hidden_groups(model: mujoco.MjModel, hide: np.ndarray, group: int):
    """Context: the geoms ``hide`` (bool, ngeom) moved to geom group ``group``."""
    import contextlib

    @contextlib.contextmanager
    def ctx():
        saved = model.geom_group.copy()
        model.geom_group[hide] = group
        try:
            yield
        finally:
            model.geom_group[:] = saved

    return ctx()


def face_px(k: np.ndarray, samples: int) -> int:
    """The face side ``n = 2·f·s`` that gives ``samples`` face pixels a sensor pixel along
    each axis (``f``: the sensor's focal length in pixels, ``k[0, 0]``).

    >>> face_px(np.diag([42.5, 42.5, 1.0]), 4)
    340
    """
    return round(2 * float(k[0, 0]) * samples)


def cube_renderer(
    model: mujoco.MjModel, n: int, renderer: CameraRenderer | None = None
) -> CameraRenderer:
    """The renderer of :func:`render_cube`'s ``n × n`` faces: ``renderer`` where it is
    one of that size, else a new one (a GL context of its own), the model's offscreen
    buffer grown to fit."""
    glob = model.vis.global_
    glob.offwidth, glob.offheight = max(glob.offwidth, n), max(glob.offheight, n)
    if renderer is None or renderer.width != n:
        renderer = CameraRenderer(model, n, n, params=RenderParams(visible_geom_groups=(0, 1, 2)))
    return renderer


def render_cube(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    n: int,
    hide: np.ndarray,
    headlight: str = "camera",
    renderer: CameraRenderer | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, CameraRenderer]:
    """The static world (the geoms ``hide`` left out) as a cube map of ``n × n`` faces
    from the centre of ``data``'s camera ``event_camera`` (the model posed):
    (linear luminance (6, n, n) float32, sRGB (6, n, n, 3) uint8, ray distance
    (6, n, n) float32 m, the face renderer, to pass back as ``renderer`` next time).

    Each face is the model's own colour render (its multisampling) from the camera with
    a 90° field of view, turned to the face. MuJoCo's headlight follows the camera that
    renders: ``headlight="camera"`` holds it along the camera's axis as posed (every face
    lit as the sensor's own view is at that pose), ``"face"`` lets it turn with each face
    (each lit head-on), ``"off"`` switches it off.
    """
    if headlight not in ("camera", "face", "off"):
        raise ValueError(f"headlight must be 'camera', 'face' or 'off', got {headlight!r}")
    cam = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_CAMERA, CAMERA_NAME)
    renderer = cube_renderer(model, n, renderer)
    _, wlut = luminance_tables()
    lum = np.empty((6, n, n), np.float32)
    srgb = np.empty((6, n, n, 3), np.uint8)
    dist = np.empty((6, n, n), np.float32)
    saved_xmat = data.cam_xmat[cam].copy()
    forward = -saved_xmat.reshape(3, 3)[:, 2]  # the camera's axis (MuJoCo: -z) in the world
    saved_fovy = float(model.cam_fovy[cam])
    saved_head = int(model.vis.headlight.active)
    a = (np.arange(n) - (n - 1) / 2) / (n / 2)
    stretch = np.sqrt(1.0 + a[None, :] ** 2 + a[:, None] ** 2)
    try:
        model.cam_fovy[cam] = 90.0
        if headlight == "off":
            model.vis.headlight.active = 0
        with _hidden_groups(model, hide, 5):
            for i, r_face in enumerate(FACE_ROTATIONS):
                # OpenCV axes -> MuJoCo's camera axes (x right, y up, z backward).
                data.cam_xmat[cam] = (r_face @ np.diag([1.0, -1.0, -1.0])).reshape(9)
                renderer.update(data)
                if headlight == "camera":
                    renderer.aim_headlight(forward)
                rgb, z = renderer.render_depth_current()
                srgb[i] = rgb
                lum[i] = wlut[0][rgb[..., 0]] + wlut[1][rgb[..., 1]] + wlut[2][rgb[..., 2]]
                dist[i] = z * stretch
    finally:
        data.cam_xmat[cam] = saved_xmat
        model.cam_fovy[cam] = saved_fovy
        model.vis.headlight.active = saved_head
    return lum, srgb, dist, renderer
