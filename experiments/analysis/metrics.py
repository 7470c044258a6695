"""Ground-truth metrics: pure functions on NumPy arrays.

Maps are on the sensor grid, indexed ``[y, x]``; points are ``(x, y)`` pixels with
origin top-left (pixel centres on integer coordinates); the fovea is the sensor
centre ``((W - 1) / 2, (H - 1) / 2)``.

Set overlap of boolean maps (nonzero counts as True):

- :func:`iou` — true intersection over union, ``|P ∩ M| / |P ∪ M|``;
- :func:`precision` — ``|P ∩ M| / |P|``. The paper's public code reports this
  number under the name "IoU"; here it has its proper name;
- :func:`recall` — ``|P ∩ M| / |M|``.

Each returns ``nan`` when its denominator is empty (nothing to score), so that
averages over trials can skip such trials explicitly (``np.nanmean``) instead of
counting them as perfect or as failures.

Events through a filter (the sOMS), counted on a ground-truth object mask:
:class:`EventCounts` (from maps: :func:`event_counts`) — events in and kept, the
object's and the background's; the suppressed fraction, the *event* precision (object
events kept / events kept) and the shares kept, each ``nan`` when its denominator is
empty, as above (a precision when nothing was kept is undefined, not 0).

A figure is held against a pass/fail bar by :func:`reaches`: ``nan`` never reaches a
bar, so an undefined figure fails it (it is no evidence for the claim); averages skip
``nan`` first, so one stimulus or trial with nothing to score does not fail a mean.

Examples:
    >>> import numpy as np
    >>> pred = np.zeros((4, 4), bool); pred[0, :2] = True
    >>> mask = np.zeros((4, 4), bool); mask[0, 1:4] = True
    >>> iou(pred, mask), precision(pred, mask), recall(pred, mask)
    (0.25, 0.5, 0.3333333333333333)
    >>> c = EventCounts(events_in=10, kept=4, object_in=5, object_kept=3)
    >>> c.suppressed, c.precision, c.object_kept_share, c.background_kept_share
    (0.6, 0.75, 0.6, 0.2)
    >>> EventCounts(10, 0, 5, 0).precision, reaches(math.nan, 0.9)
    (nan, False)
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Self

import numpy as np
from scipy.ndimage import gaussian_filter

from agents.suppression import suppressed_fraction

__all__ = [
    "EventCounts",
    "detection_hit",
    "event_counts",
    "foveation_error_px",
    "hit_box",
    "iou",
    "precision",
    "reaches",
    "recall",
    "ssim",
    "ssim_map",
]

# SSIM (Wang et al. 2004): 11×11 Gaussian window of σ = 1.5 (radius 5 = int(3.5·1.5 + 0.5)).
_SSIM_SIGMA = 1.5
_SSIM_TRUNCATE = 3.5
_SSIM_RADIUS = 5


def _pair(pred: np.ndarray, mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    p, m = np.asarray(pred), np.asarray(mask)
    if p.shape != m.shape:
        raise ValueError(f"pred and mask differ in shape: pred {p.shape} vs mask {m.shape}")
    return p.astype(bool, copy=False), m.astype(bool, copy=False)


def _ratio(num: int, den: int) -> float:
    return float(num) / float(den) if den else float("nan")


def iou(pred: np.ndarray, mask: np.ndarray) -> float:
    """Intersection over union of two boolean maps; ``nan`` when both are empty.

    >>> iou(np.array([1, 1, 0, 0]), np.array([0, 1, 1, 0]))
    0.3333333333333333
    """
    p, m = _pair(pred, mask)
    return _ratio(np.count_nonzero(p & m), np.count_nonzero(p | m))


def precision(pred: np.ndarray, mask: np.ndarray) -> float:
    """``|pred ∩ mask| / |pred|`` (the public code's "IoU"); ``nan`` when pred is empty.

    >>> precision(np.array([1, 1, 0, 0]), np.array([0, 1, 1, 1]))
    0.5
    """
    p, m = _pair(pred, mask)
    return _ratio(np.count_nonzero(p & m), np.count_nonzero(p))


def recall(pred: np.ndarray, mask: np.ndarray) -> float:
    """``|pred ∩ mask| / |mask|``; ``nan`` when the mask is empty.

    >>> recall(np.array([1, 1, 0, 0]), np.array([0, 1, 1, 1]))
    0.3333333333333333
    """
    p, m = _pair(pred, mask)
    return _ratio(np.count_nonzero(p & m), np.count_nonzero(m))


@dataclass(frozen=True)
class EventCounts:
    """Events into a filter and kept by it, all and the object's (its ground-truth mask);
    the background's are the rest. Counts add up (``a + b``: pooled over steps, trials
    or stimuli); each share is ``nan`` when its denominator is empty."""

    events_in: int
    kept: int
    object_in: int
    object_kept: int

    def __add__(self, other: EventCounts) -> Self:
        return type(self)(
            self.events_in + other.events_in,
            self.kept + other.kept,
            self.object_in + other.object_in,
            self.object_kept + other.object_kept,
        )

    @property
    def background_in(self) -> int:
        return self.events_in - self.object_in

    @property
    def background_kept(self) -> int:
        return self.kept - self.object_kept

    @property
    def suppressed(self) -> float:
        """``1 − kept / in`` (:func:`agents.suppression.suppressed_fraction`)."""
        return suppressed_fraction(self.events_in, self.kept)

    @property
    def precision(self) -> float:
        """The object's share of the events kept; ``nan`` when nothing was kept."""
        return _ratio(self.object_kept, self.kept)

    @property
    def object_kept_share(self) -> float:
        return _ratio(self.object_kept, self.object_in)

    @property
    def background_kept_share(self) -> float:
        return _ratio(self.background_kept, self.background_in)


def event_counts(counts: np.ndarray, kept: np.ndarray, mask: np.ndarray) -> EventCounts:
    """The :class:`EventCounts` of event counts ``(..., 2, H, W)`` (polarity on axis −3)
    and those kept (same shape), the object's on ``mask`` ``(..., H, W)`` (broadcast over
    the polarities); sums exact for integer counts.

    >>> c = np.ones((2, 1, 3)); m = np.array([[True, False, False]])
    >>> event_counts(c, c * [[[0, 1, 1]], [[1, 0, 0]]], m)
    EventCounts(events_in=6, kept=3, object_in=2, object_kept=1)
    """
    c, k = np.asarray(counts), np.asarray(kept)
    m = np.expand_dims(np.asarray(mask, bool), -3)

    def total(a: np.ndarray) -> int:
        return int(np.sum(a, dtype=np.float64))

    return EventCounts(total(c), total(k), total(c * m), total(k * m))


def reaches(value: float, bar: float) -> bool:
    """``value >= bar``; ``nan`` (nothing to score) never reaches a bar: it fails.

    >>> reaches(0.9, 0.9), reaches(0.5, 0.9), reaches(float("nan"), 0.0)
    (True, False, False)
    """
    return not math.isnan(value) and value >= bar


def ssim_map(a: np.ndarray, b: np.ndarray, data_range: float = 1.0) -> np.ndarray:
    """Local SSIM (Wang et al. 2004) of two 2-D float maps, on the valid region.

    Gaussian-weighted statistics over an 11×11 window (σ = 1.5), population
    (not sample) covariances, ``C1 = (0.01·L)²`` and ``C2 = (0.03·L)²`` with
    ``L = data_range``. Only window positions fully inside the image are kept,
    so the result is ``(H − 10, W − 10)``; this is the reference MATLAB code's
    ``'valid'`` filtering and what scikit-image's ``structural_similarity(...,
    gaussian_weights=True, sigma=1.5, use_sample_covariance=False)`` averages.
    """
    x = np.asarray(a, dtype=np.float64)
    y = np.asarray(b, dtype=np.float64)
    if x.shape != y.shape:
        raise ValueError(f"a and b differ in shape: a {x.shape} vs b {y.shape}")
    if x.ndim != 2:
        raise ValueError(f"ssim needs 2-D maps, got shape {x.shape}")
    win = 2 * _SSIM_RADIUS + 1
    if min(x.shape) < win:
        raise ValueError(f"ssim needs maps at least {win}×{win}, got shape {x.shape}")
    if not (math.isfinite(data_range) and data_range > 0):
        raise ValueError(f"data_range must be a finite number > 0, got {data_range!r}")

    def filt(z: np.ndarray) -> np.ndarray:
        return gaussian_filter(z, _SSIM_SIGMA, truncate=_SSIM_TRUNCATE, mode="reflect")

    c1 = (0.01 * data_range) ** 2
    c2 = (0.03 * data_range) ** 2
    mx, my = filt(x), filt(y)
    vx = filt(x * x) - mx * mx
    vy = filt(y * y) - my * my
    cxy = filt(x * y) - mx * my
    s = ((2 * mx * my + c1) * (2 * cxy + c2)) / ((mx * mx + my * my + c1) * (vx + vy + c2))
    r = _SSIM_RADIUS
    return s[r:-r, r:-r]


def ssim(a: np.ndarray, b: np.ndarray, data_range: float = 1.0) -> float:
    """Mean structural similarity of two 2-D float maps (see :func:`ssim_map`).

    ``data_range`` is the span of values the maps can take (1.0 for maps in [0, 1]).

    >>> rng = np.random.default_rng(0)
    >>> img = rng.random((16, 16))
    >>> ssim(img, img)
    1.0
    >>> round(ssim(np.full((16, 16), 0.5), np.full((16, 16), 0.6)), 6)  # luminance term only
    0.983609
    """
    return float(np.mean(ssim_map(a, b, data_range)))


def hit_box(
    point_xy: tuple[float, float], shape: tuple[int, int], box: int = 8
) -> tuple[int, int, int, int]:
    """The pixels ``[x0, x1) × [y0, y1)`` of the ``box``×``box`` square around a point in
    an image of ``shape`` ``(H, W)``: the box that decides a detection hit.

    The point is taken to its pixel (nearest integer coordinates, halves up) and the
    box covers ``x`` in ``[px − box//2, px + box//2 − 1]`` and ``y`` likewise, so for
    ``box = 8`` it is ``[px − 4, px + 3] × [py − 4, py + 3]``, clipped to the image
    (empty, ``x0 >= x1`` or ``y0 >= y1``, when the point lies that far outside).

    >>> hit_box((7, 7), (16, 16)), hit_box((14.5, 1.4), (16, 16))
    ((3, 11, 3, 11), (11, 16, 0, 5))
    """
    if isinstance(box, bool) or not isinstance(box, (int, np.integer)) or box < 1:
        raise ValueError(f"box must be an int >= 1, got {box!r}")
    h, w = shape
    px, py = (math.floor(float(c) + 0.5) for c in point_xy)
    half = int(box) // 2
    return (
        max(px - half, 0),
        min(px - half + int(box), w),
        max(py - half, 0),
        min(py - half + int(box), h),
    )


def detection_hit(point_xy: tuple[float, float], mask: np.ndarray, box: int = 8) -> bool:
    """Whether the :func:`hit_box` around a point touches the mask: the paper's detection
    criterion (the 8×8 box around the saliency argmax).

    >>> m = np.zeros((16, 16), bool); m[10, 10] = True
    >>> detection_hit((7, 7), m), detection_hit((6, 6), m), detection_hit((14, 14), m)
    (True, False, True)
    """
    m = np.asarray(mask)
    if m.ndim != 2:
        raise ValueError(f"mask must be 2-D (H, W), got shape {m.shape}")
    x0, x1, y0, y1 = hit_box(point_xy, m.shape, box)
    if x0 >= x1 or y0 >= y1:
        return False
    return bool(np.any(m[y0:y1, x0:x1]))


def foveation_error_px(
    point_xy: tuple[float, float], sensor_size: tuple[int, ...]
) -> tuple[float, float, float]:
    """``(dx, dy, distance)`` of a point from the fovea ``((W − 1)/2, (H − 1)/2)``, px.

    ``sensor_size`` is ``(W, H)`` or Tonic's ``(W, H, 2)``. Note the paper's code
    uses (64, 64) as the centre of a 128×128 sensor; the true centre is (63.5, 63.5).

    >>> foveation_error_px((66.5, 59.5), (128, 128, 2))
    (3.0, -4.0, 5.0)
    """
    if len(sensor_size) < 2 or min(sensor_size[:2]) < 1:
        raise ValueError(f"sensor_size must be (W, H[, 2]) with W, H >= 1, got {sensor_size!r}")
    w, h = sensor_size[0], sensor_size[1]
    dx = float(point_xy[0]) - (w - 1) / 2.0
    dy = float(point_xy[1]) - (h - 1) / 2.0
    return dx, dy, math.hypot(dx, dy)
