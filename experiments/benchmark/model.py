"""The benchmarks' model config: :class:`ModelConfig` → :class:`agents.pipeline.SaliencyPipeline`.

Both the real-data benchmarks (``wander benchmark``) and the simulated detection
experiment (:mod:`experiments.paper.detection`) score the one sOMS → saliency pipeline of
:mod:`agents.pipeline`; this module only maps the benchmark's flags (``--streamlined``,
``--alpha``, the dataset's window as the nominal step: :func:`nominal_dt_s`) onto the
pipeline's parameter blocks.

Examples:
    >>> pipe = ModelConfig(dt=0.01).pipeline()
    >>> maps = pipe.process(np.zeros((2, 32, 32), np.float32), 0.01)
    >>> maps.oms.shape, maps.saliency.shape, maps.point_xy
    ((32, 32), (32, 32), None)
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np

from agents.pipeline import SaliencyPipeline
from agents.proto_object import ProtoObjectParams
from agents.soms import SOMSParams
from experiments.benchmark.datasets.base import MaskWindow

__all__ = ["ModelConfig", "nominal_dt_s"]


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
    splitting the polarities; ``alpha`` is the sOMS threshold; ``soms_conv`` picks
    the sOMS's direct or separable convolution and ``proto_conv`` the proto-object's
    direct or FFT one (same results); ``follow_dt`` lets each
    call's ``dt_s`` set the LIF decay (module docstring).
    """

    dt: float = 0.005
    streamlined: bool = False
    alpha: float = 0.80
    soms_conv: Literal["direct", "separable"] = "direct"
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

    def pipeline(self) -> SaliencyPipeline:
        """The :class:`agents.pipeline.SaliencyPipeline` of this config (the paper's
        pipeline, as ``wander benchmark`` runs it)."""
        return SaliencyPipeline(self.soms_params(), self.proto_params(), follow_dt=self.follow_dt)
