"""The exact frame source: every frame rendered (every tick and adaptive sub-frame), the
reference the other sources are measured against."""

from __future__ import annotations

from concurrent.futures import Future

import numpy as np

from wander_env.dvs import DVSEmulator, LogFrame
from wander_env.frames.source import FrameParams, FrameSource
from wander_env.frames.stage import Angles, Stage
from wander_env.ptu.unit import Trajectory

__all__ = ["ExactFrames"]


class ExactFrames(FrameSource):
    """Every frame rendered: the reference. A step's ticks (every one is a frame) and,
    with ground truth on, its end's mask are handed to the draw side at the step's
    start; a sub-frame is drawn when asked for."""

    def __init__(self, stage: Stage, dvs: DVSEmulator, params: FrameParams) -> None:
        super().__init__(stage, dvs, params)
        self._camera_frame: np.ndarray | None = None
        self._latest_us = -1
        self._ahead: dict[int, Future[tuple[np.ndarray, LogFrame]]] = {}  # tick -> frame
        self._mask_ahead: tuple[int, Future[np.ndarray]] | None = None  # (t_us, mask)

    @property
    def camera_frame(self) -> np.ndarray | None:
        return self._camera_frame

    def reset(self, t_us: int, angles: Angles) -> LogFrame:
        self._latest_us, self._ahead, self._mask_ahead = t_us, {}, None
        return self.frame(t_us, angles)

    def plan(self, trajectory: Trajectory) -> None:
        stage, ticks = self.stage, trajectory.t_us
        self._ahead = {
            t: stage.submit(self._draw, t, trajectory.angles(i)) for i, t in enumerate(ticks)
        }
        self._mask_ahead = None
        if self.params.ground_truth:
            end = (ticks[-1], trajectory.angles(-1))
            self._mask_ahead = (ticks[-1], stage.submit(stage.object_mask_at, *end))

    def _draw(self, t_us: int, angles: Angles) -> tuple[np.ndarray, LogFrame]:
        """(On the draw side.) The colour frame at ``t_us`` and its DVS input."""
        rgb = self.stage.colour_at(t_us, angles)
        return rgb, self.dvs.prepare(rgb)

    def frame(self, t_us: int, angles: Angles) -> LogFrame:
        ahead = self._ahead.pop(t_us, None)
        if ahead is None:  # a sub-frame inside a tick
            ahead = self.stage.submit(self._draw, t_us, angles)
        rgb, prepared = ahead.result()
        if t_us >= self._latest_us:
            self._latest_us, self._camera_frame = t_us, rgb
        return prepared

    def object_mask(self, t_us: int) -> np.ndarray:
        if self._mask_ahead is not None and self._mask_ahead[0] == t_us:
            return self._mask_ahead[1].result()
        return super().object_mask(t_us)
