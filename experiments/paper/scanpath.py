"""Scanpaths of the attention agent: the paper's "saccades" vs "fixational" conditions.

The paper (§"evaluating the scanpath") ran its model on iCub recordings of objects on a
shelf, the eyes making fixational movements throughout, in two conditions:

- ``saccades``: no time for spatiotemporal integration, maps and a saccade every
  ``t_w = 10 ms``;
- ``fixational``: ``t_w = St_w = 124 ms`` (the demonstrator's latency);

and showed (figure only) that the fixational condition detects objects while the
saccade condition makes "random saccadic jumps to non-informative locations".

Here the closed loop (:func:`experiments.jobs.run_agent.closed_loop_metrics`) runs the agent for
``duration_s`` in the ``shelf`` (static) and ``office`` (two moving objects) scenes, in
both conditions. As in the paper's recordings the fixational random walk goes on in both
conditions (``saccades_fixational``; set it false for a saccade condition without any
fixational movement — in a static scene that camera never sees an event and never
moves). Per trial:

- the scanpath: the agent's fixation windows merged into fixations (the windows between
  two saccades, :func:`~experiments.analysis.scanpath_stats.merge_windows`), its
  saccades, and the saliency maps of its decisions put together on the pan-tilt sphere
  (:func:`experiments.jobs.scanpath_figure.saliency_mosaic`);
- statistics (:func:`experiments.analysis.scanpath_stats.scanpath_summary`, as in
  ``wander run``'s ``metrics.json``): fixation count and duration, saccade amplitude
  (reached minus start gaze), revisits and coverage (within
  ``radius_deg``), and the **object hit rate**: the fraction of the salient points
  ``P`` that lie on an object of the scene — static or moving, not walls, floor or
  furniture — found by casting ``P``'s pixel ray into the scene at the decision
  (:func:`wander_env.camera.cast_pixel`); ``object_hit_rate_box`` counts ``P``
  whose ``box``×``box`` square (the paper's detection box) sees an object; in scenes with
  moving objects the run's detection accuracy (the box touches a moving object's mask)
  too;
- the areas of interest: per decision the scene object under the fovea (ray cast by
  :class:`~experiments.paper.scanpath_recorder.ScanpathRecorder`), per fixation its most
  frequent one (``aois_json``; ``-`` = none), their stationary and transition entropy;
  objects are named as in the scene file (static and moving alike, e.g. ``mug``,
  ``cube``, ``beach_ball``); the fixation table itself rides in the row
  (``scanpath_json``);
- over the repeats (``repeats`` = 10 seeds, paired across conditions):
  :mod:`experiments.paper.scanpath_analysis` — bootstrap 95 % intervals per cell, the
  fixational − saccades differences tested (permutation test, d_z, rank-biserial),
  MultiMatch and AOI-string (Levenshtein) similarity within and between conditions;
- the fixation table for scanpath-comparison tools (MultiMatch, ScanMatch), written by
  :func:`plot` as ``fixations/<scene>_<condition>_seed<N>.csv`` in the result folder:
  the columns, units and signs of :mod:`experiments.analysis.scanpath_stats` (``pan_deg``,
  ``tilt_deg``: + = left, up; ``t_start_s``, ``duration_s``) and each fixation's
  ``aoi``.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np

import wander_env  # noqa: F401  (registers the environments, picks the GL backend)
from agents.attention import AgentParams, AttentionAgent
from agents.fixation import FIXATION_WINDOW_S
from experiments.analysis import scanpath_stats
from experiments.analysis.stats import ci_text, mean_std
from experiments.jobs.run_agent import closed_loop_metrics, scanpath_tables
from experiments.jobs.scanpath_figure import (
    limits_box,
    saliency_mosaic,
    show_mosaic,
)
from experiments.paper.env_block import check_env_block, trial_env
from experiments.paper.scanpath_recorder import ScanpathRecorder
from experiments.runs.tables import write_csv
from experiments.studies import framework as study
from wander_env.camera import (
    SPECK_HFOV_DEG,
    focal_length_px,
    pixel_to_world_angles,
    principal_point,
)
from wander_env.env_config import SceneName, WanderConfig
from wander_env.viz import pyplot, save_figure

__all__ = [
    "EXPERIMENT",
    "ScanpathConfig",
    "agent_params",
]

Condition = Literal["saccades", "fixational"]


#: The env fields each trial sets (what sets them): the block leaves them at defaults.
ENV_SET_PER_TRIAL = {"scene": "scenes", "episode_seconds": "duration_s"}


@dataclass(frozen=True)
class ScanpathConfig:
    """Defaults: the paper's two windows (10 ms, 124 ms) and 8×8 box, the shelf scene;
    the office scene, trial length, radii and DVS preset are ours. ``env`` is the env's
    block; each trial sets its scene and length (:data:`ENV_SET_PER_TRIAL`)."""

    scenes: tuple[SceneName, ...] = ("shelf", "office")
    conditions: tuple[Condition, ...] = ("saccades", "fixational")
    duration_s: study.TrialSeconds = 5.0
    saccades_window_s: float = 0.01
    fixational_window_s: float = FIXATION_WINDOW_S
    saccades_fixational: bool = True
    repeats: study.Repeats = 10
    box: int = 8
    radius_deg: study.RadiusDeg = 5.0
    mosaic_step_deg: study.GridStepDeg = 0.5
    env: WanderConfig = field(default_factory=WanderConfig)
    agent: AgentParams = field(default_factory=AgentParams)
    # MultiMatch normalises lengths and positions by a "screen": the camera's field of
    # view (degrees; Speck's 112.8° both ways by default).
    multimatch_screen_deg: tuple[float, float] = (SPECK_HFOV_DEG, SPECK_HFOV_DEG)

    def __post_init__(self) -> None:
        check_env_block(self.env, ENV_SET_PER_TRIAL)
        self.agent.check_env_fields()  # the env's camera, PTU and step are the agent's
        if not self.duration_s > 0:
            raise ValueError(f"duration_s must be > 0, got {self.duration_s}")
        study.check_lists(self, ("scenes", "conditions"))
        for name in ("saccades_window_s", "fixational_window_s"):
            v = getattr(self, name)
            if not v >= 0.01 - 1e-12:
                raise ValueError(f"{name} must be >= the 10 ms env step, got {v}")
        if self.repeats < 1:
            raise ValueError(f"repeats must be >= 1, got {self.repeats}")
        if self.box < 1:
            raise ValueError(f"box must be >= 1, got {self.box}")
        for name in ("radius_deg", "mosaic_step_deg"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name} must be > 0, got {getattr(self, name)}")
        if len(self.multimatch_screen_deg) != 2 or not all(
            math.isfinite(v) and v > 0 for v in self.multimatch_screen_deg
        ):
            raise ValueError(
                f"multimatch_screen_deg must be two angles > 0, got {self.multimatch_screen_deg}"
            )


# ----------------------------------------------------------------------------------------
# Pure helpers


def _export_name(row: study.Row) -> str:
    return f"{row['scene']}_{row['condition']}_seed{row['seed']}.csv"


# ----------------------------------------------------------------------------------------
# The agent of a condition


def agent_params(cfg: ScanpathConfig, condition: str, env: Any) -> AgentParams:
    """The agent of a condition: the config's ``agent`` block with the condition's window
    and whether the fixational walk runs."""
    if condition == "saccades":
        return cfg.agent.on_env(
            env, window_s=cfg.saccades_window_s, fixational=cfg.saccades_fixational
        )
    if condition == "fixational":
        return cfg.agent.on_env(env, window_s=cfg.fixational_window_s, fixational=True)
    raise ValueError(f"unknown condition {condition!r}; expected 'saccades' or 'fixational'")


# ----------------------------------------------------------------------------------------
# The trial


def run_trial(cfg: ScanpathConfig, spec: study.TrialSpec) -> dict[str, Any]:
    """One scene / condition: the closed loop for ``duration_s``, then the statistics."""
    scene, condition = str(spec.params["scene"]), str(spec.params["condition"])
    env = trial_env(cfg.env, scene=scene, episode_seconds=cfg.duration_s + 1.0)
    agent = AttentionAgent(agent_params(cfg, condition, env), seed=spec.seed)
    watch = ScanpathRecorder(env, cfg.box)
    try:
        m = closed_loop_metrics(env, agent, cfg.duration_s, spec.seed, recorders=(watch,))
    finally:
        agent.close()
        env.close()
    p = agent.params
    f = focal_length_px(p.width_px, p.hfov_deg)
    centre = principal_point(p.width_px, p.height_px)
    fx = agent.fixations
    windows, ends, saccades = scanpath_tables(agent)
    table = scanpath_stats.merged_fixations(windows, ends)
    aois = scanpath_stats.fixation_aois(watch.fovea_labels, ends)
    hits = [bool(centre) for centre, _ in watch.labels]
    box_hits = [bool(box) for _, box in watch.labels]
    targets = np.array(
        [
            pixel_to_world_angles(w.target_px, g, f, centre)
            for w, g in zip(fx, watch.map_gazes, strict=True)
            if w.target_px is not None
        ],
        dtype=np.float64,
    ).reshape(-1, 2)
    out: dict[str, Any] = {
        "decisions": len(fx),
        "decisions_with_target": len(watch.labels),
        **scanpath_stats.scanpath_summary(windows, ends, saccades, cfg.radius_deg),
        "saccades": len(agent.saccades),
        "object_hit_rate": float(np.mean(hits)) if hits else math.nan,
        "object_hit_rate_box": float(np.mean(box_hits)) if box_hits else math.nan,
        "objects_visited": len({name for name, _ in watch.labels if name}),
        "aois_visited": len(set(aois) - {scanpath_stats.BACKGROUND}),
        "aoi_stationary_entropy": scanpath_stats.stationary_entropy(aois),
        "aoi_transition_entropy": scanpath_stats.transition_entropy(aois),
        "detection_accuracy_moving": m["detection_accuracy"],
        "simulated_s": m["simulated_s"],
        "events_per_s": m["events"] / m["simulated_s"],
        "soms_suppression": m["soms_suppression"],
        # The scanpath itself, for the pairwise comparisons and the user's own analysis.
        "scanpath_json": json.dumps(table.tolist()),
        "aois_json": json.dumps(aois),
        "_fixations": table,
        "_targets_deg": targets,
        "_target_hits": np.array(hits, dtype=bool),
    }
    if watch.maps:
        grid_ = saliency_mosaic(watch.maps, watch.map_gazes, f, cfg.mosaic_step_deg)
        out |= {
            "_mosaic_pan": grid_.pan,
            "_mosaic_tilt": grid_.tilt,
            "_mosaic": grid_.values.astype(np.float32),
        }
    return out


def grid(cfg: ScanpathConfig) -> list[dict[str, Any]]:
    return [{"scene": s, "condition": c} for s in cfg.scenes for c in cfg.conditions]


# ----------------------------------------------------------------------------------------
# Summary, exports and plots


def _by(rows: list[study.Row], scene: str, condition: str, metric: str) -> tuple[float, float]:
    return mean_std(
        float(r[metric]) for r in rows if r["scene"] == scene and r["condition"] == condition
    )


def _metrics(cfg: ScanpathConfig) -> list[tuple[str, str, str]]:
    """(label, column, format) of the per-trial measures summarised and tested."""
    return [
        ("object hit rate", "object_hit_rate", ".0%"),
        (f"object hit rate, {cfg.box}×{cfg.box} box", "object_hit_rate_box", ".0%"),
        ("moving-object detection accuracy", "detection_accuracy_moving", ".0%"),
        ("objects visited", "objects_visited", ".1f"),
        ("fixations", "fixations", ".1f"),
        ("fixation duration (s)", "fixation_duration_mean_s", ".3f"),
        ("saccade amplitude (°)", "saccade_amplitude_mean_deg", ".1f"),
        ("revisits", "revisits", ".1f"),
        (f"coverage (deg², {cfg.radius_deg:g}° radius)", "coverage_deg2", ".0f"),
        ("AOI stationary entropy (normalised)", "aoi_stationary_entropy", ".2f"),
        ("AOI transition entropy (normalised)", "aoi_transition_entropy", ".2f"),
    ]


# The paper's statements (its scanpath result is a figure, no numbers).
PAPER_SCANPATH = {
    "object_hit_rate": (
        "fixational: salient points on the objects; saccades: random jumps to "
        "non-informative locations (figure, no numbers)"
    ),
    "stability": "fixational eye movements are needed for stable scanpaths (figure)",
}


def compare(cfg: ScanpathConfig, rows: list[study.Row]) -> list[study.Comparison]:
    """Per scene and measure: each condition's mean over the repeats with its bootstrap
    95 % interval, and the fixational − saccades difference tested (paired by seed:
    permutation test, d_z, rank-biserial); then the MultiMatch / AOI-string similarity
    within and between the conditions, and whether the fixational scanpaths are the more
    repeatable (:mod:`experiments.paper.scanpath_analysis`)."""
    from experiments.paper import scanpath_analysis as sa

    scenes = list(dict.fromkeys(str(r["scene"]) for r in rows))
    conditions = list(dict.fromkeys(str(r["condition"]) for r in rows))
    metrics = _metrics(cfg)
    summ = sa.cell_summaries(rows, [k for _, k, _ in metrics])
    tests = sa.condition_tests(rows, [k for _, k, _ in metrics])
    per = f"{cfg.duration_s:g} s per trial"
    out = []
    for s in scenes:
        for label, key, fmt in metrics:
            parts = [f"{c} {ci_text(summ[(s, c, key)], fmt)}" for c in conditions]
            t = tests.get((s, key))
            note = f"fixational − saccades: {t.text('.3g')}; {per}" if t is not None else per
            out.append(
                study.Comparison(
                    f"{s}: {label}", PAPER_SCANPATH.get(key, "—"), " / ".join(parts), note
                )
            )
    if any("scanpath_json" in r for r in rows):
        screen = tuple(cfg.multimatch_screen_deg)
        for t in sa.similarity_table(rows, screen):
            parts = [
                f"{k} {ci_text((t[k], t[k + '_low'], t[k + '_high'], t[k + '_n']), '.3f')}"
                for k in sa.SIMILARITY_MEASURES
            ]
            n = max(t[k + "_n"] for k in sa.SIMILARITY_MEASURES)
            out.append(
                study.Comparison(
                    f"{t['scene']}: MultiMatch, {t['group']}",
                    "—",
                    "; ".join(parts),
                    f"mean over {n} pairs of trials (pairs share trials: descriptive)",
                )
            )
        for (s, k), c in sa.stability_tests(rows, screen).items():
            out.append(
                study.Comparison(
                    f"{s}: repeatability ({k} similarity to the other seeds)",
                    PAPER_SCANPATH["stability"],
                    f"fixational − saccades: {c.text('.3f')}",
                    "per trial its mean similarity within its condition, paired by seed",
                )
            )
    return out


def plot(
    cfg: ScanpathConfig, rows: list[study.Row], results_dir: Path, fig_dir: Path
) -> list[Path]:
    """The scanpath figure (a panel per scene and condition: the saliency mosaic, the
    fixations sized by duration, the saccade lines, the salient points green on an
    object, red off), a bar chart of the statistics, and the fixation tables
    ``results_dir/fixations/*.csv`` (:func:`experiments.analysis.scanpath_stats.fixation_rows`,
    with each fixation's ``aoi``)."""
    plt = pyplot()

    scenes = list(dict.fromkeys(str(r["scene"]) for r in rows))
    conditions = list(dict.fromkeys(str(r["condition"]) for r in rows))
    firsts = {}
    for r in rows:
        firsts.setdefault((str(r["scene"]), str(r["condition"])), r)
        arts = study.load_artifacts(results_dir, r)
        if "fixations" in arts:
            aois = {"aoi": json.loads(str(r["aois_json"]))}
            columns, table = scanpath_stats.fixation_rows(arts["fixations"], aois)
            write_csv(table, results_dir / "fixations" / _export_name(r), columns=columns)
    from wander_env.ptu.params import PTUParams  # the env's unit (the trials use its default)

    unit = PTUParams()
    limits = (unit.pan_limits_deg, unit.tilt_limits_deg)
    fig, axes = plt.subplots(
        len(scenes),
        len(conditions),
        figsize=(5.2 * len(conditions), 4.4 * len(scenes)),
        squeeze=False,
    )
    for i, s in enumerate(scenes):
        for j, c in enumerate(conditions):
            ax = axes[i, j]
            r = firsts.get((s, c))
            arts = study.load_artifacts(results_dir, r) if r is not None else {}
            _draw_scanpath(ax, arts, limits)
            title = f"{s}, {c}"
            if r is not None:
                title += f" (seed {r['seed']}): hit rate {float(r['object_hit_rate']):.0%}"
            ax.set_title(title, fontsize=9)
    fig.suptitle(
        "Scanpaths on the pan-tilt sphere, the first seed of each cell "
        f"({cfg.duration_s:g} s of simulated time each)\nsaliency mosaic (max over "
        "fixations, each map / its peak, 0 black … 1 bright), fixations sized by duration",
        fontsize=10,
    )
    path = save_figure(fig, fig_dir / "scanpath.png")

    stats_path = plot_statistics(cfg, rows, fig_dir / "scanpath_stats.png")
    return [path, stats_path]


def _stat_panels(cfg: ScanpathConfig) -> list[tuple[str, str]]:
    """(column, label with units) of the statistics figure's panels."""
    per = f"per {cfg.duration_s:g} s trial"
    return [
        ("object_hit_rate", "object hit rate (fraction of P)"),
        ("fixations", f"fixations ({per})"),
        ("fixation_duration_mean_s", "fixation duration, mean (s)"),
        ("saccade_amplitude_mean_deg", "saccade amplitude, mean (°)"),
        ("revisits", f"revisits within {cfg.radius_deg:g}° ({per})"),
        ("coverage_deg2", f"coverage (deg², {cfg.radius_deg:g}° radius)"),
    ]


def bar_intervals(
    rows: list[study.Row], scenes: Sequence[str], condition: str, key: str
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(means, lower, upper error-bar lengths) of ``key`` per scene for one condition:
    the mean over the repeats and its bootstrap 95 % interval
    (:func:`experiments.paper.scanpath_analysis.cell_summaries`); NaN where undefined.

    >>> rows = [{"scene": "s", "condition": "c", "seed": k, "v": float(k)} for k in (1, 1, 1)]
    >>> [a.tolist() for a in bar_intervals(rows, ["s"], "c", "v")]
    [[1.0], [0.0], [0.0]]
    """
    from experiments.paper.scanpath_analysis import cell_summaries

    summ = cell_summaries([r for r in rows if str(r["condition"]) == condition], [key])
    stats = [summ.get((s, condition, key), (math.nan,) * 3 + (0,)) for s in scenes]
    m = np.array([v[0] for v in stats], float)
    return m, m - np.array([v[1] for v in stats], float), np.array([v[2] for v in stats]) - m


def plot_statistics(cfg: ScanpathConfig, rows: list[study.Row], path: Path) -> Path:
    """Bars of the per-trial statistics per scene and condition: the mean over the
    repeats with its bootstrap 95 % interval, and on the hit-rate panel the
    fixational − saccades test (paired by seed: permutation p, d_z)."""
    plt = pyplot()

    from experiments.paper.scanpath_analysis import cells, condition_tests

    scenes = list(dict.fromkeys(str(r["scene"]) for r in rows))
    conditions = list(dict.fromkeys(str(r["condition"]) for r in rows))
    panels = _stat_panels(cfg)
    tests = condition_tests(rows, ["object_hit_rate"])
    fig, axes = plt.subplots(1, len(panels), figsize=(3.1 * len(panels), 3.6), squeeze=False)
    x = np.arange(len(scenes))
    width = 0.8 / max(len(conditions), 1)
    for ax, (key, label) in zip(axes[0], panels, strict=True):
        for j, c in enumerate(conditions):
            m, lo, hi = bar_intervals(rows, scenes, c, key)
            offset = (j - (len(conditions) - 1) / 2) * width
            ax.bar(x + offset, np.nan_to_num(m), width, color=f"C{j}", label=c)
            ok = np.isfinite(lo) & np.isfinite(hi)
            if ok.any():
                ax.errorbar(
                    (x + offset)[ok],
                    m[ok],
                    yerr=[lo[ok], hi[ok]],
                    fmt="none",
                    ecolor="k",
                    capsize=3,
                    lw=1,
                )
        ax.set_xticks(x, scenes)
        ax.set_title(label, fontsize=8.5)
        ax.set_ylim(bottom=0.0)  # every statistic here is >= 0
        if ax.get_ylim()[1] <= 0.0:
            ax.set_ylim(0.0, 1.0)
        if key == "object_hit_rate":
            ax.set_ylim(0.0, 1.25)
            for i, s in enumerate(scenes):
                t = tests.get((s, key))
                if t is not None and t.n >= 2 and math.isfinite(t.p_value):
                    text = f"fix − sac: Δ = {t.mean_diff:+.2f}\np = {t.p_value:.2g}, d_z = "
                    text += f"{t.effect_d:.2f}" if math.isfinite(t.effect_d) else "—"
                    ax.text(i, 1.03, text, ha="center", va="bottom", fontsize=6.5)
    handles, labels = axes[0, 0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="upper right", ncol=len(conditions), fontsize=8)
    n = max((len(v) for v in cells(rows).values()), default=0)
    fig.suptitle(
        f"Scanpath statistics per scene and condition: mean over {n} seeded repeat"
        f"{'s' if n != 1 else ''} ({cfg.duration_s:g} s each), error bars the bootstrap "
        f"95 % interval ({len(rows)} trials)",
        fontsize=10,
        x=0.4,
    )
    return save_figure(fig, path, rect=(0.0, 0.0, 1.0, 0.93))


def _draw_scanpath(
    ax: Any,
    arts: dict[str, Any],
    limits_deg: tuple[tuple[float, float], tuple[float, float]] | None = None,
) -> None:
    """One scanpath panel: the mosaic, fixations, saccades, the salient points and (given
    ``limits_deg``, the PTU's pan and tilt ranges of the gaze) a dashed box of the reach."""

    if "mosaic" in arts:
        pan, tilt = arts["mosaic_pan"], arts["mosaic_tilt"]
        show_mosaic(ax, arts["mosaic"], pan, tilt, "saliency (normalised)", fontsize=7)
    fx = arts.get("fixations", np.zeros((0, 4)))
    if len(fx):
        ax.plot(fx[:, 0], fx[:, 1], "-", color="gold", lw=1.2, label="saccades")
        sizes = 15 + 150 * fx[:, 3]
        ax.scatter(
            fx[:, 0], fx[:, 1], s=sizes, c="cyan", edgecolors="k", zorder=3, label="fixations"
        )
    tg, hits = arts.get("targets_deg", np.zeros((0, 2))), arts.get("target_hits", np.zeros(0))
    if len(tg):
        hits = np.asarray(hits, bool)
        for sel, colour, label in ((hits, "lime", "P on an object"), (~hits, "red", "P elsewhere")):
            if sel.any():
                label += f" ({int(sel.sum())})"
                ax.scatter(
                    tg[sel, 0], tg[sel, 1], marker="x", c=colour, s=25, zorder=4, label=label
                )
    if limits_deg is not None:
        x0, x1 = ax.get_xlim()
        y0, y1 = ax.get_ylim()
        ax.add_patch(limits_box(limits_deg, "0.75", "PTU reach of the gaze"))
        ax.set_xlim(x0, x1)  # the box may be larger than the mosaic: keep the view
        ax.set_ylim(y0, y1)
    ax.invert_xaxis()  # positive pan turns left
    ax.set_xlabel("pan (°, + = left)")
    ax.set_ylabel("tilt (°, + = up)")
    ax.legend(loc="lower right", fontsize=6)


EXPERIMENT = study.Experiment(
    name="scanpath",
    description=(
        "Scanpaths of the closed-loop agent in the shelf and office scenes, the paper's "
        "'saccades' (t_w = 10 ms) vs 'fixational' (t_w = St_w = 124 ms) conditions: fixations, "
        "saccade amplitudes, object hit rate, revisits, coverage; fixation tables for "
        "scanpath-comparison tools."
    ),
    config_type=ScanpathConfig,
    grid=grid,
    run_trial=run_trial,
    plot=plot,
    compare=compare,
)
