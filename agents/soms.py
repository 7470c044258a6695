"""Spiking object-motion sensitivity (sOMS): the first visual stage of the agent.

The paper's §Methods "Spiking Object Motion Sensitivity (sOMS) model": two parallel
pathways, *centre* and *surround*, each a convolution with a Gaussian kernel (8 px,
``sigma_c = 1``, ``sigma_s = 4``, ``mu = (0, 0)``) followed by a layer of sinabs LIF
neurons (``tau = 0.02 s``); then Eq. (1) of the paper (``eq:OMSmap``)::

    OMS_map = center(Events_map) - surround(Events_map)
    OMS_map = Events_map [ 1 - norm(OMS_map) >= alpha ]

Design decisions (each checked against the paper and its public code):

* **LIF input and output.** Each pathway's LIF receives the convolution of the event
  counts (a current: every event adds its kernel weight to the membrane) and the
  pathway's map is the LIF's *spike output* (sinabs ``MultiSpike`` counts per step), as
  in the paper's sCNN (Conv -> LIF -> "intermediate maps"). ``norm_input=False``: the
  membrane obeys ``v <- exp(-dt/tau) v + I``, so with ``I`` = events in the step the
  membrane tracks the event *rate* times ``tau`` whatever the step length ``dt``;
  ``tau_mem`` is given to sinabs in steps, ``tau / dt`` (sinabs counts time in steps;
  the public code passed 0.02 as steps, i.e. no memory at all).
* **Kernel weights.** The Gaussians are scaled to a peak of 1 (``kernel_norm="peak"``,
  as the public code, which scales them to [0, 1]), so one event under the centre
  pixel is one threshold's worth of current and the surround carries ≈5.6× the centre's
  mass. With unit-sum kernels (``"sum"``) the centre wins at every event pixel and
  Eq. (1) suppresses everything: the surround must dominate.
* **norm.** Min-max over the whole map, both polarities together (the public code):
  ``norm(d) = (d - min d) / (max d - min d)``; a flat map (``max == min``, e.g. no events)
  fires nothing. So ``1 - norm(d) >= alpha`` keeps the events where the surround exceeds
  the centre by at least ``alpha`` of the map's range: the densest moving texture, which
  is why the paper's sOMS fails when the background moves faster than the object.
  Consequences, measured on synthetic maps: an object whose texture moves *faster* than
  the background stands out (≈30× the background's OMS density), one moving the other way
  at the *same* speed does not, and a perfectly uniform stimulus (an ideal grating over the
  whole field) is not suppressed, as the threshold is relative to the map's own range.
* **Input-dependent threshold** (``norm="quantile"``, the agent's default): min-max
  normalisation lets a fixed share of events through whatever the stimulus, so no α
  suppresses ego-motion on textured scenes and keeps the object's events too (the
  stimulus family of :mod:`experiments.paper.oms_stimuli`). The quantile norm pools the
  surround excess (Gaussian, σ 6 px) and divides it by the map's own peak clipped to
  [2, 3.5] × its 90th percentile (``peak_ratio``, ``gain``; :func:`peak_score`): a map
  whose peak does not stand out from the bulk by 2× (global ego-motion) keeps nothing,
  one whose peak does keeps the events within α of it, and one far above the bulk keeps
  what exceeds 2.8× the bulk. Without ``peak_ratio`` the divisor is ``gain`` × the
  quantile (:func:`quantile_score`). Chosen on the even-seed half of the family,
  scored on the odd half (``wander experiment oms_scorecard``).
* **Signed difference** kept (``diff``), as the paper stresses.
* **Sensor grid.** 'same' convolution with zero padding (torch's alignment: for the
  even 8 px kernel the centre sits half a pixel down-right of the output pixel); the
  public code's valid convolution + bilinear stretch is not repeated.
* Polarity channels keep the input order (``wander_env.events.to_frame``: 0 = OFF,
  1 = ON); each polarity is filtered separately.

Examples:
    >>> import numpy as np
    >>> soms = SOMS(SOMSParams(dt=0.01))
    >>> ev = np.zeros((2, 32, 32), np.float32)
    >>> ev[1, 8:24, 8:24] = 1.0          # a dense patch of ON events ...
    >>> ev[1, 2, ::4] = 1.0              # ... and a sparse row of them
    >>> out = soms.step(ev)
    >>> tuple(out.oms.shape), bool(out.oms[1, 16, 16]), bool(out.oms[1, 2, 4])
    ((2, 32, 32), True, False)
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, ClassVar, Generic, Literal, TypeVar

import numba
import numpy as np
import sinabs.layers as sl
import torch
import torch.nn.functional as F

from agents.kernels import SeparableConv2d, gaussian_kernel, gaussian_kernel_1d
from wander_env.config import check_fields

__all__ = [
    "MAX_KERNEL_PX",
    "SOMS",
    "TABLE_FIELDS",
    "MapLayer",
    "SOMSOutput",
    "SOMSParams",
    "centre_surround_factors",
    "lif_layer",
    "lif_step",
    "oms_map",
    "oms_score",
    "peak_scale",
    "peak_score",
    "pooling_weights",
    "quantile_score",
    "tau_steps",
]


def tau_steps(tau_s: float, dt_s: float) -> float:
    """A time constant in simulation steps: ``tau / dt`` (sinabs counts time in steps).

    Examples:
        >>> tau_steps(0.02, 0.01)
        2.0
    """
    if tau_s <= 0 or dt_s <= 0:
        raise ValueError(f"tau and dt must be > 0, got tau={tau_s}, dt={dt_s}")
    return tau_s / dt_s


def lif_layer(tau_s: float, dt_s: float, spike_threshold: float = 1.0) -> sl.LIF:
    """A sinabs ``LIF`` layer (input ``(batch, time, ...)``) with ``tau_mem`` in steps,
    ``MultiSpike``, subtractive reset, ``norm_input=False``, no gradients.

    Examples:
        >>> lif = lif_layer(0.02, 0.01)
        >>> round(float(lif.alpha_mem_calculated), 4)  # exp(-dt / tau)
        0.6065
    """
    layer = sl.LIF(
        tau_mem=tau_steps(tau_s, dt_s),
        spike_threshold=torch.tensor(float(spike_threshold)),
        norm_input=False,
    )
    layer.requires_grad_(False)
    return layer


def lif_step(layer: sl.LIF, current: np.ndarray) -> np.ndarray:
    """One time step of a :func:`lif_layer` on its own state (NumPy arrays): the membrane
    ``v <- alpha v + I`` (float32, ``alpha`` the layer's ``alpha_mem_calculated``), the
    ``MultiSpike`` count ``trunc(v / threshold)`` where ``v > 0``, the subtractive reset.
    The same float32 operations as the layer's forward on ``current[None, None]`` in one
    compiled pass (:func:`_lif_kernel`), so the spikes and membrane are bit for bit its
    own, without torch's per-call overhead on small maps. ``current`` has the state's
    shape; returns the spike counts (float32).

    Examples:
        >>> lif = lif_layer(0.02, 0.01)
        >>> lif.init_state_with_shape((1, 3))
        >>> lif_step(lif, np.array([[0.5, 1.5, 2.25]], np.float32)).tolist()
        [[0.0, 1.0, 2.0]]
        >>> lif.v_mem.tolist()
        [[0.5, 0.5, 0.25]]
    """
    v = layer.v_mem.numpy()  # the state's memory: updated in place
    i = np.ascontiguousarray(current, dtype=np.float32)
    if i.shape not in (v.shape, v.shape[1:]):
        raise ValueError(f"current has shape {i.shape}, the LIF state {v.shape}")
    spikes = np.empty_like(v)
    _lif_kernel(
        v.reshape(-1),
        i.reshape(-1),
        np.float32(layer.alpha_mem_calculated.item()),
        np.float32(layer.spike_threshold.item()),
        spikes.reshape(-1),
    )
    return spikes


@numba.njit(cache=True, nogil=True)
def _lif_kernel(
    v: np.ndarray, current: np.ndarray, alpha: np.float32, threshold: np.float32, out: np.ndarray
) -> None:
    """:func:`lif_step` on flat float32 arrays, in place on ``v``: per neuron the
    operations of sinabs' forward in its order (no contraction into a fused
    multiply-add: numba compiles without ``fastmath``)."""
    zero = np.float32(0.0)
    for k in range(v.size):
        vk = v[k] * alpha + current[k]
        s = np.trunc(vk / threshold) if vk > zero else zero
        out[k] = s
        v[k] = vk - s * threshold


_Params = TypeVar("_Params")


class MapLayer(Generic[_Params]):
    """Base of a stateful spiking layer stepped on ``(2, H, W)`` maps whose ``params``
    (a ``params_type``) have ``dt`` and ``tau_mem`` (seconds): ``_setup()`` makes what
    does not depend on the map size, ``_build(h, w)`` the state for one map size, at
    construction when ``height`` and ``width`` are given, else at the first step
    (``SOMS`` and ``ProtoObjectSaliency``)."""

    params_type: ClassVar[type[Any]]
    params: _Params
    _shape: tuple[int, int] | None

    def __init__(
        self,
        params: _Params | None = None,
        height: int | None = None,
        width: int | None = None,
    ) -> None:
        self.params = params or self.params_type()
        self._shape = None
        self._setup()
        if height is not None and width is not None:
            self._build(int(height), int(width))

    def _setup(self) -> None:
        """Make the size-independent parts (kernels, LIF layers); each layer defines it."""
        raise NotImplementedError(f"{type(self).__name__} defines no _setup")

    def _build(self, h: int, w: int) -> None:
        """Build (and reset) the state for maps of ``h × w``; each layer defines it."""
        raise NotImplementedError(f"{type(self).__name__} defines no _build")

    def _input(self, m: np.ndarray | torch.Tensor, name: str) -> torch.Tensor:
        """``m`` as a float32 tensor ``(2, H, W)`` (``ValueError`` naming ``name``
        otherwise); a new ``H, W`` rebuilds (and resets) the layer."""
        x = torch.as_tensor(m, dtype=torch.float32)
        if x.ndim != 3 or x.shape[0] != 2:
            raise ValueError(f"{name} must be (2, H, W), got {tuple(x.shape)}")
        h, w = int(x.shape[1]), int(x.shape[2])
        if self._shape != (h, w):
            self._build(h, w)
        return x


#: The largest sOMS kernel side (pixels): the sensor's side; a kernel beyond it sees
#: only padding.
MAX_KERNEL_PX = 128


@dataclass(frozen=True)
class SOMSParams:
    """sOMS parameters; defaults are the paper's (table "params").

    ``dt`` is the length of one step (one event map) in seconds; ``conv`` picks torch's
    ``conv2d`` (``"direct"``) or two 1-D passes of each Gaussian's factor
    (``"separable"``, ``cv2.sepFilter2D``: the same currents, several times faster at
    128×128). ``alpha`` 0.80 is the table's value.

    ``norm`` is Eq. (1)'s ``norm``: ``"minmax"`` (the paper-literal default) scales the
    map to its own range; ``"quantile"`` (the agent's, :data:`agents.attention.AGENT_SOMS`)
    makes the threshold depend on the input's statistics: ``surround − centre`` pooled by
    a unit-sum Gaussian of ``pool_sigma`` px, divided by ``gain`` × its ``quantile`` over
    the whole map (at least ``floor_spikes``) and clipped to [0, 1]; an event is kept
    where that is ``>= alpha`` (:func:`quantile_score`). With ``peak_ratio`` set (the
    agent's), the divisor is the map's own peak clipped to [``peak_ratio``, ``gain``] ×
    that quantile (:func:`peak_score`): a peak that stands out from the bulk is kept with
    the events near it even when it is not ``gain``× the bulk, and a map whose peak does
    not stand out by ``peak_ratio`` keeps nothing once ``alpha · peak_ratio > 1``.
    ``pool_sigma``, ``quantile``, ``gain``, ``floor_spikes`` and ``peak_ratio`` are unused
    by ``"minmax"``.
    """

    kernel_size: int = 8
    sigma_c: float = 1.0
    sigma_s: float = 4.0
    tau_mem: float = 0.02
    alpha: float = 0.80
    dt: float = 0.01
    spike_threshold: float = 1.0
    kernel_norm: Literal["peak", "sum"] = "peak"
    conv: Literal["direct", "separable"] = "direct"
    norm: Literal["minmax", "quantile"] = "minmax"
    pool_sigma: float = 6.0
    quantile: float = 0.9
    gain: float = 2.0
    floor_spikes: float = 1.0
    peak_ratio: float | None = None

    def __post_init__(self) -> None:
        if not 1 <= self.kernel_size <= MAX_KERNEL_PX:
            raise ValueError(f"kernel_size must be in [1, {MAX_KERNEL_PX}], got {self.kernel_size}")
        if self.norm not in ("minmax", "quantile"):
            raise ValueError(f"norm must be 'minmax' or 'quantile', got {self.norm!r}")
        check_fields(self, ("pool_sigma", "gain", "floor_spikes"), positive=True)
        pr = self.peak_ratio
        if pr is not None and not (
            isinstance(pr, (int, float)) and math.isfinite(pr) and 0 < pr <= self.gain
        ):
            raise ValueError(
                f"SOMSParams.peak_ratio must be None or a finite number in (0, gain={self.gain}]"
                f", got {pr!r}"
            )
        if not 0.0 <= self.quantile <= 1.0:
            raise ValueError(f"SOMSParams.quantile must be in [0, 1], got {self.quantile}")
        if not 0.0 <= self.alpha <= 1.0:
            raise ValueError(f"alpha must be in [0, 1], got {self.alpha}")
        if self.kernel_norm not in ("peak", "sum"):
            raise ValueError(f"kernel_norm must be 'peak' or 'sum', got {self.kernel_norm!r}")
        if self.conv not in ("direct", "separable"):
            raise ValueError(f"conv must be 'direct' or 'separable', got {self.conv!r}")
        tau_steps(self.tau_mem, self.dt)


#: The :class:`SOMSParams` fields the paper's parameter table gives (with ``dt``, the step).
TABLE_FIELDS: tuple[str, ...] = ("kernel_size", "sigma_c", "sigma_s", "tau_mem", "alpha")


@dataclass(frozen=True)
class SOMSOutput:
    """One step of the sOMS, all ``(2, H, W)`` on the sensor grid, polarity order of the
    input: ``oms`` 0/1 (the OMS map), ``diff`` centre − surround spike counts (signed),
    ``score`` ``1 − norm(diff)`` in [0, 1] (fires where ``>= alpha`` and an event occurred)."""

    oms: torch.Tensor
    diff: torch.Tensor
    score: torch.Tensor


def centre_surround_factors(params: SOMSParams) -> tuple[np.ndarray, np.ndarray]:
    """The 1-D factors ``g`` of the centre and surround kernels, ``outer(g, g)`` each
    (scaled as :func:`centre_surround_weights`: a peak of 1 or a unit sum).

    Examples:
        >>> gc, gs = centre_surround_factors(SOMSParams())
        >>> w = centre_surround_weights(SOMSParams()).numpy()
        >>> bool(np.allclose(np.outer(gs, gs), w[1, 0], atol=1e-7)), float(gc.max())
        (True, 1.0)
    """
    gc = gaussian_kernel_1d(params.kernel_size, params.sigma_c)
    gs = gaussian_kernel_1d(params.kernel_size, params.sigma_s)
    if params.kernel_norm == "peak":
        gc, gs = gc / gc.max(), gs / gs.max()
    return gc, gs


def centre_surround_weights(params: SOMSParams) -> torch.Tensor:
    """Conv weights ``(2, 1, k, k)``: output 0 the centre, 1 the surround Gaussian."""
    kc = gaussian_kernel(params.kernel_size, params.sigma_c)
    ks = gaussian_kernel(params.kernel_size, params.sigma_s)
    if params.kernel_norm == "peak":
        kc, ks = kc / kc.max(), ks / ks.max()
    return torch.from_numpy(np.stack([kc, ks])[:, None]).float()


def oms_map(counts: np.ndarray, score: np.ndarray, alpha: float) -> np.ndarray:
    """The OMS map (bool, the shape of ``counts`` ``(2, H, W)``): the pixels and
    polarities where events came in and the score ``1 - norm(OMS)`` reaches ``alpha``
    (compared in float32, the score's own precision), the paper's
    ``Events_map [1 - norm(OMS_map) >= alpha]``.

    Examples:
        >>> counts = np.array([[[1.0, 0.0, 2.0]], [[0.0, 0.0, 0.0]]], np.float32)
        >>> oms_map(counts, np.array([[[0.9, 0.9, 0.5]]], np.float32), 0.8).tolist()
        [[[True, False, False]], [[False, False, False]]]
    """
    return (np.asarray(counts) > 0) & (np.asarray(score) >= np.float32(alpha))


def oms_score(diff: torch.Tensor) -> torch.Tensor:
    """``1 - norm(diff)`` with min-max ``norm`` over the whole map; zeros if it is flat."""
    lo, hi = torch.aminmax(diff)
    rng = float(hi - lo)
    if not rng > 0.0:
        return torch.zeros_like(diff)
    return (hi - diff) / rng


def pooling_weights(sigma: float) -> torch.Tensor:
    """Unit-sum Gaussian ``(1, 1, k, k)``, ``k = 2 ceil(3 sigma) + 1``: the pooling of
    the ``"quantile"`` norm.

    Examples:
        >>> w = pooling_weights(1.0)
        >>> tuple(w.shape), round(float(w.sum()), 6)
        ((1, 1, 7, 7), 1.0)
    """
    k = 2 * math.ceil(3.0 * sigma) + 1
    return torch.from_numpy(gaussian_kernel(k, sigma)).float()[None, None]


def _quantile_linear(a: np.ndarray, q: float) -> float:
    """``float(np.quantile(a, q))`` (method "linear") of a 1-D array, bit for bit, by one
    ``np.partition`` at the two neighbours of the virtual index (np.quantile also
    partitions at the minimum and maximum and pays its general-case set-up)."""
    n = a.size
    if n == 0:
        raise ValueError("quantile of an empty map")
    v = (n - 1) * q
    lo = math.floor(v)
    hi = min(lo + 1, n - 1)
    g = v - lo
    part = np.partition(a, (lo, hi) if hi != lo else lo)
    x0, x1 = part[lo], part[hi]
    d = x1 - x0  # numpy's _lerp, in the array's dtype
    return float(x1 - d * (1 - g)) if g >= 0.5 else float(x0 + d * g)


def quantile_score(
    pooled: torch.Tensor,
    quantile: float,
    gain: float,
    floor_spikes: float,
    peak_ratio: float | None = None,
) -> torch.Tensor:
    """``1 - norm(OMS)`` of the ``"quantile"`` norm: the pooled surround excess
    ``pooled = G * (surround - centre)`` over :func:`peak_scale` of its ``quantile`` over
    the whole map (``gain`` times it, at least ``floor_spikes``; with ``peak_ratio``, the
    map's peak clipped to ``[peak_ratio, gain]`` times it), clipped to [0, 1].

    Examples:
        >>> d = torch.zeros(1, 10, 10); d[0, 0, :5] = 4.0; d[0, 1:, :] = 1.0
        >>> s = quantile_score(d, 0.9, 2.0, 1.0)   # 90th percentile 1 -> scale 2
        >>> float(s[0, 0, 0]), float(s[0, 5, 5]), float(s[0, 0, 9])
        (1.0, 0.5, 0.0)
    """
    a = pooled.detach().cpu().numpy()
    return torch.from_numpy(_quantile_score(a, quantile, gain, floor_spikes, peak_ratio))


def _quantile_score(
    a: np.ndarray, quantile: float, gain: float, floor_spikes: float, peak_ratio: float | None
) -> np.ndarray:
    """:func:`quantile_score` on a float32 array."""
    flat = a.ravel()
    # a selection (introselect) where torch.quantile sorts the map: ≈10× faster here
    q = _quantile_linear(flat, quantile)
    peak = float(flat.max(initial=0.0)) if peak_ratio is not None else 0.0
    scale = np.float32(peak_scale(q, peak, gain, peak_ratio, floor_spikes))
    return np.clip(a / scale, np.float32(0.0), np.float32(1.0))


def peak_scale(
    q: float, peak: float, gain: float, peak_ratio: float | None, floor_spikes: float
) -> float:
    """The divisor of the ``"quantile"`` norm from the map's ``quantile`` value ``q`` and
    its ``peak``: ``gain · q`` when ``peak_ratio`` is None, else the peak clipped to
    ``[peak_ratio · q, gain · q]``; at least ``floor_spikes``.

    Examples:
        >>> peak_scale(2.0, 5.0, 2.5, None, 1.0), peak_scale(2.0, 5.0, 3.5, 2.0, 1.0)
        (5.0, 5.0)
        >>> peak_scale(2.0, 9.0, 3.5, 2.0, 1.0), peak_scale(2.0, 2.2, 3.5, 2.0, 1.0)
        (7.0, 4.0)
    """
    if peak_ratio is None:
        return max(gain * q, floor_spikes)
    return max(min(max(peak, peak_ratio * q), gain * q), floor_spikes)


def peak_score(
    pooled: torch.Tensor, quantile: float, gain: float, peak_ratio: float, floor_spikes: float
) -> torch.Tensor:
    """``1 - norm(OMS)`` of the ``"quantile"`` norm with ``peak_ratio``: the pooled
    surround excess over :func:`peak_scale` of its ``quantile`` and its maximum over the
    whole map, clipped to [0, 1]. An event is kept where this is ``>= alpha``: with
    ``alpha`` 0.8, ``peak_ratio`` 2 and ``gain`` 3.5 the threshold is 0.8 × the peak
    when the peak lies between 2 and 3.5 × the quantile, 2.8 × the quantile above that,
    and above the peak (nothing kept) when the peak is below 2 × the quantile.

    Examples:
        >>> d = torch.zeros(1, 10, 10); d[0, 0, :5] = 3.0; d[0, 1:, :] = 1.0
        >>> s = peak_score(d, 0.9, 3.5, 2.0, 1.0)   # q 1, peak 3 -> scale 3
        >>> float(s[0, 0, 0]), round(float(s[0, 5, 5]), 4)
        (1.0, 0.3333)
        >>> float(peak_score(torch.ones(1, 4, 4), 0.9, 3.5, 2.0, 1.0).max())  # flat: 1 / 2
        0.5
    """
    return quantile_score(pooled, quantile, gain, floor_spikes, peak_ratio)


class SOMS(MapLayer[SOMSParams]):
    """Stateful sOMS: call :meth:`step` once per event map ``(2, H, W)`` (counts in one
    step of ``params.dt`` seconds); LIF membranes carry over between calls until
    :meth:`reset`. Any ``H, W`` works; a new size rebuilds and resets the layers.

    A step runs on NumPy views of the sinabs layer's own state (:func:`lif_step`), with the
    convolutions by ``params.conv`` (``"separable"`` also pools the ``"quantile"`` norm
    by two 1-D passes); its outputs are tensors sharing that memory.

    Examples:
        >>> import numpy as np
        >>> soms = SOMS()
        >>> out = soms.step(np.zeros((2, 128, 128), np.float32))
        >>> int(out.oms.sum())
        0
    """

    params_type = SOMSParams

    def _setup(self) -> None:
        self.weight = centre_surround_weights(self.params)
        self.lif = lif_layer(self.params.tau_mem, self.params.dt, self.params.spike_threshold)
        k = self.params.kernel_size
        self._pad = ((k - 1) // 2, k // 2, (k - 1) // 2, k // 2)  # torch 'same' alignment
        self.pool_weight = pooling_weights(self.params.pool_sigma)
        self._sep: tuple[SeparableConv2d, SeparableConv2d] | None = None
        self._pool_sep: SeparableConv2d | None = None
        if self.params.conv == "separable":
            gc, gs = centre_surround_factors(self.params)
            self._sep = (SeparableConv2d(gc, gc), SeparableConv2d(gs, gs))
            g = gaussian_kernel_1d(self.pool_weight.shape[-1], self.params.pool_sigma)
            self._pool_sep = SeparableConv2d(g, g)  # the pooling Gaussian is outer(g, g)

    @property
    def v_mem(self) -> torch.Tensor | None:
        """Membranes ``(2 polarities, 2 paths [centre, surround], H, W)``; None before a step."""
        if not self.lif.is_state_initialised():
            return None
        return self.lif.v_mem[0]

    def _build(self, h: int, w: int) -> None:
        self._shape = (h, w)
        self.lif.init_state_with_shape((1, 2, 2, h, w))

    def reset(self) -> None:
        """Zero every membrane."""
        self.lif.reset_states()

    def filter(self, x: torch.Tensor) -> torch.Tensor:
        """Centre and surround currents ``(2 polarities, 2 paths, H, W)`` of ``x (2, H, W)``."""
        if self._sep is not None:
            a = x.numpy()
            out = np.empty((a.shape[0], 2, *a.shape[1:]), np.float32)
            for path, conv in enumerate(self._sep):
                out[:, path] = conv(a)
            return torch.from_numpy(out)
        x = x.unsqueeze(1)  # polarity as batch: (2, 1, H, W)
        return F.conv2d(F.pad(x, self._pad), self.weight)

    def pool(self, x: torch.Tensor) -> torch.Tensor:
        """The pooling Gaussian applied to each polarity of ``x (2, H, W)`` (zero padding;
        ``conv="separable"``: two 1-D passes of its factor, equal to float32 rounding)."""
        if self._pool_sep is not None:
            return torch.from_numpy(self._pool_sep(x))
        return F.conv2d(x.unsqueeze(1), self.pool_weight, padding="same")[:, 0]

    def score(self, diff: torch.Tensor) -> torch.Tensor:
        """``1 - norm(diff)`` of ``params.norm`` (Eq. 1's left side before ``>= alpha``)."""
        p = self.params
        if p.norm == "minmax":
            return oms_score(diff)
        return quantile_score(self.pool(-diff), p.quantile, p.gain, p.floor_spikes, p.peak_ratio)

    @torch.no_grad()
    def excess(self, x: torch.Tensor) -> torch.Tensor:
        """Advance the LIF one step with the event counts ``x`` ``(2, H, W)`` (float32,
        checked: :meth:`step`'s input); the centre's spikes less the surround's ``(2, H,
        W)``: what :meth:`score` normalises."""
        spikes = lif_step(self.lif, self.filter(x).numpy())[0]  # (2, 2, H, W)
        return torch.from_numpy(spikes[:, 0] - spikes[:, 1])

    @torch.no_grad()
    def step(self, event_map: np.ndarray | torch.Tensor) -> SOMSOutput:
        """Advance one step with the event counts ``(2, H, W)``; returns the OMS map."""
        x = self._input(event_map, "event_map")
        diff = self.excess(x)
        score = self.score(diff)
        oms = oms_map(x.numpy(), score.numpy(), self.params.alpha)
        return SOMSOutput(oms=torch.from_numpy(oms.astype(np.float32)), diff=diff, score=score)
