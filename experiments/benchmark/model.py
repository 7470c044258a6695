"""The model the benchmarks stream: sOMS → saliency, as one :class:`BenchmarkModel`.

Both the real-data benchmarks (``wander benchmark``) and the simulated detection
experiment (:mod:`experiments.paper.detection`) score this one model. Each call of
:meth:`SOMSSaliencyModel.process` takes the per-polarity event counts of one step
``(2, H, W)`` and its length ``dt_s`` and runs one step of :class:`agents.soms.SOMS`;
its OMS map (both polarities) then makes the saliency map, by one of two routes:

- ``saliency="proto"`` (the paper's pipeline): one step of
  :class:`agents.proto_object.ProtoObjectSaliency`, ``(G1 − G1*) + (G2 − G2*)`` in
  spike counts;
- ``saliency="oms_density"`` (the paper's "need for proto-object" baseline): the OMS
  map's local density, the sum over polarities smoothed by a Gaussian of
  ``density_sigma_px`` (zero outside the sensor).

It returns, on the sensor grid:

- ``oms`` — bool ``(H, W)``: pixels where the OMS map fired in either polarity;
- ``oms_polarity`` — bool ``(2, H, W)``: the OMS map per polarity (0 = OFF, 1 = ON);
- ``saliency`` — float ``(H, W)``;
- ``point_xy`` — the saliency argmax ``P(x, y)`` (``None`` when nothing is salient).

**Step length.** The LIF time constants are given to sinabs in steps (``tau / dt``).
The nominal ``dt`` is the parameters' ``dt`` (for the real data, the dataset's window:
:func:`nominal_dt_s`); a call whose
``dt_s`` differs (a shorter gap-filling step, an uneven EVIMO window) sets every LIF
layer's ``tau_mem`` to ``tau / dt_s`` for that step, keeping the membranes, so the decay
per call is always ``exp(−dt_s / tau)`` (``follow_dt=False`` keeps the nominal one).

The model is deterministic: it draws no random numbers, so there is no seed.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np
import torch
from scipy.ndimage import gaussian_filter

from agents.proto_object import ProtoObjectParams, ProtoObjectSaliency, saliency_argmax
from agents.soms import SOMS, SOMSParams, tau_steps
from experiments.benchmark.datasets.base import MaskWindow

__all__ = ["ModelConfig", "OMSSaliencyMaps", "SOMSSaliencyModel", "Saliency", "nominal_dt_s"]

Saliency = Literal["proto", "oms_density"]


def nominal_dt_s(windows: Sequence[MaskWindow]) -> float:
    """The median window length of ``windows`` in seconds (the model's nominal step).

    >>> from experiments.benchmark.datasets.base import MaskWindow
    >>> m = np.ones((2, 2), np.uint8)
    >>> nominal_dt_s([MaskWindow(0, 5000, m), MaskWindow(5000, 10000, m)])
    0.005
    """
    if not windows:
        raise ValueError("no windows: cannot take the step length from the dataset")
    lengths = [w.t_end_us - w.t_start_us for w in windows]
    return float(np.median(lengths)) / 1e6


@dataclass(frozen=True)
class ModelConfig:
    """Parameters of the benchmark model (paper defaults otherwise).

    ``dt`` is the nominal step in seconds (the dataset's window); ``streamlined`` runs
    the proto-object stage on ``V = V+ ∨ V−`` (the paper's streamlined model) instead of
    splitting the polarities; ``alpha`` is the sOMS threshold; ``soms_conv`` and
    ``proto_conv`` pick direct or FFT convolution (same result); ``follow_dt`` lets each
    call's ``dt_s`` set the LIF decay (module docstring).
    """

    dt: float = 0.005
    streamlined: bool = False
    alpha: float = 0.80
    soms_conv: Literal["direct", "fft"] = "direct"
    proto_conv: Literal["direct", "fft"] = "fft"
    follow_dt: bool = True

    def __post_init__(self) -> None:
        if not (self.dt > 0 and math.isfinite(self.dt)):
            raise ValueError(f"ModelConfig.dt must be a positive number of seconds, got {self.dt}")

    def soms_params(self) -> SOMSParams:
        """The :class:`SOMSParams` of this config."""
        return SOMSParams(dt=self.dt, alpha=self.alpha, conv=self.soms_conv)

    def proto_params(self) -> ProtoObjectParams:
        """The :class:`ProtoObjectParams` of this config."""
        return ProtoObjectParams(
            dt=self.dt, polarity_split=not self.streamlined, conv=self.proto_conv
        )


@dataclass(frozen=True, eq=False)
class OMSSaliencyMaps:
    """What :meth:`SOMSSaliencyModel.process` returns (a ``MapsLike``)."""

    oms: np.ndarray
    oms_polarity: np.ndarray
    saliency: np.ndarray
    point_xy: tuple[float, float] | None


def _set_tau_steps(layer: torch.nn.Module, steps: float) -> None:
    """Set a sinabs LIF layer's ``tau_mem`` (in steps) in place, keeping its state."""
    tau = getattr(layer, "tau_mem", None)
    if not isinstance(tau, torch.Tensor):
        raise TypeError(f"{type(layer).__name__} has no tensor tau_mem to set")
    with torch.no_grad():
        tau.fill_(steps)


class SOMSSaliencyModel:
    """sOMS → saliency behind the benchmark's ``reset``/``process`` interface.

    ``soms`` and ``proto`` are the components' full parameter blocks (their ``dt`` is
    the nominal step and must agree); ``saliency`` picks the proto-object stage or the
    OMS-density baseline (module docstring); ``follow_dt`` lets each call's ``dt_s`` set
    the LIF decay. :meth:`from_config` builds it from a :class:`ModelConfig`.

    Example:
        >>> model = SOMSSaliencyModel.from_config(ModelConfig(dt=0.01))
        >>> maps = model.process(np.zeros((2, 32, 32), np.float32), 0.01)
        >>> maps.oms.shape, maps.saliency.shape, maps.point_xy
        ((32, 32), (32, 32), None)
    """

    def __init__(
        self,
        soms: SOMSParams | None = None,
        proto: ProtoObjectParams | None = None,
        *,
        saliency: Saliency = "proto",
        density_sigma_px: float = 2.0,
        follow_dt: bool = True,
    ) -> None:
        soms = soms if soms is not None else SOMSParams()
        proto = proto if proto is not None else ProtoObjectParams(dt=soms.dt)
        if saliency not in ("proto", "oms_density"):
            raise ValueError(f"saliency must be 'proto' or 'oms_density', got {saliency!r}")
        if saliency == "proto" and not math.isclose(soms.dt, proto.dt, rel_tol=1e-9):
            raise ValueError(
                f"the sOMS and proto-object steps differ: SOMSParams.dt={soms.dt}, "
                f"ProtoObjectParams.dt={proto.dt}; the model steps both together"
            )
        if not (density_sigma_px > 0 and math.isfinite(density_sigma_px)):
            raise ValueError(f"density_sigma_px must be a number > 0, got {density_sigma_px}")
        self.saliency = saliency
        self.density_sigma_px = float(density_sigma_px)
        self.follow_dt = follow_dt
        self.nominal_dt = soms.dt
        self.soms = SOMS(soms)
        self.proto = ProtoObjectSaliency(proto) if saliency == "proto" else None
        self._dt = self.nominal_dt

    @classmethod
    def from_config(cls, config: ModelConfig | None = None) -> SOMSSaliencyModel:
        """The model of a :class:`ModelConfig` (the paper's pipeline, as ``wander benchmark``
        runs it)."""
        config = config or ModelConfig()
        return cls(config.soms_params(), config.proto_params(), follow_dt=config.follow_dt)

    def _layers(self) -> tuple[tuple[torch.nn.Module, float], ...]:
        layers = [(self.soms.lif, self.soms.params.tau_mem)]
        if self.proto is not None:
            tau = self.proto.params.tau_mem
            layers += [(self.proto.border_lif, tau), (self.proto.grouping_lif, tau)]
        return tuple(layers)

    def _use_dt(self, dt_s: float) -> None:
        if math.isclose(dt_s, self._dt, rel_tol=1e-9, abs_tol=0.0):
            return
        for layer, tau in self._layers():
            _set_tau_steps(layer, tau_steps(tau, dt_s))
        self._dt = dt_s

    @property
    def dt(self) -> float:
        """The step length (s) the LIF layers currently decay with."""
        return self._dt

    def reset(self) -> None:
        """Zero every membrane and go back to the nominal step."""
        self.soms.reset()
        if self.proto is not None:
            self.proto.reset()
        self._use_dt(self.nominal_dt)

    def process(self, event_counts: np.ndarray, dt_s: float) -> OMSSaliencyMaps:
        """One step on the event counts ``(2, H, W)`` of ``dt_s`` seconds."""
        counts = np.asarray(event_counts)
        if counts.ndim != 3 or counts.shape[0] != 2:
            raise ValueError(f"event_counts must be (2, H, W), got shape {counts.shape}")
        if not (dt_s > 0 and math.isfinite(dt_s)):
            raise ValueError(f"dt_s must be a positive number of seconds, got {dt_s}")
        if self.follow_dt:
            self._use_dt(float(dt_s))
        oms = self.soms.step(counts).oms
        if self.proto is not None:
            sal = self.proto.step(oms).saliency
        else:
            dens = gaussian_filter(oms.numpy().sum(axis=0), self.density_sigma_px, mode="constant")
            sal = torch.from_numpy(np.asarray(dens, np.float32))
        point = saliency_argmax(sal)
        oms_pol = oms.numpy() > 0
        return OMSSaliencyMaps(
            oms=oms_pol.any(axis=0),
            oms_polarity=oms_pol,
            saliency=sal.numpy().astype(np.float32),
            point_xy=None if point is None else (float(point[0]), float(point[1])),
        )
