"""The hand trials' protocol (pure): the phases, the camera's shake, the phase clocks.

A trial of :mod:`experiments.paper.event_suppression` is the four phases of
:data:`PHASES` in a seeded order (its ``schedule``). The shake (:class:`Shake`) runs only
in :data:`SHAKE_PHASES`, the hand only in :data:`HAND_PHASES`: each on its own
:class:`PhaseClock`, which a pause stops; :func:`recording` gives what one phase's row
records (a lead-in, then the phase) and where both clocks stand at its start;
:class:`ClockedTrajectory` runs a scene object's trajectory on a clock.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from experiments.runs.episode import Recorder
from wander_env.actions import gaze_degrees_to_action

__all__ = [
    "HAND_PHASES",
    "PHASES",
    "SHAKE_PHASES",
    "ClockedTrajectory",
    "PhaseClock",
    "Recording",
    "Segment",
    "Shake",
    "ShakeScript",
    "WindowRecorder",
    "recording",
    "shake_start",
]

#: The phases of a trial (the paper's "shaking ... moving a hand ... pauses").
PHASES: tuple[str, ...] = ("shake", "hand", "both", "pause")
#: Phases in which the camera shakes / the hand waves.
SHAKE_PHASES: frozenset[str] = frozenset({"shake", "both"})
HAND_PHASES: frozenset[str] = frozenset({"hand", "both"})


@dataclass(frozen=True)
class Shake:
    """The camera's slight shake: the gaze circles ``amplitude_deg`` (radius) about its
    home at ``speed_deg_s`` (so ``speed_deg_s / (2π · amplitude_deg)`` turns a second).

    >>> s = Shake(amplitude_deg=1.0, speed_deg_s=2 * math.pi * 3.0)
    >>> round(s.hz, 6), [round(a, 6) for a in s.angles(0.0, 0.0, 1)]
    (3.0, [0.0, 0.0])
    >>> [round(a, 6) for a in s.angles(1 / 12, 0.0, 1)]   # a quarter turn
    [-1.0, 1.0]
    """

    amplitude_deg: float = 1.0
    speed_deg_s: float = 18.85

    def __post_init__(self) -> None:
        for name in ("amplitude_deg", "speed_deg_s"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"shake.{name} must be > 0, got {v!r}")

    @property
    def hz(self) -> float:
        """Turns per second."""
        return self.speed_deg_s / (2.0 * math.pi * self.amplitude_deg)

    def angles(self, clock_s: float, start_rad: float, sense: int) -> tuple[float, float]:
        """(pan, tilt) in degrees at ``clock_s`` of shaking: on the circle through home
        (0, 0) whose point at clock 0 is home, started at angle ``start_rad``, turning
        counter-clockwise (``sense`` 1) or clockwise (−1)."""
        a = self.amplitude_deg
        theta = start_rad + sense * 2.0 * math.pi * self.hz * clock_s
        return (
            a * (math.cos(theta) - math.cos(start_rad)),
            a * (math.sin(theta) - math.sin(start_rad)),
        )


@dataclass(frozen=True)
class Segment:
    """One phase of a trial and its length (s)."""

    phase: str
    length_s: float


def shake_start(seed: int) -> tuple[float, int]:
    """The shake's start angle (rad) and sense (±1) of a trial, drawn from ``seed``."""
    rng = np.random.default_rng([seed, 26])
    return float(rng.uniform(0.0, 2.0 * math.pi)), int(rng.choice((-1, 1)))


class PhaseClock:
    """A clock that runs only in some phases: ``clock(t)`` for a recording made of
    ``segments`` (from env time 0), starting at ``start_s``.

    >>> c = PhaseClock((Segment("pause", 0.1), Segment("hand", 0.5)), {"hand"}, 2.0)
    >>> c(0.05), c(0.3), c(0.9)   # the last phase runs on past its end
    (2.0, 2.2, 2.8)
    """

    def __init__(
        self, segments: Sequence[Segment], running: frozenset[str] | set[str], start_s: float
    ) -> None:
        self.segments, self.running, self.start_s = tuple(segments), frozenset(running), start_s

    def __call__(self, t: float) -> float:
        c, t0 = self.start_s, 0.0
        for i, seg in enumerate(self.segments):
            last = i == len(self.segments) - 1
            span = t - t0 if last else min(max(t - t0, 0.0), seg.length_s)
            if seg.phase in self.running:
                c += max(span, 0.0)
            t0 += seg.length_s
            if t < t0:
                break
        return c


def recording(
    sched: Sequence[Segment], phase: str, lead_s: float
) -> tuple[tuple[Segment, ...], float, float]:
    """What the row of ``phase`` records: the last ``lead_s`` of the phase before it (a
    pause before the first) then ``phase``; and the shake's and the hand's clocks at the
    recording's start (their running time in the trial before it).

    >>> sched = (Segment("hand", 0.5), Segment("shake", 0.4), Segment("both", 0.6))
    >>> recording(sched, "both", 0.1)
    ((Segment(phase='shake', length_s=0.1), Segment(phase='both', length_s=0.6)), 0.3, 0.5)
    """
    i = [s.phase for s in sched].index(phase)
    prev = sched[i - 1].phase if i > 0 else "pause"
    before = sched[:i]
    segs = (Segment(prev, lead_s), sched[i])
    shake0 = sum(s.length_s for s in before if s.phase in SHAKE_PHASES)
    hand0 = sum(s.length_s for s in before if s.phase in HAND_PHASES)
    if prev in SHAKE_PHASES:
        shake0 -= lead_s
    if prev in HAND_PHASES:
        hand0 -= lead_s
    return segs, round(shake0, 9), round(hand0, 9)


class ClockedTrajectory:
    """A trajectory run on a :class:`PhaseClock`, ``scale`` times as fast."""

    def __init__(self, inner: Any, clock: PhaseClock, scale: float = 1.0) -> None:
        self.inner, self.clock, self.scale = inner, clock, scale

    def position(self, t: float) -> np.ndarray:
        return self.inner.position(self.scale * self.clock(t))


# ----------------------------------------------------------------------------------------
# A row recorded: the policy that steers the gaze, the windows kept


@dataclass(frozen=True)
class Recording:
    """A row's windows: events per window (n, 2, H, W), the hand's mask (n, H, W), the
    gaze (n, 2) degrees and the hand's image centre (n, 2) px at each window's end."""

    counts: np.ndarray
    masks: np.ndarray
    gaze: np.ndarray
    hand_px: np.ndarray


class ShakeScript:
    """The policy of a row of the hand trials, no agent: after the env's reset the hand's
    trajectories run on the hand's clock (``hand_clock``, their speed times ``scale``);
    before window ``k`` the PTU is steered to ``shake``'s point at the window's end
    (``window_s`` each) on the shake's clock (``shake_clock``; ``start`` and ``sense``
    the trial's)."""

    def __init__(
        self,
        env: Any,
        shake: Shake,
        window_s: float,
        clocks: tuple[PhaseClock, PhaseClock],
        scale: float,
        start: float,
        sense: int,
    ) -> None:
        self.base = env.unwrapped
        self.shake, self.window_s = shake, window_s
        self.scale, self.start, self.sense = scale, start, sense
        self.shake_clock, self.hand_clock = clocks
        self.k = 0

    def reset(self) -> None:
        anim = self.base.animator
        anim.trajectories = tuple(
            ClockedTrajectory(tr, self.hand_clock, self.scale) for tr in anim.trajectories
        )
        self.k = 0

    def act(self, obs: Any, info: dict[str, Any]) -> np.ndarray:
        cam = self.base.scene.camera
        self.k += 1
        want = self.shake.angles(self.shake_clock(self.k * self.window_s), self.start, self.sense)
        pan, tilt = np.subtract(want, self.base.ptu.target_deg)
        action = gaze_degrees_to_action(pan, tilt, cam.width, cam.height, cam.hfov_deg)
        return action.astype(np.float32)


class WindowRecorder(Recorder):
    """A row's :class:`Recording`, a window (step) at a time, in memory: the events, the
    hand's mask, the gaze and the hand's image centre at the window's end."""

    def __init__(self, n: int, height: int, width: int) -> None:
        self.recording = Recording(
            np.zeros((n, 2, height, width), np.uint16),
            np.zeros((n, height, width), bool),
            np.zeros((n, 2)),
            np.zeros((n, 2)),
        )
        self.k = 0

    def on_step(self, env: Any, policy: Any, obs: Any, info: dict[str, Any]) -> None:
        rec, k = self.recording, self.k
        rec.counts[k] = obs["events"]
        rec.masks[k] = info["object_mask"] > 0
        rec.gaze[k] = obs["gaze"]
        rec.hand_px[k] = info["objects"][0]["centre_px"]
        self.k += 1
