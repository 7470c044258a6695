"""LLE-VOS (Li et al., "Event-assisted Low-Light Video Object Segmentation", CVPR 2024).

Public documentation of the release is thin: the dataset repository
(``HebeiFast/EventLowLightVOS``, README) only says it holds 70 videos of paired
normal/low-light frames, segmentation annotations and low-light event streams. The
layout below is the one the public code that reads it expects — ``whdgusdl48/EVOLVE``
(``datasets/Readme.md``: ``LLE_VOS/{Lowlight_Images, Annotations, Lowlight_event,
Normallight_Images, EventVoxel}`` + ``{train, val_indoor, val_outdoor, val}.txt``;
``Gen_Event/generate_voxel.py``: one ``.npz`` per frame in ``Lowlight_event/<seq>/``
with 1-D arrays ``x``, ``y``, ``t``, ``p``; ``inference/data/video_reader.py``: event
file *k* paired with frame *k* by sorted name, DAVIS-style palette PNG annotations in
``Annotations/<seq>/<frame>.png``) and a second user of the data (per-frame ``.npy``
``(N, 4)`` arrays, columns ``x, y, t, p``, ``t`` in µs, on a 346×260 grid).

Expected layout (``wander benchmark llevos PATH``)::

    PATH/                       (or PATH/<one folder>/ holding these)
      Annotations/<seq>/<frame>.png       object ids, 0 = background (P, L or RGB PNG)
      Lowlight_event/<seq>/<frame>.npz    x, y, t, p arrays   (or .npy, see below)
      Lowlight_Images/, Normallight_Images/, EventVoxel/      optional, not read
      train.txt, val.txt, val_indoor.txt, val_outdoor.txt     optional sequence lists

Assumptions (stated because the release does not document them):

- event file ``<frame>`` holds the events between the previous frame and frame
  ``<frame>``, so the annotation ``<frame>.png`` is scored on exactly those events:
  window *k* is ``[first event of file k, first event of file k+1)`` (the last one
  ends one µs after its last event), which contains every event of file *k* and no
  other when the files follow each other in time (checked: overlapping files are an
  error naming them);
- ``t`` is in ``time_unit`` (µs by default; ``"s"``, ``"ms"``, ``"ns"`` accepted);
- ``p`` is 0/1 or −1/+1 (> 0 is ON);
- ``.npy`` event files are a structured array with ``x, y, t, p`` fields or a plain
  ``(N, 4)`` array with columns ``npy_columns`` (default ``"xytp"``); ``.npz`` files
  with an ``events`` ``(N, 4)`` array use the same column order;
- the sensor grid is the annotation's size (events outside it are an error);
- a frame whose event file is empty has no time span and is not scored (noted);
  frames without an annotation are not scored, their events still reach the model
  between scored windows.

Subset = the first split list (``val_indoor``, ``val_outdoor``, ``val``, ``train``)
that names the sequence, else ``"all"``. The paper reports one accuracy per sequence
(its "sub-datasets") and the mean ± std over sequences.
"""

from __future__ import annotations

import os
import zipfile
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from experiments.benchmark.datasets.base import (
    DatasetLayoutError,
    MaskWindow,
    SequenceData,
    events_from_columns,
    scaled_times,
)
from experiments.benchmark.datasets.masks import mask_fit, read_mask_png
from wander_env.events import empty_events

ANNOTATIONS = "Annotations"
EVENTS = "Lowlight_event"
SPLITS = ("val_indoor", "val_outdoor", "val", "train")
TIME_UNITS_TO_US = {"s": 1e6, "ms": 1e3, "us": 1.0, "ns": 1e-3}
EVENT_SUFFIXES = (".npz", ".npy")
EXPECTED_LAYOUT = (
    "PATH/Annotations/<seq>/<frame>.png and PATH/Lowlight_event/<seq>/<frame>.npz "
    "(arrays x, y, t, p) or <frame>.npy (N x 4: x, y, t, p); optional "
    "PATH/{train,val,val_indoor,val_outdoor}.txt"
)


@dataclass(frozen=True)
class LLEVOSConfig:
    """How to read LLE-VOS event files (see the module docstring)."""

    time_unit: str = "us"
    npy_columns: str = "xytp"
    sensor_size: tuple[int, int, int] | None = None

    def __post_init__(self) -> None:
        if self.time_unit not in TIME_UNITS_TO_US:
            raise ValueError(f"time_unit {self.time_unit!r} not in {sorted(TIME_UNITS_TO_US)}")
        if sorted(self.npy_columns) != sorted("xytp"):
            raise ValueError(f"npy_columns must order x, y, t, p, got {self.npy_columns!r}")


def find_llevos_root(path: str | os.PathLike) -> Path:
    """``path`` or its single child holding ``Annotations/`` and ``Lowlight_event/``."""
    path = Path(path)
    if not path.is_dir():
        raise DatasetLayoutError(path, "no such folder", EXPECTED_LAYOUT)
    candidates = [path, *sorted(p for p in path.iterdir() if p.is_dir())]
    for c in candidates:
        if (c / ANNOTATIONS).is_dir() and (c / EVENTS).is_dir():
            return c
    listing = sorted(p.name for p in path.iterdir())[:8]
    raise DatasetLayoutError(
        path,
        f"no {ANNOTATIONS}/ and {EVENTS}/ folders (found {listing or 'nothing'})",
        EXPECTED_LAYOUT,
    )


def read_splits(root: Path) -> dict[str, str]:
    """Sequence name → subset from the split lists present under ``root``."""
    subset: dict[str, str] = {}
    for split in SPLITS:
        f = root / f"{split}.txt"
        if f.is_file():
            for line in f.read_text().splitlines():
                name = line.strip()
                if name and name not in subset:
                    subset[name] = split
    return subset


def list_llevos_sequences(root: Path) -> list[str]:
    """Names of sequences that have both annotations and events."""
    ann = {p.name for p in (root / ANNOTATIONS).iterdir() if p.is_dir()}
    ev = {p.name for p in (root / EVENTS).iterdir() if p.is_dir()}
    both = sorted(ann & ev)
    if not both:
        raise DatasetLayoutError(
            root,
            f"no sequence folder in both {ANNOTATIONS}/ ({len(ann)}) and {EVENTS}/ ({len(ev)})",
            EXPECTED_LAYOUT,
        )
    return both


def _columns_from_matrix(arr: np.ndarray, order: str, path: Path) -> dict[str, np.ndarray]:
    if arr.ndim != 2 or arr.shape[1] != 4:
        raise DatasetLayoutError(
            path, f"event array of shape {arr.shape}", f"(N, 4) columns {order}"
        )
    return {c: arr[:, i] for i, c in enumerate(order)}


def read_event_file(path: Path, config: LLEVOSConfig) -> dict[str, np.ndarray]:
    """Columns ``x, y, t, p`` (raw units) of one LLE-VOS event file."""
    try:
        if path.suffix.lower() == ".npz":
            with np.load(path, allow_pickle=False) as d:
                keys = set(d.files)
                if {"x", "y", "t", "p"} <= keys:
                    return {c: np.asarray(d[c]).reshape(-1) for c in "xytp"}
                if "events" in keys:
                    return _columns_from_matrix(np.asarray(d["events"]), config.npy_columns, path)
                raise DatasetLayoutError(
                    path, f"keys {sorted(keys)}", "an .npz with arrays x, y, t, p (or events N x 4)"
                )
        arr = np.load(path, allow_pickle=False)
    except (OSError, ValueError, EOFError, zipfile.BadZipFile) as err:
        if isinstance(err, DatasetLayoutError):
            raise
        raise DatasetLayoutError(path, f"unreadable event file ({err})", EXPECTED_LAYOUT) from None
    if arr.dtype.names is not None:
        missing = [c for c in "xytp" if c not in arr.dtype.names]
        if missing:
            raise DatasetLayoutError(path, f"structured array without fields {missing}")
        return {c: arr[c] for c in "xytp"}
    return _columns_from_matrix(arr, config.npy_columns, path)


def _event_files(folder: Path) -> dict[str, Path]:
    files: dict[str, Path] = {}
    for p in sorted(folder.iterdir()):
        if p.is_file() and p.suffix.lower() in EVENT_SUFFIXES:
            if p.stem in files:
                raise DatasetLayoutError(p, f"two event files for frame {p.stem!r}")
            files[p.stem] = p
    return files


def load_llevos_sequence(
    root: Path, name: str, subset: str = "all", config: LLEVOSConfig | None = None
) -> SequenceData:
    """One LLE-VOS sequence: events of all frames, one window per annotated frame."""
    config = config or LLEVOSConfig()
    scale = TIME_UNITS_TO_US[config.time_unit]
    ann_dir, ev_dir = root / ANNOTATIONS / name, root / EVENTS / name
    ann_files = {p.stem: p for p in sorted(ann_dir.glob("*.png"))}
    if not ann_files:
        raise DatasetLayoutError(ann_dir, "no annotation PNGs", EXPECTED_LAYOUT)
    ev_files = _event_files(ev_dir)
    if not ev_files:
        raise DatasetLayoutError(ev_dir, "no event files (.npz/.npy)", EXPECTED_LAYOUT)
    notes: list[str] = []
    labels = {k: read_mask_png(p) for k, p in ann_files.items()}
    shapes = {lab.shape for lab in labels.values()}
    if len(shapes) != 1:
        raise DatasetLayoutError(ann_dir, f"annotations of several sizes {sorted(shapes)}")
    h, w = next(iter(shapes))
    sensor = tuple(config.sensor_size) if config.sensor_size else (int(w), int(h), 2)
    fit = mask_fit((h, w), sensor)
    if fit.changed:
        notes.append(f"{fit.describe()} (the benchmark protocol does this, window by window)")

    chunks: list[np.ndarray] = []
    spans: dict[str, tuple[int, int]] = {}  # first, last event time of each file (µs)
    prev: tuple[str, int] | None = None
    for stem, path in ev_files.items():
        cols = read_event_file(path, config)
        t_us = scaled_times(cols["t"], scale, path)
        x, y = np.asarray(cols["x"]), np.asarray(cols["y"])
        if len(t_us) and (
            x.min() < 0 or y.min() < 0 or x.max() >= sensor[0] or y.max() >= sensor[1]
        ):
            raise DatasetLayoutError(
                path,
                f"events reach x {x.min()}..{x.max()}, y {y.min()}..{y.max()}, outside the "
                f"{sensor[0]}x{sensor[1]} annotation grid",
                "events on the annotation grid (or pass sensor_size)",
            )
        ev = events_from_columns(t_us, x, y, cols["p"], sensor, notes, path)
        if len(ev) == 0:
            continue
        first, last = int(ev["t"][0]), int(ev["t"][-1])
        if prev is not None and first < prev[1]:
            raise DatasetLayoutError(
                path,
                f"starts at t={first} µs before {ev_files[prev[0]].name} ends at t={prev[1]} µs",
                "per-frame event files that follow each other in time",
            )
        spans[stem] = (first, last)
        prev = (stem, last)
        chunks.append(ev)
    events = np.concatenate(chunks) if chunks else empty_events()

    ordered = [s for s in ev_files if s in spans]
    windows: list[MaskWindow] = []
    no_events = sorted(s for s in ann_files if s in ev_files and s not in spans)
    no_file = sorted(s for s in ann_files if s not in ev_files)
    for i, stem in enumerate(ordered):
        if stem not in labels:
            continue
        start = spans[stem][0]
        end = spans[ordered[i + 1]][0] if i + 1 < len(ordered) else spans[stem][1] + 1
        if end <= start:
            raise DatasetLayoutError(
                ev_files[stem],
                f"all its events are at t={start} µs, where {ev_files[ordered[i + 1]].name} "
                "starts: the two frames cannot be separated in time",
            )
        if i + 1 < len(ordered) and spans[stem][1] == end:
            notes.append(f"frame {stem}: last events share t={end} µs with the next file")
        windows.append(MaskWindow(start, end, labels[stem], source=str(ann_files[stem])))
    windows.sort(key=lambda wdw: wdw.t_start_us)
    if no_events:
        notes.append(
            f"{len(no_events)} annotated frame(s) with an empty event file, not scored: "
            f"{no_events[:5]}"
        )
    if no_file:
        notes.append(
            f"{len(no_file)} annotated frame(s) without an event file not scored: {no_file[:5]}"
        )
    unannotated = len(ev_files) - len([s for s in ev_files if s in labels])
    if unannotated:
        notes.append(f"{unannotated} event file(s) without annotation (fed, not scored)")
    return SequenceData("llevos", subset, name, sensor, events, windows, str(ev_dir), notes)


def load_llevos(
    path: str | os.PathLike,
    sequences: Iterable[str] | None = None,
    config: LLEVOSConfig | None = None,
) -> Iterator[SequenceData]:
    """Yield LLE-VOS sequences under ``path`` (layout checked before the first one)."""
    root = find_llevos_root(path)
    names = list_llevos_sequences(root)
    if sequences is not None:
        wanted = list(sequences)
        absent = [s for s in wanted if s not in names]
        if absent:
            raise DatasetLayoutError(root, f"sequence(s) {absent} not found; have {names[:10]}")
        names = [n for n in names if n in wanted]
    splits = read_splits(root)
    for name in names:
        yield load_llevos_sequence(root, name, splits.get(name, "all"), config)
