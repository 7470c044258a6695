"""Kernels of the attention pipeline and the FFT 'same' convolution."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch
import torch.nn.functional as F

from agents.kernels import (
    FFTConv2d,
    gaussian_kernel,
    kernel_coordinates,
    same_fft_shape,
    von_mises_kernel,
    von_mises_radius,
)


def bessel_i0(x: float) -> float:
    """I0 by its power series, independent of scipy."""
    return sum((x / 2.0) ** (2 * k) / math.factorial(k) ** 2 for k in range(60))


def test_coordinates_centre_even_and_odd():
    x, y = kernel_coordinates(8)
    assert x[0].tolist() == [-3.5, -2.5, -1.5, -0.5, 0.5, 1.5, 2.5, 3.5]
    assert np.array_equal(y, x.T)  # y grows down the rows
    x, y = kernel_coordinates(3)
    assert (x[1, 1], y[1, 1]) == (0.0, 0.0)
    assert (x[0, 2], y[0, 2]) == (1.0, -1.0)


def test_gaussian_sums_to_one_and_matches_formula():
    for size, sigma in [(8, 1.0), (8, 4.0), (5, 0.7), (16, 4.0)]:
        k = gaussian_kernel(size, sigma)
        assert k.shape == (size, size)
        assert k.sum() == pytest.approx(1.0, abs=1e-12)
    k = gaussian_kernel(8, 1.0)
    # index (3, 3) is at (-0.5, -0.5), index (0, 0) at (-3.5, -3.5)
    assert k[3, 3] / k[0, 0] == pytest.approx(math.exp((24.5 - 0.5) / 2.0), rel=1e-12)
    # index (3, 6) is at (x, y) = (2.5, -0.5)
    assert k[3, 6] / k[3, 3] == pytest.approx(math.exp(-(6.5 - 0.5) / 2.0), rel=1e-12)
    # even size: the four central pixels share the peak; symmetric under flips
    assert k[3, 3] == pytest.approx(k.max()) and k[4, 4] == pytest.approx(k.max())
    assert np.allclose(k, k[::-1, ::-1]) and np.allclose(k, k.T)
    with pytest.raises(ValueError, match="sigma must be > 0"):
        gaussian_kernel(8, 0.0)


def test_von_mises_matches_equation_at_hand_picked_points():
    r0, rho = 8.0, 0.2
    k = von_mises_kernel(r0, rho, 0.0)
    assert k.shape == (31, 31)  # centre at index 15
    # (x, y) = (8, 0): on the ring, along theta = 0 -> exp(rho R0) / I0(0)
    assert k[15, 23] == pytest.approx(math.exp(1.6), rel=1e-9)
    # (x, y) = (0, -8) (up): angle atan2(8, 0) = 90 deg -> exp(0) / I0(0) = 1
    assert k[7, 15] == pytest.approx(1.0, rel=1e-9)
    # (x, y) = (-8, 0): opposite -> exp(-1.6)
    assert k[15, 7] == pytest.approx(math.exp(-1.6), rel=1e-9)
    # centre (0, 0): exp(rho R0 cos(0)) / I0(-R0)
    assert k[15, 15] == pytest.approx(math.exp(1.6) / bessel_i0(8.0), rel=1e-9)
    # (x, y) = (3, 4): r = 5, angle atan2(-4, 3)
    expected = math.exp(1.6 * math.cos(math.atan2(-4.0, 3.0))) / bessel_i0(5.0 - 8.0)
    assert k[19, 18] == pytest.approx(expected, rel=1e-9)
    assert np.unravel_index(k.argmax(), k.shape) == (15, 23)


def test_von_mises_orientation_convention():
    k0 = von_mises_kernel(theta_deg=0.0)
    k90 = von_mises_kernel(theta_deg=90.0)
    k45 = von_mises_kernel(theta_deg=45.0)
    k225 = von_mises_kernel(theta_deg=225.0)
    # theta counts counter-clockwise on the image: 90 deg points up (row 15 - 8)
    assert np.unravel_index(k90.argmax(), k90.shape) == (7, 15)
    # rotating the image rotates the kernel; the centre is excluded: atan2(0, 0) = 0 there,
    # so the formula gives exp(rho R0 cos(theta)) / I0(R0), which depends on theta
    off = np.ones(k0.shape, bool)
    off[15, 15] = False
    assert np.allclose(np.rot90(k0)[off], k90[off])
    # the opposite direction is the point reflection through the centre
    assert np.allclose(k45[::-1, ::-1][off], k225[off])
    # x = y = 8/sqrt(2) is not on the grid; (6, -6) lies 45 deg up-right
    assert k45[15 - 6, 15 + 6] > k45[15 + 6, 15 - 6] * 20


def test_von_mises_radius():
    assert 1 / bessel_i0(6.0) > 0.01 > 1 / bessel_i0(7.0)
    assert von_mises_radius(8.0, 0.01) == 15
    assert von_mises_kernel(8.0, 0.2, 0.0, size=9).shape == (9, 9)


CASES = [
    # (H, W, kh, kw, C_in, C_out, groups)
    (128, 128, 8, 8, 2, 4, 2),
    (128, 128, 31, 31, 2, 16, 1),
    (17, 23, 8, 5, 1, 3, 1),
    (30, 31, 31, 31, 2, 16, 2),
    (10, 12, 4, 4, 3, 6, 3),
    (9, 9, 2, 3, 2, 2, 1),
    (12, 12, 8, 8, 8, 4, 2),
    (20, 7, 1, 1, 1, 1, 1),
]


@pytest.mark.parametrize("case", CASES)
@pytest.mark.filterwarnings("ignore:Using padding='same' with even kernel")
def test_fft_conv_equals_torch_same_conv(case):
    h, w, kh, kw, cin, cout, groups = case
    gen = torch.Generator().manual_seed(hash(case) % 2**31)
    weight = torch.rand(cout, cin // groups, kh, kw, generator=gen)
    x = torch.rand(2, cin, h, w, generator=gen)
    conv = FFTConv2d(weight, h, w, groups=groups)
    ref = F.conv2d(x, weight, padding="same", groups=groups)
    scale = float(ref.abs().max())
    assert torch.allclose(conv(x), ref, atol=1e-4 * max(scale, 1.0))
    flipped = FFTConv2d(weight, h, w, groups=groups, flip=True)
    ref = F.conv2d(x, torch.flip(weight, (-2, -1)), padding="same", groups=groups)
    assert torch.allclose(flipped(x), ref, atol=1e-4 * max(scale, 1.0))
    # unbatched input and a reused spectrum give the same
    assert torch.allclose(conv(x[0]), conv(x)[0])
    assert torch.allclose(conv.from_spectrum(conv.spectrum(x)), conv(x))


@pytest.mark.filterwarnings("ignore:Using padding='same' with even kernel")
def test_even_kernel_alignment_is_torchs():
    """torch 'same' pads (k-1)//2 before: kernel index 3 of 8 lies on the output pixel."""
    x = torch.zeros(1, 1, 16, 16)
    x[0, 0, 8, 8] = 1.0
    for r, c in [(3, 3), (4, 4), (0, 7)]:
        k = torch.zeros(1, 1, 8, 8)
        k[0, 0, r, c] = 1.0
        y = FFTConv2d(k, 16, 16)(x)[0, 0]
        ref = F.conv2d(x, k, padding="same")[0, 0]
        assert torch.allclose(y, ref, atol=1e-6)
        # correlation: y[i] = x[i + r - 3] -> the impulse lands at 8 - (r - 3)
        assert torch.nonzero(y > 0.5).tolist() == [[8 - (r - 3), 8 - (c - 3)]]


def test_fft_conv_rejects_wrong_input():
    conv = FFTConv2d(torch.ones(1, 1, 3, 3), 10, 10)
    with pytest.raises(ValueError, match=r"expected input \(N, 1, 10, 10\)"):
        conv(torch.zeros(1, 1, 10, 11))
    with pytest.raises(ValueError, match=r"weight must be \(C_out"):
        FFTConv2d(torch.ones(3, 3), 10, 10)


@pytest.mark.parametrize("k", [31, 8, 5])
def test_the_smallest_same_fft_grid_has_no_wrap_around(k):
    # 'same' needs height + max(p, k - 1 - p) rows (p = (k - 1) // 2), not height + k - 1:
    # on that grid the result is conv2d's, at the edges too (an input of ones).
    h, w = 37, 50
    shape = same_fft_shape(h, w, k, k)
    assert shape[0] >= h + k // 2 and shape[1] >= w + k // 2
    if k == 31:  # the von Mises kernels: 54 x 72 instead of the full 72 x 80
        assert shape == (54, 72)
    wt = torch.rand(3, 2, k, k)
    conv = FFTConv2d(wt, h, w, fft_shape=shape)
    for x in (torch.ones(1, 2, h, w), torch.rand(1, 2, h, w)):
        ref = F.conv2d(x, wt, padding="same")
        assert torch.allclose(conv(x), ref, atol=1e-4 * float(ref.abs().max()))
    with pytest.raises(ValueError, match="too small"):
        FFTConv2d(wt, h, w, fft_shape=(h + k // 2 - 1, shape[1]))
