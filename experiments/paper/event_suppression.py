"""Event suppression by the sOMS, per phase (the paper's Table "eventssupp", Figure "ev_supp").

The paper's trials: "alternating phases of slightly shaking the DVS sensor while moving a
hand in front of the camera, with intermittent pauses"; events counted every 2 ms before
and after the sOMS; 10 trials; 14747.03 ± 2029.17 events in, 2189.15 ± 385.57 out,
85.16 % suppressed.

Here: the ``hand`` scene (a hand waved at 2 Hz, 0.15 m in front of the camera, in a
cluttered room). A trial is the four phases of :data:`PHASES` — ``shake`` (the camera
shaken, the hand still), ``hand`` (the hand waving, the camera still), ``both`` and
``pause`` (nothing moves) — in an order and with lengths drawn from the trial's seed
(:func:`schedule`; lengths uniform in ``[lo, hi]`` of the config, whole sOMS steps).

The shake (:class:`Shake`): the camera's gaze circles ``amplitude_deg`` about its home at a
constant ``speed_deg_s`` (pan and tilt in quadrature; start angle and sense drawn per
trial), driven through the env's actions, so the PTU model moves the camera. Its clock
runs only in ``shake`` and ``both``; the hand's only in ``hand`` and ``both``
(:class:`PhaseClock`, :class:`ClockedTrajectory`): a pause freezes both where they are.

Rows: one per trial and phase (the grid is the phases). The row of phase ``P`` is
recorded by itself: the env starts with the hand and the camera where the trial's clocks
put them at ``P``'s start, runs ``lead_s`` of the phase before ``P`` (a pause before
the first; it warms the DVS and the sOMS and is not scored), then ``P``. The env steps
every ``window_s`` (2 ms); the sOMS steps once per ``soms_step_s`` on the summed counts and
its map gates each of the step's windows' events (an event counts as *out* when it falls
on a pixel the OMS map fires at, both polarities).

Per row: events in and out per window (mean, std), the fraction suppressed (1 − out/in
over the phase), with the ground-truth mask the hand's events kept and the background's
kept, and in the phases where the hand moves the hand hit (:func:`hand_hit`: the 8×8 box
around the OMS map's densest point touches the hand) per sOMS step with its Wilson 95 %
interval. :func:`compare` pools the rows per phase over trials (means with 95 %
bootstrap intervals over trials) beside the paper's table.

``hand_ratio`` (for the speed-ratio curve, :mod:`experiments.paper.speed_ratio`) rescales
the hand's speed so that its image speed is that many times the shake's
(:func:`image_speeds`); ``phases`` picks which phases become rows.

The protocol's pure pieces (the phases, :class:`Shake`, the clocks) are in
:mod:`experiments.paper.event_suppression_protocol`; the scorer of a row and of a trial
(:func:`score`, :func:`hand_hit`, :func:`trial_figures`) in
:mod:`experiments.paper.event_suppression_scoring`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

import wander_env  # noqa: F401  (registers the environments)
from agents.attention import AGENT_SOMS, AgentParams, same_but_step
from agents.soms import SOMSParams
from agents.speck_front import SpeckFrontParams
from experiments.analysis.stats import ci_text, mean_ci, wilson_interval
from experiments.benchmark.suppression import PAPER_SUPPRESSION
from experiments.paper.env_block import check_env_block, trial_env
from experiments.paper.event_suppression_protocol import (
    HAND_PHASES,
    PHASES,
    SHAKE_PHASES,
    PhaseClock,
    Recording,
    Segment,
    Shake,
    ShakeScript,
    WindowRecorder,
    recording,
    shake_start,
)
from experiments.paper.event_suppression_scoring import (
    HAND_BARS,
    map_model,
    pooled_mean_std,
    score,
    trial_figures,
)
from experiments.runs.episode import run_episode
from experiments.studies import framework as study
from wander_env.camera import focal_length_px
from wander_env.env_config import WanderConfig
from wander_env.scene_config import SceneConfig
from wander_env.trajectories import LinearBounceParams
from wander_env.viz import pyplot, save_figure

__all__ = [
    "EXPERIMENT",
    "EventSuppressionConfig",
    "image_speeds",
    "phase_row",
    "record",
    "schedule",
]


#: An sOMS block: the host's float sOMS or the front end on Speck's cores.
FrontBlock = SOMSParams | SpeckFrontParams

Range = tuple[float, float]


#: The env fields each trial sets (what sets them): the block leaves them at defaults.
ENV_SET_PER_TRIAL = {"control_period_s": "window_s", "episode_seconds": "the phases"}


@dataclass(frozen=True)
class EventSuppressionConfig:
    """Defaults: the paper's (2 ms windows, 10 trials, sOMS table values); the scene,
    the shake and the phase lengths are ours (the paper gives none): each in the
    config file with its reason.

    ``shake_s``, ``hand_s``, ``both_s``, ``pause_s``: each phase's length range (s),
    drawn per trial. ``agent`` is the agent's block (:class:`agents.attention.AgentParams`)
    whose front end the trials score: its ``soms`` (``--set agent.soms.alpha=0.6``; the
    paper's table by default, ``SOMSParams()``; ``--set agent.soms=agent`` the agent's
    default sOMS, ``agent.soms=speck`` the front end on Speck's cores), stepped every
    ``soms_step_s``, a whole number of ``window_s`` windows; the agent's other settings
    play no part and are refused. ``second_agent`` (None: none) is a second agent block
    whose front end is scored on the same windows at the same step (the ``second:``
    columns: two front ends side by side on identical events; ``--set
    second_agent.soms=agent``). ``env`` is the env's block
    (the hand scene and the Speck by default); each trial sets its step and length
    (:data:`ENV_SET_PER_TRIAL`).
    ``hand_margin_px``: the hand's events are those on its swept mask or within that many
    pixels (:func:`swept`)."""

    env: WanderConfig = field(default_factory=lambda: WanderConfig(scene="hand", dvs="speck"))
    window_s: float = 0.002
    shake_s: Range = (0.6, 1.0)
    hand_s: Range = (0.6, 1.0)
    both_s: Range = (0.6, 1.0)
    pause_s: Range = (0.2, 0.4)
    lead_s: float = 0.1
    phases: tuple[str, ...] = PHASES
    shake: Shake = field(default_factory=Shake)
    hand_ratio: float | None = None
    repeats: study.Repeats = 10
    soms_step_s: float = 0.02
    agent: AgentParams = field(default_factory=lambda: AgentParams(soms=SOMSParams()))
    second_agent: AgentParams | None = None
    hit_sigma_px: float = 2.0
    hand_margin_px: int = 2

    def __post_init__(self) -> None:
        check_env_block(self.env, ENV_SET_PER_TRIAL)
        self.agent.check_reads("soms")
        if self.second_agent is not None:
            self.second_agent.check_reads("soms")
        for name in ("window_s", "soms_step_s", "hit_sigma_px"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name} must be > 0, got {getattr(self, name)}")
        for p in PHASES:
            lo, hi = self.phase_range(p)
            if not 0 < lo <= hi:
                raise ValueError(f"{p}_s must be (lo, hi) with 0 < lo <= hi, got {(lo, hi)}")
        if self.lead_s < 0:
            raise ValueError(f"lead_s must be >= 0, got {self.lead_s}")
        bad = [p for p in self.phases if p not in PHASES]
        if bad or not self.phases or len(set(self.phases)) != len(self.phases):
            raise ValueError(f"phases must be distinct names among {PHASES}, got {self.phases}")
        if self.hand_ratio is not None and not self.hand_ratio > 0:
            raise ValueError(f"hand_ratio must be > 0 or None, got {self.hand_ratio}")
        if self.repeats < 1:
            raise ValueError(f"repeats must be >= 1, got {self.repeats}")
        if self.hand_margin_px < 0:
            raise ValueError(f"hand_margin_px must be >= 0, got {self.hand_margin_px}")
        ticks = self.window_s * 1000.0
        if abs(ticks - round(ticks)) > 1e-9:
            raise ValueError(f"window_s must be a whole number of ms, got {self.window_s}")
        k = self.soms_step_s / self.window_s
        if abs(k - round(k)) > 1e-9 or round(k) < 1:
            raise ValueError(
                f"soms_step_s={self.soms_step_s} must be a whole number of windows "
                f"(window_s={self.window_s})"
            )
        lead = self.lead_s / self.soms_step_s
        if abs(lead - round(lead)) > 1e-9:
            raise ValueError(f"lead_s must be a whole number of sOMS steps ({self.soms_step_s})")

    def phase_range(self, phase: str) -> Range:
        """The length range (s) of ``phase``."""
        lo, hi = getattr(self, f"{phase}_s")
        return float(lo), float(hi)

    def soms_params(self) -> FrontBlock:
        """The agent's front end (its ``soms``), stepped every ``soms_step_s``."""
        return replace(self.agent.soms, dt=self.soms_step_s)

    def second_params(self) -> FrontBlock | None:
        """The second agent's front end at the same step, or None."""
        if self.second_agent is None:
            return None
        return replace(self.second_agent.soms, dt=self.soms_step_s)

    @property
    def windows_per_step(self) -> int:
        return round(self.soms_step_s / self.window_s)


# ----------------------------------------------------------------------------------------
# The speeds and the schedule (pure)


def image_speeds(
    scene: SceneConfig, shake: Shake, camera_forward_m: float = 0.0
) -> tuple[float, float]:
    """(hand, shake) image speeds at the sensor centre, px/s: the hand's ``f · v / d``
    (its constant speed across the view at depth ``d`` ahead of the camera, which sits
    ``camera_forward_m`` ahead of the hinge: the env's ``PTUParams``; pinhole, so the
    same at every pixel) and the shake's ``f · ω``, with ``f`` the focal length.

    >>> from wander_env.scenes import load_scene_config
    >>> hand, shake = image_speeds(load_scene_config("hand"), Shake())
    >>> round(hand, 1), round(shake, 2)
    (170.0, 13.98)
    """
    (obj,) = scene.moving_objects
    tr = obj.trajectory
    if not isinstance(tr, LinearBounceParams) or tr.velocity[0] != 0:
        raise ValueError("the hand must move across the view: linear_bounce with velocity x 0")
    f = focal_length_px(scene.camera.width, scene.camera.hfov_deg)
    depth = tr.start[0] - scene.ptu.position[0] - camera_forward_m
    hand = f * math.hypot(tr.velocity[1], tr.velocity[2]) / depth
    return hand, f * math.radians(shake.speed_deg_s)


def schedule(cfg: EventSuppressionConfig, seed: int) -> tuple[Segment, ...]:
    """The trial's phases: :data:`PHASES` in an order drawn from ``seed``, each of a length
    drawn uniformly from its range and rounded to whole sOMS steps (at least one).

    >>> [s.phase for s in schedule(EventSuppressionConfig(), 0)]
    ['shake', 'both', 'hand', 'pause']
    """
    rng = np.random.default_rng([seed, 25])
    order = rng.permutation(len(PHASES))
    step = cfg.soms_step_s
    out = []
    for i in order:
        lo, hi = cfg.phase_range(PHASES[i])
        n = max(1, round(rng.uniform(lo, hi) / step))
        out.append(Segment(PHASES[i], round(n * step, 9)))
    return tuple(out)


# ----------------------------------------------------------------------------------------
# The trial


def record(cfg: EventSuppressionConfig, phase: str, seed: int) -> Recording:
    """Record the row of ``phase`` of the trial of ``seed`` (module docstring): the env
    reset at the shake's start gaze and stepped a window at a time under
    :class:`ShakeScript`, watched by :class:`WindowRecorder`."""
    sched = schedule(cfg, seed)
    segs, shake0, hand0 = recording(sched, phase, cfg.lead_s)
    clocks = PhaseClock(segs, SHAKE_PHASES, shake0), PhaseClock(segs, HAND_PHASES, hand0)
    start, sense = shake_start(seed)
    duration = sum(s.length_s for s in segs)
    n = round(duration / cfg.window_s)
    env = trial_env(cfg.env, control_period_s=cfg.window_s, episode_seconds=duration + 1.0)
    base = env.unwrapped
    scale = 1.0
    if cfg.hand_ratio is not None:
        hand, shake = image_speeds(base.scene, cfg.shake, base.config.ptu.camera_forward_m)
        scale = cfg.hand_ratio * shake / hand
    windows = WindowRecorder(n, base.height, base.width)
    try:
        gaze0 = cfg.shake.angles(shake0, start, sense)
        policy = ShakeScript(env, cfg.shake, cfg.window_s, clocks, scale, start, sense)
        run_episode(env, policy, n, (windows,), seed=seed, options={"gaze_deg": gaze0})
    finally:
        env.close()
    return windows.recording


def phase_row(
    cfg: EventSuppressionConfig, phase: str, seed: int, rec: Recording, soms: FrontBlock
) -> dict[str, Any]:
    """The figures of the row of ``phase`` of the trial of ``seed`` from its recording,
    with the sOMS ``soms``; the gaze and the hand's image centre as artifacts."""
    sched = schedule(cfg, seed)
    index = [s.phase for s in sched].index(phase)
    lead = round(cfg.lead_s / cfg.window_s)
    row = score(
        rec.counts,
        rec.masks,
        map_model(soms, *rec.counts.shape[-2:]),
        cfg.windows_per_step,
        round(cfg.lead_s / cfg.soms_step_s),
        phase in HAND_PHASES,
        cfg.hit_sigma_px,
        cfg.hand_margin_px,
    )
    return {
        "phase_index": index,
        "phase_s": sched[index].length_s,
        "simulated_s": len(rec.counts) * cfg.window_s,  # the lead-in and the phase
        **row,
        "_gaze": rec.gaze[lead:],
        "_hand_px": rec.hand_px[lead:],
    }


def run_trial(cfg: EventSuppressionConfig, spec: study.TrialSpec) -> dict[str, Any]:
    """The row of phase ``spec.params["phase"]`` of the trial of ``spec.seed``; with a
    ``second_agent``, its figures on the same windows in ``second:`` columns."""
    phase = str(spec.params["phase"])
    rec = record(cfg, phase, spec.seed)
    row = phase_row(cfg, phase, spec.seed, rec, cfg.soms_params())
    second = cfg.second_params()
    if second is not None:
        other = phase_row(cfg, phase, spec.seed, rec, second)
        row |= {
            f"second:{k}": v
            for k, v in other.items()
            if not k.startswith("_") and k not in ("phase_index", "phase_s")
        }
    return row


def grid(cfg: EventSuppressionConfig) -> list[dict[str, Any]]:
    return [{"phase": p} for p in cfg.phases]


# ----------------------------------------------------------------------------------------
# The table and the figure


def _ci(values: Sequence[float]) -> str:
    """A percentage over trials with its 95 % bootstrap interval (:func:`ci_text`)."""
    return ci_text(mean_ci(values), ".1f", " %")


def _windows(rows: Sequence[study.Row], what: str) -> tuple[float, float]:
    """Mean ± std per window of ``what`` (events_in / events_out) pooled over ``rows``."""
    return pooled_mean_std(
        np.array([float(r[f"{what}_mean"]) for r in rows]),
        np.array([float(r[f"{what}_std"]) for r in rows]),
        np.array([int(r["windows"]) for r in rows]),
    )


def compare(cfg: EventSuppressionConfig, rows: list[study.Row]) -> list[study.Comparison]:
    """The paper's Table beside ours: over whole trials, then per phase (windows pooled
    over trials; fractions as the mean over trials with a 95 % bootstrap interval)."""
    ref = PAPER_SUPPRESSION
    w = f"{cfg.window_s * 1000:g} ms"
    trials = trial_figures(rows)
    seeds = sorted(trials)

    def col(name: str) -> list[float]:
        return [trials[s][name] for s in seeds]

    mi, si = _windows(rows, "events_in")
    mo, so = _windows(rows, "events_out")
    moving = [r for r in rows if r["phase"] in HAND_PHASES]
    hits, steps = sum(int(r["hand_hits"]) for r in moving), sum(int(r["hit_steps"]) for r in moving)
    lo, hi = wilson_interval(hits, steps)
    out = [
        study.Comparison("trials", "10", str(len(seeds)), f"phases {', '.join(cfg.phases)}"),
        study.Comparison(
            f"events in per {w}",
            f"{ref['events_in_mean']} ± {ref['events_in_std']}",
            f"{mi:.1f} ± {si:.1f}",
            "all windows of all rows; ours a simulated 128×128 scene, theirs a Speck",
        ),
        study.Comparison(
            f"sOMS events out per {w}",
            f"{ref['events_out_mean']} ± {ref['events_out_std']}",
            f"{mo:.1f} ± {so:.1f}",
        ),
        study.Comparison(
            "events suppressed",
            f"{ref['suppressed_pct']} %",
            _ci(col("suppressed")),
            f"over a trial, mean over trials; bar: ≥ {HAND_BARS['suppressed']:g} % "
            "(85 ± 10 % or above)",
        ),
        study.Comparison(
            "hand hit, hand-moving phases (8×8 box around the OMS map's densest point)",
            "—",
            f"{_ci(col('hit'))}; pooled {100 * hits / steps if steps else math.nan:.1f} % of "
            f"{steps} sOMS steps (Wilson {100 * lo:.1f}–{100 * hi:.1f} %)",
            f"bar: ≥ {HAND_BARS['hit']:g} %",
        ),
        study.Comparison(
            "shake-only events suppressed",
            "—",
            _ci(col("shake_suppressed")),
            f"bar: ≥ {HAND_BARS['shake_suppressed']:g} %",
        ),
        study.Comparison(
            "hand's events kept / background's kept, hand-moving phases",
            "—",
            f"{_ci(col('hand_kept'))} / {_ci(col('background_kept'))}",
            f"bar: hand ≥ {HAND_BARS['hand_kept']:g} %; ground-truth mask, the paper cannot "
            "measure this",
        ),
    ]
    for phase in cfg.phases:
        mine = [r for r in rows if r["phase"] == phase]
        pi, psi = _windows(mine, "events_in")
        po, pso = _windows(mine, "events_out")
        parts = [
            f"in {pi:.1f} ± {psi:.1f}, out {po:.1f} ± {pso:.1f} per {w}",
            f"suppressed {_ci([float(r['suppressed_pct']) for r in mine])}",
            f"hand kept {_ci([float(r['object_kept_pct']) for r in mine])}",
            f"background kept {_ci([float(r['background_kept_pct']) for r in mine])}",
        ]
        if phase in HAND_PHASES:
            parts.append(f"hit {_ci([float(r['hand_hit_pct']) for r in mine])}")
        out.append(
            study.Comparison(f"phase `{phase}`", "—", "; ".join(parts), f"{len(mine)} trials")
        )
    return out


PHASE_COLOURS = {"shake": "tab:orange", "hand": "tab:green", "both": "tab:purple", "pause": "0.8"}


def soms_label(sp: FrontBlock) -> str:
    """Which sOMS: the agent's, the paper-literal one, the Speck front end, or another
    block."""
    if isinstance(sp, SpeckFrontParams):
        return "front end on Speck's cores (int8 DoG, IAF)"
    if same_but_step(sp, AGENT_SOMS):
        return f"agent's sOMS ({sp.norm} norm, α {sp.alpha:g})"
    if same_but_step(sp, SOMSParams()):
        return f"paper-literal sOMS (min-max, α {sp.alpha:g})"
    return f"sOMS ({sp.norm} norm, α {sp.alpha:g})"


def plot(
    cfg: EventSuppressionConfig, rows: list[study.Row], results_dir: Path, fig_dir: Path
) -> list[Path]:
    """The paper's Figure: events in (red) and out (blue) per window over the first
    trial, its phases shaded; beside it, per phase over all trials, the events
    suppressed, the hand's and the background's kept and the hand hit with 95 %
    intervals."""
    plt = pyplot()
    from matplotlib.patches import Patch

    fig, axes = plt.subplots(1, 2, figsize=(13, 4.2), gridspec_kw={"width_ratios": [2.2, 1]})
    ax = axes[0]
    first = sorted((r for r in rows if int(r["repeat"]) == 0), key=lambda r: int(r["phase_index"]))
    t0 = 0.0
    for r in first:
        arts = study.load_artifacts(results_dir, r)
        n = len(arts.get("events_in", ()))
        t = t0 + (np.arange(n) + 1) * cfg.window_s
        ax.axvspan(
            t0, t0 + n * cfg.window_s, color=PHASE_COLOURS[str(r["phase"])], alpha=0.25, lw=0
        )
        if n:
            ax.plot(t, arts["events_in"], color="tab:red", lw=0.7)
            ax.plot(t, arts["events_out"], color="tab:blue", lw=0.7)
        t0 += n * cfg.window_s
    handles = [
        plt.Line2D([], [], color="tab:red", label="DVS events (in)"),
        plt.Line2D([], [], color="tab:blue", label="sOMS events (out)"),
    ] + [Patch(color=PHASE_COLOURS[p], alpha=0.25, label=f"phase: {p}") for p in PHASES]
    ax.legend(handles=handles, fontsize=7, loc="upper right", ncol=2)
    ax.set(
        xlabel="time in the trial (s; each phase after its 0.1 s lead-in)",
        ylabel=f"events per {cfg.window_s * 1000:g} ms window",
        title=f"trial 0 (seed {first[0]['seed'] if first else '-'})",
        xlim=(0, max(t0, cfg.window_s)),
    )
    ax = axes[1]
    names = [
        ("suppressed_pct", "suppressed"),
        ("object_kept_pct", "hand kept"),
        ("background_kept_pct", "background kept"),
        ("hand_hit_pct", "hand hit"),
    ]
    x = np.arange(len(cfg.phases))
    width = 0.8 / len(names)
    for j, (key, label) in enumerate(names):
        means, errs = [], [[], []]
        for phase in cfg.phases:
            m, lo, hi, _ = mean_ci([float(r[key]) for r in rows if r["phase"] == phase])
            means.append(m)
            errs[0].append(m - lo if math.isfinite(lo) else 0.0)
            errs[1].append(hi - m if math.isfinite(hi) else 0.0)
        ax.bar(x + (j - 1.5) * width, means, width, yerr=errs, capsize=2, label=label)
    for i, phase in enumerate(cfg.phases):
        if phase not in HAND_PHASES:  # the hand holds still: no hit is scored
            ax.text(x[i] + 1.5 * width, 22, "no hit:\nhand still", fontsize=6, ha="center")
    ax.axhline(
        PAPER_SUPPRESSION["suppressed_pct"],
        color="k",
        ls="--",
        lw=1,
        label="paper: 85.16 % suppressed",
    )
    ax.set_xticks(x, cfg.phases)
    ax.set(ylim=(0, 105), ylabel="% (mean over trials, 95 % interval)", xlabel="phase")
    ax.set_title(f"per phase, {len({r['seed'] for r in rows})} trials", fontsize=9)
    ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.16), ncol=3)
    fig.suptitle(
        f"Event suppression by the {soms_label(cfg.soms_params())}: the hand scene, shake "
        f"±{cfg.shake.amplitude_deg:g}° at {cfg.shake.speed_deg_s:g}°/s, events per "
        f"{cfg.window_s * 1000:g} ms",
        fontsize=10,
    )
    path = save_figure(fig, fig_dir / "event_suppression.png")
    return [path]


EXPERIMENT = study.Experiment(
    name="event_suppression",
    description=(
        "Events per 2 ms before and after the sOMS in the hand scene, per phase: the camera "
        "shaken, a hand waving, both, a pause (paper: 85.16 % suppressed)."
    ),
    config_type=EventSuppressionConfig,
    grid=grid,
    run_trial=run_trial,
    plot=plot,
    compare=compare,
)
