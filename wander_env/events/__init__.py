"""The one event format shared by the simulator, the rig and replay.

Events are a NumPy structured array with fields ``x``, ``y`` (int16 pixel
coordinates, origin top-left, y down), ``t`` (int64 microseconds) and ``p``
(int8, 1 = ON, 0 = OFF), sorted by ``t``: the Tonic convention. A sensor is
described by ``sensor_size = (W, H, 2)``.

This package is the event library on its own: the array helpers here, and

- :mod:`wander_env.events.packet`: one step's events as a value (``info["events"]``);
- :mod:`wander_env.events.io`: ``read_events`` / ``write_events``, by suffix;
- :mod:`wander_env.events.formats`: the field's formats (EVT2/3, DAT, AEDAT4, ES);
- :mod:`wander_env.events.hdf5_index`: DSEC's ``ms_to_idx`` index, a window read through it;
- :mod:`wander_env.events.evimo2`: the EVIMO2v2 sequence layout (events and masks);
- :mod:`wander_env.events.checks`: limits and checks for untrusted files;
- :mod:`wander_env.events.stream`: ``events.h5`` written as events are made.

None of them imports the simulator (MuJoCo, the renderer, the env) or torch: reading and
writing event files costs NumPy and the format's own library. Outside this package they
use only two dependency-free helpers, :mod:`wander_env.strict_json` and
:mod:`wander_env.closing`. ``import wander_env.events`` runs ``wander_env/__init__.py``,
which registers the env with Gymnasium by name (the env module itself is not imported).

Examples:
    >>> import numpy as np
    >>> from wander_env.events import make_events, to_frame
    >>> ev = make_events(x=[1, 2], y=[0, 0], t=[10, 20], p=[1, 0])
    >>> to_frame(ev, (4, 2, 2)).sum(axis=(1, 2)).tolist()
    [1.0, 1.0]
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence

import numpy as np

EVENT_DTYPE = np.dtype([("x", "<i2"), ("y", "<i2"), ("t", "<i8"), ("p", "i1")])

SensorSize = tuple[int, int, int]


def empty_events(n: int = 0) -> np.ndarray:
    """An uninitialised event array of length ``n`` (zeros for ``n = 0``)."""
    return np.zeros(n, dtype=EVENT_DTYPE)


def make_events(
    x: Iterable[int], y: Iterable[int], t: Iterable[int], p: Iterable[int]
) -> np.ndarray:
    """Build an event array from columns; checks lengths and that ``t`` is sorted."""
    cols = [np.asarray(c) for c in (x, y, t, p)]
    n = len(cols[0])
    if any(len(c) != n for c in cols):
        raise ValueError(f"event columns differ in length: {[len(c) for c in cols]}")
    ev = np.empty(n, dtype=EVENT_DTYPE)
    for name, col in zip(("x", "y", "t", "p"), cols, strict=True):
        ev[name] = col
    check_sorted(ev)
    return ev


def check_sorted(events: np.ndarray, where: str = "events") -> None:
    """Raise ``ValueError`` naming the first index where ``t`` decreases."""
    if len(events) > 1:
        bad = np.flatnonzero(np.diff(events["t"]) < 0)
        if bad.size:
            i = int(bad[0])
            raise ValueError(
                f"{where}: timestamps are not sorted: t[{i}]={events['t'][i]} > "
                f"t[{i + 1}]={events['t'][i + 1]} ({bad.size} decreasing steps in all)"
            )


def validate_events(events: np.ndarray, sensor_size: SensorSize, where: str = "events") -> None:
    """Check dtype fields, coordinate bounds, polarity values and time order.

    Raises ``ValueError`` that names ``where`` and the first offending event.
    """
    if events.dtype.names is None or not {"x", "y", "t", "p"} <= set(events.dtype.names):
        raise ValueError(f"{where}: expected fields x, y, t, p, got dtype {events.dtype}")
    w, h = int(sensor_size[0]), int(sensor_size[1])
    for field, limit in (("x", w), ("y", h)):
        col = events[field]
        bad = np.flatnonzero((col < 0) | (col >= limit))
        if bad.size:
            i = int(bad[0])
            raise ValueError(
                f"{where}: {field}[{i}]={col[i]} is outside the sensor (0..{limit - 1}); "
                f"{bad.size} events out of range"
            )
    bad = np.flatnonzero((events["p"] != 0) & (events["p"] != 1))
    if bad.size:
        i = int(bad[0])
        raise ValueError(f"{where}: p[{i}]={events['p'][i]} is not 0 (OFF) or 1 (ON)")
    check_sorted(events, where)


def time_window(events: np.ndarray, t_start: int, t_end: int) -> np.ndarray:
    """Events with ``t_start <= t < t_end`` (a view; ``events`` must be sorted)."""
    t = events["t"]
    lo, hi = np.searchsorted(t, [t_start, t_end], side="left")
    return events[lo:hi]


def to_frame(events: np.ndarray, sensor_size: SensorSize) -> np.ndarray:
    """Per-polarity event counts, shape ``(2, H, W)``: channel 0 OFF, channel 1 ON."""
    w, h = int(sensor_size[0]), int(sensor_size[1])
    idx = (events["p"].astype(np.int64) * h + events["y"]) * w + events["x"]
    counts = np.bincount(idx, minlength=2 * h * w)
    if counts.size != 2 * h * w:
        raise ValueError(
            f"events fall outside sensor_size={tuple(sensor_size)}; run validate_events first"
        )
    return counts.reshape(2, h, w).astype(np.float32)


def merge(*arrays: np.ndarray) -> np.ndarray:
    """Merge several sorted event arrays into one sorted array (stable on ties)."""
    if not arrays:
        return empty_events()
    cat = np.concatenate(arrays)
    return cat[np.argsort(cat["t"], kind="stable")]


def concatenate(arrays: Sequence[np.ndarray]) -> np.ndarray:
    """Join consecutive chunks of one stream, checking that order is kept.

    Unlike :func:`merge` this never reorders: a chunk that starts before the
    previous one ended is an error, because it means the chunks overlap.
    """
    chunks = [a for a in arrays if len(a)]
    for i in range(1, len(chunks)):
        if chunks[i]["t"][0] < chunks[i - 1]["t"][-1]:
            raise ValueError(
                f"chunk {i} starts at t={chunks[i]['t'][0]} before chunk {i - 1} ends at "
                f"t={chunks[i - 1]['t'][-1]}; use merge() for overlapping streams"
            )
    if not chunks:
        return empty_events()
    return np.concatenate(chunks)


def rate_hz(events: np.ndarray, duration_s: float, n_pixels: int) -> float:
    """Mean event rate per pixel in Hz over ``duration_s``."""
    return len(events) / (duration_s * n_pixels)
