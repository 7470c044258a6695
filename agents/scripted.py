"""Scripted gaze policies, no attention: what ``wander record`` and the fidelity benchmark
move the camera with.

- ``still``: the camera holds its gaze;
- ``fixational``: fixational eye movements only (a new 8-step random walk of
  ±60 PTU positions every 124 ms, :mod:`agents.fixation`);
- ``saccades``: a saccade to a random pixel every ``saccade_interval_s``, with
  fixational movements in between.

Examples:
    >>> policy = GazePolicy("still", seed=0, dt_s=0.002, saccade_interval_s=0.5)
    >>> policy.act({}, {"moving": False}).tolist()
    [0.0, 0.0]
"""

from __future__ import annotations

import typing
from typing import Any, Literal

import numpy as np

from agents.fixation import FixationalMovements, FixationParams

#: A scripted policy's name.
Policy = Literal["still", "fixational", "saccades"]
POLICIES: tuple[str, ...] = typing.get_args(Policy)


class GazePolicy:
    """The scripted policies of :data:`POLICIES`, seeded: ``act(obs, info)`` returns the
    next action (relative gaze offset in env action units) given the env's ``info`` (its
    ``moving`` flag; the observation plays no part)."""

    def __init__(self, name: str, seed: int, dt_s: float, saccade_interval_s: float) -> None:
        self.name, self.dt_s, self.interval = name, dt_s, saccade_interval_s
        self.rng = np.random.default_rng(seed)
        self.fixation = FixationalMovements(FixationParams(), self.rng)
        self.fixation.start()
        self.t_fix = 0.0
        self.t = 0.0

    def act(self, obs: Any, info: dict[str, Any]) -> np.ndarray:
        action = np.zeros(2, np.float32)
        if self.name == "saccades" and self.t > 0 and self.t % self.interval < self.dt_s / 2:
            action = self.rng.uniform(-0.6, 0.6, 2).astype(np.float32)
            self.fixation.start()
            self.t_fix = self.t
        elif self.name != "still" and not info["moving"]:
            if self.fixation.done:
                self.fixation.start(after_saccade=False)
                self.t_fix = self.t
            if self.fixation.due(self.t - self.t_fix):
                action = np.asarray(self.fixation.next_offset().action, np.float32)
        self.t += self.dt_s
        return np.clip(action, -1.0, 1.0)
