"""Experiments: a registry, typed configs with ``--set`` overrides, trials, result folders.

An experiment is one module ``experiments/paper/NAME.py`` that defines ``EXPERIMENT``, an
:class:`Experiment`: its config dataclass (the paper's values as defaults), a ``grid``
function (config -> list of trial parameter dicts), ``run_trial`` (config, trial -> one
row of metrics), and optionally ``plot`` (rows -> PNG files) and ``compare`` (rows -> the
paper's numbers beside ours). Its default config file is ``experiments/paper/configs/NAME.yaml``.
``run_trial`` may also return arrays under keys that start with ``_`` (time series,
example maps): they are kept out of the table and saved as ``artifacts/<trial_id>.npz``
in the result folder, where ``plot(config, rows, results_dir, fig_dir)`` can load them
(:func:`load_artifacts`).
To add an experiment: write the module, add its name to
:data:`experiments.studies.registry.EXPERIMENT_NAMES`, add the YAML.

Trials: every parameter dict of the grid is run ``config.repeats`` times (1 when the
config has no ``repeats``); repeat ``r`` has seed ``seed + r``. A trial's identity is a
hash of (experiment, resolved config, parameters, seed): :func:`trial_id`.

A result folder holds ``results.csv`` (one row per trial, in grid order; same seed ->
same bytes), ``config.json`` (the resolved config), ``run.json`` (command, seed, git
revision, versions, timings), ``summary.md`` (paper vs ours) and the plots. A trial that
simulates time returns ``simulated_s`` among its metrics; the timings then hold the
real-time factor (simulated seconds per wall second, :func:`real_time_factor`).

Config fields that name something or size the work use the checked types of this module
(:data:`SceneName`, :data:`DvsPreset`, :data:`PtuPreset`, :data:`FrameMode`,
:data:`TrialSeconds`, :data:`Repeats`, :data:`RadiusDeg`, :data:`GridStepDeg`): an
unknown name or a value out of range is a ConfigError when the config is validated,
before any trial runs; one run holds at most :data:`MAX_TRIALS` trials. A config's lists
of what to run (scenes, groups, parts, levels) are checked by :func:`check_lists`: none
empty, no value twice.

Examples:
    >>> exp = get_experiment("event_suppression")
    >>> cfg = resolve_config(exp, sets=["repeats=2"])
    >>> cfg.repeats
    2
"""

from __future__ import annotations

import contextlib
import fcntl
import hashlib
import importlib
import json
import math
import os
import time
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated, Any

import pydantic

from experiments.analysis.stats import real_time_factor as real_time_factor_of
from experiments.runs.folder import RESULTS, RUN_JSON, RunFolder
from experiments.runs.provenance import run_record
from experiments.runs.tables import Row, Scalar, write_csv
from experiments.runs.trials import TrialStore, save_artifacts, split_artifacts
from experiments.studies.registry import EXPERIMENT_NAMES
from wander_env.config import ConfigError, coerce, load_yaml, parse_sets, to_plain, validate
from wander_env.config_messages import shown
from wander_env.env_config import DvsPreset, FrameMode, PtuPreset, SceneName
from wander_env.untrusted import UntrustedFileError

__all__ = [
    "EXPERIMENT_NAMES",
    "MAX_REPEATS",
    "MAX_SEED",
    "MAX_TRIALS",
    "MAX_TRIAL_S",
    "Comparison",
    "ConfigError",
    "DvsPreset",
    "Experiment",
    "FrameMode",
    "GridStepDeg",
    "PtuPreset",
    "RadiusDeg",
    "Repeats",
    "SceneName",
    "TrialSeconds",
    "TrialSpec",
    "check_lists",
    "coerce",
    "config_from_dict",
    "configs_dir",
    "default_config_file",
    "get_experiment",
    "hold_folder",
    "is_unfinished_run",
    "load_artifacts",
    "make_trials",
    "parse_sets",
    "real_time_factor",
    "render_summary",
    "repeated",
    "resolve_config",
    "run_experiment",
    "run_spec",
    "trial_id",
    "unfinished_folder",
    "write_result_folder",
]

ID_COLUMNS = ("trial", "trial_id", "repeat", "seed")


@dataclass(frozen=True)
class Comparison:
    """One line of the report: a result of the paper, its number, ours."""

    result: str
    paper: str
    ours: str
    note: str = ""


@dataclass(frozen=True)
class Experiment:
    """An experiment's parts (see the module docstring)."""

    name: str
    description: str
    config_type: type
    grid: Callable[[Any], list[dict[str, Scalar]]]
    run_trial: Callable[[Any, TrialSpec], dict[str, Scalar]]
    plot: Callable[[Any, list[Row], Path, Path], list[Path]] | None = None
    compare: Callable[[Any, list[Row]], list[Comparison]] | None = None


@dataclass(frozen=True)
class TrialSpec:
    """One trial, picklable: what a worker process needs to run it."""

    experiment: str
    config: Mapping[str, Any]
    params: Mapping[str, Scalar]
    seed: int
    repeat: int = 0
    index: int = 0
    extra: Mapping[str, Scalar] = field(default_factory=dict)  # sweep columns

    @property
    def id(self) -> str:
        return trial_id(self.experiment, self.config, self.params, self.seed)


# ----------------------------------------------------------------------------------------
# Checked field types of the experiments' configs: names checked and numbers bounded when
# the config is validated (pydantic, :func:`config_from_dict`), before anything runs.

#: The longest trial (simulated seconds).
MAX_TRIAL_S = 3600.0
#: The most repeats of a grid point.
MAX_REPEATS = 1000
#: The most trials of one experiment run or one sweep.
MAX_TRIALS = 100_000
#: The largest seed (``--seed``, a sweep's ``seeds``); repeat ``r`` uses ``seed + r``.
MAX_SEED = 2**32 - 1


#: A trial's simulated length, seconds: in (0, :data:`MAX_TRIAL_S`].
TrialSeconds = Annotated[float, pydantic.Field(gt=0, le=MAX_TRIAL_S)]
#: Repeats of each grid point: 1 to :data:`MAX_REPEATS`.
Repeats = Annotated[int, pydantic.Field(ge=1, le=MAX_REPEATS)]
#: A radius on the pan-tilt plane, degrees: in (0, 180].
RadiusDeg = Annotated[float, pydantic.Field(gt=0, le=180)]
#: A grid step on the pan-tilt plane, degrees: in [0.05, 10] (a finer grid of the
#: PTU's range outgrows memory).
GridStepDeg = Annotated[float, pydantic.Field(ge=0.05, le=10)]


def repeated(values: Iterable[Any]) -> list[Any]:
    """The values ``values`` lists more than once, each once, in order of their second
    appearance: equal values (``1`` and ``1.0``) are the same, and lists and mappings are
    compared by their canonical JSON.

    >>> repeated([3, 1, 3.0, [2], [2], 3])
    [3.0, [2]]
    """
    seen: set[Any] = set()
    twice: dict[Any, Any] = {}
    for v in values:
        try:
            key: Any = ("value", v)
            hash(key)
        except TypeError:  # a list or a mapping
            key = ("json", _canonical(v))
        if key in seen:
            twice.setdefault(key, v)
        seen.add(key)
    return list(twice.values())


def check_lists(config: Any, names: Iterable[str], allow_empty: bool = False) -> None:
    """The shared ``__post_init__`` check of a config's lists of what to run (scenes,
    groups, parts, levels): each of the fields ``names`` lists at least one value (an empty
    one runs no trial, or leaves the table without the rows it is about; unless
    ``allow_empty``) and no value twice (the same trials twice). ValueError ``FIELD: must
    ..., got VALUE``.

    >>> @dataclass(frozen=True)
    ... class C:
    ...     scenes: tuple[str, ...] = ("office",)
    ...     def __post_init__(self):
    ...         check_lists(self, ("scenes",))
    >>> C(scenes=())
    Traceback (most recent call last):
    ...
    ValueError: scenes: must list at least one value, got []
    >>> C(scenes=("office", "hand", "office"))
    Traceback (most recent call last):
    ...
    ValueError: scenes: must list each value once ('office' twice), got ['office', 'hand', 'office']
    """
    for name in names:
        values = list(getattr(config, name))
        if not values and not allow_empty:
            raise ValueError(f"{name}: must list at least one value, got []")
        twice = repeated(values)
        if twice:
            raise ValueError(
                f"{name}: must list each value once ({shown(twice[0])} twice), got {shown(values)}"
            )


# ----------------------------------------------------------------------------------------
# Registry


def get_experiment(name: str) -> Experiment:
    """The :class:`Experiment` called ``name`` (ConfigError listing the known ones)."""
    if name not in EXPERIMENT_NAMES:
        raise ConfigError(f"unknown experiment {name!r}; available: {', '.join(EXPERIMENT_NAMES)}")
    exp = importlib.import_module(f"experiments.paper.{name}").EXPERIMENT
    if not isinstance(exp, Experiment) or exp.name != name:
        raise ConfigError(
            f"experiments.paper.{name}.EXPERIMENT must be an Experiment named {name!r}"
        )
    return exp


def configs_dir() -> Path:
    """``experiments/paper/configs`` (default configs and example sweeps)."""
    return Path(__file__).resolve().parents[1] / "paper" / "configs"


# ----------------------------------------------------------------------------------------
# Typed config values (pure)


def config_from_dict(
    cls: type, values: Mapping[str, Any], base: Any = None, where: str = "config"
) -> Any:
    """A ``cls`` instance: ``base`` (or the defaults) with ``values`` typed and applied;
    nested mappings set nested parameter blocks (:func:`wander_env.config.validate`)."""
    return validate(cls, values, base, where)


def load_yaml_mapping(path: Path, what: str = "config file") -> dict[str, Any]:
    """A YAML file holding a mapping (empty file -> {}), read by
    :func:`wander_env.config.load_yaml` (bounded; ConfigError on one line)."""
    data = load_yaml(path, what)
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise ConfigError(f"{path}: expected a mapping of key: value, got {type(data).__name__}")
    return data


def default_config_file(experiment: Experiment) -> Path | None:
    """The experiment's config file, ``configs/NAME.yaml``, when there is one."""
    path = configs_dir() / f"{experiment.name}.yaml"
    return path if path.is_file() else None


def resolve_config(
    experiment: Experiment,
    config_file: Path | None = None,
    sets: Sequence[str] = (),
    use_default_file: bool = True,
) -> Any:
    """Defaults <- config file (:func:`default_config_file` unless given) <- ``--set``
    items (the layers of ``wander experiment``, without its command line)."""
    cls = experiment.config_type
    path = config_file
    if path is None and use_default_file:
        path = default_config_file(experiment)
    cfg = cls()
    if path is not None:
        cfg = config_from_dict(cls, load_yaml_mapping(path), cfg, where=str(path))
    if sets:
        cfg = config_from_dict(cls, parse_sets(sets, cls), cfg, where="--set")
    return cfg


# ----------------------------------------------------------------------------------------
# Trials


def _canonical(obj: Any) -> str:
    return json.dumps(obj, sort_keys=True, separators=(",", ":"), default=str)


def trial_id(
    experiment: str, config: Mapping[str, Any], params: Mapping[str, Any], seed: int
) -> str:
    """16 hex digits of SHA-256 over (experiment, config, params, seed) in canonical JSON.

    >>> trial_id("x", {"a": 1}, {"b": 2}, 0) == trial_id("x", {"a": 1}, {"b": 2}, 0)
    True
    """
    text = _canonical({"experiment": experiment, "config": config, "params": params, "seed": seed})
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def make_trials(
    experiment: Experiment, config: Any, seed: int, extra: Mapping[str, Scalar] | None = None
) -> list[TrialSpec]:
    """The grid times ``config.repeats`` (seed + r), in grid order."""
    cfg = to_plain(config)
    repeats = int(getattr(config, "repeats", 1))
    grid = experiment.grid(config)
    if len(grid) * repeats > MAX_TRIALS:
        raise ConfigError(
            f"{experiment.name}: {len(grid)} grid points x {repeats} repeats = "
            f"{len(grid) * repeats} trials; at most {MAX_TRIALS}"
        )
    specs = []
    for params in grid:
        for r in range(repeats):
            specs.append(
                TrialSpec(
                    experiment.name, cfg, dict(params), seed + r, r, len(specs), dict(extra or {})
                )
            )
    return specs


def run_spec(spec: TrialSpec) -> Row:
    """Run one trial (in any process) and return its full row: id columns, the sweep's
    extra columns, the trial parameters, then the metrics."""
    import torch

    # One thread per trial: on 2 cores torch's 2-thread small convolutions were measured
    # ~40x slower than 1 thread, and trials run in parallel processes anyway.
    torch.set_num_threads(1)
    exp = get_experiment(spec.experiment)
    config = config_from_dict(exp.config_type, spec.config)
    metrics = exp.run_trial(config, spec)
    row: Row = {"trial": spec.index, "trial_id": spec.id, "repeat": spec.repeat, "seed": spec.seed}
    for part in (spec.extra, spec.params, metrics):
        for k, v in part.items():
            if k in row:
                raise ValueError(f"{spec.experiment}: column {k!r} appears twice in a row")
            row[k] = v
    return row


def real_time_factor(rows: Sequence[Mapping[str, Any]], wall_s: float) -> float | None:
    """Simulated seconds per wall second (:func:`experiments.analysis.stats.real_time_factor`)
    of the sum of the rows' ``simulated_s`` column (a trial that simulates time reports it
    among its metrics) over ``wall_s``; None when no row has a finite one (the work
    simulated no time, or does not say) or ``wall_s`` is not positive: JSON's null, which
    the CLI leaves unprinted.

    >>> real_time_factor([{"simulated_s": 2.0}, {"simulated_s": 1.0}], 6.0)
    0.5
    >>> real_time_factor([{"events": 3}], 6.0) is None
    True
    """
    sims = [r.get("simulated_s") for r in rows]
    sims = [float(v) for v in sims if isinstance(v, (int, float)) and not isinstance(v, bool)]
    sims = [v for v in sims if math.isfinite(v)]
    rtf = real_time_factor_of(sum(sims), wall_s)
    return None if not sims or math.isnan(rtf) else rtf


Executor = Callable[[Sequence[TrialSpec]], Iterator[tuple[TrialSpec, Row, float]]]


def serial_executor(
    specs: Sequence[TrialSpec], runner: Callable[[TrialSpec], Row] = run_spec
) -> Iterator[tuple[TrialSpec, Row, float]]:
    """Run trials one after another in this process: (spec, row, seconds)."""
    for spec in specs:
        t0 = time.perf_counter()
        row = runner(spec)
        yield spec, row, time.perf_counter() - t0


# ----------------------------------------------------------------------------------------
# Artifacts


def load_artifacts(folder: Path, row: Mapping[str, Any]) -> dict[str, Any]:
    """The artifacts saved for ``row`` in the result folder ({} when none)."""
    from wander_env.untrusted import read_npz  # bounded, regular files only

    path = Path(folder) / "artifacts" / f"{row['trial_id']}.npz"
    if not path.is_file():
        return {}
    return read_npz(path)


# ----------------------------------------------------------------------------------------
# Running and writing


def render_summary(experiment: Experiment, config: Any, rows: list[Row], command: str = "") -> str:
    """Markdown: the paper's results beside ours (``experiment.compare``)."""
    lines = [f"# {experiment.name}", "", experiment.description, ""]
    if command:
        lines += [f"Produced by: `{command}`", ""]
    comps = experiment.compare(config, rows) if experiment.compare else []
    if comps:
        lines += ["| result | paper | ours | note |", "|---|---|---|---|"]
        lines += [f"| {c.result} | {c.paper} | {c.ours} | {c.note} |" for c in comps]
    return "\n".join(lines) + "\n"


def write_result_folder(
    out_dir: Path,
    experiment: Experiment,
    config: Any,
    rows: list[Row],
    seed: int,
    command: str,
    timings: Mapping[str, Any],
) -> list[Path]:
    """results.csv, config.json, run.json (keeping the ``stops`` of a resumed run),
    summary.md, artifacts and the plots; returns the files. ``rows`` may carry artifacts
    (``_*`` keys)."""
    folder = RunFolder(out_dir)
    folder.create()
    plain = []
    for row in rows:
        p, arts = split_artifacts(row)
        save_artifacts(out_dir, str(row["trial_id"]), arts)
        plain.append(p)
    rows = plain
    files = [write_csv(rows, out_dir / "results.csv")]
    files.append(
        folder.write_json("config.json", {"experiment": experiment.name, **to_plain(config)})
    )
    rec = {"experiment": experiment.name, **run_record(command, to_plain(config), seed)}
    stops = folder.read_json(RUN_JSON).get("stops")  # of a resumed run: kept
    rec.update(timing=timings, **({"stops": stops} if stops else {}))
    files.append(folder.write_run(rec))
    summary = out_dir / "summary.md"
    summary.write_text(render_summary(experiment, config, rows, command))
    files.append(summary)
    if experiment.plot is not None:
        files += experiment.plot(config, rows, out_dir, out_dir)
    return files


@contextlib.contextmanager
def hold_folder(path: Path) -> Iterator[None]:
    """Hold ``path`` (a folder) for this process: an exclusive ``flock`` on the folder,
    released when the block ends or the process dies (a killed run leaves no lock).
    ConfigError when another run holds it."""
    fd = os.open(path, os.O_RDONLY | os.O_DIRECTORY)
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            raise ConfigError(f"{str(path)!r} is in use by another run") from None
        yield
    finally:
        os.close(fd)


def _held(path: Path) -> bool:
    try:
        with hold_folder(path):
            return False
    except ConfigError:
        return True
    except OSError:
        return True  # gone or unreadable: not ours to resume


def is_unfinished_run(path: Path, name: str, config: Any, seed: int) -> bool:
    """Whether ``path`` holds an unfinished run of experiment ``name`` with this config and
    seed, free to resume: its ``config.json`` and ``run.json`` (written when a run starts)
    say so, it has no ``results.csv`` yet, and no running process holds it."""
    path = Path(path)
    try:
        if not path.is_dir() or (path / "results.csv").exists():
            return False
    except OSError:  # a name too long, a loop: no run there (making it says why, in one line)
        return False
    folder = RunFolder(path)
    try:
        if folder.read_json("config.json") != {"experiment": name, **to_plain(config)}:
            return False
        ran = folder.read_json(RUN_JSON)
    except UntrustedFileError:  # damaged: not resumed (a new run goes elsewhere; --out
        return False  # on it is refused as a folder that is not empty)
    return ran.get("seed") == seed and not _held(path)


def unfinished_folder(
    name: str, config: Any, seed: int, out: Path | None, root: Path = RESULTS
) -> Path | None:
    """The folder a rerun of ``wander experiment NAME`` continues: ``out`` when it holds an
    unfinished run of the same experiment, config and seed (:func:`is_unfinished_run`);
    without ``out``, the newest such folder under ``root/NAME`` (by its start); None when
    there is none (a new run)."""
    if out is not None:
        return Path(out) if is_unfinished_run(Path(out), name, config, seed) else None
    base = root / name
    candidates = sorted(base.iterdir()) if base.is_dir() else []
    found = [p for p in candidates if is_unfinished_run(p, name, config, seed)]
    return max(found, key=lambda p: (p / "config.json").stat().st_mtime_ns, default=None)


def run_experiment(
    name: str,
    config: Any,
    seed: int,
    out_dir: Path,
    command: str = "",
    executor: Executor | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> tuple[list[Row], list[Path]]:
    """Run every trial not yet stored in ``out_dir`` (each stored as it finishes:
    :class:`~experiments.runs.trials.TrialStore`), then write the result folder; returns
    (rows, files). A folder holding an unfinished run of the same experiment, config and
    seed is resumed (its finished trials kept); the stop its former run recorded moves to
    ``run.json``'s ``stops``."""
    exp = get_experiment(name)
    specs = make_trials(exp, config, seed)
    folder = RunFolder(out_dir)
    folder.create()
    cmd = command or f"wander experiment {name} --seed {seed}"
    with hold_folder(folder.path):
        folder.take_stop()
        stops = folder.read_json(RUN_JSON).get("stops")
        start = {"experiment": name, **run_record(cmd, to_plain(config), seed)}
        if stops:
            start["stops"] = stops
        folder.write_json("config.json", {"experiment": exp.name, **to_plain(config)})
        folder.write_run(start)  # says which run this folder holds (a rerun resumes it)
        store = TrialStore(out_dir, keep_artifacts=True)
        todo = [s for s in specs if not store.has(s)]
        t0 = time.perf_counter()
        stream = (executor or serial_executor)(todo)
        store.put_all(stream, len(specs) - len(todo), len(specs), progress)
        rows = [store.row(s) for s in specs]
        total = time.perf_counter() - t0
        ran = {s.id for s in todo}
        timings = {
            "total_s": round(total, 3),
            "trials": len(specs),
            "ran": len(todo),
            "resumed": len(specs) - len(todo),
            "trial_s": [store.seconds(s) for s in specs],
            "real_time_factor": real_time_factor([r for r in rows if r["trial_id"] in ran], total),
        }
        files = write_result_folder(out_dir, exp, config, rows, seed, cmd, timings)
    return rows, files
