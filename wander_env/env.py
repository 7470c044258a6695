"""The Gymnasium environment: an event camera on a pan-tilt unit in a MuJoCo scene.

One :meth:`WanderEnv.step` is one control period (10 ms by default). Inside it the
PTU moves toward its target under its speed and acceleration limits, the scene's
objects move along their trajectories, the camera renders at the render rate
(1 kHz by default) plus extra frames wherever the DVS emulator reports a large
log-intensity change (adaptive sampling: a frame whose largest change exceeds
``adaptive_log_change`` is preceded by up to ``max_subframes - 1`` frames splitting the
span since the previous frame), and the emulator turns the frames into events.

The step runs on one timeline: the PTU's :meth:`~wander_env.ptu.unit.PanTiltUnit.trajectory`
(the unit stepped once per tick) is computed at the step's start and the frame source
(:mod:`wander_env.frames`, chosen by ``frames`` from :mod:`wander_env.frames.registry`)
reads the camera's angles from it; the env itself only turns frames into events (this
module) and commands into targets (:class:`~wander_env.env_base.CameraEnv`, shared with
the rig).

Frames (``frames``): ``"keyframes"`` (the default) renders keys where the image motion
predicted from the poses (the camera's rotation along the PTU's trajectory, the objects'
known motion) since the last key would pass ``keyframe_px`` (2 px): the step's end when
less moves, more keys in a fast saccade, none while nothing moves at all (the last key
stands); every ``keyframe_ms`` where the motion has no bound (a camera centre that
moves, a sliding screen) or with ``keyframe_px=None``. It makes the frames in between
from the two neighbouring keys with the scene's geometry (:mod:`wander_env.frames.keyframe_maths`:
the camera's rotation homography, each moving object's rigid motion from the keys' depth
and motion layers, reprojection with depth where the camera centre moves), and hands
the DVS no frame at a tick where nothing moves by half a pixel, nor where the content
moves by less than a pixel between the frames handed around it (it interpolates between
those; ``FrameParams.interpolate_px``). The keys are rendered at the start of the step
from the PTU's own trajectory, so nothing waits for a later frame.
``"exact"`` renders every frame (every tick and sub-frame): the reference.
``"panorama"`` warps a cube map of the static world, rendered once per reset, by the
camera's rotation and renders keys only for the moving objects
(:class:`~wander_env.frames.panorama.PanoramaFrames`; docs/fidelity.md has its measurements).
``renders_in_step`` counts the RGB renders of the last step.

Action, observation and ``info``: :class:`~wander_env.env_base.CameraEnv` (shared with
the rig). Like the rig, the env exposes its lens's ``hfov_deg`` (the scene's camera) and
the PTU's ``ptu_resolution_arcsec`` (pan, tilt) for an agent to match
(:meth:`agents.attention.AgentParams.for_env`). The sim's ``info`` adds ``frames`` and
``extra_frames`` (frames handed to the DVS in the step, and how many of them were
adaptive sub-frames) and, with ground truth on, ``object_mask`` ((H, W) int32 object
ids, 0 = background) and ``objects`` (per moving object: id, name, pixel centre of its
projection, mask pixels, visible).

Processes and threads: the renderer (an OpenGL context) is created at the first
``reset``, in the process that renders, and with ``render_thread`` (the default) on a
thread of its own that draws the step's keys while this thread makes the frames between
them and runs the DVS (:mod:`wander_env.frames.stage`; the same events without it);
:meth:`WanderEnv.close` joins it. Constructing an env touches no GL and starts no thread,
so ``AsyncVectorEnv`` with the default ("fork") start method works. A process forked
after its parent rendered cannot render: there ``reset`` or ``step`` raises
:class:`~wander_env.gl_process.ForkedGLError`, which says to use ``context="spawn"`` (see
:mod:`wander_env.gl_process`).

Examples:
    >>> import gymnasium, wander_env
    >>> env = gymnasium.make("wander/Wander-v0", scene="shelf")
    >>> obs, info = env.reset(seed=0)
    >>> obs["events"].shape, obs["gaze"].tolist()
    ((2, 128, 128), [0.0, 0.0])
    >>> env.close()
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Any

import numpy as np

from wander_env.camera import focal_length_px
from wander_env.dvs import DVSEmulator, DVSParams
from wander_env.env_base import CameraEnv, StepInfo
from wander_env.env_config import WanderConfig
from wander_env.events import concatenate
from wander_env.events.packet import EventPacket
from wander_env.frames.registry import make_source
from wander_env.frames.source import FrameParams
from wander_env.frames.stage import Stage
from wander_env.mjcf import SceneAnimator, build_mjcf
from wander_env.ptu.unit import PanTiltUnit, Trajectory
from wander_env.ptu.units import round_position
from wander_env.readout import SpeckReadout
from wander_env.renderer import RenderParams
from wander_env.scene_config import SceneConfig
from wander_env.scenes import load_scene_config
from wander_env.viz import event_image, labelled_frame


class WanderEnv(CameraEnv):
    """See the module docstring. Build with ``gymnasium.make("wander/Wander-v0", ...)``."""

    def __init__(self, render_mode: str | None = None, **config: Any) -> None:
        self.config = WanderConfig(**config)
        c = self.config
        self.init_render(render_mode, c.control_period_s)
        scene = load_scene_config(c.scene)
        if c.antialias_samples is not None:
            camera = replace(scene.camera, antialias_samples=c.antialias_samples)
            scene = replace(scene, camera=camera)
        self.scene: SceneConfig = scene
        self.hfov_deg = scene.camera.hfov_deg
        self.ptu_resolution_arcsec: tuple[float, float] = (
            c.ptu.pan_resolution_arcsec,
            c.ptu.tilt_resolution_arcsec,
        )
        self.stage = Stage(
            build_mjcf(scene, c.ptu).compile(),
            scene,
            RenderParams(supersample=c.render_supersample),
            render_thread=c.render_thread,
        )
        self.model, self.data = self.stage.model, self.stage.data
        self.ptu = PanTiltUnit(c.ptu)
        self.dvs_params = c.dvs_params if c.dvs_params is not None else DVSParams.preset(c.dvs)
        self.init_spaces(
            scene.camera.width, scene.camera.height, c.ptu.pan_limits_deg, c.ptu.tilt_limits_deg
        )
        self.f_px = focal_length_px(self.width, self.hfov_deg)
        self.dvs = DVSEmulator(self.width, self.height, self.dvs_params)
        max_ticks = None
        if c.keyframe_max_ms is not None:
            max_ticks = max(round(c.keyframe_max_ms * 1e3) // c.tick_us, 1)
        params = FrameParams(c.tick_us, c.keyframe_us, c.keyframe_px, max_ticks, c.ground_truth)
        self.source = make_source(c.frames, self.stage, self.dvs, params)
        self._t_us = 0
        # Speck's readout after the DVS (wander_env.readout); None: events as the DVS gives them.
        readout = c.readout_params
        self.readout = None if readout is None else SpeckReadout(self.width, self.height, readout)

    @property
    def animator(self) -> SceneAnimator | None:
        """The objects' motion of the episode (None before the first reset)."""
        return self.stage.animator

    @property
    def renders_in_step(self) -> int:
        """Colour frames rendered in the last step (or reset)."""
        return self.stage.renders

    def warm_up(self) -> None:
        """Start what the first reset would wait for: the draw side's GL contexts
        (:meth:`~wander_env.frames.Stage.warm_up`) and numba's compiler with the DVS's
        kernels (about 0.3 s at a process's first numba call), on the render thread while
        the caller goes on. Only for a caller that keeps this process: a process forked
        after it cannot draw."""
        self.stage.warm_up()
        self.stage.submit(self.dvs.prepare, np.zeros((self.height, self.width, 3), np.uint8))

    # -- pickling: the configuration, not the GL context --------------------------------
    def __getstate__(self) -> dict[str, Any]:
        return {"render_mode": self.render_mode, "config": self.config}

    def __setstate__(self, state: dict[str, Any]) -> None:
        cfg = state["config"]
        self.__init__(render_mode=state["render_mode"], **cfg)

    # -- the step ----------------------------------------------------------------------
    def collect(self, clipped: bool) -> tuple[np.ndarray, StepInfo]:
        """The step's frames from the source, along the PTU's trajectory, into events;
        a frame whose largest log change passes ``adaptive_log_change`` is preceded by
        sub-frames splitting the span since the previous frame."""
        c = self.config
        t1 = self._t_us + c.control_period_us
        trajectory = self.ptu.trajectory(self._t_us, t1, c.tick_us)
        self.stage.begin_step()
        self.source.plan(trajectory)
        if not self.episode_over(t1 * 1e-6):  # the next step's keys, drawn on a guess
            self.source.plan_ahead(self._left_alone(t1))
        chunks: list[np.ndarray] = []
        frames = extra = 0
        t_prev = self._t_us
        for i, t in enumerate(trajectory.t_us):
            if self.source.interpolated(t):  # the DVS interpolates over it
                continue
            frame = self.source.frame(t, trajectory.angles(i))
            change = self.dvs.log_change(frame)
            m = 1
            if change > c.adaptive_log_change:
                m = min(c.max_subframes, math.ceil(change / c.adaptive_log_change))
            times = [t_prev + (t - t_prev) * j // m for j in range(1, m)]
            for tj, angles in zip(times, trajectory.at(times), strict=True):
                chunks.append(self.dvs.step(self.source.frame(tj, angles), tj))
            chunks.append(self.dvs.step(frame, t))
            frames, extra, t_prev = frames + m, extra + m - 1, t
        self._t_us = t1
        self.source.finish(t1, trajectory.angles(-1))
        events = concatenate(chunks)
        if self.readout is not None:  # Speck's readout (wander_env.readout)
            events = self.readout.step(events, t1)
        return events, self._info(events, frames, extra, clipped)

    def _left_alone(self, t_us: int) -> Trajectory:
        """The next step's trajectory from ``t_us`` if its action is zero (the target
        kept: a move under way goes on), from a copy of the PTU after this step's."""
        c = self.config
        twin = self.ptu.copy()
        twin.set_target(*twin.clip_target(*twin.target_deg))
        return twin.trajectory(t_us, t_us + c.control_period_us, c.tick_us)

    def truncated(self, info: StepInfo) -> bool:
        return self.episode_over(self._t_us * 1e-6)

    def check_ready(self) -> None:
        if self.animator is None:
            raise RuntimeError("call reset() before step()")

    # -- gymnasium API -----------------------------------------------------------------
    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, np.ndarray], StepInfo]:
        super().reset(seed=seed)
        rng = self.np_random
        self.stage.begin_episode(
            SceneAnimator(self.model, self.scene, np.random.default_rng(rng.integers(2**63)))
        )
        pan, tilt = (options or {}).get("gaze_deg", self.config.start_gaze_deg)
        self.ptu.reset(*self.ptu.clip_target(pan, tilt))
        self._t_us = 0
        angles = (self.ptu.camera_pan_deg, self.ptu.camera_tilt_deg)
        first = self.source.reset(0, angles)
        self.source.finish(0, angles)
        self.dvs.reset(first, 0, seed=int(rng.integers(2**63)))
        empty = self.dvs.flush()
        if self.readout is not None:  # Speck's readout (wander_env.readout)
            self.readout.reset(0)
        return self.observe(None), self._info(empty, frames=1, extra=0, clipped=False)

    @property
    def target_deg(self) -> tuple[float, float]:
        return self.ptu.target_deg

    def clip_target(self, pan_deg: float, tilt_deg: float) -> tuple[float, float]:
        return self.ptu.clip_target(pan_deg, tilt_deg)

    def set_target(self, pan_deg: float, tilt_deg: float) -> None:
        self.ptu.set_target(pan_deg, tilt_deg)

    def gaze(self) -> np.ndarray:
        return np.array([self.ptu.camera_pan_deg, self.ptu.camera_tilt_deg], np.float32)

    def _info(self, events: np.ndarray, frames: int, extra: int, clipped: bool) -> StepInfo:
        info = StepInfo(
            events=EventPacket(events),
            t=self._t_us * 1e-6,
            ptu_positions=self.ptu.positions,
            ptu_target_positions=tuple(round_position(p) for p in self.ptu.target_positions),
            ptu_target_deg=tuple(float(d) for d in self.ptu.target_deg),
            moving=self.ptu.moving,
            target_clipped=clipped,
            frames=frames,
            extra_frames=extra,
        )
        if self.readout is not None:  # the readout's counters of the step
            info["readout"] = dict(self.readout.counts)
        if self.config.ground_truth:
            mask = self.source.object_mask(self._t_us)
            info["object_mask"] = mask
            info["objects"] = self._objects(mask)
        return info

    def _objects(self, mask: np.ndarray) -> list[dict[str, Any]]:
        positions = self.animator.object_positions(self._t_us * 1e-6)
        centres = self.stage.project(positions)
        counts = np.bincount(mask.ravel(), minlength=len(centres) + 1)
        out = []
        for k, (obj, centre) in enumerate(zip(self.scene.moving_objects, centres, strict=True), 1):
            pixels = int(counts[k])
            out.append(
                {
                    "id": k,
                    "name": obj.name,
                    "centre_px": (float(centre[0]), float(centre[1])),
                    "mask_pixels": pixels,
                    "visible": pixels > 0,
                }
            )
        return out

    @property
    def camera_frame(self) -> np.ndarray | None:
        """The last rendered camera image (H, W, 3) uint8 (None before reset), a copy."""
        frame = self.source.camera_frame
        return None if frame is None else frame.copy()

    def render(self) -> np.ndarray | None:
        """Camera view | event frame of the last step (3x), named, the fovea marked, with
        the time stamp, the gaze and the ON/OFF key (:func:`wander_env.viz.labelled_frame`)."""
        if self.render_mode != "rgb_array":
            return None
        frame = self.source.camera_frame
        if frame is None:
            raise RuntimeError("call reset() before render()")
        pan, tilt = self.gaze()
        caption = (
            f"t = {self._t_us * 1e-6:5.2f} s   gaze pan {pan:+6.2f} deg, tilt {tilt:+6.2f} deg"
        )
        panels = [("camera", frame), ("events (last step)", event_image(self.last_counts))]
        return labelled_frame(panels, 3, caption, keys=("polarity", "fovea"), gap=6)

    def close(self) -> None:
        if getattr(self, "stage", None) is not None:
            self.source.close()
            self.stage.close()
        super().close()


__all__ = ["WanderConfig", "WanderEnv"]
