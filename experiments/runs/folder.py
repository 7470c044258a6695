"""The run folder: where a run's files go, and the one writer of its records.

A :class:`RunFolder` names the folder and makes it this process's own, refuses to write
into an earlier run's folder unless forced, writes ``run.json`` (provenance:
:func:`experiments.runs.provenance.run_record`) and ``metrics.json`` as strict JSON, and
says in the folder how a run ended badly (``metrics.json``'s ``error`` and ``signal``, an
``INCOMPLETE`` marker).

Naming, one convention:

- a job or a benchmark (``wander run``, ``record``, ``rig``, ``evaluate``, ``demo``,
  ``benchmark …``): ``runs/<command>-YYYYmmdd-HHMMSS/`` (local time; ``-2``, ``-3``… when
  that exists), or ``--out``;
- an experiment: ``results/<name>/YYYYmmdd-HHMMSS-seedN[-2…]/``, or ``--out``: grouped by
  experiment because ``wander report`` reads the newest folder of each experiment under
  ``results/<name>/``;
- a sweep: ``results/sweeps/<name>/``, or ``--out``: one folder per sweep file, not per
  run, because a rerun resumes the trials stored there (:meth:`take_stop`).

Owned exclusively: a default folder is created when named, by one ``os.mkdir`` that fails
when the name exists (then the next suffix is tried), never by a check and a later
creation, so runs started in the same second (or twenty at once) each get their own
folder, and a run's failure marks only the folder it made. An explicit folder that does not
exist is made the same way; one that exists empty is used; one that is not empty is refused
(:class:`FileExistsError`) unless ``force``: then the run is built in a new sibling folder
(``.wander-new-*``) and :meth:`RunFolder.finish` swaps it in by renames, so nothing of the
earlier run (an old ``INCOMPLETE``, an old ``run.mp4``) survives beside the new one, and a
reader never sees the two mixed (so ``force`` is refused for the current folder and the
folders above it, which no sibling can replace). :meth:`RunFolder.finish` ends every run
(the command line calls it when the command ends, however it ends): it swaps a forced
folder in (a forced run that wrote nothing leaves the earlier run as it was) and removes a
folder it made that stayed empty (a run refused during its set-up leaves nothing behind).

A command owns a :class:`CurrentRun`; a folder named with it registers itself there, so
that the command's failure handling finds the folder whether ``--out`` named it or not.

Examples:
    >>> import tempfile
    >>> root = Path(tempfile.mkdtemp())
    >>> current = CurrentRun()
    >>> run = RunFolder.new("run", root=root, current=current)
    >>> run.path.name[:4], len(run.path.name) == len("run-20260101-120000"), run.path.is_dir()
    ('run-', True, True)
    >>> current.folder is run
    True
    >>> _ = run.write_metrics({"detection": float("nan")})
    >>> (run.path / "metrics.json").read_text()
    '{\\n  "detection": null\\n}\\n'
    >>> RunFolder.new("run", run.path)
    Traceback (most recent call last):
    ...
    FileExistsError: ... is not empty: pass --force to replace it, ...for a new folder
    >>> run.record_failure(OSError(28, "No space left on device"))
    >>> (run.path / "INCOMPLETE").read_text(), run.read_json("metrics.json")["incomplete"]
    ('cannot write the output folder: No space left on device\\n', True)
    >>> again = RunFolder.new("run", run.path, force=True)
    >>> again.path != run.path, sorted(p.name for p in run.path.iterdir())
    (True, ['INCOMPLETE', 'metrics.json'])
    >>> _ = again.write_metrics({"steps": 1})
    >>> again.finish() == run.path, sorted(p.name for p in run.path.iterdir())
    (True, ['metrics.json'])
"""

from __future__ import annotations

import errno
import os
import shutil
import tempfile
import time
from pathlib import Path
from typing import Any

from experiments.runs.failure import describe, write_failure
from experiments.runs.signals import SignalExit
from wander_env import untrusted
from wander_env.strict_json import write_strict
from wander_env.untrusted import UntrustedFileError

RUN_JSON = "run.json"
#: Where experiments put their result folders (``RESULTS/NAME/...``) and sweeps theirs
#: (``RESULTS/SWEEPS/NAME``), by default: ``wander experiment``, ``sweep`` and ``report``.
RESULTS = Path("results")
SWEEPS = "sweeps"
METRICS_JSON = "metrics.json"
INCOMPLETE = "INCOMPLETE"
#: The most suffixes (``-2`` … ``-N``) tried for a default folder name.
MAX_SUFFIX = 10_000
#: The time in a default folder name.
_STAMP = "%Y%m%d-%H%M%S"

__all__ = [
    "INCOMPLETE",
    "METRICS_JSON",
    "RESULTS",
    "RUN_JSON",
    "SWEEPS",
    "CurrentRun",
    "RunFolder",
]


class CurrentRun:
    """The run folder a command made (``folder``; ``None`` before it named one)."""

    def __init__(self) -> None:
        self.folder: RunFolder | None = None


class RunFolder:
    """One run's folder at ``path`` (see the module docstring); ``current``: the command's
    :class:`CurrentRun`, where the folder registers itself. ``final``: where the folder
    ends once :meth:`finish` swaps it in (``path`` itself unless ``--force`` replaces an
    earlier run); ``made``: whether this process created ``path``."""

    def __init__(
        self,
        path: str | os.PathLike,
        current: CurrentRun | None = None,
        final: str | os.PathLike | None = None,
        made: bool = False,
    ) -> None:
        self.path = Path(path)
        self.final = self.path if final is None else Path(final)
        self.made = made
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
        """A job's or a benchmark's folder, created: ``out`` (:meth:`claim`), or a new
        ``root/COMMAND-YYYYmmdd-HHMMSS[-N]``."""
        return cls._claim_or_make(out, force, current, root, f"{command}-{time.strftime(_STAMP)}")

    @classmethod
    def for_experiment(
        cls,
        name: str,
        seed: int,
        out: str | os.PathLike | None = None,
        force: bool = False,
        root: Path = RESULTS,
        current: CurrentRun | None = None,
    ) -> RunFolder:
        """An experiment's folder, created: ``out`` (:meth:`claim`), or a new
        ``root/NAME/YYYYmmdd-HHMMSS-seedN[-N]``."""
        return cls._claim_or_make(
            out, force, current, root / name, f"{time.strftime(_STAMP)}-seed{seed}"
        )

    @classmethod
    def _claim_or_make(
        cls,
        out: str | os.PathLike | None,
        force: bool,
        current: CurrentRun | None,
        parent: Path,
        name: str,
    ) -> RunFolder:
        """``out`` claimed (:meth:`claim`), or, without one, a new ``parent/name[-N]``."""
        if out is not None:
            return cls.claim(Path(out), force, current)
        return cls(_make_unique(parent, name), current, made=True)

    @classmethod
    def claim(cls, out: Path, force: bool = False, current: CurrentRun | None = None) -> RunFolder:
        """The folder ``out`` made this run's: created when missing, used when empty,
        refused when it is a file or (unless ``force``) holds an earlier run; with ``force``
        the run is built in a new sibling that :meth:`finish` swaps in, so ``force`` is
        refused for the current folder and the folders above it (no sibling of theirs can
        replace them). Raises :class:`FileExistsError` for a refusal, :class:`OSError` when
        ``out`` cannot be created (under a file, a name too long, a read-only place)."""
        if force and out.resolve() in (Path.cwd(), *Path.cwd().parents):
            raise FileExistsError(
                f"{str(out)!r} is the current folder or holds it: --force cannot replace it, "
                "give another --out"
            )
        if cls._make(out):
            return cls(out, current, made=True)
        if not any(out.iterdir()):
            return cls(out, current)
        if not force:
            raise FileExistsError(
                f"{str(out)!r} is not empty: pass --force to replace it, "
                "or leave --out out for a new folder"
            )
        build = tempfile.mkdtemp(prefix=".wander-new-", dir=out.parent)
        return cls(build, current, final=out, made=True)

    @classmethod
    def for_sweep(cls, out: Path, current: CurrentRun | None = None) -> RunFolder:
        """A sweep's folder ``out``: created when missing, used as it is when it exists (a
        rerun resumes the trials stored there). Raises :class:`FileExistsError` when it is
        a file, :class:`OSError` when it cannot be created (as :meth:`claim`)."""
        return cls(out, current, made=cls._make(out))

    @staticmethod
    def _make(out: Path) -> bool:
        """Create the folder ``out`` (and its parents); False when it exists as a folder
        already. Raises :class:`FileExistsError` when it is a file, :class:`OSError`
        naming ``out`` when it cannot be created (under a file, a name too long, a
        read-only place)."""
        if out.exists() and not out.is_dir():
            raise FileExistsError(f"{str(out)!r} exists and is not a folder")
        try:
            out.parent.mkdir(parents=True, exist_ok=True)
            os.mkdir(out)
        except FileExistsError:
            if not out.is_dir():  # a parent is a file
                raise NotADirectoryError(
                    errno.ENOTDIR, os.strerror(errno.ENOTDIR), str(out)
                ) from None
        except OSError as err:  # the path itself named: not a parent
            raise type(err)(err.errno, err.strerror, str(out)) from None
        else:
            return True
        return False

    def finish(self) -> Path:
        """End the run's hold on its folder; returns where the folder now is (``final``).
        A folder built beside an earlier run (``--force``) replaces it: the earlier one is
        renamed aside, this one renamed into its place, the earlier one deleted; one that
        holds nothing is removed and the earlier run stays. A folder this process made
        that stayed empty is removed. Never raises: a swap the file system refuses leaves
        the earlier run in place and the new one in its build folder (returned)."""
        try:
            if self.path != self.final:
                if _empty(self.path):
                    self.path.rmdir()
                else:
                    self._swap_in()
            elif self.made and _empty(self.path):
                self.path.rmdir()
        except OSError:
            return self.path
        self.path = self.final
        return self.final

    def _swap_in(self) -> None:
        """Replace ``final`` with ``path`` by renames (the earlier run back on failure)."""
        old = Path(tempfile.mkdtemp(prefix=".wander-old-", dir=self.final.parent))
        try:
            os.rename(self.final, old)  # onto the empty folder: atomic
            moved = True
        except FileNotFoundError:  # the earlier run was removed meanwhile
            moved = False
        try:
            os.rename(self.path, self.final)
        except OSError:
            if moved:
                os.rename(old, self.final)  # should this fail, the earlier run stays in old
            else:
                old.rmdir()
            raise
        shutil.rmtree(old, ignore_errors=True)

    def create(self) -> Path:
        """Make the folder (and its parents); returns its path."""
        self.path.mkdir(parents=True, exist_ok=True)
        return self.path

    def write_json(self, name: str, data: Any) -> Path:
        """Write ``data`` as strict, indented JSON (NaN and ±inf as ``null``) to ``name``,
        whole or not at all (:func:`wander_env.strict_json.write_strict`: a full disk leaves
        the earlier file, or none, never a damaged one that :meth:`read_json` refuses)."""
        return write_strict(self.create() / name, data, indent=2)

    def read_json(self, name: str) -> dict[str, Any]:
        """The JSON object in ``name``, read as an untrusted file (bounded:
        :func:`wander_env.untrusted.read_json`); {} when there is no such file (not written
        yet). A file that is damaged, unreadable or not an object is an
        :class:`~wander_env.untrusted.UntrustedFileError` naming it, never taken for {}."""
        path = self.path / name
        try:
            data = untrusted.read_json(path)
        except UntrustedFileError as err:
            if err.missing:
                return {}
            raise
        if not isinstance(data, dict):
            raise UntrustedFileError(path, f"expected a JSON object, got {type(data).__name__}")
        return data

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
        try:
            stop = self.read_json(METRICS_JSON)
        except UntrustedFileError as err:  # a stop all the same: its record says so
            stop = {"error": f"unreadable {METRICS_JSON}: {err.problem}"}
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
        try:
            metrics = self.read_json(METRICS_JSON)
        except UntrustedFileError as bad:  # replaced, saying so: the failure comes first
            metrics = {"unreadable_metrics": bad.problem}
        metrics.setdefault("error", f"{type(err).__name__}: {err}")
        if isinstance(err, SignalExit):
            metrics["signal"] = err.name
        if failed_write is not None:
            metrics["incomplete"] = True
        try:
            self.write_json(METRICS_JSON, metrics)
        except (OSError, ValueError):
            pass


def _make_unique(parent: Path, name: str) -> Path:
    """``parent/name``, or the first of ``parent/name-2``, ``-3``… that did not exist,
    created by this call (``os.mkdir``: of concurrent callers exactly one gets each)."""
    parent.mkdir(parents=True, exist_ok=True)
    for k in range(1, MAX_SUFFIX + 1):
        path = parent / (name if k == 1 else f"{name}-{k}")
        try:
            os.mkdir(path)
        except FileExistsError:
            continue
        return path
    raise FileExistsError(
        f"no free folder name {name}-N (N up to {MAX_SUFFIX}) under {str(parent)!r}"
    )


def _empty(path: Path) -> bool:
    """Whether ``path`` is a folder holding nothing."""
    try:
        return path.is_dir() and not any(path.iterdir())
    except OSError:
        return False
