"""Forced saccades in the one loop (:mod:`experiments.paper.forced_saccades`): each target
forced at the first act after the one before ended, the episode ended by the step the
last one ended in; a fake agent whose saccade ends at its ``lasts``-th act."""

from __future__ import annotations

from types import SimpleNamespace
from typing import Any

import pytest

from experiments.paper.forced_saccades import ForcedSaccades, run_forced
from experiments.runs.episode import Recorder


class FakeAgent:
    """``saccade_to`` starts a saccade that ends (is appended to ``saccades``) in the
    ``lasts``-th ``act`` from its start; ``forced`` logs (target, gaze, step)."""

    def __init__(self, lasts: int) -> None:
        self.lasts = lasts
        self.resets = 0

    def reset(self) -> None:
        self.resets += 1
        self.saccades: list[tuple[int, int]] = []
        self.forced: list[tuple[tuple[int, int], tuple[float, float], int]] = []
        self._left: int | None = None

    def saccade_to(self, target: tuple[int, int], gaze: tuple[float, float], info: dict) -> None:
        self.forced.append((target, gaze, info["step"]))
        self._target, self._left = target, self.lasts

    def act(self, obs: Any, info: dict) -> int:
        if self._left is not None:
            self._left -= 1
            if self._left == 0:
                self.saccades.append(self._target)
                self._left = None
        return 0


class StepEnv:
    """Steps of 10 ms for ``seconds``; ``info["step"]`` the steps taken, the gaze its
    number."""

    def __init__(self, seconds: float) -> None:
        self.config = SimpleNamespace(episode_seconds=seconds, control_period_s=0.01)
        self.unwrapped = self

    def reset(self, seed: int | None = None) -> tuple[dict, dict]:
        self.k = 0
        return {"gaze": (0.0, 0.0)}, {"step": 0}

    def step(self, action: Any) -> tuple[dict, float, bool, bool, dict]:
        self.k += 1
        truncated = self.k * 0.01 >= self.config.episode_seconds - 1e-9
        return {"gaze": (float(self.k), 0.0)}, 0.0, False, truncated, {"step": self.k}


class Flags(Recorder):
    def __init__(self) -> None:
        self.log: list[tuple[int, bool, bool]] = []

    def on_step(self, env: Any, policy: Any, obs: Any, info: dict) -> None:
        self.log.append((info["step"], policy.started, policy.ended))


def test_each_target_is_forced_after_the_step_the_one_before_ended_in() -> None:
    agent, flags = FakeAgent(lasts=3), Flags()
    policy = ForcedSaccades(agent, [(1, 2), (3, 4)])
    steps = run_forced(StepEnv(10.0), policy, [flags], seed=0)
    assert steps == 6 and policy.done and agent.resets == 1
    assert agent.saccades == [(1, 2), (3, 4)]
    # the second forced from the gaze and info of the step the first ended in (step 3)
    assert agent.forced == [((1, 2), (0.0, 0.0), 0), ((3, 4), (3.0, 0.0), 3)]
    assert flags.log == [
        (1, True, False),
        (2, False, False),
        (3, False, True),
        (4, True, False),
        (5, False, False),
        (6, False, True),
    ]


def test_a_saccade_ending_in_the_act_that_forced_it_takes_one_step() -> None:
    policy = ForcedSaccades(FakeAgent(lasts=1), [(5, 5)])
    assert run_forced(StepEnv(1.0), policy, [], seed=0) == 1


def test_an_episode_that_ends_first_is_an_error() -> None:
    policy = ForcedSaccades(FakeAgent(lasts=4), [(1, 1), (2, 2)])
    with pytest.raises(RuntimeError, match="2 of 2 forced saccades started and the last had"):
        run_forced(StepEnv(0.05), policy, [], seed=0)
