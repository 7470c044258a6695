"""The benchmarks' model config: :class:`ModelConfig` → :class:`agents.pipeline.SaliencyPipeline`.

Both the real-data benchmarks (``wander benchmark``) and the simulated detection
experiment (:mod:`experiments.paper.detection`) score the one sOMS → saliency pipeline of
:mod:`agents.pipeline`; this module only maps the benchmark's config (the agent's block,
which ``--streamlined``, ``--alpha`` and ``--set agent.KEY=VALUE`` set; the dataset's
window as the nominal step: :func:`nominal_dt_s`) onto the pipeline's parameter blocks.

Examples:
    >>> pipe = ModelConfig(dt=0.01).pipeline()
    >>> maps = pipe.process(np.zeros((2, 32, 32), np.float32), 0.01)
    >>> maps.oms.shape, maps.saliency.shape, maps.point_xy
    ((32, 32), (32, 32), None)
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from agents.attention import AgentParams
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

    ``dt`` is the nominal step in seconds (the dataset's window); ``follow_dt`` lets each
    call's ``dt_s`` set the LIF decay (module docstring). ``agent`` is the agent's block
    (:class:`agents.attention.AgentParams`) whose front end the benchmark scores: its
    ``soms`` (the paper-literal sOMS by default: α = 0.80, min-max norm, ``conv``
    direct or separable) and ``proto`` (``polarity_split: false`` is the paper's
    streamlined model on ``V = V+ ∨ V−``; ``conv`` direct or FFT, same results); both
    run with the step ``dt``. The agent's other settings (fixation window, saccades) play
    no part in the benchmark: a changed one is refused
    (:meth:`agents.attention.AgentParams.check_reads`).
    """

    dt: float = 0.005
    follow_dt: bool = True
    agent: AgentParams = field(default_factory=lambda: AgentParams(soms=SOMSParams()))

    def __post_init__(self) -> None:
        if not (self.dt > 0 and math.isfinite(self.dt)):
            raise ValueError(f"ModelConfig.dt must be a positive number of seconds, got {self.dt}")
        self.agent.check_reads("soms", "proto", speck=False)

    def soms_params(self) -> SOMSParams:
        """The :class:`SOMSParams` of this config (the agent's, with the step ``dt``)."""
        return replace(self.agent.soms, dt=self.dt)  # type: ignore[type-var]

    def proto_params(self) -> ProtoObjectParams:
        """The :class:`ProtoObjectParams` of this config (the agent's, with the step
        ``dt``)."""
        return replace(self.agent.proto, dt=self.dt)

    def pipeline(self) -> SaliencyPipeline:
        """The :class:`agents.pipeline.SaliencyPipeline` of this config (the paper's
        pipeline, as ``wander benchmark`` runs it)."""
        return SaliencyPipeline(self.soms_params(), self.proto_params(), follow_dt=self.follow_dt)
