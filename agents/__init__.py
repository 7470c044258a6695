"""The attention pipeline: sOMS, proto-object saliency, spiking attention control,
fixational eye movements, and the composed :class:`AttentionAgent`.

``agents.AttentionAgent`` and ``agents.AgentParams`` are loaded on first use, so that
importing a light module (e.g. ``agents.fixation``) does not pull in torch and nengo.

Examples:
    >>> import agents
    >>> agents.AgentParams().window_s
    0.124
"""

from __future__ import annotations

from typing import Any

__all__ = ["AgentParams", "AttentionAgent"]


def __getattr__(name: str) -> Any:
    if name in __all__:
        from agents import attention

        return getattr(attention, name)
    raise AttributeError(f"module 'agents' has no attribute {name!r}")
