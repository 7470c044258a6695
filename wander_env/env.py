"""The Gymnasium environment: an event camera on a pan-tilt unit in a MuJoCo scene.

One :meth:`WanderEnv.step` is one control period (10 ms by default). Inside it the
PTU moves toward its target under its speed and acceleration limits, the scene's
objects move along their trajectories, the camera renders at the render rate
(1 kHz by default) plus extra frames wherever the DVS emulator reports a large
log-intensity change (adaptive sampling: a render tick whose largest change
exceeds ``adaptive_log_change`` is split into up to ``max_subframes`` frames),
and the emulator turns the frames into events.

Frames (``frames``): ``"keyframes"`` (the default) renders the camera at each step's end
and, while anything in view moves, every ``keyframe_ms`` (2 ms) or sooner where the
predicted image motion since the last key would pass ``keyframe_px`` (2 px; one key a
step while nothing moves; ``keyframe_px=None``: every ``keyframe_ms`` always), and makes
the frames in between from the two neighbouring keys with the scene's geometry
(:mod:`wander_env.keyframes`: the camera's rotation homography, each moving object's
rigid motion from the keys' depth and motion layers, reprojection with depth where the
camera centre moves); the keys are rendered at the start of the step from the PTU's own
trajectory, so nothing waits for a later frame.
``"exact"`` renders every frame (every tick and sub-frame): the reference.
``renders_in_step`` counts the RGB renders of the last step.

Action: ``Box(-1, 1, (2,))``, a gaze offset in units of the half sensor: the
action that brings pixel P to the fovea is ``(P - centre) / (W/2, H/2)``. It is
converted to angles with the camera's pinhole model (offset d pixels ->
``atan(d / f_px)``) and added to the PTU's current target, so relative commands
are integrated (at rest the target is where the camera looks; a zero action
lets a move under way go on). A NaN, infinite or
out-of-range action raises ``ValueError`` (the agent clips its own actions); a
target beyond the PTU's limits is clipped to them and ``info["target_clipped"]``
says so.

Observation: ``{"events": (2, H, W) float32 per-polarity counts of the step
(channel 1 = ON), "gaze": (pan, tilt) in degrees}``.

``info``: ``events`` (the step's raw events, every one of them: an
:class:`~wander_env.event_packet.EventPacket`, whose ``.events`` is the structured array;
as a packet it passes through vector envs, ``check_env`` and pickling), ``t`` (simulated s),
``ptu_positions``, ``ptu_target_positions`` (and ``ptu_target_deg``), ``moving``,
``target_clipped``, ``frames`` and ``extra_frames`` made in the step (rendered or
synthesised), and, with ground truth on, ``object_mask`` ((H, W) int32 object ids,
0 = background) and ``objects`` (per moving object: id, name, pixel centre of its
projection, mask pixels, visible).

Processes: the renderer (an OpenGL context) is created at the first ``reset``, in the
process that renders; constructing an env touches no GL, so ``AsyncVectorEnv`` with the
default ("fork") start method works. A process forked after its parent rendered cannot
render: there ``reset`` raises :class:`~wander_env.gl_fork.ForkedGLError`, which says to
use ``context="spawn"`` (see :mod:`wander_env.gl_fork`).

Example:
    >>> import gymnasium, wander_env
    >>> env = gymnasium.make("wander/Wander-v0", scene="shelf")
    >>> obs, info = env.reset(seed=0)
    >>> obs["events"].shape, obs["gaze"].tolist()
    ((2, 128, 128), [0.0, 0.0])
    >>> env.close()
"""

from __future__ import annotations

import math
import os
from dataclasses import asdict, dataclass, field, replace
from typing import Any

import gymnasium as gym
import mujoco
import numpy as np

from wander_env.actions import action_to_gaze_degrees, check_action
from wander_env.camera import CAMERA_NAME, focal_length_px, intrinsics, rotation_from_mujoco
from wander_env.config import check_fields
from wander_env.dvs import DVSEmulator, DVSParams, LogFrame
from wander_env.entities import PAN_JOINT, TILT_JOINT
from wander_env.env_base import CameraEnv
from wander_env.event_packet import EventPacket
from wander_env.events import concatenate, to_frame
from wander_env.gl_fork import ForkedGLError, fork_error_message
from wander_env.keyframes import (
    KeyframeSource,
    View,
    adaptive_key_ticks,
    make_keyframe,
    view_flow_bounds_px,
)
from wander_env.mjcf import SceneAnimator, build_mjcf, geom_layer_ids
from wander_env.ptu import PanTiltUnit, PTUParams
from wander_env.renderer import CameraRenderer, RenderParams, project_points
from wander_env.scene_config import SceneConfig, load_scene_config
from wander_env.viz import event_image, labelled_frame


@dataclass(frozen=True)
class WanderConfig:
    """Everything that defines an environment instance (pickled with it)."""

    scene: str = "office"
    control_period_s: float = 0.01
    render_rate_hz: float = 1000.0
    dvs: str = "ideal"
    adaptive_log_change: float = 1.0
    max_subframes: int = 8
    ground_truth: bool = True
    episode_seconds: float = 10.0
    start_gaze_deg: tuple[float, float] = (0.0, 0.0)
    ptu: PTUParams = field(default_factory=PTUParams)
    dvs_params: DVSParams | None = None  # overrides the `dvs` preset when given
    # Overrides the scene's camera.antialias_samples (MSAA) when given. 0 renders a frame
    # about twice as fast on a CPU, but edges jump from pixel to pixel instead of sliding:
    # bigger per-pixel log changes, so more adaptive sub-frames (office: ~1.5x the frames
    # with a still camera) and ~5 % more events. The scenes' default is 4.
    antialias_samples: int | None = None
    # How the frames between control steps are made: "exact" renders every one (every
    # render tick and adaptive sub-frame); "keyframes" renders every keyframe_ms and at
    # each step's end and synthesises the frames in between from the keys' depth and
    # motion layers (see wander_env.keyframes).
    frames: str = "keyframes"
    keyframe_ms: float = 2.0
    # Adaptive keys (frames="keyframes"): when given, a step's keys are its end and the
    # ticks where the image motion predicted since the last key (the camera's rotation
    # along the PTU's own trajectory, the objects' known motion) would pass keyframe_px
    # pixels, no more than keyframe_ms apart while anything moves and one a step while
    # nothing does (wander_env.keyframes.adaptive_key_ticks); every keyframe_ms where the
    # motion has no bound (a camera centre that moves, a sliding screen). None: every
    # keyframe_ms. Default 2 px: `wander bench fidelity` meets every bar with it (the
    # README's table), and a step where nothing moves renders once instead of 5 times.
    keyframe_px: float | None = 2.0
    # Render at this many times the resolution and average blocks (see RenderParams): the
    # finer-antialiased reference of the fidelity benchmark (2 = 16 samples a pixel).
    supersample: int = 1

    def __post_init__(self) -> None:
        names = ("control_period_s", "render_rate_hz", "adaptive_log_change", "episode_seconds")
        check_fields(self, names, positive=True)
        ticks = self.control_period_s * self.render_rate_hz
        if abs(ticks - round(ticks)) > 1e-9 or round(ticks) < 1:
            raise ValueError(
                f"control_period_s={self.control_period_s} must be a whole number (>= 1) of "
                f"render periods (render_rate_hz={self.render_rate_hz})"
            )
        if self.max_subframes < 1:  # before the division below (0 would divide by zero)
            raise ValueError(f"WanderConfig.max_subframes must be >= 1, got {self.max_subframes}")
        if round(1e6 / self.render_rate_hz / self.max_subframes) < 1:
            raise ValueError(f"max_subframes={self.max_subframes} splits a tick below 1 µs")
        if self.dvs_params is None:
            DVSParams.preset(self.dvs)  # raises for an unknown preset name
        if self.frames not in FRAME_MODES:
            raise ValueError(
                f"WanderConfig.frames must be one of {FRAME_MODES}, got {self.frames!r}"
            )
        k = self.keyframe_ms
        if isinstance(k, bool) or not (isinstance(k, (int, float)) and math.isfinite(k) and k > 0):
            raise ValueError(f"WanderConfig.keyframe_ms must be a finite number > 0, got {k!r}")
        # Keys are the render ticks at multiples of keyframe_ms (and each step's end):
        # keyframe_ms must be a whole number of ticks, or divide a tick (every tick a key).
        key_us, tick_us = round(k * 1e3), round(1e6 / self.render_rate_hz)
        if abs(k * 1e3 - key_us) > 1e-6 or key_us < 1 or (key_us % tick_us and tick_us % key_us):
            raise ValueError(
                f"WanderConfig.keyframe_ms={k} must be a whole number of render periods or "
                f"divide one (render_rate_hz={self.render_rate_hz}: {tick_us} µs)"
            )
        px = self.keyframe_px
        if px is not None and (
            isinstance(px, bool) or not (isinstance(px, (int, float)) and math.isfinite(px))
            or px <= 0
        ):  # fmt: skip
            raise ValueError(
                f"WanderConfig.keyframe_px must be None or a finite number > 0, got {px!r}"
            )
        ss = self.supersample
        if isinstance(ss, bool) or not isinstance(ss, int) or ss < 1:
            raise ValueError(f"WanderConfig.supersample must be an int >= 1, got {ss!r}")
        aa = self.antialias_samples
        if aa is not None and (isinstance(aa, bool) or not isinstance(aa, int) or aa < 0):
            raise ValueError(f"WanderConfig.antialias_samples must be an int >= 0, got {aa!r}")

    @property
    def ticks_per_step(self) -> int:
        return round(self.control_period_s * self.render_rate_hz)

    @property
    def tick_us(self) -> int:
        return round(1e6 / self.render_rate_hz)

    @property
    def keyframe_us(self) -> int:
        return round(self.keyframe_ms * 1e3)


FRAME_MODES = ("keyframes", "exact")


class WanderEnv(CameraEnv):
    """See the module docstring. Build with ``gymnasium.make("wander/Wander-v0", ...)``."""

    def __init__(self, render_mode: str | None = None, **config: Any) -> None:
        self.config = WanderConfig(**config)
        c = self.config
        self.init_render(render_mode, c.control_period_s)
        scene = self._scene_with_mount(load_scene_config(c.scene), c.ptu)
        if c.antialias_samples is not None:
            camera = replace(scene.camera, antialias_samples=c.antialias_samples)
            scene = replace(scene, camera=camera)
        self.scene: SceneConfig = scene
        cam = self.scene.camera
        self.width, self.height = cam.width, cam.height
        self.f_px = focal_length_px(cam.width, cam.hfov_deg)
        self.model = build_mjcf(self.scene).compile()
        self.data = mujoco.MjData(self.model)
        self._pan_adr = int(self.model.joint(PAN_JOINT).qposadr[0])
        self._tilt_adr = int(self.model.joint(TILT_JOINT).qposadr[0])
        self._renderer: CameraRenderer | None = None  # created where it renders: .renderer
        self._renderer_pid: int | None = None
        self.ptu = PanTiltUnit(c.ptu)
        self.dvs_params = c.dvs_params if c.dvs_params is not None else DVSParams.preset(c.dvs)
        self.dvs = DVSEmulator(self.width, self.height, self.dvs_params)
        self.animator: SceneAnimator | None = None
        self._cam_id = int(self.model.camera(CAMERA_NAME).id)
        self._keys: KeyframeSource | None = None
        if c.frames == "keyframes":
            fovy = float(self.model.cam_fovy[self._cam_id])
            self._layer_lut = geom_layer_ids(self.model)
            self._keys = KeyframeSource(
                intrinsics(self.width, self.height, fovy), self._layer_radii(), self._key_geometry
            )
        self._key_angles: dict[int, tuple[float, float]] = {}  # key t_us -> camera angles
        self._tick_views: dict[int, tuple[float, float, View]] = {}  # t_us -> angles, view
        self._pose_stale = False  # the model was moved off the step's end (keyframes)
        self._tick_bounds: dict[int, float] = {}  # t_us -> flow bound from its two keys
        self._key_inputs: dict[int, LogFrame] = {}  # key t_us -> its prepared DVS input
        self._tick_states: dict[int, PanTiltUnit] = {}  # t_us -> the PTU there (keyframes)
        self._posed_us = 0
        self._key_mask: tuple[int, np.ndarray] | None = None  # (t_us, object mask) of a key
        self.renders_in_step = 0  # frames rendered (RGB) in the last step or reset

        lo_pan, hi_pan = c.ptu.pan_limits_deg
        lo_tilt, hi_tilt = c.ptu.tilt_limits_deg
        self.action_space = gym.spaces.Box(-1.0, 1.0, (2,), np.float32)
        self.observation_space = gym.spaces.Dict(
            {
                "events": gym.spaces.Box(0.0, np.inf, (2, self.height, self.width), np.float32),
                "gaze": gym.spaces.Box(
                    np.array([lo_pan, lo_tilt], np.float32),
                    np.array([hi_pan, hi_tilt], np.float32),
                    dtype=np.float32,
                ),
            }
        )
        self._t_us = 0
        self._frame: np.ndarray | None = None
        self._last_counts = np.zeros((2, self.height, self.width), np.float32)

    @staticmethod
    def _scene_with_mount(scene: SceneConfig, ptu: PTUParams) -> SceneConfig:
        """A hinge offset given in the PTU parameters moves the camera in the model too."""
        if ptu.camera_forward_m == 0 and ptu.camera_up_m == 0:
            return scene
        mount = replace(
            scene.ptu, camera_forward_m=ptu.camera_forward_m, camera_up_m=ptu.camera_up_m
        )
        return replace(scene, ptu=mount)

    @property
    def renderer(self) -> CameraRenderer:
        """The camera's renderer, created on first use in this process (see the module doc)."""
        r = self._renderer
        if r is None:
            r = self._renderer = CameraRenderer(
                self.model,
                self.width,
                self.height,
                params=RenderParams(supersample=self.config.supersample),
            )
            self._renderer_pid = os.getpid()
        elif self._renderer_pid != os.getpid():
            raise ForkedGLError(fork_error_message(self._renderer_pid, os.getpid()))
        return r

    # -- pickling: the configuration, not the GL context --------------------------------
    def __getstate__(self) -> dict[str, Any]:
        return {"render_mode": self.render_mode, "config": asdict(self.config)}

    def __setstate__(self, state: dict[str, Any]) -> None:
        cfg = state["config"]
        cfg["ptu"] = PTUParams(**cfg["ptu"])
        if cfg["dvs_params"] is not None:
            cfg["dvs_params"] = DVSParams(**cfg["dvs_params"])
        cfg["start_gaze_deg"] = tuple(cfg["start_gaze_deg"])
        self.__init__(render_mode=state["render_mode"], **cfg)

    # -- the world at time t -----------------------------------------------------------
    def _pose(self, t_us: int) -> None:
        """Put the PTU's current camera angles and the objects at ``t_us`` into the model."""
        pan, tilt = math.radians(self.ptu.camera_pan_deg), math.radians(self.ptu.camera_tilt_deg)
        self._pose_angles(t_us, pan, tilt)

    def _pose_angles(self, t_us: int, pan_rad: float, tilt_rad: float) -> None:
        self._posed_us = t_us
        self.data.qpos[self._pan_adr] = pan_rad
        self.data.qpos[self._tilt_adr] = tilt_rad
        self.animator.apply(self.data, t_us * 1e-6)
        mujoco.mj_kinematics(self.model, self.data)
        mujoco.mj_camlight(self.model, self.data)

    def _render(self) -> np.ndarray:
        self.renders_in_step += 1
        return self.renderer.render(self.data)

    # -- keyframes ----------------------------------------------------------------------
    def _view(self, t_us: int) -> View:
        """The camera pose (posed model) and motion layers at ``t_us``."""
        return View(
            rotation_from_mujoco(self.data.cam_xmat[self._cam_id]),
            self.data.cam_xpos[self._cam_id].copy(),
            self.animator.layer_positions(t_us * 1e-6),
        )

    def _layer_radii(self) -> np.ndarray:
        """Bounding radius (m) of each motion layer about its position (inf: a screen)."""
        n = int(self._layer_lut.max(initial=0))
        radii = np.full(n + 1, np.inf)
        if self.scene.gratings is None:
            for k, obj in enumerate(self.scene.moving_objects, 1):
                radii[k] = 0.5 * math.hypot(*obj.size) * 1.01
        return radii

    def _render_key(
        self,
        t_us: int,
        geometry: bool,
        angles: tuple[float, float] | None = None,
        view: View | None = None,
    ) -> None:
        """Render a keyframe of the posed model at ``t_us`` (camera ``angles`` in degrees,
        default the PTU's; ``view`` its view when known); with ``geometry`` its layers
        and depth too (else they are rendered when a frame needs them)."""
        rgb = self._render()
        prepared = self.dvs.prepare(rgb)
        self._key_inputs = {t: p for t, p in self._key_inputs.items() if t >= self._t_us}
        self._key_inputs[t_us] = prepared  # the DVS input of the key's own tick
        lum = prepared.lum.reshape(self.height, self.width)
        view = self._view(t_us) if view is None else view
        self._key_angles = {t: a for t, a in self._key_angles.items() if t >= self._t_us}
        if angles is None:
            angles = (self.ptu.camera_pan_deg, self.ptu.camera_tilt_deg)
        self._key_angles[t_us] = angles
        if geometry:
            layers, depth = self.renderer.segment_depth_current(self._layer_lut)
            self._keys.add(make_keyframe(t_us, lum, view, depth, layers))
            mask = np.where(layers <= self.scene.num_objects, layers, 0).astype(np.int32)
            self._key_mask = (t_us, mask)
        else:
            self._keys.add(make_keyframe(t_us, lum, view))
        self._frame = rgb

    def _key_geometry(self, key: Any) -> tuple[np.ndarray, np.ndarray]:
        """(depth, layers) of a key rendered earlier: the model is posed at the key's time
        and camera angles, drawn, and posed back."""
        pan, tilt = self._key_angles[key.t_us]
        now = (self.data.qpos[self._pan_adr], self.data.qpos[self._tilt_adr], self._posed_us)
        self._pose_angles(key.t_us, math.radians(pan), math.radians(tilt))
        self.renderer.update(self.data)
        layers, depth = self.renderer.segment_depth_current(self._layer_lut)
        self._pose_angles(now[2], now[0], now[1])
        return depth, layers

    def _camera_view(self, t_us: int, pan_deg: float, tilt_deg: float) -> View:
        """The :class:`View` at ``t_us`` with the camera at these angles: only the PTU's
        joints, the kinematics and the camera are set (the objects are not moved; see
        :meth:`_pose_angles` for the full pose)."""
        self.data.qpos[self._pan_adr] = math.radians(pan_deg)
        self.data.qpos[self._tilt_adr] = math.radians(tilt_deg)
        mujoco.mj_kinematics(self.model, self.data)
        mujoco.mj_camlight(self.model, self.data)  # the camera's pose is computed here
        return self._view(t_us)

    def _render_keys(self, t0: int, t1: int) -> None:
        """Keys of the step (t0, t1]: at t1 and every keyframe_us (or, with keyframe_px,
        where the predicted motion asks: :func:`adaptive_key_ticks`), with the PTU moved
        along the same ticks as the step will move it (so the poses are the step's).
        Each tick's camera angles and view are kept for :meth:`_tick`; the model is left
        posed at t1."""
        c = self.config
        ptu = self.ptu.copy()
        ticks: list[tuple[int, float, float]] = []
        self._tick_states = {}
        t = t0
        while t < t1:
            t_next = t + c.tick_us
            ptu.step((t_next - t) * 1e-6)
            t = t_next
            ticks.append((t, ptu.camera_pan_deg, ptu.camera_tilt_deg))
            self._tick_states[t] = ptu.copy()  # the PTU at this tick, for _tick
        views = [self._camera_view(t, pan, tilt) for t, pan, tilt in ticks]
        kept = zip(ticks, views, strict=True)
        self._tick_views = {t: (pan, tilt, v) for (t, pan, tilt), v in kept}
        chosen = None
        if c.keyframe_px is not None:
            ref = self._keys.keys[-1].view  # the key at t0 (the last step's end)
            shape = (self.height, self.width)
            idx = adaptive_key_ticks(
                ref, views, self._keys.k, self._keys.radii, shape, c.keyframe_px,
                max_ticks=max(c.keyframe_us // c.tick_us, 1),
            )  # fmt: skip
            chosen = None if idx is None else {ticks[i][0] for i in idx}
        if chosen is None:
            chosen = {t for t, _, _ in ticks if t == t1 or t % c.keyframe_us == 0}
        for (t, pan, tilt), view in zip(ticks, views, strict=True):
            if t in chosen:
                self._pose_angles(t, math.radians(pan), math.radians(tilt))
                geometry = t == t1 and c.ground_truth
                self._render_key(t, geometry, angles=(pan, tilt), view=view)
        self._pose_stale = False
        # Each synthesised tick's flow bound from its two keys, for all ticks at once.
        between = [(t, v) for (t, _, _), v in zip(ticks, views, strict=True) if t not in chosen]
        self._tick_bounds = {}
        if between:
            pairs = [self._keys.neighbours(t) for t, _ in between]
            tv = [v for _, v in between]
            shape = (self.height, self.width)
            k, radii = self._keys.k, self._keys.radii
            ba = view_flow_bounds_px([p[0].view for p in pairs], tv, k, radii, shape)
            bb = view_flow_bounds_px([p[1].view for p in pairs], tv, k, radii, shape)
            both = zip(between, np.maximum(ba, bb), strict=True)
            self._tick_bounds = {t: float(b) for (t, _), b in both}

    def _frame_at(self, t_us: int) -> np.ndarray:
        """The camera frame at ``t_us``: rendered from the posed model (exact) or from
        the keys (keyframes: the model need not be posed, only the camera's view)."""
        if self._keys is None:
            return self._render()
        key = self._keys.key_at(t_us)
        if key is not None:
            return key.lum
        view = self._keyframes_view(t_us)
        kept = self._tick_views.get(t_us)
        bound = self._tick_bounds.get(t_us) if kept is not None and view is kept[2] else None
        return self._keys.frame(t_us, view, bound_px=bound)

    def _keyframes_view(self, t_us: int) -> View:
        """The view at ``t_us`` for the PTU's current angles: the one :meth:`_render_keys`
        kept for the tick when the angles agree, else the camera posed afresh."""
        pan, tilt = self.ptu.camera_pan_deg, self.ptu.camera_tilt_deg
        kept = self._tick_views.get(t_us)
        if kept is not None and kept[0] == pan and kept[1] == tilt:
            return kept[2]
        self._pose_stale = True
        return self._camera_view(t_us, pan, tilt)

    def _advance(self, t_us: int) -> None:
        """Pose the model for a frame at ``t_us`` (exact mode; keyframes need views only)."""
        if self._keys is None:
            self._pose(t_us)

    def _tick(self, t0: int, t1: int) -> tuple[list[np.ndarray], int]:
        """Advance one render period; returns its event chunks and the frames rendered."""
        ahead = self._tick_states.pop(t1, None) if self._keys is not None else None
        if ahead is not None:  # keyframes: the PTU was stepped through this tick already
            before, self.ptu = self.ptu, ahead
        else:
            before = self.ptu.copy()
            self.ptu.step((t1 - t0) * 1e-6)
        self._advance(t1)
        frame = self._frame_at(t1)
        prepared = self._key_inputs.get(t1) if self._keys is not None else None
        if prepared is None:
            prepared = self.dvs.prepare(frame)  # converted once: for the change and the step
        change = self.dvs.log_change(prepared)
        m = 1
        if change > self.config.adaptive_log_change:
            m = min(self.config.max_subframes, math.ceil(change / self.config.adaptive_log_change))
        chunks = []
        if m > 1:
            after, self.ptu = self.ptu, before
            t_prev = t0
            for j in range(1, m):
                tj = t0 + (t1 - t0) * j // m
                self.ptu.step((tj - t_prev) * 1e-6)
                t_prev = tj
                self._advance(tj)
                chunks.append(self.dvs.step(self._frame_at(tj), tj))
            self.ptu = after
            self._advance(t1)
        chunks.append(self.dvs.step(prepared, t1))
        if self._keys is None:
            self._frame = frame
        return chunks, m

    # -- gymnasium API -----------------------------------------------------------------
    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        super().reset(seed=seed)
        rng = self.np_random
        self.animator = SceneAnimator(
            self.model, self.scene, np.random.default_rng(rng.integers(2**63))
        )
        pan, tilt = (options or {}).get("gaze_deg", self.config.start_gaze_deg)
        self.ptu.reset(*self.ptu.clip_target(pan, tilt))
        self._t_us = 0
        self._pose(0)
        self.renders_in_step = 0
        if self._keys is None:
            self._frame = self._render()
            first = self._frame
        else:
            self._keys.reset()
            self._key_inputs = {}
            self._tick_states = {}
            self._render_key(0, geometry=self.config.ground_truth)
            first = self._keys.keys[0].lum
        self.dvs.reset(first, 0, seed=int(rng.integers(2**63)))
        self._last_counts = np.zeros((2, self.height, self.width), np.float32)
        empty = self.dvs.flush()
        obs = {"events": self._last_counts.copy(), "gaze": self._gaze()}
        return obs, self._info(empty, frames=1, extra=0, clipped=False)

    def step(
        self, action: np.ndarray
    ) -> tuple[dict[str, np.ndarray], float, bool, bool, dict[str, Any]]:
        if self.animator is None:
            raise RuntimeError("call reset() before step()")
        clipped = self._command(action)
        c = self.config
        chunks: list[np.ndarray] = []
        frames = 0
        self.renders_in_step = 0
        if self._keys is not None:
            self._render_keys(self._t_us, self._t_us + c.ticks_per_step * c.tick_us)
        for _ in range(c.ticks_per_step):
            t1 = self._t_us + c.tick_us
            tick_chunks, m = self._tick(self._t_us, t1)
            chunks.extend(tick_chunks)
            frames += m
            self._t_us = t1
        if self._pose_stale:  # a sub-frame's view moved the camera: back to the step's end
            self._pose(self._t_us)
            self._pose_stale = False
        events = concatenate(chunks)
        self._last_counts = to_frame(events, (self.width, self.height, 2))
        obs = {"events": self._last_counts.copy(), "gaze": self._gaze()}
        truncated = self._t_us * 1e-6 >= c.episode_seconds - 1e-9
        info = self._info(events, frames=frames, extra=frames - c.ticks_per_step, clipped=clipped)
        return obs, 0.0, False, truncated, info

    def _command(self, action: np.ndarray) -> bool:
        """Turn a relative gaze action into a PTU target; True when limits clipped it."""
        # Pixel offsets -> angles (positive pan turns left, positive tilt looks up).
        d_pan, d_tilt = action_to_gaze_degrees(
            check_action(action), self.width, self.height, self.scene.camera.hfov_deg
        )
        # Relative commands are integrated into the target (a zero action keeps the move
        # going); at rest the target is where the camera looks.
        pan0, tilt0 = self.ptu.target_deg
        want = (pan0 + d_pan, tilt0 + d_tilt)
        target = self.ptu.clip_target(*want)
        self.ptu.set_target(*target)
        return bool(np.abs(np.subtract(target, want)).max() > 1e-9)

    def _gaze(self) -> np.ndarray:
        return np.array([self.ptu.camera_pan_deg, self.ptu.camera_tilt_deg], np.float32)

    def _info(self, events: np.ndarray, frames: int, extra: int, clipped: bool) -> dict[str, Any]:
        info: dict[str, Any] = {
            "events": EventPacket(events),
            "t": self._t_us * 1e-6,
            "ptu_positions": self.ptu.positions,
            "ptu_target_positions": tuple(round(p) for p in self.ptu.target_positions),
            "ptu_target_deg": tuple(float(d) for d in self.ptu.target_deg),
            "moving": self.ptu.moving,
            "target_clipped": clipped,
            "frames": frames,
            "extra_frames": extra,
        }
        if self.config.ground_truth:
            km = self._key_mask
            mask = (
                km[1]
                if km is not None and km[0] == self._t_us
                else self.renderer.segment(self.data)
            )
            info["object_mask"] = mask
            info["objects"] = self._objects(mask)
        return info

    def _objects(self, mask: np.ndarray) -> list[dict[str, Any]]:
        positions = self.animator.object_positions(self._t_us * 1e-6)
        centres = project_points(
            self.model, self.data, positions, width=self.width, height=self.height
        )
        out = []
        for k, (obj, centre) in enumerate(zip(self.scene.moving_objects, centres, strict=True), 1):
            pixels = int(np.count_nonzero(mask == k))
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
        return None if self._frame is None else self._frame.copy()

    def render(self) -> np.ndarray | None:
        """Camera view | event frame of the last step (3x), named, the fovea marked, with
        the time stamp, the gaze and the ON/OFF key (:func:`wander_env.viz.labelled_frame`)."""
        if self.render_mode != "rgb_array":
            return None
        if self._frame is None:
            raise RuntimeError("call reset() before render()")
        pan, tilt = self._gaze()
        caption = (
            f"t = {self._t_us * 1e-6:5.2f} s   gaze pan {pan:+6.2f} deg, tilt {tilt:+6.2f} deg"
        )
        panels = [("camera", self._frame), ("events (last step)", event_image(self._last_counts))]
        return labelled_frame(panels, 3, caption, keys=("polarity", "fovea"), gap=6)

    def close(self) -> None:
        # Freeing is safe in a forked child too (only creating and drawing hang there).
        if getattr(self, "_renderer", None) is not None:
            self._renderer.close()
            self._renderer = None
        super().close()


__all__ = ["WanderConfig", "WanderEnv"]
