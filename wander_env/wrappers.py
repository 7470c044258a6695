"""Compatibility wrapper from before the env put its events in an :class:`EventPacket`.

``info["events"]`` of ``wander/Wander-v0`` and ``wander/Rig-v0`` is an
:class:`~wander_env.event_packet.EventPacket` as returned, so vector envs, ``check_env``
and pickling need no wrapper. :class:`EventPacketInfo` is kept for code that still adds
it: it boxes a bare structured array (an env of one's own that returns one) and leaves a
packet as it is.

Examples:
    >>> import gymnasium, wander_env
    >>> from wander_env.wrappers import EventPacketInfo
    >>> env = EventPacketInfo(gymnasium.make("wander/Wander-v0", scene="shelf"))
    >>> packet = env.reset(seed=0)[1]["events"]
    >>> len(packet), packet.events.dtype.names
    (0, ('x', 'y', 't', 'p'))
    >>> env.close()
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym

from wander_env.event_packet import EventPacket


class EventPacketInfo(gym.Wrapper, gym.utils.RecordConstructorArgs):
    """Makes ``info["events"]`` an :class:`EventPacket` (already one: unchanged)."""

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
        events = info["events"]
        return info if isinstance(events, EventPacket) else {**info, "events": EventPacket(events)}


__all__ = ["EventPacket", "EventPacketInfo"]
