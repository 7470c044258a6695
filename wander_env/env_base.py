"""What the simulated env and the rig env share: the render-mode contract.

Both :class:`wander_env.env.WanderEnv` and :class:`hardware.rig_env.RigEnv` render
``rgb_array`` frames at one frame per control period; :class:`CameraEnv` holds that
``metadata`` and the check of ``render_mode``.

Example:
    >>> env = CameraEnv()
    >>> env.init_render("rgb_array", 0.02)
    >>> env.render_mode, env.metadata["render_fps"]
    ('rgb_array', 50)
"""

from __future__ import annotations

from typing import Any, ClassVar

import gymnasium as gym

__all__ = ["CameraEnv"]


class CameraEnv(gym.Env):
    """A gymnasium env of the event camera on the pan-tilt unit (the two backends' base)."""

    metadata: ClassVar[dict[str, Any]] = {"render_modes": ["rgb_array"], "render_fps": 100}

    def init_render(self, render_mode: str | None, control_period_s: float) -> None:
        """Check and keep ``render_mode``; ``render_fps`` = one frame per control period."""
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be one of {self.metadata['render_modes']} or None")
        self.render_mode = render_mode
        self.metadata = {**self.metadata, "render_fps": round(1.0 / control_period_s)}
