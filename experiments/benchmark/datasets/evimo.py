"""EVIMO / EVIMO2 motion-segmentation recordings as benchmark sequences.

Formats (from the EVIMO documentation, ``better-flow/evimo`` ``docs/docs/_sources/
ground-truth-format.md.txt``; the converter ``better-flow/pydvs`` ``samples/evimo-gen.py``;
readers ``better-flow/evimo`` ``tools/evimo_flow.py`` and
``tools/evimo2_v2_inspect/view_sequence_all_cameras.py``):

**EVIMO (v1) / EVIMO2v1 NPZ** — one ``<sequence>.npz`` per sequence, holding

- ``events`` — float ``(N, 4)``: ``t`` (seconds), ``x``, ``y``, ``p`` (0/1);
- ``mask`` — uint16 ``(F, H, W)``: object id × 1000 per pixel, 0 = background;
- ``meta`` — a pickled Python dict: ``meta["frames"][i]["ts"]`` is the time (s) of
  ``mask[i]`` (plus poses, ``"id"``, ``"gt_frame"``), ``meta["meta"]`` the intrinsics and
  ``res_x``/``res_y``;
- also ``depth`` (mm), ``classical``, ``index``, ``discretization``, ``K``, ``D`` (unused).

**EVIMO2v2 NPZ** — one folder per sequence (``<camera>/<category>/<split>/<seq>/``) with
``dataset_events_t.npy`` (float s, ``(N,)``), ``dataset_events_xy.npy`` (uint16
``(N, 2)``), ``dataset_events_p.npy`` (uint8 ``(N,)``), ``dataset_mask.npz`` (keys
``mask_<10-digit frame id − first id>``, id × 1000) and ``dataset_info.npz`` (``meta``,
``K``, ``D``, ``index``, ``discretization``). Frames whose mask key is missing (Vicon
lost track) are skipped. The Samsung camera's polarity is inverted relative to the
Prophesee ones; it is kept as stored and noted.

**Layout** expected by ``wander benchmark evimo PATH`` (:func:`find_evimo_sequences`):
``PATH/<subset>/[any folders/]<sequence>.npz`` for EVIMO1, where ``<subset>`` is one of
the paper's scenes ``box, fast, floor, table, tabletop, wall`` (folder names such as
``eval_box_npz`` or ``boxes`` are recognised too); and/or EVIMO2v2 sequence folders
anywhere under ``PATH`` (subset = the folder path above the sequence, e.g.
``samsung_mono/imo/eval``). ``PATH`` may also be one ``.npz`` or one EVIMO2v2 folder.
The TXT release is not read (convert it with pydvs ``evimo-gen.py``).

**Windows.** EVIMO masks are instantaneous (rendered at ``ts`` from the Vicon poses)
and unevenly spaced (tracking gaps). :func:`windows_from_frame_times` turns the mask
times into non-overlapping half-open event windows of width ``window_us`` (default:
the median spacing of the mask times), clipped at the neighbours:

- ``"preceding"`` (default): ``[ts − w, ts)`` — causal, the model is scored at the
  mask time on the events up to it (the same convention as the ``NNNNNN_T.png``
  folders, whose names give the window end);
- ``"following"``: ``[ts, ts + w)`` — what the paper's public preprocessing did
  (events between consecutive ground-truth frames paired with the first one);
- ``"centered"``: ``[ts − w/2, ts + w/2)`` — pydvs' ``get_slice(mode=1)``.

Times are converted to integer µs (``round(t · 1e6)``). NB the EVIMO1 events are
float32 seconds, so timestamps late in a recording are quantised to a few µs.

``meta`` is a pickle inside the ``.npz``; it is unpickled with a restricted unpickler
that only admits NumPy array reconstruction and plain Python containers, so a
malicious file cannot run code.
"""

from __future__ import annotations

import ast
import importlib
import io
import json
import os
import pickle
import re
import zipfile
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from experiments.benchmark.datasets.base import (
    DatasetLayoutError,
    MaskWindow,
    SequenceData,
    events_from_columns,
    seconds_to_us,
)
from wander_env.events.checks import json_depth
from wander_env.events.evimo2 import EVIMO2_MASK_SCALE
from wander_env.untrusted import (
    LIMITS,
    UntrustedFileError,
    json_nesting,
    npy_array,
    npz_members,
    open_regular,
)

EVIMO1_SUBSETS = ("box", "fast", "floor", "table", "tabletop", "wall")
EVIMO1_KEYS = ("events", "mask", "meta")
EVIMO2_FILES = (
    "dataset_info.npz",
    "dataset_events_t.npy",
    "dataset_events_xy.npy",
    "dataset_events_p.npy",
    "dataset_mask.npz",
)
WINDOW_MODES = ("preceding", "following", "centered")
EXPECTED_LAYOUT = (
    "PATH/<subset>/<sequence>.npz (EVIMO1 NPZ with keys events, mask, meta; subset one of "
    + ", ".join(EVIMO1_SUBSETS)
    + ") and/or EVIMO2v2 sequence folders holding "
    + ", ".join(EVIMO2_FILES)
)
_SUBSET_ALIASES = {"boxes": "box"}


# ----------------------------------------------------------------------------------------
# Windows from mask times


def windows_from_frame_times(
    ts_us: Sequence[int] | np.ndarray, mode: str = "preceding", width_us: int | None = None
) -> list[tuple[int, int]]:
    """Non-overlapping half-open windows ``(start, end)`` in µs around mask times.

    See the module docstring for the modes. ``width_us`` defaults to the median
    spacing of ``ts_us``; each window is clipped so that it never reaches past the
    neighbouring mask time (``preceding``/``following``) or the midpoint between
    neighbours (``centered``), so gaps in the ground truth stay gaps.

    >>> windows_from_frame_times([100, 200, 300])
    [(0, 100), (100, 200), (200, 300)]
    >>> windows_from_frame_times([100, 200, 500], mode="following", width_us=150)
    [(100, 200), (200, 350), (500, 650)]
    """
    if mode not in WINDOW_MODES:
        raise ValueError(f"window mode {mode!r} is not one of {WINDOW_MODES}")
    t = np.asarray(ts_us, dtype=np.int64)
    if t.ndim != 1 or t.size == 0:
        return []
    steps = np.diff(t)
    if np.any(steps <= 0):
        i = int(np.flatnonzero(steps <= 0)[0])
        raise ValueError(
            f"mask times must increase strictly: ts[{i}]={t[i]} µs, ts[{i + 1}]={t[i + 1]} µs"
        )
    if width_us is None:
        if steps.size == 0:
            raise ValueError("one mask time: give width_us")
        width_us = round(float(np.median(steps)))
    width_us = int(width_us)
    if width_us <= 0:
        raise ValueError(f"width_us must be > 0, got {width_us}")
    out: list[tuple[int, int]] = []
    n = t.size
    for i in range(n):
        if mode == "preceding":
            start = int(t[i]) - width_us
            if i > 0:
                start = max(start, int(t[i - 1]))
            end = int(t[i])
        elif mode == "following":
            start = int(t[i])
            end = start + width_us
            if i < n - 1:
                end = min(end, int(t[i + 1]))
        else:
            start = int(t[i]) - width_us // 2
            end = start + width_us
            if i > 0:
                start = max(start, (int(t[i - 1]) + int(t[i]) + 1) // 2)
            if i < n - 1:
                end = min(end, (int(t[i]) + int(t[i + 1]) + 1) // 2)
        out.append((start, end))
    return out


# ----------------------------------------------------------------------------------------
# Reading ``meta`` safely


class _RestrictedUnpickler(pickle.Unpickler):
    """Unpickles NumPy arrays of plain Python objects and nothing else."""

    _ALLOWED = frozenset(
        {
            ("numpy.core.multiarray", "_reconstruct"),
            ("numpy._core.multiarray", "_reconstruct"),
            ("numpy.core.multiarray", "scalar"),
            ("numpy._core.multiarray", "scalar"),
            ("numpy", "ndarray"),
            ("numpy", "dtype"),
            ("_codecs", "encode"),
        }
    )

    def find_class(self, module: str, name: str) -> Any:
        if (module, name) not in self._ALLOWED:
            raise pickle.UnpicklingError(f"refusing to unpickle {module}.{name}")
        if module.startswith("numpy.core") and hasattr(np, "_core"):
            module = "numpy._core" + module[len("numpy.core") :]
        return getattr(importlib.import_module(module), name)


def _parse_meta_text(text: str, where: Path) -> dict[str, Any]:
    depth = json_nesting(text, quotes="\"'")
    if depth > LIMITS.json_depth:
        raise DatasetLayoutError(where, f"'meta' nested {depth} deep; at most {LIMITS.json_depth}")
    try:
        value = json.loads(text)
    except ValueError:
        try:
            value = ast.literal_eval(text)
        except (ValueError, SyntaxError) as err:
            raise DatasetLayoutError(
                where, f"'meta' is text but neither JSON nor a Python literal ({err})"
            ) from None
    if not isinstance(value, dict):
        raise DatasetLayoutError(where, f"'meta' is a {type(value).__name__}, not a dict")
    return value


def _members(path: Path) -> dict[str, bytes]:
    """The members of the ``.npz`` ``path``, read through :mod:`wander_env.untrusted`."""
    try:
        return npz_members(path)
    except UntrustedFileError as err:
        where = f"{err.field}: " if err.field else ""
        raise DatasetLayoutError(path, where + err.problem) from None


def _arrays(path: Path, members: dict[str, bytes], *keys: str) -> list[np.ndarray]:
    """Arrays ``keys`` of an ``.npz``'s ``members`` (no pickled objects)."""
    try:
        return [npy_array(path, f"{k}.npy", members[f"{k}.npy"]) for k in keys]
    except KeyError as err:
        raise DatasetLayoutError(path, f"no {err} array", EXPECTED_LAYOUT) from None
    except UntrustedFileError as err:
        raise DatasetLayoutError(path, f"{err.field}: {err.problem}", EXPECTED_LAYOUT) from None


def read_npz_meta(path: str | os.PathLike, key: str = "meta") -> dict[str, Any]:
    """The ``meta`` dict of an EVIMO ``.npz`` (pickled dict, JSON or Python-literal text),
    the archive read through :mod:`wander_env.untrusted`, nested at most
    ``LIMITS.json_depth`` deep."""
    path = Path(path)
    return _meta(path, _members(path), key)


def _meta(path: Path, members: dict[str, bytes], key: str = "meta") -> dict[str, Any]:
    member = f"{key}.npy"
    if member not in members:
        raise DatasetLayoutError(path, f"no '{key}' array", "an EVIMO .npz with 'meta'")
    f = io.BytesIO(members[member])
    try:
        version = np.lib.format.read_magic(f)
        if version == (1, 0):
            shape, _, dtype = np.lib.format.read_array_header_1_0(f)
        else:
            shape, _, dtype = np.lib.format.read_array_header_2_0(f)
        if dtype.hasobject:
            arr = _RestrictedUnpickler(f).load()
        else:
            arr = np.frombuffer(f.read(), dtype=dtype).reshape(shape)
    except (OSError, ValueError, pickle.UnpicklingError, EOFError) as err:
        raise DatasetLayoutError(path, f"cannot read '{key}' ({err})") from None
    value = arr.item() if isinstance(arr, np.ndarray) and arr.size == 1 else arr
    if isinstance(value, bytes):
        value = value.decode("utf-8", errors="replace")
    if isinstance(value, str):
        return _parse_meta_text(value, path)
    if not isinstance(value, dict):
        raise DatasetLayoutError(path, f"'{key}' holds a {type(value).__name__}, not a dict")
    depth = json_depth(value)
    if depth > LIMITS.json_depth:
        raise DatasetLayoutError(path, f"'{key}' nested {depth} deep; at most {LIMITS.json_depth}")
    return value


def _frames(meta: dict[str, Any], where: Path) -> list[dict[str, Any]]:
    frames = meta.get("frames")
    if not isinstance(frames, list) or not all(isinstance(f, dict) and "ts" in f for f in frames):
        raise DatasetLayoutError(
            where, "meta has no 'frames' list of dicts with 'ts'", "meta['frames'][i]['ts']"
        )
    return frames


def mask_labels(raw: np.ndarray) -> np.ndarray:
    """Object ids from an EVIMO mask (id × :data:`~wander_env.events.evimo2.EVIMO2_MASK_SCALE`,
    1000): ``round(raw / 1000)``, ≥ 1 where raw > 0.

    >>> mask_labels(np.array([[0, 1000, 3000, 7]])).tolist()
    [[0, 1, 3, 1]]
    """
    raw = np.asarray(raw)
    ids = np.rint(raw.astype(np.float64) / EVIMO2_MASK_SCALE).astype(np.int64)
    ids = np.where(raw > 0, np.maximum(ids, 1), 0)
    return ids.astype(np.min_scalar_type(int(ids.max(initial=0))))


# ----------------------------------------------------------------------------------------
# Discovery


@dataclass(frozen=True)
class EvimoSource:
    """One EVIMO sequence found on disk (not loaded yet)."""

    path: Path
    format: str  # "evimo1_npz" or "evimo2v2_npz"
    subset: str
    name: str


def _subset_from_parts(parts: Sequence[str]) -> str | None:
    for part in parts:
        token = re.sub(r"^(eval|train|test)_|_(npz|txt)$", "", part.lower())
        token = _SUBSET_ALIASES.get(token, token)
        if token in EVIMO1_SUBSETS:
            return token
    return None


def _check_evimo1_keys(path: Path) -> None:
    try:
        with open_regular(path) as fh, zipfile.ZipFile(fh) as z:  # its directory only
            keys = {n[:-4] for n in z.namelist() if n.endswith(".npy")}
    except UntrustedFileError as err:
        raise DatasetLayoutError(path, err.problem, EXPECTED_LAYOUT) from None
    except (OSError, zipfile.BadZipFile) as err:
        raise DatasetLayoutError(path, f"not a readable .npz ({err})", EXPECTED_LAYOUT) from None
    missing = [k for k in EVIMO1_KEYS if k not in keys]
    if missing:
        raise DatasetLayoutError(
            path,
            f"an .npz without the EVIMO keys {missing} (has {sorted(keys)})",
            EXPECTED_LAYOUT,
        )


def _is_evimo2_dir(d: Path) -> bool:
    return (d / "dataset_info.npz").is_file()


def _evimo2_source(d: Path, root: Path) -> EvimoSource:
    missing = [f for f in EVIMO2_FILES if not (d / f).is_file()]
    if missing:
        raise DatasetLayoutError(d, f"EVIMO2v2 folder without {missing}", EXPECTED_LAYOUT)
    rel = d.relative_to(root).parent.as_posix() if d != root else ""
    return EvimoSource(d, "evimo2v2_npz", rel if rel not in ("", ".") else "evimo2", d.name)


def find_evimo_sequences(
    root: str | os.PathLike, subsets: Iterable[str] | None = None
) -> list[EvimoSource]:
    """All EVIMO sequences under ``root`` (see the module docstring for the layout).

    Raises :class:`DatasetLayoutError` naming what was expected when nothing matches,
    when an ``.npz`` lacks the EVIMO keys, or when ``subsets`` names a subset absent
    from ``root``.
    """
    root = Path(root)
    if not root.exists():
        raise DatasetLayoutError(root, "no such file or folder", EXPECTED_LAYOUT)
    found: list[EvimoSource] = []
    txt_seen: list[Path] = []
    if root.is_file():
        if root.suffix.lower() != ".npz":
            raise DatasetLayoutError(root, "not an .npz file", EXPECTED_LAYOUT)
        _check_evimo1_keys(root)
        found.append(
            EvimoSource(
                root, "evimo1_npz", _subset_from_parts([root.parent.name]) or "evimo", root.stem
            )
        )
    elif _is_evimo2_dir(root):
        found.append(_evimo2_source(root, root))
    else:
        for dirpath, dirnames, filenames in os.walk(root):
            d = Path(dirpath)
            dirnames.sort()
            if _is_evimo2_dir(d):
                found.append(_evimo2_source(d, root))
                dirnames[:] = []
                continue
            if "meta.txt" in filenames and "events.txt" in filenames:
                txt_seen.append(d)
            for fn in sorted(filenames):
                if not fn.lower().endswith(".npz"):
                    continue
                p = d / fn
                _check_evimo1_keys(p)
                rel_parts = p.relative_to(root).parts[:-1]
                subset = _subset_from_parts(rel_parts) or (
                    "/".join(rel_parts) if rel_parts else "evimo"
                )
                found.append(EvimoSource(p, "evimo1_npz", subset, p.stem))
    if not found:
        listing = sorted(p.name for p in root.iterdir())[:8] if root.is_dir() else []
        problem = f"no EVIMO sequences found (top level: {listing or 'empty'})"
        if txt_seen:
            problem += (
                f"; {len(txt_seen)} folder(s) in the EVIMO TXT format (e.g. {txt_seen[0]}), "
                "which is not read: convert with pydvs samples/evimo-gen.py"
            )
        raise DatasetLayoutError(root, problem, EXPECTED_LAYOUT)
    if subsets is not None:
        wanted = [_SUBSET_ALIASES.get(s.lower(), s.lower()) for s in subsets]
        have = sorted({s.subset for s in found})
        absent = [s for s in wanted if s not in have]
        if absent:
            raise DatasetLayoutError(
                root, f"subset(s) {absent} not found; found subsets {have}", EXPECTED_LAYOUT
            )
        found = [s for s in found if s.subset in wanted]
    return found


# ----------------------------------------------------------------------------------------
# Loading


def _windows(
    ts_s: Sequence[float],
    labels: Sequence[np.ndarray],
    sources: Sequence[str],
    mode: str,
    window_us: int | None,
) -> list[MaskWindow]:
    ts_us = seconds_to_us(np.asarray(ts_s, dtype=np.float64))
    try:
        spans = windows_from_frame_times(ts_us, mode, window_us)
    except ValueError as err:
        raise DatasetLayoutError(sources[0] if sources else "", str(err)) from None
    return [
        MaskWindow(start, end, lab, source=src)
        for (start, end), lab, src in zip(spans, labels, sources, strict=True)
    ]


def _load_evimo1(src: EvimoSource, mode: str, window_us: int | None) -> SequenceData:
    path = src.path
    members = _members(path)
    meta = _meta(path, members)
    frames = _frames(meta, path)
    raw_events, masks = _arrays(path, members, "events", "mask")
    del members
    if raw_events.ndim != 2 or raw_events.shape[1] < 4:
        raise DatasetLayoutError(
            path, f"'events' has shape {raw_events.shape}", "'events' (N, 4): t [s], x, y, p"
        )
    if masks.ndim != 3:
        raise DatasetLayoutError(path, f"'mask' has shape {masks.shape}", "'mask' (F, H, W)")
    if len(frames) != masks.shape[0]:
        raise DatasetLayoutError(
            path,
            f"meta['frames'] has {len(frames)} entries but 'mask' {masks.shape[0]} frames",
            "one meta['frames'] entry per mask frame",
        )
    h, w = int(masks.shape[1]), int(masks.shape[2])
    sensor = (w, h, 2)
    notes: list[str] = []
    events = events_from_columns(
        seconds_to_us(raw_events[:, 0], path),
        raw_events[:, 1],
        raw_events[:, 2],
        raw_events[:, 3],
        sensor,
        notes,
        path,
    )
    labels = [mask_labels(masks[i]) for i in range(masks.shape[0])]
    sources = [f"{path}:mask[{i}]" for i in range(masks.shape[0])]
    windows = _windows([float(f["ts"]) for f in frames], labels, sources, mode, window_us)
    notes.append(f"windows: {mode}")
    return SequenceData("evimo", src.subset, src.name, sensor, events, windows, str(path), notes)


def _load_evimo2(src: EvimoSource, mode: str, window_us: int | None) -> SequenceData:
    d = src.path
    meta = read_npz_meta(d / "dataset_info.npz")
    frames = _frames(meta, d / "dataset_info.npz")
    try:
        for name in ("t", "xy", "p"):  # regular files (mapped, not read, below)
            open_regular(d / f"dataset_events_{name}.npy").close()
        t = np.load(d / "dataset_events_t.npy", mmap_mode="r")
        xy = np.load(d / "dataset_events_xy.npy", mmap_mode="r")
        p = np.load(d / "dataset_events_p.npy", mmap_mode="r")
    except (OSError, ValueError) as err:
        raise DatasetLayoutError(
            d, f"cannot read the event arrays ({err})", EXPECTED_LAYOUT
        ) from None
    t = np.asarray(t).reshape(-1)
    p = np.asarray(p).reshape(-1)
    xy = np.asarray(xy)
    if xy.ndim != 2 or xy.shape[1] != 2:
        raise DatasetLayoutError(
            d / "dataset_events_xy.npy", f"shape {xy.shape}", "dataset_events_xy.npy (N, 2)"
        )
    notes: list[str] = []
    ts_s: list[float] = []
    labels: list[np.ndarray] = []
    sources: list[str] = []
    first_id = int(frames[0].get("id", 0)) if frames else 0
    missing = 0
    mask_path = d / "dataset_mask.npz"
    mz = _members(mask_path)
    keys = {name.removesuffix(".npy") for name in mz}
    for i, f in enumerate(frames):
        key = f"mask_{int(f.get('id', i)) - first_id:010d}"
        if key not in keys:
            missing += 1
            continue
        ts_s.append(float(f["ts"]))
        (mask,) = _arrays(mask_path, mz, key)
        labels.append(mask_labels(mask))
        sources.append(f"{mask_path}:{key}")
    if not labels:
        raise DatasetLayoutError(
            d / "dataset_mask.npz",
            f"no mask matches meta['frames'] (keys like {sorted(keys)[:2]})",
            "keys mask_<10-digit frame id − first id>",
        )
    if missing:
        notes.append(f"{missing} of {len(frames)} frames have no mask (skipped)")
    shapes = {lab.shape for lab in labels}
    if len(shapes) != 1:
        raise DatasetLayoutError(d / "dataset_mask.npz", f"masks of several sizes {sorted(shapes)}")
    h, w = labels[0].shape
    res = meta.get("meta", {}) if isinstance(meta.get("meta"), dict) else {}
    if "res_x" in res and (int(res["res_x"]), int(res["res_y"])) != (w, h):
        notes.append(f"meta res {res['res_x']}x{res['res_y']} differs from mask {w}x{h}")
    sensor = (int(w), int(h), 2)
    if "samsung" in d.as_posix().lower():
        notes.append("Samsung camera: polarity kept as stored (inverted vs Prophesee)")
    t_us = seconds_to_us(t, d / "dataset_events_t.npy")
    events = events_from_columns(t_us, xy[:, 0], xy[:, 1], p, sensor, notes, d)
    windows = _windows(ts_s, labels, sources, mode, window_us)
    notes.append(f"windows: {mode}")
    return SequenceData("evimo", src.subset, src.name, sensor, events, windows, str(d), notes)


def load_evimo_sequence(
    src: EvimoSource, window_mode: str = "preceding", window_us: int | None = None
) -> SequenceData:
    """Load one sequence found by :func:`find_evimo_sequences`."""
    if window_mode not in WINDOW_MODES:
        raise ValueError(f"window mode {window_mode!r} is not one of {WINDOW_MODES}")
    if src.format == "evimo1_npz":
        return _load_evimo1(src, window_mode, window_us)
    if src.format == "evimo2v2_npz":
        return _load_evimo2(src, window_mode, window_us)
    raise ValueError(f"unknown EVIMO format {src.format!r}")


def load_evimo(
    root: str | os.PathLike,
    subsets: Iterable[str] | None = None,
    window_mode: str = "preceding",
    window_us: int | None = None,
) -> Iterator[SequenceData]:
    """Yield every EVIMO sequence under ``root``, one at a time (layout checked first)."""
    for src in find_evimo_sequences(root, subsets):
        yield load_evimo_sequence(src, window_mode, window_us)
