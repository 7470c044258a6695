"""``wander evaluate``: the agent's quality in simulation over several seeds.

Runs :func:`experiments.jobs.run_agent.run` once per seed (each a full run folder under
``out/seed-N``) and pools the figures the issue and the paper ask for:

- detection accuracy: the 8×8 box around each decision's ``P`` touches a moving
  object's mask (union of the masks over the fixation window); pooled over all
  scored decisions of all seeds (the paper: 68–89 % on EVIMO; our aim
  :data:`DETECTION_BAR`, ≥ 90 %), with its 95 % Wilson interval (:func:`detection_interval`);
- sOMS event suppression (the paper: ≈ 85 %);
- foveation error after a saccade, x and y, pixels at the fovea (reached minus intended
  gaze; the paper's real PTU: 4.64 ± 1.49 px and 11.76 ± 2.58 px);
- the real-time factor: simulated seconds over wall seconds of the runs.

One row per seed and the pooled row, whose ``seed`` is ``all``, go to ``quality.csv`` (one
line a row, the columns of :class:`QualityRow`; floats exact, an undefined figure empty)
and ``quality.json`` (with the run record: config, seeds, git revision, versions), which
:func:`read_quality` reads back.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

import numpy as np

from agents.suppression import suppressed_fraction
from experiments.analysis.stats import real_time_factor, wilson_interval
from experiments.jobs.run_agent import RunConfig, run
from experiments.runs.folder import RunFolder
from experiments.runs.provenance import run_record
from experiments.runs.tables import write_csv
from wander_env.config import to_plain
from wander_env.env_config import WanderConfig
from wander_env.untrusted import UntrustedFileError, read_json

if TYPE_CHECKING:
    from agents.soms import SOMSParams
    from agents.speck_front import SpeckFrontParams

#: The simulated seconds of each seed's run (:class:`EvaluateConfig`'s
#: ``env.episode_seconds``).
EVALUATE_SECONDS = 20.0
#: The detection accuracy the agent aims at, pooled over a run's scored decisions (the
#: office bar of :mod:`experiments.paper.oms_scorecard`).
DETECTION_BAR = 0.90


def _evaluate_env() -> WanderConfig:
    return WanderConfig(episode_seconds=EVALUATE_SECONDS)


@dataclass(frozen=True)
class EvaluateConfig(RunConfig):
    """What ``wander evaluate`` runs for each seed: a :class:`RunConfig` (its ``seed``
    replaced by each seed's), but :data:`EVALUATE_SECONDS` a seed and no video.

    >>> config = EvaluateConfig()
    >>> config.seconds, config.video, config.agent == RunConfig().agent
    (20.0, False, True)
    """

    env: WanderConfig = field(default_factory=_evaluate_env)
    video: bool = False


def detection_interval(hits: int, scored: int, confidence: float = 0.95) -> tuple[float, float]:
    """Wilson score interval of a hit rate ``hits / scored`` (nan, nan when nothing was
    scored): how far the detection accuracy of a few dozen decisions can be trusted.

    Examples:
        >>> low, high = detection_interval(124, 140)
        >>> round(low, 3), round(high, 3)
        (0.822, 0.928)
    """
    return wilson_interval(hits, scored, confidence)


@dataclass(frozen=True)
class QualityRow:
    """One seed's figures (or the pooled ones, ``seed = "all"``); the 95 % interval of the
    detection accuracy is derived from ``hits`` and ``scored``, the real-time factor from
    ``simulated_s`` and ``wall_s``."""

    seed: int | Literal["all"]
    decisions: int
    scored: int
    hits: int
    detection_accuracy: float
    soms_suppression: float
    foveation_error_x_px: float
    foveation_error_y_px: float
    saccades: int
    simulated_s: float
    wall_s: float
    detection_ci_low: float = field(init=False)
    detection_ci_high: float = field(init=False)
    real_time_factor: float = field(init=False)

    def __post_init__(self) -> None:
        low, high = detection_interval(self.hits, self.scored)
        object.__setattr__(self, "detection_ci_low", low)
        object.__setattr__(self, "detection_ci_high", high)
        rtf = real_time_factor(self.simulated_s, self.wall_s)
        object.__setattr__(self, "real_time_factor", rtf)


def _row(seed: int, m: dict) -> QualityRow:
    scored = int(m["decisions_scored"])
    acc = m["detection_accuracy"]
    return QualityRow(
        seed=seed,
        decisions=int(m["decisions"]),
        scored=scored,
        hits=round(acc * scored) if scored else 0,
        detection_accuracy=acc,
        soms_suppression=m["soms_suppression"],
        foveation_error_x_px=m.get("foveation_error_x_px_mean", math.nan),
        foveation_error_y_px=m.get("foveation_error_y_px_mean", math.nan),
        saccades=int(m["saccades"]),
        simulated_s=float(m["simulated_s"]),
        wall_s=float(m["wall_s"]),
    )


def pooled(rows: list[QualityRow], kept: list[int], seen: list[int]) -> QualityRow:
    """All seeds together (``seed = "all"``): hits / scored decisions, suppression over all
    events, the saccade-weighted mean foveation errors, and the simulated and wall seconds
    summed."""
    scored = sum(r.scored for r in rows)
    hits = sum(r.hits for r in rows)
    sac = [r for r in rows if r.saccades and not math.isnan(r.foveation_error_x_px)]
    w = np.array([r.saccades for r in sac], dtype=float)

    def wmean(vals: list[float]) -> float:
        return float(np.average(vals, weights=w)) if len(sac) else math.nan

    return QualityRow(
        seed="all",
        decisions=sum(r.decisions for r in rows),
        scored=scored,
        hits=hits,
        detection_accuracy=hits / scored if scored else math.nan,
        soms_suppression=suppressed_fraction(sum(seen), sum(kept)),
        foveation_error_x_px=wmean([r.foveation_error_x_px for r in sac]),
        foveation_error_y_px=wmean([r.foveation_error_y_px for r in sac]),
        saccades=sum(r.saccades for r in rows),
        simulated_s=sum(r.simulated_s for r in rows),
        wall_s=sum(r.wall_s for r in rows),
    )


def evaluate(
    out_dir: Path,
    config: RunConfig,
    seeds: list[int],
    progress: Callable[[int, int, int], None] | None = None,
) -> list[QualityRow]:
    """One run per seed (``config`` with its ``seed`` replaced); per-seed rows + pooled,
    written to ``quality.csv`` and ``quality.json``."""
    if not seeds:
        raise ValueError("evaluate needs at least one seed")
    rows, kept, seen = [], [], []
    for seed in seeds:
        cb = (lambda i, n, s=seed: progress(s, i, n)) if progress else None
        result = run(out_dir / f"seed-{seed}", replace(config, seed=seed), progress=cb)
        m = result.metrics
        rows.append(_row(seed, m))
        kept.append(int(m["events_kept_by_soms"]))
        seen.append(int(m["events_into_agent"]))
    total = pooled(rows, kept, seen)
    rec = run_record("wander evaluate", {"run": asdict(config), "seeds": seeds}, None)
    RunFolder(out_dir).write_json(
        "quality.json", rec | {"rows": [asdict(r) for r in rows], "pooled": asdict(total)}
    )
    write_csv([asdict(r) for r in (*rows, total)], out_dir / "quality.csv")
    return [*rows, total]


def read_quality(
    path: str | Path, key: str, soms: SOMSParams | SpeckFrontParams | None = None
) -> dict[str, Any]:
    """The ``quality.json`` :func:`evaluate` wrote, named in a config's or a caller's
    ``key`` (a bounded, regular file: :func:`wander_env.untrusted.read_json`), its
    ``rows`` (one a seed) and ``pooled`` with every undefined figure (``null``) as NaN;
    with ``soms``, its run's ``agent.soms`` must be that block (the step aside).
    ValueError naming the key and the file otherwise."""
    try:
        data = read_json(path)
    except UntrustedFileError as err:
        raise ValueError(f"{key}: {err}") from None
    if not (
        isinstance(data, dict)
        and isinstance(data.get("pooled"), dict)
        and isinstance(data.get("rows"), list)
        and all(isinstance(r, dict) for r in data["rows"])
    ):
        raise ValueError(f"{key}: {path}: not the quality.json of a wander evaluate run")
    if soms is not None:
        config = data.get("config")
        run = config.get("run") if isinstance(config, dict) else None
        agent = run.get("agent") if isinstance(run, dict) else None
        ran = agent.get("soms") if isinstance(agent, dict) else None
        if not isinstance(ran, dict):
            raise ValueError(f"{key}: {path}: its run records no agent.soms")
        mine = {k: v for k, v in to_plain(soms).items() if k != "dt"}
        if {k: v for k, v in ran.items() if k != "dt"} != mine:
            raise ValueError(
                f"{key}: {path}: its run's agent.soms is not this scorecard's (agent.soms)"
            )

    def figures(row: dict[str, Any]) -> dict[str, Any]:
        return {k: math.nan if v is None else v for k, v in row.items()}

    return data | {"rows": [figures(r) for r in data["rows"]], "pooled": figures(data["pooled"])}
