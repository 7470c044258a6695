"""Small wrappers around the wander environments.

Example:
    >>> import gymnasium, wander_env
    >>> from wander_env.wrappers import EventColumns
    >>> env = EventColumns(gymnasium.make("wander/Wander-v0", scene="shelf"))
    >>> sorted(env.reset(seed=0)[1]["events"])
    ['p', 't', 'x', 'y']
    >>> env.close()
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np


def event_columns(events: np.ndarray) -> dict[str, np.ndarray]:
    """The event array as plain columns ``{"x", "y", "t", "p"}`` (copies)."""
    return {name: np.array(events[name]) for name in ("x", "y", "t", "p")}


class EventColumns(gym.Wrapper, gym.utils.RecordConstructorArgs):
    """Replaces ``info["events"]`` (a structured array) by its columns.

    Some generic tools compare or stack ``info`` values as plain numeric arrays
    (gymnasium's ``check_env`` determinism check, for one); they cannot handle a
    structured dtype. Nothing else changes.
    """

    def __init__(self, env: gym.Env) -> None:
        gym.utils.RecordConstructorArgs.__init__(self)
        gym.Wrapper.__init__(self, env)

    def reset(self, **kwargs: Any) -> tuple[Any, dict[str, Any]]:
        obs, info = self.env.reset(**kwargs)
        return obs, self._convert(info)

    def step(self, action: Any) -> tuple[Any, float, bool, bool, dict[str, Any]]:
        obs, reward, terminated, truncated, info = self.env.step(action)
        return obs, reward, terminated, truncated, self._convert(info)

    @staticmethod
    def _convert(info: dict[str, Any]) -> dict[str, Any]:
        return {**info, "events": event_columns(info["events"])}
