"""In-between camera frames made from two rendered keyframes and the scene's geometry.

A :class:`Keyframe` is a rendered frame (linear luminance) with its depth, its motion
layers (0 = the static world, k = a rigidly moving layer: object k, or a sliding
gratings screen, see :func:`wander_env.mjcf.geom_layer_ids`) and the :class:`View` it
was rendered from (camera rotation and centre, each layer's position). What does not
change while the key is used is computed once, when the key is made: each layer's
presence, pixel box and inverse depth (median and largest).

:class:`KeyPair` makes the frame of a view at a time between two keys, every pixel in
one pass of a compiled kernel (:func:`synthesize` for a single frame):

- per key, each target pixel is looked up per layer by reprojection: the static world
  (layer 0) by the camera's rotation homography ``K R K⁻¹`` (when the camera centre
  moves — a camera offset from the tilt hinge makes parallax — with the key's depth);
  a moving layer only inside its box (its key pixels' box mapped by the rotation and
  padded by its largest displacement), by its rigid motion with the key's depth (a
  fixed-point iteration on the source depth, :func:`wander_env.camera.source_pixels`).
  A candidate counts only if its source pixel belongs to that layer, and per key the
  nearest candidate wins (depth test);
- the two keys' candidates are blended with time weights; a pixel that one key does
  not see (disoccluded, or outside its view) comes from the other alone; one neither
  sees takes the nearer key's nearest edge pixel.

Per frame, Python computes only each key's 3 × 3 homography and each layer's
translation and box, for all layers at once (NumPy); the pixels are the kernel's.

Sampling is nearest-pixel. The renderer's multisampled pixels change as an edge crosses
their samples; bilinear resampling instead leaks a bright neighbour into a dark pixel
in proportion to the shift, which from the two keys rises and falls within the interval
(spurious ON/OFF pairs: a first version with bilinear sampling gave +13 % events in the office
with a still camera, this one -1.8 %, both with 5 ms keys).

:func:`view_flow_bounds_px` bounds how far any pixel's content moves between views from
the poses alone, and :func:`adaptive_key_ticks` places a step's keys where that bound
would pass a number of pixels.

Example:
    >>> import numpy as np
    >>> from wander_env.camera import intrinsics
    >>> k = intrinsics(8, 8, 90.0)
    >>> view = View(np.eye(3), np.zeros(3), np.zeros((1, 3)))
    >>> lum = np.linspace(0.1, 0.9, 64, dtype=np.float32).reshape(8, 8)
    >>> a = make_keyframe(0, lum, view, np.full((8, 8), 2.0), np.zeros((8, 8), np.int32))
    >>> b = make_keyframe(10, lum * 2, view, np.full((8, 8), 2.0), np.zeros((8, 8), np.int32))
    >>> mid = synthesize(a, b, view, 0.25, k)
    >>> bool(np.allclose(mid, lum * 1.25))
    True
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numba
import numpy as np

from wander_env.camera import relative_pose

__all__ = [
    "SUBPIXEL_PX",
    "KeyPair",
    "Keyframe",
    "View",
    "adaptive_key_ticks",
    "make_keyframe",
    "synthesize",
    "view_flow_bounds_px",
]

# A moving layer's pixels are searched in the bounding box of its key pixels, mapped to
# the target view and padded by its largest displacement plus this many pixels.
_PAD_PX = 3
# Below this flow bound (px) from both keys, each pixel's nearest source is itself and
# the frame is the keys' time-weighted blend.
SUBPIXEL_PX = 0.45
# Fixed-point iterations on the source depth (moving layers, parallax).
_ITERATIONS = 3


@dataclass(frozen=True)
class View:
    """A camera pose and the motion layers' positions at one time.

    ``rotation``: world-from-camera (OpenCV axes: x right, y down, z forward);
    ``centre``: the camera centre (m); ``layer_positions`` (L, 3): each layer's
    position (m; row 0, the static world, is zero).
    """

    rotation: np.ndarray
    centre: np.ndarray
    layer_positions: np.ndarray


@dataclass(frozen=True)
class Keyframe:
    """A rendered frame, its view and geometry, and its per-layer statistics (build
    with :func:`make_keyframe`)."""

    t_us: int
    lum: np.ndarray  # (H, W) float32 linear luminance
    view: View
    inv_depth: np.ndarray  # (H, W) float64, 1 / depth on the optical axis (1/m)
    layers: np.ndarray  # (H, W) int32 motion layer of each pixel
    present: np.ndarray  # (L,) bool: the layer has pixels in this key
    boxes: np.ndarray  # (L, 4) int64 (y0, y1, x0, x1) of each layer's pixels
    rho_median: np.ndarray  # (L,) median inverse depth of each layer's pixels
    rho_max: np.ndarray  # (L,) largest inverse depth of each layer's pixels


def make_keyframe(
    t_us: int, lum: np.ndarray, view: View, depth_m: np.ndarray, layers: np.ndarray
) -> Keyframe:
    """A :class:`Keyframe` from a frame's luminance, its depth (m along the optical axis)
    and its layer ids (H, W); the per-layer statistics are computed here, once."""
    lum = np.ascontiguousarray(lum, dtype=np.float32)
    if lum.ndim != 2:
        raise ValueError(f"lum must be 2-D (H, W), got shape {lum.shape}")
    if depth_m.shape != lum.shape or layers.shape != lum.shape:
        raise ValueError(
            f"depth and layers must have the frame's shape {lum.shape}, got "
            f"{depth_m.shape}, {layers.shape}"
        )
    depth = np.asarray(depth_m, dtype=np.float64)
    if not (np.isfinite(depth).all() and depth.min() > 0):
        raise ValueError("depth must be finite and > 0")
    layers = np.ascontiguousarray(layers, dtype=np.int32)
    if layers.min() < 0:
        raise ValueError(f"layer ids must be >= 0, got {int(layers.min())}")
    n = len(view.layer_positions)
    if layers.max() >= n:
        raise ValueError(f"layer id {int(layers.max())} but the view has {n} layers")
    inv = 1.0 / depth
    present = np.bincount(layers.ravel(), minlength=n) > 0
    boxes = np.zeros((n, 4), np.int64)
    rho_median, rho_max = np.zeros(n), np.zeros(n)
    for v in np.flatnonzero(present):  # once per key, a few layers
        inside = layers == v
        r = inv[inside]
        rho_median[v], rho_max[v] = np.median(r), r.max()
        ys, xs = np.flatnonzero(inside.any(axis=1)), np.flatnonzero(inside.any(axis=0))
        boxes[v] = (ys[0], ys[-1] + 1, xs[0], xs[-1] + 1)
    return Keyframe(int(t_us), lum, view, inv, layers, present, boxes, rho_median, rho_max)


def _key_params(
    key: Keyframe, view: View, k: np.ndarray, k_inv: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """For all layers of ``key`` at once, toward ``view``: the target-to-source
    homography (3, 3), each layer's ``b = H⁻¹ K t`` (L, 3) (see
    :func:`~wander_env.camera.source_pixels`), whether it moves relative to the camera
    (L,), and the target box (L, 4) it can reach (layer 0: the whole image)."""
    h, w = key.lum.shape
    r_rel, t_rel = relative_pose(key.view.rotation, key.view.centre, view.rotation, view.centre)
    back = k @ r_rel.T
    hinv = back @ k_inv
    t_l = t_rel[None, :] + (view.layer_positions - key.view.layer_positions) @ view.rotation
    b = t_l @ back.T
    moving = (b != 0).any(axis=1)
    xs, ys = key.boxes[:, [2, 3, 2, 3]], key.boxes[:, [0, 0, 1, 1]]  # (L, 4) corners
    hom = k @ r_rel @ k_inv
    z = hom[2, 0] * xs + hom[2, 1] * ys + hom[2, 2]
    u = (hom[0, 0] * xs + hom[0, 1] * ys + hom[0, 2]) / z
    v = (hom[1, 0] * xs + hom[1, 1] * ys + hom[1, 2]) / z
    # |Δq| <= f·ρ·(|t_xy| + |t_z|·r/f) at image radius r (<= 1.5 f here): bounded by 4 f ρ |t|
    pad = _PAD_PX + 4.0 * k[0, 0] * np.sqrt((t_l * t_l).sum(axis=1)) * key.rho_max
    boxes = np.empty((len(pad), 4))
    boxes[:, 0] = np.floor(v.min(axis=1) - pad)
    boxes[:, 1] = np.ceil(v.max(axis=1) + pad) + 1
    boxes[:, 2] = np.floor(u.min(axis=1) - pad)
    boxes[:, 3] = np.ceil(u.max(axis=1) + pad) + 1
    boxes = np.clip(boxes, 0, [h, h, w, w]).astype(np.int64)
    boxes[0] = (0, h, 0, w)
    return hinv, b, moving, boxes


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _nearest(v: float, n: int) -> int:
    """The pixel index nearest ``v``, clamped to [0, n)."""
    i = math.floor(v + 0.5)
    return min(max(i, 0), n - 1)


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _synth_kernel(
    out, region, weights, near, lum, layers, inv, present, boxes, hinv, bvec, rho0, moving
):
    """Fill ``out`` (H, W) inside ``region`` (y0, y1, x0, x1): per pixel and key (index
    0, 1), the nearest layer candidate (see the module docstring), blended with
    ``weights``. A pixel neither key sees takes key ``near``'s nearest edge pixel, or,
    with ``near`` < 0, keeps its value."""
    h, w = out.shape
    n_layers = present.shape[1]
    for y in range(region[0], region[1]):
        for x in range(region[2], region[3]):
            num = 0.0
            den = 0.0
            for kk in range(2):
                wk = weights[kk]
                if wk <= 0.0:
                    continue
                ax = hinv[kk, 0, 0] * x + hinv[kk, 0, 1] * y + hinv[kk, 0, 2]
                ay = hinv[kk, 1, 0] * x + hinv[kk, 1, 1] * y + hinv[kk, 1, 2]
                az = hinv[kk, 2, 0] * x + hinv[kk, 2, 1] * y + hinv[kk, 2, 2]
                best_v = 0.0
                best_r = -1.0
                for ll in range(n_layers):
                    if not present[kk, ll]:
                        continue
                    if y < boxes[kk, ll, 0] or y >= boxes[kk, ll, 1]:
                        continue
                    if x < boxes[kk, ll, 2] or x >= boxes[kk, ll, 3]:
                        continue
                    b0, b1, b2 = bvec[kk, ll, 0], bvec[kk, ll, 1], bvec[kk, ll, 2]
                    rho = rho0[kk, ll]
                    mov = moving[kk, ll]
                    if mov:
                        for _ in range(_ITERATIONS):
                            lam = (1.0 + rho * b2) / az
                            ix = _nearest(lam * ax - rho * b0, w)
                            iy = _nearest(lam * ay - rho * b1, h)
                            if layers[kk, iy, ix] == ll:
                                rho = inv[kk, iy, ix]
                    lam = (1.0 + rho * b2) / az
                    px = lam * ax - rho * b0
                    py = lam * ay - rho * b1
                    if not (-0.5 < px < w - 0.5 and -0.5 < py < h - 0.5):
                        continue
                    ix = _nearest(px, w)
                    iy = _nearest(py, h)
                    if layers[kk, iy, ix] != ll:
                        continue
                    src = inv[kk, iy, ix]
                    if mov:
                        if abs(src - rho) * math.hypot(b0, b1) >= 0.5:
                            continue  # the depth assumed is not the source's: not converged
                    else:
                        rho = src
                    r_t = rho / lam
                    if r_t > best_r:
                        best_r = r_t
                        best_v = lum[kk, iy, ix]
                if best_r > 0.0:
                    num += wk * best_v
                    den += wk
            if den > 0.0:
                out[y, x] = num / den
            elif near >= 0:  # seen by neither key: the nearer key's nearest edge pixel
                az = hinv[near, 2, 0] * x + hinv[near, 2, 1] * y + hinv[near, 2, 2]
                px = (hinv[near, 0, 0] * x + hinv[near, 0, 1] * y + hinv[near, 0, 2]) / az
                py = (hinv[near, 1, 0] * x + hinv[near, 1, 1] * y + hinv[near, 1, 2]) / az
                out[y, x] = lum[near, _nearest(py, h), _nearest(px, w)]


class KeyPair:
    """Two consecutive keys and the frames between them: their pixels stacked once for
    the kernel; per frame, only the views' homographies and the layers' motion."""

    def __init__(self, a: Keyframe, b: Keyframe, k: np.ndarray) -> None:
        if b.t_us <= a.t_us:
            raise ValueError(f"keys must come in time order: {b.t_us} <= {a.t_us}")
        self.a, self.b = a, b
        self.k = np.asarray(k, dtype=np.float64)
        self._k_inv = np.linalg.inv(self.k)
        self._lum = np.stack([a.lum, b.lum])
        self._layers = np.stack([a.layers, b.layers])
        self._inv = np.stack([a.inv_depth, b.inv_depth])
        self._present = np.stack([a.present, b.present])
        self._rho0 = np.stack([a.rho_median, b.rho_median])
        self._lum1 = [np.dstack([key.lum, np.ones_like(key.lum)]) for key in (a, b)]

    def weight(self, t_us: int) -> float:
        """The time fraction of ``t_us``: 0 at key ``a``, 1 at key ``b``."""
        return (t_us - self.a.t_us) / (self.b.t_us - self.a.t_us)

    def blend(self, w: float) -> np.ndarray:
        """The keys' time-weighted blend (where nothing moves by half a pixel)."""
        return np.float32(1.0 - w) * self.a.lum + np.float32(w) * self.b.lum

    def frame(self, view: View, w: float) -> np.ndarray:
        """The frame (H, W) float32 linear luminance of ``view`` at time fraction ``w``.

        Where the camera only rotates, the static world is one nearest-pixel warp of each
        key (OpenCV) and the kernel runs over the moving layers' boxes alone; where its
        centre moves (parallax), the kernel runs over the whole image."""
        if not 0.0 <= w <= 1.0:
            raise ValueError(f"time fraction w must be in [0, 1], got {w!r}")
        pa = _key_params(self.a, view, self.k, self._k_inv)
        pb = _key_params(self.b, view, self.k, self._k_inv)
        hinv, bvec, moving, boxes = (np.stack([x, y]) for x, y in zip(pa, pb, strict=True))
        weights = np.array([1.0 - w, w])
        h, wd = self.a.lum.shape
        near = int(w > 0.5)
        if moving[:, 0].any():  # the camera centre moved: parallax everywhere
            out = np.empty_like(self.a.lum)
            region = np.array([0, h, 0, wd])
        else:
            out = self._static(hinv, weights, near)
            inside = self._present[:, 1:] & (boxes[:, 1:, 1] > boxes[:, 1:, 0])
            inside &= boxes[:, 1:, 3] > boxes[:, 1:, 2]
            if not inside.any():
                return out
            b = boxes[:, 1:][inside]
            region = np.array([b[:, 0].min(), b[:, 1].max(), b[:, 2].min(), b[:, 3].max()])
            near = -1
        _synth_kernel(
            out, region, weights, near, self._lum, self._layers, self._inv, self._present,
            boxes, hinv, bvec, self._rho0, moving,
        )  # fmt: skip
        return out

    def _static(self, hinv: np.ndarray, weights: np.ndarray, near: int) -> np.ndarray:
        """Both keys warped by their rotation homographies (nearest pixel) and blended
        with ``weights``, each where it sees the pixel; the nearer key's edge elsewhere."""
        h, wd = self.a.lum.shape
        flags = cv2.INTER_NEAREST | cv2.WARP_INVERSE_MAP
        num = np.zeros((h, wd), np.float32)
        den = np.zeros((h, wd), np.float32)
        for i in (0, 1):  # the two keys
            if weights[i] <= 0:
                continue
            if np.abs(hinv[i] - np.eye(3)).max() < 1e-12:
                m = self._lum1[i]
            else:
                m = cv2.warpPerspective(self._lum1[i], hinv[i], (wd, h), flags=flags)
            num += np.float32(weights[i]) * m[..., 0]
            den += np.float32(weights[i]) * m[..., 1]
        seen = den > 1e-6
        out = np.divide(num, den, out=num, where=seen)
        if not seen.all():
            edge = cv2.warpPerspective(
                self._lum[near], hinv[near], (wd, h), flags=flags,
                borderMode=cv2.BORDER_REPLICATE,
            )  # fmt: skip
            out[~seen] = edge[~seen]
        return out


def synthesize(a: Keyframe, b: Keyframe, view: View, w: float, k: np.ndarray) -> np.ndarray:
    """The frame (H, W) float32 linear luminance of ``view`` at the time fraction ``w``
    (0 at key ``a``, 1 at key ``b``) between two keys; ``k`` the camera intrinsics."""
    return KeyPair(a, b, k).frame(view, w)


def view_flow_bounds_px(
    ref: View | Sequence[View],
    views: Sequence[View],
    k: np.ndarray,
    radii: np.ndarray,
    shape: tuple[int, int],
) -> np.ndarray:
    """Upper bounds (n,) in px on how far any pixel's content moves from the view
    ``ref`` (or from each of a sequence of views, one per view) to each of ``views``,
    from the poses alone (no key's geometry: each moving layer is taken as a ball).

    The camera's rotation is measured at the image's corners and edge midpoints; a
    moving layer (a ball of radius ``radii[layer]`` m about its position) adds
    ``f/near·(|t_xy| + |t_z|·r_max/f)`` (``near``: the ball's nearest depth in either
    view); both times 1.25. ``inf`` where the camera
    centre moves or a moving layer may reach the camera (or has no bounded radius).

    >>> from wander_env.camera import intrinsics
    >>> k = intrinsics(128, 128, 90.0)
    >>> still = View(np.eye(3), np.zeros(3), np.array([[0, 0, 0], [0, 0, 2.0]]))
    >>> moved = View(np.eye(3), np.zeros(3), np.array([[0, 0, 0], [0.01, 0, 2.0]]))
    >>> view_flow_bounds_px(still, [still, moved], k, np.array([np.inf, 0.1]), (128, 128))
    array([0.        , 0.42105263])
    """
    n = len(views)
    if n == 0:
        return np.zeros(0)
    h, w = shape
    rot = np.array([v.rotation for v in views])  # (n, 3, 3) world-from-camera
    centres = np.array([v.centre for v in views])
    layers = np.array([v.layer_positions for v in views])  # (n, L, 3)
    if isinstance(ref, View):
        r_rot, r_centre, r_layers = ref.rotation, ref.centre, ref.layer_positions
    else:
        if len(ref) != n:
            raise ValueError(f"{len(ref)} reference views for {n} views")
        r_rot = np.array([v.rotation for v in ref])
        r_centre = np.array([v.centre for v in ref])
        r_layers = np.array([v.layer_positions for v in ref])
    out = np.where((centres != r_centre).any(axis=1), np.inf, 0.0)
    fx, fy, cx, cy = float(k[0, 0]), float(k[1, 1]), float(k[0, 2]), float(k[1, 2])
    if (rot != r_rot).any():
        # Rotation part: target-from-ref rotation R_i^T R_ref applied to the rays of the
        # corners and edge midpoints (the homography K R K^-1).
        xs, ys = np.meshgrid([0.0, (w - 1) / 2, w - 1], [0.0, (h - 1) / 2, h - 1])
        px = np.stack([xs.ravel(), ys.ravel()], axis=1)  # (9, 2)
        rays = np.stack([(px[:, 0] - cx) / fx, (px[:, 1] - cy) / fy, np.ones(9)], axis=1)
        rel = np.swapaxes(rot, 1, 2) @ r_rot  # (n, 3, 3)
        m = rays @ np.swapaxes(rel, 1, 2)  # (n, 9, 3) rays in each target camera
        uv = np.stack([fx * m[..., 0] / m[..., 2] + cx, fy * m[..., 1] / m[..., 2] + cy], -1)
        out += 1.25 * np.abs(uv - px).max(axis=(1, 2))
    shift = layers - r_layers  # (n, L, 3) world
    moved = (shift != 0).any(axis=2)  # (n, L)
    if moved.any():
        r_max = float(np.hypot(w, h)) / 2 + 1.0
        rel_pos = r_layers - np.asarray(r_centre)[..., None, :]  # (L, 3) or (n, L, 3)
        z = np.einsum("...lj,...j->...l", rel_pos, np.asarray(r_rot)[..., :, 2])  # depth
        z_to = np.einsum("nlj,nj->nl", layers - centres[:, None, :], rot[:, :, 2])
        near = np.minimum(z, z_to) - np.asarray(radii, float)[: layers.shape[1]]
        t_l = np.einsum("nji,nlj->nli", rot, shift)  # in each target camera's axes
        move = fx * np.hypot(t_l[..., 0], t_l[..., 1]) + np.abs(t_l[..., 2]) * r_max
        with np.errstate(divide="ignore", invalid="ignore"):
            extra = np.where(moved, np.where(near > 0.01, move / near, np.inf), 0.0)
        out += 1.25 * extra.max(axis=1)
    return out


def adaptive_key_ticks(
    ref: View,
    views: Sequence[View],
    k: np.ndarray,
    radii: np.ndarray,
    shape: tuple[int, int],
    bound_px: float,
) -> list[int] | None:
    """Indices of the ticks of a step (``views``, the last one the step's end) to
    render as keys, after the key ``ref`` at the step's start.

    Between two consecutive keys no pixel's content moves more than ``bound_px``
    (:func:`view_flow_bounds_px`; each key as late as that allows; where one tick alone
    moves more, every tick is a key); the step's end is a key, unless nothing moves at
    all: then there is none (``[]``; the key at the start is the frame all along).
    ``None`` when the motion has no finite bound (a moving camera centre, a layer
    without a bounded radius): the caller keeps a fixed interval.

    >>> from wander_env.camera import intrinsics
    >>> k = intrinsics(128, 128, 90.0)
    >>> v = [View(np.eye(3), np.zeros(3), np.array([[0, 0, 0], [0.002 * i, 0, 2.0]]))
    ...      for i in range(11)]
    >>> radii = np.array([np.inf, 0.1])
    >>> adaptive_key_ticks(v[0], v[1:], k, radii, (128, 128), 0.3)
    [2, 5, 8, 9]
    >>> adaptive_key_ticks(v[0], v[1:], k, radii, (128, 128), 10.0)
    [9]
    >>> adaptive_key_ticks(v[0], [v[0]] * 10, k, radii, (128, 128), 0.3)
    []
    """
    if not bound_px > 0:
        raise ValueError(f"bound_px must be > 0, got {bound_px!r}")
    n = len(views)
    keys: list[int] = []
    start = 0
    while start < n:
        bounds = view_flow_bounds_px(ref, views[start:], k, radii, shape)
        if not np.isfinite(bounds).all():
            return None
        if start == 0 and not bounds.any():
            return []
        over = np.flatnonzero(bounds > bound_px)
        j = n - 1 if not len(over) else start + max(int(over[0]) - 1, 0)
        keys.append(j)
        ref, start = views[j], j + 1
    return keys
