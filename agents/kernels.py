"""Convolution kernels of the attention pipeline and an FFT 'same' convolution.

Pure functions build the kernels of the paper (``../shared/seed/paper.tex``, §Methods):

* :func:`gaussian_kernel` — the centre and surround kernels of the sOMS model
  (Gaussians centred at ``mu = (0, 0)``, 8 px, ``sigma_c = 1``, ``sigma_s = 4``).
* :func:`von_mises_kernel` — the von Mises kernel of the proto-object model, Eq. (2).

The proto-object model needs no separate edge (Gabor) stage: the paper feeds events, which
already are an edge map, straight into the border-ownership stage.

Kernel coordinates: rows are ``y`` (down), columns are ``x`` (right); the centre of a
``size``-long axis is at index ``(size - 1) / 2`` — a pixel for odd sizes, between two
pixels for even sizes (the 8 px sOMS kernels).

:class:`FFTConv2d` computes exactly what ``torch.nn.functional.conv2d(x, w, padding='same')``
computes (a cross-correlation with zero padding; for an even kernel torch pads
``(k - 1) // 2`` before and ``k // 2`` after, so kernel index ``(k - 1) // 2`` sits on the
output pixel) by multiplying precomputed spectra: large kernels cost the same as small ones.

Examples:
    >>> import torch
    >>> g = gaussian_kernel(8, 1.0)
    >>> round(float(g.sum()), 6), g.shape
    (1.0, (8, 8))
    >>> conv = FFTConv2d(torch.from_numpy(g).float()[None, None], 16, 16)
    >>> x = torch.zeros(1, 1, 16, 16); x[0, 0, 5, 5] = 1.0
    >>> y = conv(x)
    >>> ref = torch.nn.functional.conv2d(x, conv.weight, padding="same")
    >>> bool(torch.allclose(y, ref, atol=1e-6))
    True
"""

from __future__ import annotations

import math

import cv2
import numpy as np
import scipy.fft
import torch
from scipy.special import i0

__all__ = [
    "FFTConv2d",
    "SeparableConv2d",
    "gaussian_kernel",
    "gaussian_kernel_1d",
    "kernel_coordinates",
    "same_fft_shape",
    "von_mises_kernel",
    "von_mises_radius",
]


def kernel_coordinates(size: int) -> tuple[np.ndarray, np.ndarray]:
    """``(x, y)`` grids of shape ``(size, size)``: offsets from the kernel centre
    ``(size - 1) / 2``; ``x`` grows to the right (columns), ``y`` downwards (rows).

    Examples:
        >>> x, y = kernel_coordinates(4)
        >>> x[0].tolist(), y[:, 0].tolist()
        ([-1.5, -0.5, 0.5, 1.5], [-1.5, -0.5, 0.5, 1.5])
    """
    if size < 1:
        raise ValueError(f"size must be >= 1, got {size}")
    c = np.arange(size, dtype=np.float64) - (size - 1) / 2.0
    y, x = np.meshgrid(c, c, indexing="ij")
    return x, y


def gaussian_kernel(size: int = 8, sigma: float = 1.0) -> np.ndarray:
    """Isotropic Gaussian ``exp(-(x² + y²) / (2 σ²))`` on a ``size × size`` grid centred at
    ``(size - 1) / 2`` (``mu = (0, 0)`` in kernel coordinates), normalised to sum 1.

    Examples:
        >>> k = gaussian_kernel(3, 1.0)
        >>> round(float(k[1, 1] / k[0, 0]), 6) == round(float(np.exp(1.0)), 6)
        True
    """
    if sigma <= 0:
        raise ValueError(f"sigma must be > 0, got {sigma}")
    x, y = kernel_coordinates(size)
    k = np.exp(-(x**2 + y**2) / (2.0 * sigma**2))
    return k / k.sum()


def gaussian_kernel_1d(size: int = 8, sigma: float = 1.0) -> np.ndarray:
    """The 1-D factor of :func:`gaussian_kernel`: ``exp(-x² / (2 σ²))`` on ``size``
    points centred at ``(size - 1) / 2``, normalised to sum 1, so that
    ``np.outer(g, g)`` is ``gaussian_kernel(size, sigma)`` (to float64 rounding).

    Examples:
        >>> g = gaussian_kernel_1d(7, 1.5)
        >>> bool(np.allclose(np.outer(g, g), gaussian_kernel(7, 1.5), rtol=1e-12, atol=0))
        True
    """
    if sigma <= 0:
        raise ValueError(f"sigma must be > 0, got {sigma}")
    if size < 1:
        raise ValueError(f"size must be >= 1, got {size}")
    c = np.arange(size, dtype=np.float64) - (size - 1) / 2.0
    k = np.exp(-(c**2) / (2.0 * sigma**2))
    return k / k.sum()


def von_mises_radius(r0: float = 8.0, tol: float = 0.01) -> int:
    """Half-width (px) of a von Mises kernel: the ring ``1 / I0(r - R0)`` has fallen below
    ``tol`` of its peak (``I0(0) = 1``) at ``r = R0 + d``; returns ``ceil(R0 + d)``.

    Examples:
        >>> von_mises_radius(8.0)
        15
    """
    if not 0 < tol < 1:
        raise ValueError(f"tol must be in (0, 1), got {tol}")
    d = 0.0
    while 1.0 / i0(d) > tol:
        d += 0.05
    return math.ceil(r0 + d - 1e-9)


def von_mises_kernel(
    r0: float = 8.0,
    rho: float = 0.2,
    theta_deg: float = 0.0,
    size: int | None = None,
) -> np.ndarray:
    """Von Mises kernel of the proto-object model, paper Eq. (2) (``eq:VMeq``):

    ``VM_θ(x, y) = exp(ρ · R0 · cos(atan2(-y, x) - θ)) / I0(sqrt(x² + y²) - R0)``

    ``x, y`` are offsets from the kernel centre (``y`` down, so ``atan2(-y, x)`` is the
    counter-clockwise angle seen on the image), ``I0`` the modified Bessel function of the
    first kind, order 0. The paper typesets the Bessel argument as ``sqrt(x² + y² - R0)``,
    which is undefined inside ``r² < R0``; it is read as ``sqrt(x² + y²) - R0`` (the form of
    the original model and of the public code): a ring of radius ``R0`` whose weight peaks
    at the angle ``θ``. Unnormalised, exactly the formula (peak ``exp(ρ R0)`` at
    ``(R0 cos θ, -R0 sin θ)``). ``size`` defaults to ``2 * von_mises_radius(r0) + 1`` (odd,
    so the centre is a pixel).

    Examples:
        >>> k = von_mises_kernel(8.0, 0.2, 0.0)
        >>> k.shape, np.unravel_index(k.argmax(), k.shape)  # peak 8 px right of the centre
        ((31, 31), (np.int64(15), np.int64(23)))
    """
    if size is None:
        size = 2 * von_mises_radius(r0) + 1
    x, y = kernel_coordinates(size)
    theta = math.radians(theta_deg)
    num = np.exp(rho * r0 * np.cos(np.arctan2(-y, x) - theta))
    den = i0(np.sqrt(x**2 + y**2) - r0)
    return num / den


def _fast_len(n: int) -> int:
    return int(scipy.fft.next_fast_len(n, real=True))


def _same_margin(k: int) -> int:
    """Zeros a 'same' convolution needs past the input along an axis of kernel length
    ``k``: ``max(p, k - 1 - p)`` with ``p = (k - 1) // 2`` (torch's alignment)."""
    p = (k - 1) // 2
    return max(p, k - 1 - p)


def same_fft_shape(height: int, width: int, kh: int, kw: int) -> tuple[int, int]:
    """The smallest fast (real) FFT grid for a 'same' convolution of a ``height`` ×
    ``width`` input with a ``kh`` × ``kw`` kernel: ``height + max(p, kh - 1 - p)`` (and
    likewise for the width), rounded up to a fast length. The circular wrap-around then
    lands only on rows and columns that are cropped away, so the result is the same as
    on the full ``height + kh - 1`` grid (to float rounding) at less cost.

    Examples:
        >>> same_fft_shape(128, 128, 31, 31), same_fft_shape(32, 32, 31, 31)
        ((144, 144), (48, 48))
    """
    return _fast_len(height + _same_margin(kh)), _fast_len(width + _same_margin(kw))


class FFTConv2d:
    """'Same'-size 2-D convolution by FFT with precomputed kernel spectra.

    ``weight`` has the layout of ``torch.nn.functional.conv2d``: ``(C_out, C_in / groups,
    kh, kw)``; the result equals ``conv2d(x, weight, padding='same', groups=groups)`` (a
    cross-correlation, zero padding, torch's even-kernel alignment) to float rounding, for
    inputs ``(N, C_in, height, width)`` or ``(C_in, height, width)``. ``flip=True`` turns
    it into a true convolution (the kernel rotated by 180° before the correlation).

    Inputs may also be given as spectra (:meth:`spectrum`, :meth:`from_spectrum`) so one
    input FFT can feed several kernel banks of the same padded size.

    The transforms write into workspaces the convolution keeps (one per batch size), so
    a step allocates nothing: fresh megabyte buffers cost more in page faults than the
    FFTs themselves. **A result is a view of that workspace, valid until the next call
    with the same batch size**; copy it to keep it.

    Examples:
        >>> import torch
        >>> w = torch.randn(3, 1, 31, 31)
        >>> conv = FFTConv2d(w, 128, 128)
        >>> x = torch.rand(1, 1, 128, 128)
        >>> ref = torch.nn.functional.conv2d(x, w, padding="same")
        >>> bool(torch.allclose(conv(x), ref, atol=1e-3))
        True
    """

    def __init__(
        self,
        weight: torch.Tensor | np.ndarray,
        height: int,
        width: int,
        groups: int = 1,
        flip: bool = False,
        fft_shape: tuple[int, int] | None = None,
    ) -> None:
        w = torch.as_tensor(weight, dtype=torch.float32)
        if w.ndim != 4:
            raise ValueError(f"weight must be (C_out, C_in/groups, kh, kw), got {tuple(w.shape)}")
        if flip:
            w = torch.flip(w, dims=(-2, -1))
        c_out, c_in_g, kh, kw = w.shape
        if c_out % groups:
            raise ValueError(f"C_out={c_out} is not divisible by groups={groups}")
        self.weight = w
        self.height, self.width = int(height), int(width)
        self.groups = groups
        self.in_channels = c_in_g * groups
        self.out_channels = c_out
        if fft_shape is None:
            fft_shape = (_fast_len(self.height + kh - 1), _fast_len(self.width + kw - 1))
        fh, fw = fft_shape
        if fh < self.height + _same_margin(kh) or fw < self.width + _same_margin(kw):
            raise ValueError(f"fft_shape {fft_shape} too small for kernel {kh}x{kw}")
        self.fft_shape = (fh, fw)
        # torch 'same': kernel index (k - 1) // 2 lies on the output pixel, i.e.
        # y[i] = sum_j w[j] x[i + j - p] with p = (k - 1) // 2. As a circular convolution
        # y = x (*) kp with kp[(p - j) mod F] = w[j].
        ph, pw = (kh - 1) // 2, (kw - 1) // 2
        rows = (ph - torch.arange(kh)) % fh
        cols = (pw - torch.arange(kw)) % fw
        kp = torch.zeros(c_out, c_in_g, fh, fw)
        kp[:, :, rows[:, None], cols[None, :]] = w
        spec = torch.fft.rfft2(kp)  # (C_out, C_in/g, fh, fw//2+1)
        self._spec = spec.reshape(groups, c_out // groups, c_in_g, fh, fw // 2 + 1)
        self._buffers: dict[str, torch.Tensor] = {}

    def _workspace(self, name: str, shape: tuple[int, ...], dtype: torch.dtype) -> torch.Tensor:
        """The kept buffer ``name`` of ``shape`` (made on first use, or for a new shape)."""
        buf = self._buffers.get(name)
        if buf is None or buf.shape != shape:
            buf = self._buffers[name] = torch.empty(shape, dtype=dtype)
        return buf

    def spectrum(self, x: torch.Tensor) -> torch.Tensor:
        """Zero-padded ``rfft2`` of ``x`` ``(N, C_in, H, W)`` on this convolution's grid
        (a view of a workspace: see the class)."""
        fh, fw = self.fft_shape
        out = self._workspace("x", (*x.shape[:-2], fh, fw // 2 + 1), torch.complex64)
        return torch.fft.rfft2(x, s=self.fft_shape, out=out)

    def from_spectrum(self, xs: torch.Tensor) -> torch.Tensor:
        """Convolution output ``(N, C_out, H, W)`` from an input spectrum (:meth:`spectrum`;
        a view of a workspace: see the class)."""
        n = xs.shape[0]
        g = self.groups
        xs = xs.reshape(n, g, self.in_channels // g, *xs.shape[-2:])
        # sum over the input channels of each group; multiply-accumulate in place
        # (several times faster than a complex einsum on the CPU)
        ys = self._workspace("y", (n, g, self.out_channels // g, *xs.shape[-2:]), torch.complex64)
        torch.mul(xs[:, :, 0:1], self._spec[:, :, 0], out=ys)
        for c in range(1, xs.shape[2]):
            ys.addcmul_(xs[:, :, c : c + 1], self._spec[:, :, c])
        ys = ys.reshape(n, self.out_channels, *xs.shape[-2:])
        out = self._workspace("out", (n, self.out_channels, *self.fft_shape), torch.float32)
        y = torch.fft.irfft2(ys, s=self.fft_shape, out=out)
        return y[..., : self.height, : self.width]

    def __call__(self, x: torch.Tensor) -> torch.Tensor:
        squeeze = x.ndim == 3
        if squeeze:
            x = x.unsqueeze(0)
        if x.shape[1:] != (self.in_channels, self.height, self.width):
            raise ValueError(
                f"expected input (N, {self.in_channels}, {self.height}, {self.width}), "
                f"got {tuple(x.shape)}"
            )
        y = self.from_spectrum(self.spectrum(x))
        return y[0] if squeeze else y


class SeparableConv2d:
    """'Same'-size 2-D cross-correlation with a separable kernel ``outer(ky, kx)``, zero
    padding and torch's alignment (kernel index ``(k - 1) // 2`` on the output pixel),
    by two 1-D passes (``cv2.sepFilter2D``, float32). Equals
    ``conv2d(x, outer(ky, kx), padding='same')`` per channel to float32 rounding, at a
    fraction of the cost of an FFT pair for a 37-tap Gaussian on 128×128.

    Inputs are ``(C, H, W)`` or ``(H, W)`` arrays or tensors (any float dtype, computed
    in float32); the result is a float32 numpy array of the same shape.

    Examples:
        >>> g = gaussian_kernel_1d(5, 1.0)
        >>> conv = SeparableConv2d(g, g)
        >>> x = np.zeros((1, 9, 9), np.float32); x[0, 0, 0] = 1.0
        >>> y = conv(x)
        >>> ref = torch.nn.functional.conv2d(
        ...     torch.from_numpy(x)[None], torch.from_numpy(np.outer(g, g)).float()[None, None],
        ...     padding="same")[0].numpy()
        >>> bool(np.allclose(y, ref, atol=1e-7)), round(float(y.sum()), 4)  # a corner: its quadrant
        (True, 0.4918)
    """

    def __init__(self, ky: np.ndarray, kx: np.ndarray) -> None:
        self.ky = np.ascontiguousarray(np.asarray(ky, dtype=np.float32).ravel())
        self.kx = np.ascontiguousarray(np.asarray(kx, dtype=np.float32).ravel())
        if self.ky.size < 1 or self.kx.size < 1:
            raise ValueError("SeparableConv2d needs non-empty 1-D kernels")
        # cv2's anchor (x, y): the kernel index lying on the output pixel
        self._anchor = ((self.kx.size - 1) // 2, (self.ky.size - 1) // 2)

    def __call__(self, x: np.ndarray | torch.Tensor) -> np.ndarray:
        a = x.detach().cpu().numpy() if isinstance(x, torch.Tensor) else np.asarray(x)
        a = np.ascontiguousarray(a, dtype=np.float32)
        if a.ndim == 2:
            return self._one(a)
        if a.ndim != 3:
            raise ValueError(f"expected (C, H, W) or (H, W), got shape {a.shape}")
        out = np.empty_like(a)
        for c in range(a.shape[0]):
            out[c] = self._one(a[c])
        return out

    def _one(self, a: np.ndarray) -> np.ndarray:
        return cv2.sepFilter2D(
            a, cv2.CV_32F, self.kx, self.ky, anchor=self._anchor, borderType=cv2.BORDER_CONSTANT
        )
