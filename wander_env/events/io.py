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

plus the formats of :mod:`wander_env.events.formats`: Prophesee ``.raw`` (EVT 2/3, EVT3
written too), ``.dat``, Event Stream ``.es``, and AEDAT 4.0 writing; ``.h5`` files also
get the DSEC ``ms_to_idx`` index.

Every reader returns an :class:`EventRecording` whose events are in the shared
format of :mod:`wander_env.events`, validated against the sensor size. A file that
is truncated, of the wrong format, or has unsorted timestamps raises
:class:`EventFileError` (a ``ValueError``) naming the file and the problem.

Examples:
    >>> import tempfile, pathlib
    >>> from wander_env.events import make_events
    >>> from wander_env.events.io import EventRecording, read_events, write_events
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "demo.h5"
    >>> rec = EventRecording(make_events([0], [1], [5], [1]), (4, 4, 2), {"seed": 0})
    >>> write_events(path, rec)
    >>> read_events(path).metadata["seed"]
    0
"""

from __future__ import annotations

import errno
import io
import os
import re
import shutil
import uuid
import zipfile
from pathlib import Path
from typing import Any

import numpy as np

from wander_env.events import EVENT_DTYPE, SensorSize, validate_events
from wander_env.events.checks import (
    MAX_EVENTS,
    MAX_SENSOR_SIDE,
    EventFileError,
    EventRecording,
    ReadLimits,
    check_claim,
    check_sensor_size,
    checked_recording,
    n_rows,
    parse_metadata,
)
from wander_env.strict_json import dumps_strict

FORMAT_TAG = "wander-events/1"
#: Free bytes kept beyond a write's own size (HDF5 metadata, attributes, the run folder).
SPACE_MARGIN = 1 << 20


class OutputError(OSError):
    """A result file could not be written (disk full, folder not writable): names it."""

    def __init__(self, path: str | os.PathLike, cause: BaseException | str) -> None:
        code = getattr(cause, "errno", None) if not isinstance(cause, str) else None
        text = cause if isinstance(cause, str) else (getattr(cause, "strerror", None) or str(cause))
        super().__init__(code or errno.EIO, text, str(path))

    def __str__(self) -> str:
        return f"cannot write {self.filename}: {self.strerror}"


def check_space(path: str | os.PathLike, need_bytes: int) -> None:
    """Raise :class:`OutputError` (ENOSPC) unless ``need_bytes`` + a margin are free."""
    folder = Path(path).parent
    try:
        free = shutil.disk_usage(folder).free
    except OSError as err:
        raise OutputError(path, err) from err
    if free < need_bytes + SPACE_MARGIN:
        raise OutputError(
            path,
            OSError(
                errno.ENOSPC,
                f"No space left on device ({free:,} bytes free; {need_bytes:,} needed plus "
                f"a reserve of {SPACE_MARGIN:,})",
            ),
        )


def _npy_header(
    path: Path, fh: Any, available: int, what: str, limits: ReadLimits
) -> tuple[tuple, np.dtype]:
    """Shape and dtype of an ``.npy`` stream, checked against the bytes that follow and the
    event limit (an ``.npz`` member is compressed: its claim is checked before it is
    inflated)."""
    try:
        version = np.lib.format.read_magic(fh)
        read = (
            np.lib.format.read_array_header_1_0
            if version == (1, 0)
            else np.lib.format.read_array_header_2_0
        )
        shape, _, dtype = read(fh, max_header_size=1 << 16)
    except (ValueError, OSError, EOFError) as err:
        raise EventFileError(path, f"not a readable .npy header ({err})", what) from None
    if dtype.hasobject:
        raise EventFileError(path, f"dtype {dtype} holds Python objects", what, str(dtype))
    count = int(np.prod(shape, dtype=np.int64)) if shape else 1
    check_claim(path, what, count, dtype.itemsize, available - fh.tell())
    limits.check_count(path, what, count)
    return shape, dtype


def _read_npz(path: Path, sensor_size: SensorSize | None, limits: ReadLimits) -> EventRecording:
    try:
        with zipfile.ZipFile(path) as zf:
            for info in zf.infolist():  # headers against the stored sizes, before np.load
                with zf.open(info) as fh:
                    what = info.filename.removesuffix(".npy")
                    _npy_header(path, fh, info.file_size, what, limits)
        with np.load(path, allow_pickle=False) as data:
            keys = set(data.files)
            if "events" in keys:
                arr = data["events"]
                if arr.dtype.names is None:
                    raise EventFileError(path, "not a structured array", "events", str(arr.dtype))
                columns = {f: arr[f] for f in arr.dtype.names}
            else:
                columns = {f: data[f] for f in ("x", "y", "t", "p") if f in keys}
            if sensor_size is None and "sensor_size" in keys:
                sensor_size = check_sensor_size(path, data["sensor_size"], limits.max_side)
            metadata = parse_metadata(path, data["metadata"]) if "metadata" in keys else {}
    except EventFileError:
        raise
    except (OSError, ValueError, EOFError, zipfile.BadZipFile) as err:
        raise EventFileError(path, f"not a readable .npz file ({err})") from None
    return checked_recording(path, columns, sensor_size, metadata, limits)


def _read_npy(path: Path, sensor_size: SensorSize | None, limits: ReadLimits) -> EventRecording:
    with open(path, "rb") as fh:
        _npy_header(path, fh, path.stat().st_size, "array", limits)
    try:
        arr = np.load(path, mmap_mode="r", allow_pickle=False)  # read in chunks below
    except (OSError, ValueError, EOFError) as err:
        raise EventFileError(path, f"not a readable .npy file ({err})") from None
    if arr.dtype.names is None:
        raise EventFileError(path, f"expected a structured array with x, y, t, p; got {arr.dtype}")
    columns = {f: arr[f] for f in arr.dtype.names}
    return checked_recording(path, columns, sensor_size, {}, limits)


def _h5_column(path: Path, group: Any, name: str, unfinished: bool = False) -> Any:
    """An HDF5 event column, its claimed length checked against what is stored (for the
    stream of an ``unfinished`` writer, :func:`stream_state` reads only stored chunks)."""
    import h5py

    ds = group[name]
    if not isinstance(ds, h5py.Dataset):
        raise EventFileError(path, f"is a {type(ds).__name__}, not a dataset", f"events/{name}")
    field = f"events/{name}"
    if ds.ndim != 1:
        raise EventFileError(path, f"expected a 1-D column, got shape {ds.shape}", field, ds.shape)
    if ds.dtype.kind not in "biuf":
        raise EventFileError(path, f"dtype {ds.dtype} is not a number type", field, str(ds.dtype))
    if ds.is_virtual or ds.external:
        raise EventFileError(path, "stored outside the file (virtual/external): refused", field)
    n = ds.shape[0]
    if n == 0 or (unfinished and ds.chunks is not None):
        return ds
    if ds.chunks is None:
        stored = ds.id.get_storage_size()
        check_claim(path, field, n, ds.dtype.itemsize, stored)
    else:
        want = -(-n // ds.chunks[0])
        have = ds.id.get_num_chunks()
        if have < want:
            raise EventFileError(
                path,
                f"claims {n:,} events in {want:,} chunks but the file stores {have:,} of them "
                "(sparse, truncated or forged)",
                field,
                n,
            )
    return ds


def _read_h5(path: Path, sensor_size: SensorSize | None, limits: ReadLimits) -> EventRecording:
    import h5py

    try:
        with h5py.File(path, "r") as f:
            if "events" not in f:
                raise EventFileError(path, f"no 'events' group (found {sorted(f.keys())})")
            g = f["events"]
            if not isinstance(g, h5py.Group):
                raise EventFileError(
                    path, f"is a {type(g).__name__}, expected a group of x, y, t, p", "events"
                )
            unfinished = "complete" in f.attrs and not bool(f.attrs["complete"])
            columns = {
                k: _h5_column(path, g, k, unfinished) for k in ("x", "y", "t", "p") if k in g
            }
            if sensor_size is None and "sensor_size" in f.attrs:
                sensor_size = check_sensor_size(path, f.attrs["sensor_size"], limits.max_side)
            metadata = parse_metadata(path, f.attrs["metadata"]) if "metadata" in f.attrs else {}
            n, metadata = stream_state(path, f.attrs, columns, sensor_size, metadata)
            return checked_recording(path, columns, sensor_size, metadata, limits, n=n)
    except EventFileError:
        raise
    except (OSError, KeyError, TypeError, ValueError) as err:
        raise EventFileError(path, f"not a readable HDF5 file ({err})") from None


def stream_state(
    path: Path,
    attrs: Any,
    columns: dict[str, Any],
    sensor_size: SensorSize | None,
    metadata: dict[str, Any],
) -> tuple[int, dict[str, Any]]:
    """Events to read from a file that :class:`~wander_env.events.stream.EventStreamWriter`
    wrote, and its metadata; one it did not finish says where it stops.

    A stream killed while it flushed can claim more than it stored (its new length on
    disk before its last chunk) or hold a torn last chunk (the writer rewrites the partial
    chunk at the end of what it had flushed, and a kill in that write leaves it
    undecodable). Only stored chunks are read, torn ones are dropped from the end (the
    events up to the last chunk that decodes in every column are read), and
    ``incomplete["torn_events"]`` counts the flushed events that were lost so.
    """
    stored = n_rows(path, columns)
    if "complete" not in attrs or bool(attrs["complete"]):
        return stored, metadata
    flushed = min(stored, max(int(attrs.get("events_flushed", stored)), 0))
    n = _decodable_prefix(columns, flushed, sensor_size)
    t_end = int(attrs.get("t_flushed_us", -1)) if n == flushed else int(columns["t"][n - 1])
    incomplete = {"events": n, "last_t_us": t_end if n else None}
    if n < flushed:
        incomplete["torn_events"] = flushed - n
    return n, {**metadata, "incomplete": incomplete}


def _decodable_prefix(columns: dict[str, Any], n: int, sensor_size: SensorSize | None) -> int:
    """``n`` capped at the stored chunks, or the start of the earliest of the last chunks
    that does not decode in some column or holds events no writer wrote (walking back to
    a chunk that decodes in all and is :func:`_plausible`)."""
    chunked = [c for c in columns.values() if getattr(c, "chunks", None)]
    for column in chunked:  # chunks are stored in order: those missing are the last ones
        n = min(n, column.id.get_num_chunks() * column.chunks[0])
    step = min((c.chunks[0] for c in chunked), default=0)
    while n > 0 and step:
        start = (n - 1) // step * step
        if _plausible(columns, start, n, sensor_size):
            break
        n = start
    return n


def _plausible(
    columns: dict[str, Any], start: int, stop: int, sensor_size: SensorSize | None
) -> bool:
    """Whether the events ``start:stop`` decode in every column and pass
    :func:`~wander_env.events.validate_events` (on the sensor, where its size is known;
    polarity 0 or 1; in time order): a chunk stored before its events holds fill values,
    and one whose place the writer reused for another column's chunk decodes to that
    column's numbers."""
    events = np.empty(stop - start, EVENT_DTYPE)
    try:
        for k, column in columns.items():
            events[k] = column[start:stop]
    except OSError:  # a filter (gzip, shuffle) failed on a torn chunk
        return False
    unbounded = (np.iinfo(np.int64).max, np.iinfo(np.int64).max)
    try:
        validate_events(events, sensor_size or unbounded)
    except ValueError:
        return False
    return True


def _read_aedat4(path: Path, sensor_size: SensorSize | None, limits: ReadLimits) -> EventRecording:
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
        decoded = 0
        for packet in decoder:  # LZ4-compressed: counted as it inflates
            if "events" in packet:
                chunks.append(packet["events"])
                decoded += len(packet["events"])
                limits.check_count(path, "events", decoded)
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
        stream = event_streams[0]
        size = (stream.get("width"), stream.get("height"))
        sensor_size = check_sensor_size(path, size, limits.max_side, "event stream width/height")
    raw = np.concatenate(chunks) if chunks else np.zeros(0, dtype=[("t", "<u8")])
    empty = np.zeros(0, np.int64)
    columns = {
        "x": raw["x"] if len(raw) else empty,
        "y": raw["y"] if len(raw) else empty,
        "t": raw["t"],
        "p": raw["on"] if len(raw) else empty,
    }
    metadata = {"source_format": "aedat4", "other_stream_packets": other}
    return checked_recording(path, columns, sensor_size, metadata, limits)


def _read_aedat2(path: Path, sensor_size: SensorSize | None, limits: ReadLimits) -> EventRecording:
    """jAER AEDAT 2.0, DVS128 addresses (big-endian int32 address, int32 timestamp)."""
    size = path.stat().st_size
    with open(path, "rb") as fh:
        first = fh.read(12)
        if not first.startswith(b"#!AER-DAT"):
            raise EventFileError(path, f"not a jAER AEDAT file (starts with {first!r})")
        version = first[9:12]
        if version != b"2.0":
            raise EventFileError(
                path, f"AEDAT version {version.decode(errors='replace')} found; 2.0 is read"
            )
        fh.seek(0)
        pos = 0
        while fh.peek(1)[:1] == b"#":
            line = fh.readline(1 << 16)
            if not line.endswith(b"\n"):
                raise EventFileError(path, "truncated inside the ASCII header (or a line > 64 KiB)")
            pos += len(line)
    body = size - pos
    if body % 8:
        raise EventFileError(
            path, f"truncated: {body} bytes of events is not a whole number of 8-byte events"
        )
    n = body // 8
    limits.check_count(path, "events", n)
    words = (
        np.memmap(path, dtype=">i4", mode="r", offset=pos, shape=(n, 2))
        if n
        else np.zeros((0, 2), ">i4")
    )
    parts: dict[str, list[np.ndarray]] = {f: [] for f in ("x", "y", "t", "p")}
    special_n = 0
    for a in range(0, n, 1 << 20):  # decoded in chunks: the file is never held twice
        block = np.asarray(words[a : a + (1 << 20)])
        addr, ts = block[:, 0].astype(np.int64), block[:, 1].astype(np.int64)
        special = (addr >> 15) & 1 == 1
        special_n += int(special.sum())
        addr, ts = addr[~special], ts[~special]
        # jAER stores the DVS128 mirrored in both axes; flip so that row 0 is the top.
        parts["x"].append((127 - ((addr >> 1) & 0x7F)).astype(np.int16))
        parts["y"].append((127 - ((addr >> 8) & 0x7F)).astype(np.int16))
        parts["t"].append(ts)
        parts["p"].append((addr & 1).astype(np.int8))
    del words
    columns = {f: np.concatenate(v) if v else np.zeros(0, np.int64) for f, v in parts.items()}
    metadata = {"source_format": "aedat2", "special_events": special_n}
    return checked_recording(path, columns, sensor_size or (128, 128, 2), metadata, limits)


_READERS = {
    ".npz": _read_npz,
    ".npy": _read_npy,
    ".h5": _read_h5,
    ".hdf5": _read_h5,
    ".aedat4": _read_aedat4,
    ".aedat": _read_aedat2,
}


def read_events(
    path: str | os.PathLike,
    sensor_size: SensorSize | None = None,
    max_sensor_side: int = MAX_SENSOR_SIDE,
    max_events: int = MAX_EVENTS,
) -> EventRecording:
    """Read an event file of any supported format (see the module docstring).

    ``sensor_size`` overrides what the file says; for ``.npy`` without it the size
    is inferred from the largest coordinates and ``metadata["sensor_size_inferred"]``
    is set. The file is untrusted (:mod:`wander_env.events.checks`): a sensor side above
    ``max_sensor_side``, a count the file cannot hold, a value that does not fit its
    field, more than ``max_events`` events (counted before a compressed file is inflated)
    are :class:`EventFileError` before anything large is allocated. A file that
    :class:`~wander_env.events.stream.EventStreamWriter` did not finish (a killed run) is
    read up to its last flushed chunk; ``metadata["incomplete"]`` says where it stops.
    """
    from wander_env.events import formats  # the field's formats (EVT2/3, DAT, ES)

    path = Path(path)
    readers = {**_READERS, **formats.READERS}
    reader = readers.get(path.suffix.lower())
    if reader is None:
        raise EventFileError(path, f"unknown suffix {path.suffix!r}; readable: {sorted(readers)}")
    if not path.is_file():
        raise EventFileError(path, "no such file")
    return reader(path, sensor_size, ReadLimits(max_sensor_side, max_events))


def write_events(path: str | os.PathLike, recording: EventRecording) -> None:
    """Write ``.npz``, ``.h5``/``.hdf5``, ``.aedat4`` or ``.raw`` (EVT3); validates first.

    A file that cannot be written (a full disk, a read-only folder) is
    :class:`OutputError` (an ``OSError`` naming the file and the
    errno) and no partial file is left. ``.npz`` and ``.h5`` files are built in memory
    (HDF5's core driver: h5py never writes to the disk, so a full disk cannot leave it
    to fail in a dealloc, which segfaults) and written once the free space is checked.
    """
    from wander_env.events import formats  # the AEDAT4/EVT3 writers

    path = Path(path)
    validate_events(recording.events, recording.sensor_size, where=str(path))
    suffix = path.suffix.lower()
    if suffix not in (".npz", ".h5", ".hdf5", *formats.WRITERS):
        writable = [".npz", ".h5", ".hdf5", *formats.WRITERS]
        raise EventFileError(
            path, f"cannot write suffix {path.suffix!r}; writable: {', '.join(writable)}"
        )
    if suffix == ".npz":
        write_file(path, _npz_image(recording))
    elif suffix in (".h5", ".hdf5"):
        write_file(path, _h5_image(recording))
    else:
        # at most 16 bytes an event (AEDAT 4: 13 bytes LZ4-packed; EVT3: 2-6)
        check_space(path, 16 * len(recording.events) + (1 << 16))
        try:
            formats.WRITERS[suffix](path, recording)
        except (OSError, RuntimeError) as err:  # faery's Rust I/O errors are RuntimeErrors
            path.unlink(missing_ok=True)
            raise OutputError(path, as_os_error(err)) from None


def as_os_error(err: BaseException) -> OSError:
    """``err`` as an ``OSError`` with its errno: itself, or one from a Rust library's
    ``... (os error N)`` message (``EIO`` when it names none).

    >>> as_os_error(RuntimeError("No space left on device (os error 28)")).errno
    28
    """
    if isinstance(err, OSError):
        return err
    found = re.search(r"\(os error (\d+)\)", str(err))
    code = int(found.group(1)) if found else errno.EIO
    return OSError(code, os.strerror(code))


def write_file(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path`` whole: the free space checked first, a failed write an
    :class:`OutputError` naming it with no partial file left."""
    check_space(path, len(data))
    try:
        with open(path, "wb") as fh:
            fh.write(data)
    except OSError as err:
        path.unlink(missing_ok=True)
        raise OutputError(path, err) from None


def _npz_image(recording: EventRecording) -> bytes:
    buf = io.BytesIO()
    np.savez_compressed(
        buf,
        events=recording.events.astype(EVENT_DTYPE, copy=False),
        sensor_size=np.asarray(recording.sensor_size, dtype=np.int64),
        metadata=np.asarray(dumps_strict(recording.metadata)),
        format=np.asarray(FORMAT_TAG),
    )
    return buf.getvalue()


def _h5_image(recording: EventRecording) -> bytes:
    """The bytes of the ``.h5`` file of ``recording``, built in memory."""
    import h5py

    from wander_env.events.hdf5_index import write_ms_to_idx

    name = f"wander-events-{uuid.uuid4().hex}.h5"  # the core driver's name, never a file
    with h5py.File(name, "w", driver="core", backing_store=False) as f:
        g = f.create_group("events")
        n = len(recording.events)
        # An empty recording (e.g. a run that failed at its first step) is stored
        # uncompressed: HDF5 cannot chunk a zero-length dataset.
        packing = (
            {
                "compression": "gzip",
                "compression_opts": 4,
                "shuffle": True,
                "chunks": (min(n, 1 << 16),),
            }
            if n
            else {}
        )
        for field in ("x", "y", "t", "p"):
            g.create_dataset(field, data=recording.events[field], **packing)
        f.attrs["sensor_size"] = np.asarray(recording.sensor_size, dtype=np.int64)
        f.attrs["metadata"] = dumps_strict(recording.metadata)
        f.attrs["format"] = FORMAT_TAG
        write_ms_to_idx(f, recording.events)
        f.flush()
        return f.id.get_file_image()


def divert_h5(file: Any) -> None:
    """Point the open h5py ``file``'s descriptor at ``/dev/null``: call it as soon as a
    write or flush of the file fails (a full disk). Every later write (the close's flush,
    a dealloc's) then succeeds without touching the disk, so h5py never deallocs an object
    whose close fails, which segfaults (h5py 3.16, plain h5py too). What reached the disk
    stays as it is (its attributes say what was flushed). Then close the file as usual."""
    fd = file.id.get_vfd_handle()
    null = os.open(os.devnull, os.O_RDWR)
    try:
        os.dup2(null, fd)
    finally:
        os.close(null)
