"""The frame modes by name: each ``WanderConfig.frames`` value, the source class that
makes it and a one-line description (what ``wander --frames`` lists).

This module imports nothing heavy: the names and descriptions are read where no
renderer is wanted (the configuration, the command line's help); a mode's class is
imported when an env asks for it (:meth:`RegisteredMode.source_class`).

Examples:
    >>> MODE_NAMES
    ('keyframes', 'exact', 'panorama')
    >>> REGISTRY["exact"].description
    'render every frame (every tick and adaptive sub-frame): the reference'
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from wander_env.dvs import DVSEmulator
    from wander_env.frames.source import FrameParams, FrameSource
    from wander_env.frames.stage import Stage

__all__ = ["MODE_NAMES", "REGISTRY", "RegisteredMode", "frame_modes_help", "make_source"]


@dataclass(frozen=True)
class RegisteredMode:
    """A frame mode: its name, the class (``module:Class`` in this package) that makes
    its frames and what it does, in one line."""

    name: str
    source: str
    description: str

    def source_class(self) -> type[FrameSource]:
        """The :class:`~wander_env.frames.source.FrameSource` subclass (imported now)."""
        module, _, cls = self.source.partition(":")
        return getattr(importlib.import_module(f"wander_env.frames.{module}"), cls)


#: Every frame mode by name, the default first.
REGISTRY: dict[str, RegisteredMode] = {
    mode.name: mode
    for mode in (
        RegisteredMode(
            "keyframes",
            "keyframes:KeyframeFrames",
            "render keys where the image motion needs them and synthesise the frames in "
            "between from the keys' depth and motion layers (the default)",
        ),
        RegisteredMode(
            "exact",
            "exact:ExactFrames",
            "render every frame (every tick and adaptive sub-frame): the reference",
        ),
        RegisteredMode(
            "panorama",
            "panorama:PanoramaFrames",
            "warp a cube map of the static world rendered once per reset, render keys only "
            "for the moving objects (keyframes where the camera centre moves)",
        ),
    )
}
#: The names of :data:`REGISTRY`, the default first.
MODE_NAMES: tuple[str, ...] = tuple(REGISTRY)


def frame_modes_help() -> str:
    """Every mode with its description, as one sentence for a help text."""
    return "; ".join(f"{m.name} ({m.description})" for m in REGISTRY.values())


def make_source(name: str, stage: Stage, dvs: DVSEmulator, params: FrameParams) -> FrameSource:
    """The source of mode ``name`` for ``stage`` (its class's ``create``)."""
    return REGISTRY[name].source_class().create(stage, dvs, params)
