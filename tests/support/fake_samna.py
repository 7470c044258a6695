"""A fake ``samna`` for tests: the API surface ``hardware/speck.py`` uses, and no more.

Names, argument types and units follow the public samna usage cited in
``hardware/speck.py``. The fake is strict where the real library is (objects have
fixed attributes, so ``event.t`` or a misspelt config field raises
``AttributeError``; a configuration of the wrong chip family or a sink of the wrong
event type raises ``TypeError``) and stricter where a test should catch a unit
mistake: ``get_events_blocking`` takes an ``int`` in milliseconds and rejects
floats (seconds) and values above 10 s (probably µs); config flags take ``bool``.

A :class:`FakeSpeck` replays a recording (``x``, ``y``, ``t`` µs from the stop-watch
reset, ``p``) in wall-clock time once the configuration with
``dvs_layer.raw_monitor_enable`` is applied and the stop watch runs; it can mix in
``Spike`` and ``ReadoutPinValue`` events. The fake emits nothing before the stop
watch is enabled (a real Speck would emit events with no usable timestamp).

Install it with :func:`install`; nothing here imports the real samna.
"""

from __future__ import annotations

import sys
import threading
import time
import types
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

FAMILIES = ("speck2e", "speck2f")


# -- strict value objects ------------------------------------------------------------


class _Strict:
    """Fixed attributes (``__slots__``); fields named in ``_bools`` accept only bool."""

    __slots__ = ()
    _bools: tuple[str, ...] = ()

    def __setattr__(self, name: str, value: Any) -> None:
        if name in self._bools and type(value) is not bool:
            raise TypeError(f"{type(self).__name__}.{name} takes a bool, got {value!r}")
        object.__setattr__(self, name, value)


class Vec2(_Strict):
    __slots__ = ("x", "y")

    def __init__(self, x: int = 0, y: int = 0) -> None:
        self.x, self.y = x, y


class Vec2Bool(_Strict):
    __slots__ = ("x", "y")
    _bools = ("x", "y")

    def __init__(self) -> None:
        self.x, self.y = False, False


class Destination(_Strict):
    __slots__ = ("enable", "layer")
    _bools = ("enable",)

    def __init__(self, enable: bool = False, layer: int = 0) -> None:
        self.enable, self.layer = enable, layer


class DvsLayerConfig(_Strict):
    __slots__ = (
        "cut",
        "destinations",
        "merge",
        "mirror",
        "mirror_diagonal",
        "monitor_enable",
        "off_channel",
        "on_channel",
        "origin",
        "pass_sensor_events",
        "pooling",
        "raw_monitor_enable",
    )
    _bools = (
        "merge",
        "mirror_diagonal",
        "monitor_enable",
        "off_channel",
        "on_channel",
        "pass_sensor_events",
        "raw_monitor_enable",
    )

    def __init__(self) -> None:
        self.raw_monitor_enable = False
        self.monitor_enable = False
        self.pass_sensor_events = True
        self.merge = False
        self.on_channel = True
        self.off_channel = True
        self.mirror_diagonal = False
        self.origin = Vec2(0, 0)
        self.cut = Vec2(127, 127)
        self.pooling = Vec2(1, 1)
        self.mirror = Vec2Bool()
        self.destinations = [Destination(True, 0), Destination(False, 0)]

    def __setattr__(self, name: str, value: Any) -> None:
        if isinstance(value, dict):  # speckcores: sinabs writes {"x": .., "y": ..}, samna
            vec = getattr(self, name)  # converts it to the field's Vec2
            for key, v in value.items():
                setattr(vec, key, v)
            return
        super().__setattr__(name, value)


# -- readout (helper `readout`): the DVS filter block and the slow clock ---------------
# Field names: Speck Dev Kit Datasheet (Aug 2023) §3.2.2, §3.2.3.5 and §3.2.6.3.2; sinabs
# play_with_speck_dvs.ipynb. Defaults: filter off (the documented examples switch it on).


class DvsFilterConfig(_Strict):
    __slots__ = (
        "enable",
        "filter_size",
        "hot_pixel_filter_enable",
        "low_pass_mode_enable",
        "threshold",
    )
    _bools = ("enable", "hot_pixel_filter_enable", "low_pass_mode_enable")

    def __init__(self) -> None:
        self.enable = False
        self.filter_size = Vec2(3, 3)
        self.hot_pixel_filter_enable = False
        self.low_pass_mode_enable = False
        self.threshold = 5

    def __setattr__(self, name: str, value: Any) -> None:
        if name == "threshold" and type(value) is not int:
            raise TypeError(f"DvsFilterConfig.threshold takes an int, got {value!r}")
        super().__setattr__(name, value)


class IoModule:
    """``handle.get_io_module()``: the dev kit's slow clock (datasheet §3.2.6.3.2)."""

    def __init__(self) -> None:
        self.slow_clock = False
        self.slow_clk_rate: int | None = None

    def set_slow_clock(self, enable: bool) -> None:
        if type(enable) is not bool:
            raise TypeError(f"set_slow_clock takes a bool, got {enable!r}")
        self.slow_clock = enable

    def set_slow_clk_rate(self, rate: int) -> None:
        if type(rate) is not int:
            raise TypeError(f"set_slow_clk_rate takes an int (Hz), got {rate!r}")
        self.slow_clk_rate = rate


# -- end of the readout block -----------------------------------------------------------


class _SpeckConfigurationBase(_Strict):
    __slots__ = ("cnn_layers", "dvs_filter", "dvs_layer")
    family = ""

    def __init__(self) -> None:
        self.dvs_layer = DvsLayerConfig()
        self.dvs_filter = DvsFilterConfig()  # readout block
        self.cnn_layers = [SpeckCnnLayerConfig() for _ in range(9)]  # speckcores block


class _Event(_Strict):
    __slots__ = ()
    family = ""

    def __repr__(self) -> str:
        names = [n for cls in type(self).__mro__ for n in getattr(cls, "__slots__", ())]
        fields = ", ".join(f"{k}={getattr(self, k)!r}" for k in names)
        return f"{self.family}::event::{type(self).__name__}({fields})"


class _DvsEventBase(_Event):
    __slots__ = ("p", "timestamp", "x", "y")
    _bools = ("p",)

    def __init__(self) -> None:
        self.x, self.y, self.p, self.timestamp = 0, 0, False, 0


class _SpikeBase(_Event):
    __slots__ = ("feature", "layer", "timestamp", "x", "y")

    def __init__(self) -> None:
        self.layer, self.feature, self.x, self.y, self.timestamp = 0, 0, 0, 0, 0


class _ReadoutPinValueBase(_Event):
    __slots__ = ("index", "timestamp")

    def __init__(self) -> None:
        self.index, self.timestamp = 0, 0


# -- the device ------------------------------------------------------------------------


class DeviceInfo(_Strict):
    __slots__ = (
        "device_type_name",
        "logic_version",
        "serial_number",
        "usb_bus_number",
        "usb_device_address",
    )

    def __init__(self, device_type_name: str, serial_number: str, address: int) -> None:
        self.device_type_name = device_type_name
        self.serial_number = serial_number
        self.usb_bus_number = 2
        self.usb_device_address = address
        self.logic_version = 0

    def __repr__(self) -> str:
        return (
            f"device::DeviceInfo(serial_number={self.serial_number}, usb_bus_number="
            f"{self.usb_bus_number}, usb_device_address={self.usb_device_address}, "
            f"logic_version={self.logic_version}, device_type_name={self.device_type_name})"
        )


@dataclass
class FakeSpeck:
    """What the fake chip streams: a recording plus optional non-DVS events.

    ``events``: structured array with ``x``, ``y``, ``t`` (µs after the stop-watch
    reset, sorted), ``p``; ``speed``: device µs per wall-clock µs; ``other_every``:
    after every that many DVS events emit one ``Spike`` (and every third time also a
    ``ReadoutPinValue``); ``timestamp_offset``: added to the stamps modulo 2**32 (to
    exercise the counter wraparound); ``max_batch``: cap on events per
    ``get_events_blocking`` answer; ``core_spikes``: ``(t, core, feature, x, y)`` sorted
    by ``t``, the network's ``Spike`` events, streamed while the applied configuration
    monitors that core (speckcores block).
    """

    events: np.ndarray
    speed: float = 1.0
    other_every: int | None = None
    timestamp_offset: int = 0
    max_batch: int | None = None
    core_spikes: list[tuple[int, int, int, int, int]] = field(default_factory=list)
    emitted_dvs: int = 0
    emitted_other: dict[str, int] = field(default_factory=dict)


class StopWatch:
    def __init__(self, handle: DeviceHandle) -> None:
        self._handle = handle
        self.enabled = False
        self.calls: list[str] = []

    def set_enable_value(self, value: bool) -> None:
        if type(value) is not bool:
            raise TypeError(f"set_enable_value takes a bool, got {value!r}")
        self.calls.append(f"set_enable_value({value})")
        if value and not self.enabled:
            self._handle._origin = time.monotonic()
        self.enabled = value

    def start(self) -> None:
        self.set_enable_value(True)

    def stop(self) -> None:
        self.set_enable_value(False)

    def reset(self) -> None:
        self.calls.append("reset()")
        self._handle._origin = time.monotonic()

    def get_enable_value(self) -> bool:
        return self.enabled


class DeviceSourceNode:
    """``DeviceSourceNode_<family>_event_output_event``: the model's output stream."""

    def __init__(self, handle: DeviceHandle) -> None:
        self.handle = handle
        self.family = handle.family


class BasicSinkNode:
    """``BasicSinkNode_<family>_event_output_event``: a buffer read from Python."""

    family = ""

    def __init__(self) -> None:
        self._buffer: list[Any] = []
        self._source: DeviceSourceNode | None = None
        self._graph: EventFilterGraph | None = None
        self.calls: list[tuple[float, float, int]] = []  # (start, end, n) of blocking reads

    def _pump(self) -> None:
        if self._source is not None and self._graph is not None and self._graph.running:
            self._source.handle._pump()

    def get_events(self) -> list[Any]:
        self._pump()
        out, self._buffer = self._buffer, []
        return out

    def clear_events(self) -> None:
        self.get_events()

    def get_events_blocking(self, timeout: int) -> list[Any]:
        """Wait up to ``timeout`` **milliseconds** for events; return those available."""
        if type(timeout) is not int:
            raise TypeError(f"get_events_blocking(timeout: int [ms]) got {timeout!r}")
        if not 0 <= timeout <= 10_000:
            raise ValueError(f"timeout={timeout} ms is implausible (µs passed for ms?)")
        t_start = time.monotonic()
        deadline = t_start + timeout / 1000
        while True:
            self._pump()
            if self._buffer or time.monotonic() >= deadline:
                break
            time.sleep(min(0.001, max(0.0, deadline - time.monotonic())))
        cap = self._source.handle.speck.max_batch if self._source is not None else None
        n = len(self._buffer) if cap is None else min(cap, len(self._buffer))
        out, self._buffer = self._buffer[:n], self._buffer[n:]
        self.calls.append((t_start, time.monotonic(), len(out)))
        return out


class Model:
    def __init__(self, handle: DeviceHandle) -> None:
        self._handle = handle

    def apply_configuration(self, config: _SpeckConfigurationBase) -> None:
        expected = self._handle.module.configuration.SpeckConfiguration
        if not isinstance(config, expected):
            raise TypeError(
                f"apply_configuration expects {self._handle.family}.configuration."
                f"SpeckConfiguration, got {type(config).__module__}.{type(config).__name__}"
            )
        if self._handle.fail_on_apply:
            raise RuntimeError("fake: apply_configuration failed")
        self._handle.applied.append(config)

    def get_source_node(self) -> DeviceSourceNode:
        return self._handle._source_node


class DeviceHandle:
    """What ``samna.device.open_device`` returns for a Speck dev kit."""

    def __init__(self, info: DeviceInfo, module: types.ModuleType, speck: FakeSpeck) -> None:
        self.info = info
        self.family = module.__name__.split(".")[-1]
        self.module = module
        self.speck = speck
        self.closed = False
        self.fail_on_apply = False
        self.applied: list[_SpeckConfigurationBase] = []
        self._stop_watch = StopWatch(self)
        self._io = IoModule()  # readout block
        self._source_node = DeviceSourceNode(self)
        self._model = Model(self)
        self._sinks: list[BasicSinkNode] = []
        self._origin = 0.0
        self._next = 0  # index of the next recorded event to emit
        self._next_spike = 0  # ... and of the next core spike (speckcores block)
        self._lock = threading.Lock()

    def get_model(self) -> Model:
        return self._model

    def get_model_source_node(self) -> DeviceSourceNode:
        return self._source_node

    def get_stop_watch(self) -> StopWatch:
        return self._stop_watch

    def get_io_module(self) -> IoModule:  # readout block
        return self._io

    def _pump(self) -> None:
        """Push the recorded events that are due by now to every running sink."""
        with self._lock:
            config = self.applied[-1] if self.applied else None
            if self.closed or config is None or not self._stop_watch.enabled:
                return
            if not config.dvs_layer.raw_monitor_enable and not config.dvs_layer.monitor_enable:
                return
            ev = self.speck.events
            now_us = (time.monotonic() - self._origin) * 1e6 * self.speck.speed
            stop = int(np.searchsorted(ev["t"], now_us, side="right"))
            out: list[Any] = []
            ev_mod = self.module.event
            every = self.speck.other_every
            for i in range(self._next, stop):
                stamp = (int(ev["t"][i]) + self.speck.timestamp_offset) % (1 << 32)
                if config.dvs_layer.raw_monitor_enable:
                    e = ev_mod.DvsEvent()
                    e.x, e.y, e.p, e.timestamp = (
                        int(ev["x"][i]),
                        int(ev["y"][i]),
                        bool(ev["p"][i]),
                        stamp,
                    )
                    out.append(e)
                    self.speck.emitted_dvs += 1
                if config.dvs_layer.monitor_enable:  # pre-processed copy: Spike from layer 13
                    # (unprocessed here: the fake does not model the DVS layer; feature = p)
                    x, y, p = int(ev["x"][i]), int(ev["y"][i]), int(ev["p"][i])
                    out.append(self._other(ev_mod.Spike, stamp, layer=13, x=x, y=y, feature=p))
                if every and (i + 1) % every == 0:
                    out.append(self._other(ev_mod.Spike, stamp, layer=2, feature=1))
                    if (i + 1) % (3 * every) == 0:
                        out.append(self._other(ev_mod.ReadoutPinValue, stamp, index=3))
            self._next = max(self._next, stop)
            out += _core_spikes(self, config, now_us)
            for sink in self._sinks:
                if sink._graph is not None and sink._graph.running:
                    sink._buffer.extend(out)

    def _other(self, cls: type, stamp: int, **fields: int) -> Any:
        e = cls()
        e.timestamp = stamp
        for k, v in fields.items():
            setattr(e, k, v)
        name = cls.__name__
        self.speck.emitted_other[name] = self.speck.emitted_other.get(name, 0) + 1
        return e


# -- graph ---------------------------------------------------------------------------


class EventFilterGraph:
    def __init__(self) -> None:
        self.running = False
        self.nodes: list[Any] = []

    def sequential(self, nodes: Sequence[Any]) -> list[Any]:
        nodes = list(nodes)
        if len(nodes) != 2 or not isinstance(nodes[0], DeviceSourceNode):
            raise TypeError("fake sequential() supports [device source node, sink node] only")
        source, sink = nodes
        if not isinstance(sink, BasicSinkNode) or sink.family != source.family:
            raise TypeError(
                f"cannot connect {source.family} output events to {type(sink).__name__}"
            )
        sink._source, sink._graph = source, self
        source.handle._sinks.append(sink)
        self.nodes = nodes
        return nodes

    def start(self) -> bool:
        self.running = True
        return True

    def stop(self) -> bool:
        self.running = False
        return True

    def is_running(self) -> bool:
        return self.running


# -- the module --------------------------------------------------------------------------


class FakeSamna:
    """Builds the ``samna`` module tree and keeps the fake devices for inspection."""

    def __init__(self, devices: Sequence[tuple[str, str, FakeSpeck | None]]) -> None:
        self.module = types.ModuleType("samna")
        self.module.__file__ = "<fake samna>"
        self.submodules: dict[str, types.ModuleType] = {}
        self.families: dict[str, types.ModuleType] = {}
        for fam in FAMILIES:
            self.families[fam] = self._family_module(fam)
        self.infos = [
            DeviceInfo(name, serial, 9 + i) for i, (name, serial, _) in enumerate(devices)
        ]
        self.specks = {
            id(info): speck for info, (_, _, speck) in zip(self.infos, devices, strict=True)
        }
        self.opened: dict[int, DeviceHandle] = {}
        self.handles: list[DeviceHandle] = []
        self.close_calls = 0

        device = types.ModuleType("samna.device")
        device.get_unopened_devices = self.get_unopened_devices
        device.get_all_devices = lambda: list(self.infos)
        device.open_device = self.open_device
        device.close_device = self.close_device
        device.DeviceInfo = DeviceInfo  # speckcores block: an annotation in sinabs' io.py
        graph = types.ModuleType("samna.graph")
        graph.EventFilterGraph = EventFilterGraph
        graph.sink_from = self.sink_from
        self.module.device, self.module.graph = device, graph
        self.submodules.update({"samna.device": device, "samna.graph": graph})

    def _family_module(self, fam: str) -> types.ModuleType:
        mod = types.ModuleType(f"samna.{fam}")
        configuration = types.ModuleType(f"samna.{fam}.configuration")
        event = types.ModuleType(f"samna.{fam}.event")
        configuration.SpeckConfiguration = type(
            "SpeckConfiguration", (_SpeckConfigurationBase,), {"__slots__": (), "family": fam}
        )
        for name, base in (
            ("DvsEvent", _DvsEventBase),
            ("Spike", _SpikeBase),
            ("ReadoutPinValue", _ReadoutPinValueBase),
        ):
            setattr(event, name, type(name, (base,), {"__slots__": (), "family": fam}))
        mod.configuration, mod.event = configuration, event
        setattr(self.module, fam, mod)
        _add_cnn_api(self, fam, mod)  # speckcores block
        sink_name = f"BasicSinkNode_{fam}_event_output_event"
        setattr(self.module, sink_name, type(sink_name, (BasicSinkNode,), {"family": fam}))
        self.submodules.update(
            {
                f"samna.{fam}": mod,
                f"samna.{fam}.configuration": configuration,
                f"samna.{fam}.event": event,
            }
        )
        return mod

    # samna.device
    def get_unopened_devices(self) -> list[DeviceInfo]:
        return [info for info in self.infos if id(info) not in self.opened]

    def open_device(self, info: DeviceInfo | str, default_config: Any = None) -> DeviceHandle:
        if isinstance(info, str):
            matches = [i for i in self.get_unopened_devices() if i.device_type_name == info]
            if not matches:
                raise RuntimeError(f"no unopened device named {info!r}")
            info = matches[0]
        if not isinstance(info, DeviceInfo):
            raise TypeError(f"open_device(DeviceInfo | str) got {info!r}")
        if id(info) in self.opened:
            raise RuntimeError(f"{info.device_type_name} is already open")
        speck = self.specks[id(info)]
        fam = info.device_type_name.lower()[:7]
        if speck is None or fam not in self.families:
            raise RuntimeError(f"fake cannot open {info.device_type_name!r}")
        handle = DeviceHandle(info, self.families[fam], speck)
        self.opened[id(info)] = handle
        self.handles.append(handle)
        return handle

    def close_device(self, handle: DeviceHandle) -> None:
        self.close_calls += 1
        if not isinstance(handle, DeviceHandle):
            raise TypeError(f"close_device(device) got {handle!r}")
        if handle.closed:
            raise RuntimeError("device already closed")
        handle.closed = True
        self.opened.pop(id(handle.info), None)

    # samna.graph
    def sink_from(self, source: DeviceSourceNode) -> BasicSinkNode:
        sink = getattr(self.module, f"BasicSinkNode_{source.family}_event_output_event")()
        graph = EventFilterGraph()
        graph.sequential([source, sink])
        graph.start()
        return sink


def install(monkeypatch: Any, fake: FakeSamna) -> FakeSamna:
    """Put ``fake`` into ``sys.modules`` as ``samna`` (and its submodules) for one test."""
    monkeypatch.setitem(sys.modules, "samna", fake.module)
    for name, mod in fake.submodules.items():
        monkeypatch.setitem(sys.modules, name, mod)
    return fake


# == speckcores: the CNN cores, for sinabs' DynapcnnNetwork.make_config ==================
# (issue 35, item 4). What ``sinabs.backend.dynapcnn`` (3.1.3) touches when it builds and
# checks a configuration offline: ``samna.<family>.configuration.SpeckConfiguration``'s
# ``cnn_layers[i]`` fields written by ``chips/dynapcnn.py``
# (``write_dynapcnn_layer_config``: dimensions, weights, biases, leak_enable,
# thresholds, neuron states, destinations with pooling, monitor_enable),
# ``samna.<family>.validate_configuration`` (a stand-in: it checks only that every
# enabled destination names a core and records the call; samna's own rules cannot run
# here), the input-buffer class, and the ``samnagui`` module that
# ``sinabs/backend/dynapcnn/io.py`` imports at module level.


class CnnDestination(_Strict):
    __slots__ = ("enable", "layer", "pooling")
    _bools = ("enable",)

    def __init__(self) -> None:
        self.enable, self.layer, self.pooling = False, 0, 1


class SpeckCnnLayerConfig(_Strict):
    """``cnn_layers[i]``: the fields sinabs writes, with the types it writes."""

    __slots__ = (
        "biases",
        "destinations",
        "dimensions",
        "leak_enable",
        "monitor_enable",
        "neurons_initial_value",
        "return_to_zero",
        "threshold_high",
        "threshold_low",
        "weights",
    )
    _bools = ("leak_enable", "monitor_enable", "return_to_zero")

    def __init__(self) -> None:
        self.monitor_enable = False
        self.destinations = [CnnDestination(), CnnDestination()]
        self.dimensions: dict[str, Any] = {}
        self.weights: list[Any] = []
        self.biases: list[int] = []
        self.neurons_initial_value: list[Any] = []
        self.leak_enable = False
        self.return_to_zero = False
        self.threshold_high = 0
        self.threshold_low = 0

    def __setattr__(self, name: str, value: Any) -> None:
        if name == "leak_enable" and hasattr(value, "item"):  # sinabs passes a 0-d tensor
            value = bool(value.item())
        super().__setattr__(name, value)


def _validate(fake: FakeSamna, config: _SpeckConfigurationBase) -> tuple[bool, str]:
    """The stand-in for ``samna.<family>.validate_configuration``: enabled destinations
    must name one of the 9 cores; every configuration checked is kept in
    ``fake.validated``."""
    fake.validated.append(config)
    for i, layer in enumerate(config.cnn_layers):
        for d in layer.destinations:
            if d.enable and not 0 <= d.layer < len(config.cnn_layers):
                return False, f"cnn_layers[{i}] sends to core {d.layer}"
    return True, ""


class BasicSourceNode(_Strict):
    """``BasicSourceNode_<family>_event_input_event``: the input buffer sinabs makes."""

    __slots__ = ("written",)

    def __init__(self) -> None:
        self.written: list[Any] = []

    def write(self, events: list[Any]) -> None:
        self.written.extend(events)


def _add_cnn_api(fake: FakeSamna, fam: str, mod: types.ModuleType) -> None:
    """Add the CNN-core API of family ``fam`` to its module (called by ``_family_module``)."""
    if not hasattr(fake, "validated"):
        fake.validated = []  # the configurations checked, in order
    mod.validate_configuration = lambda config: _validate(fake, config)
    for name in (
        f"BasicSourceNode_{fam}_event_input_event",
        f"BasicSourceNode_{fam}_event_{fam}_input_event",
    ):
        setattr(fake.module, name, type(name, (BasicSourceNode,), {"__slots__": ()}))
    fake.submodules.setdefault("samnagui", types.ModuleType("samnagui"))


def spike(fake: FakeSamna, fam: str, layer: int, feature: int, x: int, y: int, t: int) -> Any:
    """A ``samna.<fam>.event.Spike`` from core ``layer`` (the chip's output events)."""
    e = fake.families[fam].event.Spike()
    e.layer, e.feature, e.x, e.y, e.timestamp = layer, feature, x, y, t
    return e


def _core_spikes(handle: DeviceHandle, config: Any, now_us: float) -> list[Any]:
    """The ``Spike`` events of ``handle.speck.core_spikes`` due by ``now_us``, from the
    cores ``config`` monitors (those of unmonitored cores are not streamed)."""
    due, out = handle.speck.core_spikes, []
    while handle._next_spike < len(due) and due[handle._next_spike][0] <= now_us:
        t, core, feature, x, y = due[handle._next_spike]
        handle._next_spike += 1
        if config.cnn_layers[core].monitor_enable:
            spike_type = handle.module.event.Spike
            out.append(handle._other(spike_type, t, layer=core, feature=feature, x=x, y=y))
    return out


def forget_dynapcnn(monkeypatch: Any) -> None:
    """Drop ``sinabs.backend.dynapcnn`` from ``sys.modules`` for one test: it binds
    samna's classes at import, so each test's fake needs its own import."""
    for name in [n for n in sys.modules if n.startswith("sinabs.backend.dynapcnn")]:
        monkeypatch.delitem(sys.modules, name)
    backend = sys.modules.get("sinabs.backend")
    if backend is not None and hasattr(backend, "dynapcnn"):
        monkeypatch.delattr(backend, "dynapcnn")


# == end speckcores ========================================================================
