"""The PTU's main sequence: forced pan saccades measured, beside the unit's trapezoid.

:func:`measure` forces saccades (:meth:`agents.attention.AttentionAgent.saccade_to`) of
the given amplitudes along the pan axis, alternating in direction
(:func:`main_sequence_targets`; :class:`~experiments.paper.forced_saccades.ForcedSaccades`
in the one episode loop), in a static scene rendered at 100 Hz (events play no part),
and measures (:class:`MainSequenceRecorder`) each one's pan amplitude reached, peak pan
speed (the tilt moves only the half pixel between the fovea and a pixel row) and
duration (command to standstill, to the 10 ms step); it fits the main sequence's two forms
(:mod:`experiments.paper.main_sequence`) to them and returns the columns of a trial's
row (:func:`fit_columns`). :func:`theory_main_sequence` is the PTU's rest-to-rest
trapezoid (:func:`wander_env.ptu.axis.move_duration`,
:func:`wander_env.ptu.axis.peak_speed`); :func:`fits_text` and :func:`plot` report the
fits stored in rows.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from agents.attention import AgentParams, AttentionAgent
from experiments.analysis.stats import number_text
from experiments.paper import main_sequence
from experiments.paper.env_block import trial_env
from experiments.paper.forced_saccades import ForcedSaccades, run_forced
from experiments.runs.episode import Recorder
from experiments.runs.tables import Row
from wander_env.camera import SPECK_HFOV_DEG, degrees_to_pixels, principal_point
from wander_env.env_config import WanderConfig
from wander_env.ptu.axis import move_duration, peak_speed
from wander_env.ptu.params import PTUParams
from wander_env.ptu.units import degrees_to_positions
from wander_env.viz import pyplot, save_figure

__all__ = [
    "MIN_FIT_AMPLITUDES",
    "MIN_INTERVAL_AMPLITUDES",
    "MainSequenceRecorder",
    "fit_columns",
    "fits_text",
    "main_sequence_targets",
    "measure",
    "plot",
    "theory_main_sequence",
]

# A main-sequence fit has two parameters: it needs a residual (3 amplitudes; fewer leave
# its columns empty) and, for its 95 % intervals, two residual degrees of freedom (4: with
# one, Student's t is 12.7 and a Vmax interval spans e.g. [−38, 120] °/s).
MIN_FIT_AMPLITUDES = 3
MIN_INTERVAL_AMPLITUDES = 4


def theory_main_sequence(
    amplitudes_deg: np.ndarray, ptu: PTUParams
) -> tuple[np.ndarray, np.ndarray]:
    """(peak speed °/s, duration s) of rest-to-rest pan moves of the PTU's trapezoid.

    >>> v, t = theory_main_sequence(np.array([25.714]), PTUParams())
    >>> round(float(v[0]), 1), round(float(t[0]), 3)
    (44.5, 0.732)
    """
    r = ptu.pan_resolution_arcsec
    speeds, durations = [], []
    for a in np.asarray(amplitudes_deg, float):
        d = degrees_to_positions(float(a), r)
        speeds.append(peak_speed(d, ptu.pan_speed, ptu.pan_accel, ptu.pan_base_speed))
        durations.append(move_duration(d, ptu.pan_speed, ptu.pan_accel, ptu.pan_base_speed))
    return np.asarray(speeds) * ptu.pan_deg_per_pos, np.asarray(durations)


def main_sequence_targets(
    amplitudes_deg: tuple[float, ...],
    width: int = 128,
    height: int = 128,
    hfov_deg: float = SPECK_HFOV_DEG,
) -> list[tuple[int, int]]:
    """Target pixels for pan saccades of the given amplitudes, alternating right and left
    (rows alternating 63 and 64 so the half-pixel tilt offsets cancel).

    >>> main_sequence_targets((10.0, 10.0))
    [(71, 63), (56, 64)]
    """
    cx = principal_point(width, height)[0]
    out = []
    for k, a in enumerate(amplitudes_deg):
        sign = 1.0 if k % 2 == 0 else -1.0
        x = min(max(round(cx + sign * degrees_to_pixels(a, width, hfov_deg)), 0), width - 1)
        out.append((int(x), height // 2 - 1 + k % 2))
    return out


class MainSequenceRecorder(Recorder):
    """Measures each forced saccade of an episode under
    :class:`~experiments.paper.forced_saccades.ForcedSaccades`: the pan amplitude
    reached (``amplitude_deg``, from the gaze it started at to the gaze after the step it
    ended in), the peak pan speed over its steps (``peak_velocity_deg_s``, the PTU's at
    each step's end) and its duration, command to standstill (``duration_s``: standstill
    is reached within the step after the last one that ended moving; ``step_s`` is the
    step)."""

    def __init__(self, step_s: float) -> None:
        self.step_s = step_s
        self.amplitude_deg: list[float] = []
        self.peak_velocity_deg_s: list[float] = []
        self.duration_s: list[float] = []
        self._start = self._t0 = self._t_stop = self._peak = 0.0  # of the one in flight

    def on_act(self, env: Any, policy: Any, obs: Any, info: dict[str, Any]) -> None:
        if policy.started:
            self._start = float(np.asarray(obs["gaze"], float)[0])
            self._t0 = self._t_stop = float(info["t"])
            self._peak = 0.0

    def on_step(self, env: Any, policy: Any, obs: Any, info: dict[str, Any]) -> None:
        self._peak = max(self._peak, abs(env.unwrapped.ptu.pan_velocity_deg_s))
        if info["moving"]:
            self._t_stop = float(info["t"])  # still moving at this step's end
        if policy.ended:
            self.amplitude_deg.append(abs(float(obs["gaze"][0]) - self._start))
            self.peak_velocity_deg_s.append(self._peak)
            self.duration_s.append(self._t_stop + self.step_s - self._t0)


def measure(
    env_block: WanderConfig,
    scene: str,
    agent_params: AgentParams,
    ptu: PTUParams,
    amplitudes_deg: tuple[float, ...],
    seed: int,
) -> dict[str, Any]:
    """The main sequence of ``ptu`` in ``scene`` (the rest of the env from ``env_block``):
    one forced saccade per amplitude, their fits; the measured series as ``_ms_*``
    artifacts."""
    env = trial_env(
        env_block,
        scene=scene,
        ptu=ptu,
        render_rate_hz=100.0,
        max_subframes=1,
        ground_truth=False,
        episode_seconds=1000.0,
    )
    agent = AttentionAgent(agent_params.on_env(env, fixational=False), seed=seed)
    series = MainSequenceRecorder(agent.params.step_s)
    try:
        run_forced(
            env, ForcedSaccades(agent, main_sequence_targets(amplitudes_deg)), [series], seed
        )
    finally:
        agent.close()
        env.close()
    amp, vpeak, dur = series.amplitude_deg, series.peak_velocity_deg_s, series.duration_s
    vfit = main_sequence.fit_saturating(amp, vpeak)
    dfit = main_sequence.fit_linear(amp, dur)
    return {
        "ms_amplitudes": vfit.n,
        "_ms_amplitude_deg": np.asarray(amp),
        "_ms_peak_velocity_deg_s": np.asarray(vpeak),
        "_ms_duration_s": np.asarray(dur),
        "ms_peak_velocity_max_deg_s": max(vpeak) if vpeak else math.nan,
        "ms_duration_max_s": max(dur) if dur else math.nan,
        # The main-sequence fits (parameters and 95 % intervals), per PTU setting.
        **fit_columns(vfit, "ms_v_"),
        **fit_columns(dfit, "ms_d_"),
    }


def fit_columns(fit: main_sequence.MainSequenceFit, prefix: str) -> dict[str, float]:
    """A fit's columns; the intervals NaN below :data:`MIN_INTERVAL_AMPLITUDES`."""
    out = fit.as_dict(prefix)
    if fit.n < MIN_INTERVAL_AMPLITUDES:
        out |= {k: math.nan for k in out if k.endswith(("_low", "_high"))}
    return out


def _f(r: Row, key: str, fmt: str = ".3f") -> str:
    """``r[key]`` formatted, "—" where missing or NaN."""
    return number_text(float(r.get(key, math.nan)), fmt)


def _too_few(n: int, minimum: int, what: str) -> str:
    return f"n too small for {what} ({n} amplitudes; {what} needs ≥ {minimum})"


def fits_text(r: Row) -> str:
    """The main-sequence fits stored in a row, as text ('' when the row has none); below
    :data:`MIN_FIT_AMPLITUDES` or :data:`MIN_INTERVAL_AMPLITUDES` amplitudes it says so."""
    n = float(r.get("ms_amplitudes", math.nan))
    if math.isnan(n):
        return ""
    if n < MIN_FIT_AMPLITUDES:
        return _too_few(int(n), MIN_FIT_AMPLITUDES, "a fit")

    def part(name: str, unit: str, fmt: str) -> str:
        v, lo, hi = (float(r.get(f"{name}{x}", math.nan)) for x in ("", "_low", "_high"))
        if math.isnan(v):
            return "— (not identifiable)"
        if math.isnan(lo) or math.isnan(hi):
            return f"{v:{fmt}} {unit}"
        return f"{v:{fmt}} [{lo:{fmt}}, {hi:{fmt}}] {unit}"

    text = (
        f"V = Vmax(1 − e^(−A/C)): Vmax {part('ms_v_vmax', '°/s', '.1f')}, "
        f"C {part('ms_v_c', '°', '.2f')} (R² {_f(r, 'ms_v_r2')}); D = D0 + k·A: "
        f"D0 {part('ms_d_d0', 's', '.3f')}, k {part('ms_d_k', 's/°', '.4f')} "
        f"(R² {_f(r, 'ms_d_r2')})"
    )
    if n < MIN_INTERVAL_AMPLITUDES:
        text += f"; {_too_few(int(n), MIN_INTERVAL_AMPLITUDES, 'an interval')}"
    return text


def _row_fits(r: Row) -> tuple[tuple[float, float] | None, tuple[float, float] | None]:
    """The (Vmax, C) and (D0, k) fitted parameters stored in a row (None where absent)."""

    def get(*keys: str) -> tuple[float, float] | None:
        v = tuple(float(r.get(k, math.nan)) for k in keys)
        return v if all(math.isfinite(x) for x in v) else None  # type: ignore[return-value]

    return get("ms_v_vmax", "ms_v_c"), get("ms_d_d0", "ms_d_k")


def plot(
    series: Sequence[tuple[Row, PTUParams, dict[str, Any]]],
    max_amplitude_deg: float,
    scene: str,
    path: Path,
) -> Path:
    """Amplitude against peak velocity and duration, one series per (row, its PTU, its
    :func:`measure` artifacts), with the PTU's trapezoid and the row's fits, into
    ``path``."""
    plt = pyplot()

    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
    amps = np.linspace(0.5, max_amplitude_deg, 100)
    for k, (r, ptu, arts) in enumerate(series):
        label = (
            f"{ptu.pan_speed * ptu.pan_deg_per_pos:.0f} °/s, "
            f"{ptu.pan_accel * ptu.pan_deg_per_pos:.0f} °/s², {r['ptu_preset']}"
        )
        v, t = theory_main_sequence(amps, ptu)
        c = f"C{k}"
        ms_amp = arts["ms_amplitude_deg"]
        mk = dict(color=c, marker="osD^v<>p"[k % 8], ls="none", mfc="none" if k == 0 else c)
        axes[0].plot(ms_amp, arts["ms_peak_velocity_deg_s"], label=label, **mk)
        axes[0].plot(amps, v, "--", color=c, lw=0.8)
        axes[1].plot(ms_amp, arts["ms_duration_s"], label=label, **mk)
        axes[1].plot(amps, t, "--", color=c, lw=0.8)
        vfit, dfit = _row_fits(r)
        fit_style = dict(color=c, lw=1.4, alpha=0.6)
        if vfit is not None:
            v_label = f"fit: Vmax {vfit[0]:.1f} °/s, C {vfit[1]:.2f}° (R² {_f(r, 'ms_v_r2')})"
            v_fit = main_sequence.saturating(amps, *vfit)
            axes[0].plot(amps, v_fit, "-", label=v_label, **fit_style)
        if dfit is not None:
            d_label = f"fit: D0 {dfit[0]:.3f} s, k {dfit[1]:.4f} s/° (R² {_f(r, 'ms_d_r2')})"
            axes[1].plot(amps, main_sequence.linear(amps, *dfit), "-", label=d_label, **fit_style)
        if len(ms_amp) < MIN_FIT_AMPLITUDES:  # say so in the legends: no line is drawn
            for ax in axes:
                ax.plot(
                    [],
                    [],
                    " ",
                    label=f"no fit: {_too_few(len(ms_amp), MIN_FIT_AMPLITUDES, 'a fit')}",
                )
    axes[0].set(xlabel="saccade amplitude (°)", ylabel="peak pan velocity (°/s)")
    axes[0].set_title("peak velocity: V = Vmax(1 − e^(−A/C))", fontsize=9)
    axes[1].set(xlabel="saccade amplitude (°)", ylabel="duration, command to standstill (s)")
    axes[1].set_title("duration: D = D0 + k·A", fontsize=9)
    for ax in axes:
        ax.legend(fontsize=6.5)
    fig.suptitle(
        f"Main sequence: forced pan saccades in the static {scene} scene, "
        "one series per PTU setting (markers: measured; solid: fit; dashed: the PTU's "
        "rest-to-rest trapezoid)",
        fontsize=9,
    )
    return save_figure(fig, path)
