"""DSEC's ``ms_to_idx`` index of an HDF5 event file, and a time window read through it.

A wander ``.h5`` (:func:`wander_env.events.io.write_events`, the streaming writer of
:mod:`wander_env.events.stream`) carries ``ms_to_idx`` (:func:`ms_to_idx`: entry ``i`` is
the first event at or after ``t_offset + i`` ms) and ``t_offset`` (µs,
:func:`index_offset_us`: 0, as in DSEC, unless the clock starts after a minute);
:func:`read_h5_window` reads one time window through it without loading the file,
checking the index against the timestamps it uses.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np

from wander_env.events import time_window
from wander_env.events.checks import EventFileError

__all__ = [
    "MS_TO_IDX_ZERO_OFFSET_LIMIT_US",
    "MsToIdx",
    "index_offset_us",
    "ms_to_idx",
    "read_h5_window",
    "write_ms_to_idx",
]

# t_offset stays 0 (DSEC-compatible) unless the clock starts later than this.
MS_TO_IDX_ZERO_OFFSET_LIMIT_US = 60_000_000


def ms_to_idx(t: np.ndarray, t_offset_us: int = 0, first_ms: int = 0) -> np.ndarray:
    """DSEC's index: entry ``i`` is the first event with ``t >= t_offset_us + 1000 i``.

    One entry per millisecond up to the last event's, from entry ``first_ms`` on (the
    rest of an index whose entries before ``first_ms`` fall before every event of ``t``).

    >>> ms_to_idx(np.array([0, 10, 999, 1000, 3500])).tolist()
    [0, 3, 4, 4]
    >>> ms_to_idx(np.array([2500, 3500]), first_ms=2).tolist()
    [0, 1]
    """
    t = np.asarray(t, dtype=np.int64)
    if t.size == 0:
        return np.zeros(0, np.uint64)
    last_ms = (int(t[-1]) - int(t_offset_us)) // 1000
    ms = np.arange(first_ms, max(last_ms + 1, first_ms), dtype=np.int64)
    return np.searchsorted(t, int(t_offset_us) + 1000 * ms, side="left").astype(np.uint64)


def index_offset_us(t: np.ndarray) -> int:
    """``t_offset`` of the index: 0 (as DSEC) unless the clock starts after a minute.

    >>> index_offset_us(np.array([5, 9])), index_offset_us(np.array([1_605_537_493_718_345]))
    (0, 1605537493718000)
    """
    if len(t) == 0 or 0 <= int(t[0]) < MS_TO_IDX_ZERO_OFFSET_LIMIT_US:
        return 0
    return int(t[0]) // 1000 * 1000


class MsToIdx:
    """:func:`ms_to_idx` of events given in time-ordered batches, none of them kept: the
    index of the concatenated batches, whatever their sizes (empty ones included).

    >>> index = MsToIdx()
    >>> for t in ([0, 10], [], [999, 1000], [3500]):
    ...     index.add(np.array(t, np.int64))
    >>> index.offset_us, np.concatenate(index.parts).tolist()
    (0, [0, 3, 4, 4])
    """

    def __init__(self) -> None:
        self.offset_us: int | None = None  # set by the first event (index_offset_us)
        self.parts: list[np.ndarray] = []
        self.rows = 0  # events added so far
        self.next_ms = 0  # the first entry not yet indexed

    def add(self, t: np.ndarray) -> None:
        """Index the batch ``t`` (sorted, at or after every earlier batch's events)."""
        if len(t) == 0:
            return
        if self.offset_us is None:
            self.offset_us = index_offset_us(t)
        part = ms_to_idx(t, self.offset_us, self.next_ms)
        self.parts.append(part + np.uint64(self.rows))
        self.next_ms += len(part)
        self.rows += len(t)

    def write(self, h5file: Any) -> None:
        """Add ``ms_to_idx`` and ``t_offset`` (µs) to an open ``h5py.File``.

        ``events/t`` stays absolute: the index counts milliseconds from ``t_offset``,
        which is 0 — DSEC's own convention — for every recording whose clock starts within
        a minute of 0 (all simulated ones); an empty recording has an empty index at 0.
        """
        index = np.concatenate(self.parts) if self.parts else np.zeros(0, np.uint64)
        h5file.create_dataset("ms_to_idx", data=index)
        h5file.create_dataset("t_offset", data=np.int64(self.offset_us or 0))


def write_ms_to_idx(h5file: Any, events: np.ndarray) -> None:
    """Add the :class:`MsToIdx` index of all of ``events`` to an open ``h5py.File``."""
    index = MsToIdx()
    index.add(events["t"])
    index.write(h5file)


def read_h5_window(path: str | os.PathLike, t_start_us: int, t_end_us: int) -> np.ndarray:
    """The events with ``t_start_us <= t < t_end_us`` of a wander ``.h5``, via ``ms_to_idx``.

    Reads only the rows the index points at (plus at most a millisecond either side),
    not the whole file. Raises :class:`EventFileError` when the index is missing,
    damaged or disagrees with the timestamps.
    """
    import h5py

    from wander_env.events import EVENT_DTYPE

    path = Path(path)
    try:
        with h5py.File(path, "r") as f:
            if "ms_to_idx" not in f or "events" not in f or "t" not in f["events"]:
                raise EventFileError(path, "no 'ms_to_idx' index (write it with wander >= 0.1)")
            g = f["events"]
            n = int(g["t"].shape[0])
            index = np.asarray(f["ms_to_idx"][()])
            offset = int(f["t_offset"][()]) if "t_offset" in f else 0
            if index.ndim != 1 or index.dtype.kind not in "ui":
                raise EventFileError(
                    path, f"ms_to_idx has dtype {index.dtype}, shape {index.shape}"
                )
            if index.size and (np.any(np.diff(index.astype(np.int64)) < 0) or index[-1] > n):
                raise EventFileError(path, "ms_to_idx decreases or points past the events")
            t_last = int(g["t"][n - 1]) if n else offset
            if n and index.size != (t_last - offset) // 1000 + 1:
                raise EventFileError(
                    path,
                    f"ms_to_idx has {index.size} entries; events up to t={t_last} µs need "
                    f"{(t_last - offset) // 1000 + 1}",
                )

            t_col = g["t"]

            def row(ms: int) -> int:
                """``index[ms]``, checked against the timestamps on either side of it."""
                if ms < 0:
                    return 0
                if ms >= index.size:
                    return n
                i, edge = int(index[ms]), offset + 1000 * ms
                if (i > 0 and int(t_col[i - 1]) >= edge) or (i < n and int(t_col[i]) < edge):
                    raise EventFileError(
                        path, f"ms_to_idx[{ms}]={i} disagrees with events/t around t={edge} µs"
                    )
                return i

            lo = row((int(t_start_us) - offset) // 1000)
            hi = row(-(-(int(t_end_us) - offset) // 1000))
            cols = {k: g[k][lo:hi] for k in ("x", "y", "t", "p")}
    except EventFileError:
        raise
    except (OSError, KeyError, ValueError) as err:
        raise EventFileError(path, f"not a readable HDF5 event file ({err})") from None
    ev = np.empty(max(hi - lo, 0), dtype=EVENT_DTYPE)
    for k, v in cols.items():
        ev[k] = v
    return time_window(ev, int(t_start_us), int(t_end_us))
