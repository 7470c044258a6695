"""Reading and writing event files.

Formats, chosen by suffix:

========================  =====  =====  ==============================================
suffix                    read   write  notes
========================  =====  =====  ==============================================
``.npz``                  yes    yes    ``events`` structured array + ``sensor_size`` +
                                        ``metadata`` (JSON)
``.h5`` / ``.hdf5``       yes    yes    group ``events`` with columns x, y, t, p (gzip);
                                        ``sensor_size`` and ``metadata`` attributes
``.npy``                  yes    no     a bare structured array with fields x, y, t, p
                                        (any order); sensor size given or inferred
``.aedat4``               yes    no     AEDAT 4.0 (iniVation DV) via the ``aedat`` package
``.aedat``                yes    no     jAER AEDAT 2.0 from a DVS128
========================  =====  =====  ==============================================

plus the formats of :mod:`wander_env.event_formats`: Prophesee ``.raw`` (EVT 2/3, EVT3
written too), ``.dat``, Event Stream ``.es``, and AEDAT 4.0 writing; ``.h5`` files also
get the DSEC ``ms_to_idx`` index.

Every reader returns an :class:`EventRecording` whose events are in the shared
format of :mod:`wander_env.events`, validated against the sensor size. A file that
is truncated, of the wrong format, or has unsorted timestamps raises
:class:`EventFileError` (a ``ValueError``) naming the file and the problem.

Example:
    >>> import tempfile, pathlib
    >>> from wander_env.events import make_events
    >>> from wander_env.event_io import EventRecording, read_events, write_events
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "demo.h5"
    >>> rec = EventRecording(make_events([0], [1], [5], [1]), (4, 4, 2), {"seed": 0})
    >>> write_events(path, rec)
    >>> read_events(path).metadata["seed"]
    0
"""

from __future__ import annotations

import json
import os
import zipfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from wander_env.events import EVENT_DTYPE, SensorSize, validate_events
from wander_env.runinfo import dumps_strict

FORMAT_TAG = "wander-events/1"


class EventFileError(ValueError):
    """An event file could not be read: names the file and what was wrong."""

    def __init__(self, path: str | os.PathLike, problem: str):
        self.path = str(path)
        self.problem = problem
        super().__init__(f"{self.path}: {problem}")


@dataclass
class EventRecording:
    """Events with the sensor they came from and free-form metadata."""

    events: np.ndarray
    sensor_size: SensorSize
    metadata: dict[str, Any] = field(default_factory=dict)

    @property
    def duration_us(self) -> int:
        if len(self.events) == 0:
            return 0
        return int(self.events["t"][-1] - self.events["t"][0])


def _as_events(columns: dict[str, np.ndarray], path: Path) -> np.ndarray:
    missing = [f for f in ("x", "y", "t", "p") if f not in columns]
    if missing:
        raise EventFileError(path, f"missing event fields {missing}")
    n = len(columns["t"])
    if any(len(columns[f]) != n for f in ("x", "y", "p")):
        lengths = {f: len(columns[f]) for f in ("x", "y", "t", "p")}
        raise EventFileError(path, f"event columns differ in length: {lengths}")
    ev = np.empty(n, dtype=EVENT_DTYPE)
    for f in ("x", "y", "t", "p"):
        ev[f] = columns[f]
    return ev


def _finish(
    path: Path, events: np.ndarray, sensor_size: SensorSize | None, metadata: dict[str, Any]
) -> EventRecording:
    if sensor_size is None:
        if len(events) == 0:
            raise EventFileError(path, "no events and no sensor size: pass sensor_size")
        sensor_size = (int(events["x"].max()) + 1, int(events["y"].max()) + 1, 2)
        metadata = {**metadata, "sensor_size_inferred": True}
    sensor_size = (int(sensor_size[0]), int(sensor_size[1]), 2)
    try:
        validate_events(events, sensor_size, where="events")
    except ValueError as err:
        raise EventFileError(path, str(err)) from None
    return EventRecording(events, sensor_size, metadata)


def _read_npz(path: Path, sensor_size: SensorSize | None) -> EventRecording:
    try:
        with np.load(path, allow_pickle=False) as data:
            keys = set(data.files)
            if "events" in keys:
                arr = data["events"]
                if arr.dtype.names is None:
                    raise EventFileError(path, "'events' is not a structured array")
                columns = {f: arr[f] for f in arr.dtype.names}
            else:
                columns = {f: data[f] for f in ("x", "y", "t", "p") if f in keys}
            if sensor_size is None and "sensor_size" in keys:
                sensor_size = tuple(int(v) for v in data["sensor_size"])
            metadata = json.loads(str(data["metadata"])) if "metadata" in keys else {}
    except EventFileError:
        raise
    except (OSError, ValueError, EOFError, zipfile.BadZipFile) as err:
        raise EventFileError(path, f"not a readable .npz file ({err})") from None
    return _finish(path, _as_events(columns, path), sensor_size, metadata)


def _read_npy(path: Path, sensor_size: SensorSize | None) -> EventRecording:
    try:
        arr = np.load(path, allow_pickle=False)
    except (OSError, ValueError, EOFError) as err:
        raise EventFileError(path, f"not a readable .npy file ({err})") from None
    if arr.dtype.names is None:
        raise EventFileError(path, f"expected a structured array with x, y, t, p; got {arr.dtype}")
    columns = {f: arr[f] for f in arr.dtype.names}
    return _finish(path, _as_events(columns, path), sensor_size, {})


def _read_h5(path: Path, sensor_size: SensorSize | None) -> EventRecording:
    import h5py

    try:
        with h5py.File(path, "r") as f:
            if "events" not in f:
                raise EventFileError(path, f"no 'events' group (found {sorted(f.keys())})")
            g = f["events"]
            columns = {k: g[k][()] for k in ("x", "y", "t", "p") if k in g}
            if sensor_size is None and "sensor_size" in f.attrs:
                sensor_size = tuple(int(v) for v in f.attrs["sensor_size"])
            metadata = json.loads(f.attrs["metadata"]) if "metadata" in f.attrs else {}
    except EventFileError:
        raise
    except OSError as err:
        raise EventFileError(path, f"not a readable HDF5 file ({err})") from None
    return _finish(path, _as_events(columns, path), sensor_size, metadata)


def _read_aedat4(path: Path, sensor_size: SensorSize | None) -> EventRecording:
    import aedat

    with open(path, "rb") as fh:
        magic = fh.read(14)
    if not magic.startswith(b"#!AER-DAT4.0"):
        raise EventFileError(path, f"not an AEDAT 4.0 file (starts with {magic!r})")
    try:
        decoder = aedat.Decoder(str(path))
        streams = decoder.id_to_stream()
        chunks: list[np.ndarray] = []
        other: dict[str, int] = {}
        for packet in decoder:
            if "events" in packet:
                chunks.append(packet["events"])
            else:
                kind = streams.get(packet["stream_id"], {}).get("type", "unknown")
                other[kind] = other.get(kind, 0) + 1
    except (OSError, RuntimeError, ValueError) as err:
        raise EventFileError(
            path, f"AEDAT 4.0 decoding failed, file damaged or truncated ({err})"
        ) from None
    event_streams = [s for s in streams.values() if s.get("type") == "events"]
    if not event_streams:
        raise EventFileError(path, f"no event stream (streams: {streams})")
    if sensor_size is None:
        sensor_size = (int(event_streams[0]["width"]), int(event_streams[0]["height"]), 2)
    raw = np.concatenate(chunks) if chunks else np.zeros(0, dtype=[("t", "<u8")])
    columns = {
        "x": raw["x"] if len(raw) else np.zeros(0),
        "y": raw["y"] if len(raw) else np.zeros(0),
        "t": raw["t"].astype(np.int64),
        "p": raw["on"].astype(np.int8) if len(raw) else np.zeros(0),
    }
    metadata = {"source_format": "aedat4", "other_stream_packets": other}
    return _finish(path, _as_events(columns, path), sensor_size, metadata)


def _read_aedat2(path: Path, sensor_size: SensorSize | None) -> EventRecording:
    """jAER AEDAT 2.0, DVS128 addresses (big-endian int32 address, int32 timestamp)."""
    data = path.read_bytes()
    if not data.startswith(b"#!AER-DAT"):
        raise EventFileError(path, f"not a jAER AEDAT file (starts with {data[:12]!r})")
    version = data[9:12]
    if version != b"2.0":
        raise EventFileError(
            path, f"AEDAT version {version.decode(errors='replace')} found; 2.0 is read"
        )
    pos = 0
    while pos < len(data) and data[pos : pos + 1] == b"#":
        end = data.find(b"\n", pos)
        if end < 0:
            raise EventFileError(path, "truncated inside the ASCII header")
        pos = end + 1
    body = len(data) - pos
    if body % 8:
        raise EventFileError(
            path, f"truncated: {body} bytes of events is not a whole number of 8-byte events"
        )
    words = np.frombuffer(data, dtype=">i4", offset=pos).reshape(-1, 2)
    addr, ts = words[:, 0].astype(np.int64), words[:, 1].astype(np.int64)
    special = (addr >> 15) & 1 == 1
    addr, ts = addr[~special], ts[~special]
    # jAER stores the DVS128 mirrored in both axes; flip so that row 0 is the top.
    columns = {
        "x": 127 - ((addr >> 1) & 0x7F),
        "y": 127 - ((addr >> 8) & 0x7F),
        "t": ts,
        "p": (addr & 1).astype(np.int8),
    }
    metadata = {"source_format": "aedat2", "special_events": int(special.sum())}
    return _finish(path, _as_events(columns, path), sensor_size or (128, 128, 2), metadata)


_READERS = {
    ".npz": _read_npz,
    ".npy": _read_npy,
    ".h5": _read_h5,
    ".hdf5": _read_h5,
    ".aedat4": _read_aedat4,
    ".aedat": _read_aedat2,
}


def read_events(path: str | os.PathLike, sensor_size: SensorSize | None = None) -> EventRecording:
    """Read an event file of any supported format (see the module docstring).

    ``sensor_size`` overrides what the file says; for ``.npy`` without it the size
    is inferred from the largest coordinates and ``metadata["sensor_size_inferred"]``
    is set.
    """
    from wander_env import event_formats  # the field's formats (EVT2/3, DAT, ES)

    path = Path(path)
    readers = {**_READERS, **event_formats.READERS}
    reader = readers.get(path.suffix.lower())
    if reader is None:
        raise EventFileError(path, f"unknown suffix {path.suffix!r}; readable: {sorted(readers)}")
    if not path.is_file():
        raise EventFileError(path, "no such file")
    return reader(path, sensor_size)


def write_events(path: str | os.PathLike, recording: EventRecording) -> None:
    """Write ``.npz``, ``.h5``/``.hdf5``, ``.aedat4`` or ``.raw`` (EVT3); validates first."""
    from wander_env import event_formats  # AEDAT4/EVT3 writers, the HDF5 ms_to_idx index

    path = Path(path)
    validate_events(recording.events, recording.sensor_size, where=str(path))
    meta = dumps_strict(recording.metadata)
    size = np.asarray(recording.sensor_size, dtype=np.int64)
    suffix = path.suffix.lower()
    if suffix == ".npz":
        np.savez_compressed(
            path,
            events=recording.events.astype(EVENT_DTYPE, copy=False),
            sensor_size=size,
            metadata=np.asarray(meta),
            format=np.asarray(FORMAT_TAG),
        )
    elif suffix in (".h5", ".hdf5"):
        import h5py

        with h5py.File(path, "w") as f:
            g = f.create_group("events")
            n = len(recording.events)
            # An empty recording (e.g. a run that failed at its first step) is stored
            # uncompressed: HDF5 cannot chunk a zero-length dataset.
            packing = (
                {"compression": "gzip", "compression_opts": 4, "shuffle": True,
                 "chunks": (min(n, 1 << 16),)}
                if n
                else {}
            )  # fmt: skip
            for name in ("x", "y", "t", "p"):
                g.create_dataset(name, data=recording.events[name], **packing)
            f.attrs["sensor_size"] = size
            f.attrs["metadata"] = meta
            f.attrs["format"] = FORMAT_TAG
            event_formats.write_ms_to_idx(f, recording.events)
    elif suffix in event_formats.WRITERS:
        event_formats.WRITERS[suffix](path, recording)
    else:
        writable = [".npz", ".h5", ".hdf5", *event_formats.WRITERS]
        raise EventFileError(
            path, f"cannot write suffix {path.suffix!r}; writable: {', '.join(writable)}"
        )
