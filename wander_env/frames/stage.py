"""The posed scene: a model and data, the episode's animator and the camera's renderer.

:class:`Stage` poses the world at a time and camera angles and draws what the camera
sees there: a colour frame, a frame's geometry (motion layers and depth) and the ground
truth's object mask. The env drives it through a few verbs (:meth:`Stage.begin_episode`
at each reset, :meth:`Stage.begin_step` at each step); what it counts
(:attr:`Stage.renders`, :attr:`Stage.geometry_draws`) and what it holds are read, never
written, by everyone else.

Two sides, two ``MjData``:

- the **draw side** (:meth:`Stage.pose`, :meth:`Stage.render`, :meth:`Stage.geometry`,
  :meth:`Stage.object_mask`, :attr:`Stage.draw_data`): the renderer's GL context and the
  data it draws, posed at a time (the objects) and camera angles. With
  ``render_thread=True`` all of it lives on one thread of its own (an EGL context
  belongs to the thread that made it current; :mod:`wander_env.frames.draw_thread`): a
  frame source hands it work with :meth:`Stage.submit` and reads the result when it
  needs it, drawing the next key while the main thread synthesises frames and runs the
  DVS; work for the next step drawn on a guess (``ahead``) runs only while the step's
  own waits for nothing, and is adopted (:meth:`Stage.adopt_ahead`) or dropped
  (:meth:`Stage.drop_ahead`). Called from another thread, a draw-side method runs there
  and waits. Without the thread the same work runs inline, in the same order (nothing
  ahead): the same pixels either way.
- the **camera side** (:meth:`Stage.camera_views`, :meth:`Stage.pose_camera`,
  :attr:`Stage.data`): the main thread's data, where only the PTU's joints move (views
  for the frame sources, the camera for the ground truth's projection).

A thread that would wait for a key's geometry the render thread has not started may cast
it itself where it is ray cast, with a pose of its own (:meth:`Stage.geometry_here`):
the same arrays either way. Only the draw side draws: a stage's GL runs on one thread.

The renderer (and the thread) are created on first use (or by :meth:`Stage.warm_up`), in
the process that renders; in a process forked after that, drawing raises
:class:`~wander_env.gl_process.ForkedGLError` (see :mod:`wander_env.gl_process`);
:meth:`Stage.close` joins the thread.

Where every moving object is a primitive, :attr:`Stage.caster`
(:mod:`wander_env.frames.raycast`) makes the object masks and the keys' layers and depth
without a GL pass (on the draw side too: it reads the draw data).
"""

from __future__ import annotations

import math
import os
import threading
from collections.abc import Callable
from concurrent.futures import Future, wait
from dataclasses import dataclass
from typing import Any, Literal, TypeVar

import mujoco
import numpy as np

from wander_env.camera import CAMERA_NAME, intrinsics, project, rotation_from_mujoco
from wander_env.entities import PAN_JOINT, TILT_JOINT
from wander_env.frames.draw_thread import DrawThread
from wander_env.frames.keyframe_maths import View
from wander_env.frames.raycast import PrimitiveCaster, RaycastParams, unsupported_geoms
from wander_env.gl_process import ForkedGLError, fork_error_message
from wander_env.mjcf import SceneAnimator, geom_layer_ids, geom_layer_radii
from wander_env.renderer import CameraRenderer, RenderParams
from wander_env.scene_config import SceneConfig

__all__ = ["Angles", "DrawCount", "Stage"]

Angles = tuple[float, float]  # camera (pan, tilt) in degrees
T = TypeVar("T")


@dataclass
class DrawCount:
    """What a share of the draw side's work drew (GL passes; ray casts are free)."""

    renders: int = 0  # colour frames
    geometry_draws: int = 0  # layer-and-depth draws


class Stage:
    """A scene's model and data, its animator (set at each reset) and the camera's
    renderer: the world posed at a time and camera angles, and what the camera sees
    (see the module docstring for the draw side and the camera side)."""

    def __init__(
        self,
        model: mujoco.MjModel,
        scene: SceneConfig,
        params: RenderParams,
        render_thread: bool = False,
        raycast: RaycastParams | None = None,
    ) -> None:
        self.model, self.scene, self.params = model, scene, params
        self.render_thread = render_thread
        self.data = mujoco.MjData(model)  # the camera side's (main thread)
        self._draw_data = mujoco.MjData(model)  # the draw side's
        self.width, self.height = scene.camera.width, scene.camera.height
        self._pan_adr = int(model.joint(PAN_JOINT).qposadr[0])
        self._tilt_adr = int(model.joint(TILT_JOINT).qposadr[0])
        self._cam_id = int(model.camera(CAMERA_NAME).id)
        self.k = intrinsics(self.width, self.height, float(model.cam_fovy[self._cam_id]))
        self.k_inv = np.linalg.inv(self.k)
        self.layer_lut = geom_layer_ids(model)
        self._animator: SceneAnimator | None = None
        self._renderer: CameraRenderer | None = None  # created on the draw side
        self._renderer_pid: int | None = None  # the process that draws (renderer, thread)
        self._thread: DrawThread | None = None  # the render thread, once started
        self._draw_ident: int | None = None  # its thread id
        self._last: Future | None = None  # the latest of the step's work handed to it
        self._posed: tuple[int, float, float] | None = None  # (t_us, pan, tilt) drawn
        # What the step's work drew (work ahead adopted into the step adds its count),
        # what the work ahead drew, and the count the draw side's running work adds to.
        self._step_counts = [DrawCount()]
        self._ahead_count: DrawCount | None = None
        self._ahead_last: Future | None = None  # the latest work ahead handed over
        self._ahead_epoch = 0  # counts the drops of work ahead (a guess made before one is void)
        self._charging = self._step_counts[0]
        # Ray casting: masks and key geometry without a GL pass where every moving geom is
        # a primitive; None: GL draws them.
        rc = raycast or RaycastParams()
        self.caster: PrimitiveCaster | None = None
        if (rc.ground_truth or rc.key_layers) and not unsupported_geoms(model):
            self.caster = PrimitiveCaster(
                model, self.width, self.height, rc, params.visible_geom_groups
            )
        self._cast_for: SceneAnimator | None = None  # the reset the caster's cube is of
        self._here_data: mujoco.MjData | None = None  # the main thread's pose (geometry_here)

    # -- the env's verbs --------------------------------------------------------------------
    def begin_episode(self, animator: SceneAnimator) -> None:
        """A reset: the objects' motion of the new episode; nothing posed, counters zero,
        the work ahead dropped."""
        self.drop_ahead()
        self.drain()
        if self._thread is not None:  # work ahead that had started: done before the reset
            self._thread.settle()
        self._animator = animator
        self._posed = None
        self.begin_step()

    def warm_up(self) -> Future[None]:
        """Make the draw side's GL contexts now (the renderer's and the caster's: about
        0.1 s each, the first in a process) instead of at the first reset; with the
        render thread in the background, while the caller goes on. Only for a caller
        that keeps this process: a process forked after it cannot draw
        (:mod:`wander_env.gl_process`)."""
        return self.submit(self._warm_up)

    def _warm_up(self) -> None:
        self._the_renderer()
        if self._uses_caster():
            self.caster.cube_renderer()

    def begin_step(self) -> None:
        """A step's (or reset's) start: the draw counters back to zero (work ahead keeps
        running and counts in the step that adopts it)."""
        self.drain()
        self._step_counts = [DrawCount()]

    def invalidate(self) -> None:
        """The draw data was moved outside :meth:`pose` (the next pose poses it again)."""
        self._posed = None

    # -- what it holds (read-only) ------------------------------------------------------------
    @property
    def animator(self) -> SceneAnimator | None:
        """The objects' motion of the episode (None before the first reset)."""
        return self._animator

    @property
    def posed(self) -> tuple[int, float, float] | None:
        """(t_us, pan, tilt) the draw data is posed at (None: not posed at one time)."""
        return self._posed

    @property
    def draw_data(self) -> mujoco.MjData:
        """The data the renderer draws: read or move it only on the draw side (inside
        work handed to :meth:`submit`)."""
        return self._draw_data

    @property
    def renders(self) -> int:
        """Colour frames rendered for the step (or reset) since its start, the work ahead
        it adopted included (once the work handed to the draw side has run)."""
        self.drain()
        return sum(c.renders for c in self._step_counts)

    @property
    def geometry_draws(self) -> int:
        """Layer-and-depth draws for the step (or reset) (as :attr:`renders`)."""
        self.drain()
        return sum(c.geometry_draws for c in self._step_counts)

    @property
    def renderer(self) -> CameraRenderer:
        """The camera's renderer, created on first use on the draw side (use it there)."""
        return self.on_draw_side(self._the_renderer)

    def _the_renderer(self) -> CameraRenderer:
        if self._renderer is None:
            self._renderer = CameraRenderer(self.model, self.width, self.height, params=self.params)
            self._renderer_pid = os.getpid()
        return self._renderer

    def layer_radii(self) -> np.ndarray:
        """Bounding radius (m) of each motion layer about its position, 1 % beyond the
        geoms' reach (meshes included; inf: the static world or a sliding screen)."""
        return geom_layer_radii(self.model) * 1.01

    def camera_centre_moves(self) -> bool:
        """Whether the camera centre moves as the PTU turns: the model's camera sits off
        the tilt hinge (the unit's hinge offset, ``PTUParams.camera_forward_m`` /
        ``camera_up_m``, that the model was built with)."""
        return bool(np.any(self.model.cam_pos[self._cam_id] != 0))

    # -- handing work to the draw side ----------------------------------------------------------
    def _check_process(self) -> None:
        pid = os.getpid()
        if self._renderer_pid is not None and self._renderer_pid != pid:
            raise ForkedGLError(fork_error_message(self._renderer_pid, pid))

    @property
    def draws_ahead(self) -> bool:
        """Whether work ahead of time can be handed over (:meth:`submit` with ``ahead``):
        only with the render thread, where it runs beside the main thread's work."""
        return self.render_thread

    def submit(self, fn: Callable[..., T], *args: Any, ahead: bool = False) -> Future[T]:
        """Run ``fn(*args)`` on the draw side: on the render thread (in the order handed
        over), else here and now; its result (or its exception, raised where the result
        is read) as a future. With ``ahead`` (the render thread only: :attr:`draws_ahead`)
        it is work for the next step, drawn on a guess: it runs when the step's work
        waits for nothing, and is adopted or dropped at the next step's start."""
        self._check_process()
        if not self.render_thread or self.on_draw_thread:
            if ahead:
                raise ValueError("work ahead needs the render thread (Stage.draws_ahead)")
            if not self.on_draw_thread:
                self._charging = self._step_counts[0]
            done: Future[T] = Future()
            try:
                done.set_result(fn(*args))
            except Exception as e:  # raised where the result is read, as on the thread
                done.set_exception(e)
            return done
        if self._thread is None:
            self._thread = DrawThread("wander-render")
            self._renderer_pid = os.getpid()
            self._draw_ident = self._thread.ident
        if ahead:
            if self._ahead_count is None:
                self._ahead_count = DrawCount()
            self._ahead_last = self._thread.submit(
                self._charged, self._ahead_count, fn, args, ahead=True
            )
            return self._ahead_last
        self._last = self._thread.submit(self._charged, self._step_counts[0], fn, args)
        return self._last

    def _charged(self, count: DrawCount, fn: Callable[..., T], args: tuple[Any, ...]) -> T:
        """(On the draw side.) ``fn(*args)``, its draws counted in ``count``."""
        self._charging = count
        return fn(*args)

    def adopt_ahead(self) -> None:
        """The work ahead was for this step: it joins the step's work (what has not run
        yet runs next, in its order) and its draws count in the step."""
        if self._thread is None or self._ahead_count is None:
            return
        self._thread.promote()
        self._step_counts.append(self._ahead_count)
        if self._ahead_last is not None and not self._ahead_last.done():
            self._last = self._ahead_last
        self._ahead_count = self._ahead_last = None

    def drop_ahead(self) -> None:
        """The work ahead was not for this step: what has not started never runs."""
        if self._thread is not None:
            self._thread.cancel_ahead()
        self._ahead_count = self._ahead_last = None
        self._ahead_epoch += 1

    @property
    def ahead_epoch(self) -> int:
        """How many times work ahead was dropped: a source adopts its work ahead only if
        none was dropped since it handed it over."""
        return self._ahead_epoch

    @property
    def on_draw_thread(self) -> bool:
        """Whether this call runs on the render thread (inside work handed to it)."""
        return self._thread is not None and threading.get_ident() == self._draw_ident

    def _from_outside(self) -> bool:
        """Whether this call comes from outside the render thread (while it runs)."""
        return self._thread is not None and threading.get_ident() != self._draw_ident

    def _take_over(self) -> None:
        """A draw-side verb called from outside, one call at a time: work ahead would run
        between its calls and move the draw data, so it is dropped."""
        if self._from_outside() and self._ahead_count is not None:
            self.drop_ahead()

    def on_draw_side(self, fn: Callable[..., T], *args: Any) -> T:
        """``fn(*args)`` run on the draw side, waited for."""
        return self.submit(fn, *args).result()

    def drain(self) -> None:
        """Wait until the work handed to the render thread has run (errors stay with
        their futures)."""
        if self._last is not None and threading.get_ident() != self._draw_ident:
            wait([self._last])
            self._last = None

    # -- the draw side ----------------------------------------------------------------------------
    def pose(self, t_us: int, pan_deg: float, tilt_deg: float) -> None:
        """The camera at these angles and the objects at ``t_us`` into the draw data."""
        self._take_over()
        self.on_draw_side(self._pose, t_us, pan_deg, tilt_deg)

    def _pose(self, t_us: int, pan_deg: float, tilt_deg: float) -> None:
        if self._posed == (t_us, pan_deg, tilt_deg):
            return
        self._pose_into(self._draw_data, t_us, pan_deg, tilt_deg)
        self._posed = (t_us, pan_deg, tilt_deg)

    def _pose_into(self, data: mujoco.MjData, t_us: int, pan_deg: float, tilt_deg: float) -> None:
        data.qpos[self._pan_adr] = math.radians(pan_deg)
        data.qpos[self._tilt_adr] = math.radians(tilt_deg)
        self._animator.apply(data, t_us * 1e-6)
        mujoco.mj_kinematics(self.model, data)
        mujoco.mj_camlight(self.model, data)

    def render(self) -> np.ndarray:
        """RGB uint8 (H, W, 3) of the posed draw data."""
        self._take_over()
        return self.on_draw_side(self._render)

    def _render(self) -> np.ndarray:
        self._charging.renders += 1
        return self._the_renderer().render(self._draw_data)

    def casts(self, what: Literal["ground_truth", "key_layers"]) -> bool:
        """Whether ray casting (:attr:`caster`) makes the object masks (``ground_truth``)
        or the keys' layers and depth (``key_layers``: the camera on its hinge only)."""
        c = self.caster
        if c is None or not getattr(c.params, what):
            return False
        return what == "ground_truth" or c.exact_depth

    def _ready_caster(self) -> PrimitiveCaster:
        """(On the draw side.) The caster, its static cube dropped at each reset."""
        if self._cast_for is not self._animator:
            self.caster.reset()
            self._cast_for = self._animator
        return self.caster

    def geometry(self) -> tuple[np.ndarray, np.ndarray]:
        """(motion layers int32, depth m) of the posed draw data, from one draw (or ray
        cast: not counted in :attr:`geometry_draws`)."""
        self._take_over()
        return self.on_draw_side(self._geometry)

    def _geometry(self) -> tuple[np.ndarray, np.ndarray]:
        if self.casts("key_layers"):
            return self._ready_caster().geometry(self._draw_data)
        self._charging.geometry_draws += 1
        renderer = self._the_renderer()
        renderer.update(self._draw_data)
        return renderer.segment_depth_current(self.layer_lut)

    def casts_here(self) -> bool:
        """Whether :meth:`geometry_here` can cast a key's geometry on this thread now:
        off the render thread, where the keys' layers are ray cast and the caster's
        static cube is of this episode (no GL left to do). Posing then writes only the
        pose's own data: the one scene whose posing writes the model (the gratings'
        strip colours) has a plane screen, which the caster does not take."""
        return self._from_outside() and self.casts("key_layers") and self._cube_of_episode()

    def _uses_caster(self) -> bool:
        """Whether the caster makes the masks or the keys' layers (its static cube
        rendered once an episode, on the draw side)."""
        return self.casts("ground_truth") or self.casts("key_layers")

    def _cube_of_episode(self) -> bool:
        """Whether the caster's static cube of this episode is rendered: casting then
        needs no GL, and the draw side no longer changes the model for it."""
        return self._cast_for is self._animator and self.caster.cube_ready

    def geometry_here(self, t_us: int, angles: Angles) -> tuple[np.ndarray, np.ndarray]:
        """(motion layers int32, depth m) at ``t_us`` and ``angles``, ray cast on this
        thread into a pose of its own (only where :meth:`casts_here`): the same arrays
        as :meth:`geometry_at` on the draw side, while the render thread draws."""
        if not self.casts_here():
            raise RuntimeError("geometry_here: this thread cannot cast now (casts_here)")
        return self.caster.geometry(self._here_pose(t_us, angles))

    def _here_pose(self, t_us: int, angles: Angles) -> mujoco.MjData:
        """(Main thread.) Its own data posed at ``t_us`` and ``angles``."""
        if self._here_data is None:
            self._here_data = mujoco.MjData(self.model)
        self._pose_into(self._here_data, t_us, *angles)
        return self._here_data

    def object_mask(self) -> np.ndarray:
        """Object ids (H, W) int32 of the posed draw data (0 = background)."""
        self._take_over()
        return self.on_draw_side(self._object_mask)

    def _object_mask(self) -> np.ndarray:
        if self.casts("ground_truth"):
            return self._ready_caster().object_mask(self._draw_data)
        return self._the_renderer().segment(self._draw_data)

    def colour_at(self, t_us: int, angles: Angles) -> np.ndarray:
        """:meth:`pose` then :meth:`render` (work for :meth:`submit`; from outside the
        draw side, one piece of work)."""
        if self._from_outside():
            return self.on_draw_side(self.colour_at, t_us, angles)
        self.pose(t_us, *angles)
        return self.render()

    def geometry_at(self, t_us: int, angles: Angles) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`pose` then :meth:`geometry` (as :meth:`colour_at`)."""
        if self._from_outside():
            return self.on_draw_side(self.geometry_at, t_us, angles)
        self.pose(t_us, *angles)
        return self.geometry()

    def object_mask_at(self, t_us: int, angles: Angles) -> np.ndarray:
        """:meth:`pose` then :meth:`object_mask` (as :meth:`colour_at`)."""
        if self._from_outside():
            return self.on_draw_side(self.object_mask_at, t_us, angles)
        self.pose(t_us, *angles)
        return self.object_mask()

    # -- the camera side -------------------------------------------------------------------------
    def pose_camera(self, pan_deg: float, tilt_deg: float) -> None:
        """The camera side's data with the camera at these angles (the objects as they
        were: the ground truth projects their positions through this camera)."""
        self.camera_views([0], [(pan_deg, tilt_deg)])

    def project(self, points: np.ndarray) -> np.ndarray:
        """World points (N, 3) -> pixel coordinates (N, 2) (x right, y down; NaN behind
        the camera) through the camera side's pose (:meth:`pose_camera`)."""
        r_wc = rotation_from_mujoco(self.data.cam_xmat[self._cam_id])
        return project(self.k, r_wc, self.data.cam_xpos[self._cam_id], points)[0]

    def camera_view(self, t_us: int, pan_deg: float, tilt_deg: float) -> View:
        """The :class:`View` at ``t_us`` with the camera at these angles (the camera
        side's data moved there)."""
        return self.camera_views([t_us], [(pan_deg, tilt_deg)])[0]

    def camera_views(self, times_us: list[int], angles: list[Angles]) -> list[View]:
        """:meth:`camera_view` at each time and angles; the camera is posed again only
        where the angles change."""
        views, last = [], None
        data = self.data
        layers = self._animator.layer_positions_at(np.asarray(times_us, np.int64) * 1e-6)
        for a, at_t in zip(angles, layers, strict=True):
            if a != last:
                data.qpos[self._pan_adr] = math.radians(a[0])
                data.qpos[self._tilt_adr] = math.radians(a[1])
                mujoco.mj_kinematics(self.model, data)
                mujoco.mj_camlight(self.model, data)
                rotation = rotation_from_mujoco(data.cam_xmat[self._cam_id])
                centre, last = data.cam_xpos[self._cam_id].copy(), a
            views.append(View(rotation, centre, at_t))
        return views

    def close_renderer(self, renderer: CameraRenderer) -> None:
        """Free another renderer made on the draw side (forget it in a forked child)."""
        if self._renderer_pid is not None and self._renderer_pid != os.getpid():
            renderer.abandon()
        elif self._thread is not None:
            self._thread.submit(renderer.close).result()
        else:
            renderer.close()

    def close(self) -> None:
        """Free the renderer on the draw side and join the render thread (idempotent).
        In a process forked after drawing, the GL state is the parent's: forgotten, not
        freed."""
        thread = self._thread
        forked = self._renderer_pid is not None and self._renderer_pid != os.getpid()
        if thread is not None and not forked:
            # The step's work left (a step that raised leaves some) runs while the thread
            # is still this stage's: work that poses on the draw side stays on it.
            thread.cancel_ahead()
            thread.settle()
        self._thread = self._last = None
        self._ahead_count = self._ahead_last = None
        renderer, self._renderer = self._renderer, None
        if forked:
            if renderer is not None:
                renderer.abandon()
            if self.caster is not None:
                self.caster.abandon()
            return
        for free in (renderer, self.caster):
            if free is None:
                continue
            if thread is not None:
                thread.submit(free.close).result()
            else:
                free.close()
        if thread is not None:
            thread.close()
        self._draw_ident = None
