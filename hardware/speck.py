"""Live DVS events from a SynSense Speck (Speck2f / Speck2e dev kit) through samna.

:class:`SpeckSource` opens the first unopened Speck whose samna
``device_type_name`` starts with one of the requested prefixes, configures the chip
to stream only the raw events of its 128×128 pixel array (or applies a prepared
configuration, the attention front end's cores, with the DVS layer's monitor switched
on in it: :func:`~hardware.speck_config.monitor_dvs`), and reads them in a
background thread into a bounded queue. ``read`` hands out consecutive windows in
the shared event format (``t`` in µs since the device's stop watch was reset in
``start``, ``p`` 1 = ON) through the :class:`~hardware.event_source.EventSource`
interface.

samna is imported lazily, in ``start``, through :func:`hardware.samna_import.import_samna`
(never at module import: the PyPI ``samna`` wheel is a placeholder that installs the real
library at import time). What the source writes to the chip's configuration (the DVS
monitor, a readout's fields, silent cores) is in :mod:`hardware.speck_config`.

The samna calls used, and where they are documented (public sources):

* ``samna.device.get_unopened_devices()`` → infos with ``.device_type_name``
  (e.g. ``"Speck2fModuleDevKit"``, ``"Speck2fDevKit"``, ``"Speck2eDevKit"``) and
  ``.serial_number``; ``samna.device.open_device(info)``;
  ``samna.device.close_device(handle)`` — synsense/sinabs
  ``docs/source/faqs/device_management.md`` and ``sinabs/backend/dynapcnn/io.py``
  (``open_device`` / ``close_device``; device names in ``device_types``).
* ``samna.speck2f.configuration.SpeckConfiguration()`` (``samna.speck2e…`` for
  Speck2e), ``config.dvs_layer.raw_monitor_enable = True``,
  ``handle.get_model().apply_configuration(config)`` — synsense/sinabs
  ``docs/source/getting_started/notebooks/visualize_speck_dvs_input.ipynb``.
  ``dvs_layer.monitor_enable`` (pre-processed copies as ``Spike`` with
  ``layer == 13``), ``dvs_layer.pass_sensor_events``,
  ``dvs_layer.destinations[i].enable`` — ``play_with_speck_dvs.ipynb`` in the same
  folder; ``cnn_layers[i].monitor_enable`` — ``docs/source/faqs/output_monitoring.md``;
  ``dvs_layer.origin`` / ``.cut`` (inclusive corners of the DVS region) — the
  SynSense Speck dev-kit datasheet §3.2.3.3 and ``play_with_speck_dvs.ipynb``.
* ``samna.graph.EventFilterGraph()``, ``graph.sequential([handle.get_model_source_node(),
  samna.BasicSinkNode_speck2f_event_output_event()])``, ``graph.start()`` /
  ``graph.stop()`` — ``sinabs/backend/dynapcnn/dynapcnn_network.py`` (``to``) and
  ``chips/speck2f.py`` / ``chips/speck2e.py`` (``get_output_buffer``).
* ``sink.get_events_blocking(timeout_ms)`` (milliseconds; public scripts call
  ``get_events_blocking(1000)`` "with a timeout of 1 second", rockpool passes
  ``ceil(seconds * 1000)``), ``sink.get_events()`` — sinabs ``hw_forward`` and
  the Speck scripts of the paper's public code.
* ``samna.speck2f.event.DvsEvent`` with ``.x``, ``.y``, ``.p``, ``.timestamp`` (µs)
  — public Speck scripts (``dvs_events_to_numpy``); the datasheet §3.2.5.3 gives
  Speck event timestamps in microseconds.
* ``handle.get_stop_watch().set_enable_value(True)`` and ``.reset()`` — the paper's
  public Speck script; sinabs ``io.py`` uses ``.start()`` / ``.stop()`` / ``.reset()``
  on the same object. Without it events carry no usable timestamps.
"""

from __future__ import annotations

import atexit
import threading
import time
import warnings
from collections import Counter, deque
from dataclasses import dataclass, replace
from types import ModuleType
from typing import Any

import numpy as np

from hardware.event_source import EventSourceBase
from hardware.samna_import import import_samna
from hardware.speck_config import (
    DVS_LAYER_ID,
    check_readout_for_chip,
    chip_family,
    monitor_dvs,
    sensor_size_from,
    silence_cores,
)
from wander_env.events import EVENT_DTYPE, empty_events
from wander_env.readout import SPECK_DVS_SIZE, ReadoutParams, SpeckReadout

_TS_WRAP = 1 << 32  # Speck timestamps are 32-bit µs counters (wrap after ~71.6 min)


@dataclass(frozen=True)
class SpeckParams:
    """Device choice, queue and timing of a :class:`SpeckSource`.

    ``device_type_prefixes``: accepted samna ``device_type_name`` prefixes, in order of
    preference (case-insensitive); ``serial_number``: also require this serial;
    ``queue_events``: capacity of the event queue (the oldest events are dropped
    beyond it); ``read_timeout_ms``: ``get_events_blocking`` timeout, also the
    longest ``close`` waits for the reader thread per poll; ``latency_margin_us``:
    how long after a window's end (by the host clock) ``read`` waits for its last
    events when no later event has arrived; ``join_timeout_s``: extra time
    ``close`` gives the reader thread.
    """

    device_type_prefixes: tuple[str, ...] = ("Speck2f", "Speck2e")
    serial_number: str | None = None
    queue_events: int = 2_000_000
    read_timeout_ms: int = 50
    latency_margin_us: int = 20_000
    join_timeout_s: float = 2.0
    sensor_size_fallback: tuple[int, int] = SPECK_DVS_SIZE
    readout: ReadoutParams | None = None

    def __post_init__(self) -> None:
        prefixes = self.device_type_prefixes
        if isinstance(prefixes, str):
            prefixes = (prefixes,)
        object.__setattr__(self, "device_type_prefixes", tuple(prefixes))
        if not self.device_type_prefixes or not all(
            isinstance(p, str) and p for p in self.device_type_prefixes
        ):
            raise ValueError(f"device_type_prefixes must be non-empty strings, got {prefixes!r}")
        if int(self.queue_events) < 1:
            raise ValueError(f"queue_events must be >= 1, got {self.queue_events}")
        if not (isinstance(self.read_timeout_ms, int) and 1 <= self.read_timeout_ms <= 10_000):
            raise ValueError(
                f"read_timeout_ms must be an int in 1..10000 ms, got {self.read_timeout_ms!r}"
            )
        if self.latency_margin_us < 0 or self.join_timeout_s < 0:
            raise ValueError("latency_margin_us and join_timeout_s must be >= 0")
        if self.readout is not None:
            check_readout_for_chip(self.readout)


class SpeckSource(EventSourceBase):
    """Raw DVS events from a Speck dev kit as an :class:`EventSource`.

    ``config``: a prepared samna ``SpeckConfiguration`` to apply instead of a fresh one
    (the attention front end's, :func:`hardware.speck_network.deploy`): its cores are
    kept as they are and the DVS layer's monitor is switched on in it
    (:func:`monitor_dvs`), so one configuration runs the network and streams the
    camera's events. Without it the cores are silenced.

    Queue policy: the reader thread never waits for the consumer; when more than
    ``queue_events`` events are buffered the *oldest* are discarded (a live camera
    driving a controller needs the newest events) and counted in
    ``stats["dropped_overflow"]``. Events that arrive for a window already read, or
    out of time order, are discarded and counted as ``late``; non-DVS events are
    counted by type name in ``stats["other_events"]``.
    """

    def __init__(
        self, params: SpeckParams | None = None, config: Any = None, **overrides: Any
    ) -> None:
        base = params if params is not None else SpeckParams()
        self.params = replace(base, **overrides) if overrides else base
        self.prepared_config = config
        super().__init__((*self.params.sensor_size_fallback, 2))
        self.device_type_name: str | None = None
        self._samna: ModuleType | None = None
        self._device: Any = None
        self._graph: Any = None
        self._sink: Any = None
        self._stop_watch: Any = None
        self._dvs_event_type: type | None = None
        self._sensor_size_from = "not started"
        self._cond = threading.Condition()
        self._chunks: deque[np.ndarray] = deque()
        self._buffered = 0
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._reader_error: BaseException | None = None
        self._t0_host = 0.0
        self._max_t = -1  # highest timestamp queued so far (unwrapped)
        self._last_raw = -1  # last unwrapped timestamp seen, for wrap detection
        self._wrap_offset = 0
        self._other: Counter[str] = Counter()
        self._close_errors: list[str] = []
        self._n = dict.fromkeys(
            (
                "received",
                "delivered",
                "dropped_overflow",
                "late",
                "out_of_range",
                "batches",
                "empty_polls",
                "wraps",
            ),
            0,
        )

    # -- EventSource ---------------------------------------------------------------

    @property
    def dropped(self) -> int:
        """Events lost: queue overflow + late/out-of-order + out of the sensor."""
        with self._cond:
            return self._n["dropped_overflow"] + self._n["late"] + self._n["out_of_range"]

    @property
    def stats(self) -> dict[str, Any]:
        with self._cond:
            thread = self._thread
            return {
                **self._n,
                "buffered": self._buffered,
                "other_events": dict(self._other),
                "other_total": sum(self._other.values()),
                "device_type_name": self.device_type_name,
                "sensor_size": self._sensor_size,
                "sensor_size_from": self._sensor_size_from,
                "reader_alive": thread is not None and thread.is_alive(),
                "reader_error": repr(self._reader_error) if self._reader_error else None,
                "close_errors": list(self._close_errors),
                "cursor_us": self._cursor_us,
            }

    @property
    def device(self) -> Any:
        """samna's handle of the open device (``None`` before :meth:`start` and after
        :meth:`close`): the front end's :class:`~hardware.speck_network.ChipPipeline`
        reads the cores' spikes through it."""
        return self._device

    def now_us(self) -> int:
        """Device time estimated from the host clock (µs since the stop watch reset)."""
        return int((time.monotonic() - self._t0_host) * 1e6) if self._started else 0

    def start(self) -> None:
        """Open the device, configure raw DVS output, reset its clock, start reading."""
        if self._closed:
            raise RuntimeError("SpeckSource is closed; create a new one")
        if self._started:
            return
        samna = import_samna()
        self._samna = samna
        try:
            self._open(samna)
        except BaseException:
            self.close()
            raise
        atexit.register(self.close)

    def read(
        self,
        duration_us: int | None = None,
        *,
        until_t_us: int | None = None,
        timeout_s: float | None = None,
    ) -> np.ndarray:
        """Events with ``cursor <= t < end``; see :mod:`hardware.event_source`.

        With a window, waits until an event at or after its end has arrived (all
        earlier ones are then in) or, failing that, until the host clock passes the
        end by ``latency_margin_us``, or ``timeout_s``. Without one, returns what has
        arrived. Raises ``RuntimeError`` if the reader thread failed.
        """
        self._check_running()
        end = self._window_end(duration_us, until_t_us)
        with self._cond:
            if end is not None:
                deadline = self._t0_host + (end + self.params.latency_margin_us) / 1e6
                if timeout_s is not None:
                    deadline = min(deadline, time.monotonic() + timeout_s)
                while self._max_t < end and self._reader_error is None and self._reader_running():
                    remaining = deadline - time.monotonic()
                    if remaining <= 0:
                        break
                    self._cond.wait(remaining)
            if self._reader_error is not None:
                raise RuntimeError(
                    f"Speck reader thread failed: {self._reader_error!r}"
                ) from self._reader_error
            return self._take(end)

    def close(self) -> None:
        """Stop the reader, stop the graph, switch the stop watch off, close the device.

        Idempotent; errors while closing are warned about and kept in
        ``stats["close_errors"]`` rather than raised (close often runs while
        another exception propagates).
        """
        if self._closed:
            return
        self._closed = True
        atexit.unregister(self.close)
        self._stop.set()
        thread = self._thread
        if thread is not None and thread is not threading.current_thread():
            thread.join(self.params.join_timeout_s + self.params.read_timeout_ms / 1000)
            if thread.is_alive():
                self._close_error("reader thread did not stop in time")
            else:
                self._thread = None
        graph, stop_watch, device, samna = self._graph, self._stop_watch, self._device, self._samna
        steps: list[tuple[str, Any]] = []
        if graph is not None:
            steps.append(("stop graph", graph.stop))
        if stop_watch is not None:
            steps.append(("stop watch off", lambda: stop_watch.set_enable_value(False)))
        if device is not None and samna is not None:
            steps.append(("close device", lambda: samna.device.close_device(device)))
        for what, step in steps:
            try:
                step()
            except Exception as err:
                self._close_error(f"{what}: {err!r}")
        self._graph = self._stop_watch = self._device = self._sink = None
        with self._cond:
            self._cond.notify_all()

    # -- opening -------------------------------------------------------------------

    def _select_device(self, samna: ModuleType) -> Any:
        infos = list(samna.device.get_unopened_devices())
        want_serial = self.params.serial_number
        for prefix in self.params.device_type_prefixes:
            for info in infos:
                if not str(info.device_type_name).lower().startswith(prefix.lower()):
                    continue
                if want_serial is None or str(info.serial_number) == want_serial:
                    return info
        found = (
            ", ".join(f"{info.device_type_name} (serial {info.serial_number!r})" for info in infos)
            or "no devices at all"
        )
        serial = f" with serial {want_serial!r}" if want_serial is not None else ""
        raise RuntimeError(
            f"no unopened Speck whose device_type_name starts with "
            f"{' or '.join(self.params.device_type_prefixes)}{serial}; samna found: {found}. "
            "Check the USB cable, and that no other process (samnagui, a notebook) holds it: "
            "samna lists only unopened devices."
        )

    def _open(self, samna: ModuleType) -> None:
        info = self._select_device(samna)
        family = chip_family(info.device_type_name)
        chip = getattr(samna, family, None)
        if chip is None:
            raise RuntimeError(f"this samna has no samna.{family} for {info.device_type_name!r}")
        self._dvs_event_type = chip.event.DvsEvent
        sink_type = getattr(samna, f"BasicSinkNode_{family}_event_output_event")

        config = self.prepared_config
        if config is None:
            config = chip.configuration.SpeckConfiguration()
            silence_cores(config)
        elif not isinstance(config, chip.configuration.SpeckConfiguration):
            raise RuntimeError(
                f"the prepared configuration is a {type(config).__module__}."
                f"{type(config).__name__}, not samna.{family}'s SpeckConfiguration for "
                f"{info.device_type_name!r}"
            )
        self._sensor_size, self._sensor_size_from = sensor_size_from(
            config, self.params.sensor_size_fallback
        )
        readout = self.params.readout
        monitor_dvs(config, readout)
        if readout is not None:
            w, h = SpeckReadout(*self._sensor_size[:2], readout).output_size
            self._sensor_size, self._sensor_size_from = (w, h, 2), "readout dvs_layer region"
            self._dvs_event_type = chip.event.Spike

        device = samna.device.open_device(info)
        if device is None:
            raise RuntimeError(
                f"samna.device.open_device returned None for {info.device_type_name}"
            )
        self._device = device
        self.device_type_name = str(info.device_type_name)

        sink = sink_type()
        graph = samna.graph.EventFilterGraph()
        graph.sequential([device.get_model_source_node(), sink])
        self._graph, self._sink = graph, sink
        graph.start()

        device.get_model().apply_configuration(config)
        if readout is not None and readout.dvs_filter.enable:  # the filter's slow clock
            io = device.get_io_module()
            io.set_slow_clock(True)
            io.set_slow_clk_rate(readout.slow_clk_rate_hz)
        stop_watch = device.get_stop_watch()
        self._stop_watch = stop_watch
        stop_watch.set_enable_value(True)
        stop_watch.reset()
        self._t0_host = time.monotonic()
        sink.get_events()  # discard anything stamped before the reset (as sinabs does before a run)

        self._started = True
        self._thread = threading.Thread(
            target=self._reader, name=f"speck-reader-{self.device_type_name}", daemon=True
        )
        self._thread.start()

    # -- reader thread -------------------------------------------------------------

    def _reader_running(self) -> bool:
        return self._thread is not None and self._thread.is_alive() and not self._stop.is_set()

    def _reader(self) -> None:
        sink, timeout_ms = self._sink, int(self.params.read_timeout_ms)
        try:
            while not self._stop.is_set():
                batch = sink.get_events_blocking(timeout_ms)
                if batch:
                    self._ingest(batch)
                else:
                    with self._cond:
                        self._n["empty_polls"] += 1
        except BaseException as err:
            with self._cond:
                self._reader_error = err
                self._cond.notify_all()

    def _convert(self, batch: list[Any]) -> tuple[np.ndarray, Counter[str]]:
        """DVS events of a samna batch as an event array (unsorted); other events counted."""
        dvs_type = self._dvs_event_type
        assert dvs_type is not None
        processed = self.params.readout is not None  # Spike events of the DVS layer
        dvs = [
            e
            for e in batch
            if isinstance(e, dvs_type) and (not processed or e.layer == DVS_LAYER_ID)
        ]
        other: Counter[str] = Counter()
        if len(dvs) != len(batch):
            dvs_ids = {id(e) for e in dvs}
            other.update(type(e).__name__ for e in batch if id(e) not in dvs_ids)
        n = len(dvs)
        ev = np.empty(n, dtype=EVENT_DTYPE)
        if n:
            x = np.fromiter((e.x for e in dvs), dtype=np.int64, count=n)
            y = np.fromiter((e.y for e in dvs), dtype=np.int64, count=n)
            polarity = (lambda e: e.feature) if processed else (lambda e: e.p)
            p = np.fromiter((polarity(e) for e in dvs), dtype=np.int64, count=n)
            t = np.fromiter((e.timestamp for e in dvs), dtype=np.int64, count=n)
            w, h = self._sensor_size[0], self._sensor_size[1]
            ok = (x >= 0) & (x < w) & (y >= 0) & (y < h)
            if not ok.all():
                with self._cond:
                    self._n["out_of_range"] += int(n - ok.sum())
                x, y, p, t = x[ok], y[ok], p[ok], t[ok]
                ev = np.empty(len(t), dtype=EVENT_DTYPE)
            ev["x"], ev["y"], ev["t"] = x, y, self._unwrap(t)
            ev["p"] = p != 0  # samna DvsEvent.p: 1 (True) = ON
        return ev, other

    def _unwrap(self, t: np.ndarray) -> np.ndarray:
        """Undo 32-bit wraparounds of the device timestamps (a drop of more than 2^31 µs)."""
        if len(t) == 0:
            return t
        t = t + self._wrap_offset
        prev = np.concatenate(([self._last_raw], t[:-1]))
        wraps = np.cumsum((prev - t) > _TS_WRAP // 2)
        if wraps[-1]:
            t = t + wraps * _TS_WRAP
            self._wrap_offset += int(wraps[-1]) * _TS_WRAP
            with self._cond:
                self._n["wraps"] += int(wraps[-1])
        self._last_raw = int(t[-1])
        return t

    def _ingest(self, batch: list[Any]) -> None:
        ev, other = self._convert(batch)
        if len(ev) > 1 and np.any(np.diff(ev["t"]) < 0):
            ev = ev[np.argsort(ev["t"], kind="stable")]
        with self._cond:
            self._n["batches"] += 1
            self._other.update(other)
            self._n["received"] += len(ev)
            if len(ev) and ev["t"][0] < self._max_t:  # older than what is queued: out of order
                keep = ev["t"] >= self._max_t
                self._n["late"] += int(len(ev) - keep.sum())
                ev = ev[keep]
            if len(ev):
                self._chunks.append(ev)
                self._buffered += len(ev)
                self._max_t = int(ev["t"][-1])
                self._trim_oldest()
            self._cond.notify_all()

    def _trim_oldest(self) -> None:
        excess = self._buffered - int(self.params.queue_events)
        while excess > 0 and self._chunks:
            head = self._chunks[0]
            if len(head) <= excess:
                self._chunks.popleft()
                cut = len(head)
            else:
                self._chunks[0] = head[excess:]
                cut = excess
            excess -= cut
            self._buffered -= cut
            self._n["dropped_overflow"] += cut

    # -- consumer side (called with the lock held) ------------------------------------

    def _take(self, end: int | None) -> np.ndarray:
        """Remove and return the queued events with ``t < end`` (all if ``end`` is None)."""
        taken: list[np.ndarray] = []
        while self._chunks:
            chunk = self._chunks[0]
            if end is None or chunk["t"][-1] < end:
                taken.append(self._chunks.popleft())
                continue
            k = int(np.searchsorted(chunk["t"], end, side="left"))
            if k:
                taken.append(chunk[:k])
                self._chunks[0] = chunk[k:]
            break
        out = np.concatenate(taken) if taken else empty_events()
        self._buffered -= len(out)
        if len(out) and out["t"][0] < self._cursor_us:  # arrived after its window was read
            keep = out["t"] >= self._cursor_us
            self._n["late"] += int(len(out) - keep.sum())
            out = out[keep]
        self._n["delivered"] += len(out)
        if end is not None:
            self._cursor_us = end
        elif len(out):
            self._cursor_us = max(self._cursor_us, int(out["t"][-1]) + 1)
        return out

    def _close_error(self, message: str) -> None:
        with self._cond:
            self._close_errors.append(message)
        warnings.warn(f"SpeckSource.close: {message}", RuntimeWarning, stacklevel=3)
