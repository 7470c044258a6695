"""Tests for the ground-truth metrics (experiments.analysis.metrics)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.lib.stride_tricks import sliding_window_view

from experiments.analysis.metrics import (
    EventCounts,
    detection_hit,
    event_counts,
    foveation_error_px,
    hit_box,
    iou,
    precision,
    reaches,
    recall,
    ssim,
    ssim_map,
)


def box_map(shape, y0, y1, x0, x1):
    m = np.zeros(shape, dtype=bool)
    m[y0:y1, x0:x1] = True
    return m


# ----------------------------------------------------------------------------------------
# Overlap


def test_overlap_on_hand_made_maps():
    pred = box_map((10, 10), 0, 4, 0, 4)  # 16 px
    mask = box_map((10, 10), 2, 6, 2, 6)  # 16 px, overlap 2×2 = 4
    assert iou(pred, mask) == 4 / 28
    assert precision(pred, mask) == 4 / 16
    assert recall(pred, mask) == 4 / 16


def test_precision_is_not_iou_for_a_small_prediction_inside_the_mask():
    # The public code's "IoU": a tiny prediction inside a big mask scores 1.
    mask = box_map((8, 8), 0, 8, 0, 8)
    pred = box_map((8, 8), 3, 4, 3, 4)
    assert precision(pred, mask) == 1.0
    assert iou(pred, mask) == 1 / 64
    assert recall(pred, mask) == 1 / 64


def test_identical_and_disjoint():
    m = box_map((5, 7), 1, 3, 2, 6)
    assert iou(m, m) == precision(m, m) == recall(m, m) == 1.0
    other = box_map((5, 7), 4, 5, 0, 1)
    assert iou(m, other) == precision(m, other) == recall(m, other) == 0.0


def test_empty_denominators_give_nan():
    empty = np.zeros((3, 3), bool)
    full = np.ones((3, 3), bool)
    assert math.isnan(iou(empty, empty))
    assert math.isnan(precision(empty, full))
    assert recall(empty, full) == 0.0
    assert math.isnan(recall(full, empty))
    assert precision(full, empty) == 0.0
    assert iou(empty, full) == 0.0


def test_nonzero_values_count_as_true():
    pred = np.array([[0.0, 0.7], [2.0, 0.0]])
    mask = np.array([[0, 1], [0, 1]], dtype=np.uint8)
    assert iou(pred, mask) == 1 / 3
    assert precision(pred, mask) == 0.5


@pytest.mark.parametrize("fn", [iou, precision, recall])
def test_shape_mismatch_names_both_shapes(fn):
    with pytest.raises(ValueError, match=r"\(4, 5\).*\(5, 4\)"):
        fn(np.zeros((4, 5), bool), np.zeros((5, 4), bool))


# ----------------------------------------------------------------------------------------
# SSIM


def naive_ssim(a, b, data_range):
    """Direct Wang et al. (2004): explicit 11×11 Gaussian (σ = 1.5), 'valid' windows."""
    r = np.arange(-5, 6)
    g = np.exp(-(r**2) / (2 * 1.5**2))
    w = np.outer(g, g)
    w /= w.sum()
    wa, wb = sliding_window_view(a, (11, 11)), sliding_window_view(b, (11, 11))

    def mean(z):
        return np.einsum("ijkl,kl->ij", z, w)

    ma, mb = mean(wa), mean(wb)
    va = mean(wa**2) - ma**2
    vb = mean(wb**2) - mb**2
    cab = mean(wa * wb) - ma * mb
    c1, c2 = (0.01 * data_range) ** 2, (0.03 * data_range) ** 2
    s = (2 * ma * mb + c1) * (2 * cab + c2) / ((ma**2 + mb**2 + c1) * (va + vb + c2))
    return s


def test_ssim_identical_is_one():
    rng = np.random.default_rng(1)
    img = rng.random((32, 40))
    assert ssim(img, img) == pytest.approx(1.0, abs=1e-12)
    assert ssim(np.zeros((11, 11)), np.zeros((11, 11))) == 1.0


def test_ssim_constant_maps_closed_form():
    # No variance: only the luminance term (2ab + C1) / (a² + b² + C1) remains.
    a, b, rng_ = 0.2, 0.7, 1.0
    c1 = (0.01 * rng_) ** 2
    expected = (2 * a * b + c1) / (a * a + b * b + c1)
    assert ssim(np.full((16, 16), a), np.full((16, 16), b), data_range=rng_) == pytest.approx(
        expected, rel=1e-12
    )


def test_ssim_matches_a_direct_implementation():
    rng = np.random.default_rng(2)
    a = rng.random((24, 30))
    b = np.clip(a + rng.normal(0, 0.1, a.shape), 0, 1)
    expected = naive_ssim(a, b, 1.0)
    got = ssim_map(a, b, 1.0)
    assert got.shape == (14, 20)
    np.testing.assert_allclose(got, expected, rtol=1e-10, atol=1e-12)
    assert ssim(a, b) == pytest.approx(expected.mean(), rel=1e-10)
    assert 0.0 < ssim(a, b) < 1.0


def _maps() -> list[tuple[str, np.ndarray, np.ndarray, float]]:
    """Pairs of maps as the detection scoring compares them: noise, a salient blob and
    the same blob moved, a binary mask and a blurred saliency of it, a wider value range."""
    rng = np.random.default_rng(3)
    yy, xx = np.mgrid[0:64, 0:80]

    def blob(cx: float, cy: float, s: float) -> np.ndarray:
        return np.exp(-((xx - cx) ** 2 + (yy - cy) ** 2) / (2 * s**2))

    mask = ((xx - 40) ** 2 + (yy - 30) ** 2 < 12**2).astype(float)
    noisy = np.clip(mask + rng.normal(0, 0.2, mask.shape), 0, 1)
    a = rng.random((24, 30))
    return [
        ("noise", a, np.clip(a + rng.normal(0, 0.1, a.shape), 0, 1), 1.0),
        ("moved blob", blob(30, 30, 6), blob(36, 28, 6), 1.0),
        ("mask vs saliency", mask, noisy, 1.0),
        ("range 2", 2 * rng.random((16, 16)), 2 * rng.random((16, 16)), 2.0),
    ]


@pytest.mark.parametrize(("name", "a", "b", "data_range"), _maps(), ids=lambda v: str(v)[:16])
def test_ssim_matches_scikit_image(name, a, b, data_range):
    from skimage.metrics import structural_similarity

    kwargs = {"gaussian_weights": True, "sigma": 1.5, "use_sample_covariance": False}
    mean, full = structural_similarity(a, b, data_range=data_range, full=True, **kwargs)
    # scikit-image averages its map over the positions whose window lies inside the map
    np.testing.assert_allclose(ssim_map(a, b, data_range), full[5:-5, 5:-5], rtol=1e-9, atol=1e-12)
    assert ssim(a, b, data_range) == pytest.approx(mean, rel=1e-9, abs=1e-12)


def test_ssim_properties():
    rng = np.random.default_rng(3)
    a, b = rng.random((20, 20)), rng.random((20, 20))
    assert ssim(a, b) == pytest.approx(ssim(b, a))
    # Scaling the maps and the data range together leaves SSIM unchanged.
    assert ssim(255 * a, 255 * b, data_range=255) == pytest.approx(ssim(a, b))
    # An inverted image is anti-correlated in structure.
    assert ssim(a, 1.0 - a) < 0.0


def test_ssim_rejects_bad_input():
    with pytest.raises(ValueError, match=r"\(12, 12\).*\(12, 13\)"):
        ssim(np.zeros((12, 12)), np.zeros((12, 13)))
    with pytest.raises(ValueError, match="at least 11"):
        ssim(np.zeros((10, 20)), np.zeros((10, 20)))
    with pytest.raises(ValueError, match="2-D"):
        ssim(np.zeros((2, 12, 12)), np.zeros((2, 12, 12)))
    with pytest.raises(ValueError, match="data_range"):
        ssim(np.zeros((12, 12)), np.zeros((12, 12)), data_range=0.0)


# ----------------------------------------------------------------------------------------
# Detection


def single_pixel(x, y, shape=(32, 32)):
    m = np.zeros(shape, dtype=bool)
    m[y, x] = True
    return m


@pytest.mark.parametrize(
    ("point", "hit"),
    [
        ((10, 10), True),
        ((14, 10), True),  # box x in [10, 17]: the mask pixel is its left column
        ((15, 10), False),  # box x in [11, 18]
        ((7, 10), True),  # box x in [3, 10]: right column
        ((6, 10), False),  # box x in [2, 9]
        ((10, 14), True),
        ((10, 15), False),
        ((10, 7), True),
        ((10, 6), False),
        ((14, 14), True),  # corner
        ((6, 6), False),
        ((14.49, 10), True),  # rounds to 14
        ((14.5, 10), False),  # rounds (half up) to 15
    ],
)
def test_detection_box_is_px_minus_4_to_px_plus_3(point, hit):
    assert detection_hit(point, single_pixel(10, 10)) is hit


def test_detection_uses_x_y_not_row_col():
    m = single_pixel(20, 2)  # x = 20, y = 2
    assert detection_hit((20, 2), m)
    assert not detection_hit((2, 20), m)


def test_detection_box_is_clipped_to_the_image():
    m = single_pixel(0, 0, shape=(16, 16))
    assert detection_hit((3, 3), m)
    assert detection_hit((-3, -3), m)  # box [-7, 0]
    assert not detection_hit((-4, -4), m)  # box [-8, -1]: entirely outside
    corner = single_pixel(15, 15, shape=(16, 16))
    assert detection_hit((19, 19), corner)  # box [15, 22]
    assert not detection_hit((20, 20), corner)


def test_hit_box_is_the_clipped_pixel_range_detection_scores():
    assert hit_box((10, 10), (32, 32)) == (6, 14, 6, 14)
    assert hit_box((14.5, 9.49), (32, 32)) == (11, 19, 5, 13)  # (15, 9): halves up
    assert hit_box((1, 30), (32, 40)) == (0, 5, 26, 32)  # (H, W): y clipped at 32
    assert hit_box((11, 10), (32, 32), box=3) == (10, 13, 9, 12)
    assert hit_box((-20, 5), (16, 16)) == (0, -16, 1, 9)  # entirely outside: x0 >= x1
    with pytest.raises(ValueError, match="box"):
        hit_box((1, 1), (4, 4), box=0)


def test_detection_other_box_sizes():
    m = single_pixel(10, 10)
    assert detection_hit((10, 10), m, box=1)
    assert not detection_hit((11, 10), m, box=1)
    assert detection_hit((11, 10), m, box=3)  # [10, 12]
    assert not detection_hit((12, 10), m, box=3)
    assert not detection_hit((5, 5), np.zeros((8, 8), bool))


def test_detection_rejects_bad_input():
    with pytest.raises(ValueError, match="box"):
        detection_hit((1, 1), np.ones((4, 4), bool), box=0)
    with pytest.raises(ValueError, match="box"):
        detection_hit((1, 1), np.ones((4, 4), bool), box=True)
    with pytest.raises(ValueError, match="2-D"):
        detection_hit((1, 1), np.ones(4, bool))


# ----------------------------------------------------------------------------------------
# Foveation and angles


def test_foveation_error():
    assert foveation_error_px((63.5, 63.5), (128, 128, 2)) == (0.0, 0.0, 0.0)
    assert foveation_error_px((64, 64), (128, 128)) == (0.5, 0.5, math.sqrt(0.5))
    assert foveation_error_px((0, 0), (128, 64)) == (-63.5, -31.5, math.hypot(63.5, 31.5))
    with pytest.raises(ValueError, match="sensor_size"):
        foveation_error_px((0, 0), (128,))
    with pytest.raises(ValueError, match="sensor_size"):
        foveation_error_px((0, 0), (0, 128))


# ----------------------------------------------------------------------------------------
# Event counts and bars


def test_event_counts_per_polarity_and_window_on_the_mask():
    """Counts (windows, 2, H, W) and the kept ones, the object's on a mask per window
    (broadcast over the polarities): exact integer sums; the background is the rest."""
    counts = np.zeros((2, 2, 1, 3), np.float32)
    counts[0, 1] = (3, 2, 1)  # window 0: ON events
    counts[1, 0] = (4, 0, 5)  # window 1: OFF events
    kept = counts.copy()
    kept[0, 1, 0, 2] = kept[1, 0, 0, 0] = 0
    mask = np.array([[[True, False, False]], [[False, False, True]]])
    c = event_counts(counts, kept, mask)
    assert c == EventCounts(events_in=15, kept=10, object_in=8, object_kept=8)
    assert (c.background_in, c.background_kept) == (7, 2)
    assert (c.suppressed, c.precision, c.object_kept_share) == (1 - 10 / 15, 0.8, 1.0)
    assert c.background_kept_share == 2 / 7
    assert c + c == EventCounts(30, 20, 16, 16)


def test_event_shares_are_nan_when_their_denominator_is_empty():
    """Nothing kept: the precision is undefined (NaN), not 0; nothing in: every share."""
    nothing_kept = EventCounts(10, 0, 5, 0)
    assert math.isnan(nothing_kept.precision)
    assert (nothing_kept.suppressed, nothing_kept.object_kept_share) == (1.0, 0.0)
    empty = EventCounts(0, 0, 0, 0)
    shares = (empty.suppressed, empty.precision, empty.object_kept_share)
    assert all(math.isnan(v) for v in (*shares, empty.background_kept_share))


def test_nan_never_reaches_a_bar():
    assert reaches(0.9, 0.9) and not reaches(0.899, 0.9)
    assert not reaches(math.nan, 0.0) and not reaches(math.nan, -math.inf)


def test_docstring_examples_run():
    import doctest

    import experiments.analysis.metrics

    result = doctest.testmod(experiments.analysis.metrics)
    assert (result.failed, result.attempted) == (0, 21)  # all ran, none failed
