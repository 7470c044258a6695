"""Wrappers that make the env's raw event arrays travel through generic tools.

``info["events"]`` is a structured array whose length changes from step to step.
Gymnasium's vector envs batch every ``ndarray`` in ``info`` assuming a fixed
shape, and ``check_env`` compares them with ``np.allclose``: both fail on it.
:class:`EventPacketInfo` puts the array in an :class:`EventPacket`, which they
treat as an opaque object (vector envs gather one per env in an object array).

Example:
    >>> import gymnasium, wander_env
    >>> from wander_env.wrappers import EventPacketInfo
    >>> env = EventPacketInfo(gymnasium.make("wander/Wander-v0", scene="shelf"))
    >>> packet = env.reset(seed=0)[1]["events"]
    >>> len(packet), packet.events.dtype.names
    (0, ('x', 'y', 't', 'p'))
    >>> env.close()
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import gymnasium as gym
import numpy as np


@dataclass(frozen=True, eq=False)
class EventPacket:
    """One step's events (the shared structured array) as an opaque value."""

    events: np.ndarray

    def __len__(self) -> int:
        return len(self.events)

    def __eq__(self, other: object) -> bool:
        return isinstance(other, EventPacket) and np.array_equal(self.events, other.events)

    def __hash__(self) -> int:
        return hash(self.events.tobytes())


class EventPacketInfo(gym.Wrapper, gym.utils.RecordConstructorArgs):
    """Replaces ``info["events"]`` by an :class:`EventPacket`; nothing else changes."""

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
        return {**info, "events": EventPacket(info["events"])}
