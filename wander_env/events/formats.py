"""The event-file formats of the field, through maintained libraries.

:func:`wander_env.events.io.read_events` / :func:`~wander_env.events.io.write_events`
dispatch here by suffix:

==========  =====  =====  ================================================================
suffix      read   write  through
==========  =====  =====  ================================================================
``.raw``    yes    yes    Prophesee EVT 3.0: read by ``evt3`` (OpenEB-exact timestamps),
                          written by ``faery``; EVT 2.0: read by ``faery`` (EVT 2.1 is
                          refused: ``faery`` has no decoder for it yet)
``.dat``    yes    no     Prophesee DAT 2 (CD events) by ``faery``
``.es``     yes    no     Event Stream 2.0, DVS type (neuromorphicsystems/sepia) by ``faery``
``.aedat4`` (1)    yes    AEDAT 4.0 written by ``faery`` (LZ4); read by ``aedat`` (1)
==========  =====  =====  ================================================================

(1) the AEDAT 4.0 reader lives in :mod:`wander_env.events.io`.

Why these libraries: ``wander perf formats`` decodes the same real recordings with
each candidate and compares them event for event (README, "Event files"). On a real
Prophesee EVT 3.0 recording ``evt3`` reproduces a word-level decode exactly, ``faery``
differs by up to 11 µs on 0.7 % of the events and ``expelliarmus`` by up to 45 ms on
91 %; ``faery`` is the one maintained library that reads EVT 2, DAT and ES and writes
AEDAT4 and EVT3.

Every reader checks its input before trusting it — the header declares the format, the
body is a whole number of words/events, decoded coordinates fall inside the sensor,
polarities are 0/1, time never runs backwards and the events decoded stay within the
reader's event limit (counted as a decoder produces them, before the file is held in full)
— and raises :class:`~wander_env.events.io.EventFileError` naming the file. A decoder's
failure, a Rust panic inside ``faery`` included, becomes that one error. What a format cannot hold
(wander's JSON metadata, in EVT3 and AEDAT4) is said here and in the README, not lost
silently: write an ``.h5`` beside it to keep it.

wander's own ``.h5`` files and their DSEC ``ms_to_idx`` index are
:mod:`wander_env.events.io`'s and :mod:`wander_env.events.hdf5_index`'s; the EVIMO2
dataset layout is written by :mod:`wander_env.events.evimo2`.

Examples:
    >>> import tempfile, pathlib
    >>> from wander_env.events import make_events
    >>> from wander_env.events.io import EventRecording, read_events, write_events
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "demo.raw"
    >>> ev = make_events(x=[3, 1], y=[0, 2], t=[10, 2500], p=[1, 0])
    >>> write_events(path, EventRecording(ev, (4, 4, 2)))
    >>> read_events(path).events["t"].tolist()
    [10, 2500]
"""

from __future__ import annotations

import re
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np

from wander_env.events import SensorSize
from wander_env.events.checks import (
    EventFileError,
    EventRecording,
    ReadLimits,
    check_sensor_size,
    checked_recording,
)

# Prophesee sensors whose headers omit the geometry (older plugins), by plugin name:
# the Gen3/Gen3.1 sensors are VGA, the Gen4.1/IMX636 ones HD.
_VGA, _HD = (640, 480), (1280, 720)
PLUGIN_GEOMETRY = {
    "hal_plugin_gen3_fx3": _VGA,
    "hal_plugin_gen31_fx3": _VGA,
    "hal_plugin_gen31_evk2": _VGA,
    "hal_plugin_gen41_evk2": _HD,
    "hal_plugin_gen41_evk3": _HD,
    "hal_plugin_imx636_evk3": _HD,
    "hal_plugin_imx636_evk4": _HD,
}
ES_HEADER = b"Event Stream"
EVT3_MAX_COORD = 2048  # 11-bit addresses (EVT 2 too)
DAT_MAX_COORD = 1 << 14  # 14-bit addresses
EVT3_CLOCK_US = 1 << 24  # TIME_HIGH + TIME_LOW: 24 bits of µs before the first wrap


@contextmanager
def _decoding(path: Path, what: str) -> Iterator[None]:
    """A decoder's failure as one :class:`EventFileError`. ``faery`` is Rust: a panic in it
    arrives as ``pyo3_runtime.PanicException``, a ``BaseException`` that ``except
    Exception`` would miss; it is caught here, by its name, and nothing broader."""
    try:
        yield
    except (OSError, RuntimeError, ValueError, OverflowError) as err:
        raise EventFileError(path, f"{what} failed, file damaged or truncated ({err})") from None
    except BaseException as err:
        if type(err).__name__ != "PanicException":
            raise
        problem = f"{what} failed: the decoder gave up on this file ({err})"
        raise EventFileError(path, problem) from None


# ----------------------------------------------------------------------------------------
# Prophesee headers


def prophesee_header(data: bytes) -> tuple[dict[str, str], int]:
    """The ``% key value`` header lines of a Prophesee ``.raw``/``.dat`` and its length.

    >>> prophesee_header(b"% evt 3.0\\n% geometry 640x480\\n% end\\n\\x00\\x80")
    ({'evt': '3.0', 'geometry': '640x480', 'end': ''}, 35)
    """
    fields: dict[str, str] = {}
    pos = 0
    while data.startswith(b"%", pos):
        end = data.find(b"\n", pos)
        if end < 0:
            break
        line = data[pos + 1 : end].decode("ascii", errors="replace").strip()
        key, _, value = line.partition(" ")
        if key:
            fields[key] = value.strip()
        pos = end + 1
        if key == "end":
            break
    return fields, pos


def _header_geometry(fields: dict[str, str]) -> tuple[int, int] | None:
    if "geometry" in fields:
        m = re.fullmatch(r"(\d+)\s*x\s*(\d+)", fields["geometry"])
        if m:
            return int(m[1]), int(m[2])
    fmt = fields.get("format", "")
    w, h = re.search(r"width=(\d+)", fmt), re.search(r"height=(\d+)", fmt)
    if w and h:
        return int(w[1]), int(h[1])
    if "Width" in fields and "Height" in fields:
        return int(fields["Width"]), int(fields["Height"])
    return PLUGIN_GEOMETRY.get(fields.get("plugin_name", ""))


def _evt_version(fields: dict[str, str]) -> str | None:
    fmt = fields.get("format", "").split(";")[0].strip().upper()
    if fmt in ("EVT3", "EVT2", "EVT21"):
        return {"EVT3": "evt3", "EVT2": "evt2", "EVT21": "evt2.1"}[fmt]
    return {"3.0": "evt3", "2.0": "evt2", "2.1": "evt2.1"}.get(fields.get("evt", ""))


def _sensor(
    path: Path,
    given: SensorSize | None,
    fields: dict[str, str],
    meta: dict[str, Any],
    limits: ReadLimits,
) -> SensorSize | None:
    """The sensor size: the caller's, else the header's (checked: a decoder is handed it);
    None: ``checked_recording`` infers it."""
    if given is not None:
        return check_sensor_size(path, given, limits.max_side)
    geometry = _header_geometry(fields)
    if geometry is None:
        return None
    meta["sensor_size_from"] = "header"
    return check_sensor_size(path, geometry, limits.max_side, "header geometry")


def evt3_event_count(words: np.ndarray) -> int:
    """The CD events an EVT 3.0 body of 16-bit ``words`` holds: one per ``EVT_ADDR_X``
    (type 0x2), one per set bit of a ``VECT_12`` (0x4) or ``VECT_8`` (0x5) word.

    >>> evt3_event_count(np.array([0x2005, 0x4FFF, 0x50F0, 0x8001], np.uint16))
    17
    """
    kind = words >> 12
    vect12 = np.bitwise_count(words[kind == 0x4] & 0xFFF).sum(dtype=np.int64)
    vect8 = np.bitwise_count(words[kind == 0x5] & 0xFF).sum(dtype=np.int64)
    return int(np.count_nonzero(kind == 0x2) + vect12 + vect8)


# ----------------------------------------------------------------------------------------
# Readers


def read_prophesee_raw(
    path: Path, sensor_size: SensorSize | None, limits: ReadLimits
) -> EventRecording:
    """Prophesee ``.raw``: EVT 3.0 through ``evt3``, EVT 2.0 through ``faery``."""
    data = path.read_bytes()
    fields, start = prophesee_header(data)
    version = _evt_version(fields)
    if version is None:
        raise EventFileError(
            path,
            "no Prophesee header declaring the encoding ('% evt 3.0', '% evt 2.0' or "
            f"'% format EVT3'); found header fields {sorted(fields)}",
        )
    if version == "evt2.1":
        raise EventFileError(
            path, "EVT 2.1 is not read (faery has no decoder for it yet); convert it to EVT 3.0"
        )
    word = {"evt3": 2, "evt2": 4}[version]
    body = len(data) - start
    if body % word:
        raise EventFileError(
            path,
            f"truncated: {body} bytes of {version.upper()} data is not a whole number of "
            f"{word}-byte words",
        )
    meta: dict[str, Any] = {"source_format": version, "header": fields}
    size = _sensor(path, sensor_size, fields, meta, limits)
    if version == "evt3":
        import evt3

        words = np.frombuffer(data, dtype="<u2", offset=start)
        limits.check_count(path, "events", evt3_event_count(words))  # before decoding
        # Events before the first TIME_HIGH have no time: OpenEB (and evt3) skip them.
        kind = words >> 12
        first_th = np.flatnonzero(kind == 0x8)
        before = kind[: first_th[0] if first_th.size else kind.size]
        meta["event_words_before_first_time_high"] = int(np.isin(before, (2, 3, 4, 5)).sum())
        with _decoding(path, "EVT 3.0 decoding"):
            dec = evt3.decode_file(str(path))
        t = np.asarray(dec.t, dtype=np.int64)
        if "t0" in fields:  # faery's header line for streams written relative to t0
            try:
                t = t + int(fields["t0"])
            except ValueError:
                problem = f"header t0 {fields['t0']!r} is not an integer"
                raise EventFileError(path, problem) from None
        columns = {"x": dec.x, "y": dec.y, "t": t, "p": dec.p}
    else:
        import faery

        # Without a known geometry: decode the full 11-bit range; checked_recording infers the size.
        fallback = (size[0], size[1]) if size else (EVT3_MAX_COORD, EVT3_MAX_COORD)
        chunks, triggers, decoded = [], 0, 0
        with _decoding(path, f"{version.upper()} decoding"):
            with faery.evt.Decoder(path, fallback, version) as dec:
                for packet in dec:
                    if "events" in packet:
                        chunks.append(packet["events"])
                        decoded += len(packet["events"])
                        limits.check_count(path, "events", decoded)
                    triggers += len(packet.get("triggers", ()))
        raw = np.concatenate(chunks) if chunks else np.zeros(0, faery.EVENTS_DTYPE)
        columns = {"x": raw["x"], "y": raw["y"], "t": raw["t"], "p": raw["on"]}
        meta["trigger_events"] = triggers
    return checked_recording(path, _checked(path, columns), size, meta, limits)


def _decoded(path: Path, decoder: Any, limits: ReadLimits) -> list[np.ndarray]:
    """A ``faery`` decoder's event chunks, counted against the limit as they come."""
    chunks, decoded = [], 0
    for chunk in decoder:
        chunks.append(chunk)
        decoded += len(chunk)
        limits.check_count(path, "events", decoded)
    return chunks


def _checked(path: Path, columns: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """The columns, refusing timestamps the int64 µs clock cannot hold (``checked_recording`` checks
    every value as it copies)."""
    t = np.asarray(columns["t"])
    if t.dtype.kind == "u" and len(t) and int(t.max()) > np.iinfo(np.int64).max:
        raise EventFileError(path, f"timestamp {int(t.max())} µs overflows int64")
    return {k: np.asarray(v) for k, v in columns.items()}


def read_dat(path: Path, sensor_size: SensorSize | None, limits: ReadLimits) -> EventRecording:
    """Prophesee DAT 2 (CD events) through ``faery``."""
    import faery

    data = path.read_bytes()
    fields, start = prophesee_header(data)
    if not fields:
        raise EventFileError(path, "no Prophesee DAT header ('% Version 2' ...)")
    if len(data) < start + 2:
        raise EventFileError(path, "truncated: the header is not followed by the event type")
    event_type, event_size = data[start], data[start + 1]
    if event_type != 0x0C or event_size != 8:
        raise EventFileError(
            path,
            f"event type {event_type} of {event_size} bytes; only CD events "
            "(type 12, 8 bytes) are read",
        )
    body = len(data) - start - 2
    if body % 8:
        raise EventFileError(
            path, f"truncated: {body} bytes of events is not a whole number of 8-byte events"
        )
    meta: dict[str, Any] = {"source_format": "dat", "header": fields}
    size = _sensor(path, sensor_size, fields, meta, limits)
    limits.check_count(path, "events", body // 8)
    # Without a known geometry: decode the full 14-bit range; checked_recording infers the size.
    fallback = (size[0], size[1]) if size else (DAT_MAX_COORD, DAT_MAX_COORD)
    with _decoding(path, "DAT decoding"), faery.dat.Decoder(path, fallback, "dat2") as dec:
        chunks = _decoded(path, dec, limits)
    raw = np.concatenate(chunks) if chunks else np.zeros(0, [("t", "<u8"), ("payload", "u1")])
    columns = {
        "x": raw["x"] if len(raw) else np.zeros(0),
        "y": raw["y"] if len(raw) else np.zeros(0),
        "t": raw["t"],
        "p": raw["payload"],
    }
    return checked_recording(path, _checked(path, columns), size, meta, limits)


def es_expected_bytes(t: np.ndarray) -> int:
    """Bytes an Event Stream 2.0 DVS body needs for events at times ``t`` (µs from 0).

    Each event is 5 bytes; a gap of ``dt`` µs costs ``dt // 127`` overflow bytes
    (``0xFF``), because one event byte carries at most 126 µs.

    >>> es_expected_bytes(np.array([1, 500, 9000]))
    84
    """
    t = np.asarray(t, dtype=np.int64)
    if t.size == 0:
        return 0
    gaps = np.diff(t, prepend=0)
    return int(5 * t.size + np.sum(gaps // 127))


def read_es(
    path: Path,
    sensor_size: SensorSize | None = None,
    limits: ReadLimits | None = None,
    *,
    flip_y: bool = True,
) -> EventRecording:
    """Event Stream 2.0 (DVS type) through ``faery``.

    The format's origin is the bottom-left corner; ``flip_y`` (default) turns rows so that
    row 0 is the top, as everywhere in wander. ``flip_y=False`` keeps rows as stored
    (for files converted without the flip, e.g. the EED sequence in
    ``../shared/realdata``, whose README says so).
    """
    limits = limits or ReadLimits()
    import faery

    data = path.read_bytes()
    if not data.startswith(ES_HEADER) and not (len(data) < 20 and ES_HEADER.startswith(data)):
        raise EventFileError(path, f"not an Event Stream file (starts with {data[:12]!r})")
    if len(data) < 20:
        raise EventFileError(path, f"truncated: {len(data)} bytes, the header alone is 20")
    version = tuple(data[12:15])
    kinds = {0: "generic", 1: "dvs", 2: "atis", 4: "color"}
    kind = kinds.get(data[15], f"unknown ({data[15]})")
    if version[0] != 2:
        raise EventFileError(path, f"Event Stream version {version}; 2.x is read")
    if kind != "dvs":
        raise EventFileError(path, f"Event Stream of type {kind!r}; the DVS type is read")
    with _decoding(path, "Event Stream decoding"), faery.es.Decoder(path=path, t0=0) as dec:
        width, height = dec.dimensions
        chunks = _decoded(path, dec, limits)
    raw = np.concatenate(chunks) if chunks else np.zeros(0, faery.EVENTS_DTYPE)
    spare = len(data) - 20 - es_expected_bytes(raw["t"])
    tail = data[len(data) - spare :] if spare > 0 else b""
    if spare < 0 or tail.strip(b"\xff\xfe"):
        raise EventFileError(
            path,
            f"truncated or damaged: {len(raw)} events need {20 + es_expected_bytes(raw['t'])} "
            f"bytes, the file has {len(data)}",
        )
    y = raw["y"].astype(np.int64)
    columns = {"x": raw["x"], "y": height - 1 - y if flip_y else y, "t": raw["t"], "p": raw["on"]}
    meta = {"source_format": "es", "es_version": ".".join(map(str, version)), "flip_y": flip_y}
    size = sensor_size or (width, height, 2)
    return checked_recording(path, _checked(path, columns), size, meta, limits)


# ----------------------------------------------------------------------------------------
# Writers


def _for_faery(path: Path, recording: EventRecording, max_coord: int | None = None) -> Any:
    """The events as ``faery.EVENTS_DTYPE``, refusing what the unsigned fields cannot hold."""
    import faery

    ev = recording.events
    w, h = int(recording.sensor_size[0]), int(recording.sensor_size[1])
    if max_coord is not None and max(w, h) > max_coord:
        raise EventFileError(
            path, f"sensor {w}x{h} does not fit the format's {max_coord}-pixel addresses"
        )
    if len(ev) and int(ev["t"][0]) < 0:
        raise EventFileError(path, f"t[0]={int(ev['t'][0])} µs is negative; the format is unsigned")
    out = np.zeros(len(ev), dtype=faery.EVENTS_DTYPE)
    out["t"], out["x"], out["y"], out["on"] = ev["t"], ev["x"], ev["y"], ev["p"] == 1
    return out


def write_aedat4(path: Path, recording: EventRecording) -> None:
    """AEDAT 4.0 (one LZ4-compressed event stream) through ``faery``.

    Holds the events and the sensor size; wander's metadata is not stored.
    """
    import faery

    events = _for_faery(path, recording)
    w, h = int(recording.sensor_size[0]), int(recording.sensor_size[1])
    attr = faery.aedat.DescriptionAttribute
    info = faery.aedat.DescriptionNode(
        name="info",
        path="/mainloop/Recorder/outInfo/0/info/",
        attributes={
            "sizeX": attr("int", w),
            "sizeY": attr("int", h),
            "source": attr("string", "wander"),
        },
        nodes=[],
    )
    stream = faery.aedat.DescriptionNode(
        name="0",
        path="/mainloop/Recorder/outInfo/0/",
        attributes={
            "compression": attr("string", "LZ4"),
            "originalOutputName": attr("string", "events"),
            "typeIdentifier": attr("string", "EVTS"),
        },
        nodes=[info],
    )
    root = faery.aedat.DescriptionNode(
        name="outInfo", path="/mainloop/Recorder/outInfo/", attributes={}, nodes=[stream]
    )
    with faery.aedat.Encoder(path, [root], faery.aedat.LZ4_DEFAULT) as enc:
        # One packet per 65536 events, as DV's recorder does, so readers can stream.
        for i in range(0, len(events), 1 << 16):
            enc.write(0, events[i : i + (1 << 16)])


def write_evt3(path: Path, recording: EventRecording) -> None:
    """Prophesee EVT 3.0 ``.raw`` through ``faery``.

    Times are written as they are when the clock starts within EVT3's 24-bit range
    (16.7 s; every simulated recording): any EVT3 reader then sees them exactly. A later
    clock (e.g. UNIX µs) is written from the first event, with faery's ``% t0`` header
    line, which :func:`read_prophesee_raw` (and faery) add back. The header gives the
    geometry; wander's metadata is not stored.
    """
    import faery

    events = _for_faery(path, recording, EVT3_MAX_COORD)
    size = (int(recording.sensor_size[0]), int(recording.sensor_size[1]))
    relative = bool(len(events)) and int(events["t"][0]) >= EVT3_CLOCK_US
    with faery.evt.Encoder(path, "evt3", relative, size, True) as enc:
        for i in range(0, len(events), 1 << 16):
            enc.write({"events": events[i : i + (1 << 16)]})


READERS: dict[str, Callable[[Path, SensorSize | None, ReadLimits], EventRecording]] = {
    ".raw": read_prophesee_raw,
    ".dat": read_dat,
    ".es": read_es,
}
WRITERS: dict[str, Callable[[Path, EventRecording], None]] = {
    ".aedat4": write_aedat4,
    ".raw": write_evt3,
}
