"""What the simulated env and the rig env share: spaces, action -> target, the ``info``
contract, the observation and the render-mode contract.

:class:`CameraEnv` is the base of :class:`wander_env.env.WanderEnv` and
:class:`hardware.rig_env.RigEnv`. Its :meth:`~CameraEnv.step` turns the action into a
PTU target (pinhole model, integrated into the current target, clipped to the unit's
limits), asks the env for the step's events (:meth:`~CameraEnv.collect`: the one thing
each backend does its own way), and assembles the observation: per-polarity counts and
the gaze. :class:`StepInfo` is the ``info`` both give.

Action: ``Box(-1, 1, (2,))``, a gaze offset in units of the half sensor: the action that
brings pixel P to the fovea is ``(P - centre) / (W/2, H/2)``. It is converted to angles
with the camera's pinhole model (offset d pixels -> ``atan(d / f_px)``) and added to the
PTU's current target, so relative commands are integrated (at rest the target is where
the camera looks; a zero action lets a move under way go on). A NaN, infinite or
out-of-range action raises ``ValueError`` (the agent clips its own actions); a target
beyond the PTU's limits is clipped to them and ``info["target_clipped"]`` says so.

Observation: ``{"events": (2, H, W) float32 per-polarity counts of the step (channel
1 = ON), "gaze": (pan, tilt) in degrees}``. ``info["events"]`` holds the step's raw
events, every one of them, as an :class:`~wander_env.events.packet.EventPacket` (whose
``.events`` is the structured array; as a packet it passes through vector envs,
``check_env`` and pickling).

Examples:
    >>> env = CameraEnv()
    >>> env.init_render("rgb_array", 0.02)
    >>> env.render_mode, env.metadata["render_fps"]
    ('rgb_array', 50)
"""

from __future__ import annotations

from typing import Any, ClassVar, TypedDict

import gymnasium as gym
import numpy as np

from wander_env.actions import action_to_gaze_degrees, check_action
from wander_env.events import to_frame
from wander_env.events.packet import EventPacket

__all__ = ["CameraEnv", "StepInfo"]


class _StepInfoBase(TypedDict):
    events: EventPacket  # the step's raw events, every one of them
    t: float  # s since reset: the end of the step's window
    ptu_positions: tuple[int, int]
    ptu_target_positions: tuple[int, int]
    ptu_target_deg: tuple[float, float]
    moving: bool
    target_clipped: bool  # the PTU's limits clipped the target


class StepInfo(_StepInfoBase, total=False):
    """``info`` of a step (and of ``reset``) of either env: the keys above always; the
    sim adds ``frames`` and ``extra_frames`` (frames made in the step, rendered or
    synthesised), with a readout stage ``readout`` (its counters of the step,
    :data:`wander_env.readout.COUNTERS`) and, with ground truth on, ``object_mask`` and
    ``objects``; the rig
    adds ``command_latency_s``, ``dropped_events`` and ``lag_s``."""

    frames: int
    extra_frames: int
    object_mask: np.ndarray  # (H, W) int32 object ids, 0 = background
    objects: list[dict[str, Any]]
    readout: dict[str, int]
    command_latency_s: float
    dropped_events: int
    lag_s: float


class CameraEnv(gym.Env):
    """A gymnasium env of the event camera on the pan-tilt unit (the two backends' base).

    A subclass sets ``config``, ``width``, ``height``, ``hfov_deg``,
    ``ptu_resolution_arcsec`` (pan, tilt: what :meth:`agents.attention.AgentParams.for_env`
    reads) and the spaces
    (:meth:`init_spaces`) and implements :attr:`target_deg`, :meth:`clip_target`,
    :meth:`set_target`, :meth:`gaze`, :meth:`check_ready`, :meth:`collect` and
    :meth:`truncated`.
    """

    metadata: ClassVar[dict[str, Any]] = {"render_modes": ["rgb_array"], "render_fps": 100}
    config: Any  # the backend's config: episode_seconds, control_period_s, ...
    width: int
    height: int
    hfov_deg: float
    ptu_resolution_arcsec: tuple[float, float]

    def init_render(self, render_mode: str | None, control_period_s: float) -> None:
        """Check and keep ``render_mode``; ``render_fps`` = one frame per control period."""
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be one of {self.metadata['render_modes']} or None")
        self.render_mode = render_mode
        self.metadata = {**self.metadata, "render_fps": round(1.0 / control_period_s)}

    def init_spaces(
        self,
        width: int,
        height: int,
        pan_limits: tuple[float, float],
        tilt_limits: tuple[float, float],
    ) -> None:
        """The action ``Box(-1, 1, (2,))`` and the observation (counts and gaze) spaces."""
        self.width, self.height = width, height
        self.action_space = gym.spaces.Box(-1.0, 1.0, (2,), np.float32)
        self.observation_space = gym.spaces.Dict(
            {
                "events": gym.spaces.Box(0.0, np.inf, (2, height, width), np.float32),
                "gaze": gym.spaces.Box(
                    np.array([pan_limits[0], tilt_limits[0]], np.float32),
                    np.array([pan_limits[1], tilt_limits[1]], np.float32),
                    dtype=np.float32,
                ),
            }
        )
        self.last_counts = np.zeros((2, height, width), np.float32)

    # -- what each backend implements ------------------------------------------------------
    @property
    def target_deg(self) -> tuple[float, float]:
        """The commanded (pan, tilt) target in degrees."""
        raise NotImplementedError

    def clip_target(self, pan_deg: float, tilt_deg: float) -> tuple[float, float]:
        """A (pan, tilt) target clipped to the unit's limits."""
        raise NotImplementedError

    def set_target(self, pan_deg: float, tilt_deg: float) -> None:
        """Command the PTU to a target inside its limits."""
        raise NotImplementedError

    def gaze(self) -> np.ndarray:
        """(pan, tilt) of the camera in degrees, float32."""
        raise NotImplementedError

    def check_ready(self) -> None:
        """Raise when the env cannot step (before ``reset``, closed, faulted)."""
        raise NotImplementedError

    def collect(self, clipped: bool) -> tuple[np.ndarray, StepInfo]:
        """Run the step's window: its events (sorted by ``t``) and its ``info``."""
        raise NotImplementedError

    def truncated(self, info: StepInfo) -> bool:
        """Whether the episode ends after this step."""
        raise NotImplementedError

    # -- shared ------------------------------------------------------------------------
    def episode_over(self, t_s: float) -> bool:
        """Whether ``t_s`` seconds of the episode reach its ``config.episode_seconds`` (to
        a nanosecond: a sum of steps may fall short by rounding)."""
        return t_s >= self.config.episode_seconds - 1e-9

    def command(self, action: np.ndarray) -> bool:
        """Turn a relative gaze action into a PTU target; True when the limits clipped it.

        Pixel offsets become angles with the pinhole model (positive pan turns left,
        positive tilt looks up) and are added to the current target (a zero action lets
        a move under way go on; at rest the target is where the camera looks).
        """
        d_pan, d_tilt = action_to_gaze_degrees(
            check_action(action), self.width, self.height, self.hfov_deg
        )
        pan0, tilt0 = self.target_deg
        return self.aim(pan0 + d_pan, tilt0 + d_tilt)

    def aim(self, pan_deg: float, tilt_deg: float) -> bool:
        """Set the PTU's target to (pan, tilt) degrees clipped to its limits; True when
        the limits clipped it."""
        target = self.clip_target(pan_deg, tilt_deg)
        self.set_target(*target)
        return bool(np.abs(np.subtract(target, (pan_deg, tilt_deg))).max() > 1e-9)

    def observe(self, events: np.ndarray | None) -> dict[str, np.ndarray]:
        """The observation: the events' per-polarity counts (none: zeros) and the gaze."""
        if events is None:
            self.last_counts = np.zeros((2, self.height, self.width), np.float32)
        else:
            self.last_counts = to_frame(events, (self.width, self.height, 2))
        return {"events": self.last_counts.copy(), "gaze": self.gaze()}

    def step(self, action: np.ndarray) -> tuple[dict[str, np.ndarray], float, bool, bool, StepInfo]:
        self.check_ready()
        clipped = self.command(action)
        events, info = self.collect(clipped)
        return self.observe(events), 0.0, False, self.truncated(info), info
