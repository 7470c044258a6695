"""The event camera's pinhole model: pure functions on NumPy arrays.

Conventions: pixel ``(u, v)`` with ``u`` right, ``v`` down, pixel centres on integers,
principal point at the sensor centre ``((W - 1) / 2, (H - 1) / 2)``, square pixels.
Camera coordinates are OpenCV's (x right, y down, z forward along the optical axis);
MuJoCo's camera frame (x right, y up, z backward) converts with
:func:`rotation_from_mujoco`. A rotation ``R`` is world-from-camera (columns: the
camera's axes in world coordinates) and ``c`` the camera centre in world coordinates.

- :func:`check_hfov_deg`: the one rule of a horizontal field of view, (0, 180) degrees;
- :func:`focal_length_px`, :func:`field_of_view_deg`, :func:`vertical_fov_deg`,
  :func:`pixels_to_degrees`, :func:`degrees_to_pixels`: the focal length from the field of
  view and back, and the angle of a pixel offset;
- :func:`pixel_to_rotation`, :func:`pixel_to_world_angles`, :func:`world_angles_to_pixels`:
  pixels and the pan-tilt unit's angles (PTU signs: positive pan turns left, positive tilt
  looks up), exact for a camera rotating about its optical centre;
- :func:`intrinsics`: the 3 × 3 matrix ``K``;
- :func:`rotation_homography`: ``K R K⁻¹``, the exact image motion of a pure rotation
  about the camera centre (static geometry at any depth);
- :func:`project`: world points to pixels;
- :func:`linearise_depth`: MuJoCo's depth buffer to metres along the optical axis;
- :func:`source_pixels`: where a target pixel's content was in a source view, for a
  rotation plus a translation (parallax, moving objects) given the source's depth;
- :func:`pixel_ray`, :func:`cast_pixel`: a pixel's ray in the world and the first
  surface it meets in a posed MuJoCo scene (the one function here that takes MuJoCo's
  model and data; it imports ``mujoco`` when called).

Examples:
    >>> import numpy as np
    >>> K = intrinsics(128, 128, 90.0)
    >>> round(float(K[0, 0]), 9), float(K[0, 2])
    (64.0, 63.5)
    >>> rz = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1.0]])
    >>> np.allclose(rotation_homography(K, rz), np.eye(3))
    True
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

# Speck DVS: sensor width 5.12 mm behind a 1.7 mm lens -> 2·atan(5.12 / 3.4) ≈ 112.8°.
SPECK_HFOV_DEG = math.degrees(2.0 * math.atan(5.12 / (2.0 * 1.7)))
#: The MJCF name of the event camera (on the pan-tilt unit, wander_env.entities.PanTiltCamera).
CAMERA_NAME = "event_camera"

# MuJoCo camera axes (x right, y up, z back) -> OpenCV's (x right, y down, z forward).
_MJ_TO_CV = np.diag([1.0, -1.0, -1.0])


def check_hfov_deg(hfov_deg: float, name: str = "hfov_deg") -> float:
    """``hfov_deg`` when a pinhole can have it as its horizontal field of view: a number
    (not a bool) in the open interval (0, 180) degrees; ValueError naming ``name`` and the
    value otherwise. The one rule of every ``hfov_deg`` (the scene's camera, the rig, the
    agent, :func:`focal_length_px`).

    >>> check_hfov_deg(90.0)
    90.0
    >>> check_hfov_deg(180, "RigConfig.hfov_deg")
    Traceback (most recent call last):
    ...
    ValueError: RigConfig.hfov_deg: must be in (0, 180) degrees, got 180
    """
    number = isinstance(hfov_deg, (int, float)) and not isinstance(hfov_deg, bool)
    if not (number and 0 < hfov_deg < 180):
        raise ValueError(f"{name}: must be in (0, 180) degrees, got {hfov_deg!r}")
    return hfov_deg


def focal_length_px(width_px: int, hfov_deg: float = SPECK_HFOV_DEG) -> float:
    """Pinhole focal length in pixels, ``(W / 2) / tan(HFOV / 2)``.

    >>> round(focal_length_px(128), 4)  # Speck: 1.7 mm / (5.12 mm / 128 px)
    42.5
    """
    if width_px <= 0:
        raise ValueError(f"width_px must be > 0, got {width_px!r}")
    check_hfov_deg(hfov_deg)
    return (width_px / 2.0) / math.tan(math.radians(hfov_deg) / 2.0)


def field_of_view_deg(size_px: float, focal_px: float) -> float:
    """The field of view (degrees) across ``size_px`` pixels at focal length ``focal_px``,
    ``2·atan((size / 2) / f)``: the inverse of :func:`focal_length_px`.

    >>> round(field_of_view_deg(128, focal_length_px(128, 90.0)), 9)
    90.0
    """
    return 2.0 * math.degrees(math.atan((size_px / 2.0) / focal_px))


def vertical_fov_deg(hfov_deg: float, width: int, height: int) -> float:
    """Vertical FOV (MuJoCo ``fovy``) for a horizontal FOV and image size (square pixels).

    >>> round(vertical_fov_deg(112.83, 128, 128), 2), round(vertical_fov_deg(90.0, 200, 100), 2)
    (112.83, 53.13)
    """
    half = math.radians(hfov_deg) / 2.0
    return math.degrees(2.0 * math.atan(math.tan(half) * height / width))


def pixels_to_degrees(
    dx_px: float | np.ndarray, width_px: int, hfov_deg: float = SPECK_HFOV_DEG
) -> float | np.ndarray:
    """Angle (degrees) of a pixel offset from the principal point, pinhole model.

    Works on scalars and arrays: ``atan(dx / f)`` with ``f`` = :func:`focal_length_px`.

    >>> round(pixels_to_degrees(64, 128), 4)  # the sensor edge: half the HFOV
    56.4134
    """
    f = focal_length_px(width_px, hfov_deg)
    out = np.degrees(np.arctan(np.asarray(dx_px, dtype=np.float64) / f))
    return float(out) if out.ndim == 0 else out


def degrees_to_pixels(
    angle_deg: float | np.ndarray, width_px: int, hfov_deg: float = SPECK_HFOV_DEG
) -> float | np.ndarray:
    """Pixel offset from the principal point of a ray at ``angle_deg``: ``f·tan(angle)``.

    >>> round(degrees_to_pixels(pixels_to_degrees(10.0, 128), 128), 9)
    10.0
    """
    f = focal_length_px(width_px, hfov_deg)
    out = f * np.tan(np.radians(np.asarray(angle_deg, dtype=np.float64)))
    return float(out) if out.ndim == 0 else out


def pixel_to_rotation(
    dx_px: float,
    dy_px: float,
    tilt_deg: float,
    width_px: int = 128,
    hfov_deg: float = SPECK_HFOV_DEG,
) -> tuple[float, float]:
    """The pan-tilt rotation (degrees, PTU signs) that brings the ray through the pixel
    offset ``(dx, dy)`` from the principal point (x right, y down) onto the optical axis,
    for a camera at tilt ``tilt_deg`` (pan does not matter: it is about the vertical).

    Exact for a camera rotating about its optical centre: the ray
    ``f·forward + dx·right − dy·up`` gets pan ``atan2(−dx, f cos φ + dy sin φ)`` and
    elevation ``atan2(f sin φ − dy cos φ, ‖horizontal part‖)``. Converting each axis on
    its own (``atan(dx/f)``, ``atan(dy/f)``) is only right near the centre: for a corner
    pixel of the 113° Speck view it overshoots the tilt by ≈ 14°.

    >>> pan, tilt = pixel_to_rotation(56.0, -43.0, 0.0)  # right and up, camera level
    >>> round(pan, 1), round(tilt, 1)
    (-52.8, 31.5)
    """
    f = focal_length_px(width_px, hfov_deg)
    phi = math.radians(tilt_deg)
    x = f * math.cos(phi) + dy_px * math.sin(phi)
    y = -dx_px
    z = f * math.sin(phi) - dy_px * math.cos(phi)
    pan = math.degrees(math.atan2(y, x))
    tilt = math.degrees(math.atan2(z, math.hypot(x, y)))
    return pan + 0.0, tilt - tilt_deg + 0.0


def pixel_to_world_angles(
    xy: tuple[float, float],
    gaze_deg: tuple[float, float],
    focal_px: float,
    centre: tuple[float, float],
) -> tuple[float, float]:
    """World (pan, tilt) in degrees of pixel ``xy`` seen with the camera at ``gaze_deg``:
    the gaze plus the exact rotation that brings the pixel to the fovea
    (:func:`pixel_to_rotation`; at the tilt of the gaze).

    >>> pan, tilt = pixel_to_world_angles((63.5, 63.5), (10.0, -5.0), 42.5, (63.5, 63.5))
    >>> round(pan, 9), round(tilt, 9)  # the centre pixel: the gaze itself
    (10.0, -5.0)
    >>> pan, tilt = pixel_to_world_angles((127.0, 0.0), (0.0, 0.0), 42.5, (63.5, 63.5))
    >>> round(pan, 2), round(tilt, 2)  # a corner: atan per axis would say (-56.21, 56.21)
    (-56.21, 39.73)
    """
    width = round(2 * centre[0] + 1)  # cx = (W − 1) / 2
    hfov = field_of_view_deg(width, focal_px)
    rot = pixel_to_rotation(
        xy[0] - centre[0], xy[1] - centre[1], gaze_deg[1], width_px=width, hfov_deg=hfov
    )
    return gaze_deg[0] + rot[0], gaze_deg[1] + rot[1]


def world_angles_to_pixels(
    pan_deg: np.ndarray,
    tilt_deg: np.ndarray,
    gaze_deg: tuple[float, float],
    focal_px: float,
    centre: tuple[float, float],
) -> tuple[np.ndarray, np.ndarray]:
    """Pixel (x, y) where the world directions (``pan``, ``tilt``, degrees; arrays of one
    shape) appear to a camera at ``gaze_deg`` — the inverse of :func:`pixel_to_world_angles`;
    NaN behind the camera.

    >>> gaze, centre = (5.0, -10.0), (63.5, 63.5)
    >>> pan, tilt = pixel_to_world_angles((100.0, 10.0), gaze, 42.5, centre)
    >>> x, y = world_angles_to_pixels(np.array(pan), np.array(tilt), gaze, 42.5, centre)
    >>> round(float(x), 9), round(float(y), 9)
    (100.0, 10.0)
    """
    p, t = np.radians(pan_deg), np.radians(tilt_deg)
    gp, gt = math.radians(gaze_deg[0]), math.radians(gaze_deg[1])
    d = np.stack([np.cos(t) * np.cos(p), np.cos(t) * np.sin(p), np.sin(t)])
    fwd = np.array([math.cos(gt) * math.cos(gp), math.cos(gt) * math.sin(gp), math.sin(gt)])
    left = np.array([-math.sin(gp), math.cos(gp), 0.0])
    up = np.array([-math.sin(gt) * math.cos(gp), -math.sin(gt) * math.sin(gp), math.cos(gt)])
    depth = np.tensordot(fwd, d, axes=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        x = centre[0] - focal_px * np.tensordot(left, d, axes=1) / depth
        y = centre[1] - focal_px * np.tensordot(up, d, axes=1) / depth
    behind = depth <= 1e-9
    return np.where(behind, np.nan, x), np.where(behind, np.nan, y)


def principal_point(width: int, height: int) -> tuple[float, float]:
    """The principal point ``((W - 1) / 2, (H - 1) / 2)``: the sensor's centre in pixel
    coordinates (pixel ``i`` centred on ``i``), the fovea.

    >>> principal_point(128, 128), principal_point(4, 3)
    ((63.5, 63.5), (1.5, 1.0))
    """
    return (width - 1) / 2.0, (height - 1) / 2.0


def intrinsics(width: int, height: int, fovy_deg: float) -> np.ndarray:
    """``K`` (3 × 3) of a MuJoCo camera: ``f = (H / 2) / tan(fovy / 2)`` on both axes.

    >>> intrinsics(4, 2, 90.0).round(9).tolist()
    [[1.0, 0.0, 1.5], [0.0, 1.0, 0.5], [0.0, 0.0, 1.0]]
    """
    if width < 1 or height < 1:
        raise ValueError(f"image size must be >= 1 x 1, got {width} x {height}")
    if not 0 < fovy_deg < 180:
        raise ValueError(f"fovy_deg must be in (0, 180), got {fovy_deg!r}")
    f = (height / 2.0) / math.tan(math.radians(fovy_deg) / 2.0)
    cx, cy = principal_point(width, height)
    return np.array([[f, 0.0, cx], [0.0, f, cy], [0.0, 0.0, 1.0]])


def rotation_from_mujoco(cam_xmat: np.ndarray) -> np.ndarray:
    """World-from-camera rotation in OpenCV axes from MuJoCo's ``data.cam_xmat[i]``.

    >>> rotation_from_mujoco(np.eye(3).reshape(9)).tolist()
    [[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]]
    """
    return np.asarray(cam_xmat, dtype=np.float64).reshape(3, 3) @ _MJ_TO_CV


def rotation_homography(k: np.ndarray, r_rel: np.ndarray) -> np.ndarray:
    """``K R K⁻¹``: pixels of a source view -> pixels of a view rotated by ``r_rel``
    (target-from-source camera rotation) about the same centre."""
    return k @ r_rel @ np.linalg.inv(k)


def relative_pose(
    r_src: np.ndarray, c_src: np.ndarray, r_dst: np.ndarray, c_dst: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """``(R, t)`` with ``X_dst = R X_src + t`` for camera coordinates of two views."""
    r = r_dst.T @ r_src
    return r, r_dst.T @ (np.asarray(c_src, float) - np.asarray(c_dst, float))


def project(
    k: np.ndarray, r_wc: np.ndarray, c: np.ndarray, points: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """World points (N, 3) -> (pixels (N, 2), depth along the optical axis (N,)).

    Pixels of points behind the camera (depth <= 0) are NaN.

    >>> k = intrinsics(128, 128, 90.0)
    >>> px, z = project(k, np.eye(3), np.zeros(3), np.array([[1.0, 0.5, 2.0]]))
    >>> px.tolist(), z.tolist()
    ([[95.5, 79.5]], [2.0])
    """
    pc = (np.atleast_2d(np.asarray(points, float)) - np.asarray(c, float)) @ r_wc
    z = pc[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        uv = (pc[:, :2] / z[:, None]) * np.diag(k)[:2] + k[:2, 2]
    uv[z <= 0] = np.nan
    return uv, z


def linearise_depth(buffer: np.ndarray, znear_m: float, zfar_m: float) -> np.ndarray:
    """MuJoCo's depth buffer (default ``mjDEPTH_ZERONEAR``: 0 at the near plane, 1 at
    the far plane, perspective) -> depth along the optical axis in metres.

    The clip planes are ``model.vis.map.znear/zfar · model.stat.extent``.

    >>> d = np.array([0.0, 1.0])
    >>> linearise_depth(d, 0.1, 10.0).round(6).tolist()
    [0.1, 10.0]
    """
    b = np.asarray(buffer, dtype=np.float64)
    return (znear_m * zfar_m) / (znear_m + (zfar_m - znear_m) * (1.0 - b))


def source_pixels(
    a: np.ndarray, b: np.ndarray, inv_depth: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Source pixel and depth ratio of target pixels under rotation + translation.

    A source pixel ``p`` at inverse depth ``ρ`` moves to ``q ~ H p + ρ K t`` (``H`` the
    rotation homography, ``t`` the translation in target camera coordinates). Given
    ``a = H⁻¹ q`` (N, 3) for homogeneous target pixels ``q`` and ``b = H⁻¹ K t`` (3,),
    the source is ``p = λ a - ρ b`` with ``λ = (1 + ρ b_z) / a_z``; ``λ`` is the ratio
    of target to source depth, so the point's inverse depth in the target is ``ρ / λ``.
    Returns ``(p (N, 2), λ (N,))``. With ``b = 0`` this is the homography.

    >>> a = np.array([[10.0, 20.0, 1.0]])
    >>> p, lam = source_pixels(a, np.array([1.0, 0.0, 0.0]), np.array([0.5]))
    >>> p.tolist(), lam.tolist()
    ([[9.5, 20.0]], [1.0])
    """
    rho = np.asarray(inv_depth, dtype=np.float64)
    lam = (1.0 + rho * b[2]) / a[:, 2]
    p = lam[:, None] * a[:, :2] - rho[:, None] * b[None, :2]
    return p, lam


def pixel_ray(
    cam_pos: np.ndarray,
    cam_mat: np.ndarray,
    fovy_deg: float,
    xy: tuple[float, float],
    width: int = 128,
    height: int = 128,
) -> tuple[np.ndarray, np.ndarray]:
    """(origin, unit direction) in the world of pixel ``xy``: the inverse of
    :func:`wander_env.renderer.project_points` (``cam_mat`` columns: right, up, back).

    >>> o, d = pixel_ray(np.zeros(3), np.eye(3), 90.0, (63.5, 63.5))
    >>> d.tolist()
    [0.0, 0.0, -1.0]
    """
    k = intrinsics(width, height, fovy_deg)
    f, (cx, cy) = k[0, 0], (k[0, 2], k[1, 2])
    local = np.array([(xy[0] - cx) / f, -(xy[1] - cy) / f, -1.0])
    d = np.asarray(cam_mat, float).reshape(3, 3) @ local
    return np.asarray(cam_pos, float).copy(), d / np.linalg.norm(d)


def cast_pixel(
    model: Any, data: Any, xy: tuple[float, float], width: int = 128, height: int = 128
) -> tuple[np.ndarray, float, str]:
    """(world point, distance in m, geom name) of the first visible surface under pixel
    ``xy`` of the event camera (the PTU's own geoms, group 3, are not seen); the point is
    NaN and the name empty when the ray hits nothing. ``data`` must be posed."""
    import mujoco

    cam = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_CAMERA, CAMERA_NAME)
    origin, direction = pixel_ray(
        data.cam_xpos[cam], data.cam_xmat[cam], float(model.cam_fovy[cam]), xy, width, height
    )
    geom = np.full(1, -1, np.int32)
    groups = np.array([1, 1, 1, 0, 0, 0], np.uint8)
    dist = mujoco.mj_ray(model, data, origin, direction, groups, 1, -1, geom)
    if geom[0] < 0 or dist < 0:
        return np.full(3, np.nan), math.nan, ""
    return origin + dist * direction, float(dist), str(model.geom(int(geom[0])).name)


__all__ = [
    "SPECK_HFOV_DEG",
    "cast_pixel",
    "check_hfov_deg",
    "degrees_to_pixels",
    "field_of_view_deg",
    "focal_length_px",
    "intrinsics",
    "linearise_depth",
    "pixel_ray",
    "pixel_to_rotation",
    "pixel_to_world_angles",
    "pixels_to_degrees",
    "principal_point",
    "project",
    "relative_pose",
    "rotation_from_mujoco",
    "rotation_homography",
    "source_pixels",
    "vertical_fov_deg",
    "world_angles_to_pixels",
]
