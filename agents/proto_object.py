"""Spiking proto-object saliency: the second visual stage of the agent.

The paper's §Methods "SNN Proto-Object model", on the OMS map ``V`` (binary, per
polarity ``V+``/``V-``), for the directions ``θ`` in ``orientations`` and their opposites
``θ + π``, at every pyramid level ``s``:

* Eq. (2) — von Mises kernels ``VM_θ`` (:func:`agents.kernels.von_mises_kernel`).
* Eq. (3) (``eq:BO``) — border ownership::

      B1_θ = V ⊙ (V+ * VM_θ − w V− * VM_θ+π  +  V− * VM_θ − w V+ * VM_θ+π)
      B2_θ = V ⊙ (V+ * VM_θ+π − w V− * VM_θ  +  V− * VM_θ+π − w V+ * VM_θ)

* Eq. (4) (``eq:G``) — grouping, pooled over orientations and levels::

      G1 = Σθ Σs B1_θ,s · VM_θ,s        G1* = Σθ Σs B1_θ,s · VM_θ+π,s
      G2 = Σθ Σs B2_θ,s · VM_θ+π,s      G2* = Σθ Σs B2_θ,s · VM_θ,s

* Eq. (5) (``eq:pxy``) — ``P(x, y) = argmax [(G1 − G1*) + (G2 − G2*)]``.

Design decisions:

* **Operators.** ``*`` in Eq. (3) is a CNN convolution (torch ``conv2d``, a
  cross-correlation): ``V * VM_θ`` at ``p`` gathers the OMS pixels on the arc at
  distance ``R0`` in direction ``θ`` from ``p``, so ``B1_θ(p) > 0`` says "the object lies
  towards ``θ``". ``·`` in Eq. (4) is the transposed operation (a true convolution): each
  border-ownership spike at ``p`` votes for the pixel ``R0`` further along ``θ``, so ``G1``
  peaks at the centre of a closed contour of radius ≈ ``R0`` and ``G1*`` away from it.
  (With the same operator in both stages ``G1*``, not ``G1``, would peak at the centre.)
* **Polarity split.** As the two lines of Eq. (3) and the public code: each line is its
  own population of LIF neurons (excitation from one polarity, inhibition from the other)
  and ``B1_θ`` is the sum of their spikes. ``polarity_split=False`` is the paper's
  "streamlined" model: one population on ``V = V+ ∨ V−``,
  ``B1_θ = LIF(V ⊙ (V * VM_θ − w V * VM_θ+π))``. (As one linear sum, the two lines of
  Eq. (3) equal the streamlined current; only the per-line rectification differs.)
  ``B2_θ = B1_θ+π``, so one population per direction (8 directions) serves both.
* **Neurons.** sinabs ``LIF`` layers, ``tau = 0.1 s`` converted to steps (``tau / dt``),
  ``MultiSpike`` output, subtractive reset, ``norm_input=False`` (each input adds its
  current to the membrane). Border ownership: one LIF neuron per direction, line,
  level and pixel; grouping: four populations (``G1, G1*, G2, G2*``) on the sensor grid,
  fed the currents pooled over orientations and levels (Eq. (4)); saliency is the
  spike-count difference of Eq. (5).
* **Pyramid.** Level ``s`` max-pools ``V±`` by ``2^s`` (stays binary; the map is padded
  with zeros up to a multiple of ``2^s``); the same ``R0``-pixel kernels then see objects
  ``2^s`` times larger. Grouping currents go back to the sensor grid by bilinear
  upsampling by exactly ``2^s`` (pixel ``i`` of level ``s`` covers sensor pixels
  ``[i 2^s, (i + 1) 2^s)``), then the padding is cropped — never a resize to another size.
* **Speed.** The von Mises kernels are 31 × 31 (ring of ``R0 = 8`` until ``1/I0`` falls
  under 1 % of its peak), so convolutions run by FFT on precomputed kernel spectra
  (:class:`agents.kernels.FFTConv2d`), on the smallest grid without wrap-around
  (:func:`agents.kernels.same_fft_shape`); ``conv="direct"`` uses ``conv2d`` (same
  result, much slower). Eq. (3) needs only the 2 × 2n distinct convolutions
  ``V± * VM_j`` (2n with the streamlined model), one input transform per level: each
  line of Eq. (3) takes one of them as excitation and, scaled by ``−w``, the opposite
  direction's of the other polarity as inhibition (instead of convolving every one of
  the 2 · 2n lines with its own two-channel kernel).

Examples:
    >>> import numpy as np
    >>> po = ProtoObjectSaliency()
    >>> oms = np.zeros((2, 64, 64), np.float32)
    >>> yy, xx = np.mgrid[0:64, 0:64]
    >>> ring = np.abs(np.hypot(xx - 40, yy - 20) - 8) < 0.6   # a circle around (40, 20)
    >>> oms[1][ring] = 1.0
    >>> for _ in range(5):
    ...     out = po.step(oms)
    >>> x, y = po.argmax()
    >>> abs(x - 40) <= 2 and abs(y - 20) <= 2
    True
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numba
import numpy as np
import torch
import torch.nn.functional as F

from agents.kernels import FFTConv2d, same_fft_shape, von_mises_kernel, von_mises_radius
from agents.soms import MapLayer, lif_layer, lif_step, tau_steps

__all__ = [
    "ProtoObjectOutput",
    "ProtoObjectParams",
    "ProtoObjectSaliency",
    "border_weights",
    "grouping_weights",
    "saliency_argmax",
    "von_mises_bank",
]


@dataclass(frozen=True)
class ProtoObjectParams:
    """Proto-object parameters; defaults are the paper's (table "params").

    ``orientations_deg`` are the ``θ`` (their opposites ``θ + 180°`` are added);
    ``dt`` is the step length in seconds; ``vm_tol`` truncates the von Mises kernels
    where ``1/I0`` has fallen below that fraction of its peak.

    ``border`` says what lies beyond the sensor's edge in Eq. (3). ``"zero"`` (zero
    padding) reads it as "no events", so the image frame itself becomes a contour that
    owns the whole image: on spatially uniform noise the saliency then peaks
    ≈ R0·2^s px from the image corners (s the coarsest level) instead of anywhere.
    ``"unknown"`` (default) reads it as unobserved: the excitatory and the inhibitory
    sums of Eq. (3) are each divided by the fraction of their kernel that lies on the
    sensor (normalised convolution), and a border-ownership cell whose excitatory or
    inhibitory field has less than ``min_coverage`` of its mass on the sensor gets no
    drive (it cannot tell which side owns the border). Where a kernel lies wholly on
    the sensor both are identical (for the coarsest level of a 128-px sensor that is
    only its middle).
    """

    r0: float = 8.0
    rho: float = 0.2
    w: float = 3.0
    orientations_deg: tuple[float, ...] = (0.0, 45.0, 90.0, 135.0)
    levels: int = 3
    tau_mem: float = 0.1
    dt: float = 0.01
    polarity_split: bool = True
    spike_threshold: float = 1.0
    vm_tol: float = 0.01
    conv: Literal["fft", "direct"] = "fft"
    border: Literal["unknown", "zero"] = "unknown"
    min_coverage: float = 0.75

    def __post_init__(self) -> None:
        if self.border not in ("unknown", "zero"):
            raise ValueError(f"border must be 'unknown' or 'zero', got {self.border!r}")
        if not 0.0 < self.min_coverage <= 1.0:
            raise ValueError(f"min_coverage must be in (0, 1], got {self.min_coverage}")
        if self.levels < 1:
            raise ValueError(f"levels must be >= 1, got {self.levels}")
        if not self.orientations_deg:
            raise ValueError("orientations_deg must not be empty")
        if self.conv not in ("fft", "direct"):
            raise ValueError(f"conv must be 'fft' or 'direct', got {self.conv!r}")
        tau_steps(self.tau_mem, self.dt)

    @property
    def directions_deg(self) -> tuple[float, ...]:
        """``θ`` then ``θ + 180°``: index ``j`` and ``j + n`` are opposite."""
        return tuple(self.orientations_deg) + tuple(t + 180.0 for t in self.orientations_deg)

    @property
    def kernel_size(self) -> int:
        return 2 * von_mises_radius(self.r0, self.vm_tol) + 1


@dataclass(frozen=True)
class ProtoObjectOutput:
    """One step: ``saliency`` ``(H, W)`` = ``(G1 − G1*) + (G2 − G2*)`` in spike counts;
    ``grouping`` ``(4, H, W)`` the spikes of ``G1, G1*, G2, G2*``."""

    saliency: torch.Tensor
    grouping: torch.Tensor


def von_mises_bank(params: ProtoObjectParams) -> torch.Tensor:
    """Kernels ``(2n, k, k)`` for :attr:`ProtoObjectParams.directions_deg` (float32)."""
    size = params.kernel_size
    bank = [von_mises_kernel(params.r0, params.rho, d, size) for d in params.directions_deg]
    return torch.from_numpy(np.stack(bank)).float()


def border_weights(bank: torch.Tensor, w: float, polarity_split: bool) -> torch.Tensor:
    """Conv weights of Eq. (3) for the directions of ``bank`` (``j`` and ``j + n``
    opposite). Polarity split: inputs ``[V−, V+]`` (channel 0 OFF, 1 ON), outputs
    ``2j`` = ``V+ * VM_j − w V− * VM_opp(j)`` and ``2j + 1`` = ``V− * VM_j − w V+ * VM_opp(j)``.
    Streamlined: input ``V``, output ``j`` = ``V * VM_j − w V * VM_opp(j)``."""
    m = bank.shape[0]
    n = m // 2
    opp = [(j + n) % m for j in range(m)]
    if not polarity_split:
        return (bank - w * bank[opp]).unsqueeze(1)
    wt = torch.zeros(2 * m, 2, *bank.shape[-2:])
    for j in range(m):
        wt[2 * j, 1], wt[2 * j, 0] = bank[j], -w * bank[opp[j]]
        wt[2 * j + 1, 0], wt[2 * j + 1, 1] = bank[j], -w * bank[opp[j]]
    return wt


def grouping_weights(bank: torch.Tensor) -> torch.Tensor:
    """Weights ``(4, n, k, k)`` (``groups=2``) of Eq. (4): inputs ``B_0..B_{n-1}``
    (``= B1_θ``) feed ``G1`` (``VM_θ``) and ``G1*`` (``VM_θ+π``); inputs ``B_n..B_{2n-1}``
    (``= B2_θ``) feed ``G2`` (``VM_θ+π``) and ``G2*`` (``VM_θ``). Used as a true
    convolution (``flip=True``)."""
    n = bank.shape[0] // 2
    th, opp = bank[:n], bank[n:]
    return torch.stack([th, opp, opp, th])


def saliency_argmax(saliency: torch.Tensor) -> tuple[int, int] | None:
    """``(x, y)`` of the maximum of ``saliency`` ``(H, W)`` (x right, y down, origin top
    left); among tied maxima the one nearest their centroid; None if no value is > 0.

    Examples:
        >>> s = torch.zeros(5, 7); s[1, 2:5] = 3.0
        >>> saliency_argmax(s)
        (3, 1)
    """
    top = float(saliency.max())
    if not top > 0.0:
        return None
    ys, xs = torch.nonzero(saliency == top, as_tuple=True)
    if len(xs) == 1:
        return int(xs[0]), int(ys[0])
    cx, cy = xs.float().mean(), ys.float().mean()
    i = int(torch.argmin((xs - cx) ** 2 + (ys - cy) ** 2))
    return int(xs[i]), int(ys[i])


def _conv(
    weight: torch.Tensor,
    h: int,
    w: int,
    kind: str,
    groups: int = 1,
    flip: bool = False,
    fft_shape: tuple[int, int] | None = None,
) -> FFTConv2d | _DirectConv2d:
    """A 'same' convolution of ``weight`` on an ``h``×``w`` grid, by FFT or directly."""
    if kind == "fft":
        return FFTConv2d(weight, h, w, groups=groups, flip=flip, fft_shape=fft_shape)
    return _DirectConv2d(weight, groups=groups, flip=flip)


def _coverage_gain(
    weight: torch.Tensor, valid: torch.Tensor, min_coverage: float, kind: str
) -> torch.Tensor:
    """Per output channel and pixel: 1 / (fraction of the kernel's absolute mass lying on
    ``valid`` sensor pixels), or 0 where that fraction is below ``min_coverage``."""
    mag = weight.abs()
    mass = mag.sum(dim=(1, 2, 3)).clamp_min(1e-12).view(1, -1, 1, 1)
    cover = _conv(mag, *valid.shape[-2:], kind)(valid) / mass
    return torch.where(cover >= min_coverage, 1.0 / cover.clamp_min(min_coverage), 0.0)


def _gain_arrays(g_exc: torch.Tensor, g_inh: torch.Tensor) -> tuple[np.ndarray, np.ndarray]:
    """Gains ``(1, 2n, h, w)`` as the contiguous float32 ``(2n, h, w)`` arrays that
    :func:`_gated_border_cells` reads."""
    return tuple(  # type: ignore[return-value]
        np.ascontiguousarray(g[0].numpy(), dtype=np.float32) for g in (g_exc, g_inh)
    )


@numba.njit(cache=True, nogil=True)
def _gated_border_cells(
    v: np.ndarray,
    conv: np.ndarray,
    swap: np.ndarray,
    g_exc: np.ndarray,
    g_inh: np.ndarray,
    out: np.ndarray,
    on: np.ndarray,
) -> None:
    """Eq. (3)'s cells where ``V`` fired: for every pixel ``p`` with ``v[:, p] > 0`` and
    cell ``i = (c, j)``, ``out[i, p] = conv[i, p] g_exc[j, p] + conv[swap[i], p]
    g_inh[j, p]`` (float32, the two products then their sum, as the tensors' operations
    did); ``out`` elsewhere is left as it is (zeros). ``v`` ``(C, h, w)``, ``conv`` (any
    strides) and ``out`` ``(C 2n, h, w)``, gains ``(2n, h, w)``; ``on`` (at least
    ``(h w, 2)`` integers) is scratch space for the fired pixels."""
    n_cells, h, w = conv.shape
    m = g_exc.shape[0]
    n_on = 0  # the pixels where V fired, listed in on
    for y in range(h):
        for x in range(w):
            for c in range(v.shape[0]):
                if v[c, y, x] > 0:
                    on[n_on, 0], on[n_on, 1] = y, x
                    n_on += 1
                    break
    for i in range(n_cells):  # cell by cell: the cells' planes lie 2^k floats apart
        j, k = i % m, swap[i]
        for q in range(n_on):
            y, x = on[q, 0], on[q, 1]
            out[i, y, x] = conv[i, y, x] * g_exc[j, y, x] + conv[k, y, x] * g_inh[j, y, x]


class _DirectConv2d:
    """``conv2d(padding='same')`` with the call signature of :class:`FFTConv2d`."""

    def __init__(self, weight: torch.Tensor, groups: int = 1, flip: bool = False) -> None:
        self.weight = torch.flip(weight, dims=(-2, -1)) if flip else weight
        self.groups = groups

    def __call__(self, x: torch.Tensor) -> torch.Tensor:
        return F.conv2d(x, self.weight, padding="same", groups=self.groups)


class ProtoObjectSaliency(MapLayer[ProtoObjectParams]):
    """Stateful SNN proto-object model: :meth:`step` once per OMS map ``(2, H, W)``
    (channel 0 OFF, 1 ON; nonzero = spike); the LIF state carries over until
    :meth:`reset`. Any ``H, W`` works (a new size rebuilds and resets).

    Examples:
        >>> po = ProtoObjectSaliency(ProtoObjectParams(polarity_split=False))
        >>> out = po.step(np.zeros((2, 128, 128), np.float32))
        >>> tuple(out.saliency.shape), po.argmax()
        ((128, 128), None)
    """

    params_type = ProtoObjectParams

    def _setup(self) -> None:
        p = self.params
        self.bank = von_mises_bank(p)
        m = self.bank.shape[0]
        self._opp = [(j + m // 2) % m for j in range(m)]
        # Border-ownership cell (c, j), c = 0..C-1 (C = 2 polarities, or 1 streamlined):
        # excitation V_c * VM_j, inhibition -w V_c' * VM_opp(j) with c' = C-1-c, so
        # (1, j) is line 1 of Eq. (3) for θ_j (V+ excites) and (0, j) line 2 (V− excites).
        # _swap gathers the inhibiting convolution of every cell from the (c, j) stack.
        n_c = 2 if p.polarity_split else 1
        self._swap = np.array(
            [(n_c - 1 - c) * m + self._opp[j] for c in range(n_c) for j in range(m)], np.int64
        )
        self._g_weight = grouping_weights(self.bank)
        self.border_lif = lif_layer(p.tau_mem, p.dt, p.spike_threshold)
        self.grouping_lif = lif_layer(p.tau_mem, p.dt, p.spike_threshold)
        self._saliency: torch.Tensor | None = None

    @property
    def saliency(self) -> torch.Tensor | None:
        """The last saliency map ``(H, W)`` (None before the first step)."""
        return self._saliency

    def _build(self, h: int, w: int) -> None:
        p = self.params
        self._shape = (h, w)
        f = 2 ** (p.levels - 1)
        self._padded = (math.ceil(h / f) * f, math.ceil(w / f) * f)
        self._level_shapes = [
            (self._padded[0] // 2**s, self._padded[1] // 2**s) for s in range(p.levels)
        ]
        k, m = p.kernel_size, self.bank.shape[0]
        vm = self.bank.unsqueeze(1)  # (2n, 1, k, k): one input channel -> every V * VM_j
        self._vm_conv: list[FFTConv2d | _DirectConv2d] = []
        self._g_conv: list[FFTConv2d | _DirectConv2d] = []
        for hs, ws in self._level_shapes:
            fft = same_fft_shape(hs, ws, k, k)
            self._vm_conv.append(_conv(vm, hs, ws, p.conv, fft_shape=fft))
            self._g_conv.append(
                _conv(self._g_weight, hs, ws, p.conv, groups=2, flip=True, fft_shape=fft)
            )
        # Per level: the gains (2n, h_s, w_s) of the excitation and of the inhibition
        # (-w folded in) of the cells of direction j; border "zero": 1 and -w.
        self._gain: list[tuple[np.ndarray, np.ndarray]] = []
        for valid in self._levels(torch.ones(2, h, w)):
            if p.border == "zero":
                g = torch.ones(1, m, *valid.shape[-2:])
                self._gain.append(_gain_arrays(g, -p.w * g))
                continue
            g = _coverage_gain(vm, valid[:, :1], p.min_coverage, p.conv)
            g_inh = g[:, self._opp]
            known = (g > 0) & (g_inh > 0)
            self._gain.append(_gain_arrays(g * known, -p.w * g_inh * known))
        n_bo = self._swap.size
        self._bo_sizes = [n_bo * hs * ws for hs, ws in self._level_shapes]
        self.border_lif.init_state_with_shape((1, sum(self._bo_sizes)))
        self._currents = np.zeros(sum(self._bo_sizes), np.float32)  # the border LIF's input
        self._on = np.empty((self._padded[0] * self._padded[1], 2), np.int64)
        self.grouping_lif.init_state_with_shape((1, 4, h, w))
        self._saliency = None

    def reset(self) -> None:
        """Zero every membrane and forget the last saliency map."""
        self.border_lif.reset_states()
        self.grouping_lif.reset_states()
        self._saliency = None

    def _levels(self, x: torch.Tensor) -> list[torch.Tensor]:
        """Binary input maps per level, ``(1, C, h_s, w_s)``; C = 2 (split) or 1."""
        v = (x > 0).float()
        if not self.params.polarity_split:
            v = v.amax(dim=0, keepdim=True)
        v = v.unsqueeze(0)
        h, w = self._shape
        ph, pw = self._padded
        if (ph, pw) != (h, w):
            v = F.pad(v, (0, pw - w, 0, ph - h))
        out = [v]
        for _ in range(1, self.params.levels):
            out.append(F.max_pool2d(out[-1], 2))
        return out

    def _border_currents(self, levels: list[torch.Tensor]) -> np.ndarray:
        """Border-ownership currents of Eq. (3), ``V ⊙ (excitation − w · inhibition)``, as
        the border LIF holds them: one flat buffer of the levels' ``(C, 2n, h_s, w_s)``
        blocks (cell ``(c, j)``, see ``_swap``; sizes ``_bo_sizes``), from the distinct
        convolutions ``V_c * VM_j`` of each level (one input transform). The gate ``V ⊙``
        is applied by computing the cells only where ``V`` fired (elsewhere 0). The buffer
        is the layer's own, overwritten by the next call."""
        buf = self._currents
        buf.fill(0.0)
        start = 0
        for s, v in enumerate(levels):
            conv = self._vm_conv[s](v.transpose(0, 1))  # (C, 2n, h_s, w_s), a view
            cells = conv.numpy().reshape(-1, *conv.shape[-2:])
            g_exc, g_inh = self._gain[s]
            stop = start + cells[0].size * len(cells)
            _gated_border_cells(
                v[0].numpy(),
                cells,
                self._swap,
                g_exc,
                g_inh,
                buf[start:stop].reshape(cells.shape),
                self._on,
            )
            start = stop
        return buf

    @torch.no_grad()
    def step(self, oms_map: np.ndarray | torch.Tensor) -> ProtoObjectOutput:
        """Advance one step with the OMS map ``(2, H, W)``; returns the saliency."""
        x = self._input(oms_map, "oms_map")
        h, w = x.shape[1:]
        currents = self._border_currents(self._levels(x))
        spikes = torch.from_numpy(lif_step(self.border_lif, currents)[0])
        # Grouping currents, Eq. (4), pooled over orientations and levels.
        group = torch.zeros(1, 4, *self._padded)
        for s, b in enumerate(torch.split(spikes, self._bo_sizes)):
            hs, ws = self._level_shapes[s]
            # B_j = the spikes of both lines of Eq. (3) (one line when streamlined)
            b = b.reshape(-1, self.bank.shape[0], hs, ws).sum(dim=0, keepdim=True)
            g = self._g_conv[s](b)
            if s:
                g = F.interpolate(g, scale_factor=2**s, mode="bilinear", align_corners=False)
            group += g
        g_spikes = torch.from_numpy(lif_step(self.grouping_lif, group[:, :, :h, :w].numpy())[0])
        saliency = (g_spikes[0] - g_spikes[1]) + (g_spikes[2] - g_spikes[3])
        self._saliency = saliency
        return ProtoObjectOutput(saliency=saliency, grouping=g_spikes)

    def argmax(self) -> tuple[int, int] | None:
        """``P(x, y)`` of Eq. (5) on the last saliency map, pixel coordinates (x right,
        y down, origin top left); None before a step or when nothing is salient (> 0)."""
        if self._saliency is None:
            return None
        return saliency_argmax(self._saliency)
