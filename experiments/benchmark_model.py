"""The model the benchmark streams: sOMS → proto-object saliency, as one :class:`BenchmarkModel`.

Each call of :meth:`SOMSSaliencyModel.process` takes the per-polarity event counts of
one step ``(2, H, W)`` and its length ``dt_s``, runs one step of
:class:`agents.soms.SOMS` and feeds its OMS map (both polarities) to one step of
:class:`agents.proto_object.ProtoObjectSaliency`. It returns, on the sensor grid:

- ``oms`` — bool ``(H, W)``: pixels where the OMS map fired in either polarity;
- ``oms_polarity`` — bool ``(2, H, W)``: the OMS map per polarity (0 = OFF, 1 = ON);
- ``saliency`` — float ``(H, W)``: ``(G1 − G1*) + (G2 − G2*)`` in spike counts;
- ``point_xy`` — the saliency argmax ``P(x, y)`` (``None`` when nothing is salient).

**Step length.** The LIF time constants are given to sinabs in steps (``tau / dt``).
The nominal ``dt`` is the dataset's window (:func:`nominal_dt_s`); a call whose
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

from agents.proto_object import ProtoObjectParams, ProtoObjectSaliency
from agents.soms import SOMS, SOMSParams, tau_steps
from experiments.datasets.base import MaskWindow

__all__ = ["ModelConfig", "OMSSaliencyMaps", "SOMSSaliencyModel", "nominal_dt_s"]


def nominal_dt_s(windows: Sequence[MaskWindow]) -> float:
    """The median window length of ``windows`` in seconds (the model's nominal step).

    >>> from experiments.datasets.base import MaskWindow
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
    """sOMS → proto-object saliency behind the benchmark's ``reset``/``process`` interface.

    Example:
        >>> model = SOMSSaliencyModel(ModelConfig(dt=0.01))
        >>> maps = model.process(np.zeros((2, 32, 32), np.float32), 0.01)
        >>> maps.oms.shape, maps.saliency.shape, maps.point_xy
        ((32, 32), (32, 32), None)
    """

    def __init__(self, config: ModelConfig | None = None) -> None:
        self.config = config or ModelConfig()
        self.soms = SOMS(self.config.soms_params())
        self.proto = ProtoObjectSaliency(self.config.proto_params())
        self._dt = self.config.dt

    def _layers(self) -> tuple[tuple[torch.nn.Module, float], ...]:
        return (
            (self.soms.lif, self.soms.params.tau_mem),
            (self.proto.border_lif, self.proto.params.tau_mem),
            (self.proto.grouping_lif, self.proto.params.tau_mem),
        )

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
        self.proto.reset()
        self._use_dt(self.config.dt)

    def process(self, event_counts: np.ndarray, dt_s: float) -> OMSSaliencyMaps:
        """One step on the event counts ``(2, H, W)`` of ``dt_s`` seconds."""
        counts = np.asarray(event_counts)
        if counts.ndim != 3 or counts.shape[0] != 2:
            raise ValueError(f"event_counts must be (2, H, W), got shape {counts.shape}")
        if not (dt_s > 0 and math.isfinite(dt_s)):
            raise ValueError(f"dt_s must be a positive number of seconds, got {dt_s}")
        if self.config.follow_dt:
            self._use_dt(float(dt_s))
        out = self.soms.step(counts)
        sal = self.proto.step(out.oms)
        point = self.proto.argmax()
        oms_pol = out.oms.numpy() > 0
        return OMSSaliencyMaps(
            oms=oms_pol.any(axis=0),
            oms_polarity=oms_pol,
            saliency=sal.saliency.numpy().astype(np.float32),
            point_xy=None if point is None else (float(point[0]), float(point[1])),
        )
