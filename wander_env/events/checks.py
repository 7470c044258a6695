"""Event files are untrusted: checks made before anything is allocated or cast.

Every reader of :mod:`wander_env.events.io` goes through these. A check that fails
raises :class:`EventFileError` naming the file, the field and the offending value:

- :func:`check_sensor_size`: two or three whole numbers, positive, at most
  ``max_side`` (:data:`MAX_SENSOR_SIDE` unless the caller raises it) per side;
- :func:`check_claim`: a count a header claims, against the bytes the file really
  holds (a 3 KB file cannot hold 2^27 events);
- :meth:`ReadLimits.check_count`: the events a file holds (its header's claim, or what a
  decoder has produced so far), at most ``max_events`` (:data:`MAX_EVENTS`): a
  compressed file of a few MB can hold 2^27 events, which decompress to GBs;
- :func:`check_sensor_area`: the sensor area the agent and the benchmark model will
  process, at most :data:`MAX_SENSOR_PIXELS` (their maps take about 1.2 KB a pixel);
- :func:`fill_events`: the columns copied in chunks of :data:`CHUNK_EVENTS` into the
  shared event dtype, each chunk checked first: integer (or whole, finite float)
  values, inside the sensor and the dtype (no silent cast: ``x = 65541`` is an
  error, not 5), polarity 0 or 1, ``t`` finite and sorted;
- :func:`parse_metadata`: a JSON object, by the rules of every untrusted JSON document
  (:func:`wander_env.untrusted.parse_json`: nested at most ``LIMITS.json_depth`` deep, no
  key given twice).

Examples:
    >>> import numpy as np
    >>> cols = {"x": np.array([1, 2]), "y": np.array([0, 3]), "t": np.array([5, 9]),
    ...         "p": np.array([1, 0])}
    >>> fill_events("a.npy", cols, (4, 4, 2))["x"].tolist()
    [1, 2]
    >>> cols["x"] = np.array([1.0, 12.7])
    >>> fill_events("a.npy", cols, (16, 16, 2))
    Traceback (most recent call last):
    ...
    wander_env.events.checks.EventFileError: a.npy: field 'x': x[1]=12.7 is not a whole number
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from wander_env.events import EVENT_DTYPE, SensorSize
from wander_env.file_error import FileError
from wander_env.untrusted import UntrustedFileError, parse_json

#: The largest sensor side a reader accepts unless its caller raises the limit.
MAX_SENSOR_SIDE = 8192
#: The most events a reader returns unless its caller raises the limit: 218 MB as events;
#: a replay or a benchmark of this many events stays within about 1.5 GB.
MAX_EVENTS = 1 << 24
#: The largest sensor area (W×H) the agent and the benchmark model process: the HD sensor of
#: Prophesee's Gen4 / IMX636 (1280×720); their maps take about 1.2 KB a pixel, 1.1 GB here.
MAX_SENSOR_PIXELS = 1280 * 720
#: Events checked and copied at a time.
CHUNK_EVENTS = 1 << 20
_FIELDS = ("x", "y", "t", "p")


@dataclass(eq=False, repr=False)
class EventFileError(FileError):
    """An event file could not be read: names the file, the field and what was wrong (the
    offending ``value``)."""

    value: Any = None

    def message(self) -> str:
        """``FILE: field 'FIELD': PROBLEM``."""
        where = f"field {self.field!r}: " if self.field is not None else ""
        return f"{self.path}: {where}{self.problem}"


def check_sensor_size(
    path: str | os.PathLike,
    value: Any,
    max_side: int = MAX_SENSOR_SIDE,
    field: str = "sensor_size",
) -> SensorSize:
    """``(W, H, 2)`` from ``value``, or :class:`EventFileError` saying what is wrong.

    >>> check_sensor_size("f.h5", [346, 260])
    (346, 260, 2)
    >>> check_sensor_size("f.h5", (100000, 100000, 2))  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    wander_env.events.checks.EventFileError: f.h5: field 'sensor_size': (100000, ...) exceeds ...
    """
    try:
        items = list(np.asarray(value).reshape(-1).tolist())
    except (TypeError, ValueError):
        raise EventFileError(path, f"{value!r} is not a list of numbers", field, value) from None
    shown = tuple(items) if len(items) <= 8 else f"{len(items)} values"
    if len(items) not in (2, 3):
        raise EventFileError(
            path, f"{shown} must be (width, height) or (width, height, 2)", field, value
        )
    if not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in items):
        raise EventFileError(path, f"{shown} is not all numbers", field, value)
    if not all(math.isfinite(v) and float(v).is_integer() for v in items):
        raise EventFileError(path, f"{shown} is not all whole numbers", field, value)
    w, h = int(items[0]), int(items[1])
    if len(items) == 3 and int(items[2]) != 2:
        raise EventFileError(path, f"{shown}: the third entry (polarities) must be 2", field, value)
    if w < 1 or h < 1:
        raise EventFileError(path, f"{shown}: width and height must be >= 1", field, value)
    if w > max_side or h > max_side:
        raise EventFileError(
            path,
            f"{shown} exceeds {max_side} pixels per side (pass a larger max_sensor_side to "
            "read it)",
            field,
            value,
        )
    return (w, h, 2)


@dataclass(frozen=True)
class ReadLimits:
    """What a reader accepts: ``max_side`` pixels per sensor side, ``max_events`` events.

    >>> ReadLimits(max_events=10).check_count("f.h5", "events/t", 11)
    Traceback (most recent call last):
    ...
    wander_env.events.checks.EventFileError: f.h5: field 'events/t': holds at least 11 events; \
at most 10 are read (the max_events of read_events)
    """

    max_side: int = MAX_SENSOR_SIDE
    max_events: int = MAX_EVENTS

    def check_count(self, path: str | os.PathLike, field: str, count: int) -> None:
        """``count`` events (claimed, or decoded so far) must not pass ``max_events``."""
        if count > self.max_events:
            raise EventFileError(
                path,
                f"holds at least {count:,} events; at most {self.max_events:,} are read "
                "(the max_events of read_events)",
                field,
                count,
            )


def check_sensor_area(
    path: str | os.PathLike,
    sensor_size: SensorSize,
    max_pixels: int = MAX_SENSOR_PIXELS,
    field: str = "sensor_size",
) -> None:
    """The agent's and the benchmark model's maps cost about 1.2 KB a pixel: a sensor of
    more than ``max_pixels`` is refused before they are allocated.

    >>> check_sensor_area("f.h5", (8192, 8192, 2))
    Traceback (most recent call last):
    ...
    wander_env.events.checks.EventFileError: f.h5: field 'sensor_size': 8192x8192 is \
67,108,864 pixels; the agent and the benchmark model process at most 921,600 (about 1.2 KB \
of maps a pixel)
    """
    w, h = int(sensor_size[0]), int(sensor_size[1])
    if w * h > max_pixels:
        raise EventFileError(
            path,
            f"{w}x{h} is {w * h:,} pixels; the agent and the benchmark model process at most "
            f"{max_pixels:,} (about 1.2 KB of maps a pixel)",
            field,
            [w, h],
        )


def check_claim(
    path: str | os.PathLike, field: str, count: int, itemsize: int, available: int
) -> None:
    """A header's ``count`` items of ``itemsize`` bytes must fit in ``available`` bytes."""
    if count < 0:
        raise EventFileError(path, f"claims a negative count {count}", field, count)
    need = count * itemsize
    if need > available:
        raise EventFileError(
            path,
            f"claims {count:,} entries ({need:,} bytes) but the file holds only "
            f"{available:,} bytes for them (truncated or forged header)",
            field,
            count,
        )


def parse_metadata(path: str | os.PathLike, raw: Any, field: str = "metadata") -> dict[str, Any]:
    """The ``metadata`` JSON object (bytes or str), parsed by the rules of every untrusted
    JSON document (:func:`wander_env.untrusted.parse_json`: nested at most
    ``LIMITS.json_depth`` deep, no key given twice); :class:`EventFileError` otherwise.

    >>> parse_metadata("a.h5", '{"seed": 1, "seed": 2}')
    Traceback (most recent call last):
    ...
    wander_env.events.checks.EventFileError: a.h5: field 'metadata': the key 'seed' is given twice
    """
    if isinstance(raw, np.ndarray):
        raw = raw.item() if raw.shape == () else raw
    if isinstance(raw, bytes):
        try:
            raw = raw.decode("utf-8")
        except UnicodeDecodeError as err:
            raise EventFileError(path, f"not UTF-8 text ({err})", field) from None
    if not isinstance(raw, str):
        raise EventFileError(path, f"expected JSON text, got {type(raw).__name__}", field)
    try:
        meta = parse_json(raw, path)
    except UntrustedFileError as err:
        raise EventFileError(path, err.problem, field) from None
    if not isinstance(meta, dict):
        raise EventFileError(path, f"expected a JSON object, got {type(meta).__name__}", field)
    return meta


def json_depth(value: Any) -> int:
    """How deep lists and objects nest in ``value`` (walked without recursion).

    >>> json_depth({"a": [1, {"b": []}]}), json_depth(3)
    (4, 0)
    """
    deepest, stack = 0, [(value, 1)]
    while stack:
        v, depth = stack.pop()
        items = v.values() if isinstance(v, dict) else v if isinstance(v, list) else None
        if items is not None:
            deepest = max(deepest, depth)
            stack.extend((item, depth + 1) for item in items)
    return deepest


def _limits(name: str, sensor_size: SensorSize | None, max_side: int) -> tuple[int, int]:
    """The allowed [lo, hi] of a column."""
    if name == "t":
        return np.iinfo(np.int64).min, np.iinfo(np.int64).max
    if name == "p":
        return 0, 1
    side = 0 if name == "x" else 1
    hi = (sensor_size[side] if sensor_size is not None else max_side) - 1
    return 0, min(hi, np.iinfo(np.int16).max)


def check_column(
    path: str | os.PathLike,
    name: str,
    values: np.ndarray,
    sensor_size: SensorSize | None,
    max_side: int = MAX_SENSOR_SIDE,
    offset: int = 0,
) -> np.ndarray:
    """``values`` of column ``name`` as int64, each checked (index ``offset`` + i named)."""
    v = np.asarray(values)
    if v.ndim != 1:
        raise EventFileError(path, f"expected a 1-D column, got shape {v.shape}", name)
    kind = v.dtype.kind
    if kind == "b":
        v = v.astype(np.int64)
    elif kind == "f":
        bad = np.flatnonzero(~np.isfinite(v))
        if bad.size:
            i = int(bad[0])
            raise EventFileError(
                path, f"{name}[{offset + i}]={v[i]} is not a finite number", name, v[i].item()
            )
        frac = np.flatnonzero(v != np.floor(v))
        if frac.size:
            i = int(frac[0])
            raise EventFileError(
                path, f"{name}[{offset + i}]={v[i]} is not a whole number", name, v[i].item()
            )
        if len(v) and (v.min() < -(2.0**63) or v.max() >= 2.0**63):
            i = int(np.argmax(np.abs(v)))
            raise EventFileError(
                path, f"{name}[{offset + i}]={v[i]} does not fit in int64", name, v[i].item()
            )
        v = v.astype(np.int64)
    elif kind == "u":
        if v.dtype.itemsize == 8 and len(v) and v.max() > np.iinfo(np.int64).max:
            i = int(np.argmax(v))
            raise EventFileError(
                path, f"{name}[{offset + i}]={v[i]} does not fit in int64", name, int(v[i])
            )
        v = v.astype(np.int64)
    elif kind == "i":
        v = v.astype(np.int64, copy=False)
    else:
        raise EventFileError(path, f"dtype {v.dtype} is not a number type", name, str(v.dtype))
    lo, hi = _limits(name, sensor_size, max_side)
    if name != "t" and len(v):
        bad = np.flatnonzero((v < lo) | (v > hi))
        if bad.size:
            i = int(bad[0])
            what = {
                "x": f"outside the sensor (0..{hi})",
                "y": f"outside the sensor (0..{hi})",
                "p": "not 0 (OFF) or 1 (ON)",
            }[name]
            raise EventFileError(
                path,
                f"{name}[{offset + i}]={v[i]} is {what}; {bad.size} such values in this chunk",
                name,
                int(v[i]),
            )
    return v


def n_rows(path: str | os.PathLike, columns: Mapping[str, Any]) -> int:
    """The common length of the x, y, t, p columns (an error when one is missing)."""
    missing = [f for f in _FIELDS if f not in columns]
    if missing:
        raise EventFileError(path, f"missing event fields {missing}")
    shapes = {f: tuple(getattr(columns[f], "shape", (len(columns[f]),))) for f in _FIELDS}
    for f, shape in shapes.items():
        if len(shape) != 1:
            raise EventFileError(path, f"expected a 1-D column, got shape {shape}", f, shape)
    lengths = {f: s[0] for f, s in shapes.items()}
    if len(set(lengths.values())) != 1:
        raise EventFileError(path, f"event columns differ in length: {lengths}")
    return int(lengths["t"])


def column_max(
    path: str | os.PathLike, name: str, column: Any, n: int, max_side: int, chunk: int
) -> int:
    """The largest value of a coordinate column, read in chunks and checked (-1 if empty)."""
    top = -1
    for a in range(0, n, chunk):
        v = check_column(path, name, column[a : a + chunk], None, max_side, offset=a)
        if len(v):
            top = max(top, int(v.max()))
    return top


def fill_events(
    path: str | os.PathLike,
    columns: Mapping[str, Any],
    sensor_size: SensorSize | None,
    max_side: int = MAX_SENSOR_SIDE,
    chunk: int = CHUNK_EVENTS,
    n: int | None = None,
) -> np.ndarray:
    """Copy sliceable x, y, t, p columns into one checked, sorted event array.

    ``columns`` may be arrays, memory maps or HDF5 datasets: only ``chunk`` events
    are read at a time. ``n`` limits the rows read (default: all).
    """
    total = n_rows(path, columns)
    n = total if n is None else min(int(n), total)
    out = np.empty(n, dtype=EVENT_DTYPE)
    last_t: int | None = None
    for a in range(0, n, chunk):
        b = min(n, a + chunk)
        block = {
            f: check_column(path, f, columns[f][a:b], sensor_size, max_side, offset=a)
            for f in _FIELDS
        }
        t = block["t"]
        if len(t):
            if last_t is not None and t[0] < last_t:
                raise EventFileError(
                    path,
                    f"timestamps are not sorted: t[{a - 1}]={last_t} > t[{a}]={t[0]}",
                    "t",
                    int(t[0]),
                )
            down = np.flatnonzero(np.diff(t) < 0)
            if down.size:
                i = int(down[0])
                raise EventFileError(
                    path,
                    f"timestamps are not sorted: t[{a + i}]={t[i]} > t[{a + i + 1}]={t[i + 1]} "
                    f"({down.size} decreasing steps in this chunk)",
                    "t",
                    int(t[i + 1]),
                )
            last_t = int(t[-1])
        for f in _FIELDS:
            out[f][a:b] = block[f]
    return out


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


def checked_recording(
    path: Path,
    columns: dict[str, Any],
    sensor_size: SensorSize | None,
    metadata: dict[str, Any],
    limits: ReadLimits,
    n: int | None = None,
) -> EventRecording:
    """The recording of a reader's raw ``columns``: check the count against the limits and
    the sensor size (or infer it from the largest coordinates), then copy the columns in
    checked chunks."""
    count = n_rows(path, columns) if n is None else n
    limits.check_count(path, "events", count)
    max_side = limits.max_side
    if sensor_size is None:
        if count == 0:
            raise EventFileError(path, "no events and no sensor size: pass sensor_size")
        chunk = 1 << 20
        w = column_max(path, "x", columns["x"], count, max_side, chunk) + 1
        h = column_max(path, "y", columns["y"], count, max_side, chunk) + 1
        sensor_size = check_sensor_size(path, (w, h, 2), max_side, "sensor_size (inferred)")
        metadata = {**metadata, "sensor_size_inferred": True}
    else:
        sensor_size = check_sensor_size(path, sensor_size, max_side)
    events = fill_events(path, columns, sensor_size, max_side, n=count)
    return EventRecording(events, sensor_size, metadata)
