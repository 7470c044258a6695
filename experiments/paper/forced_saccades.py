"""Forced saccades as an episode: the attention agent made to saccade to given pixels in
turn (:meth:`agents.attention.AttentionAgent.saccade_to`), each forced at the first step
after the one before it ended, stepped by the one loop
(:func:`experiments.runs.episode.run_episode`) until the last has ended.

:class:`ForcedSaccades` is the policy (its ``started``/``ended`` say what the last
``act`` did, for the recorders that measure a saccade); :func:`run_forced` runs the
episode. Used by :mod:`experiments.paper.sac_accuracy` (one saccade) and
:mod:`experiments.paper.ptu_main_sequence` (one per amplitude).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from experiments.runs.episode import Recorder, run_episode

if TYPE_CHECKING:
    from agents.attention import AttentionAgent

__all__ = ["ForcedSaccades", "run_forced"]


class ForcedSaccades:
    """A policy: ``agent`` (its fixational walk off) made to saccade to each of
    ``targets`` (pixels) in turn from the gaze it sees, the next one forced at the first
    ``act`` after the one before it ended; each action is the agent's.

    After each ``act``: ``started``, whether it forced a saccade; ``ended``, whether the
    saccade in flight ended in it (the step it returns is still the saccade's); ``done``,
    whether every target's saccade has ended.
    """

    def __init__(self, agent: AttentionAgent, targets: Sequence[tuple[int, int]]) -> None:
        self.agent = agent
        self.targets = tuple(targets)
        self._clear()

    def _clear(self) -> None:
        self.forced = 0  # saccades forced so far
        self.in_flight = False
        self.started = self.ended = False
        self._before = 0  # the agent's saccades before the one in flight

    def reset(self) -> None:
        """After the env's reset: the agent's reset, no saccade forced yet."""
        self.agent.reset()
        self._clear()

    def act(self, obs: Any, info: dict[str, Any]) -> np.ndarray:
        agent = self.agent
        self.started = not self.in_flight and self.forced < len(self.targets)
        if self.started:
            self._before = len(agent.saccades)
            gaze = obs["gaze"]
            agent.saccade_to(self.targets[self.forced], (float(gaze[0]), float(gaze[1])), info)
            self.forced += 1
            self.in_flight = True
        action = agent.act(obs, info)
        self.ended = self.in_flight and len(agent.saccades) > self._before
        if self.ended:
            self.in_flight = False
        return action

    @property
    def done(self) -> bool:
        return self.forced == len(self.targets) and not self.in_flight


def run_forced(env: Any, policy: ForcedSaccades, recorders: Sequence[Recorder], seed: int) -> int:
    """Reset ``env`` with ``seed`` and step it under ``policy`` until its last saccade
    ended (the step it ended in taken); the steps taken. Raises when the env's episode
    (``episode_seconds``) ended first."""
    config = env.unwrapped.config
    limit = math.ceil(config.episode_seconds / config.control_period_s)
    steps = run_episode(env, policy, limit, recorders, seed=seed, until=lambda: policy.done)
    if not policy.done:
        raise RuntimeError(
            f"{policy.forced} of {len(policy.targets)} forced saccades started and the last "
            f"had not ended when the episode ended ({config.episode_seconds:g} s)"
        )
    return steps
