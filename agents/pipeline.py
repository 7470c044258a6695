"""The one sOMS → saliency pipeline: event counts → :class:`agents.soms.SOMS` → saliency.

:class:`SaliencyPipeline` owns the two stages every user of the paper's model needs
(the agent, ``wander benchmark``, the detection experiment):

- the **sOMS** stage: per-polarity event counts ``(2, H, W)`` of one step → the OMS map
  (:meth:`SaliencyPipeline.oms_step`);
- the **saliency** stage on an OMS map (:meth:`SaliencyPipeline.saliency_of`), by one of
  two routes:

  - ``saliency="proto"`` (the paper's pipeline): one step of
    :class:`agents.proto_object.ProtoObjectSaliency`, ``(G1 − G1*) + (G2 − G2*)`` in
    spike counts;
  - ``saliency="oms_density"`` (the paper's "need for proto-object" baseline): the OMS
    map's local density, the sum over polarities smoothed by a Gaussian of
    ``density_sigma_px`` (zero outside the sensor).

:meth:`SaliencyPipeline.process` runs both stages on one step (the benchmarks' streaming
interface, ``reset``/``process``) and returns :class:`OMSSaliencyMaps` on the sensor
grid: ``oms`` (bool ``(H, W)``, either polarity fired), ``oms_polarity`` (bool
``(2, H, W)``, 0 = OFF, 1 = ON), ``saliency`` (float ``(H, W)``) and ``point_xy`` (the
saliency argmax ``P(x, y)``, ``None`` when nothing is salient). The agent instead steps
the sOMS every env step and the saliency stage once per fixation window (its own
``dt``), so the stages' nominal steps may differ (``lockstep=False``).

**Window-following step.** The LIF time constants are given to sinabs in steps
(``tau / dt``). The nominal ``dt`` of each stage is its parameters' ``dt``; a call whose
``dt_s`` differs (a shorter gap-filling step, an uneven EVIMO window) sets that stage's
LIF layers' ``tau_mem`` to ``tau / dt_s`` for the call, keeping the membranes, so the
decay per call is always ``exp(−dt_s / tau)`` (``follow_dt=False`` keeps the nominal
one). :meth:`SaliencyPipeline.reset` goes back to the nominal steps.

The pipeline is deterministic: it draws no random numbers, so there is no seed.

Examples:
    >>> pipe = SaliencyPipeline(SOMSParams(dt=0.01), ProtoObjectParams(dt=0.01))
    >>> maps = pipe.process(np.zeros((2, 32, 32), np.float32), 0.01)
    >>> maps.oms.shape, maps.saliency.shape, maps.point_xy
    ((32, 32), (32, 32), None)
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
import torch
from scipy.ndimage import gaussian_filter

from agents.proto_object import ProtoObjectParams, ProtoObjectSaliency, saliency_argmax
from agents.soms import SOMS, SOMSParams, tau_steps

__all__ = ["OMSSaliencyMaps", "PipelineBase", "Saliency", "SaliencyPipeline"]

Saliency = Literal["proto", "oms_density"]


@dataclass(frozen=True, eq=False)
class OMSSaliencyMaps:
    """What :meth:`SaliencyPipeline.process` returns (the benchmarks' ``MapsLike``)."""

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


class PipelineBase:
    """The stages' interface (:class:`SaliencyPipeline`, and
    :class:`agents.speck_front.SpeckPipeline` for the front end on Speck's cores):
    ``reset``, ``oms_step``, ``saliency_of``, ``argmax``, and :meth:`process` built on them;
    ``soms`` and ``proto`` are the stages' stepped objects where a pipeline has them
    (``None`` otherwise)."""

    soms: Any = None
    proto: Any = None

    def reset(self) -> None:
        """Zero every membrane."""
        raise NotImplementedError(f"{type(self).__name__} defines no reset")

    def oms_step(self, event_counts: np.ndarray | torch.Tensor, dt_s: float | None = None):
        """The OMS map ``(2, H, W)`` of one step of event counts ``(2, H, W)``."""
        raise NotImplementedError(f"{type(self).__name__} defines no oms_step")

    def saliency_of(
        self, oms_map: np.ndarray | torch.Tensor, dt_s: float | None = None
    ) -> torch.Tensor:
        """The saliency ``(H, W)`` of an OMS map."""
        raise NotImplementedError(f"{type(self).__name__} defines no saliency_of")

    def argmax(self) -> tuple[int, int] | None:
        """``P(x, y)`` of the last saliency map (None when nothing is salient)."""
        raise NotImplementedError(f"{type(self).__name__} defines no argmax")

    def process(self, event_counts: np.ndarray, dt_s: float) -> OMSSaliencyMaps:
        """Both stages on the event counts ``(2, H, W)`` of one step of ``dt_s`` seconds."""
        counts = np.asarray(event_counts)
        if counts.ndim != 3 or counts.shape[0] != 2:
            raise ValueError(f"event_counts must be (2, H, W), got shape {counts.shape}")
        if not (dt_s > 0 and math.isfinite(dt_s)):
            raise ValueError(f"dt_s must be a positive number of seconds, got {dt_s}")
        oms = self.oms_step(counts, float(dt_s))
        sal = self.saliency_of(oms, float(dt_s))
        point = self.argmax()
        oms_pol = oms.numpy() > 0
        return OMSSaliencyMaps(
            oms=oms_pol.any(axis=0),
            oms_polarity=oms_pol,
            saliency=sal.numpy().astype(np.float32),
            point_xy=None if point is None else (float(point[0]), float(point[1])),
        )


class SaliencyPipeline(PipelineBase):
    """sOMS → saliency (module docstring).

    ``soms`` and ``proto`` are the stages' full parameter blocks (defaults: the
    paper-literal sOMS, the proto-object stage at the sOMS's ``dt``); ``height`` and
    ``width`` pre-build the stages for a sensor (else they are built on the first map);
    ``saliency`` picks the proto-object stage or the OMS-density baseline;
    ``lockstep`` (default) requires both stages to share one nominal step, as
    :meth:`process` steps them together; ``follow_dt`` lets each call's ``dt_s`` set the
    LIF decay.
    """

    def __init__(
        self,
        soms: SOMSParams | None = None,
        proto: ProtoObjectParams | None = None,
        height: int | None = None,
        width: int | None = None,
        *,
        saliency: Saliency = "proto",
        density_sigma_px: float = 2.0,
        follow_dt: bool = True,
        lockstep: bool = True,
    ) -> None:
        soms = soms if soms is not None else SOMSParams()
        proto = proto if proto is not None else ProtoObjectParams(dt=soms.dt)
        if saliency not in ("proto", "oms_density"):
            raise ValueError(f"saliency must be 'proto' or 'oms_density', got {saliency!r}")
        if lockstep and saliency == "proto" and not math.isclose(soms.dt, proto.dt, rel_tol=1e-9):
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
        self.soms = SOMS(soms, height, width)
        self.proto = ProtoObjectSaliency(proto, height, width) if saliency == "proto" else None
        self._dt = self.nominal_dt
        self._proto_dt = proto.dt
        self._last_saliency: torch.Tensor | None = None

    # -- the window-following step -------------------------------------------------------

    def _use_dt(self, dt_s: float, proto: bool) -> None:
        if proto:
            if self.proto is None or math.isclose(dt_s, self._proto_dt, rel_tol=1e-9):
                return
            tau = self.proto.params.tau_mem
            for layer in (self.proto.border_lif, self.proto.grouping_lif):
                _set_tau_steps(layer, tau_steps(tau, dt_s))
            self._proto_dt = dt_s
            return
        if math.isclose(dt_s, self._dt, rel_tol=1e-9, abs_tol=0.0):
            return
        _set_tau_steps(self.soms.lif, tau_steps(self.soms.params.tau_mem, dt_s))
        self._dt = dt_s

    @property
    def dt(self) -> float:
        """The step length (s) the sOMS LIF layer currently decays with."""
        return self._dt

    # -- stages --------------------------------------------------------------------------

    def reset(self) -> None:
        """Zero every membrane and go back to the nominal steps."""
        self.soms.reset()
        if self.proto is not None:
            self.proto.reset()
        self._last_saliency = None
        self._use_dt(self.nominal_dt, proto=False)
        if self.proto is not None:
            self._use_dt(self.proto.params.dt, proto=True)

    def oms_step(self, event_counts: np.ndarray | torch.Tensor, dt_s: float | None = None):
        """One sOMS step on event counts ``(2, H, W)`` of ``dt_s`` seconds (None: the
        nominal step); the OMS map ``(2, H, W)`` as a float tensor."""
        if dt_s is not None and self.follow_dt:
            self._use_dt(float(dt_s), proto=False)
        return self.soms.step(event_counts).oms

    def saliency_of(
        self, oms_map: np.ndarray | torch.Tensor, dt_s: float | None = None
    ) -> torch.Tensor:
        """The saliency ``(H, W)`` of an OMS map ``(2, H, W)`` (one proto-object step of
        ``dt_s`` seconds, None: its nominal step; or the OMS density)."""
        if self.proto is not None:
            if dt_s is not None and self.follow_dt:
                self._use_dt(float(dt_s), proto=True)
            sal = self.proto.step(oms_map).saliency
        else:
            oms = oms_map.numpy() if isinstance(oms_map, torch.Tensor) else np.asarray(oms_map)
            dens = gaussian_filter(oms.sum(axis=0), self.density_sigma_px, mode="constant")
            sal = torch.from_numpy(np.asarray(dens, np.float32))
        self._last_saliency = sal
        return sal

    def argmax(self) -> tuple[int, int] | None:
        """``P(x, y)`` of the last saliency map (None before one, or when nothing is salient)."""
        if self._last_saliency is None:
            return None
        return saliency_argmax(self._last_saliency)
