"""Types shared by the benchmark dataset loaders.

A loader yields :class:`SequenceData`: one recording in the shared event format
(:data:`wander_env.events.EVENT_DTYPE`, sorted by ``t`` in µs) with its sensor size and
a list of :class:`MaskWindow` — half-open time windows ``[t_start_us, t_end_us)`` each
paired with a ground-truth object mask. Masks keep the dataset's object ids
(``labels``, 0 = background); ``mask`` is ``labels > 0`` (any object counts).

Masks stay at the resolution the dataset gives them; the benchmark protocol, not the
loader, fits them to the sensor grid (and records that it did, see
:mod:`experiments.benchmark.datasets.masks`).
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from dataclasses import dataclass, field

import numpy as np

from wander_env.events import EVENT_DTYPE, SensorSize


class DatasetLayoutError(ValueError):
    """A dataset folder or file does not have the expected layout.

    The message names the path, what was found and what was expected.
    """

    def __init__(self, path: str | os.PathLike, problem: str, expected: str = ""):
        self.path = str(path)
        self.problem = problem
        self.expected = expected
        msg = f"{self.path}: {problem}"
        if expected:
            msg += f"; expected: {expected}"
        super().__init__(msg)


@dataclass(frozen=True, eq=False)
class MaskWindow:
    """A ground-truth mask for the events with ``t_start_us <= t < t_end_us``.

    ``labels`` is an ``(H, W)`` integer array of object ids (0 = background). Unpacks as
    ``t_start_us, t_end_us, mask = window``.
    """

    t_start_us: int
    t_end_us: int
    labels: np.ndarray
    source: str = ""

    def __post_init__(self) -> None:
        if self.t_end_us <= self.t_start_us:
            raise ValueError(
                f"{self.source or 'mask window'}: empty time window "
                f"[{self.t_start_us}, {self.t_end_us}) µs"
            )
        if np.ndim(self.labels) != 2:
            raise ValueError(
                f"{self.source or 'mask window'}: mask must be 2-D (H, W), "
                f"got shape {np.shape(self.labels)}"
            )

    @property
    def mask(self) -> np.ndarray:
        """Boolean ``(H, W)`` map: True where any object (id > 0) is."""
        return np.asarray(self.labels) > 0

    @property
    def shape(self) -> tuple[int, int]:
        """``(H, W)`` of the mask."""
        h, w = np.shape(self.labels)
        return int(h), int(w)

    @property
    def object_ids(self) -> tuple[int, ...]:
        """The object ids present (> 0), sorted."""
        ids = np.unique(np.asarray(self.labels))
        return tuple(int(i) for i in ids if i > 0)

    def __iter__(self) -> Iterator[object]:
        return iter((self.t_start_us, self.t_end_us, self.mask))


@dataclass
class SequenceData:
    """One benchmark recording: events, sensor and ground-truth mask windows."""

    dataset: str
    subset: str
    name: str
    sensor_size: SensorSize
    events: np.ndarray
    windows: list[MaskWindow]
    source: str = ""
    notes: list[str] = field(default_factory=list)

    @property
    def n_events(self) -> int:
        return len(self.events)


def events_from_columns(
    t_us: np.ndarray,
    x: np.ndarray,
    y: np.ndarray,
    p: np.ndarray,
    sensor_size: SensorSize,
    notes: list[str] | None = None,
    where: str | os.PathLike = "events",
) -> np.ndarray:
    """Events in the shared format from the columns of the file ``where``: sorted by
    ``t``, inside the sensor.

    ``t_us`` is cast to int64, ``x``/``y`` must be whole numbers, ``p`` 0/1 or −1/1
    (``p > 0`` is ON); :class:`DatasetLayoutError` naming ``where`` otherwise, as for
    columns of different lengths. Unsorted input is stably sorted and events outside the
    sensor are dropped; both are said in ``notes`` (appended to) rather than done
    silently.
    """
    n = len(t_us)
    if not (len(x) == len(y) == len(p) == n):
        raise DatasetLayoutError(
            where, f"event columns differ in length: t {n}, x {len(x)}, y {len(y)}, p {len(p)}"
        )
    for name, col in (("x", x), ("y", y)):
        col = np.asarray(col)
        if not np.issubdtype(col.dtype, np.integer):  # floats: whole and finite
            bad = ~np.isfinite(col) | (col % 1 != 0)
            if bad.any():
                raise DatasetLayoutError(
                    where, f"{name} holds values that are not whole numbers, e.g. {col[bad][0]}"
                )
    p = np.asarray(p)
    if p.dtype != np.bool_:
        bad = (p != 0) & (p != 1) & (p != -1)
        if bad.any():
            raise DatasetLayoutError(
                where, f"p holds values other than 0/1 or -1/1, e.g. {p[bad][0]}"
            )
    w, h = int(sensor_size[0]), int(sensor_size[1])
    xi = np.asarray(x).astype(np.int64)
    yi = np.asarray(y).astype(np.int64)
    inside = (xi >= 0) & (xi < w) & (yi >= 0) & (yi < h)
    ev = np.empty(int(inside.sum()), dtype=EVENT_DTYPE)
    ev["t"] = np.asarray(t_us)[inside]
    ev["x"] = xi[inside]
    ev["y"] = yi[inside]
    ev["p"] = np.asarray(p)[inside] > 0
    dropped = n - len(ev)
    if dropped and notes is not None:
        notes.append(f"dropped {dropped} events outside the {w}x{h} sensor")
    if len(ev) > 1 and np.any(np.diff(ev["t"]) < 0):
        ev = ev[np.argsort(ev["t"], kind="stable")]
        if notes is not None:
            notes.append("events were not sorted by time: sorted (stable)")
    return ev


def seconds_to_us(t_s: np.ndarray, where: str | os.PathLike = "t") -> np.ndarray:
    """Seconds (float) to integer microseconds, rounded to nearest; a NaN or infinite time
    (which no cast keeps) is :class:`DatasetLayoutError` naming ``where``."""
    return scaled_times(t_s, 1e6, where)


def scaled_times(t: np.ndarray, scale: float, where: str | os.PathLike = "t") -> np.ndarray:
    """``t × scale`` rounded to integer microseconds; :class:`DatasetLayoutError` naming
    ``where`` for a NaN or infinite time, or one past int64's microseconds."""
    us = np.asarray(t, dtype=np.float64) * scale
    bad = ~np.isfinite(us) | (np.abs(us) >= 2.0**63)
    if bad.any():
        value = np.asarray(t)[bad][0]
        raise DatasetLayoutError(where, f"t holds {value}, not a finite time")
    return np.rint(us).astype(np.int64)


def check_windows_ordered(windows: list[MaskWindow], where: str = "windows") -> None:
    """Raise ``ValueError`` unless windows are sorted by time and do not overlap."""
    for i in range(1, len(windows)):
        a, b = windows[i - 1], windows[i]
        if b.t_start_us < a.t_end_us:
            raise ValueError(
                f"{where}: window {i} [{b.t_start_us}, {b.t_end_us}) starts before window "
                f"{i - 1} [{a.t_start_us}, {a.t_end_us}) ends; windows must be sorted and "
                f"must not overlap"
            )
