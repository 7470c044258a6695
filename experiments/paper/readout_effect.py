"""The readout's effect on the agent (issue 35, item 5): what Speck's readout
(:mod:`wander_env.readout`) drops, filters and holds back of the events the agent would
see, in three scripted cases, for the presets ``ideal`` (the reference: every stage off),
``speck`` and ``speck_filtered``, several seeds.

The cases (:data:`CASES`), each an episode of the env with ``dvs="speck"``:

- ``hand``: the hand trials' "both" phase: the hand scene (the event-suppression trials'
  hand waved at 2 Hz) with the camera's slight shake of those trials
  (:class:`~experiments.paper.event_suppression_protocol.Shake`'s defaults: a 1° circle at
  18.85°/s about the start gaze);
- ``gratings_saccade``: the gratings scene, a 10° pan saccade at ``saccade_step``;
- ``office_saccade``: the office scene, a 20° pan saccade at ``saccade_step``.

A saccade is the PTU's target set ``amplitude_deg`` to the left of where it looks
(:meth:`~wander_env.env_base.CameraEnv.aim`); the shake aims the PTU at the circle's
point at each step's start; every other step's action is zero (:class:`CaseAim`, the
policy of :func:`experiments.runs.episode.run_episode`). The counters come from
``info["readout"]`` of each step, summed over the episode in memory
(:class:`~experiments.runs.recorders.ReadoutRecorder`); :func:`table` gives each as a
share of the events in, mean with its 95 % interval over seeds
(:func:`experiments.analysis.stats.mean_ci`), the peak events/s of a step and the events
still held (arbiter queue and unsent packets) at a step's end: the latency the readout
adds, in events.

Run: ``python -m experiments.paper.readout_effect --seeds 5 --steps 100 --saccade-step 5
--figure docs/img/readout_effect.png`` (the table and the picture in docs/readout.md,
"The readout's effect on the agent").
"""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from experiments.analysis.stats import ci_text, mean_ci
from experiments.paper.event_suppression_protocol import Shake
from wander_env.readout import LOST
from wander_env.viz import pyplot, save_figure

__all__ = [
    "CASES",
    "PRESETS",
    "Case",
    "CaseAim",
    "CaseResult",
    "figure",
    "identity_gap",
    "run_case",
    "shares",
    "table",
]

#: The presets compared; ``ideal`` is the reference.
PRESETS: tuple[str, ...] = ("ideal", "speck", "speck_filtered")


@dataclass(frozen=True)
class Case:
    """A scripted case: a scene, a pan saccade of ``amplitude_deg`` (0: none) and the
    camera's ``shake`` (None: the camera stays still but for the saccade)."""

    name: str
    scene: str
    amplitude_deg: float
    shake: Shake | None = None


CASES: tuple[Case, ...] = (
    Case("hand", "hand", 0.0, Shake()),
    Case("gratings_saccade", "gratings", 10.0),
    Case("office_saccade", "office", 20.0),
)


@dataclass(frozen=True)
class CaseResult:
    """One episode's readout: the counters summed over its steps (``pending``: at the
    episode's end), the most events in one step, the most held at a step's end, and the
    control period (s)."""

    case: str
    preset: str
    seed: int
    totals: dict[str, int]
    peak_in_step: int
    peak_pending: int
    control_period_s: float

    @property
    def peak_eps(self) -> float:
        """The peak events/s into the readout over a step."""
        return self.peak_in_step / self.control_period_s


def identity_gap(totals: dict[str, int]) -> int:
    """``in − (out + lost + pending)`` over an episode that starts empty: 0 when every
    event is accounted for.

    >>> identity_gap({"in": 10, "out": 6, "dropped_queue": 1, "filtered_noise": 2,
    ...               "pending": 1, "killed": 0, "filtered_hot": 0, "filtered_flicker": 0,
    ...               "channel_off": 0, "outside_roi": 0})
    0
    """
    return totals["in"] - totals["out"] - sum(totals[k] for k in LOST) - totals["pending"]


class CaseAim:
    """The policy of a case: no agent; before each step it aims the PTU (on ``env``)
    straight at the shake's circle point (if the case shakes) and, before step
    ``saccade_step``, ``amplitude_deg`` to the left of its target (if the case has a
    saccade); every action is zero."""

    def __init__(self, env: Any, case: Case, saccade_step: int) -> None:
        self.base = env.unwrapped
        self.case, self.saccade_step = case, saccade_step
        self.period = self.base.config.control_period_s
        self.zero = np.zeros(2, np.float32)

    def reset(self) -> None:
        self.home = self.base.target_deg
        self.i = 0

    def act(self, obs: Any, info: dict[str, Any]) -> np.ndarray:
        i, case, base = self.i, self.case, self.base
        if case.shake is not None:
            dp, dt = case.shake.angles(i * self.period, 0.0, 1)
            base.aim(self.home[0] + dp, self.home[1] + dt)
        if i == self.saccade_step and case.amplitude_deg:
            pan, tilt = base.target_deg
            base.aim(pan + case.amplitude_deg, tilt)
        self.i += 1
        return self.zero


def run_case(case: Case, preset: str, seed: int, steps: int, saccade_step: int) -> CaseResult:
    """One episode of ``case`` with the readout ``preset``: ``steps`` control steps, the
    saccade (if any) commanded before step ``saccade_step``; the counters kept in memory
    (:class:`~experiments.runs.recorders.ReadoutRecorder`, ``pending`` at the end)."""
    if not 0 <= saccade_step < steps:
        raise ValueError(f"saccade_step: {saccade_step} must be in [0, steps={steps})")
    import gymnasium

    import wander_env  # noqa: F401  (registers the env)
    from experiments.runs.episode import run_episode
    from experiments.runs.recorders import ReadoutRecorder

    env = gymnasium.make("wander/Wander-v0", scene=case.scene, readout=preset, dvs="speck")
    readout = ReadoutRecorder(levels=("pending",))
    try:
        policy = CaseAim(env, case, saccade_step)
        run_episode(env, policy, steps, (readout,), seed=seed)
    finally:
        env.close()
    totals, peaks = readout.totals or {}, readout.peaks
    return CaseResult(case.name, preset, seed, totals, peaks["in"], peaks["pending"], policy.period)


def shares(results: Sequence[CaseResult], keys: tuple[str, ...]) -> list[float]:
    """Per episode, the counters ``keys`` together as a share of its events in; NaN for an
    episode with none in (skipped by :func:`experiments.analysis.stats.mean_ci`).

    >>> r = CaseResult("c", "p", 0, {"in": 8, "out": 6, "pending": 1}, 8, 1, 0.01)
    >>> shares([r, CaseResult("c", "p", 1, {"in": 0, "out": 0, "pending": 0}, 0, 0, 0.01)],
    ...        ("out", "pending"))
    [0.875, nan]
    """
    return [
        sum(r.totals[k] for k in keys) / r.totals["in"] if r.totals["in"] else math.nan
        for r in results
    ]


def _share(results: Sequence[CaseResult], key: str) -> str:
    """``key``'s mean count per episode and its share of in, mean [95 % interval]."""
    count = np.mean([r.totals[key] for r in results])
    return f"{count:,.0f}: {ci_text(mean_ci(shares(results, (key,))), '.2%')}"


def table(results: Sequence[CaseResult]) -> str:
    """The markdown table: per case and preset, mean events in per episode; delivered,
    dropped by the queue and filtered (noise, hot, flicker), each its mean count per
    episode and its share of in (mean [95 % interval] over seeds); the peak events/s of
    a step and the most events held at a step's end (over seeds)."""
    head = (
        "| case | preset | in / episode | delivered | dropped (queue) | filtered noise | "
        "filtered hot | filtered flicker | peak in (ev/s) | held at step end (max) |\n"
        + "|---" * 10
        + "|"
    )
    lines = [head]
    groups: dict[tuple[str, str], list[CaseResult]] = {}
    for r in results:
        groups.setdefault((r.case, r.preset), []).append(r)
    for (case, preset), rs in groups.items():
        cells = [
            case,
            preset,
            f"{np.mean([r.totals['in'] for r in rs]):,.0f}",
            _share(rs, "out"),
            _share(rs, "dropped_queue"),
            _share(rs, "filtered_noise"),
            _share(rs, "filtered_hot"),
            _share(rs, "filtered_flicker"),
            f"{max(r.peak_eps for r in rs):,.0f}",
            f"{max(r.peak_pending for r in rs):,}",
        ]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


#: The picture's parts of the events in, in the order stacked, with their colours.
PARTS: tuple[tuple[str, tuple[str, ...], str], ...] = (
    ("delivered", ("out",), "#4c72b0"),
    ("dropped (queue)", ("dropped_queue",), "#c44e52"),
    ("filtered noise", ("filtered_noise",), "#dd8452"),
    ("filtered hot pixel", ("filtered_hot",), "#8172b3"),
    ("filtered flicker", ("filtered_flicker",), "#937860"),
    (
        "other (killed, channel off, outside ROI)",
        ("killed", "channel_off", "outside_roi"),
        "#8c8c8c",
    ),
    ("held at the end", ("pending",), "#55a868"),
)


def figure(results: Sequence[CaseResult], path: Path, seeds: int, seconds: float) -> Path:
    """A stacked bar per case and preset: the share of the events in that the readout
    delivered, dropped, filtered and held at the episode's end (means over the seeds with
    events in, :func:`shares`; none: an empty bar); returns ``path``."""
    plt = pyplot()

    groups: dict[tuple[str, str], list[CaseResult]] = {}
    for r in results:
        groups.setdefault((r.case, r.preset), []).append(r)
    labels = [f"{case}\n{preset}" for case, preset in groups]
    fig, ax = plt.subplots(figsize=(9.0, 4.8))
    left = np.zeros(len(groups))
    for name, keys, colour in PARTS:
        share = np.nan_to_num([100.0 * mean_ci(shares(rs, keys))[0] for rs in groups.values()])
        ax.barh(labels, share, left=left, color=colour, label=name)
        left += share
    ax.invert_yaxis()
    ax.set_xlim(0, 100)
    ax.set_xlabel("share of the events into the readout (%)")
    ax.set_title(
        "Speck's readout: what it delivers, drops and filters\n"
        f"(assumed 1 Meps arbiter, 1,024-event queue; means over {seeds} seeds, "
        f"{seconds:g} s episodes)",
        fontsize=10,
    )
    ax.legend(loc="lower left", bbox_to_anchor=(1.01, 0.0), fontsize=8, frameon=False)
    return save_figure(fig, path)


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m experiments.paper.readout_effect``: run every case and preset over
    ``--seeds`` seeds (0, 1, ...) and print the table."""
    ap = argparse.ArgumentParser(prog="python -m experiments.paper.readout_effect")
    ap.add_argument("--seeds", type=int, default=5, help="seeds 0..N-1 (default 5)")
    ap.add_argument("--steps", type=int, default=100, help="control steps per episode")
    ap.add_argument("--saccade-step", type=int, default=5, help="step the saccade starts")
    ap.add_argument("--figure", type=Path, default=None, help="write the picture here (PNG)")
    a = ap.parse_args(argv)
    if a.seeds < 1 or a.steps < 1 or not 0 <= a.saccade_step < a.steps:
        ap.error(
            f"--seeds {a.seeds} and --steps {a.steps} must be >= 1 and --saccade-step "
            f"{a.saccade_step} in [0, steps)"
        )
    results = [
        run_case(case, preset, seed, a.steps, a.saccade_step)
        for case in CASES
        for preset in PRESETS
        for seed in range(a.seeds)
    ]
    bad = [(r.case, r.preset, r.seed) for r in results if identity_gap(r.totals)]
    print(table(results))
    if a.figure is not None:
        figure(results, a.figure, a.seeds, a.steps * results[0].control_period_s)
    if bad:
        print(f"accounting identity broken in {bad}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
