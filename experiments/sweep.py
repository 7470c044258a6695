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
keyed by :func:`experiments.framework.trial_id` — a hash of (experiment, resolved config,
parameters, seed) — and, once run, stored as ``trials/<id>.json`` (written atomically).
A rerun skips every trial whose file exists, so an interrupted sweep resumes where it
stopped and an edited sweep runs only what is new. At the end all rows are gathered into
``results.csv`` (one row per trial, grid order; columns ``experiment`` and ``cfg.<key>``
for the grid keys, then the experiment's columns) and ``sweep.json`` (provenance).

Backends: ``serial`` (this process), ``local`` (worker processes, spawn context), ``ray``
(one task per trial; ``ray.init(address=...)`` joins a cluster — wander must be
importable on its nodes — or, without an address, starts a local Ray instance).
"""

from __future__ import annotations

import concurrent.futures as cf
import itertools
import json
import math
import multiprocessing
import os
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

from experiments.framework import (
    ConfigError,
    Row,
    TrialSpec,
    config_from_dict,
    configs_dir,
    get_experiment,
    load_yaml_mapping,
    make_trials,
    run_spec,
    serial_executor,
    split_artifacts,
    write_csv,
)
from wander_env.runinfo import dumps_strict, run_record, write_json

__all__ = [
    "BACKENDS",
    "SweepConfig",
    "SweepEntry",
    "SweepResult",
    "expand",
    "load_sweep",
    "local_executor",
    "ray_executor",
    "run_sweep",
    "serial_executor",
]

BACKENDS = ("serial", "local", "ray")
Runner = Callable[[TrialSpec], Row]


@dataclass(frozen=True)
class SweepEntry:
    """One experiment of a sweep: fixed overrides and a grid of values per key."""

    experiment: str
    set: Mapping[str, Any] = field(default_factory=dict)
    grid: Mapping[str, Sequence[Any]] = field(default_factory=dict)


@dataclass(frozen=True)
class SweepConfig:
    """A sweep file: name, seeds, experiments."""

    name: str
    seeds: tuple[int, ...] = (0,)
    experiments: tuple[SweepEntry, ...] = ()


@dataclass
class SweepResult:
    """What :func:`run_sweep` did."""

    rows: list[Row]
    ran: int
    skipped: int
    out_dir: Path


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
    if not isinstance(name, str) or not name or "/" in name:
        raise ConfigError(f"{where}.name: must be a non-empty string without '/', got {name!r}")
    seeds = data.get("seeds", [0])
    if (
        not isinstance(seeds, list)
        or not seeds
        or not all(isinstance(s, int) and not isinstance(s, bool) for s in seeds)
    ):
        raise ConfigError(f"{where}.seeds: must be a non-empty list of integers, got {seeds!r}")
    entries = []
    raw = data.get("experiments")
    if not isinstance(raw, list) or not raw:
        raise ConfigError(f"{where}.experiments: must be a non-empty list")
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
        config_from_dict(exp.config_type, {**sets, **{k: v[0] for k, v in grid.items()}}, where=at)
        entries.append(SweepEntry(exp.name, dict(sets), {k: list(v) for k, v in grid.items()}))
    return SweepConfig(name, tuple(seeds), tuple(entries))


def load_sweep(path: Path) -> SweepConfig:
    """Read and validate a sweep file."""
    return sweep_from_dict(load_yaml_mapping(path), where=str(path))


def _column_value(v: Any) -> Any:
    return v if isinstance(v, (int, float, str, bool)) else json.dumps(v)


def expand(sweep: SweepConfig) -> list[TrialSpec]:
    """All trials of the sweep in order (entries, grid points, seeds, the experiment's
    trials); duplicates (same trial id) are kept once."""
    specs: list[TrialSpec] = []
    seen: set[str] = set()
    for entry in sweep.experiments:
        exp = get_experiment(entry.experiment)
        default = configs_dir() / f"{exp.name}.yaml"
        base = exp.config_type()
        if default.is_file():
            base = config_from_dict(exp.config_type, load_yaml_mapping(default), base, str(default))
        base = config_from_dict(exp.config_type, entry.set, base, where=f"{exp.name}.set")
        keys = list(entry.grid)
        for values in itertools.product(*(entry.grid[k] for k in keys)):
            point = dict(zip(keys, values, strict=True))
            cfg = config_from_dict(exp.config_type, point, base, where=f"{exp.name}.grid {point}")
            extra = {"experiment": exp.name}
            extra.update({f"cfg.{k}": _column_value(v) for k, v in point.items()})
            for seed in sweep.seeds:
                for spec in make_trials(exp, cfg, seed, extra):
                    if spec.id in seen:
                        continue
                    seen.add(spec.id)
                    specs.append(replace(spec, index=len(specs)))
    return specs


# ----------------------------------------------------------------------------------------
# Backends: each yields (spec, row, seconds) as trials finish


def _timed(runner: Runner, spec: TrialSpec) -> tuple[Row, float]:
    t0 = time.perf_counter()
    row = runner(spec)
    return row, time.perf_counter() - t0


def local_executor(
    specs: Sequence[TrialSpec], workers: int | None = None, runner: Runner = run_spec
) -> Iterator[tuple[TrialSpec, Row, float]]:
    """Worker processes (spawn: no forked GL or torch state); ``runner`` must be a
    module-level function."""
    if not specs:
        return
    n = max(1, min(workers or os.cpu_count() or 1, len(specs)))
    ctx = multiprocessing.get_context("spawn")
    with cf.ProcessPoolExecutor(max_workers=n, mp_context=ctx) as pool:
        futures = {pool.submit(_timed, runner, s): s for s in specs}
        try:
            for fut in cf.as_completed(futures):
                row, secs = fut.result()
                yield futures[fut], row, secs
        finally:
            for fut in futures:
                fut.cancel()


def _repo_root() -> str:
    return str(Path(__file__).resolve().parents[1])


def ray_executor(
    specs: Sequence[TrialSpec],
    address: str | None = None,
    workers: int | None = None,
    runner: Runner = run_spec,
) -> Iterator[tuple[TrialSpec, Row, float]]:
    """One Ray task per trial. ``address`` (e.g. ``"auto"`` or ``"ray://host:10001"``)
    joins a running cluster; None starts a local instance with ``workers`` CPUs (and the
    repository on the workers' ``PYTHONPATH``). A Ray already initialised is reused."""
    import ray

    own = not ray.is_initialized()
    if own:
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
            done, _ = ray.wait(list(pending), num_returns=1)
            for ref in done:
                spec = pending.pop(ref)
                row, secs = ray.get(ref)
                yield spec, row, secs
    finally:
        if own:
            ray.shutdown()


# ----------------------------------------------------------------------------------------
# Running


def _trial_file(out_dir: Path, spec: TrialSpec) -> Path:
    return out_dir / "trials" / f"{spec.id}.json"


def _store(out_dir: Path, spec: TrialSpec, row: Row, secs: float) -> None:
    plain, _ = split_artifacts(row)  # artifacts are not kept by sweeps
    path = _trial_file(out_dir, spec)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp")
    rec = {"spec": asdict(spec), "row": plain, "seconds": round(secs, 3)}
    tmp.write_text(dumps_strict(rec) + "\n")  # NaN as null: strict JSON
    os.replace(tmp, path)


def _load_row(out_dir: Path, spec: TrialSpec) -> Row:
    row = json.loads(_trial_file(out_dir, spec).read_text())["row"]
    row = {k: math.nan if v is None else v for k, v in row.items()}  # null: a missing figure
    # ids and sweep columns from the current sweep file (indices shift when it is edited)
    row.update({"trial": spec.index, "repeat": spec.repeat, "seed": spec.seed})
    row.update(spec.extra)
    head = ["trial", "trial_id", "repeat", "seed", *spec.extra]
    return {**{k: row[k] for k in head}, **{k: v for k, v in row.items() if k not in head}}


def run_sweep(
    sweep: SweepConfig,
    out_dir: Path,
    backend: str = "local",
    workers: int | None = None,
    address: str | None = None,
    progress: Callable[[int, int], None] | None = None,
    runner: Runner = run_spec,
    command: str = "",
) -> SweepResult:
    """Run the trials not yet stored, then gather every row into ``results.csv``."""
    if backend not in BACKENDS:
        raise ConfigError(f"backend must be one of {BACKENDS}, got {backend!r}")
    specs = expand(sweep)
    todo = [s for s in specs if not _trial_file(out_dir, s).is_file()]
    skipped = len(specs) - len(todo)
    out_dir.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    if backend == "serial":
        stream = serial_executor(todo, runner)
    elif backend == "local":
        stream = local_executor(todo, workers, runner)
    else:
        stream = ray_executor(todo, address, workers, runner)
    done = skipped
    if progress is not None:
        progress(done, len(specs))
    for spec, row, secs in stream:
        _store(out_dir, spec, row, secs)
        done += 1
        if progress is not None:
            progress(done, len(specs))
    rows = [_load_row(out_dir, s) for s in specs]
    write_csv(rows, out_dir / "results.csv")
    rec = run_record(command or f"wander sweep (backend {backend})", asdict(sweep), None)
    rec.update(
        backend=backend,
        trials=len(specs),
        ran=len(todo),
        skipped=skipped,
        seconds=round(time.perf_counter() - t0, 3),
    )
    write_json(out_dir / "sweep.json", rec)
    return SweepResult(rows, len(todo), skipped, out_dir)
