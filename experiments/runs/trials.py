"""A results folder's finished trials, one file each, stored as each trial finishes.

``trials/<trial_id>.json`` holds ``{"spec": ..., "row": ..., "seconds": ...}`` in strict
JSON (NaN and ±inf as ``null``, read back as NaN); with ``keep_artifacts`` (an experiment:
its plots read them) the row's arrays (``_*`` keys) go to ``artifacts/<trial_id>.npz``
first. Each file is written beside its place and renamed into it, so it is whole or
absent. ``wander sweep`` and ``wander experiment`` resume from the store: a trial whose
file holds its row is not run again. A trial file that is empty, truncated, garbled,
nested too deep, over :data:`MAX_TRIAL_FILE_BYTES` or holds a row that is not its
trial's is named in a warning, set aside (``*.json.corrupt``) and its trial is run again.

Examples:
    >>> import tempfile
    >>> from experiments.studies.framework import TrialSpec
    >>> tmp = tempfile.TemporaryDirectory()
    >>> store, spec = TrialStore(Path(tmp.name)), TrialSpec("x", {}, {"a": 1}, 0)
    >>> store.has(spec)
    False
    >>> store.put(spec, {"trial": 0, "trial_id": spec.id, "value": 0.5}, 1.25)
    >>> store.has(spec), store.row(spec)["value"], store.seconds(spec)
    (True, 0.5, 1.25)
    >>> tmp.cleanup()
"""

from __future__ import annotations

import math
import os
import warnings
from collections.abc import Callable, Iterable, Mapping
from dataclasses import asdict
from pathlib import Path
from typing import Any, Protocol

from wander_env.strict_json import write_strict
from wander_env.untrusted import FileLimits, read_json

__all__ = ["MAX_TRIAL_FILE_BYTES", "TrialStore", "save_artifacts", "split_artifacts"]

#: The largest trial file read back (bytes); a larger one is damaged.
MAX_TRIAL_FILE_BYTES = 1 << 24

Row = dict[str, Any]


class TrialSpec(Protocol):
    """What the store needs of a trial (:class:`experiments.studies.framework.TrialSpec`, a
    dataclass)."""

    index: int
    repeat: int
    seed: int
    extra: Mapping[str, Any]

    @property
    def id(self) -> str: ...


def split_artifacts(row: Mapping[str, Any]) -> tuple[Row, dict[str, Any]]:
    """(the row without ``_*`` keys, the artifacts with the ``_`` stripped from their names)."""
    plain = {k: v for k, v in row.items() if not k.startswith("_")}
    arts = {k[1:]: v for k, v in row.items() if k.startswith("_")}
    return plain, arts


def save_artifacts(folder: Path, tid: str, artifacts: Mapping[str, Any]) -> Path | None:
    """``folder/artifacts/<tid>.npz`` (nothing when there are none)."""
    if not artifacts:
        return None
    import numpy as np

    path = folder / "artifacts" / f"{tid}.npz"
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(path, **{k: np.asarray(v) for k, v in artifacts.items()})
    return path


class TrialStore:
    """The finished trials in ``folder`` (see the module docstring)."""

    def __init__(self, folder: Path, keep_artifacts: bool = False) -> None:
        self.folder = Path(folder)
        self.keep_artifacts = keep_artifacts

    def path(self, spec: TrialSpec) -> Path:
        """``trials/<trial_id>.json``."""
        return self.folder / "trials" / f"{spec.id}.json"

    def put(self, spec: TrialSpec, row: Row, seconds: float) -> None:
        """Store a finished trial's row (its artifacts first, with ``keep_artifacts``)."""
        plain, artifacts = split_artifacts(row)
        if self.keep_artifacts and artifacts:
            tmp = save_artifacts(self.folder, f"{spec.id}.tmp", artifacts)
            os.replace(tmp, tmp.with_name(f"{spec.id}.npz"))
        path = self.path(spec)
        path.parent.mkdir(parents=True, exist_ok=True)
        rec = {"spec": asdict(spec), "row": plain, "seconds": round(seconds, 3)}
        write_strict(path, rec)

    def put_all(
        self,
        stream: Iterable[tuple[TrialSpec, Row, float]],
        done: int,
        total: int,
        progress: Callable[[int, int], None] | None = None,
    ) -> None:
        """Store each trial of ``stream`` as it finishes (``progress(done, total)`` after
        each, and once before the first: ``done`` were stored already); the stream is
        closed however the loop ends (an executor's workers end at once)."""
        if progress is not None:
            progress(done, total)
        try:
            for spec, row, secs in stream:
                self.put(spec, row, secs)
                done += 1
                if progress is not None:
                    progress(done, total)
        finally:
            close = getattr(stream, "close", None)
            if close is not None:
                close()

    def has(self, spec: TrialSpec) -> bool:
        """True if ``spec``'s trial file holds its row; a damaged one is set aside (warned)."""
        path = self.path(spec)
        if not path.exists():
            return False
        try:
            self._read(path, spec)
            return True
        except (OSError, ValueError, RecursionError) as err:  # RecursionError: nested too deep
            aside = path.with_name(path.name + ".corrupt")
            k = 1
            while aside.exists():
                k += 1
                aside = path.with_name(f"{path.name}.corrupt{k}")
            os.replace(path, aside)
            why = " ".join(getattr(err, "problem", str(err)).split()) or type(err).__name__
            warnings.warn(
                f"{path}: damaged trial file ({why}); set aside as {aside.name}, the trial is "
                "rerun",
                RuntimeWarning,
                stacklevel=2,
            )
            return False

    def row(self, spec: TrialSpec) -> Row:
        """The stored row (``null`` read as NaN), with the id columns and the sweep's columns
        of ``spec`` (indices shift when a sweep file is edited), those first."""
        row = self._read(self.path(spec), spec)["row"]
        row = {k: math.nan if v is None else v for k, v in row.items()}
        row.update({"trial": spec.index, "repeat": spec.repeat, "seed": spec.seed})
        row.update(spec.extra)
        head = ["trial", "trial_id", "repeat", "seed", *spec.extra]
        return {**{k: row[k] for k in head}, **{k: v for k, v in row.items() if k not in head}}

    def seconds(self, spec: TrialSpec) -> float:
        """The wall-clock seconds the stored trial took (NaN when not recorded)."""
        value = self._read(self.path(spec), spec).get("seconds")
        return float(value) if isinstance(value, (int, float)) else math.nan

    @staticmethod
    def _read(path: Path, spec: TrialSpec) -> dict[str, Any]:
        # A regular file of at most MAX_TRIAL_FILE_BYTES (a row is a few kB), nested within
        # the JSON depth cap: a FIFO, a /dev/zero link or a bomb is refused, never read.
        rec = read_json(path, FileLimits(json_bytes=MAX_TRIAL_FILE_BYTES))
        if not isinstance(rec, dict) or not isinstance(rec.get("row"), dict):
            raise ValueError("no 'row' object")
        if rec["row"].get("trial_id") != spec.id:
            raise ValueError(f"its row has no 'trial_id' {spec.id!r}")
        return rec
