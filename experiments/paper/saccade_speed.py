"""Saccade and fixational speeds: what the PTU's limits and the eye movements cost.

The paper leaves this as future work ("the investigation of saccades and fixational eye
speeds, exploring the limits of the system and the PTU"); its numbers are the FLIR
defaults and the fixational walk (N = 8 steps of up to ±60 positions in St_w = 124 ms).

One factor at a time around that baseline (:func:`grid`): the PTU's slew speed and
acceleration (positions/s, /s²; 0.025714° each), the fixational step amplitude
(``max_step_pos``) and count (``n_steps``), and the speed of the scene's moving objects
(their trajectories run ``object_speed_scale`` times faster, :class:`ScaledTrajectory`).
Each trial:

- runs the agent closed-loop in the ``office`` scene for ``duration_s``
  (:func:`experiments.jobs.run_agent.closed_loop_metrics`) and measures the **time to foveate**
  (decision to settled gaze: the saccades' mean duration), the **foveation error**
  (reached minus ideal gaze for ``P``, px at the fovea), the **detection accuracy** (the
  8×8 box around ``P`` touches a moving object) and the **events per second**;
- for the baseline and the PTU settings, measures the **main sequence**
  (:func:`experiments.paper.ptu_main_sequence.measure`): forced pan saccades of
  ``main_sequence_amplitudes_deg`` in the static ``main_sequence_scene``, their amplitude,
  peak speed and duration and the fits, beside the PTU's rest-to-rest trapezoid.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Literal

import gymnasium as gym
import numpy as np

import wander_env  # noqa: F401  (registers the environments, picks the GL backend)
from agents.attention import AgentParams, AttentionAgent
from agents.fixation import FIXATION_WINDOW_S, FixationParams
from experiments.analysis.stats import ci_text, mean_ci, mean_std, number_text, paired_comparison
from experiments.jobs.run_agent import closed_loop_metrics
from experiments.paper import ptu_main_sequence
from experiments.paper.env_block import check_env_block, trial_env
from experiments.paper.speed_study import AXIS_LABELS, plot_surfaces
from experiments.studies import framework as study
from wander_env.camera import SPECK_HFOV_DEG, pixels_to_degrees
from wander_env.env_config import PtuPreset, SceneName, WanderConfig
from wander_env.ptu.params import PTUParams
from wander_env.viz import pyplot, save_figure

__all__ = [
    "EXPERIMENT",
    "FACTORS",
    "ObjectSpeed",
    "SaccadeSpeedConfig",
    "ScaledTrajectory",
    "baseline",
    "ptu_for",
]

# factor name -> (the grid column it sets, the config field holding its values)
FACTORS = {
    "ptu_speed": ("speed_pos_s", "speeds_pos_s"),
    "ptu_accel": ("accel_pos_s2", "accels_pos_s2"),
    "fixational_amplitude": ("fixational_step_pos", "fixational_steps_pos"),
    "fixational_count": ("fixational_n_steps", "fixational_counts"),
    "window": ("window_s", "windows_s"),
    "object_speed": ("object_speed_scale", "object_speed_scales"),
    "ptu_link": ("ptu_preset", "ptu_presets"),
}
# The numeric factors (one plot column each); ``ptu_link`` is compared by a test.
NUMERIC_FACTORS = {k: v for k, v in FACTORS.items() if k != "ptu_link"}
# The factorial design's factors (object speed and the link stay at the baseline).
FACTORIAL = ("ptu_speed", "ptu_accel", "fixational_amplitude", "fixational_count", "window")


#: The env fields each trial sets (what sets them): the block leaves them at defaults.
ENV_SET_PER_TRIAL = {"ptu": "the trial's PTU setting", "episode_seconds": "duration_s"}


@dataclass(frozen=True)
class SaccadeSpeedConfig:
    """Defaults: the baseline is the paper's (FLIR defaults, N = 8 steps of ±60 positions,
    St_w = 124 ms) on the ``flir`` PTU (its 9600-baud command latency); the swept values,
    the scene, the trial length and the repeats are ours.

    ``design``: ``one_at_a_time`` (the baseline, then each factor's other values) or
    ``factorial`` (every combination of PTU speed × acceleration × fixational step ×
    count × window, the other factors at the baseline). Every setting runs ``repeats``
    seeds (``seed + r``: paired across settings).

    ``env`` is the env's block of the closed-loop trials (the office); each trial sets
    its PTU and length (:data:`ENV_SET_PER_TRIAL`). The main-sequence trials run the same
    block in ``main_sequence_scene`` at 100 Hz frames without sub-frames or ground truth
    (events play no part in the measure). ``agent`` is the agent's block: its
    ``window_s`` is the baseline's window; each setting sets the window and the walk's
    steps (``fixation.n_steps``, ``fixation.max_step_pos``)."""

    duration_s: study.TrialSeconds = 3.0
    design: Literal["one_at_a_time", "factorial"] = "one_at_a_time"
    ptu_preset: Literal["ideal", "flir"] = "flir"
    windows_s: tuple[float, ...] = (0.05, FIXATION_WINDOW_S, 0.25)
    ptu_presets: tuple[PtuPreset, ...] = ("flir", "ideal")
    speeds_pos_s: tuple[float, ...] = (1000.0, 2000.0, 2902.0)
    accels_pos_s2: tuple[float, ...] = (1000.0, 2000.0, 8000.0)
    fixational_steps_pos: tuple[int, ...] = (20, 60, 120)
    fixational_counts: tuple[int, ...] = (4, 8, 16)
    object_speed_scales: tuple[float, ...] = (0.5, 1.0, 2.0)
    main_sequence_amplitudes_deg: tuple[float, ...] = (
        1.0,
        2.0,
        4.0,
        7.0,
        10.0,
        15.0,
        20.0,
        30.0,
        40.0,
    )
    main_sequence_scene: SceneName = "shelf"
    repeats: study.Repeats = 10
    env: WanderConfig = field(default_factory=lambda: WanderConfig(scene="office"))
    agent: AgentParams = field(default_factory=AgentParams)

    def __post_init__(self) -> None:
        check_env_block(self.env, ENV_SET_PER_TRIAL)
        self.agent.check_env_fields()  # the env's camera, PTU and step are the agent's
        if not self.duration_s > 0:
            raise ValueError(f"duration_s must be > 0, got {self.duration_s}")
        # each factor's values (the baseline's value alone leaves the factor unvaried)
        study.check_lists(
            self,
            (*(name for _, name in FACTORS.values()), "main_sequence_amplitudes_deg"),
        )
        for w in (self.agent.window_s, *self.windows_s):
            if not w >= 0.01 - 1e-12:
                raise ValueError(
                    f"agent.window_s / windows_s must be >= the 10 ms env step, got {w}"
                )
        for name in self.ptu_presets:
            PTUParams.preset(name)  # raises for an unknown preset
        if self.repeats < 1:
            raise ValueError(f"repeats must be >= 1, got {self.repeats}")
        lower, upper = PTUParams().pan_lower_speed, PTUParams().pan_upper_speed
        if any(not lower <= v <= upper for v in self.speeds_pos_s):
            raise ValueError(
                f"speeds_pos_s must be in [{lower:g}, {upper:g}] (PL, PU), got {self.speeds_pos_s}"
            )
        if any(not v > 0 for v in self.accels_pos_s2):
            raise ValueError(f"accels_pos_s2 must be > 0, got {self.accels_pos_s2}")
        if any(v < 0 for v in self.fixational_steps_pos):
            raise ValueError(f"fixational_steps_pos must be >= 0, got {self.fixational_steps_pos}")
        if any(v < 1 for v in self.fixational_counts):
            raise ValueError(f"fixational_counts must be >= 1, got {self.fixational_counts}")
        if any(v < 0 for v in self.object_speed_scales):
            raise ValueError(f"object_speed_scales must be >= 0, got {self.object_speed_scales}")
        half = pixels_to_degrees(63.0, 128, SPECK_HFOV_DEG)
        if any(not 0 < a <= half for a in self.main_sequence_amplitudes_deg):
            raise ValueError(
                f"main_sequence_amplitudes_deg must be in (0, {half:.1f}] (a pixel on the "
                f"sensor), got {self.main_sequence_amplitudes_deg}"
            )


# ----------------------------------------------------------------------------------------
# Pure helpers


def baseline(
    window_s: float = FIXATION_WINDOW_S, ptu_preset: str = "flir"
) -> dict[str, float | int | str]:
    """The grid columns at the paper's values (FLIR defaults, the paper's walk, St_w).

    >>> baseline()["speed_pos_s"], baseline()["fixational_n_steps"], baseline()["ptu_preset"]
    (2000.0, 8, 'flir')
    """
    ptu_, fix = PTUParams(), FixationParams()
    return {
        "speed_pos_s": float(ptu_.pan_speed),
        "accel_pos_s2": float(ptu_.pan_accel),
        "fixational_step_pos": int(fix.max_step_pos),
        "fixational_n_steps": int(fix.n_steps),
        "window_s": float(window_s),
        "object_speed_scale": 1.0,
        "ptu_preset": ptu_preset,
    }


def ptu_for(speed_pos_s: float, accel_pos_s2: float, preset: str = "ideal") -> PTUParams:
    """The ``preset``'s unit (:meth:`PTUParams.preset`) with both axes' speed and
    acceleration set (base speed capped to the speed).

    >>> p = ptu_for(500.0, 4000.0, "flir")
    >>> p.tilt_speed, p.pan_base_speed, p.tilt_accel, p.link.baudrate
    (500.0, 500.0, 4000.0, 9600)
    """
    return PTUParams.preset(preset).with_slew(speed_pos_s, accel_pos_s2)


def _trial_ptu(p: dict[str, Any]) -> PTUParams:
    return ptu_for(float(p["speed_pos_s"]), float(p["accel_pos_s2"]), str(p["ptu_preset"]))


class ScaledTrajectory:
    """A trajectory run ``scale`` times faster: ``position(t) = inner.position(scale·t)``."""

    def __init__(self, inner: Any, scale: float) -> None:
        self.inner, self.scale = inner, scale

    def position(self, t: float) -> np.ndarray:
        return self.inner.position(self.scale * t)


class ObjectSpeed(gym.Wrapper):
    """The env with its moving objects' trajectories sped up by ``scale`` (after every
    reset, which builds them anew)."""

    def __init__(self, env: gym.Env, scale: float) -> None:
        super().__init__(env)
        self.scale = scale

    def reset(self, **kwargs: Any) -> tuple[Any, dict[str, Any]]:
        obs, info = self.env.reset(**kwargs)
        anim = self.env.unwrapped.animator
        anim.trajectories = tuple(ScaledTrajectory(tr, self.scale) for tr in anim.trajectories)
        return obs, info


# ----------------------------------------------------------------------------------------
# The trial


def _closed_loop(cfg: SaccadeSpeedConfig, p: dict[str, Any], seed: int) -> dict[str, Any]:
    env = ObjectSpeed(
        trial_env(cfg.env, ptu=_trial_ptu(p), episode_seconds=cfg.duration_s + 1.0),
        float(p["object_speed_scale"]),
    )
    fixation = replace(
        cfg.agent.fixation,
        n_steps=int(p["fixational_n_steps"]),
        max_step_pos=int(p["fixational_step_pos"]),
    )
    params = cfg.agent.on_env(
        env, window_s=float(p["window_s"]), fixational=True, fixation=fixation
    )
    agent = AttentionAgent(params, seed=seed)
    try:
        m = closed_loop_metrics(env, agent, cfg.duration_s, seed)
        link = env.unwrapped.ptu.link
        latencies = list(link.schedule.latencies_s) if link is not None else []
    finally:
        agent.close()
        env.close()
    durations = [s.t_end - s.t_start for s in agent.saccades]
    return {
        # Command latency on the PTU's serial link (0 on the ideal unit).
        "command_latency_mean_s": mean_std(latencies)[0] if latencies else 0.0,
        "commands_sent": len(latencies),
        "saccades": len(agent.saccades),
        "time_to_foveate_s": mean_std(durations)[0],
        "foveation_error_x_px": m.get("foveation_error_x_px_mean", math.nan),
        "foveation_error_y_px": m.get("foveation_error_y_px_mean", math.nan),
        "detection_accuracy": m["detection_accuracy"],
        "decisions_scored": m["decisions_scored"],
        "simulated_s": m["simulated_s"],
        "events_per_s": m["events"] / m["simulated_s"],
        "soms_suppression": m["soms_suppression"],
    }


def run_trial(cfg: SaccadeSpeedConfig, spec: study.TrialSpec) -> dict[str, Any]:
    """The closed loop at one setting; at the first repeat of a setting marked
    ``main_sequence`` (one per PTU setting: the PTU is deterministic), its main sequence
    and the fits too."""
    p = dict(spec.params)
    out = _closed_loop(cfg, p, spec.seed)
    if p["main_sequence"] and spec.repeat == 0:
        out |= ptu_main_sequence.measure(
            cfg.env,
            cfg.main_sequence_scene,
            cfg.agent,
            _trial_ptu(p),
            cfg.main_sequence_amplitudes_deg,
            spec.seed,
        )
    return out


def grid(cfg: SaccadeSpeedConfig) -> list[dict[str, Any]]:
    """``one_at_a_time``: the baseline, then each factor's other values with the rest at
    the baseline; ``factorial``: every combination of :data:`FACTORIAL`'s values. The
    first setting of each PTU (speed, acceleration, link) is marked ``main_sequence``."""
    base = baseline(cfg.agent.window_s, cfg.ptu_preset)
    rows: list[dict[str, Any]] = []
    if cfg.design == "factorial":
        cols = [FACTORS[f] for f in FACTORIAL]
        for values in itertools.product(*(getattr(cfg, field) for _, field in cols)):
            point = dict(zip((c for c, _ in cols), values, strict=True))
            rows.append({"factor": "factorial", **base, **point})
    else:
        rows.append({"factor": "baseline", **base})
        for factor, (column, field_name) in FACTORS.items():
            for v in getattr(cfg, field_name):
                if v != base[column]:
                    rows.append({"factor": factor, **base, column: v})
    seen: set[tuple[Any, ...]] = set()
    for r in rows:
        key = (r["speed_pos_s"], r["accel_pos_s2"], r["ptu_preset"])
        r["main_sequence"] = key not in seen
        seen.add(key)
    return rows


# ----------------------------------------------------------------------------------------
# Summary and plots


def _value(row: study.Row) -> tuple[str, Any]:
    factor = str(row["factor"])
    if factor == "baseline":
        return "baseline", ""
    return factor, row[FACTORS[factor][0]]


SETTING_COLUMNS = (
    "speed_pos_s",
    "accel_pos_s2",
    "fixational_step_pos",
    "fixational_n_steps",
    "window_s",
    "object_speed_scale",
    "ptu_preset",
)
# (column, label, format) of the closed-loop measures summarised per setting.
MEASURES = (
    ("time_to_foveate_s", "time to foveate (s)", ".3f"),
    ("detection_accuracy", "detection accuracy", ".2f"),
    ("foveation_error_x_px", "foveation error x (px)", ".2f"),
    ("foveation_error_y_px", "foveation error y (px)", ".2f"),
    ("command_latency_mean_s", "command latency (s)", ".4f"),
)
TESTED = ("time_to_foveate_s", "detection_accuracy")


def settings(rows: list[study.Row]) -> dict[tuple[Any, ...], list[study.Row]]:
    """Rows grouped by setting (:data:`SETTING_COLUMNS`), in grid order."""
    out: dict[tuple[Any, ...], list[study.Row]] = {}
    for r in rows:
        out.setdefault(tuple(r[c] for c in SETTING_COLUMNS), []).append(r)
    return out


def _label(r: study.Row) -> str:
    factor, v = _value(r)
    return "baseline (paper's values)" if factor == "baseline" else f"{factor} = {v}"


def _pairs(a: list[study.Row], b: list[study.Row], key: str) -> tuple[list[float], list[float]]:
    bs = {int(r["seed"]): float(r[key]) for r in b}
    common = [r for r in a if int(r["seed"]) in bs]
    return [float(r[key]) for r in common], [bs[int(r["seed"])] for r in common]


def compare(cfg: SaccadeSpeedConfig, rows: list[study.Row]) -> list[study.Comparison]:
    """Per setting: each measure's mean over the repeats with its bootstrap 95 % interval,
    the time to foveate and detection accuracy against the baseline (paired by seed:
    permutation test, d_z, rank-biserial), and the main-sequence fits of each PTU
    setting (``factorial``: per factor level, the marginal means). The paper gives
    no numbers here (future work), except its 124 ms decision latency."""
    groups = settings(rows)
    out = [
        study.Comparison(
            "latency to the salient point",
            "0.124 s (St_w), then the saccade",
            f"{cfg.agent.window_s:g} s window + time to foveate "
            f"{number_text(mean_std(float(r['time_to_foveate_s']) for r in rows)[0], '.2f')} s "
            "(mean over all trials)",
        )
    ]
    base = next((g for g in groups.values() if str(g[0]["factor"]) == "baseline"), None)
    factorial = any(str(r["factor"]) == "factorial" for r in rows)
    if factorial:
        for factor in FACTORIAL:
            col = FACTORS[factor][0]
            for v in dict.fromkeys(r[col] for r in rows):
                sel = [r for r in rows if r[col] == v]
                parts = []
                for key, label, fmt in MEASURES[:2]:
                    parts.append(f"{label} {_ci(sel, key, fmt)}")
                out.append(
                    study.Comparison(f"{factor} = {v} (marginal)", "—", "; ".join(parts), "")
                )
    else:
        for g in groups.values():
            r0 = g[0]
            parts = [f"{label} {_ci(g, key, fmt)}" for key, label, fmt in MEASURES]
            notes = []
            if base is not None and g is not base:
                for key in TESTED:
                    t = paired_comparison(*_pairs(g, base, key))
                    notes.append(f"{key} − baseline: {t.text('.3g')}")
            out.append(
                study.Comparison(
                    _label(r0),
                    "— (future work)",
                    "; ".join(parts),
                    "; ".join(notes) or f"{len(g)} repeats",
                )
            )
    for g in groups.values():
        fits = next((text for text in map(ptu_main_sequence.fits_text, g) if text), "")
        if fits:
            r0 = g[0]
            name = (
                f"{float(r0['speed_pos_s']):g} pos/s, {float(r0['accel_pos_s2']):g} pos/s², "
                f"{r0['ptu_preset']} PTU"
            )
            out.append(
                study.Comparison(
                    f"main sequence, {name}",
                    "— (future work)",
                    fits,
                    "curve_fit, 95 % intervals from the covariance; D = command to standstill",
                )
            )
    return out


def _ci(rows: list[study.Row], key: str, fmt: str) -> str:
    return ci_text(mean_ci(float(r[key]) for r in rows), fmt)


def factor_intervals(
    rows: list[study.Row], column: str, key: str, levels: list[float]
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(means, lower, upper error-bar lengths) of ``key`` at each level of ``column``: the
    mean over the rows at that level and its bootstrap 95 % interval (0-length bars
    where the interval is undefined; NaN means where no row has a value).

    >>> rows = [{"f": 1.0, "y": v} for v in (1.0, 1.0)] + [{"f": 2.0, "y": 3.0}]
    >>> [a.tolist() for a in factor_intervals(rows, "f", "y", [1.0, 2.0])]
    [[1.0, 3.0], [0.0, 0.0], [0.0, 0.0]]
    """
    out = [mean_ci(float(r[key]) for r in rows if float(r[column]) == x) for x in levels]
    m = np.array([v[0] for v in out], float)
    lo = np.nan_to_num(m - np.array([v[1] for v in out], float))
    hi = np.nan_to_num(np.array([v[2] for v in out], float) - m)
    return m, lo, hi


def plot(
    cfg: SaccadeSpeedConfig, rows: list[study.Row], results_dir: Path, fig_dir: Path
) -> list[Path]:
    """The main sequence (amplitude vs peak velocity and duration) per PTU setting, with
    the PTU's trapezoid; and each measure against each factor."""
    plt = pyplot()

    series = []
    for r in rows:
        if r["repeat"] != 0:
            continue
        arts = study.load_artifacts(results_dir, r)
        if "ms_amplitude_deg" in arts:
            series.append((r, _trial_ptu(r), arts))
    ms_path = ptu_main_sequence.plot(
        series,
        max(cfg.main_sequence_amplitudes_deg),
        cfg.main_sequence_scene,
        fig_dir / "main_sequence.png",
    )
    if any(str(r["factor"]) == "factorial" for r in rows):
        return [ms_path, plot_surfaces(rows, fig_dir / "response_surfaces.png")]

    metrics = [
        ("time_to_foveate_s", "time to foveate (s)"),
        ("foveation_error_x_px", "foveation error (px): x, y"),
        ("detection_accuracy", "detection accuracy"),
        ("events_per_s", "events / s"),
    ]
    base = [r for r in rows if r["factor"] == "baseline"]
    fig, axes = plt.subplots(
        len(metrics),
        len(NUMERIC_FACTORS),
        figsize=(3.0 * len(NUMERIC_FACTORS), 2.4 * len(metrics)),
        squeeze=False,
    )
    for j, (factor, (column, _)) in enumerate(NUMERIC_FACTORS.items()):
        sel = base + [r for r in rows if r["factor"] == factor]
        xs = sorted({float(r[column]) for r in sel})
        for i, (key, label) in enumerate(metrics):
            ax = axes[i, j]
            series = [(key, "o-", "x")]
            if key == "foveation_error_x_px":
                series.append(("foveation_error_y_px", "s--", "y"))
            for col, style, name in series:
                m, lo, hi = factor_intervals(sel, column, col, xs)
                ax.errorbar(
                    xs,
                    m,
                    yerr=[lo, hi],
                    fmt=style,
                    capsize=3,
                    ms=4,
                    label=name if len(series) > 1 else None,
                )
            if len(series) > 1:
                ax.legend(fontsize=6)
            if i == len(metrics) - 1:
                ax.set_xlabel(AXIS_LABELS.get(column, column), fontsize=7.5)
            if j == 0:
                ax.set_ylabel(label, fontsize=8)
            if i == 0:
                ax.set_title(factor, fontsize=9)
    n = max((len(g) for g in settings(rows).values()), default=0)
    fig.suptitle(
        "One factor at a time around the paper's values (PTU speed and acceleration, "
        f"fixational steps, window, object speed): mean over {n} seeded repeats of "
        f"{cfg.duration_s:g} s in the {cfg.env.scene} scene per setting, error bars the "
        "bootstrap 95 % interval",
        fontsize=10,
    )
    sweep_path = save_figure(fig, fig_dir / "saccade_speed.png")
    return [ms_path, sweep_path]


EXPERIMENT = study.Experiment(
    name="saccade_speed",
    description=(
        "One factor at a time around the paper's values (or a factorial design): PTU speed "
        "and acceleration, fixational step amplitude and count, window, object speed, the "
        "PTU's serial-link latency; time to foveate, foveation error, detection accuracy "
        "and events per second in the office scene over seeded repeats with intervals and "
        "paired tests, and the main sequence (peak velocity and duration against "
        "amplitude) with its saturating and linear fits."
    ),
    config_type=SaccadeSpeedConfig,
    grid=grid,
    run_trial=run_trial,
    plot=plot,
    compare=compare,
)
