"""Event data to disk as it is made: an ``events.h5`` appended chunk by chunk.

:class:`EventStreamWriter` writes the ``events.h5`` layout of
:func:`wander_env.events.io.write_events` (group ``events`` with gzip columns x, y, t, p;
``sensor_size``, ``metadata`` and ``format`` attributes), but into resizable datasets:
:meth:`~EventStreamWriter.append` buffers a step's events; each chunk of
``chunk_events`` events is appended as it fills, the rest every ``flush_s`` seconds, each
time with the file flushed, so the memory of a run does not grow with its length. Until
:meth:`~EventStreamWriter.close` the file says ``complete = False`` and how far it got
(``events_flushed``, ``t_flushed_us``): a run killed mid-way leaves a file that
:func:`~wander_env.events.io.read_events` reads up to its last flushed chunk, with
``metadata["incomplete"]`` saying where it stops (a kill during a flush can tear the
partial chunk being rewritten: the reader drops it and counts its events as torn).

:class:`H5Appender` does the same for per-step arrays (ground truth). Before each
write the free space is checked: a full disk (or an unwritable folder) raises
:class:`OutputError` naming the file, never a half-written HDF5 structure.

Examples:
    >>> import tempfile, pathlib
    >>> from wander_env.events import make_events
    >>> from wander_env.events.io import read_events
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "events.h5"
    >>> with EventStreamWriter(path, (4, 4, 2), {"seed": 0}, chunk_events=2) as w:
    ...     w.append(make_events([0, 1], [1, 1], [5, 7], [1, 0]))
    ...     w.append(make_events([3], [2], [9], [1]))
    >>> rec = read_events(path)
    >>> rec.events["t"].tolist(), rec.metadata
    ([5, 7, 9], {'seed': 0})
"""

from __future__ import annotations

import os
import time
import zlib
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from wander_env.closing import Closing
from wander_env.events import EVENT_DTYPE, SensorSize, validate_events
from wander_env.events.hdf5_index import MsToIdx
from wander_env.events.io import FORMAT_TAG, OutputError, check_space, divert_h5
from wander_env.strict_json import dumps_strict

_FIELDS = ("x", "y", "t", "p")
#: zlib level of the event columns (the ``gzip`` filter's ``compression_opts``): on 2^20
#: events of a closed-loop run, level 1 takes 0.65× the CPU of level 4 for a file 4 %
#: larger (the writer shares the cores with the loop; ``write_events`` keeps level 4).
GZIP_LEVEL = 1


def stored_chunk(values: np.ndarray, size: int, level: int = GZIP_LEVEL) -> bytes:
    """A chunk of ``size`` elements as HDF5 stores it through the shuffle and gzip filters:
    ``values`` (zero-padded to ``size``), bytes grouped by significance, zlib-compressed
    with deflate's run-length strategy (a standard stream any reader inflates: on the
    6.4 M events of a 10 s closed-loop run 0.30 s of CPU against 0.43 s for the default
    strategy, the columns 18.3 against 16.8 MB; the shuffled columns are mostly runs of
    equal high bytes).

    Examples:
        >>> import zlib
        >>> raw = zlib.decompress(stored_chunk(np.array([1, 2], "<i2"), 3))
        >>> list(raw)  # low bytes of 1, 2, 0, then the high bytes
        [1, 2, 0, 0, 0, 0]
    """
    block = np.zeros(size, values.dtype)
    block[: len(values)] = values
    shuffled = block.view(np.uint8).reshape(size, values.dtype.itemsize).T.tobytes()
    packer = zlib.compressobj(level, zlib.DEFLATED, zlib.MAX_WBITS, 8, zlib.Z_RLE)
    return packer.compress(shuffled) + packer.flush()


class _StreamFile(Closing):
    """An HDF5 file opened for appending; closed as it is when an exception passes."""

    def _open(self, path: str | os.PathLike) -> None:
        import h5py

        self.path = Path(path)
        self._closed = True
        check_space(self.path, 0)
        try:
            # No chunk cache: a write that fails (a full disk) fails in the write call,
            # not later in a dealloc.
            self._file = h5py.File(self.path, "w", rdcc_nbytes=0)
        except OSError as err:
            raise OutputError(self.path, err) from err
        self._closed = False

    def _abandon(self) -> None:
        """Close the file as it is: what was flushed stays readable."""
        if not self._closed:
            self._closed = True
            try:
                self._file.close()
            except (OSError, RuntimeError) as err:
                raise OutputError(self.path, err) from err

    def __exit__(self, exc_type: Any, exc: Any, tb: Any) -> None:
        if exc_type is None:
            self.close()
        else:
            self._abandon()


class H5Appender(_StreamFile):
    """Resizable HDF5 datasets, appended row by row and flushed in chunks.

    ``fields`` maps a dataset name to ``(dtype, row_shape)``; ``attrs`` are set at
    creation. Rows are written every ``chunk_rows`` rows or ``flush_s`` seconds. The file
    carries ``complete`` (False until :meth:`close`) and ``rows`` (flushed so far).
    """

    def __init__(
        self,
        path: str | os.PathLike,
        fields: Mapping[str, tuple[Any, tuple[int, ...]]],
        attrs: Mapping[str, Any] | None = None,
        chunk_rows: int = 256,
        compression: bool = True,
        flush_s: float = 1.0,
    ) -> None:
        self.fields = {k: (np.dtype(d), tuple(s)) for k, (d, s) in fields.items()}
        self.chunk_rows = int(chunk_rows)
        self.flush_s = float(flush_s)
        self._last_flush = time.monotonic()
        self.rows = 0
        self._buffer: dict[str, list[np.ndarray]] = {k: [] for k in self.fields}
        self._buffered = 0
        self._open(path)
        try:
            for name, (dtype, shape) in self.fields.items():
                if 0 in shape:  # nothing to store per row (no moving objects): made at close
                    continue
                self._file.create_dataset(
                    name,
                    shape=(0, *shape),
                    maxshape=(None, *shape),
                    dtype=dtype,
                    chunks=(self.chunk_rows, *shape),
                    **({"compression": "gzip", "compression_opts": 4} if compression else {}),
                )
            for k, v in (attrs or {}).items():
                self._file.attrs[k] = v
            self._file.attrs["complete"] = False
            self._file.attrs["rows"] = 0
            self._file.flush()
        except BaseException:
            self._abandon()
            raise

    def append(self, **row: Any) -> None:
        """One row per field (``row[name]`` of the field's row shape)."""
        for name, (dtype, shape) in self.fields.items():
            value = np.asarray(row[name], dtype=dtype)
            if value.shape != shape:
                raise ValueError(f"{self.path}: {name} row has shape {value.shape}, not {shape}")
            self._buffer[name].append(value)
        self._buffered += 1
        due = time.monotonic() - self._last_flush >= self.flush_s
        if self._buffered >= self.chunk_rows or due:
            self.flush()

    def flush(self) -> None:
        """Append the buffered rows and flush the file."""
        self._last_flush = time.monotonic()
        if self._closed or not self._buffered:
            return
        need = sum(
            self._buffered * d.itemsize * int(np.prod(s, dtype=np.int64))
            for d, s in self.fields.values()
        )
        check_space(self.path, need)
        n, self._buffered = self._buffered, 0
        try:
            for name, rows in self._buffer.items():
                if name not in self._file:
                    rows.clear()
                    continue
                ds = self._file[name]
                ds.resize(self.rows + n, axis=0)
                ds[self.rows :] = np.stack(rows)
                rows.clear()
            self.rows += n
            self._file.attrs["rows"] = self.rows
            self._file.flush()
        except (OSError, RuntimeError) as err:
            divert_h5(self._file)  # closing it later cannot segfault on the full disk
            raise OutputError(self.path, err) from err

    def close(self, attrs: Mapping[str, Any] | None = None) -> None:
        """Flush, set ``attrs`` and ``complete = True``, close; idempotent."""
        if self._closed:
            return
        try:
            self.flush()
            for name, (dtype, shape) in self.fields.items():
                if name not in self._file:
                    self._file.create_dataset(name, shape=(self.rows, *shape), dtype=dtype)
            for k, v in (attrs or {}).items():
                self._file.attrs[k] = v
            self._file.attrs["complete"] = True
        finally:
            self._abandon()


class EventStreamWriter(_StreamFile):
    """``events.h5`` written as the events are made (module docstring).

    Each :meth:`append` is checked against the sensor and the time order of what came
    before (a ``ValueError`` naming the file). ``metadata`` is stored at creation and
    replaced by :meth:`close`'s, if given.
    """

    def __init__(
        self,
        path: str | os.PathLike,
        sensor_size: SensorSize,
        metadata: Mapping[str, Any] | None = None,
        chunk_events: int = 1 << 16,
        flush_s: float = 1.0,
    ) -> None:
        self.sensor_size = (int(sensor_size[0]), int(sensor_size[1]), 2)
        self.chunk_events = int(chunk_events)
        self.flush_s = float(flush_s)
        self.flushed = 0
        self.last_t_us: int | None = None
        self._buffer: list[np.ndarray] = []
        self._buffered = 0
        self._tail = np.zeros(0, EVENT_DTYPE)  # flushed events of the partial last chunk
        self._last_flush = time.monotonic()
        self._index = MsToIdx()  # DSEC's ms_to_idx, built chunk by chunk
        self._open(path)
        try:
            g = self._file.create_group("events")
            self._columns = {  # the datasets, looked up once (a lookup a flush cost 0.3 ms)
                name: g.create_dataset(
                    name,
                    shape=(0,),
                    maxshape=(None,),
                    dtype=EVENT_DTYPE[name],
                    chunks=(self.chunk_events,),
                    compression="gzip",
                    compression_opts=GZIP_LEVEL,
                    shuffle=True,
                )
                for name in _FIELDS
            }
            attrs = self._file.attrs
            attrs["sensor_size"] = np.asarray(self.sensor_size, dtype=np.int64)
            attrs["metadata"] = dumps_strict(dict(metadata or {}))
            attrs["format"] = FORMAT_TAG
            attrs["complete"] = False
            attrs["events_flushed"] = 0
            attrs["t_flushed_us"] = -1
            self._file.flush()
        except BaseException:
            self._abandon()
            raise

    @property
    def events_written(self) -> int:
        """Events appended so far (flushed or still buffered)."""
        return self.flushed + self._buffered

    def append(self, events: np.ndarray) -> None:
        """Queue one step's events (sorted, after the previous step's); flush when due."""
        if self._closed:
            raise ValueError(f"{self.path}: the writer is closed")
        if len(events):
            validate_events(events, self.sensor_size, where=str(self.path))
            t0 = int(events["t"][0])
            if self.last_t_us is not None and t0 < self.last_t_us:
                raise ValueError(
                    f"{self.path}: events start at t={t0} before the previous ones end at "
                    f"t={self.last_t_us}"
                )
            self._buffer.append(np.asarray(events).astype(EVENT_DTYPE, copy=True))
            self._buffered += len(events)
            self.last_t_us = int(events["t"][-1])
        if self._buffered and time.monotonic() - self._last_flush >= self.flush_s:
            self.flush()
        elif self._buffered >= self.chunk_events:
            self.flush(whole_chunks=True)

    def flush(self, whole_chunks: bool = False) -> None:
        """Append the buffered events to the datasets and flush the file to disk;
        ``whole_chunks``: only the chunks they fill, the rest stays buffered until the next
        flush (so each chunk is compressed once: on a closed-loop run, whose batches are about
        a chunk, flushing every buffered event compressed 1.7× as many chunks).

        The chunks are compressed here (HDF5's shuffle, then zlib at ``GZIP_LEVEL``: the
        datasets' own filters) and written as they are stored: zlib works without
        Python's lock, which h5py's filters hold, so the other threads run meanwhile. A
        partial chunk at the end is written again, longer, by a later flush."""
        if not whole_chunks:
            self._last_flush = time.monotonic()
        if self._closed or not self._buffered:
            return
        new = np.concatenate(self._buffer)
        data = np.concatenate([self._tail, new])  # from the chunk boundary at or before a
        end = len(data) // self.chunk_events * self.chunk_events if whole_chunks else len(data)
        if end <= len(self._tail):  # no chunk filled
            return
        chunk, rest = new[: end - len(self._tail)], new[end - len(self._tail) :]
        data = data[:end]
        check_space(self.path, len(chunk) * EVENT_DTYPE.itemsize)
        self._buffer, self._buffered = ([rest] if len(rest) else []), len(rest)
        a, b = self.flushed, self.flushed + len(chunk)
        start = a - len(self._tail)
        try:
            for name, column in self._columns.items():
                column.resize((b,))
                for k in range(0, len(data), self.chunk_events):
                    block = stored_chunk(data[name][k : k + self.chunk_events], self.chunk_events)
                    column.id.write_direct_chunk((start + k,), block, 0)
            self._file.attrs.modify("events_flushed", b)
            self._file.attrs.modify("t_flushed_us", int(chunk["t"][-1]))
            self._file.flush()
        except (OSError, RuntimeError) as err:
            divert_h5(self._file)  # closing it later cannot segfault on the full disk
            raise OutputError(self.path, err) from err
        self.flushed = b
        self._tail = data[len(data) // self.chunk_events * self.chunk_events :]
        self._index.add(chunk["t"])

    def close(self, metadata: Mapping[str, Any] | None = None) -> None:
        """Flush the rest, store ``metadata`` (if given), mark the file complete; idempotent."""
        if self._closed:
            return
        try:
            self.flush()
            if metadata is not None:
                self._file.attrs["metadata"] = dumps_strict(dict(metadata))
            self._index.write(self._file)  # the DSEC index of a finished file
            self._file.attrs["complete"] = True
        finally:
            self._abandon()
