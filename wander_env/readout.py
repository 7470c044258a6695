"""Speck's readout after the DVS emulator: what the chip does to the pixels' events
before the host sees them (:class:`SpeckReadout`, parameters :class:`ReadoutParams`).

The stages, in the order an event meets them (each off unless asked for):

1. **Kill mask** (``kill_pixels``): pixels whose kill bit is set never send an event
   (counted ``killed``).
2. **Arbiter** (``throughput_eps``, ``queue_depth``): the pixel array's events leave one
   at a time, ``1 / throughput_eps`` apart, first in first out; an event that finds
   ``queue_depth`` events in the arbiter (waiting or being read) is dropped
   (``dropped_queue``). The model is IEBCS's ``BottleNeckArbiter``
   (neuromorphicsystems/IEBCS ``src/arbiter.py``; Joubert et al., Front. Neurosci.
   2021): one server with a fixed time per event, events released in arrival order and
   stamped when they leave. It was chosen over a tile arbiter (TIDES) because Speck's
   documents name no arbiter structure, tile geometry or per-tile rate: the one number
   such a model needs (a throughput) is the one a measurement on the rig can give. To
   IEBCS's unbounded buffer it adds a finite queue that drops the newest events when full
   (the datasheet's congestion balancer drops a busy core's input the same way).
   The service time is rounded to 1 ns.
3. **1 µs timestamps**: an event is stamped when it leaves the arbiter, on Speck's µs
   counter (datasheet §3.2.5.3; ``hardware/speck.py`` reads ``DvsEvent.timestamp`` in
   µs): ``floor(departure / 1 µs)``. The emulator already emits whole µs, so with the
   arbiter off the stamps are unchanged.
4. **DVS filter** (``dvs_filter``; datasheet §3.2.3.5), one mode at a time, timed by the
   slow clock (``slow_clk_rate_hz``; ticks counted from :meth:`SpeckReadout.reset`). Each
   pixel keeps the slow-clock tick of its last event (16 Ki words of filter memory: one
   per pixel of the 128 × 128 array), written by every event that reaches the filter.

   - *noise filter* (``enable``): an event passes when some pixel of the
     ``filter_size`` window around it (the pixel itself included, so that the
     documented 1 × 1 window is meaningful) had an event fewer than ``threshold``
     ticks before it (``filtered_noise`` otherwise);
   - *noise + hot-pixel filter* (``enable`` and ``hot_pixel_filter_enable``): as the
     noise filter, but the pixel's own past events do not count as support, so a pixel
     firing alone (a hot pixel, 50–1000 Hz in the datasheet) is blocked; an event that
     only its own pixel supported is counted ``filtered_hot``;
   - *flicker filter* (``enable`` and ``low_pass_mode_enable``): an event less than
     ``threshold`` ticks after the same pixel's previous event is blocked
     (``filtered_flicker``; the datasheet's example: 1 kHz and 25 → 25 ms).

   The datasheet describes the behaviour, not the circuit: the window's centring, the
   inclusion of the pixel itself and what the hot-pixel mode adds are this module's
   reading of it. Counters do not wrap (the chip's filter words are 16 bits).
5. **The DVS layer** (``dvs_layer``; datasheet §3.2.3.1–4), in sinabs ``DVSLayer``'s
   order: polarity (``on_channel`` / ``off_channel``: a switched-off channel's events are
   counted ``channel_off``; ``merge``: both polarities as one channel, ``p = 0``), sum
   pooling (``pooling`` 1, 2 or 4 per axis: each event moves to ``(x // px, y // py)``,
   one event in, one out), the region of interest (``origin`` / ``cut``: inclusive corners
   on the pooled grid, shifted to start at (0, 0); events outside it are counted
   ``outside_roi``) and mirroring (``mirror`` x / y flip the region, then
   ``mirror_diagonal`` swaps x and y).
6. **Host packets** (``batch_interval_us``, ``latency_us``): events travel to the host in
   packets covering ``[t0 + k·B, t0 + (k+1)·B)`` of device time; a packet is delivered
   ``latency_us`` after it closes, with each event keeping its own timestamp. Events not
   yet delivered are ``pending`` (as are those still in the arbiter).

Names: the fields of ``dvs_layer`` and ``dvs_filter`` are samna's
(``samna.speck2f.configuration.SpeckConfiguration.dvs_layer`` / ``.dvs_filter``:
``pooling``, ``origin``, ``cut``, ``mirror``, ``mirror_diagonal``, ``merge``,
``on_channel``, ``off_channel``, ``enable``, ``filter_size``, ``hot_pixel_filter_enable``,
``low_pass_mode_enable``, ``threshold``; pairs are samna's ``.x``/``.y`` as ``(x, y)``),
so one YAML block configures the simulated readout and the chip (``wander rig`` writes
them, :func:`hardware.speck_config.write_readout_config`). The rest are ours: ``kill_pixels``
(the per-pixel kill bits; no public samna name), ``slow_clk_rate_hz`` (samna sets it on
the dev kit's IO module, ``set_slow_clk_rate``), ``throughput_eps``, ``queue_depth``,
``batch_interval_us`` and ``latency_us`` (not configurable on the chip).

Every event is accounted for: per step and in total, ``in = out + killed +
dropped_queue + filtered_noise + filtered_hot + filtered_flicker + channel_off +
outside_roi + (pending now − pending before)``.

Examples:
    >>> import numpy as np
    >>> from wander_env.events import make_events
    >>> ro = SpeckReadout(8, 8, ReadoutParams(throughput_eps=1e6, queue_depth=2))
    >>> ro.reset(0)
    >>> out = ro.step(make_events([1, 2, 3], [0, 0, 0], [0, 0, 0], [1, 1, 1]), t_us=10)
    >>> out["t"].tolist(), ro.counts["dropped_queue"]  # read 1 µs apart; the third is dropped
    ([1, 2], 1)
"""

from __future__ import annotations

import typing
from dataclasses import dataclass, field, fields, replace
from typing import Annotated, Any

import numba
import numpy as np
import pydantic

from wander_env.config import check_annotated
from wander_env.events import EVENT_DTYPE
from wander_env.field_doc import field_doc

__all__ = [
    "COUNTERS",
    "LOST",
    "DvsFilterParams",
    "DvsLayerParams",
    "ReadoutParams",
    "SpeckReadout",
    "arbiter_departures",
    "dvs_layer_map",
    "filter_events",
    "packet_delivery_us",
]

#: Speck's DVS pixel array, (width, height) (sinabs ``play_with_speck_dvs.ipynb``,
#: datasheet §2.2): the chip front end's largest input and the rig's sensor size where
#: the chip's configuration gives no DVS region.
SPECK_DVS_SIZE = (128, 128)

#: The counters of events that leave the stream (each its own share of ``in``).
LOST: tuple[str, ...] = (
    "killed",
    "dropped_queue",
    "filtered_noise",
    "filtered_hot",
    "filtered_flicker",
    "channel_off",
    "outside_roi",
)
#: The counters of :attr:`SpeckReadout.counts` (``info["readout"]``), in order: every
#: event ``in`` goes ``out``, is lost (:data:`LOST`) or is still ``pending``.
COUNTERS: tuple[str, ...] = ("in", "out", *LOST, "pending")

# Filter verdicts of :func:`filter_events`.
PASS, NOISE, HOT, FLICKER = 0, 1, 2, 3
_NEVER = np.iinfo(np.int64).min // 4  # a pixel that has not fired since reset

_Coord = Annotated[int, field_doc("A pixel coordinate", unit="px", ge=0, le=4095)]
_Pool = typing.Literal[1, 2, 4]


@dataclass(frozen=True)
class DvsLayerParams:
    """samna's ``dvs_layer`` fields that shape the events (datasheet §3.2.3.1–4); the
    defaults are samna's (sinabs ``play_with_speck_dvs.ipynb``: pooling 1, mirror off,
    both channels on; ``cut`` None = the whole array, samna's (127, 127) on Speck)."""

    pooling: Annotated[
        tuple[_Pool, _Pool], field_doc("Sum pooling (x, y): 1, 2 or 4 (datasheet §3.2.3.2)")
    ] = (1, 1)
    origin: Annotated[
        tuple[_Coord, _Coord], field_doc("Top-left corner (x, y) of the region, pooled grid")
    ] = (0, 0)
    cut: Annotated[
        tuple[_Coord, _Coord] | None,
        field_doc("Bottom-right corner (x, y) of the region, inclusive (None: the whole grid)"),
    ] = None
    mirror: Annotated[
        tuple[bool, bool], field_doc("Flip the region along x, along y (samna mirror.x/.y)")
    ] = (False, False)
    mirror_diagonal: Annotated[bool, field_doc("Swap x and y (after the flips)")] = False
    merge: Annotated[bool, field_doc("Both polarities as one channel (p = 0)")] = False
    on_channel: Annotated[bool, field_doc("Pass ON events")] = True
    off_channel: Annotated[bool, field_doc("Pass OFF events")] = True

    def __post_init__(self) -> None:
        check_annotated(self)
        if self.cut is not None and (self.cut[0] < self.origin[0] or self.cut[1] < self.origin[1]):
            raise ValueError(f"cut: {self.cut} must not be left of or above origin {self.origin}")

    @property
    def active(self) -> bool:
        """Whether the layer changes any event (a field off its default)."""
        return any(getattr(self, f.name) != f.default for f in fields(self))


@dataclass(frozen=True)
class DvsFilterParams:
    """samna's ``dvs_filter`` (datasheet §3.2.3.5): off by default (samna's default; the
    documented examples switch it on)."""

    enable: Annotated[bool, field_doc("Switch the filter block on")] = False
    filter_size: Annotated[
        tuple[
            Annotated[int, field_doc("Window width", ge=0, le=15)],
            Annotated[int, field_doc("Window height", ge=0, le=15)],
        ],
        field_doc("Noise filter window (x, y), 1..15 (0 in the low-pass mode)", unit="px"),
    ] = (3, 3)
    hot_pixel_filter_enable: Annotated[
        bool, field_doc("Noise filter + hot-pixel filter: a pixel's own events are no support")
    ] = False
    low_pass_mode_enable: Annotated[
        bool, field_doc("Flicker (low-pass) filter instead of the noise filter")
    ] = False
    threshold: Annotated[
        int, field_doc("Support window / flicker period in slow-clock ticks", ge=1, le=65535)
    ] = 5

    def __post_init__(self) -> None:
        check_annotated(self)
        if self.hot_pixel_filter_enable and self.low_pass_mode_enable:
            raise ValueError(
                "hot_pixel_filter_enable: the filter runs one mode at a time (datasheet "
                "§3.2.3.5.4); not with low_pass_mode_enable"
            )
        if self.enable and not self.low_pass_mode_enable and min(self.filter_size) < 1:
            raise ValueError(f"filter_size: the noise filter needs >= 1, got {self.filter_size}")

    @property
    def mode(self) -> int:
        """0 off, 1 noise, 2 noise + hot pixel, 3 flicker."""
        if not self.enable:
            return 0
        if self.low_pass_mode_enable:
            return 3
        return 2 if self.hot_pixel_filter_enable else 1


def _check_kill(value: tuple[tuple[int, int], ...]) -> tuple[tuple[int, int], ...]:
    if len(set(value)) != len(value):
        raise ValueError("a pixel is listed twice")
    return value


@dataclass(frozen=True)
class ReadoutParams:
    """The readout's parameters; every stage off by default (:meth:`preset` ``"ideal"``).

    ``dvs_layer`` and ``dvs_filter`` hold samna's field names; the others are ours (see
    the module docstring)."""

    kill_pixels: Annotated[
        tuple[tuple[_Coord, _Coord], ...],
        field_doc("Pixels (x, y) whose kill bit is set: they send nothing"),
        pydantic.AfterValidator(_check_kill),
    ] = ()
    dvs_layer: DvsLayerParams = field(default_factory=DvsLayerParams)
    dvs_filter: DvsFilterParams = field(default_factory=DvsFilterParams)
    slow_clk_rate_hz: Annotated[
        int,
        field_doc("Slow clock timing the filter (datasheet: 10 Hz-10 kHz)", "Hz", ge=10, le=10_000),
    ] = 1000
    throughput_eps: Annotated[
        float | None,
        field_doc("Arbiter throughput (None: no arbiter)", unit="events/s", gt=0, le=1e9),
    ] = None
    queue_depth: Annotated[
        int | None, field_doc("Events the arbiter holds (None: no limit)", ge=1, le=1 << 24)
    ] = None
    batch_interval_us: Annotated[
        int | None,
        field_doc("Host packets cover this much device time (None: no packets)", "µs", ge=1),
    ] = None
    latency_us: Annotated[
        int, field_doc("A packet reaches the host this long after it closes", "µs", ge=0)
    ] = 0

    def __post_init__(self) -> None:
        check_annotated(self)
        if self.queue_depth is not None and self.throughput_eps is None:
            raise ValueError("queue_depth: a queue needs an arbiter (give throughput_eps)")

    @property
    def service_ns(self) -> int:
        """The arbiter's time per event, rounded to 1 ns (0: no arbiter)."""
        return 0 if self.throughput_eps is None else max(1, round(1e9 / self.throughput_eps))

    @classmethod
    def preset(cls, name: str, **overrides: Any) -> ReadoutParams:
        """``"ideal"`` (every stage off), ``"speck"`` (samna's defaults, as the paper's rig
        runs the chip, plus the assumed arbiter and host link) or ``"speck_filtered"``
        (``speck`` with the datasheet's noise + hot-pixel filter example), with optional
        field overrides."""
        # Values marked "assumption" have no published Speck figure: each says what it
        # stands on; measure them on the rig (docs/readout.md).
        speck = dict(
            # samna defaults (sinabs play_with_speck_dvs.ipynb): pooling 1, whole array,
            # no mirror, both channels, no merge; dvs_filter off (its examples enable it).
            # The paper's public rig script (Speckegomotion functions/Speck_helpers.py)
            # streams the raw pixel array with no filter.
            dvs_layer=DvsLayerParams(),
            dvs_filter=DvsFilterParams(),
            # Datasheet §3.2.6.3.2: the dev kit's example slow clock, set_slow_clk_rate(1000).
            slow_clk_rate_hz=1000,
            # Assumption: no arbiter rate is published for Speck (datasheet, samna, sinabs);
            # 1 Meps is a round order of magnitude for a 128 × 128 AER readout.
            throughput_eps=1e6,
            # Assumption: 1024 events; Speck publishes no FIFO size.
            queue_depth=1024,
            # Assumption: host packets every 1 ms (USB 3 bulk transfers, 125 µs microframes,
            # batched by samna), delivered 1 ms after closing; the rig's reader waits up
            # to 20 ms for a window's last events (hardware/speck.py latency_margin_us).
            batch_interval_us=1000,
            latency_us=1000,
        )
        presets: dict[str, dict[str, Any]] = {
            "ideal": {},
            "speck": speck,
            # Datasheet §3.2.3.5.3 and sinabs play_with_speck_dvs.ipynb: enable, 3 × 3
            # window, hot_pixel_filter_enable, threshold 5 (at the 1 kHz slow clock: 5 ms).
            "speck_filtered": {
                **speck,
                "dvs_filter": DvsFilterParams(
                    enable=True, filter_size=(3, 3), hot_pixel_filter_enable=True, threshold=5
                ),
            },
        }
        if name not in presets:
            raise ValueError(f"unknown readout preset {name!r}; choose one of {sorted(presets)}")
        return replace(cls(**presets[name]), **overrides)


# ----------------------------------------------------------------------------------------
# Pure functions


@numba.njit(cache=True, nogil=True)
def _fifo(
    t_ns: np.ndarray, backlog_ns: np.ndarray, service_ns: int, depth: int, out: np.ndarray
) -> int:
    """Departure time (ns) of each arrival (-1: dropped), after ``backlog_ns`` (the
    departures still ahead, sorted); returns how many were dropped."""
    nb = backlog_ns.size
    deps = np.empty(nb + t_ns.size, np.int64)
    deps[:nb] = backlog_ns
    n = nb
    head = 0
    last = backlog_ns[nb - 1] if nb else np.iinfo(np.int64).min
    dropped = 0
    for i in range(t_ns.size):
        t = t_ns[i]
        while head < n and deps[head] <= t:
            head += 1
        if depth > 0 and n - head >= depth:
            out[i] = -1
            dropped += 1
            continue
        d = max(t, last) + service_ns
        deps[n] = d
        n += 1
        last = d
        out[i] = d
    return dropped


def arbiter_departures(
    t_us: np.ndarray, service_ns: int, depth: int | None, backlog_ns: np.ndarray | None = None
) -> np.ndarray:
    """When each event (arrival times ``t_us``, sorted) leaves a FIFO arbiter reading one
    event per ``service_ns`` and holding at most ``depth`` (None: no limit), in ns; -1 for
    a dropped event. ``backlog_ns``: departures of events already inside (sorted).

    >>> arbiter_departures(np.array([0, 0, 0, 0]), 1000, 3).tolist()
    [1000, 2000, 3000, -1]
    """
    out = np.empty(len(t_us), np.int64)
    backlog = np.empty(0, np.int64) if backlog_ns is None else np.asarray(backlog_ns, np.int64)
    _fifo(np.asarray(t_us, np.int64) * 1000, backlog, int(service_ns), depth or 0, out)
    return out


@numba.njit(cache=True, nogil=True)
def _filter(x, y, tick, last, width, height, fx, fy, threshold, mode, out):
    """See :func:`filter_events`; ``last`` (H·W) is updated in place."""
    ax, bx = (fx - 1) // 2, fx // 2
    ay, by = (fy - 1) // 2, fy // 2
    for i in range(x.size):
        xi, yi, k = np.int64(x[i]), np.int64(y[i]), tick[i]
        own = yi * width + xi
        if mode == 3:
            out[i] = FLICKER if k - last[own] < threshold else PASS
            last[own] = k
            continue
        support = False
        for yy in range(max(yi - ay, 0), min(yi + by, height - 1) + 1):
            for xx in range(max(xi - ax, 0), min(xi + bx, width - 1) + 1):
                j = yy * width + xx
                if j != own and k - last[j] < threshold:
                    support = True
        if support:
            out[i] = PASS
        elif k - last[own] < threshold:
            out[i] = HOT if mode == 2 else PASS
        else:
            out[i] = NOISE
        last[own] = k


def filter_events(
    x: np.ndarray,
    y: np.ndarray,
    tick: np.ndarray,
    last_tick: np.ndarray,
    params: DvsFilterParams,
) -> np.ndarray:
    """The filter's verdict on each event (0 pass, 1 noise, 2 hot pixel, 3 flicker) given
    its slow-clock ``tick``; ``last_tick`` (H, W) int64, each pixel's last tick, is
    updated in place (the filter memory). Events in time order."""
    out = np.zeros(len(x), np.int8)
    if params.mode == 0 or len(x) == 0:
        return out
    h, w = last_tick.shape
    fx, fy = params.filter_size
    flat = last_tick.reshape(-1)
    _filter(
        x, y, np.asarray(tick, np.int64), flat, w, h, fx, fy, params.threshold, params.mode, out
    )
    return out


def dvs_layer_map(
    x: np.ndarray, y: np.ndarray, p: np.ndarray, params: DvsLayerParams, size: tuple[int, int]
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The DVS layer on events of a ``size`` = (W, H) array: ``(x, y, p, channel_off,
    outside_roi)``, the last two boolean masks of the removed events (the coordinates
    of removed events are meaningless).

    >>> dvs_layer_map(np.array([5]), np.array([2]), np.array([1]),
    ...               DvsLayerParams(pooling=(2, 2), mirror=(True, False)), (8, 8))[:2]
    (array([1]), array([1]))
    """
    keep_p = np.where(p != 0, params.on_channel, params.off_channel)
    px, py = params.pooling
    xo, yo = x.astype(np.int64) // px, y.astype(np.int64) // py
    w, h = -(-size[0] // px), -(-size[1] // py)
    (ox, oy), (cx, cy) = params.origin, params.cut or (w - 1, h - 1)
    inside = (xo >= ox) & (xo <= cx) & (yo >= oy) & (yo <= cy)
    xo, yo = xo - ox, yo - oy
    if params.mirror[1]:
        yo = (cy - oy) - yo
    if params.mirror[0]:
        xo = (cx - ox) - xo
    if params.mirror_diagonal:
        xo, yo = yo, xo
    po = np.zeros_like(p) if params.merge else p
    return xo, yo, po, ~keep_p, keep_p & ~inside


def packet_delivery_us(t: np.ndarray, t0: int, batch_us: int | None, latency_us: int) -> np.ndarray:
    """When the host receives each event stamped ``t`` (µs): its packet ``[t0 + k·B,
    t0 + (k+1)·B)`` closes at ``t0 + (k+1)·B``, plus ``latency_us`` (no packets: ``t +
    latency_us``).

    >>> packet_delivery_us(np.array([0, 999, 1000]), 0, 1000, 50).tolist()
    [1050, 1050, 2050]
    """
    t = np.asarray(t, np.int64)
    if batch_us is None:
        return t + latency_us
    return t0 + ((t - t0) // batch_us + 1) * batch_us + latency_us


def _events(x: np.ndarray, y: np.ndarray, t: np.ndarray, p: np.ndarray) -> np.ndarray:
    ev = np.empty(len(t), EVENT_DTYPE)
    ev["x"], ev["y"], ev["t"], ev["p"] = x, y, t, p
    return ev


# ----------------------------------------------------------------------------------------
# The stateful stage


class SpeckReadout:
    """The readout of a ``width`` × ``height`` pixel array (see the module docstring).

    :meth:`reset` at the stream's start, then :meth:`step` once per window with that
    window's events (sorted by ``t``): it returns the events the host has received by
    ``t_us``. :attr:`counts` holds the last step's counters, :attr:`totals` the sums
    since reset (``pending``: events held now, in both).
    """

    def __init__(self, width: int, height: int, params: ReadoutParams | None = None) -> None:
        self.width, self.height = int(width), int(height)
        self.params = params if params is not None else ReadoutParams()
        p = self.params
        for x, y in p.kill_pixels:
            if x >= self.width or y >= self.height:
                raise ValueError(
                    f"kill_pixels: ({x}, {y}) is outside the {self.width}x{self.height} array"
                )
        if p.dvs_layer.cut is not None:
            cx, cy = p.dvs_layer.cut
            pw = -(-self.width // p.dvs_layer.pooling[0])
            ph = -(-self.height // p.dvs_layer.pooling[1])
            if cx >= pw or cy >= ph:
                raise ValueError(
                    f"dvs_layer.cut: {p.dvs_layer.cut} is outside the pooled {pw}x{ph} grid"
                )
        w, h = self.output_size
        if w > self.width or h > self.height:
            raise ValueError(
                f"dvs_layer.mirror_diagonal: the swapped {w}x{h} region does not fit the "
                f"{self.width}x{self.height} array"
            )
        self._alive = np.ones((self.height, self.width), bool)
        for x, y in p.kill_pixels:
            self._alive[y, x] = False
        self._t0: int | None = None
        self.counts: dict[str, int] = dict.fromkeys(COUNTERS, 0)
        self.totals: dict[str, int] = dict.fromkeys(COUNTERS, 0)

    @property
    def output_size(self) -> tuple[int, int]:
        """(W, H) of the events the readout emits (after pooling, the region, mirroring)."""
        layer = self.params.dvs_layer
        w = -(-self.width // layer.pooling[0])
        h = -(-self.height // layer.pooling[1])
        (ox, oy), (cx, cy) = layer.origin, layer.cut or (w - 1, h - 1)
        w, h = cx - ox + 1, cy - oy + 1
        return (h, w) if layer.mirror_diagonal else (w, h)

    def reset(self, t_us: int) -> None:
        """Start a stream at ``t_us``: empty queue and packets, filter memory cleared,
        slow clock at tick 0, counters zero."""
        self._t0 = self._t_prev = int(t_us)
        self._queue = np.empty(0, EVENT_DTYPE)  # in the arbiter (t: arrival, µs)
        self._queue_dep = np.empty(0, np.int64)  # their departures (ns)
        self._host = np.empty(0, EVENT_DTYPE)  # stamped, processed, not yet delivered
        self._last_tick = np.full((self.height, self.width), _NEVER, np.int64)
        self.counts = dict.fromkeys(COUNTERS, 0)
        self.totals = dict.fromkeys(COUNTERS, 0)

    @property
    def pending(self) -> int:
        """Events held: in the arbiter or in packets not yet delivered."""
        return len(self._queue) + len(self._host)

    def step(self, events: np.ndarray, t_us: int) -> np.ndarray:
        """The events the host has received by ``t_us`` (sorted by ``t``), after feeding
        the window's ``events`` (sorted, with ``t <= t_us``)."""
        if self._t0 is None:
            raise RuntimeError("call reset(t_us) before step()")
        t_us = int(t_us)
        if t_us < self._t_prev:
            raise ValueError(f"time must not go back: t_us={t_us} < previous {self._t_prev}")
        if len(events):
            if int(events["t"][-1]) > t_us:
                raise ValueError(f"events after the window's end: t={events['t'][-1]} > {t_us}")
            x, y = events["x"], events["y"]
            if min(x.min(), y.min()) < 0 or x.max() >= self.width or y.max() >= self.height:
                raise ValueError(f"events outside the {self.width}x{self.height} array")
        self._t_prev = t_us
        p = self.params
        c = dict.fromkeys(COUNTERS, 0)
        c["in"] = len(events)
        if p.kill_pixels:
            alive = self._alive[events["y"], events["x"]]
            c["killed"] = int(len(events) - alive.sum())
            events = events[alive]
        released = self._arbiter(events, t_us, c)
        released = self._layer(released, c)
        out = self._deliver(released, t_us)
        c["out"] = len(out)
        c["pending"] = self.pending
        self.counts = c
        for k in COUNTERS:
            self.totals[k] = c[k] if k == "pending" else self.totals[k] + c[k]
        return out

    def _arbiter(self, events: np.ndarray, t_us: int, c: dict[str, int]) -> np.ndarray:
        """Events that have left the arbiter by ``t_us``, stamped with their departure."""
        p = self.params
        if p.throughput_eps is None:
            return events
        dep = arbiter_departures(events["t"], p.service_ns, p.queue_depth, self._queue_dep)
        kept = dep >= 0
        c["dropped_queue"] = int(len(dep) - kept.sum())
        queue = np.concatenate([self._queue, events[kept]])
        deps = np.concatenate([self._queue_dep, dep[kept]])
        n = int(np.searchsorted(deps, t_us * 1000, side="right"))
        out = queue[:n].copy()
        out["t"] = deps[:n] // 1000
        self._queue, self._queue_dep = queue[n:], deps[n:]
        return out

    def _layer(self, events: np.ndarray, c: dict[str, int]) -> np.ndarray:
        """The filter, then the DVS layer."""
        p = self.params
        if p.dvs_filter.mode:
            ticks = (events["t"].astype(np.int64) - self._t0) * p.slow_clk_rate_hz // 1_000_000
            verdict = filter_events(events["x"], events["y"], ticks, self._last_tick, p.dvs_filter)
            c["filtered_noise"] = int(np.count_nonzero(verdict == NOISE))
            c["filtered_hot"] = int(np.count_nonzero(verdict == HOT))
            c["filtered_flicker"] = int(np.count_nonzero(verdict == FLICKER))
            events = events[verdict == PASS]
        if not p.dvs_layer.active:
            return events
        x, y, pol, off, outside = dvs_layer_map(
            events["x"], events["y"], events["p"], p.dvs_layer, (self.width, self.height)
        )
        c["channel_off"], c["outside_roi"] = int(off.sum()), int(outside.sum())
        keep = ~(off | outside)
        return _events(x[keep], y[keep], events["t"][keep], pol[keep])

    def _deliver(self, events: np.ndarray, t_us: int) -> np.ndarray:
        """Events whose packet has reached the host by ``t_us``; the rest wait."""
        p = self.params
        if p.batch_interval_us is None and p.latency_us == 0:
            return events
        host = np.concatenate([self._host, events]) if len(self._host) else events
        due = packet_delivery_us(host["t"], self._t0, p.batch_interval_us, p.latency_us)
        n = int(np.searchsorted(due, t_us, side="right"))
        self._host = host[n:]
        return host[:n]
