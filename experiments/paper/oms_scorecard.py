"""The sOMS scorecard: every sOMS finding of the paper, pass or fail with its figures,
for the paper-literal sOMS (min-max norm, α 0.80: ``SOMSParams()``) beside the agent's
(its ``agent`` block's ``soms``; by default :data:`agents.attention.AGENT_SOMS`, the
``"quantile"`` norm whose divisor is the map's peak clipped to [2, 3.5] × its 90th
percentile; ``--set agent.soms.alpha=0.7`` scores another).

Parts (``parts``), one trial each (both variants in the same trial):

- ``family-train`` / ``family-test``: the stimulus family (:mod:`experiments.paper.oms_stimuli`,
  4 textures × 2 object kinds × 3 periods × 7 motions × ``ideal``/``paper`` DVS, 2 seeds
  per cell), even seeds (where the agent's parameters were chosen) and odd seeds (held
  out). Claims (:func:`experiments.paper.oms_family.family_claims`, means over the stimuli of
  a group): eye-only ≥ 90 % of events suppressed; eye+object (object 2× and 4× the
  background's speed) and object-only: precision ≥ 0.9 with ≥ 30 % of the object's
  events kept; background as fast or faster (object still, half speed, opposite
  direction): the share of stimuli where the object is still enhanced — the paper's sOMS
  fails in all, so the paper-literal one passes when it enhances ≤ 20 % of them.
- ``real``: the real ego-motion recordings (``uzh_poster_egomotion``, each clip, 2, 10
  and 20 ms bins; a static scene, so every event should go): suppressed ≥ 90 %; the claim
  is taken at 10 ms (the agent's step), the other bins are reported.
- ``hand``: :mod:`experiments.paper.event_suppression` (the paper's suppression protocol in
  the ``hand`` scene: shake / hand / both / pause phases, 2 ms windows, 20 ms sOMS steps;
  each phase recorded once and scored by both variants): suppression beside the paper's
  85.16 % (≥ 75 %), shake-only ≥ 90 % suppressed, the hand's events ≥ 50 % kept and the
  hand hit (8×8 box around the OMS map's densest point) in ≥ 90 % of the
  sOMS steps of the hand-moving phases (hand, both).
- ``office``: the agent's detection accuracy in the office (``wander evaluate``): read
  from the ``quality.json`` files named in ``office_results`` (runs of the ``agent``
  block's sOMS: a file whose run had another is refused) and
  ``office_results_paper`` (paper-literal, ``--alpha``-style runs with ``norm=minmax``);
  ≥ 90 % on each file's pooled decisions, with the 95 % interval.

The bars are :data:`experiments.paper.oms_family.SUPPRESS_BAR` (family eye-only and real),
``PRECISION_BAR``, ``OBJECT_KEPT_BAR`` and ``ENHANCED_BAR`` (family),
:data:`experiments.paper.event_suppression_scoring.HAND_BARS` (hand) and
:data:`experiments.jobs.evaluate_agent.DETECTION_BAR` (office); the scorecard's text is
made from them. A figure that is undefined (NaN: nothing to score) fails its bar
(:func:`experiments.analysis.metrics.reaches`).

``reuse`` names earlier ``oms_scorecard`` result folders: a part found there (same
family, bins and hand settings, same seed) is copied from its ``results.csv`` instead of
being run again, so the parts can run as separate processes and be gathered into one
scorecard (each copied row says where it came from, ``reused_from``).

The experiment's ``--seed`` offsets every stimulus seed by an even number (the halves
stay the halves); the same seed gives the same scorecard.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Literal

import numpy as np

from agents.attention import AGENT_SOMS, AgentParams, same_but_step
from agents.soms import SOMSParams
from agents.speck_front import SpeckFrontParams
from experiments.analysis.metrics import reaches
from experiments.analysis.stats import number_text, percent_text
from experiments.jobs.evaluate_agent import DETECTION_BAR, read_quality
from experiments.paper.event_suppression_scoring import HAND_BARS, trial_figures
from experiments.paper.oms_family import (
    OBJECT_KEPT_BAR,
    PRECISION_BAR,
    SUPPRESS_BAR,
    family_claims,
    measure,
)
from experiments.paper.oms_stimuli import (
    MAX_PERIOD_PX,
    MOTIONS,
    OBJECTS,
    PERIODS_PX,
    PRESETS,
    TEXTURES,
    family,
    split,
)
from experiments.studies import framework as study
from wander_env.config import to_plain
from wander_env.untrusted import read_json
from wander_env.viz import pyplot, save_figure

__all__ = ["EXPERIMENT", "OMSScorecardConfig", "variants"]

PARTS = ("family-train", "family-test", "real", "hand", "office")
#: What the first column can hold (``compare``): the paper-literal sOMS or the front end
#: on Speck's cores (:class:`agents.speck_front.SpeckFrontParams`).
COMPARED = ("paper", "speck")
_LABELS = {
    "paper": "paper-literal (min-max, α 0.80)",
    "speck": "front end on Speck's cores (int8 DoG, IAF)",
}


def agent_label(soms: SOMSParams | SpeckFrontParams) -> str:
    """The second column's heading: the agent's default, or the config's ``agent.soms``."""
    if same_but_step(soms, AGENT_SOMS):
        return "agent default (quantile norm)"
    if isinstance(soms, SpeckFrontParams):
        return "agent.soms: the front end on Speck's cores"
    return f"agent.soms ({soms.norm} norm, α {soms.alpha:g})"


REAL_CLIPS = ("poster_6dof", "poster_translation")
#: The longest stimulus (s): its 128×128 float frames at 1 kHz, about 65 MB a second, are held
#: in memory while it is measured.
MAX_STIMULUS_S = 10.0


@dataclass(frozen=True)
class OMSScorecardConfig:
    """The scorecard's parts and their sizes (module docstring); ``compare`` is the
    variant scored beside the agent's default: ``paper`` the paper-literal sOMS, ``speck``
    the front end on Speck's cores (``--set compare=speck``; ``office_results_paper``
    then names its ``wander evaluate --set agent.soms=speck`` results). ``agent`` is the
    agent's block whose front end (its ``soms``) is the second column; its other
    settings play no part and are refused."""

    parts: tuple[str, ...] = PARTS
    textures: tuple[str, ...] = TEXTURES
    objects: tuple[str, ...] = OBJECTS
    periods: tuple[int, ...] = PERIODS_PX
    motions: tuple[str, ...] = MOTIONS
    presets: tuple[str, ...] = PRESETS
    replicates: study.Repeats = 2
    duration_s: study.TrialSeconds = 0.3
    real_dir: str = "../shared/realdata/uzh_poster_egomotion"
    real_bins_ms: tuple[int, ...] = (2, 10, 20)
    hand_repeats: study.Repeats = 10
    office_results: tuple[str, ...] = ()
    office_results_paper: tuple[str, ...] = ()
    reuse: tuple[str, ...] = ()
    compare: Literal["paper", "speck"] = "paper"
    agent: AgentParams = field(default_factory=AgentParams)

    def __post_init__(self) -> None:
        self.agent.check_reads("soms")
        if self.compare not in COMPARED:
            raise ValueError(f"compare must be one of {COMPARED}, got {self.compare!r}")
        bad = [p for p in self.parts if p not in PARTS]
        if bad:
            raise ValueError(f"parts must be among {PARTS}, got {bad}")
        if self.replicates < 2 or self.replicates % 2:
            raise ValueError(f"replicates must be even and >= 2, got {self.replicates}")
        for name, allowed in (
            ("textures", TEXTURES),
            ("objects", OBJECTS),
            ("motions", MOTIONS),
            ("presets", PRESETS),
        ):
            extra = [v for v in getattr(self, name) if v not in allowed]
            if extra:
                raise ValueError(f"{name} must be among {allowed}, got {extra}")
        if any(b <= 0 for b in self.real_bins_ms):
            raise ValueError(f"real_bins_ms must be > 0, got {self.real_bins_ms}")
        if self.hand_repeats < 1:
            raise ValueError(f"hand_repeats must be >= 1, got {self.hand_repeats}")
        study.check_lists(
            self, ("parts", "textures", "objects", "periods", "motions", "presets", "real_bins_ms")
        )
        study.check_lists(
            self, ("office_results", "office_results_paper", "reuse"), allow_empty=True
        )
        if self.duration_s > MAX_STIMULUS_S:
            raise ValueError(
                f"duration_s: must be <= {MAX_STIMULUS_S:g} s (a stimulus's frames are held in "
                f"memory, about 65 MB a second), got {self.duration_s}"
            )
        if not all(2 <= p <= MAX_PERIOD_PX for p in self.periods):
            raise ValueError(
                f"periods: must be in [2, {MAX_PERIOD_PX}] px (the texture tile), got "
                f"{list(self.periods)}"
            )

    def real_clip(self, clip: str) -> Path:
        """The events file of the real recording ``clip`` in ``real_dir``."""
        return Path(self.real_dir) / f"{clip}_events_txyp.npy"


def variants(
    compare: str = "paper", agent: SOMSParams | SpeckFrontParams = AGENT_SOMS
) -> dict[str, SOMSParams | SpeckFrontParams]:
    """The first column's variant ``compare`` (``paper``: the paper-literal sOMS,
    ``SOMSParams()``, min-max, α 0.80; ``speck``: the front end on Speck's cores,
    ``SpeckFrontParams()``) and ``agent``: the agent's front end ``agent`` (the
    config's ``agent.soms``)."""
    first = SOMSParams(conv="separable") if compare == "paper" else SpeckFrontParams()
    return {compare: first, "agent": agent}


def stimuli(cfg: OMSScorecardConfig, seed: int) -> list:
    """The configured family, stimulus seeds offset by ``2 · 10⁶ · seed``."""
    fam = family(
        cfg.replicates,
        cfg.textures,
        cfg.objects,
        cfg.periods,
        cfg.motions,
        cfg.presets,
        duration_s=cfg.duration_s,
    )
    return [replace(s, seed=s.seed + 2_000_000 * seed) for s in fam]


# ----------------------------------------------------------------------------------------
# Trials


def _family_row(cfg: OMSScorecardConfig, seed: int, half: str) -> dict[str, Any]:
    train, test = split(stimuli(cfg, seed))
    chosen = train if half == "train" else test
    vs = variants(cfg.compare, cfg.agent.soms)
    items: dict[str, list] = {k: [] for k in vs}
    for s in chosen:
        for k, m in measure(s, vs).items():
            items[k].append((s, m))
    row: dict[str, Any] = {"stimuli": len(chosen)}
    for k in vs:
        for group, figs in family_claims(items[k]).items():
            for name, v in figs.items():
                row[f"{k}:{group}:{name}"] = v
    return row


def _real_row(cfg: OMSScorecardConfig) -> dict[str, Any]:
    from agents.pipeline import PipelineBase, SaliencyPipeline
    from agents.speck_front import SpeckPipeline
    from experiments.benchmark.suppression import event_suppression
    from wander_env.events.io import read_events

    row: dict[str, Any] = {}
    for clip in REAL_CLIPS:
        rec = read_events(cfg.real_clip(clip), (240, 180))  # DAVIS240C
        for ms in cfg.real_bins_ms:
            for k, p in variants(cfg.compare, cfg.agent.soms).items():
                model: PipelineBase
                if isinstance(p, SpeckFrontParams):
                    w, h = rec.sensor_size
                    model = SpeckPipeline(replace(p, dt=ms / 1000.0, width_px=w, height_px=h))
                else:
                    model = SaliencyPipeline(replace(p, dt=ms / 1000.0), saliency="oms_density")
                r = event_suppression(rec.events, rec.sensor_size, model, ms * 1000, name=clip)
                row[f"{k}:{clip}:{ms}ms:suppressed"] = r.fraction_suppressed
                row[f"{k}:{clip}:{ms}ms:windows"] = r.n_windows
    return row


def _hand_row(cfg: OMSScorecardConfig, seed: int) -> dict[str, Any]:
    """The hand protocol (:mod:`experiments.paper.event_suppression`, its default config):
    every phase of every trial recorded once, scored by both variants."""
    from experiments.paper.event_suppression import (
        EventSuppressionConfig,
        phase_row,
        record,
    )
    from experiments.paper.event_suppression_protocol import HAND_PHASES, PHASES

    hc = EventSuppressionConfig(repeats=cfg.hand_repeats)
    # the hand trials' own paper-literal block (direct convolution), at their sOMS step
    first = SOMSParams() if cfg.compare == "paper" else SpeckFrontParams()
    blocks = {cfg.compare: first, "agent": cfg.agent.soms}
    rows: dict[str, list[dict[str, Any]]] = {k: [] for k in blocks}
    for r in range(cfg.hand_repeats):
        for phase in PHASES:
            rec = record(hc, phase, seed + r)
            for k, block in blocks.items():
                m = phase_row(hc, phase, seed + r, rec, replace(block, dt=hc.soms_step_s))
                rows[k].append({"seed": seed + r, "phase": phase, **m})
    row: dict[str, Any] = {}
    for k, mine in rows.items():
        figs = trial_figures(mine)
        moving = [m for m in mine if m["phase"] in HAND_PHASES]
        for name in HAND_BARS:
            row[f"{k}:hand:{name}"] = float(np.mean([f[name] for f in figs.values()])) / 100
        row[f"{k}:hand:hit_steps"] = sum(int(m["hit_steps"]) for m in moving)
    return row


def _office_row(cfg: OMSScorecardConfig) -> dict[str, Any]:
    row: dict[str, Any] = {}
    sources = (
        ("agent", "office_results", cfg.office_results, cfg.agent.soms),
        (cfg.compare, "office_results_paper", cfg.office_results_paper, None),
    )
    for k, field_name, files, soms in sources:
        for i, f in enumerate(files):
            data = read_quality(f, field_name, soms)
            pooled = data["pooled"]
            seeds = [r["seed"] for r in data["rows"]]
            row[f"{k}:office{i}:seeds"] = ",".join(str(s) for s in seeds)
            row[f"{k}:office{i}:accuracy"] = float(pooled["detection_accuracy"])
            row[f"{k}:office{i}:ci_low"] = float(pooled["detection_ci_low"])
            row[f"{k}:office{i}:ci_high"] = float(pooled["detection_ci_high"])
            row[f"{k}:office{i}:scored"] = int(pooled["scored"])
            row[f"{k}:office{i}:file"] = str(f)
    return row


#: config fields a reused part must share with this run
_SHARED = (
    "textures",
    "objects",
    "periods",
    "motions",
    "presets",
    "replicates",
    "duration_s",
    "real_dir",
    "real_bins_ms",
    "hand_repeats",
    "agent",
)


def reused_row(cfg: OMSScorecardConfig, part: str, seed: int) -> dict[str, Any] | None:
    """The metrics of ``part`` from the first ``cfg.reuse`` folder holding it (None when
    none does); a folder whose config or seed differs is refused (ValueError)."""
    from experiments.runs.tables import read_csv
    from experiments.studies.framework import ID_COLUMNS

    for folder in map(Path, cfg.reuse):
        conf, run = read_json(folder / "config.json"), read_json(folder / "run.json")
        if not (isinstance(conf, dict) and isinstance(run, dict)):
            raise ValueError(f"reuse: {folder}: config.json and run.json must be objects")
        rows = [r for r in read_csv(folder / "results.csv") if r.get("part") == part]
        if not rows:
            continue
        mine = {k: v for k, v in to_plain(cfg).items() if k in _SHARED}
        theirs = {k: conf.get(k) for k in _SHARED}
        if conf.get("experiment") != "oms_scorecard" or mine != theirs:
            diff = sorted(k for k in _SHARED if mine[k] != theirs[k])
            raise ValueError(f"reuse: {folder} was run with another config ({', '.join(diff)})")
        if run.get("seed") != seed:
            raise ValueError(f"reuse: {folder} has seed {run.get('seed')}, this run {seed}")
        out = {k: v for k, v in rows[0].items() if k not in (*ID_COLUMNS, "part")}
        out["reused_from"] = str(folder)
        return out
    return None


def run_trial(cfg: OMSScorecardConfig, spec: study.TrialSpec) -> dict[str, Any]:
    part = str(spec.params["part"])
    if part != "office":
        row = reused_row(cfg, part, spec.seed)
        if row is not None:
            return row
    if part.startswith("family-"):
        return _family_row(cfg, spec.seed, part.removeprefix("family-"))
    if part == "real":
        return _real_row(cfg)
    if part == "hand":
        return _hand_row(cfg, spec.seed)
    return _office_row(cfg)


def check_inputs(cfg: OMSScorecardConfig) -> None:
    """The files the parts to run read, checked before any trial runs (by :func:`grid`):
    the real clips in ``real_dir`` (with ``real`` in ``parts``) and every file named in
    ``office_results`` and ``office_results_paper`` (:func:`read_quality`), and the
    ``reuse`` folders' ``config.json`` and ``run.json``. ConfigError
    naming the key and the file. Not in the config's own check: a stored config (the
    report's) or one layer of a config (the config file before ``--set``) validates
    without its files."""
    try:
        if "real" in cfg.parts:
            missing = [p for p in map(cfg.real_clip, REAL_CLIPS) if not p.is_file()]
            if missing:
                raise ValueError(
                    f"real_dir: {missing[0]} not found (the real part reads it: set real_dir, "
                    f"or leave real out of parts), got {cfg.real_dir!r}"
                )
        for i, path in enumerate(cfg.office_results):
            read_quality(path, f"office_results[{i}]", cfg.agent.soms)
        for i, path in enumerate(cfg.office_results_paper):
            read_quality(path, f"office_results_paper[{i}]")
        for i, folder in enumerate(cfg.reuse):
            for name in ("config.json", "run.json"):
                if not (Path(folder) / name).is_file():
                    raise ValueError(
                        f"reuse[{i}]: {folder} holds no {name}: not an oms_scorecard result folder"
                    )
    except ValueError as err:
        raise study.ConfigError(str(err)) from None


def grid(cfg: OMSScorecardConfig) -> list[dict[str, Any]]:
    check_inputs(cfg)
    return [{"part": p} for p in cfg.parts]


# ----------------------------------------------------------------------------------------
# The scorecard


def _at_least(bar: float) -> str:
    """A bar on a fraction as text: ``≥ 90 %``."""
    return f"≥ {100 * bar:g} %"


def _ok(flag: bool) -> str:
    return "**pass**" if flag else "FAIL"


def _family_lines(
    row: study.Row, half: str, keys: tuple[str, ...]
) -> list[tuple[str, str, dict[str, str]]]:
    out = []
    n = row["stimuli"]
    label = "held-out (odd seeds)" if half == "test" else "tuning half (even seeds)"
    cells: dict[str, dict[str, str]] = {}
    for k in keys:
        g = lambda grp, name, k=k: row.get(f"{k}:{grp}:{name}")  # noqa: E731
        cells.setdefault("eye-only", {})[k] = (
            f"{_ok(bool(g('eye-only', 'pass')))} {percent_text(g('eye-only', 'suppressed'))} "
            f"suppressed ({percent_text(g('eye-only', 'stimuli_passing'))} of "
            f"{g('eye-only', 'n')} stimuli {_at_least(SUPPRESS_BAR)})"
        )
        for grp in ("eye+object", "object-only"):
            cells.setdefault(grp, {})[k] = (
                f"{_ok(bool(g(grp, 'pass')))} precision {number_text(g(grp, 'precision'), '.2f')}, "
                f"object kept {percent_text(g(grp, 'object_kept'))} "
                f"({percent_text(g(grp, 'stimuli_passing'))} of {g(grp, 'n')} pass)"
            )
        cells.setdefault("background-faster", {})[k] = (
            f"object enhanced in {percent_text(g('background-faster', 'enhanced'))} of "
            f"{g('background-faster', 'n')} (precision "
            f"{number_text(g('background-faster', 'precision'), '.2f')}, object kept "
            f"{percent_text(g('background-faster', 'object_kept'))})"
            + (" — fails as the paper" if g("background-faster", "pass") else "")
        )
    bars = {
        "eye-only": f"≥ {SUPPRESS_BAR:.0%} suppressed",
        "eye+object": f"precision ≥ {PRECISION_BAR}, ≥ {OBJECT_KEPT_BAR:.0%} kept",
        "object-only": f"precision ≥ {PRECISION_BAR}, ≥ {OBJECT_KEPT_BAR:.0%} kept",
        "background-faster": "paper: fails in all (reported)",
    }
    for grp in ("eye-only", "eye+object", "object-only", "background-faster"):
        out.append((f"{grp}, family {label}, {n} stimuli", bars[grp], cells[grp]))
    return out


def scorecard(
    cfg: OMSScorecardConfig, rows: list[study.Row]
) -> list[tuple[str, str, dict[str, str]]]:
    """``(claim, bar, {variant: cell})`` for every claim the rows hold."""
    out: list[tuple[str, str, dict[str, str]]] = []
    by = {str(r["part"]): r for r in rows}
    keys = (cfg.compare, "agent")
    for half in ("test", "train"):
        if f"family-{half}" in by:
            out += _family_lines(by[f"family-{half}"], half, keys)
    if "real" in by:
        r = by["real"]
        for clip in REAL_CLIPS:
            cells = {}
            for k in keys:
                parts = []
                for ms in cfg.real_bins_ms:
                    v = r.get(f"{k}:{clip}:{ms}ms:suppressed")
                    parts.append(f"{ms} ms {percent_text(v)}")
                v10 = r.get(f"{k}:{clip}:10ms:suppressed")
                ok = v10 is not None and reaches(float(v10), SUPPRESS_BAR)
                cells[k] = f"{_ok(ok)} " + ", ".join(parts)
            bar = f"{_at_least(SUPPRESS_BAR)} suppressed at 10 ms"
            out.append((f"real eye-only `{clip}`", bar, cells))
    if "hand" in by:
        r = by["hand"]
        cells = {}
        for k in keys:
            f = {n: float(r[f"{k}:hand:{n}"]) for n in HAND_BARS}
            ok = all(reaches(f[n], bar / 100) for n, bar in HAND_BARS.items())
            cells[k] = (
                f"{_ok(ok)} hand hit in {percent_text(f['hit'])} of "
                f"{r[f'{k}:hand:hit_steps']} steps; {percent_text(f['suppressed'])} suppressed "
                f"(paper 85.16 %); shake-only {percent_text(f['shake_suppressed'])}; hand's "
                f"events kept {percent_text(f['hand_kept'])}"
            )
        b = {n: _at_least(v / 100) for n, v in HAND_BARS.items()}
        bar = (
            f"hand hit {b['hit']} of the hand-moving steps, {b['suppressed']} suppressed, "
            f"shake-only {b['shake_suppressed']}, hand's events kept {b['hand_kept']} "
            "(means over trials)"
        )
        out.append(("hand scene (suppression protocol, 4 phases)", bar, cells))
    if "office" in by:
        r = by["office"]
        cells = {}
        for k in keys:
            parts, ok = [], True
            i = 0
            while f"{k}:office{i}:accuracy" in r:
                acc = float(r[f"{k}:office{i}:accuracy"])
                ok &= reaches(acc, DETECTION_BAR)
                parts.append(
                    f"seeds {r[f'{k}:office{i}:seeds']}: {percent_text(acc)} "
                    f"({percent_text(r[f'{k}:office{i}:ci_low'])}–"
                    f"{percent_text(r[f'{k}:office{i}:ci_high'])}, "
                    f"{r[f'{k}:office{i}:scored']} decisions)"
                )
                i += 1
            cells[k] = f"{_ok(ok)} " + "; ".join(parts) if parts else "not run"
        out.append(("office detection (`wander evaluate`)", _at_least(DETECTION_BAR), cells))
    return out


def compare(cfg: OMSScorecardConfig, rows: list[study.Row]) -> list[study.Comparison]:
    """The scorecard as the report's table: paper column = ``compare`` (the paper-literal
    sOMS, or the front end on Speck's cores), ours = the agent's (``agent.soms``); the bar
    in the note."""
    out = [
        study.Comparison(claim, cells.get(cfg.compare, "—"), cells.get("agent", "—"), bar)
        for claim, bar, cells in scorecard(cfg, rows)
    ]
    if out:
        out.append(choice_comparison(cfg.compare, cfg.agent.soms))
    default = same_but_step(cfg.agent.soms, AGENT_SOMS)
    if out and (cfg.compare != "paper" or not default):  # the columns are not the usual two
        heads = (_LABELS[cfg.compare], agent_label(cfg.agent.soms))
        out.insert(0, study.Comparison("columns", *heads, "compare"))
    return out


def choice_comparison(
    compare: str = "paper", p: SOMSParams | SpeckFrontParams = AGENT_SOMS
) -> study.Comparison:
    """The report's line on the two variants' thresholds (``p``: the agent's front end)
    and how the agent's default was chosen."""
    fixed = "none: a fixed int8 threshold per layer (IAF, no map-wide norm)"
    if isinstance(p, SpeckFrontParams):
        first = "min-max over the map, α 0.80" if compare == "paper" else fixed
        return study.Comparison("sOMS threshold (Eq. 1's norm)", first, fixed, "agent.soms")
    how = (
        f"divisor: the map's peak clipped to [{p.peak_ratio:g}, {p.gain:g}] × its "
        f"{p.quantile:g} quantile"
        if p.peak_ratio is not None
        else f"divisor: {p.gain:g} × its {p.quantile:g} quantile"
    )
    first = "min-max over the map, α 0.80" if compare == "paper" else fixed
    chosen = (
        "ours chosen on the even-seed half (most family claims, then the largest margin: "
        "`experiments.paper.oms_family.tune`); the odd half held out"
        if same_but_step(p, AGENT_SOMS)
        else "ours: the config's agent.soms"
    )
    return study.Comparison(
        "sOMS threshold (Eq. 1's norm)",
        first,
        f"{p.norm} norm of the σ {p.pool_sigma:g} px pooled surround excess, {how}, α {p.alpha:g}",
        chosen,
    )


def plot(
    cfg: OMSScorecardConfig, rows: list[study.Row], results_dir: Path, fig_dir: Path
) -> list[Path]:
    """Bars of the family's figures per claim group, both variants, held-out half."""
    plt = pyplot()

    row = next((r for r in rows if r["part"] == "family-test"), None)
    if row is None:
        return []
    figs = [  # (group, figure, label, bar)
        ("eye-only", "suppressed", "eye-only:\nsuppressed", SUPPRESS_BAR),
        ("eye+object", "precision", "eye+object:\nprecision", PRECISION_BAR),
        ("eye+object", "object_kept", "eye+object:\nobject kept", OBJECT_KEPT_BAR),
        ("object-only", "precision", "object-only:\nprecision", PRECISION_BAR),
        ("object-only", "object_kept", "object-only:\nobject kept", OBJECT_KEPT_BAR),
        ("background-faster", "enhanced", "bg faster:\nobject enhanced", None),
    ]
    x = np.arange(len(figs))
    fig, ax = plt.subplots(figsize=(9, 3.8))
    for j, k in enumerate((cfg.compare, "agent")):
        label = _LABELS[k] if k != "agent" else agent_label(cfg.agent.soms)
        vals = [float(row[f"{k}:{g}:{n}"]) for g, n, _, _ in figs]
        ax.bar(x + (j - 0.5) * 0.38, vals, 0.38, label=label)
    for xi, (*_, bar) in zip(x, figs, strict=True):
        if bar is not None:
            ax.hlines(bar, xi - 0.45, xi + 0.45, colors="k", linestyles="--", lw=1)
    ax.set_xticks(x, [f[2] for f in figs], fontsize=8)
    ax.set(ylim=(0, 1.05), ylabel="fraction (mean over stimuli)")
    ax.set_title(
        f"sOMS scorecard, held-out half of the stimulus family ({row['stimuli']} stimuli); "
        "dashed: the bars",
        fontsize=9,
    )
    ax.legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.2), ncol=2)
    return [save_figure(fig, fig_dir / "oms_scorecard.png")]


EXPERIMENT = study.Experiment(
    name="oms_scorecard",
    description=(
        "Every sOMS claim of the paper, pass/fail, for the paper-literal sOMS beside the "
        "agent's default: a seeded stimulus family (tuning and held-out halves), real "
        "ego-motion recordings, the hand scene and office detection."
    ),
    config_type=OMSScorecardConfig,
    grid=grid,
    run_trial=run_trial,
    plot=plot,
    compare=compare,
)
