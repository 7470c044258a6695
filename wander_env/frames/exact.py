"""The exact frame source: every frame rendered (every tick and adaptive sub-frame), the
reference the other sources are measured against."""

from __future__ import annotations

import numpy as np

from wander_env.dvs import DVSEmulator, LogFrame
from wander_env.frames.source import FrameParams, FrameSource
from wander_env.frames.stage import Angles, Stage
from wander_env.ptu.unit import Trajectory

__all__ = ["ExactFrames"]


class ExactFrames(FrameSource):
    """Every frame rendered: the reference."""

    def __init__(self, stage: Stage, dvs: DVSEmulator, params: FrameParams) -> None:
        super().__init__(stage, dvs, params)
        self._camera_frame: np.ndarray | None = None
        self._latest_us = -1

    @property
    def camera_frame(self) -> np.ndarray | None:
        return self._camera_frame

    def reset(self, t_us: int, angles: Angles) -> LogFrame:
        self._latest_us = t_us
        return self.frame(t_us, angles)

    def plan(self, trajectory: Trajectory) -> None:
        pass

    def frame(self, t_us: int, angles: Angles) -> LogFrame:
        self.stage.pose(t_us, *angles)
        rgb = self.stage.render()
        if t_us >= self._latest_us:
            self._latest_us, self._camera_frame = t_us, rgb
        return self.dvs.prepare(rgb)
