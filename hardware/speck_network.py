"""The attention front end deployed on a Speck's cores (issue 35, items 3–4).

:func:`deploy` turns the one quantised model of :mod:`agents.speck_front` into a samna
configuration: wander's offline chip check first (:func:`agents.speck_limits.check_network`,
refusing with one line), then sinabs' per-layer ``validate_memory_mapping_speck``, then
``DynapcnnNetwork(model, dvs_input=True, discretize=True)`` (the chip's own pixel array
feeds core 0; the discretisation must leave the model as it is: its weights already
sit on the int8 grid with scale 1, and a change is refused), and ``make_config`` for
the device (``"speck2fmodule"`` by default) with the first (DoG) and last (grouping)
layers monitored.

:class:`ChipPipeline` is the host side on the rig: it applies the configuration to an
open device, reads the monitored cores' ``Spike`` events and hands them to the rest of
the agent through the same interface as the simulated front end
(:class:`agents.speck_front.SpeckPipeline`): the DoG spikes of each step as the OMS
map, the grouping spikes summed over the window as the saliency, both on the sensor
grid (each 64×64 output covers 2×2 pixels); the argmax stays on the host.

samna is imported here only, lazily (:func:`hardware.samna_import.import_samna`): the
``sinabs.backend.dynapcnn`` package imports samna at module level, so it is imported
inside :func:`deploy` after samna was found.
"""

from __future__ import annotations

import contextlib
import io
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch

from agents.speck_front import FrontEndPipeline, SpeckFrontParams, build_front
from agents.speck_limits import NetworkReport, SpeckLimitError, check_network
from hardware.samna_import import import_samna

__all__ = ["ChipPipeline", "Deployment", "deploy", "spike_counts"]


@dataclass(frozen=True)
class Deployment:
    """A configuration ready for a device: ``config`` (samna's ``SpeckConfiguration``),
    ``report`` (the offline check's cores), ``layer2core`` (sinabs' layer index → chip
    core), ``oms_core`` and ``saliency_core`` (the monitored DoG and grouping cores),
    ``params`` the front end's parameters."""

    config: Any
    report: NetworkReport
    layer2core: dict[int, int]
    oms_core: int
    saliency_core: int
    params: SpeckFrontParams


def _sinabs_memory_check(report: NetworkReport) -> None:
    """sinabs' own per-layer memory check (``sinabs.utils.validate_memory_mapping_speck``;
    it needs no samna). Its exception becomes a :class:`SpeckLimitError` naming the layer."""
    from sinabs.utils import validate_memory_mapping_speck

    for lay in report.layers:
        pad = lay.padding if not isinstance(lay.padding, str) else (lay.kernel[0] // 2,) * 2
        try:
            validate_memory_mapping_speck(
                lay.in_shape[0],
                lay.out_shape[0],
                lay.kernel,
                lay.stride,
                pad,
                [lay.in_shape[1], lay.in_shape[2]],
            )
        except Exception as err:  # sinabs raises a bare Exception
            raise SpeckLimitError(f"{lay.label}: sinabs memory check: {err}") from err


def deploy(params: SpeckFrontParams | None = None, device: str = "speck2fmodule") -> Deployment:
    """The samna configuration of the front end for ``device`` (module docstring);
    :class:`SpeckLimitError` before samna is touched when the network does not fit,
    :class:`hardware.samna_import.SamnaUnavailableError` when samna cannot be imported."""
    p = params if params is not None else SpeckFrontParams()
    model = build_front(p)
    shape = (2, p.height_px, p.width_px)
    report = check_network(model, shape)
    _sinabs_memory_check(report)
    import_samna()
    from sinabs.backend.dynapcnn import DynapcnnNetwork

    reference = [m.weight.detach().clone() for m in model if isinstance(m, torch.nn.Conv2d)]
    net = DynapcnnNetwork(model, input_shape=shape, batch_size=1, dvs_input=True, discretize=True)
    indices = sorted(k for k in net.dynapcnn_layers if isinstance(k, int))
    for i, (k, ref) in enumerate(zip(indices, reference, strict=True)):
        got = net.dynapcnn_layers[k].conv_layer.weight.detach()
        if not torch.equal(got, ref):
            raise SpeckLimitError(
                f"layer {i}: sinabs' discretisation changed the quantised weights "
                "(the model and the chip would differ)"
            )
    with contextlib.redirect_stdout(io.StringIO()):  # sinabs prints "Network is valid"
        config = net.make_config(device=device, monitor_layers=[indices[0], indices[-1]])
    l2c = {int(k): int(v) for k, v in net.layer2core_map.items()}
    return Deployment(
        config=config,
        report=report,
        layer2core=l2c,
        oms_core=l2c[indices[0]],
        saliency_core=l2c[indices[-1]],
        params=p,
    )


def spike_counts(events: Iterable[Any], core: int, shape: tuple[int, int, int]) -> np.ndarray:
    """Counts ``(f, h, w)`` of the ``Spike`` events (``.layer``, ``.feature``, ``.x``,
    ``.y``) from chip core ``core``; other events and cores are skipped, and a spike
    outside ``shape`` raises ``ValueError`` (nothing is dropped silently)."""
    out = np.zeros(shape, np.float32)
    f, h, w = shape
    for e in events:
        if getattr(e, "layer", None) != core or not hasattr(e, "feature"):
            continue
        c, x, y = int(e.feature), int(e.x), int(e.y)
        if not (0 <= c < f and 0 <= x < w and 0 <= y < h):
            raise ValueError(f"core {core} spike at feature {c}, x {x}, y {y} is outside {shape}")
        out[c, y, x] += 1.0
    return out


class ChipPipeline(FrontEndPipeline):
    """The front end running on an open Speck (``handle`` from ``samna.device.open_device``):
    :meth:`start` applies the configuration (unless ``configured``: the device already
    holds it, as on the rig, where :class:`hardware.speck.SpeckSource` applied it with
    the DVS layer's monitor switched on; applying it again would drop that) and connects
    a sink to the device's output; each step drains the sink (the ``event_counts``
    argument, the host's copy of the events, is only shape-checked: the chip sees its own
    pixels). ``spikes_read`` counts the monitored cores' spikes taken from the sink (it
    also gets the camera's events and other cores' spikes, which are skipped)."""

    def __init__(self, handle: Any, deployment: Deployment, configured: bool = False) -> None:
        super().__init__(deployment.params)
        self.handle = handle
        self.deployment = deployment
        self.configured = configured
        self._sink: Any = None
        self.spikes_read = 0

    def start(self) -> None:
        samna = import_samna()
        if not self.configured:
            self.handle.get_model().apply_configuration(self.deployment.config)
            self.configured = True
        self._sink = samna.graph.sink_from(self.handle.get_model_source_node())

    def spikes(self, event_counts: np.ndarray | torch.Tensor) -> tuple[np.ndarray, np.ndarray]:
        if self._sink is None:
            raise RuntimeError("ChipPipeline.start() was not called")
        p = self.params
        shape = tuple(np.shape(event_counts))
        if shape != (2, p.height_px, p.width_px):
            raise ValueError(f"event counts must be (2, {p.height_px}, {p.width_px}), got {shape}")
        events = self._sink.get_events()
        dog = spike_counts(events, self.deployment.oms_core, (2, *p.grid))
        group = spike_counts(events, self.deployment.saliency_core, (1, *p.grid))
        self.spikes_read += int(dog.sum() + group.sum())
        return dog, group
