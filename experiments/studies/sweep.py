"""Sweeps: a grid of (experiment, parameters, seeds), run locally or on Ray, resumable.

A sweep file (YAML)::

    name: alpha                      # the folder: results/sweeps/alpha
    seeds: [0, 1]                    # each trial of each grid point, once per seed
    experiments:
      - experiment: event_suppression
        set: {duration_s: 1.0, repeats: 1}   # fixed overrides (after configs/NAME.yaml)
        grid: {alpha: [0.5, 0.65, 0.8]}      # cartesian product of the lists

Each grid point is resolved to a full config (defaults <- ``configs/NAME.yaml`` <- ``set``
<- the point), then expanded to the experiment's trials (:func:`make_trials`). A trial is
keyed by :func:`experiments.studies.framework.trial_id` — a hash of (experiment, resolved config,
parameters, seed) — and, as it finishes, stored as ``trials/<id>.json``
(:class:`~experiments.runs.trials.TrialStore`, the store ``wander experiment`` resumes
from too).
A rerun skips every trial whose file exists, so an interrupted sweep resumes where it
stopped and an edited sweep runs only what is new; the stop a former run recorded in the
folder (``metrics.json``'s error and signal, an ``INCOMPLETE`` marker) moves to the
history of stops in ``run.json`` (``{"stops": [...]}``) when the sweep resumes, so a
finished folder holds no stale error. At the end all rows are gathered into
``results.csv`` (one row per trial, grid order; columns ``experiment`` and ``cfg.<key>``
for the grid keys, then the experiment's columns) and ``sweep.json`` (provenance, and the
real-time factor of the trials run now when they report ``simulated_s``).

Limits, checked before anything runs: seeds in [0, 2**32 - 1], each listed once (as is each
grid value), at most :data:`experiments.studies.framework.MAX_TRIALS` trials (grid points x
seeds x repeats); every grid value is validated on its own (naming the file,
``grid.KEY[i]``), their combinations when expanded.

Backends: ``serial`` (this process), ``local`` (worker processes, spawn context), ``ray``
(one task per trial; ``ray.init(address=...)`` joins a cluster — wander must be
importable on its nodes — or, without an address, starts a local Ray instance). Ray's own
messages on the driver go to the sweep folder's ``ray.log``, so a failure of Ray itself
shows as the sweep's one line (:class:`BackendFailed`), not Ray's block of raylet logs.

Nothing is left behind: local workers run in their own process groups (a Ctrl-C at the
terminal reaches only the sweep, which then ends them) and are ended — SIGTERM, then
SIGKILL — whenever the sweep stops (finished, failed, signalled); if the sweep itself is
killed with SIGKILL they die with it (``PR_SET_PDEATHSIG`` on Linux, and a thread that
watches the parent elsewhere). Every wait on a worker or a Ray task is bounded by
``timeout_s`` (no trial finishing for that long is an error saying so). A local worker
that dies in a trial (the out-of-memory killer's SIGKILL, a crash) breaks its pool: that
trial is run once more, with the others not yet finished, in a fresh pool (as Ray retries a
task), with a warning; a second death of the same trial ends the sweep with one line
(:class:`TrialCrashed`), the finished trials kept. A damaged trial file is named in a
warning, set aside and its trial run again (:mod:`experiments.runs.trials`).
"""

from __future__ import annotations

import concurrent.futures as cf
import contextlib
import itertools
import json
import math
import multiprocessing
import os
import signal
import sys
import tempfile
import threading
import time
import warnings
from collections.abc import Callable, Iterator, Mapping, Sequence
from concurrent.futures.process import BrokenProcessPool
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

from experiments.runs.folder import RunFolder
from experiments.runs.provenance import run_record
from experiments.runs.tables import Row, write_csv
from experiments.runs.trials import TrialStore
from experiments.studies.framework import (
    MAX_SEED,
    MAX_TRIALS,
    ConfigError,
    TrialSpec,
    config_from_dict,
    configs_dir,
    get_experiment,
    load_yaml_mapping,
    make_trials,
    real_time_factor,
    repeated,
    run_spec,
    serial_executor,
)
from experiments.studies.ray_log import ray_output_to
from wander_env.config_messages import SHOWN_CHARS, shown

__all__ = [
    "BACKENDS",
    "BackendFailed",
    "SweepConfig",
    "SweepEntry",
    "SweepResult",
    "TrialCrashed",
    "expand",
    "load_sweep",
    "local_executor",
    "ray_executor",
    "run_sweep",
    "serial_executor",
]

BACKENDS = ("serial", "local", "ray")
# Ray's own messages on the driver (its logger, a dead raylet's log tail), in the sweep folder.
RAY_LOG = "ray.log"
Runner = Callable[[TrialSpec], Row]


@dataclass(frozen=True)
class SweepEntry:
    """One experiment of a sweep: fixed overrides and a grid of values per key."""

    experiment: str
    set: Mapping[str, Any] = field(default_factory=dict)
    grid: Mapping[str, Sequence[Any]] = field(default_factory=dict)


@dataclass(frozen=True)
class SweepConfig:
    """A sweep file: name, seeds, experiments; ``where`` the file it was read from (its
    errors name it)."""

    name: str
    seeds: tuple[int, ...] = (0,)
    experiments: tuple[SweepEntry, ...] = ()
    where: str = "sweep"


@dataclass
class SweepResult:
    """What :func:`run_sweep` did."""

    rows: list[Row]
    ran: int
    skipped: int
    out_dir: Path
    real_time_factor: float | None = None  # of the trials run now (None: no simulated time)


def _check_keys(data: Mapping[str, Any], allowed: Sequence[str], where: str) -> None:
    bad = sorted(set(data) - set(allowed))
    if bad:
        raise ConfigError(f"{where}: unknown key(s) {bad}; allowed: {list(allowed)}")


def sweep_from_dict(data: Mapping[str, Any], where: str = "sweep") -> SweepConfig:
    """Validate a parsed sweep file (ConfigError naming the field)."""
    if not isinstance(data, Mapping):
        raise ConfigError(f"{where}: expected a mapping")
    _check_keys(data, ("name", "seeds", "experiments"), where)
    name = data.get("name")
    if not isinstance(name, str) or name in ("", ".", "..") or "/" in name or "\0" in name:
        raise ConfigError(
            f"{where}.name: must be a folder name (no '/', not '.' or '..'), got {name!r}"
        )
    seeds = data.get("seeds", [0])
    if (
        not isinstance(seeds, list)
        or not seeds
        or not all(
            isinstance(s, int) and not isinstance(s, bool) and 0 <= s <= MAX_SEED for s in seeds
        )
    ):
        raise ConfigError(
            f"{where}.seeds: must be a non-empty list of integers in [0, {MAX_SEED}], got {seeds!r}"
        )
    twice = repeated(seeds)
    if twice:  # the same trials twice
        raise ConfigError(
            f"{where}.seeds: must list each seed once ({twice[0]} twice), got {shown(seeds)}"
        )
    entries = []
    raw = data.get("experiments")
    if not isinstance(raw, list) or not raw:
        raise ConfigError(f"{where}.experiments: must be a non-empty list")
    points = 0
    for i, e in enumerate(raw):
        at = f"{where}.experiments[{i}]"
        if not isinstance(e, Mapping):
            raise ConfigError(f"{at}: expected a mapping")
        _check_keys(e, ("experiment", "set", "grid"), at)
        exp = get_experiment(str(e.get("experiment")))
        sets = e.get("set") or {}
        grid = e.get("grid") or {}
        if not isinstance(sets, Mapping) or not isinstance(grid, Mapping):
            raise ConfigError(f"{at}: set and grid must be mappings")
        for k, v in grid.items():
            if not isinstance(v, list) or not v:
                raise ConfigError(f"{at}.grid.{k}: must be a non-empty list, got {v!r}")
        points += math.prod(len(v) for v in grid.values())
        if points * len(seeds) > MAX_TRIALS:  # before any point is expanded
            raise ConfigError(
                f"{at}.grid: {points} grid points x {len(seeds)} seeds; at most "
                f"{MAX_TRIALS} trials in a sweep"
            )
        for k, v in grid.items():
            twice = repeated(v)
            if twice:  # the same grid points twice
                raise ConfigError(
                    f"{at}.grid.{k}: must list each value once ({shown(twice[0])} twice), "
                    f"got {shown(v)}"
                )
        first = {k: v[0] for k, v in grid.items()}
        config_from_dict(exp.config_type, {**sets, **first}, where=at)
        for k, values in grid.items():  # each value once (their combinations: expand)
            for j, v in enumerate(values[1:], 1):
                config_from_dict(
                    exp.config_type, {**sets, **first, k: v}, where=f"{at}.grid.{k}[{j}]"
                )
        entries.append(SweepEntry(exp.name, dict(sets), {k: list(v) for k, v in grid.items()}))
    return SweepConfig(name, tuple(seeds), tuple(entries), where)


def load_sweep(path: Path) -> SweepConfig:
    """Read and validate a sweep file (:func:`wander_env.config.load_yaml`: bounded;
    ConfigError on one line)."""
    return sweep_from_dict(load_yaml_mapping(path, "sweep file"), where=str(path))


def _column_value(v: Any) -> Any:
    return v if isinstance(v, (int, float, str, bool)) else json.dumps(v)


def expand(sweep: SweepConfig) -> list[TrialSpec]:
    """All trials of the sweep in order (entries, grid points, seeds, the experiment's
    trials); duplicates (same trial id) are kept once."""
    specs: list[TrialSpec] = []
    seen: set[str] = set()
    for i, entry in enumerate(sweep.experiments):
        at = f"{sweep.where}.experiments[{i}]"
        exp = get_experiment(entry.experiment)
        default = configs_dir() / f"{exp.name}.yaml"
        base = exp.config_type()
        if default.is_file():
            base = config_from_dict(exp.config_type, load_yaml_mapping(default), base, str(default))
        base = config_from_dict(exp.config_type, entry.set, base, where=f"{at}.set")
        keys = list(entry.grid)
        for values in itertools.product(*(entry.grid[k] for k in keys)):
            point = dict(zip(keys, values, strict=True))
            cfg = config_from_dict(exp.config_type, point, base, where=f"{at}.grid {point}")
            extra = {"experiment": exp.name}
            extra.update({f"cfg.{k}": _column_value(v) for k, v in point.items()})
            for seed in sweep.seeds:
                for spec in make_trials(exp, cfg, seed, extra):
                    if spec.id in seen:
                        continue
                    seen.add(spec.id)
                    specs.append(replace(spec, index=len(specs)))
                    if len(specs) > MAX_TRIALS:
                        raise ConfigError(
                            f"sweep {sweep.name!r}: more than {MAX_TRIALS} trials "
                            "(grid points x seeds x repeats)"
                        )
    return specs


# ----------------------------------------------------------------------------------------
# Backends: each yields (spec, row, seconds) as trials finish


def _timed(runner: Runner, spec: TrialSpec) -> tuple[Row, float]:
    t0 = time.perf_counter()
    row = runner(spec)
    return row, time.perf_counter() - t0


#: Default bound on any wait for the next trial to finish (seconds).
WAIT_TIMEOUT_S = 6 * 3600.0


def _watch_parent(parent: int) -> None:
    while True:
        time.sleep(1.0)
        if os.getppid() != parent:
            os._exit(1)


def _worker_init(parent: int) -> None:
    """In each worker: its own process group, and death with the parent."""
    os.setpgid(0, 0)  # terminal signals go to the sweep only; it ends the workers itself
    if sys.platform.startswith("linux"):
        import ctypes

        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(1, signal.SIGKILL, 0, 0, 0)  # PR_SET_PDEATHSIG: killed with the parent
    if os.getppid() != parent:  # the parent died before prctl took effect
        os._exit(1)
    threading.Thread(target=_watch_parent, args=(parent,), daemon=True).start()


def end_workers(processes: Sequence[Any], grace_s: float = 5.0) -> None:
    """SIGTERM each worker's process group, wait up to ``grace_s``, then SIGKILL.

    ``processes``: ``multiprocessing`` processes (``pid``, ``is_alive()``).
    """
    alive = [p for p in processes if p.pid is not None]
    for sig in (signal.SIGTERM, signal.SIGKILL):
        for p in alive:
            try:
                os.killpg(p.pid, sig)  # the worker and anything it started
            except (ProcessLookupError, PermissionError):
                try:
                    os.kill(p.pid, sig)
                except (ProcessLookupError, PermissionError):
                    pass
        deadline = time.monotonic() + grace_s
        while alive and time.monotonic() < deadline:
            alive = [p for p in alive if p.is_alive()]
            if alive:
                time.sleep(0.05)
        if not alive:
            return


class TrialCrashed(RuntimeError):
    """A trial whose worker process died twice (killed by the out-of-memory killer, a
    crash); the message is one line."""


class BackendFailed(RuntimeError):
    """The Ray instance failed under the sweep (its raylet died: the raylet or its
    dashboard agent killed, by hand or by the out-of-memory killer; a node lost); the
    message is one line. The finished trials are kept: a rerun resumes."""


def _attempt(runner: Runner, spec: TrialSpec, marks: str) -> tuple[Row, float]:
    """In a worker: run the trial with ``marks/<pid>`` naming it while it runs (a worker
    that dies leaves it behind, so the sweep knows whose trial died)."""
    mark = Path(marks) / str(os.getpid())
    mark.write_text(spec.id)
    try:
        return _timed(runner, spec)
    finally:
        mark.unlink(missing_ok=True)


def _death(code: int) -> str:
    """How a worker process ended, from its exit code."""
    if code == -signal.SIGKILL:
        return "killed by SIGKILL, as the out-of-memory killer does"
    if code < 0:
        return f"killed by {signal.Signals(-code).name}"
    return f"exit status {code}"


def _crashed(processes: Mapping[int, Any], marks: Path) -> list[tuple[str, str]]:
    """(trial id, how its worker died) for each worker that died on its own while running
    a trial (the pool ends the other workers with SIGTERM, which is not counted); every
    trial then running when no worker can be told apart."""
    running = {int(m.name): m.read_text() for m in marks.iterdir() if m.name.isdigit()}
    own = []
    deadline = time.monotonic() + 5.0  # a dead worker's exit code is there a moment later
    for pid, proc in processes.items():
        proc.join(max(0.0, deadline - time.monotonic()))
        # The join returns when the worker's pipe closes, which the kernel does a moment
        # before the exit status can be read (2-3 runs in 12 of the test read none): wait.
        while proc.exitcode is None and time.monotonic() < deadline:
            time.sleep(0.005)
        code = proc.exitcode
        if code is not None and code not in (0, -signal.SIGTERM) and pid in running:
            own.append((running[pid], _death(code)))
    return own or [(tid, "the worker pool broke") for tid in running.values()]


def local_executor(
    specs: Sequence[TrialSpec],
    workers: int | None = None,
    runner: Runner = run_spec,
    timeout_s: float = WAIT_TIMEOUT_S,
) -> Iterator[tuple[TrialSpec, Row, float]]:
    """Worker processes (spawn: no forked GL or torch state); ``runner`` must be a
    module-level function. A trial whose worker dies (the out-of-memory killer's SIGKILL,
    a crash) is run once more in a fresh pool with the trials not yet finished, as Ray
    retries a task; dying twice is :class:`TrialCrashed` (one line). The workers are ended
    on any exit (module docstring)."""
    todo = list(specs)
    deaths: dict[str, int] = {}
    with tempfile.TemporaryDirectory(prefix="wander-workers-") as marks:
        while todo:
            finished: set[str] = set()
            crashed = yield from _pool(todo, workers, runner, timeout_s, Path(marks), finished)
            for mark in Path(marks).iterdir():
                mark.unlink()
            if not crashed:
                return
            by_id = {s.id: s for s in todo}
            for tid, how in crashed:
                spec = by_id[tid]  # (a trial of this pool: the marks were cleared)
                deaths[tid] = deaths.get(tid, 0) + 1
                where = f"trial {tid} ({spec.experiment} #{spec.index}, seed {spec.seed})"
                if deaths[tid] >= 2:
                    raise TrialCrashed(
                        f"{where}: its worker process died twice ({how}); the trials that "
                        "finished are kept: rerun the same command to resume"
                    )
                warnings.warn(
                    f"{where}: its worker process died ({how}); running it once more",
                    RuntimeWarning,
                    stacklevel=2,
                )
            todo = [s for s in todo if s.id not in finished]


def _pool(
    specs: Sequence[TrialSpec],
    workers: int | None,
    runner: Runner,
    timeout_s: float,
    marks: Path,
    finished: set[str],
) -> Iterator[tuple[TrialSpec, Row, float]]:
    """One process pool over ``specs``, yielding as trials finish (their ids added to
    ``finished``); returns the crashed trials (:func:`_crashed`) when a worker died."""
    n = max(1, min(workers or os.cpu_count() or 1, len(specs)))
    ctx = multiprocessing.get_context("spawn")
    pool = cf.ProcessPoolExecutor(
        max_workers=n, mp_context=ctx, initializer=_worker_init, initargs=(os.getpid(),)
    )
    futures: dict[cf.Future, TrialSpec] = {}
    # The workers' processes, kept here: a pool that breaks may drop its own table before
    # the dead worker's exit code is read.
    processes: dict[int, Any] = {}
    try:
        futures = {pool.submit(_attempt, runner, s, str(marks)): s for s in specs}
        pending = set(futures)
        while pending:
            processes.update(getattr(pool, "_processes", None) or {})
            done, pending = cf.wait(pending, timeout=timeout_s, return_when=cf.FIRST_COMPLETED)
            if not done:
                raise TimeoutError(
                    f"no trial finished within {timeout_s:g} s ({len(pending)} not done); "
                    "the workers were ended"
                )
            broken = [f for f in done if isinstance(f.exception(), BrokenProcessPool)]
            if broken:
                processes.update(getattr(pool, "_processes", None) or {})
            crashed = _crashed(processes, marks) if broken else []
            for fut in done:
                if fut not in broken:  # finished before the pool broke
                    row, secs = fut.result()
                    finished.add(futures[fut].id)
                    yield futures[fut], row, secs
            if broken:
                return crashed
        return []
    finally:
        # End the workers first and leave the futures as they are: the pool's manager
        # thread then fails every unfinished one with BrokenProcessPool and exits. (A
        # future cancelled before the workers die makes that thread raise
        # InvalidStateError on Python < 3.12, a traceback after the sweep's one line.)
        end_workers(list((getattr(pool, "_processes", None) or {}).values()))
        pool.shutdown(wait=False)


def _repo_root() -> str:
    return str(Path(__file__).resolve().parents[2])


def _ray_failure(err: BaseException, unfinished: int) -> str:
    """One line for a failure of Ray itself (:class:`BackendFailed`)."""
    first = str(err).strip().splitlines()[0] if str(err).strip() else ""
    why = f"{type(err).__name__}: {first}" if first else type(err).__name__
    if len(why) > SHOWN_CHARS:
        why = why[: SHOWN_CHARS - 3] + "..."
    return (
        f"the Ray instance failed mid-sweep ({why}; a raylet dies when it or its "
        f"dashboard agent is killed, by hand or by the out-of-memory killer); {unfinished} "
        "trial(s) not finished, the finished ones are kept: rerun to resume"
    )


def ray_executor(
    specs: Sequence[TrialSpec],
    address: str | None = None,
    workers: int | None = None,
    runner: Runner = run_spec,
    timeout_s: float = WAIT_TIMEOUT_S,
    log: Path | None = None,
) -> Iterator[tuple[TrialSpec, Row, float]]:
    """One Ray task per trial. ``address`` (e.g. ``"auto"`` or ``"ray://host:10001"``)
    joins a running cluster; None starts a local instance with ``workers`` CPUs (and the
    repository on the workers' ``PYTHONPATH``). A Ray already initialised is reused.
    Waits are bounded by ``timeout_s``; unfinished tasks are cancelled on any exit.
    Ray's own messages on the driver go to ``log`` (:func:`ray_output_to`), not the
    terminal, when it is given."""
    import ray  # noqa: F401  (first: importing Ray configures its logger)

    with ray_output_to(log) if log is not None else contextlib.nullcontext():
        yield from _ray_tasks(specs, address, workers, runner, timeout_s)


def _ray_tasks(
    specs: Sequence[TrialSpec],
    address: str | None,
    workers: int | None,
    runner: Runner,
    timeout_s: float,
) -> Iterator[tuple[TrialSpec, Row, float]]:
    import ray

    own = not ray.is_initialized()
    pending: dict[Any, TrialSpec] = {}
    if own:
        # (ray.init keeps the ``ray`` logger's handlers, setting their format and level)
        opts: dict[str, Any] = {"include_dashboard": False, "log_to_driver": False}
        if address:
            ray.init(address=address, **opts)
        else:
            path = os.pathsep.join(p for p in (_repo_root(), os.environ.get("PYTHONPATH")) if p)
            ray.init(
                num_cpus=workers or os.cpu_count() or 1,
                runtime_env={"env_vars": {"PYTHONPATH": path}},
                **opts,
            )
    try:
        task = ray.remote(num_cpus=1)(_timed)
        pending = {task.remote(runner, s): s for s in specs}
        while pending:
            done, _ = ray.wait(list(pending), num_returns=1, timeout=timeout_s)
            if not done:
                raise TimeoutError(
                    f"no Ray task finished within {timeout_s:g} s ({len(pending)} not done)"
                )
            for ref in done:
                spec = pending.pop(ref)
                try:
                    row, secs = ray.get(ref, timeout=timeout_s)
                except ray.exceptions.RayTaskError:  # the trial's own error
                    raise
                except ray.exceptions.RayError as err:  # Ray itself failed
                    pending[ref] = spec
                    raise BackendFailed(_ray_failure(err, len(pending))) from err
                yield spec, row, secs
    finally:
        for ref in list(pending):
            try:
                ray.cancel(ref, force=True)
            except Exception:  # already finished or gone with its worker
                pass
        if own:
            ray.shutdown()


# ----------------------------------------------------------------------------------------
# Running


def run_sweep(
    sweep: SweepConfig,
    out_dir: Path,
    backend: str = "local",
    workers: int | None = None,
    address: str | None = None,
    progress: Callable[[int, int], None] | None = None,
    runner: Runner = run_spec,
    command: str = "",
    timeout_s: float = WAIT_TIMEOUT_S,
) -> SweepResult:
    """Run the trials not yet stored, then gather every row into ``results.csv``.
    ``out_dir`` must be a folder or not exist (FileExistsError naming it otherwise)."""
    if backend not in BACKENDS:
        raise ConfigError(f"backend must be one of {BACKENDS}, got {backend!r}")
    if out_dir.exists() and not out_dir.is_dir():
        raise FileExistsError(f"{str(out_dir)!r} exists and is not a folder")
    specs = expand(sweep)
    store = TrialStore(out_dir)  # artifacts are not kept by sweeps
    todo = [s for s in specs if not store.has(s)]
    skipped = len(specs) - len(todo)
    folder = RunFolder(out_dir)
    folder.create()
    folder.take_stop()
    t0 = time.perf_counter()
    if backend == "serial":
        stream = serial_executor(todo, runner)
    elif backend == "local":
        stream = local_executor(todo, workers, runner, timeout_s)
    else:
        stream = ray_executor(todo, address, workers, runner, timeout_s, out_dir / RAY_LOG)
    store.put_all(stream, skipped, len(specs), progress)
    rows = [store.row(s) for s in specs]
    write_csv(rows, out_dir / "results.csv")
    seconds = time.perf_counter() - t0
    ran_ids = {s.id for s in todo}
    rtf = real_time_factor([r for r in rows if r["trial_id"] in ran_ids], seconds)
    rec = run_record(command or f"wander sweep (backend {backend})", asdict(sweep), None)
    rec.update(
        backend=backend,
        trials=len(specs),
        ran=len(todo),
        skipped=skipped,
        seconds=round(seconds, 3),
        real_time_factor=rtf,
    )
    folder.write_json("sweep.json", rec)
    return SweepResult(rows, len(todo), skipped, out_dir, rtf)
