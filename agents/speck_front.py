"""The attention front end shaped for Speck's cores: one quantised sinabs network for the
simulation and the chip (issue 35, item 3).

The paper-literal sOMS (LIF neurons, 8 px kernels, 128×128 output, global
normalisation, event gating) does not fit Speck (:mod:`agents.speck_limits`). This
front end keeps the pipeline's three stages and what Speck offers, on 3 of its 9
cores (conv → IAF each)::

    events (2, 128, 128) ─► centre–surround (DoG)  9 px, stride 2   ─► (2, 64, 64)
                         ─► border ownership        15 px, 8 dirs   ─► (8, 64, 64)
                         ─► grouping (saliency)     15 px           ─► (1, 64, 64)

* **Centre–surround** (the sOMS's job): per polarity, ``centre − surround`` with the
  centre a Gaussian of ``sigma_c`` scaled to a peak of 1 (one event under the centre is
  one threshold's worth, as :class:`agents.soms.SOMSParams`' ``kernel_norm="peak"``) and
  the surround a Gaussian of ``sigma_s`` scaled to the *same sum* as the centre, so a
  uniform event field (ego-motion over an even texture) drives nothing and a patch
  denser than its surround drives the cells. IAF replaces the global norm of Eq. (1):
  Speck has no map-wide operation, so the threshold is local and fixed.
* **Border ownership**, Eq. (3) of the paper as one linear sum (both polarity lines
  together, :mod:`agents.proto_object`): ``B_j = (V+ + V−) * (VM_j − w VM_j+π)``, the
  von Mises kernels at ``R0 = r0`` (the paper's 8 px at half resolution) cut to
  ``bo_kernel_px``; the gate ``V ⊙`` as a coincidence (a core cannot multiply two
  maps: a strong centre tap ``gate`` and a threshold to match, :class:`SpeckFrontParams`)
  and zero padding (Speck pads with zeros; padding 7 keeps the 64×64 grid).
* **Grouping**, Eqs. (4)–(5) folded into one population:
  ``(G1 − G1*) + (G2 − G2*) = Σ_j B_j · (VM_j − VM_j+π)`` (``·`` a true convolution),
  so one IAF channel spikes where the saliency is positive; the host sums its spikes
  over the fixation window and takes the argmax (Speck's readout holds ≤ 16 classes).

**Quantisation.** Each layer's float weights ``W`` are scaled by one factor
``s = min(127 / max W⁺, 128 / max W⁻)`` (the int8 range; the extreme weight lands on
127 or −128, so sinabs' own ``discretize`` finds a scale of exactly 1 and leaves the
model as it is) and rounded; the layer's threshold is ``round(threshold · s)`` (one
per layer), its lower bound ``−threshold`` (``threshold_low`` 0 is a known chip bug),
and its leak a per-channel bias ``−round(threshold_int · dt / (2 tau))``: the linear
drain equal to what an LIF of time constant ``tau`` loses in a step of ``dt``, averaged
over membranes spread evenly between 0 and the threshold (``v · dt / tau`` at ``v``).
Speck adds the bias every slow-clock tick; the simulation adds it every step of ``dt``.
A leak beyond the int8 bias range is refused (a shorter step fits).
:func:`quantisation_report` gives each layer's scale, relative L1 error and how many
excitatory taps round to 0.

**Time.** The simulation steps the network once per step of ``dt`` on the step's event
counts, and an IAF layer emits as many spikes as its membrane holds thresholds
(sinabs' ``MultiSpike``, subtractive reset); the chip updates on every event and a
neuron spikes at most once per input event, so where one event drives a membrane past
two thresholds the chip spikes once and keeps the rest for the next event, the
simulation spikes twice in the step.

**The sensor grid.** Output ``(i, j)`` of the stride-2 layer is centred on sensor
pixel ``(2i, 2j)`` (the 9 px kernel, padding 4) and stands for the 2×2 block
``[2i, 2i + 1] × [2j, 2j + 1]``: a 64×64 map goes to 128×128 by repeating each value
2×2 (:func:`to_sensor_grid`), never by interpolation; the argmax of a lone maximum
lands on the block's top-left pixel, the kernel's centre. The OMS map of a step (for
the agent's suppression counters) is the DoG spikes on that grid: an event is kept
when its block's cell of its polarity spiked.

Examples:
    >>> import numpy as np
    >>> front = SpeckFront(SpeckFrontParams())
    >>> out = front.step(np.zeros((2, 128, 128), np.float32))
    >>> tuple(out.grouping.shape), tuple(out.border.shape), out.oms.shape, int(out.oms.sum())
    ((1, 64, 64), (8, 64, 64), (2, 128, 128), 0)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import sinabs.layers as sl
import torch
from torch import nn

from agents.kernels import gaussian_kernel, von_mises_kernel
from agents.pipeline import PipelineBase
from agents.proto_object import saliency_argmax
from agents.speck_limits import SpeckLimits, conv_out, signed_range
from wander_env.config import check_fields
from wander_env.readout import SPECK_DVS_SIZE

__all__ = [
    "INT8_RANGE",
    "FrontEndPipeline",
    "LayerQuantisation",
    "SpeckFront",
    "SpeckFrontOutput",
    "SpeckFrontParams",
    "SpeckPipeline",
    "border_ownership_weights",
    "build_front",
    "dog_weights",
    "grouping_weights",
    "int8_scale",
    "quantisation_report",
    "to_sensor_grid",
]

#: Speck's weight range (8-bit two's complement).
INT8_RANGE = signed_range(SpeckLimits().weight_bits)


@dataclass(frozen=True)
class SpeckFrontParams:
    """Parameters of the Speck-shaped front end; each default with its reason.

    - ``width_px``, ``height_px`` 128: Speck's pixel array (the input limit, 128×128).
    - ``dog_kernel_px`` 9, ``dog_stride`` 2: odd so the kernel centres on a pixel;
      stride 2 brings 128×128 to Speck's 64×64 output limit, and 9 px with padding 4 gives
      exactly 64 (issue 35's sketch).
    - ``sigma_c`` 1 px: the paper's centre. ``sigma_s`` 2 px: the paper's 4 px surround
      would be cut to a flat square by a 9 px kernel; 2 px keeps a Gaussian falling to
      e⁻² at the kernel's edge (Speck allows 16 px, but a larger stride-2 kernel buys
      nothing the border-ownership stage's 15 px fields do not already pool).
    - ``dog_threshold`` 1: one event under the centre pixel is 0.75 of it (the balanced
      surround takes a quarter), so a lone noise event does not fire and two do (the
      paper's threshold of 1 with peak-scaled kernels).
    - ``dog_tau_s`` 0.02 s: the paper's sOMS τ, as the leak (module docstring).
    - ``r0`` 4 px, ``rho`` 0.2, ``w`` 3: the paper's R0 = 8 px at the half resolution,
      its ρ and inhibition weight.
    - ``orientations`` 4: the paper's 0°, 45°, 90°, 135° and their opposites, 8 directions.
    - ``bo_kernel_px`` 15: 2·7 + 1, the largest odd kernel whose 'same' padding (7) Speck
      allows; the ring R0 = 4 falls to ``1/I0(3)`` ≈ 0.2 of its peak at the edge.
    - ``gate`` 16, ``bo_threshold`` 16: Eq. (3)'s gate ``V ⊙`` as a coincidence: a core
      cannot multiply two maps, so each border-ownership cell gets ``gate`` from its own
      block's DoG spike (the kernel's centre tap) and fires once any net ring support
      adds to it; a cell whose block did not spike needs ``bo_threshold`` ≈ 7 von Mises
      peaks (``exp(ρ R0)`` ≈ 2.2) of net support. Without it (``gate`` 0, threshold 1,
      the paper's value) every cell near a contour fires and the saliency of a ring of
      radius 2 R0 peaked 7–11 px off its centre (measured on synthetic rings with 2 %
      noise); with it, on the centre. The price: the gate takes the top of the int8
      range, so more of the ring's taps round to 0 (:func:`quantisation_report`).
    - ``group_threshold`` 2: the grouping cell counts votes of unnormalised von Mises
      weight; 2 (≈ one vote at the ring's peak) halves the saturation of threshold 1
      with the same argmax on those rings.
    - ``bo_tau_s`` 0.1 s, ``group_tau_s`` 0.1 s: the paper's proto-object τ, as leaks.
    - ``dt`` 0.01 s: one step (the env's control period); sets the leak per step.
    """

    width_px: int = SPECK_DVS_SIZE[0]
    height_px: int = SPECK_DVS_SIZE[1]
    dog_kernel_px: int = 9
    dog_stride: int = 2
    sigma_c: float = 1.0
    sigma_s: float = 2.0
    dog_threshold: float = 1.0
    dog_tau_s: float = 0.02
    r0: float = 4.0
    rho: float = 0.2
    w: float = 3.0
    orientations: int = 4
    bo_kernel_px: int = 15
    gate: float = 16.0
    bo_threshold: float = 16.0
    bo_tau_s: float = 0.1
    group_threshold: float = 2.0
    group_tau_s: float = 0.1
    dt: float = 0.01

    def __post_init__(self) -> None:
        check_fields(
            self,
            ("width_px", "height_px", "dog_kernel_px", "dog_stride", "orientations"),
            integer=True,
            minimum=1,
        )
        check_fields(self, ("bo_kernel_px",), integer=True, minimum=1)
        check_fields(
            self,
            (
                "sigma_c",
                "sigma_s",
                "dog_threshold",
                "dog_tau_s",
                "r0",
                "bo_threshold",
                "bo_tau_s",
                "group_threshold",
                "group_tau_s",
                "dt",
            ),
            positive=True,
        )
        check_fields(self, ("rho", "w"), minimum=0.0)
        for name in ("dog_kernel_px", "bo_kernel_px"):
            if getattr(self, name) % 2 == 0:
                raise ValueError(
                    f"SpeckFrontParams.{name} must be odd (Speck pads symmetrically), "
                    f"got {getattr(self, name)}"
                )

    @property
    def grid(self) -> tuple[int, int]:
        """The maps' (height, width) after the stride-``dog_stride`` layer."""
        k, s, pad = self.dog_kernel_px, self.dog_stride, self.dog_kernel_px // 2
        return conv_out(self.height_px, k, s, pad), conv_out(self.width_px, k, s, pad)

    @property
    def directions_deg(self) -> tuple[float, ...]:
        """The ``2 · orientations`` directions; index ``j`` and ``j + orientations`` opposite."""
        n = self.orientations
        return tuple(180.0 * i / n for i in range(2 * n))


# -- float weights (pure) ------------------------------------------------------------------


def dog_weights(p: SpeckFrontParams) -> np.ndarray:
    """The centre–surround weights ``(2, 2, k, k)``, polarity to the same polarity:
    ``centre / max(centre) − surround · sum(centre) / (max(centre) · sum(surround))``.

    Examples:
        >>> w = dog_weights(SpeckFrontParams())
        >>> w.shape, abs(round(float(w[0, 0].sum()), 12)), float(w[0, 1].max())
        ((2, 2, 9, 9), 0.0, 0.0)
    """
    k = p.dog_kernel_px
    c = gaussian_kernel(k, p.sigma_c)
    s = gaussian_kernel(k, p.sigma_s)
    c = c / c.max()
    dog = c - s * (c.sum() / s.sum())
    w = np.zeros((2, 2, k, k))
    w[0, 0] = w[1, 1] = dog
    return w


def _bank(p: SpeckFrontParams) -> np.ndarray:
    size = p.bo_kernel_px
    return np.stack([von_mises_kernel(p.r0, p.rho, d, size) for d in p.directions_deg])


def border_ownership_weights(p: SpeckFrontParams) -> np.ndarray:
    """Eq. (3) as one sum over both polarities: ``(2n, 2, k, k)``, output ``j`` =
    ``VM_j − w VM_j+π`` from either polarity (a cross-correlation, as torch's conv), plus
    ``gate`` on the centre tap.

    Examples:
        >>> w = border_ownership_weights(SpeckFrontParams())
        >>> w.shape, bool(np.array_equal(w[:, 0], w[:, 1]))
        ((8, 2, 15, 15), True)
    """
    bank = _bank(p)
    m = len(bank)
    opp = [(j + m // 2) % m for j in range(m)]
    cell = bank - p.w * bank[opp]
    c = p.bo_kernel_px // 2
    cell[:, c, c] += p.gate
    return np.repeat(cell[:, None], 2, axis=1)


def grouping_weights(p: SpeckFrontParams) -> np.ndarray:
    """Eqs. (4)–(5) in one channel: ``(1, 2n, k, k)``, input ``j`` weighted by
    ``VM_j − VM_j+π`` used as a true convolution (the kernel flipped for torch's
    cross-correlation): border-ownership spikes vote for the pixel ``R0`` further along
    their direction.

    Examples:
        >>> w = grouping_weights(SpeckFrontParams())
        >>> w.shape, abs(round(float(w.sum()), 9))
        ((1, 8, 15, 15), 0.0)
    """
    bank = _bank(p)
    m = len(bank)
    opp = [(j + m // 2) % m for j in range(m)]
    vote = bank - bank[opp]
    return np.flip(vote, axis=(-2, -1))[None].copy()


# -- quantisation (pure) -------------------------------------------------------------------


def int8_scale(weights: np.ndarray) -> float:
    """The one factor that maps ``weights`` onto Speck's int8 range with the extreme
    weight on 127 or −128: ``min(127 / max w⁺, 128 / max w⁻)``.

    Examples:
        >>> int8_scale(np.array([0.5, -1.0])), int8_scale(np.array([1.0, -0.25]))
        (128.0, 127.0)
    """
    hi = float(np.max(weights, initial=0.0))
    lo = float(-np.min(weights, initial=0.0))
    scales = [INT8_RANGE[1] / hi] if hi > 0 else []
    scales += [-INT8_RANGE[0] / lo] if lo > 0 else []
    if not scales:
        raise ValueError("weights are all zero: no int8 scale")
    return min(scales)


@dataclass(frozen=True)
class LayerQuantisation:
    """One layer quantised: ``weight`` (int-valued float64), ``threshold`` and ``bias``
    (per output channel) in the same integer units; ``scale`` integer units per float
    unit; ``rel_l1_error`` ``Σ|W_int / scale − W| / Σ|W|``; ``excitatory_taps`` the
    positive float weights and ``excitatory_zeros`` how many of them round to 0;
    ``levels`` the largest integer weight of the excitation."""

    name: str
    weight: np.ndarray
    threshold: int
    bias: np.ndarray
    scale: float
    rel_l1_error: float
    excitatory_taps: int
    excitatory_zeros: int
    levels: int


def quantise_layer(
    name: str, weights: np.ndarray, threshold: float, tau_s: float, dt: float
) -> LayerQuantisation:
    """Quantise one layer (module docstring): int8 weights by :func:`int8_scale`, the
    threshold in the same units, the leak as a per-channel bias.

    Examples:
        >>> q = quantise_layer("x", np.array([[[[1.0, -0.5, 0.001]]]]), 1.0, 0.1, 0.01)
        >>> q.weight.tolist(), q.threshold, q.bias.tolist(), q.excitatory_zeros
        ([[[[127.0, -64.0, 0.0]]]], 127, [-6.0], 1)
    """
    s = int8_scale(weights)
    wq = np.round(weights * s)
    thr = round(threshold * s)
    if not 1 <= thr <= 2**15 - 1:
        raise ValueError(f"{name}: threshold {threshold} × scale {s:g} = {thr} leaves 16 bits")
    leak = round(thr * dt / (2.0 * tau_s))
    if leak > -INT8_RANGE[0]:
        raise ValueError(
            f"{name}: the leak {leak} per step (threshold {thr} × dt {dt} / (2 tau {tau_s})) "
            f"exceeds the int8 bias range; use a shorter step"
        )
    exc = weights > 0
    return LayerQuantisation(
        name=name,
        weight=wq,
        threshold=thr,
        bias=np.full(weights.shape[0], -float(leak)),
        scale=s,
        rel_l1_error=float(np.abs(wq / s - weights).sum() / np.abs(weights).sum()),
        excitatory_taps=int(exc.sum()),
        excitatory_zeros=int((exc & (wq == 0)).sum()),
        levels=int(wq.max(initial=0.0)),
    )


def quantisation_report(p: SpeckFrontParams) -> list[LayerQuantisation]:
    """The three layers quantised: ``dog``, ``border``, ``grouping``.

    Examples:
        >>> [(q.name, q.threshold) for q in quantisation_report(SpeckFrontParams())][:1]
        [('dog', 172)]
    """
    return [
        quantise_layer("dog", dog_weights(p), p.dog_threshold, p.dog_tau_s, p.dt),
        quantise_layer("border", border_ownership_weights(p), p.bo_threshold, p.bo_tau_s, p.dt),
        quantise_layer("grouping", grouping_weights(p), p.group_threshold, p.group_tau_s, p.dt),
    ]


# -- the network ---------------------------------------------------------------------------


def build_front(p: SpeckFrontParams) -> nn.Sequential:
    """The quantised network in plain sinabs layers: ``Conv2d`` (int-valued weights, the
    leak as bias) → ``IAFSqueeze`` (one threshold, ``min_v_mem`` = −threshold,
    subtractive reset, batch 1) for each of the three layers; input
    ``(steps, 2, height, width)`` event counts. The object the chip gets
    (:mod:`hardware.speck_network`) and the simulation steps (:class:`SpeckFront`)."""
    layers: list[nn.Module] = []
    strides = (p.dog_stride, 1, 1)
    for q, stride in zip(quantisation_report(p), strides, strict=True):
        out_c, in_c, k, _ = q.weight.shape
        conv = nn.Conv2d(in_c, out_c, k, stride=stride, padding=k // 2, bias=True)
        with torch.no_grad():
            conv.weight.copy_(torch.from_numpy(q.weight))
            conv.bias.copy_(torch.from_numpy(q.bias))
        conv.requires_grad_(False)
        iaf = sl.IAFSqueeze(
            batch_size=1,
            spike_threshold=torch.tensor(float(q.threshold)),
            min_v_mem=-float(q.threshold),
        )
        iaf.requires_grad_(False)
        layers += [conv, iaf]
    return nn.Sequential(*layers)


def to_sensor_grid(m: np.ndarray, factor: int, height: int, width: int) -> np.ndarray:
    """A map ``(..., h, w)`` on the sensor grid ``(..., height, width)``: each value
    repeated ``factor`` × ``factor`` (output ``(i, j)`` covers the pixels
    ``[i f, (i + 1) f) × [j f, (j + 1) f)``), rows or columns beyond the sensor cut
    and a sensor beyond the map padded with zeros; never interpolated.

    Examples:
        >>> to_sensor_grid(np.array([[1, 2], [3, 4]]), 2, 4, 3).tolist()
        [[1, 1, 2], [1, 1, 2], [3, 3, 4], [3, 3, 4]]
    """
    up = np.repeat(np.repeat(m, factor, axis=-2), factor, axis=-1)
    up = up[..., :height, :width]
    ph, pw = height - up.shape[-2], width - up.shape[-1]
    if ph or pw:
        pad = [(0, 0)] * (up.ndim - 2) + [(0, ph), (0, pw)]
        up = np.pad(up, pad)
    return up


@dataclass(frozen=True, eq=False)
class SpeckFrontOutput:
    """One step's spikes on the 64×64 grid: ``dog`` ``(2, h, w)``, ``border``
    ``(2n, h, w)``, ``grouping`` ``(1, h, w)``; ``oms`` the DoG spikes on the sensor
    grid ``(2, H, W)`` as 0/1 (what the sOMS's ``step(counts).oms`` gives)."""

    dog: torch.Tensor
    border: torch.Tensor
    grouping: torch.Tensor
    factor: int
    sensor: tuple[int, int]

    @property
    def oms(self) -> np.ndarray:
        fired = (self.dog.numpy() > 0).astype(np.float32)
        return to_sensor_grid(fired, self.factor, *self.sensor)


class SpeckFront:
    """The quantised network stepped on event counts, its IAF states carried between
    steps until :meth:`reset`; :meth:`step` returns the three layers' spikes."""

    def __init__(self, params: SpeckFrontParams | None = None) -> None:
        self.params = params if params is not None else SpeckFrontParams()
        self.model = build_front(self.params)
        self._spiking = [m for m in self.model if isinstance(m, sl.IAF)]

    def reset(self) -> None:
        """Zero every membrane."""
        for layer in self._spiking:
            layer.reset_states()

    @torch.no_grad()
    def step(self, counts: np.ndarray | torch.Tensor) -> SpeckFrontOutput:
        """One step on event counts ``(2, H, W)``."""
        p = self.params
        x = torch.as_tensor(counts, dtype=torch.float32)
        if tuple(x.shape) != (2, p.height_px, p.width_px):
            raise ValueError(
                f"event counts must be (2, {p.height_px}, {p.width_px}), got {tuple(x.shape)}"
            )
        x = x[None]
        out = []
        for module in self.model:
            x = module(x)
            if isinstance(module, sl.IAF):
                out.append(x[0])
        return SpeckFrontOutput(*out, p.dog_stride, (p.height_px, p.width_px))


class FrontEndPipeline(PipelineBase):
    """The pipeline interface around a Speck-shaped front end, wherever it runs: a
    subclass gives :meth:`spikes` (the DoG and grouping spikes of one step on the 64×64
    grid); :meth:`oms_step` returns the DoG spikes on the sensor grid and sums the
    grouping spikes until :meth:`saliency_of`, which returns that sum on the sensor
    grid (the monitored layer read by the host; its argument, the window's OMS map, is
    what the front end's own first layer already fed it). ``dt_s`` is accepted and
    unused: the leak is a fixed bias per step (per slow-clock tick on the chip)."""

    def __init__(self, params: SpeckFrontParams) -> None:
        self.params = params
        self._acc = np.zeros((1, *params.grid), np.float32)
        self._last_saliency: torch.Tensor | None = None

    def spikes(self, event_counts: np.ndarray | torch.Tensor) -> tuple[np.ndarray, np.ndarray]:
        """The DoG ``(2, h, w)`` and grouping ``(1, h, w)`` spikes of one step."""
        raise NotImplementedError(f"{type(self).__name__} defines no spikes")

    def reset(self) -> None:
        self._acc[:] = 0.0
        self._last_saliency = None

    def _on_sensor(self, m: np.ndarray) -> np.ndarray:
        p = self.params
        return to_sensor_grid(m, p.dog_stride, p.height_px, p.width_px)

    def oms_step(
        self, event_counts: np.ndarray | torch.Tensor, dt_s: float | None = None
    ) -> torch.Tensor:
        dog, group = self.spikes(event_counts)
        self._acc += group
        return torch.from_numpy(self._on_sensor((dog > 0).astype(np.float32)))

    def saliency_of(
        self, oms_map: np.ndarray | torch.Tensor, dt_s: float | None = None
    ) -> torch.Tensor:
        sal = self._on_sensor(self._acc[0])
        self._acc[:] = 0.0
        self._last_saliency = torch.from_numpy(np.ascontiguousarray(sal))
        return self._last_saliency

    def argmax(self) -> tuple[int, int] | None:
        if self._last_saliency is None:
            return None
        return saliency_argmax(self._last_saliency)


class SpeckPipeline(FrontEndPipeline):
    """The front end simulated (:class:`SpeckFront`) as the agent's pipeline
    (``AgentParams(soms=SpeckFrontParams())``): every env step runs the whole network,
    as the chip runs on every event."""

    def __init__(self, params: SpeckFrontParams | None = None) -> None:
        self.front = SpeckFront(params)
        super().__init__(self.front.params)
        self.soms = self.front
        self.proto = None

    def reset(self) -> None:
        self.front.reset()
        super().reset()

    def spikes(self, event_counts: np.ndarray | torch.Tensor) -> tuple[np.ndarray, np.ndarray]:
        out = self.front.step(event_counts)
        return out.dog.numpy(), out.grouping.numpy()
