"""Detection benchmark in simulation: the paper's EVIMO protocol on scenes with ground truth.

For each scene type and camera-speed level the camera sweeps between random gaze targets
(±``sweep_amplitude_deg`` around the start) with the PTU's speed set to the level
(0 = a still camera), the moving objects move along their trajectories, and the events of
each ``step_s`` window go through the sOMS and then either

- the proto-object stage (saliency argmax ``P(x, y)``, the paper's pipeline), or
- no proto-object stage: the argmax of the OMS map's local density (the OMS map smoothed by
  a Gaussian of ``baseline_sigma_px``) — the paper's "need for proto-object" comparison.

Each window is scored by :mod:`experiments.benchmark.protocol` against the ground-truth
object mask of the env (``info["object_mask"]``): detection hit (the 8×8 box around the
point touches the mask), true IoU, precision (the paper's "IoU") and SSIM of the OMS map.
Windows before ``warmup_s`` (the LIF states filling) and windows with no object in view are
not scored. One row per trial: means over the scored windows.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

import wander_env  # noqa: F401  (registers the environments)
from agents.attention import AgentParams
from agents.pipeline import SaliencyPipeline
from agents.proto_object import ProtoObjectParams
from agents.soms import SOMSParams
from experiments.analysis.stats import mean_std, percent_text
from experiments.benchmark.datasets.base import MaskWindow, SequenceData
from experiments.benchmark.protocol import (
    NOTE_OMS_EMPTY,
    ProtocolConfig,
    WindowRow,
    evaluate_sequence,
)
from experiments.benchmark.summary import paper_reference
from experiments.paper.env_block import check_env_block, trial_env
from experiments.runs.episode import Recorder, run_episode
from experiments.studies import framework as study
from wander_env.actions import gaze_degrees_to_action
from wander_env.env_config import SceneName, WanderConfig
from wander_env.events import concatenate
from wander_env.ptu.params import PTUParams
from wander_env.ptu.units import FLIR_RESOLUTION_ARCSEC
from wander_env.scene_config import MAX_CAMERA_SIDE
from wander_env.viz import pyplot, save_figure

__all__ = [
    "EXPERIMENT",
    "DetectionConfig",
    "SweepPolicy",
    "ptu_for_speed",
]


#: The env fields each trial sets (what sets them): the block leaves them at defaults.
ENV_SET_PER_TRIAL = {
    "scene": "scenes",
    "control_period_s": "step_s",
    "episode_seconds": "duration_s",
    "ptu": "camera_speeds_deg_s",
}
#: The longest event window (s): the sOMS and the proto-object stage step once a window.
MAX_STEP_S = 1.0
#: The widest Gaussian of the baseline (px): the 128-px sensor's side; a wider one
#: smooths the OMS map flat (and its kernel, 8 σ across, outgrows the map).
MAX_SIGMA_PX = 128.0


@dataclass(frozen=True)
class DetectionConfig:
    """Defaults: the paper's sOMS / proto-object table values and its 8×8 box; scenes,
    speed levels, sweep amplitude and trial length are ours.

    ``agent`` is the agent's block (:class:`agents.attention.AgentParams`) whose two
    stages the experiment runs: its ``soms`` (the paper-literal sOMS by default, min-max
    norm, α 0.80) and ``proto`` (``--set agent.soms.alpha=0.5``), both stepped every
    ``step_s`` (one event window); the agent's other settings play no part and are refused
    (as in ``wander benchmark``). ``env`` is the env's block (``--set env.frames=exact``);
    each trial sets its scene, step, length and PTU (:data:`ENV_SET_PER_TRIAL`)."""

    scenes: tuple[SceneName, ...] = ("office", "hand", "gratings")
    camera_speeds_deg_s: tuple[float, ...] = (0.0, 10.0, 30.0, 60.0)
    sweep_amplitude_deg: float = 5.0
    duration_s: study.TrialSeconds = 2.0
    warmup_s: float = 0.2
    env: WanderConfig = field(default_factory=lambda: WanderConfig(dvs="paper"))
    box: int = 8
    baseline_sigma_px: float = 2.0
    repeats: study.Repeats = 2
    step_s: float = 0.02
    agent: AgentParams = field(default_factory=lambda: AgentParams(soms=SOMSParams()))

    def __post_init__(self) -> None:
        check_env_block(self.env, ENV_SET_PER_TRIAL)
        if not self.duration_s > self.warmup_s >= 0:
            raise ValueError(
                f"need duration_s > warmup_s >= 0, got {self.duration_s}, {self.warmup_s}"
            )
        self.agent.check_reads("soms", "proto", speck=False)
        study.check_lists(self, ("scenes", "camera_speeds_deg_s"))
        ticks = self.step_s * 1000.0
        if not 0 < self.step_s <= MAX_STEP_S or abs(ticks - round(ticks)) > 1e-9:
            raise ValueError(
                f"step_s: must be a whole number of ms in (0, {MAX_STEP_S:g}] s, got {self.step_s}"
            )
        if self.step_s > self.duration_s:
            raise ValueError(
                f"step_s: must be <= duration_s ({self.duration_s}: one window at least), "
                f"got {self.step_s}"
            )
        if not 1 <= self.box <= MAX_CAMERA_SIDE:
            raise ValueError(f"box: must be in [1, {MAX_CAMERA_SIDE}] px, got {self.box}")
        if not 0 < self.baseline_sigma_px <= MAX_SIGMA_PX:
            raise ValueError(
                f"baseline_sigma_px: must be in (0, {MAX_SIGMA_PX:g}] px, got "
                f"{self.baseline_sigma_px}"
            )
        if not 0 < self.sweep_amplitude_deg < 90:
            raise ValueError(
                f"sweep_amplitude_deg: must be in (0, 90) deg, got {self.sweep_amplitude_deg}"
            )
        d = PTUParams()
        low, top = (
            FLIR_RESOLUTION_ARCSEC / 3600.0 * v for v in (d.pan_lower_speed, d.pan_upper_speed)
        )
        bad = [v for v in self.camera_speeds_deg_s if not (v == 0 or low <= v <= top)]
        if bad:
            raise ValueError(
                f"camera_speeds_deg_s must be 0 (still) or in [{low:.2f}, {top:.1f}] (the "
                f"PTU's PL, PU), got {bad}"
            )
        if self.repeats < 1:
            raise ValueError(f"repeats must be >= 1, got {self.repeats}")

    def soms_params(self) -> SOMSParams:
        """The agent's sOMS block, stepped every ``step_s``."""
        return replace(self.agent.soms, dt=self.step_s)  # type: ignore[type-var]

    def proto_params(self) -> ProtoObjectParams:
        """The agent's proto-object block, stepped every ``step_s``."""
        return replace(self.agent.proto, dt=self.step_s)


# ----------------------------------------------------------------------------------------
# Camera motion


def ptu_for_speed(speed_deg_s: float, ramp_s: float = 0.05) -> PTUParams:
    """PTU parameters whose slew speed is ``speed_deg_s`` on both axes, reached within
    ``ramp_s`` (the acceleration raised above the FLIR default where needed; start speed
    capped to the level). 0 keeps the defaults (the camera stays still)."""
    d = PTUParams()
    if speed_deg_s <= 0:
        return d
    pos = speed_deg_s / (d.pan_resolution_arcsec / 3600.0)
    accel = max(d.pan_accel, pos / ramp_s)
    return d.with_slew(pos, accel)


class SweepPolicy:
    """Saccade-free sweeps: whenever the PTU has stopped, a new gaze target drawn
    uniformly in ±``amplitude_deg`` (pan and tilt) around the start; still at speed 0."""

    def __init__(self, speed_deg_s: float, amplitude_deg: float, rng: np.random.Generator):
        self.speed, self.amplitude, self.rng = speed_deg_s, amplitude_deg, rng
        self.target = np.zeros(2)  # relative to the start, degrees (pan, tilt)

    def act(self, obs: Any, info: dict[str, Any]) -> np.ndarray:
        if self.speed <= 0 or info["moving"]:
            return np.zeros(2, np.float32)
        new = self.rng.uniform(-self.amplitude, self.amplitude, 2)
        d_pan, d_tilt = new - self.target
        self.target = new
        return np.clip(gaze_degrees_to_action(d_pan, d_tilt), -1, 1).astype(np.float32)


class _Sequence(Recorder):
    """The events and one object-mask window per step of ``step_us``, and the gaze (the
    reset's first)."""

    def __init__(self, step_us: int) -> None:
        self.step_us = step_us
        self.chunks: list[np.ndarray] = []
        self.windows: list[MaskWindow] = []
        self.gaze: list[np.ndarray] = []

    def on_reset(self, env: Any, policy: Any, obs: Any, info: dict) -> None:
        self.gaze = [np.asarray(obs["gaze"], np.float64)]

    def on_step(self, env: Any, policy: Any, obs: Any, info: dict) -> None:
        k = len(self.chunks)
        self.chunks.append(info["events"].events)
        window = MaskWindow(k * self.step_us, (k + 1) * self.step_us, info["object_mask"])
        self.windows.append(window)
        self.gaze.append(np.asarray(obs["gaze"], np.float64))


# ----------------------------------------------------------------------------------------
# The trial


def record_sequence(
    cfg: DetectionConfig, scene: str, speed: float, seed: int
) -> tuple[SequenceData, float]:
    """Run the env under :class:`SweepPolicy`; (events + one mask window per step,
    mean camera speed in deg/s)."""
    n = round(cfg.duration_s / cfg.step_s)
    env = trial_env(
        cfg.env,
        scene=scene,
        control_period_s=cfg.step_s,
        episode_seconds=cfg.duration_s + 1.0,
        ptu=ptu_for_speed(speed),
    )
    policy = SweepPolicy(speed, cfg.sweep_amplitude_deg, np.random.default_rng(seed + 1))
    sequence = _Sequence(round(cfg.step_s * 1e6))
    try:
        run_episode(env, policy, n, (sequence,), seed=seed)
        base = env.unwrapped
        sensor = (base.width, base.height, 2)
    finally:
        env.close()
    gaze = np.asarray(sequence.gaze)
    chunks, windows = sequence.chunks, sequence.windows
    speed_meas = float(np.mean(np.linalg.norm(np.diff(gaze, axis=0), axis=1)) / cfg.step_s)
    seq = SequenceData(
        "wander", scene, f"{scene}-v{speed:g}-s{seed}", sensor, concatenate(chunks), windows
    )
    return seq, speed_meas


def _means(rows: list[WindowRow], warmup_us: int) -> dict[str, float]:
    scored = [r for r in rows if r.scored and r.t_start_us >= warmup_us]
    out = {"scored_windows": float(len(scored))}
    for name in ("hit", "iou", "precision", "ssim"):
        out[name] = mean_std(getattr(r, name) for r in scored)[0]
    out["oms_empty"] = float(sum(r.has_note(NOTE_OMS_EMPTY) for r in scored))
    return out


def run_trial(cfg: DetectionConfig, spec: study.TrialSpec) -> dict[str, Any]:
    """One scene / speed / seed: record, then score with and without the proto stage."""
    scene, speed = str(spec.params["scene"]), float(spec.params["camera_speed_deg_s"])
    seq, speed_meas = record_sequence(cfg, scene, speed, spec.seed)
    protocol = ProtocolConfig(box=cfg.box)
    warm = round(cfg.warmup_s * 1e6)
    baseline = SaliencyPipeline(
        cfg.soms_params(), saliency="oms_density", density_sigma_px=cfg.baseline_sigma_px
    )
    proto = SaliencyPipeline(cfg.soms_params(), cfg.proto_params())
    with_proto = _means(evaluate_sequence(seq, proto, protocol), warm)
    without = _means(evaluate_sequence(seq, baseline, protocol), warm)
    n_windows = len(seq.windows)
    return {
        "simulated_s": round(cfg.duration_s / cfg.step_s) * cfg.step_s,
        "camera_speed_measured_deg_s": speed_meas,
        "events_per_step": len(seq.events) / n_windows,
        "mask_pixels_mean": float(np.mean([w.mask.sum() for w in seq.windows])),
        "scored_windows": int(with_proto["scored_windows"]),
        "accuracy_proto": with_proto["hit"],
        "accuracy_oms_only": without["hit"],
        "iou": with_proto["iou"],
        "precision": with_proto["precision"],
        "ssim": with_proto["ssim"],
        "oms_empty_windows": int(with_proto["oms_empty"]),
    }


def grid(cfg: DetectionConfig) -> list[dict[str, Any]]:
    return [
        {"scene": s, "camera_speed_deg_s": float(v)}
        for s in cfg.scenes
        for v in cfg.camera_speeds_deg_s
    ]


# ----------------------------------------------------------------------------------------
# Summary and plots


def group_means(rows: list[study.Row], metric: str) -> dict[tuple[str, float], float]:
    """Mean of ``metric`` over repeats, per (scene, camera speed)."""
    acc: dict[tuple[str, float], list[float]] = {}
    for r in rows:
        acc.setdefault((str(r["scene"]), float(r["camera_speed_deg_s"])), []).append(
            float(r[metric])
        )
    return {k: mean_std(v)[0] for k, v in acc.items()}


def compare(cfg: DetectionConfig, rows: list[study.Row]) -> list[study.Comparison]:
    """Per scene and camera speed: our accuracy with / without proto-objects, IoU,
    precision and SSIM beside the paper's EVIMO figures."""
    ref = paper_reference("evimo")
    acc = [f"{k} {v.accuracy_mean:g} %" for k, v in ref.items() if v.accuracy_mean is not None]
    paper = (
        "EVIMO accuracy: " + ", ".join(acc) + '; "IoU" (a precision) 82.2 %, SSIM 96 %; '
        "fails when the camera moves faster than the objects"
    )
    a_p, a_o, iou, prec, ss, speed = (
        group_means(rows, m)
        for m in (
            "accuracy_proto",
            "accuracy_oms_only",
            "iou",
            "precision",
            "ssim",
            "camera_speed_measured_deg_s",
        )
    )
    out = []
    for i, (s, v) in enumerate(a_p):
        k = (s, v)
        out.append(
            study.Comparison(
                f"{s}, camera {v:g}°/s (measured {speed[k]:.0f})",
                paper if i == 0 else "″",
                f"accuracy {percent_text(a_p[k])} with / {percent_text(a_o[k])} without "
                f"proto-objects; IoU {percent_text(iou[k])}, precision {percent_text(prec[k])}, "
                f"SSIM {percent_text(ss[k])}",
            )
        )
    return out


def plot(
    cfg: DetectionConfig, rows: list[study.Row], results_dir: Path, fig_dir: Path
) -> list[Path]:
    """Accuracy (with / without proto-objects) and OMS-map scores against camera speed."""
    plt = pyplot()

    scenes = list(dict.fromkeys(str(r["scene"]) for r in rows))
    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    metrics = {
        "accuracy_proto": ("accuracy, proto-object", "-"),
        "accuracy_oms_only": ("accuracy, OMS only", "--"),
    }
    for i, s in enumerate(scenes):
        c = f"C{i}"
        for m, (label, ls) in metrics.items():
            g = group_means([r for r in rows if r["scene"] == s], m)
            v = sorted(k[1] for k in g)
            axes[0].plot(v, [g[(s, x)] for x in v], ls, color=c, marker="o", label=f"{s}: {label}")
        for m, ls in (("precision", "-"), ("iou", "--"), ("ssim", ":")):
            g = group_means([r for r in rows if r["scene"] == s], m)
            v = sorted(k[1] for k in g)
            axes[1].plot(v, [g[(s, x)] for x in v], ls, color=c, marker=".", label=f"{s}: {m}")
    axes[0].set(xlabel="camera speed (°/s)", ylabel="detection accuracy (8×8 box)", ylim=(0, 1))
    axes[1].set(xlabel="camera speed (°/s)", ylabel="OMS map vs mask", ylim=(0, 1))
    axes[0].set_title("salient point P on a moving object (8×8 box)", fontsize=9)
    axes[1].set_title("OMS map against the ground-truth mask", fontsize=9)
    for ax in axes:
        ax.legend(fontsize=7)
    fig.suptitle(
        f"Detection against camera speed (α = {cfg.agent.soms.alpha:g}, {cfg.duration_s:g} s "
        "per trial, means over windows and repeats)",
        fontsize=10,
    )
    path = save_figure(fig, fig_dir / "detection.png")
    return [path]


EXPERIMENT = study.Experiment(
    name="detection",
    description=(
        "Detection accuracy (8×8 box around the salient point), true IoU, precision and SSIM "
        "of the OMS map against ground-truth masks, per scene and camera speed, with and "
        "without the proto-object stage."
    ),
    config_type=DetectionConfig,
    grid=grid,
    run_trial=run_trial,
    plot=plot,
    compare=compare,
)
