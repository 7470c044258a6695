"""In-between camera frames made from two rendered keyframes and the scene's geometry.

A :class:`Keyframe` is a rendered frame (linear luminance) with its depth, its motion
layers (0 = the static world, k = a rigidly moving layer: object k, or a sliding
gratings screen, see :func:`wander_env.mjcf.geom_layer_ids`) and the :class:`View` it
was rendered from (camera rotation and centre, each layer's position). What does not
change while the key is used is computed once, when the key is made: each layer's
presence, pixel box and inverse depth (median and largest).

:class:`KeyPair` makes the frame of a view at a time between two keys, every pixel in
compiled (numba) kernels (:func:`synthesize` for a single frame):

- per key, each target pixel is looked up per layer by reprojection: the static world
  (layer 0) by the camera's rotation homography ``K R K⁻¹`` (when the camera centre
  moves — a camera offset from the tilt hinge makes parallax — with the key's depth);
  a moving layer only inside its box (the hull of its key pixels' box mapped by the
  rotation alone and by its rigid motion at its nearest and farthest depth: no pixel
  outside it can take a candidate from the layer), by its rigid motion with the key's depth (a
  fixed-point iteration on the source depth, :func:`wander_env.camera.source_pixels`).
  A candidate counts only if its source pixel belongs to that layer, and per key the
  nearest candidate wins (depth test);
- the two keys' candidates are blended with time weights; a pixel that one key does
  not see (disoccluded, or outside its view) comes from the other alone; one neither
  sees takes the nearer key's nearest edge pixel.

Per frame, each key's 3 × 3 homography and each layer's translation and box come from a
small compiled function too; where the camera only rotates, the static world is one
warp of both keys (:func:`_static_kernel`) and the layers' kernel runs over the moving
layers' boxes alone.

Sampling. The static world under a rotation is sampled by cubic convolution at the
source position (:func:`warp_keys`, Keys' kernel with ``a = -0.75``): a sub-pixel
turn of the camera moves the key's content by its fraction of a pixel, as it moves the
world under a render's samples. Nearest-pixel sampling there left each key as it was
below half a pixel, so a frame between keys was their time-weighted blend: each pixel's
path a straight line between the keys' values, and the DVS lost every change between
keys off that line (texture sliding under the pixel while the camera walks, which the
64-sample reference sees; docs/fidelity.md, "Walking cameras"). A bilinear sample blurs
by its fraction, most at half a pixel: a blur that rises and falls between keys (ON/OFF
pairs that are not in the world). A key the camera has not turned from gives its own
pixels. The moving layers keep nearest-pixel sampling: a layer's pixel must come from
that layer (bilinear sampling there gave +13 % events in the office with a still camera,
nearest -1.8 %, both with 5 ms keys).

Where a step's keys fall, from how far its content can move between views, is
:mod:`wander_env.frames.flow_bounds`'. For a background made elsewhere (the panorama,
:mod:`wander_env.frames.cube`): :func:`layers_in_view` tells whether a moving layer may
reach the image, :func:`grow_layers` grows a key's moving layers by a pixel or more, and
:func:`layers_over` composites two keys' moving layers over the background by depth.

Examples:
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
from dataclasses import dataclass
from functools import cached_property
from typing import Any

import numba
import numpy as np

__all__ = [
    "SUBPIXEL_PX",
    "KeyPair",
    "Keyframe",
    "View",
    "blend",
    "grow_layers",
    "layers_in_view",
    "layers_over",
    "make_keyframe",
    "synthesize",
    "turned",
]

# A moving layer's target box is the bound of its mapped key box widened by this many
# pixels: against rounding in the kernels' arithmetic, and so that no pixel outside it
# reads one of the layer's pixels among the 4 × 4 of its cubic sample (reaching 2 px).
_MARGIN_PX = 2
# Below this flow bound (px) from both keys, and where the camera has not turned since
# either (:func:`turned`), each pixel's source is itself and the frame is the keys'
# time-weighted blend. (Where it has turned, the static world's cubic sample moves the
# content by any fraction of a pixel.)
SUBPIXEL_PX = 0.45
# Fixed-point iterations on the source depth (moving layers, parallax), at most; they
# stop at a fixed point (the source depth unchanged), where the rest would change nothing.
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
    rho_median: np.ndarray  # (L,) moving layers' median inverse depth; [0] is 0: see below
    rho_max: np.ndarray  # (L,) largest inverse depth of each layer's pixels
    static_taps: np.ndarray  # (H + 1, W + 1) bool, see :func:`_static_tap_map`

    @cached_property
    def static_rho_median(self) -> float:
        """The median inverse depth of the static world's pixels (layer 0), taken when
        first asked for: only a moving camera centre needs it (the fixed-point start of
        the static layer's candidates, :meth:`KeyPair.kernel_args`), and over most of a
        key's pixels it cost 0.15 of the 0.2 ms of a key's statistics."""
        return float(_layer_median(self.layers, self.inv_depth, 0))


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
    present = np.zeros(n, np.bool_)
    boxes = np.zeros((n, 4), np.int64)
    rho_median, rho_max = np.zeros(n), np.zeros(n)
    _layer_stats(layers, inv, present, boxes, rho_median, rho_max)
    taps = _static_tap_map(layers)
    return Keyframe(int(t_us), lum, view, inv, layers, present, boxes, rho_median, rho_max, taps)


@numba.njit(cache=True, nogil=True)
def _static_tap_map(layers):
    """(H + 1, W + 1) bool: at [y0 + 1, x0 + 1] (x0 in [-1, W), y0 in [-1, H)), whether
    the 4 × 4 pixels a cubic sample whose position's floor is (x0, y0) reads (columns
    x0 - 1 .. x0 + 2, rows y0 - 1 .. y0 + 2, clamped to the image) are all the static
    world's (layer 0). Two passes of a 4-wide window's count of other layers."""
    h, w = layers.shape
    rows = np.empty((h, w + 1), np.int32)  # per row and x0: the window's pixels off layer 0
    for yy in range(h):
        for i in range(w + 1):
            n = 0
            for d in range(-2, 2):  # x0 - 1 .. x0 + 2 with x0 = i - 1
                n += layers[yy, min(max(i + d, 0), w - 1)] != 0
            rows[yy, i] = n
    out = np.empty((h + 1, w + 1), np.bool_)
    for j in range(h + 1):
        for i in range(w + 1):
            n = 0
            for d in range(-2, 2):
                n += rows[min(max(j + d, 0), h - 1), i]
            out[j, i] = n == 0
    return out


@numba.njit(cache=True, nogil=True)
def _layer_stats(layers, inv, present, boxes, rho_median, rho_max):
    """Per layer of a key (ids ``< len(present)``): whether it has pixels, their box
    (y0, y1, x0, x1), their largest inverse depth and, for the moving layers (ids >= 1),
    their median inverse depth (as ``np.median`` takes it: the mean of the two middle
    values of an even count; 0 for layer 0: :attr:`Keyframe.static_rho_median`)."""
    h, w = layers.shape
    n = len(present)
    counts = np.zeros(n, np.int64)
    boxes[:, 0], boxes[:, 1], boxes[:, 2], boxes[:, 3] = h, 0, w, 0
    for y in range(h):
        for x in range(w):
            v = layers[y, x]
            r = inv[y, x]
            if counts[v] == 0 or r > rho_max[v]:
                rho_max[v] = r
            counts[v] += 1
            boxes[v, 0] = min(boxes[v, 0], y)
            boxes[v, 1] = max(boxes[v, 1], y + 1)
            boxes[v, 2] = min(boxes[v, 2], x)
            boxes[v, 3] = max(boxes[v, 3], x + 1)
    start = np.zeros(n + 1, np.int64)
    for v in range(n):
        start[v + 1] = start[v] + counts[v]
    values = np.empty(h * w)
    fill = start[:n].copy()
    for y in range(h):
        for x in range(w):
            v = layers[y, x]
            if v != 0:
                values[fill[v]] = inv[y, x]
                fill[v] += 1
    for v in range(n):
        present[v] = counts[v] > 0
        if not present[v]:
            boxes[v] = 0
        elif v != 0:
            rho_median[v] = np.median(values[start[v] : start[v + 1]])


@numba.njit(cache=True, nogil=True)
def _layer_median(layers, inv, layer):
    """The median inverse depth ``inv`` of the pixels of ``layer`` (as
    :func:`_layer_stats` takes a moving layer's; 0 where it has none)."""
    values = np.empty(layers.size)
    n = 0
    for y in range(layers.shape[0]):
        for x in range(layers.shape[1]):
            if layers[y, x] == layer:
                values[n] = inv[y, x]
                n += 1
    return np.median(values[:n]) if n else 0.0


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _key_params(
    k,
    k_inv,
    key_rot,
    key_centre,
    key_layers,
    key_boxes,
    rho_max,
    rot,
    centre,
    layers,
    h,
    w,
    hinv,
    bvec,
    moving,
    boxes,
):
    """For all layers of a key (rotation, centre, layer positions, boxes, largest inverse
    depths) toward a view (rotation, centre, layer positions): fill the
    target-to-source homography ``hinv`` (3, 3), each layer's ``b = H⁻¹ K t`` (L, 3) (see
    :func:`~wander_env.camera.source_pixels`), whether it moves relative to the camera
    (L,) and the target box (L, 4) it can reach (layer 0: the whole image).

    A layer's box: a source pixel ``p`` at inverse depth ``ρ`` lands at
    ``K R K⁻¹ p̃ + ρ K t`` (homogeneous), a projective map of (x, y, ρ); the kernels take
    a layer's candidate only from a source inside its key box (± half a pixel) at an
    inverse depth in [0, its largest], so the target lies in the hull of that box's 8
    corners mapped (a convex set's image, all corners in front of the camera; else the
    whole image), widened by :data:`_MARGIN_PX`. At ρ = 0 the corners are those of the
    rotation alone: where the static world's candidates change (the layer covers them
    in the key)."""
    r_rel = rot.T @ key_rot  # target-from-key camera rotation
    t_rel = rot.T @ (key_centre - centre)
    back = k @ r_rel.T
    hinv[:] = back @ k_inv
    hom = k @ r_rel @ k_inv
    for ll in range(len(key_layers)):
        t_l = t_rel + rot.T @ (layers[ll] - key_layers[ll])
        bvec[ll] = back @ t_l
        moving[ll] = bvec[ll, 0] != 0 or bvec[ll, 1] != 0 or bvec[ll, 2] != 0
        kt = k @ t_l
        u0, u1, v0, v1 = np.inf, -np.inf, np.inf, -np.inf
        whole = False
        for x in (key_boxes[ll, 2] - 0.5, key_boxes[ll, 3] - 0.5):
            for y in (key_boxes[ll, 0] - 0.5, key_boxes[ll, 1] - 0.5):
                hx = hom[0, 0] * x + hom[0, 1] * y + hom[0, 2]
                hy = hom[1, 0] * x + hom[1, 1] * y + hom[1, 2]
                hz = hom[2, 0] * x + hom[2, 1] * y + hom[2, 2]
                for rho in (0.0, rho_max[ll]):
                    z = hz + rho * kt[2]
                    if not z > 0.0:
                        whole = True
                        continue
                    u = (hx + rho * kt[0]) / z
                    v = (hy + rho * kt[1]) / z
                    u0, u1, v0, v1 = min(u0, u), max(u1, u), min(v0, v), max(v1, v)
        if whole or not (np.isfinite(u0) and np.isfinite(u1)):
            u0, u1, v0, v1 = 0.0, w, 0.0, h
        boxes[ll, 0] = min(max(math.floor(v0) - _MARGIN_PX, 0), h)
        boxes[ll, 1] = min(max(math.floor(v1) + 1 + _MARGIN_PX, 0), h)
        boxes[ll, 2] = min(max(math.floor(u0) - _MARGIN_PX, 0), w)
        boxes[ll, 3] = min(max(math.floor(u1) + 1 + _MARGIN_PX, 0), w)
    boxes[0, 0], boxes[0, 1], boxes[0, 2], boxes[0, 3] = 0, h, 0, w


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _nearest(v: float, n: int) -> int:
    """The pixel index nearest ``v``, clamped to [0, n)."""
    i = math.floor(v + 0.5)
    return min(max(i, 0), n - 1)


@numba.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _source_pixel(hinv, kk, x, y):
    """Where key ``kk``'s homography ``hinv[kk]`` (target to source) maps pixel (x, y)."""
    az = hinv[kk, 2, 0] * x + hinv[kk, 2, 1] * y + hinv[kk, 2, 2]
    px = (hinv[kk, 0, 0] * x + hinv[kk, 0, 1] * y + hinv[kk, 0, 2]) / az
    py = (hinv[kk, 1, 0] * x + hinv[kk, 1, 1] * y + hinv[kk, 1, 2]) / az
    return px, py


@numba.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _key_images(keys, kk):
    """Key ``kk``'s images of ``keys`` (:meth:`KeyPair.kernel_args`): its luminance,
    warped static world, tap map, layers and inverse depth. A kernel takes both keys'
    once, before its pixel loops, and calls :func:`_candidate` with one or the other in
    two branches: picking them per pixel (by index, or by a run-time choice between the
    two) made the layers' kernel 3× slower."""
    return keys[0][kk], keys[1][kk], keys[2][kk], keys[3][kk], keys[4][kk]


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _candidate(kk, x, y, first, keys, images):
    """Key ``kk``'s nearest candidate for target pixel (x, y) among its layers from
    ``first`` on (see the module docstring): (its luminance, its inverse depth in the
    target view); inverse depth -1 where no layer has one. ``keys``: the two keys'
    arrays with a view's parameters (:meth:`KeyPair.kernel_args`); ``images``: key
    ``kk``'s own (:func:`_key_images`). Its ``warped``, the key's cubic sample at every
    target pixel's source position (:func:`warp_keys`), is the static world's candidate
    where all the sample's taps are the static world's (``taps``, the key's
    :func:`_static_tap_map`; else its nearest pixel)."""
    present, boxes, hinv, bvec, rho0, moving = keys[5:]
    lum, warped, taps, layers, inv = images
    h, w = layers.shape
    n_layers = present.shape[1]
    ax = hinv[kk, 0, 0] * x + hinv[kk, 0, 1] * y + hinv[kk, 0, 2]
    ay = hinv[kk, 1, 0] * x + hinv[kk, 1, 1] * y + hinv[kk, 1, 2]
    az = hinv[kk, 2, 0] * x + hinv[kk, 2, 1] * y + hinv[kk, 2, 2]
    best_v = 0.0
    best_r = -1.0
    for ll in range(first, n_layers):
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
                if layers[iy, ix] != ll or inv[iy, ix] == rho:
                    break  # a fixed point: the iterations left change nothing
                rho = inv[iy, ix]
        lam = (1.0 + rho * b2) / az
        px = lam * ax - rho * b0
        py = lam * ay - rho * b1
        if not (-0.5 < px < w - 0.5 and -0.5 < py < h - 0.5):
            continue
        ix = _nearest(px, w)
        iy = _nearest(py, h)
        if layers[iy, ix] != ll:
            continue
        src = inv[iy, ix]
        if mov:
            if abs(src - rho) * math.hypot(b0, b1) >= 0.5:
                continue  # the depth assumed is not the source's: not converged
        else:
            rho = src
        r_t = rho / lam
        if r_t > best_r:
            best_r = r_t
            best_v = lum[iy, ix]
            if ll == 0 and not mov:  # as the static world's kernel, where it reads no layer
                tx = min(max(math.floor(px) + 1, 0), w)
                ty = min(max(math.floor(py) + 1, 0), h)
                if taps[ty, tx]:
                    best_v = max(warped[y, x], 0.0)
    return best_v, best_r


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _synth_kernel(out, regions, weights, near, keys):
    """Fill ``out`` (H, W) inside each of ``regions`` (R, 4) (y0, y1, x0, x1; a pixel in
    two is computed twice, to the same value): per pixel and key (index 0, 1), the
    nearest layer candidate of ``keys`` (:func:`_candidate`), blended with ``weights``. A
    pixel neither key sees takes key ``near``'s nearest edge pixel, or, with ``near`` < 0,
    keeps its value."""
    h, w = out.shape
    lum, hinv = keys[0], keys[7]
    key0, key1 = _key_images(keys, 0), _key_images(keys, 1)
    for r in range(len(regions)):
        for y in range(regions[r, 0], regions[r, 1]):
            for x in range(regions[r, 2], regions[r, 3]):
                num = 0.0
                den = 0.0
                for kk in range(2):
                    wk = weights[kk]
                    if wk <= 0.0:
                        continue
                    if kk == 0:
                        best_v, best_r = _candidate(0, x, y, 0, keys, key0)
                    else:
                        best_v, best_r = _candidate(1, x, y, 0, keys, key1)
                    if best_r > 0.0:
                        num += wk * best_v
                        den += wk
                if den > 0.0:
                    out[y, x] = num / den
                elif near >= 0:  # seen by neither key: the nearer key's nearest edge pixel
                    px, py = _source_pixel(hinv, near, x, y)
                    out[y, x] = lum[near][_nearest(py, h), _nearest(px, w)]


def warp_keys(
    lum: tuple[np.ndarray, np.ndarray], hinv: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Each key's luminance (``lum``: the two keys' (H, W) float32) at every target
    pixel's source position under its target-to-source homography ``hinv[k]``: cubic
    convolution over the 4 × 4 pixels around it (Keys 1981 with ``a = -0.75``, as
    OpenCV's and Pillow's bicubic: it keeps more of a key's contrast at a sub-pixel shift
    than Catmull-Rom's -0.5), the border's pixels repeated beyond the image (OpenCV's
    ``INTER_CUBIC``, which rounds the position to 1/32 px: a pixel centre gives that
    pixel). May dip below 0 beside an edge: the kernels clamp it."""
    import cv2  # (here: OpenCV's import starts thread pools a key's maths does not need)

    h, w = lum[0].shape
    flags, border = cv2.INTER_CUBIC | cv2.WARP_INVERSE_MAP, cv2.BORDER_REPLICATE
    out = (np.empty_like(lum[0]), np.empty_like(lum[1]))
    for k in range(2):
        cv2.warpPerspective(lum[k], hinv[k], (w, h), out[k], flags=flags, borderMode=border)
    return out


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _static_kernel(out, weights, near, lum, warped, hinv):
    """Fill ``out`` (H, W) with both keys (index 0, 1) warped by their target-to-source
    homographies ``hinv`` (``warped``, :func:`warp_keys`, no less than 0; a key whose
    homography is the identity to 1e-12, a camera that has not turned since it, gives
    its own pixels) and blended with ``weights``, each where it sees the pixel; a pixel
    neither sees takes key ``near``'s nearest edge pixel."""
    h, w = out.shape
    same = np.zeros(2, np.bool_)
    for kk in range(2):
        same[kk] = True
        for i in range(3):
            for j in range(3):
                if abs(hinv[kk, i, j] - (1.0 if i == j else 0.0)) > 1e-12:
                    same[kk] = False
    for y in range(h):
        for x in range(w):
            num = den = 0.0
            for kk in range(2):
                if weights[kk] <= 0.0:  # a key at weight 0 adds nothing
                    continue
                if same[kk]:
                    num += weights[kk] * lum[kk][y, x]
                    den += weights[kk]
                    continue
                px, py = _source_pixel(hinv, kk, x, y)
                if -0.5 <= px < w - 0.5 and -0.5 <= py < h - 0.5:
                    num += weights[kk] * max(warped[kk][y, x], 0.0)
                    den += weights[kk]
            if den > 0.0:
                out[y, x] = num / den
            else:
                px, py = _source_pixel(hinv, near, x, y)
                out[y, x] = lum[near][_nearest(py, h), _nearest(px, w)]


@numba.njit(cache=True, nogil=True)
def _regions(present, boxes):
    """See :meth:`KeyPair.regions` (``present`` (2, L), ``boxes`` (2, L, 4))."""
    out = np.empty((2 * present.shape[1], 4), np.int64)
    n = 0
    for ll in range(1, present.shape[1]):
        y0, y1, x0, x1 = 1 << 30, -1, 1 << 30, -1
        area = keys = 0
        for kk in range(2):
            if present[kk, ll]:
                b = boxes[kk, ll]
                y0, y1, x0, x1 = min(y0, b[0]), max(y1, b[1]), min(x0, b[2]), max(x1, b[3])
                area += max(b[1] - b[0], 0) * max(b[3] - b[2], 0)
                keys += 1
        if keys == 0:
            continue
        if keys == 2 and area < (y1 - y0) * (x1 - x0):
            out[n] = boxes[0, ll]
            out[n + 1] = boxes[1, ll]
            n += 2
        else:
            out[n, 0], out[n, 1], out[n, 2], out[n, 3] = y0, y1, x0, x1
            n += 1
    out = out[:n]
    return out[(out[:, 1] > out[:, 0]) & (out[:, 3] > out[:, 2])]


class KeyPair:
    """Two consecutive keys and the frames between them: their arrays gathered once for
    the kernels; per frame, only the views' homographies and the layers' motion."""

    def __init__(
        self, a: Keyframe, b: Keyframe, k: np.ndarray, k_inv: np.ndarray | None = None
    ) -> None:
        """``k``: the camera intrinsics; ``k_inv``: their inverse where the caller keeps
        it (``np.linalg.inv(k)``; else computed here)."""
        if b.t_us <= a.t_us:
            raise ValueError(f"keys must come in time order: {b.t_us} <= {a.t_us}")
        self.a, self.b = a, b
        self.k = np.asarray(k, dtype=np.float64)
        self._k_inv = np.linalg.inv(self.k) if k_inv is None else k_inv

    @cached_property
    def _arrays(self) -> tuple[Any, ...]:
        """Both keys' luminance, layers, inverse depth, layer presence, median inverse
        depth and static tap maps for the kernel: the images as pairs of the keys' own
        arrays (a key's pixels are not copied), the per-layer values stacked (made when a
        frame first needs them)."""
        a, b = self.a, self.b
        return (
            (a.lum, b.lum),
            (a.layers, b.layers),
            (a.inv_depth, b.inv_depth),
            np.stack([a.present, b.present]),
            np.stack([a.rho_median, b.rho_median]),
            (a.static_taps, b.static_taps),
        )

    def weight(self, t_us: int) -> float:
        """The time fraction of ``t_us``: 0 at key ``a``, 1 at key ``b``."""
        return (t_us - self.a.t_us) / (self.b.t_us - self.a.t_us)

    def blend(self, w: float) -> np.ndarray:
        """The keys' time-weighted blend (where nothing moves by half a pixel)."""
        return blend(self.a.lum, self.b.lum, w)

    def params(self, view: View) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Per key (index 0, 1) toward ``view``: the target-to-source homography (2, 3, 3),
        each layer's ``b`` (2, L, 3), whether it moves (2, L) and its target box (2, L, 4)
        (see :func:`_key_params`)."""
        n = len(view.layer_positions)
        hinv, bvec = np.empty((2, 3, 3)), np.empty((2, n, 3))
        moving, boxes = np.empty((2, n), np.bool_), np.empty((2, n, 4), np.int64)
        h, wd = self.a.lum.shape
        for i, key in enumerate((self.a, self.b)):
            kv = key.view
            _key_params(
                self.k,
                self._k_inv,
                kv.rotation,
                kv.centre,
                kv.layer_positions,
                key.boxes,
                key.rho_max,
                view.rotation,
                view.centre,
                view.layer_positions,
                h,
                wd,
                hinv[i],
                bvec[i],
                moving[i],
                boxes[i],
            )
        return hinv, bvec, moving, boxes

    def regions(self, boxes: np.ndarray) -> np.ndarray:
        """The moving layers' target regions (R, 4): per layer, the union of its boxes
        (``boxes`` from :meth:`params`) from the keys that have it, or both boxes where
        they cover fewer pixels than their union; empty ones left out."""
        return _regions(self._arrays[3], boxes)

    def frame(self, view: View, w: float) -> np.ndarray:
        """The frame (H, W) float32 linear luminance of ``view`` at time fraction ``w``.

        Where the camera only rotates, the static world is one warp of both keys
        (:func:`_static_kernel`, cubic samples) and the layers' kernel runs over the moving layers'
        boxes alone; where its centre moves (parallax), over the whole image."""
        if not 0.0 <= w <= 1.0:
            raise ValueError(f"time fraction w must be in [0, 1], got {w!r}")
        hinv, bvec, moving, boxes = self.params(view)
        h, wd = self.a.lum.shape
        weights = np.array([1.0 - w, w])
        near = int(w > 0.5)
        out = np.empty_like(self.a.lum)
        lum = self._arrays[0]
        warped = None  # the keys' cubic warp, made where the static world is one
        if moving[:, 0].any():  # the camera centre moved: parallax everywhere
            regions = np.array([[0, h, 0, wd]])
        else:
            warped = warp_keys(lum, hinv)
            _static_kernel(out, weights, near, lum, warped, hinv)
            regions = self.regions(boxes)
            if not len(regions):
                return out
            near = -1
        _synth_kernel(
            out, regions, weights, near, self.kernel_args(hinv, bvec, moving, boxes, warped)
        )
        return out

    def kernel_args(
        self,
        hinv: np.ndarray,
        bvec: np.ndarray,
        moving: np.ndarray,
        boxes: np.ndarray,
        warped: tuple[np.ndarray, np.ndarray] | None = None,
    ) -> tuple[Any, ...]:
        """The layers' kernels' ``keys``: the two keys' arrays with a view's
        :meth:`params` and the keys' ``warped`` static world (:func:`warp_keys`; None for
        a kernel that reads only the moving layers), one tuple (``lum, warped, taps,
        layers, inv, present, boxes, hinv, bvec, rho0, moving``). Where the static
        world moves relative to a key (its centre moved), ``rho0`` holds that key's
        :attr:`Keyframe.static_rho_median` (elsewhere the value changes nothing: the
        static layer's ``b`` is 0)."""
        lum, layers, inv, present, rho0, taps = self._arrays
        if moving[:, 0].any():
            rho0 = rho0.copy()
            for i, key in enumerate((self.a, self.b)):
                if moving[i, 0]:
                    rho0[i, 0] = key.static_rho_median
        warped = lum if warped is None else warped
        return lum, warped, taps, layers, inv, present, boxes, hinv, bvec, rho0, moving


@numba.njit(cache=True, nogil=True, error_model="numpy")
def layers_over(out, bg, bg_rho, regions, weights, keys):
    """Composite two keys' moving layers (ids >= 1) over the background ``bg`` (H, W)
    with inverse depth ``bg_rho`` into ``out`` inside ``regions`` (R, 4): per key, its
    nearest moving-layer candidate of ``keys`` (the synthesis's own lookup) where it is
    not behind the background, else the background, blended with ``weights``; a pixel no
    key's layer reaches keeps ``bg``. Idempotent per pixel (regions may overlap)."""
    key0, key1 = _key_images(keys, 0), _key_images(keys, 1)
    for r in range(len(regions)):
        for y in range(regions[r, 0], regions[r, 1]):
            for x in range(regions[r, 2], regions[r, 3]):
                num = 0.0
                hit = False
                floor = bg_rho[y, x] * 0.999
                for kk in range(2):
                    wk = weights[kk]
                    if wk <= 0.0:
                        continue
                    if kk == 0:
                        v, rt = _candidate(0, x, y, 1, keys, key0)
                    else:
                        v, rt = _candidate(1, x, y, 1, keys, key1)
                    if rt > 0.0 and rt >= floor:
                        num += wk * v
                        hit = True
                    else:
                        num += wk * bg[y, x]
                if hit:
                    out[y, x] = num
                else:
                    out[y, x] = bg[y, x]


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


def grow_layers(
    layers: np.ndarray, inv_depth: np.ndarray, px: int
) -> tuple[np.ndarray, np.ndarray]:
    """(layers, inverse depth) with each moving layer grown by ``px`` pixels into the
    static world's (layer 0): each such pixel takes its nearest neighbour's layer and
    inverse depth (the nearer where two meet); new arrays."""
    layers, inv = layers.copy(), inv_depth.copy()
    for _ in range(px):
        grown_l, grown_i = layers.copy(), inv.copy()
        for dy, dx in ((-1, 0), (1, 0), (0, -1), (0, 1), (-1, -1), (-1, 1), (1, -1), (1, 1)):
            nl, ni = _shifted(layers, dy, dx, 0), _shifted(inv, dy, dx, 0.0)
            take = (layers == 0) & (nl != 0) & (ni > np.where(grown_l == 0, 0.0, grown_i))
            grown_l[take], grown_i[take] = nl[take], ni[take]
        layers, inv = grown_l, grown_i
    return layers, inv


def blend(a: np.ndarray, b: np.ndarray, w: float) -> np.ndarray:
    """Two keys' luminance blended at the time fraction ``w`` (0: ``a``, 1: ``b``)."""
    return np.float32(1.0 - w) * a + np.float32(w) * b


def turned(a: View, b: View) -> bool:
    """Whether the camera's rotation differs between two views (a frame between keys
    then differs from their blend however little it turned: see :data:`SUBPIXEL_PX`)."""
    return not np.array_equal(a.rotation, b.rotation)


def synthesize(a: Keyframe, b: Keyframe, view: View, w: float, k: np.ndarray) -> np.ndarray:
    """The frame (H, W) float32 linear luminance of ``view`` at the time fraction ``w``
    (0 at key ``a``, 1 at key ``b``) between two keys; ``k`` the camera intrinsics."""
    return KeyPair(a, b, k).frame(view, w)
