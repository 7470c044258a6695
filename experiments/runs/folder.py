"""The run folder: where a run's files go, and the one writer of its records.

A :class:`RunFolder` names the folder, refuses to write into an earlier run's folder
unless forced, writes ``run.json`` (provenance: :func:`experiments.runs.provenance.run_record`)
and ``metrics.json`` as strict JSON, and says in the folder how a run ended badly
(``metrics.json``'s ``error`` and ``signal``, an ``INCOMPLETE`` marker).

Naming, one convention:

- a job or a benchmark (``wander run``, ``record``, ``rig``, ``evaluate``, ``demo``,
  ``benchmark …``): ``runs/<command>-YYYYmmdd-HHMMSS/`` (local time; ``-2``, ``-3``… when
  that exists), or ``--out``;
- an experiment: ``results/<name>/YYYYmmdd-HHMMSS-seedN/``, or ``--out``: the same stamp,
  grouped by experiment because ``wander report`` reads the newest folder of each
  experiment under ``results/<name>/``;
- a sweep: ``results/sweeps/<name>/``, or ``--out``: one folder per sweep file, not per
  run, because a rerun resumes the trials stored there (:meth:`take_stop`).

An explicit folder that exists and is not empty is refused (:class:`FileExistsError`)
unless ``force``. The folder is not created when named: a run that fails before it
starts leaves nothing behind, except a signal, which creates it to say so.

A command owns a :class:`CurrentRun`; a folder named with it registers itself there, so
that the command's failure handling finds the folder whether ``--out`` named it or not.

Examples:
    >>> import tempfile
    >>> root = Path(tempfile.mkdtemp())
    >>> current = CurrentRun()
    >>> run = RunFolder.new("run", root=root, current=current)
    >>> run.path.name[:4], len(run.path.name) == len("run-20260101-120000"), run.path.exists()
    ('run-', True, False)
    >>> current.folder is run
    True
    >>> _ = run.write_metrics({"detection": float("nan")})
    >>> (run.path / "metrics.json").read_text()
    '{\\n  "detection": null\\n}\\n'
    >>> RunFolder.new("run", run.path)
    Traceback (most recent call last):
    ...
    FileExistsError: ... is not empty: pass --force to write into it, ...for a new folder
    >>> run.record_failure(OSError(28, "No space left on device"))
    >>> (run.path / "INCOMPLETE").read_text(), run.read_json("metrics.json")["incomplete"]
    ('cannot write the output folder: No space left on device\\n', True)
"""

from __future__ import annotations

import json
import os
import time
from pathlib import Path
from typing import Any

from experiments.runs.failure import describe, write_failure
from experiments.runs.signals import SignalExit
from wander_env.strict_json import dumps_strict

RUN_JSON = "run.json"
METRICS_JSON = "metrics.json"
INCOMPLETE = "INCOMPLETE"

__all__ = ["INCOMPLETE", "METRICS_JSON", "RUN_JSON", "CurrentRun", "RunFolder"]


class CurrentRun:
    """The run folder a command made (``folder``; ``None`` before it named one)."""

    def __init__(self) -> None:
        self.folder: RunFolder | None = None


class RunFolder:
    """One run's folder at ``path`` (see the module docstring); ``current``: the command's
    :class:`CurrentRun`, where the folder registers itself."""

    def __init__(self, path: str | os.PathLike, current: CurrentRun | None = None) -> None:
        self.path = Path(path)
        if current is not None:
            current.folder = self

    @classmethod
    def new(
        cls,
        command: str,
        out: str | os.PathLike | None = None,
        force: bool = False,
        root: Path = Path("runs"),
        current: CurrentRun | None = None,
    ) -> RunFolder:
        """A job's or a benchmark's folder: ``out`` (refused when it holds an earlier run,
        unless ``force``), or a new ``root/COMMAND-YYYYmmdd-HHMMSS[-N]``."""
        if out is not None:
            return cls(_writable(Path(out), force), current)
        stamp = time.strftime("%Y%m%d-%H%M%S")
        for k in range(1, 1000):
            path = root / (f"{command}-{stamp}" if k == 1 else f"{command}-{stamp}-{k}")
            if not path.exists():
                return cls(path, current)
        raise FileExistsError(f"no free run folder for {command}-{stamp} under {root}")

    @classmethod
    def for_experiment(
        cls,
        name: str,
        seed: int,
        out: str | os.PathLike | None = None,
        root: Path = Path("results"),
        current: CurrentRun | None = None,
    ) -> RunFolder:
        """An experiment's folder: ``out``, or ``root/NAME/YYYYmmdd-HHMMSS-seedN``."""
        if out is not None:
            return cls(out, current)
        return cls(root / name / f"{time.strftime('%Y%m%d-%H%M%S')}-seed{seed}", current)

    def create(self) -> Path:
        """Make the folder (and its parents); returns its path."""
        self.path.mkdir(parents=True, exist_ok=True)
        return self.path

    def write_json(self, name: str, data: Any) -> Path:
        """Write ``data`` as strict, indented JSON (NaN and ±inf as ``null``) to ``name``."""
        path = self.create() / name
        path.write_text(dumps_strict(data, indent=2) + "\n")
        return path

    def read_json(self, name: str) -> dict[str, Any]:
        """The JSON object in ``name`` ({} when missing, unreadable or not an object)."""
        try:
            data = json.loads((self.path / name).read_text())
        except (OSError, ValueError, RecursionError):
            return {}
        return data if isinstance(data, dict) else {}

    def write_run(self, record: dict[str, Any]) -> Path:
        """Write ``run.json``."""
        return self.write_json(RUN_JSON, record)

    def write_metrics(self, metrics: dict[str, Any]) -> Path:
        """Write ``metrics.json``."""
        return self.write_json(METRICS_JSON, metrics)

    def mark_incomplete(self, why: str) -> None:
        """Mark the folder with an ``INCOMPLETE`` file holding ``why`` (one line): a disk
        too full for the text still gets the empty file. Never raises."""
        path = self.path / INCOMPLETE
        try:
            path.touch()  # an empty file needs no free blocks
            path.write_text(f"{' '.join(why.split())}\n")
        except OSError:
            pass

    def incomplete(self) -> bool:
        """Whether the folder is marked ``INCOMPLETE``."""
        return (self.path / INCOMPLETE).exists()

    def take_stop(self) -> None:
        """Before a run resumes in this folder (a sweep): the stop a former run recorded
        here (``metrics.json``'s error and signal, the ``INCOMPLETE`` marker) moved to the
        history of stops in ``run.json`` (``{"stops": [...]}``), so that the folder says
        only how this run ends."""
        metrics, marker = self.path / METRICS_JSON, self.path / INCOMPLETE
        stop: dict[str, Any] = {}
        if metrics.is_file():
            try:
                data = json.loads(metrics.read_text())
            except (ValueError, RecursionError):
                data = {"error": "unreadable metrics.json"}
            stop.update(data if isinstance(data, dict) else {"error": str(data)[:200]})
        if marker.is_file():
            stop["incomplete"] = marker.read_text(errors="replace").strip() or True
        if not stop:
            return
        stops = self.read_json(RUN_JSON).get("stops")
        self.write_run({"stops": [*(stops if isinstance(stops, list) else []), stop]})
        metrics.unlink(missing_ok=True)
        marker.unlink(missing_ok=True)

    def record_late_signal(self, signum: int, written: str) -> None:
        """A signal ``signum`` that came after the loop, while ``written`` (what was
        written, e.g. "the run folder was written, after the run's 100 steps") went on:
        every file was finished, and the folder is marked ``INCOMPLETE`` with the stop
        recorded (:meth:`record_failure`). The caller raises the signal after."""
        stop = SignalExit(signum)
        self.mark_incomplete(f"{stop} while {written}; every file was finished")
        self.record_failure(stop)

    def record_failure(self, err: BaseException) -> None:
        """Add ``err`` (and the signal) to ``metrics.json``; mark a write failure with
        ``INCOMPLETE``. A signal that came before the folder existed (during set-up)
        creates it. Never raises (the disk may be full)."""
        if isinstance(err, SignalExit):  # stopped before the run made its folder: say so there
            try:
                self.create()
            except OSError:
                return
        if not self.path.is_dir():
            return
        failed_write = write_failure(err)
        if failed_write is not None:
            self.mark_incomplete(describe(err))
        metrics = self.read_json(METRICS_JSON)
        metrics.setdefault("error", f"{type(err).__name__}: {err}")
        if isinstance(err, SignalExit):
            metrics["signal"] = err.name
        if failed_write is not None:
            metrics["incomplete"] = True
        path = self.path / METRICS_JSON
        try:
            tmp = path.with_suffix(".json.tmp")
            tmp.write_text(dumps_strict(metrics, indent=2) + "\n")
            os.replace(tmp, path)
        except (OSError, ValueError):
            pass


def _writable(out: Path, force: bool) -> Path:
    """``out``, unless it is a file, or a folder holding an earlier run and not ``force``."""
    if out.exists() and not out.is_dir():
        raise FileExistsError(f"{str(out)!r} exists and is not a folder")
    if out.is_dir() and any(out.iterdir()) and not force:
        raise FileExistsError(
            f"{str(out)!r} is not empty: pass --force to write into it, "
            "or leave --out out for a new folder"
        )
    return out
