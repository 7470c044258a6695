"""What the rig writes to a Speck's samna configuration (no device, no samna import).

Functions over a samna ``SpeckConfiguration`` (or an object of its shape):
:func:`monitor_dvs` switches on the DVS layer's stream that
:class:`hardware.speck.SpeckSource` reads, :func:`silence_cores` feeds and monitors no
DYNAP-CNN core, :func:`sensor_size_from` reads the DVS region, :func:`chip_family` names
the samna submodule of a device.

With a readout (``SpeckParams.readout``, a :class:`~wander_env.readout.ReadoutParams`,
the block the simulated camera takes as ``env.readout``), :func:`write_readout_config`
writes its samna fields to the configuration and the source reads the chip's
pre-processed stream instead of the raw one: ``dvs_layer.pooling`` / ``.origin`` /
``.cut`` / ``.mirror`` / ``.mirror_diagonal`` / ``.merge`` / ``.on_channel`` /
``.off_channel`` and ``dvs_filter.enable`` / ``.filter_size`` /
``.hot_pixel_filter_enable`` / ``.low_pass_mode_enable`` / ``.threshold`` — the Speck Dev
Kit Datasheet (Aug 2023) §3.2.3 and sinabs ``play_with_speck_dvs.ipynb``; the slow clock
timing the filter, ``handle.get_io_module().set_slow_clock(True)`` and
``.set_slow_clk_rate(hz)`` — datasheet §3.2.6.3.2; the pre-processed events,
``dvs_layer.monitor_enable`` → ``Spike`` with ``layer == 13`` (x, y, ``feature`` = the
channel: 1 ON, 0 OFF or merged) — sinabs ``play_with_speck_dvs.ipynb``. The monitor does
not show the DVS layer's pooling (sinabs ``DynapcnnNetwork`` warns so), so a readout
with pooling is refused here; the kill bits have no public samna field, so a readout
with ``kill_pixels`` is refused too. The arbiter, queue and host packets are the chip's
own (nothing to write).
"""

from __future__ import annotations

import re
from typing import Any

from wander_env.events import SensorSize
from wander_env.readout import ReadoutParams

__all__ = [
    "DVS_LAYER_ID",
    "check_readout_for_chip",
    "chip_family",
    "monitor_dvs",
    "sensor_size_from",
    "silence_cores",
    "write_readout_config",
]


def chip_family(device_type_name: str) -> str:
    """``"Speck2fModuleDevKit"`` → ``"speck2f"`` (the samna submodule name)."""
    match = re.match(r"speck2[a-z]", device_type_name.lower())
    if match is None:
        raise RuntimeError(f"cannot tell the Speck chip family from {device_type_name!r}")
    return match.group(0)


def sensor_size_from(config: Any, fallback: tuple[int, int]) -> tuple[SensorSize, str]:
    """Sensor size from a fresh configuration's DVS region (inclusive ``origin``/``cut``)."""
    dvs = config.dvs_layer
    w = int(dvs.cut.x) - int(dvs.origin.x) + 1
    h = int(dvs.cut.y) - int(dvs.origin.y) + 1
    if 0 < w <= 4096 and 0 < h <= 4096:
        return (w, h, 2), "configuration dvs_layer.origin/cut"
    return (int(fallback[0]), int(fallback[1]), 2), "fallback (configuration gave no region)"


def check_readout_for_chip(readout: ReadoutParams) -> None:
    """ValueError (one line) when the chip cannot do what ``readout`` asks and the host
    see it (see the module docstring)."""
    if readout.dvs_layer.pooling != (1, 1):
        raise ValueError(
            f"readout.dvs_layer.pooling: {readout.dvs_layer.pooling} is not shown by the "
            "chip's DVS monitor (sinabs warns so), which the rig reads; use (1, 1) here"
        )
    if readout.kill_pixels:
        raise ValueError(
            "readout.kill_pixels: the kill bits have no public samna field to write; leave "
            "it empty on the rig"
        )


def write_readout_config(config: Any, readout: ReadoutParams) -> None:
    """Write ``readout``'s samna fields (``dvs_layer.*``, ``dvs_filter.*``) to a samna
    ``SpeckConfiguration``; ``cut`` None leaves the configuration's own."""
    layer, filt = readout.dvs_layer, readout.dvs_filter
    dvs = config.dvs_layer
    dvs.pooling.x, dvs.pooling.y = layer.pooling
    dvs.origin.x, dvs.origin.y = layer.origin
    if layer.cut is not None:
        dvs.cut.x, dvs.cut.y = layer.cut
    dvs.mirror.x, dvs.mirror.y = layer.mirror
    dvs.mirror_diagonal = layer.mirror_diagonal
    dvs.merge = layer.merge
    dvs.on_channel, dvs.off_channel = layer.on_channel, layer.off_channel
    f = config.dvs_filter
    f.enable = filt.enable
    f.filter_size.x, f.filter_size.y = filt.filter_size
    f.hot_pixel_filter_enable = filt.hot_pixel_filter_enable
    f.low_pass_mode_enable = filt.low_pass_mode_enable
    f.threshold = filt.threshold


#: samna's layer number of the DVS layer's monitored events (sinabs play_with_speck_dvs).
DVS_LAYER_ID = 13


def monitor_dvs(config: Any, readout: ReadoutParams | None) -> None:
    """Switch on the DVS layer's stream a :class:`SpeckSource` reads, leaving the cores as
    they are: the raw pixel-array events (``DvsEvent``), or with a ``readout`` its samna
    fields written and the pre-processed events (``Spike``, layer 13) instead."""
    dvs = config.dvs_layer
    if readout is not None:
        write_readout_config(config, readout)
    dvs.raw_monitor_enable = readout is None  # DvsEvent straight from the pixel array
    dvs.monitor_enable = readout is not None  # pre-processed copies (Spike, layer 13)
    dvs.pass_sensor_events = True  # keep the pixel array on (datasheet §3.2.3.8)


def silence_cores(config: Any) -> None:
    """Feed no DYNAP-CNN core and monitor none: the network stays silent."""
    dvs = config.dvs_layer
    for i in range(len(dvs.destinations)):
        dvs.destinations[i].enable = False
    for i in range(len(config.cnn_layers)):
        config.cnn_layers[i].monitor_enable = False
