"""What a frame source is: the camera frames of a stream, read along the PTU's trajectory.

A :class:`FrameSource` turns a step's :class:`~wander_env.ptu.unit.Trajectory` (the PTU
stepped once per tick, computed once per step) into the frames the DVS sees, each as the
DVS's own input (a :class:`~wander_env.dvs.LogFrame`):

- :meth:`~FrameSource.reset` at an episode's start: the first frame;
- :meth:`~FrameSource.plan` at the step's start, with the whole trajectory (a source
  may render its keys there: everything it needs is known, nothing waits for later);
- :meth:`~FrameSource.plan_ahead` after it, with a guess of the next step's trajectory
  (a source may start drawing the next step's keys while this step's frames are made);
- :meth:`~FrameSource.frame` at each render tick and adaptive sub-frame, with that
  time's camera angles;
- :meth:`~FrameSource.object_mask` at the step's end (ground truth).

The sources themselves: :mod:`wander_env.frames.registry`.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass

import numpy as np

from wander_env.dvs import DVSEmulator, LogFrame
from wander_env.frames.stage import Angles, Stage
from wander_env.ptu.unit import Trajectory

__all__ = ["FrameParams", "FrameSource"]


@dataclass(frozen=True)
class FrameParams:
    """What a frame source needs of the env's configuration (see ``WanderConfig``)."""

    tick_us: int = 1000
    keyframe_us: int = 2000
    keyframe_px: float | None = 2.0
    key_max_ticks: int | None = None  # keys no more ticks apart while anything moves
    ground_truth: bool = True
    # A tick between keys is left to the DVS's interpolation (no frame made) where no
    # pixel's content moves more than this (px) between the frames handed before and
    # after it; None: only where it moves by less than half a pixel from both keys.
    # 1 px: a quarter of the synthesised frames of a closed loop, and the same events,
    # L1 and matched share against the 64-sample reference on every row of
    # `wander bench fidelity` (seed 0, 0.1 s) as without.
    interpolate_px: float | None = 1.0

    def __post_init__(self) -> None:
        x = self.interpolate_px
        if x is not None and not (isinstance(x, int | float) and x > 0):
            raise ValueError(f"FrameParams.interpolate_px must be > 0 or None, got {x!r}")


class FrameSource(ABC):
    """The camera frames of a stream (see the module docstring); ``dvs`` is the
    emulator the frames are for (a frame is its :meth:`~DVSEmulator.prepare` d input)."""

    #: Keys drawn ahead of time (:meth:`plan_ahead`) that the next step adopted, and that
    #: it dropped (its trajectory not the one guessed); 0 for a source drawing none ahead.
    keys_ahead_adopted: int = 0
    keys_ahead_dropped: int = 0

    def __init__(self, stage: Stage, dvs: DVSEmulator, params: FrameParams) -> None:
        self.stage, self.dvs, self.params = stage, dvs, params
        self._end: tuple[int, Angles] | None = None  # the step's (or reset's) end

    @classmethod
    def create(cls, stage: Stage, dvs: DVSEmulator, params: FrameParams) -> FrameSource:
        """The source of this mode for ``stage`` (a mode that cannot serve a stage names
        the one that stands in for it here)."""
        return cls(stage, dvs, params)

    @property
    @abstractmethod
    def camera_frame(self) -> np.ndarray | None:
        """The latest colour frame (H, W, 3) uint8 (None before the first reset)."""

    @abstractmethod
    def reset(self, t_us: int, angles: Angles) -> LogFrame:
        """Start a stream at ``t_us``; the first frame (for the DVS's reset)."""

    @abstractmethod
    def plan(self, trajectory: Trajectory) -> None:
        """A step's start: the camera's trajectory through the step."""

    def plan_ahead(self, trajectory: Trajectory) -> None:
        """After :meth:`plan`: the next step's likely trajectory (the PTU left to itself);
        a source may start drawing it, and its next :meth:`plan` adopt what it drew where
        the trajectory turns out the same. The frames must not depend on whether it did."""
        return None  # this source draws nothing ahead

    @abstractmethod
    def frame(self, t_us: int, angles: Angles) -> LogFrame:
        """The frame at ``t_us`` (a tick of the planned step or a time inside one)."""

    def interpolated(self, t_us: int) -> bool:
        """Whether the DVS may go without the frame of this tick of the planned step and
        interpolate over it (nothing in it moves but by a fraction of a pixel)."""
        return False

    def finish(self, t_us: int, angles: Angles) -> None:
        """The step's (or reset's) end: the camera side posed there (the ground truth
        projects through it)."""
        self._end = (t_us, angles)
        self.stage.pose_camera(*angles)

    def object_mask(self, t_us: int) -> np.ndarray:
        """Object ids (H, W) int32 at the step's end ``t_us`` (after :meth:`finish`)."""
        t_end, angles = self._end
        if t_end != t_us:
            raise ValueError(f"object_mask: t_us {t_us} is not the step's end {t_end}")
        return self.stage.on_draw_side(self.stage.object_mask_at, t_us, angles)

    def close(self) -> None:
        """The stream's end: free what the source holds beyond the stage (a source that
        draws with its own renderer frees it on the draw side)."""
        self._end = None
