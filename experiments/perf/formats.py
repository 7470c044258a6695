"""``wander perf formats``: decode real event files with every library that can, side by side.

For each file and each installed decoder: events decoded, the median time of a few
full decodes and the rate, and the decoder's agreement with a reference — the
``<stem>.npy`` or ``events_txyp.npy`` beside the file when there is one (as in
``../shared/realdata``), else wander's own reader. Agreement is counted event by event:
how many events differ in ``x``/``y``/``p``, how many in ``t`` and by how much at most.
Decoders that are not installed are skipped (listed in the table's caption).

Rows are returned as :class:`FormatRow`; ``experiments/cli/main.py`` prints them.
"""

from __future__ import annotations

import importlib.util
import statistics
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from wander_env.events import empty_events
from wander_env.events.io import read_events

Decoder = Callable[[Path], np.ndarray]


# The columns of `wander perf formats`'s table (row field -> format spec).
COLUMNS: dict[str, str] = {
    "file": "",
    "decoder": "",
    "events": ",d",
    "ms": ".1f",
    "mev_per_s": ".1f",
    "reference": "",
    "xyp_differ": ",d",
    "t_differ": ",d",
    "max_abs_dt_us": ",d",
}


def _txyp(t: np.ndarray, x: np.ndarray, y: np.ndarray, p: np.ndarray) -> np.ndarray:
    """A decoder's columns as wander's events (:data:`~wander_env.events.EVENT_DTYPE`),
    polarity 1 where ``p > 0``; unlike :func:`~wander_env.events.make_events` it takes
    the events in any time order, so that an unsorted decode counts as differing events."""
    out = empty_events(len(t))
    out["t"], out["x"], out["y"], out["p"] = t, x, y, np.asarray(p) > 0
    return out


def _wander(path: Path) -> np.ndarray:
    if path.suffix.lower() == ".es":  # rows as stored, like the other decoders here
        from wander_env.events.formats import read_es

        ev = read_es(path, flip_y=False).events
    else:
        ev = read_events(path).events
    return _txyp(ev["t"], ev["x"], ev["y"], ev["p"])


def _faery(path: Path) -> np.ndarray:
    import faery

    if path.suffix.lower() == ".es":  # the low-level decoder keeps the stored rows
        with faery.es.Decoder(path=path, t0=0) as dec:
            a = np.concatenate(list(dec))
    else:
        a = faery.events_stream_from_file(path).to_array()
    return _txyp(a["t"], a["x"], a["y"], a["on"])


def _aedat(path: Path) -> np.ndarray:
    import aedat

    a = np.concatenate([p["events"] for p in aedat.Decoder(str(path)) if "events" in p])
    return _txyp(a["t"], a["x"], a["y"], a["on"])


def _evt3(path: Path) -> np.ndarray:
    import evt3

    d = evt3.decode_file(str(path))
    return _txyp(d.t, d.x, d.y, d.p)


def _raw_version(path: Path) -> str | None:
    from wander_env.events.formats import _evt_version, prophesee_header

    with open(path, "rb") as fh:
        return _evt_version(prophesee_header(fh.read(4096))[0])


def _expelliarmus(path: Path) -> np.ndarray:
    import expelliarmus

    encoding = "dat" if path.suffix.lower() == ".dat" else _raw_version(path) or "evt3"
    a = expelliarmus.Wizard(encoding=encoding.replace(".", "")).read(str(path))
    return _txyp(a["t"], a["x"], a["y"], a["p"])


def _dv_processing(path: Path) -> np.ndarray:
    import dv_processing as dv

    rec = dv.io.MonoCameraRecording(str(path))
    chunks = []
    while rec.isRunning():
        batch = rec.getNextEventBatch()
        if batch is None:
            break
        chunks.append(batch.numpy())
    a = np.concatenate(chunks)
    return _txyp(a["timestamp"], a["x"], a["y"], a["polarity"])


# suffix -> [(decoder name, importable module, function)]
DECODERS: dict[str, list[tuple[str, str, Decoder]]] = {
    ".aedat4": [
        ("wander", "aedat", _wander),
        ("aedat", "aedat", _aedat),
        ("faery", "faery", _faery),
        ("dv-processing", "dv_processing", _dv_processing),
    ],
    ".raw": [
        ("wander", "faery", _wander),
        ("evt3", "evt3", _evt3),
        ("faery", "faery", _faery),
        ("expelliarmus", "expelliarmus", _expelliarmus),
    ],
    ".dat": [
        ("wander", "faery", _wander),
        ("faery", "faery", _faery),
        ("expelliarmus", "expelliarmus", _expelliarmus),
    ],
    ".es": [("wander", "faery", _wander), ("faery", "faery", _faery)],
}


@dataclass(frozen=True)
class FormatRow:
    file: str
    decoder: str
    events: int
    ms: float
    mev_per_s: float
    reference: str
    xyp_differ: int
    t_differ: int
    max_abs_dt_us: int


def compare(got: np.ndarray, ref: np.ndarray) -> tuple[int, int, int]:
    """``(events differing in x/y/p, events differing in t, max |Δt| µs)``; a length
    mismatch counts every event of the longer one as differing.

    >>> a = _txyp([1, 2, 3], [0, 0, 0], [0, 0, 0], [1, 0, 1])
    >>> b = _txyp([1, 2, 5], [0, 1, 0], [0, 0, 0], [1, 0, 1])
    >>> compare(a, b)
    (1, 1, 2)
    """
    if len(got) != len(ref):
        n = max(len(got), len(ref))
        return n, n, -1
    xyp = (got["x"] != ref["x"]) | (got["y"] != ref["y"]) | (got["p"] != ref["p"])
    dt = np.abs(got["t"] - ref["t"])
    return int(xyp.sum()), int(np.count_nonzero(dt)), int(dt.max(initial=0))


def reference_for(path: Path) -> Path | None:
    """The reference ``.npy`` beside ``path``: ``<stem>.npy`` or ``events_txyp.npy``."""
    for cand in (path.with_suffix(".npy"), path.parent / "events_txyp.npy"):
        if cand.is_file():
            return cand
    return None


def bench_formats(files: Sequence[Path], repeats: int = 3) -> tuple[list[FormatRow], list[str]]:
    """Rows for every (file, installed decoder); also the decoders that were skipped."""
    rows: list[FormatRow] = []
    skipped: set[str] = set()
    for path in files:
        decoders = DECODERS.get(path.suffix.lower())
        if decoders is None:
            raise ValueError(f"{path}: no decoders for suffix {path.suffix!r}; {sorted(DECODERS)}")
        ref_path = reference_for(path)
        ref = None
        if ref_path is not None:
            r = np.load(ref_path, allow_pickle=False)
            ref = _txyp(r["t"], r["x"], r["y"], r["p"])
        for name, module, fn in decoders:
            if name == "evt3" and _raw_version(path) != "evt3":
                continue  # the evt3 package decodes EVT 3.0 only
            if importlib.util.find_spec(module) is None:
                skipped.add(name)
                continue
            times, got = [], None
            for _ in range(repeats):
                t0 = time.perf_counter()
                got = fn(path)
                times.append(time.perf_counter() - t0)
            assert got is not None
            if ref is None:
                ref = _wander(path)
            xyp, tdiff, dtmax = compare(got, ref)
            ms = statistics.median(times) * 1e3
            rows.append(
                FormatRow(
                    path.name,
                    name,
                    len(got),
                    ms,
                    len(got) / ms / 1e3,
                    ref_path.name if ref_path else "wander",
                    xyp,
                    tdiff,
                    dtmax,
                )
            )
    return rows, sorted(skipped)


def default_files(realdata: Path) -> list[Path]:
    """The real recordings of ``../shared/realdata`` these decoders read."""
    return sorted(p for p in realdata.rglob("*") if p.suffix.lower() in DECODERS)
