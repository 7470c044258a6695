"""Event suppression by the sOMS (the paper's Table "eventssupp" and its Figure "ev_supp").

The paper's trials: "alternating phases of slightly shaking the DVS sensor while moving a
hand in front of the camera, with intermittent pauses"; events counted every 2 ms before
and after the sOMS; 10 trials; 14747.03 ± 2029.17 events in, 2189.15 ± 385.57 out,
85.16 % suppressed.

Here: the ``hand`` scene (a hand-sized textured box waved 0.25 m in front of the camera in
a cluttered room). Time alternates ``active_s`` of activity — the camera shaken by
fixational eye movements (:class:`experiments.jobs.record.GazePolicy`, ±60 PTU positions per
step) and the hand moving — with ``pause_s`` where both stand still (the hand's
trajectory is time-warped to stop: :class:`PausedTrajectory`). The env steps every
``window_s`` (2 ms), the sOMS steps once per window on its event counts, and an event
counts as *out* when it falls on a pixel the OMS map fires at (both polarities).

Per trial: mean ± std over windows of events in and out, the fraction suppressed
(1 − out/in over the trial), and with the ground-truth mask the fraction of the hand's
events kept and of the background's events kept.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, ClassVar, Literal

import gymnasium as gym
import numpy as np
import torch
from scipy.ndimage import gaussian_filter

import wander_env  # noqa: F401  (registers the environments)
from agents.proto_object import saliency_argmax
from agents.soms import SOMS, TABLE_FIELDS, SOMSParams
from experiments.benchmark.protocol import PAPER_SUPPRESSION
from experiments.framework import (
    Comparison,
    DvsPreset,
    Experiment,
    Repeats,
    Row,
    SceneName,
    TrialSeconds,
    TrialSpec,
    load_artifacts,
)
from experiments.jobs.record import GazePolicy
from wander_env.config import block_aliases
from wander_env.metrics import detection_hit
from wander_env.viz import save_figure

__all__ = [
    "EXPERIMENT",
    "EventSuppressionConfig",
    "PausedTrajectory",
    "active_time",
    "hand_hit",
    "is_active",
    "pooled_mean_std",
    "soms_preset",
]

#: The named sOMS blocks of ``soms=...``: the paper's table, or the agent's default.
SOMSPreset = Literal["table", "agent"]


def soms_preset(name: str, dt: float = 0.02) -> SOMSParams:
    """The sOMS block ``name`` at step ``dt``: ``"table"`` the paper's table (min-max norm),
    ``"agent"`` the agent's default (:data:`agents.attention.AGENT_SOMS`).

    >>> soms_preset("table").norm, soms_preset("agent").norm, soms_preset("agent").dt
    ('minmax', 'quantile', 0.02)
    """
    if name == "agent":
        from agents.attention import AGENT_SOMS

        return replace(AGENT_SOMS, dt=dt)
    if name == "table":
        return SOMSParams(dt=dt)
    raise ValueError(f"soms must be a parameter block or 'table' or 'agent', got {name!r}")


@dataclass(frozen=True)
class EventSuppressionConfig:
    """Defaults: the paper's (2 ms windows, 10 trials, sOMS table values); the scene,
    phase lengths and trial length are ours (the paper gives none).

    ``soms`` is the sOMS block (``--set soms.alpha=0.6``) or a preset name
    (:func:`soms_preset`: ``--set soms=agent`` runs the agent's sOMS); its ``dt`` is the
    sOMS step, a whole number of ``window_s`` windows. The former flat keys are still
    read (:data:`CONFIG_ALIASES`: ``alpha`` sets ``soms.alpha``, ``soms_step_s``
    ``soms.dt``)."""

    CONFIG_ALIASES: ClassVar[dict[str, str]] = {
        "soms_step_s": "soms.dt",
        **block_aliases("soms", TABLE_FIELDS),
    }

    scene: SceneName = "hand"
    dvs: DvsPreset = "speck"
    duration_s: TrialSeconds = 3.0
    window_s: float = 0.002
    active_s: float = 1.0
    pause_s: float = 0.5
    shake: str = "fixational"
    repeats: Repeats = 10
    soms: SOMSParams | SOMSPreset = field(default_factory=lambda: soms_preset("table"))
    hit_sigma_px: float = 2.0

    def __post_init__(self) -> None:
        if isinstance(self.soms, str):  # a preset name: its block
            object.__setattr__(self, "soms", soms_preset(self.soms))
        for name in ("duration_s", "window_s", "active_s", "hit_sigma_px"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name} must be > 0, got {getattr(self, name)}")
        if self.pause_s < 0:
            raise ValueError(f"pause_s must be >= 0, got {self.pause_s}")
        if self.shake not in ("still", "fixational"):
            raise ValueError(f"shake must be 'still' or 'fixational', got {self.shake!r}")
        if self.repeats < 1:
            raise ValueError(f"repeats must be >= 1, got {self.repeats}")
        ticks = self.window_s * 1000.0
        if abs(ticks - round(ticks)) > 1e-9:
            raise ValueError(f"window_s must be a whole number of ms, got {self.window_s}")
        k = self.soms_step_s / self.window_s
        if abs(k - round(k)) > 1e-9 or round(k) < 1:
            raise ValueError(
                f"soms.dt={self.soms_step_s} must be a whole number of windows "
                f"(window_s={self.window_s})"
            )

    @property
    def soms_step_s(self) -> float:
        """One sOMS step, seconds (``soms.dt``)."""
        return self.soms_params.dt

    @property
    def soms_params(self) -> SOMSParams:
        """The sOMS block (``soms``, a preset name resolved)."""
        assert isinstance(self.soms, SOMSParams)
        return self.soms

    @property
    def windows_per_step(self) -> int:
        return round(self.soms_step_s / self.window_s)


# ----------------------------------------------------------------------------------------
# Pure helpers


def is_active(t: float, active_s: float, pause_s: float) -> bool:
    """Whether ``t`` lies in an active phase (cycles of ``active_s`` then ``pause_s``).

    >>> is_active(0.5, 1.0, 0.5), is_active(1.2, 1.0, 0.5), is_active(1.6, 1.0, 0.5)
    (True, False, True)
    """
    return math.fmod(t, active_s + pause_s) < active_s


def active_time(t: float, active_s: float, pause_s: float) -> float:
    """Time spent in active phases up to ``t``: a clock that stops during pauses.

    >>> active_time(0.5, 1.0, 0.5), active_time(1.2, 1.0, 0.5), active_time(2.0, 1.0, 0.5)
    (0.5, 1.0, 1.5)
    """
    period = active_s + pause_s
    k = math.floor(t / period)
    return k * active_s + min(t - k * period, active_s)


def pooled_mean_std(means: np.ndarray, stds: np.ndarray) -> tuple[float, float]:
    """Mean and (population) std of the union of equal-sized groups from their means and
    population stds.

    >>> pooled_mean_std(np.array([1.0, 3.0]), np.array([0.0, 0.0]))
    (2.0, 1.0)
    """
    m = np.asarray(means, float)
    s = np.asarray(stds, float)
    mean = float(m.mean())
    return mean, float(math.sqrt(max(float(np.mean(s**2 + m**2)) - mean**2, 0.0)))


class PausedTrajectory:
    """A trajectory whose clock stops during pauses (:func:`active_time`)."""

    def __init__(self, inner: Any, active_s: float, pause_s: float) -> None:
        self.inner, self.active_s, self.pause_s = inner, active_s, pause_s

    def position(self, t: float) -> np.ndarray:
        return self.inner.position(active_time(t, self.active_s, self.pause_s))


# ----------------------------------------------------------------------------------------
# The trial


def oms_point(oms: np.ndarray, sigma_px: float) -> tuple[int, int] | None:
    """The OMS map's densest point ``(x, y)``: the argmax of its both-polarity sum
    smoothed by a Gaussian of ``sigma_px`` (zero outside the sensor); None when empty.

    >>> m = np.zeros((2, 16, 16), bool); m[1, 4:7, 9:12] = True; m[0, 14, 1] = True
    >>> oms_point(m, 2.0)
    (10, 5)
    """
    dens = gaussian_filter(np.asarray(oms, np.float32).sum(axis=0), sigma_px, mode="constant")
    return saliency_argmax(torch.from_numpy(dens))


def hand_hit(oms: np.ndarray, hand: np.ndarray, sigma_px: float, box: int = 8) -> bool:
    """The scorer of the hand claim for one sOMS step: the ``box``×``box`` square around
    the OMS map's densest point (:func:`oms_point`) touches the hand's mask
    (:func:`wander_env.metrics.detection_hit`); an empty map is a miss (the hand's events
    did not survive).

    >>> m = np.zeros((2, 32, 32), bool); m[1, 20:24, 20:24] = True   # kept events
    >>> oms_point(m, 2.0)                         # box: x and y in [17, 24]
    (21, 21)
    >>> hand = np.zeros((32, 32), bool); hand[24:29, 24:29] = True
    >>> hand_hit(m, hand, 2.0), hand_hit(m, np.roll(hand, 1, axis=1), 2.0)
    (True, False)
    >>> hand_hit(np.zeros((2, 32, 32), bool), hand, 2.0)   # nothing kept: a miss
    False
    """
    point = oms_point(oms, sigma_px)
    return point is not None and detection_hit(point, hand, box)


def run_trial(cfg: EventSuppressionConfig, spec: TrialSpec) -> dict[str, Any]:
    """One trial: shake + hand with pauses, sOMS per window; counts in and out."""
    n = round(cfg.duration_s / cfg.window_s)
    env = gym.make(
        "wander/Wander-v0",
        scene=cfg.scene,
        dvs=cfg.dvs,
        control_period_s=cfg.window_s,
        episode_seconds=cfg.duration_s + 1.0,
    )
    base = env.unwrapped
    try:
        _, info = env.reset(seed=spec.seed)
        anim = base.animator
        anim.trajectories = tuple(
            PausedTrajectory(tr, cfg.active_s, cfg.pause_s) for tr in anim.trajectories
        )
        policy = GazePolicy(cfg.shake, spec.seed + 1, cfg.window_s, 0.5)
        soms = SOMS(cfg.soms_params)
        ins = np.zeros(n, np.int64)
        outs = np.zeros(n, np.int64)
        obj_in = obj_out = bg_in = bg_out = 0
        gaze = np.zeros((n + 1, 2))
        m = cfg.windows_per_step
        windows: list[tuple[np.ndarray, np.ndarray]] = []  # (counts, mask) of this step
        hits = hit_steps = 0
        for k in range(n):
            t = k * cfg.window_s
            action = policy.act(info) if is_active(t, cfg.active_s, cfg.pause_s) else np.zeros(2)
            obs, _, _, _, info = env.step(np.asarray(action, np.float32))
            gaze[k + 1] = obs["gaze"]
            windows.append((obs["events"], info["object_mask"] > 0))
            if len(windows) < m and k < n - 1:
                continue
            # one sOMS step on the step's events; its map gates each window's events
            oms = soms.step(np.sum([c for c, _ in windows], axis=0)).oms.numpy() > 0
            hand = np.any([mk for _, mk in windows], axis=0)
            if hand.any() and is_active(t, cfg.active_s, cfg.pause_s):
                hit_steps += 1
                hits += hand_hit(oms, hand, cfg.hit_sigma_px)
            for j, (counts, mask) in enumerate(windows):
                kept = counts * oms
                i = k - len(windows) + 1 + j
                ins[i], outs[i] = int(counts.sum()), int(kept.sum())
                obj_in += int(counts[:, mask].sum())
                obj_out += int(kept[:, mask].sum())
                bg_in += int(counts[:, ~mask].sum())
                bg_out += int(kept[:, ~mask].sum())
            windows = []
    finally:
        env.close()
    active = np.array([is_active(k * cfg.window_s, cfg.active_s, cfg.pause_s) for k in range(n)])
    speed = np.linalg.norm(np.diff(gaze, axis=0), axis=1) / cfg.window_s
    total_in, total_out = int(ins.sum()), int(outs.sum())

    def frac(a: int, b: int) -> float:
        return a / b if b else math.nan

    return {
        "windows": n,
        "events_in_mean": float(ins.mean()),
        "events_in_std": float(ins.std()),
        "events_out_mean": float(outs.mean()),
        "events_out_std": float(outs.std()),
        "events_in_active_mean": float(ins[active].mean()),
        "events_in_pause_mean": float(ins[~active].mean()) if (~active).any() else math.nan,
        "suppressed_pct": 100.0 * (1.0 - frac(total_out, total_in)),
        "suppressed_active_pct": 100.0
        * (1.0 - frac(int(outs[active].sum()), int(ins[active].sum()))),
        "object_events_in": obj_in,
        "object_kept_pct": 100.0 * frac(obj_out, obj_in),
        "background_kept_pct": 100.0 * frac(bg_out, bg_in),
        "camera_speed_deg_s": float(speed[active].mean()),
        "hit_steps": hit_steps,
        "hand_hits": int(hits),
        "hand_hit_pct": 100.0 * frac(hits, hit_steps),
        "_events_in": ins,
        "_events_out": outs,
    }


def grid(cfg: EventSuppressionConfig) -> list[dict[str, Any]]:
    return [{"scene": cfg.scene}]


# ----------------------------------------------------------------------------------------
# Summary and plot


def _pooled(rows: list[Row], what: str) -> tuple[float, float]:
    m = np.array([float(r[f"{what}_mean"]) for r in rows])
    s = np.array([float(r[f"{what}_std"]) for r in rows])
    return pooled_mean_std(m, s)


def _hit_rate(rows: list[Row]) -> float:
    """Hits over all trials' scored steps, percent (nan when none)."""
    steps = sum(int(r["hit_steps"]) for r in rows)
    hits = sum(int(r["hand_hits"]) for r in rows)
    return 100.0 * hits / steps if steps else math.nan


def compare(cfg: EventSuppressionConfig, rows: list[Row]) -> list[Comparison]:
    """The paper's Table beside ours (windows pooled over trials)."""
    ref = PAPER_SUPPRESSION
    mi, si = _pooled(rows, "events_in")
    mo, so = _pooled(rows, "events_out")
    supp = np.array([float(r["suppressed_pct"]) for r in rows])
    obj = np.array([float(r["object_kept_pct"]) for r in rows])
    bg = np.array([float(r["background_kept_pct"]) for r in rows])
    w = f"{cfg.window_s * 1000:g} ms"
    return [
        Comparison("trials", "10", str(len(rows))),
        Comparison(
            f"events in per {w}",
            f"{ref['events_in_mean']} ± {ref['events_in_std']}",
            f"{mi:.2f} ± {si:.2f}",
            "128×128 sensor; ours is a simulated scene, theirs a hand before a Speck",
        ),
        Comparison(
            f"sOMS events out per {w}",
            f"{ref['events_out_mean']} ± {ref['events_out_std']}",
            f"{mo:.2f} ± {so:.2f}",
        ),
        Comparison(
            "events suppressed",
            f"{ref['suppressed_pct']} %",
            f"{supp.mean():.2f} % (± {supp.std():.2f} over trials)",
        ),
        Comparison(
            "hand hit (8×8 box around the OMS map's densest point)",
            "—",
            f"{_hit_rate(rows):.1f} % of {sum(int(r['hit_steps']) for r in rows)} sOMS steps",
            "active phases with the hand in view; the bar: ≥ 90 %",
        ),
        Comparison(
            "hand's events kept / background's kept",
            "—",
            f"{np.nanmean(obj):.1f} % / {np.nanmean(bg):.1f} %",
            "ground-truth mask; the paper cannot measure this",
        ),
    ]


def plot(
    cfg: EventSuppressionConfig, rows: list[Row], results_dir: Path, fig_dir: Path
) -> list[Path]:
    """The paper's Figure: events in (red) and out (blue) per window for the first trial,
    and the suppression of every trial."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig_dir.mkdir(parents=True, exist_ok=True)
    arts = load_artifacts(results_dir, rows[0]) if rows else {}
    fig, axes = plt.subplots(1, 2, figsize=(11, 3.5), gridspec_kw={"width_ratios": [3, 1]})
    if arts:
        t = np.arange(len(arts["events_in"])) * cfg.window_s
        axes[0].plot(t, arts["events_in"], color="tab:red", lw=0.8, label="DVS events")
        axes[0].plot(t, arts["events_out"], color="tab:blue", lw=0.8, label="sOMS events")
        axes[0].legend(loc="upper right")
    axes[0].set(
        xlabel="time (s)",
        ylabel=f"events per {cfg.window_s * 1000:g} ms",
        title=f"trial 0 (seed {rows[0]['seed'] if rows else '-'})",
    )
    axes[1].bar(range(len(rows)), [float(r["suppressed_pct"]) for r in rows], color="0.5")
    axes[1].axhline(PAPER_SUPPRESSION["suppressed_pct"], color="k", ls="--", label="paper")
    axes[1].set(xlabel="trial", ylabel="suppressed (%)", ylim=(0, 100))
    axes[1].set_xticks(range(len(rows)))
    axes[1].legend(loc="lower right")
    axes[1].set_title("events suppressed per trial", fontsize=9)
    sp = cfg.soms_params
    if sp == soms_preset("agent", sp.dt):
        which = f"agent's sOMS ({sp.norm} norm)"
    else:
        which = "paper-literal sOMS (min-max)" if sp.norm == "minmax" else f"sOMS ({sp.norm} norm)"
    fig.suptitle(
        f"Event suppression by the {which}, α = {sp.alpha:g}: events in and out per "
        f"{cfg.window_s * 1000:g} ms",
        fontsize=10,
    )
    path = save_figure(fig, fig_dir / "event_suppression.png")
    return [path]


EXPERIMENT = Experiment(
    name="event_suppression",
    description=(
        "Events per 2 ms before and after the sOMS while the camera shakes (fixational "
        "movements) and a hand-like object moves, with pauses (paper: 85.16 % suppressed)."
    ),
    config_type=EventSuppressionConfig,
    grid=grid,
    run_trial=run_trial,
    plot=plot,
    compare=compare,
)
