"""The keyframe source: keys rendered where the image motion needs them, the frames
between them synthesised from the keys' geometry (:mod:`wander_env.frames.keyframe_maths`).

With the render thread, the next step's keys are drawn ahead of time on a guess of its
trajectory (:meth:`KeyframeFrames.plan_ahead`: the PTU left to itself, as a zero action
leaves it), while the main thread makes this step's frames and the agent decides; the
next :meth:`~KeyframeFrames.plan` adopts them where the trajectory is the one guessed
and drops them where it is not. A key is the same pixels whenever it is drawn, so the
frames, events and masks are the same with and without the guess. The in-between frames
the plan knows it needs are synthesised on the draw side too, after the keys they lie
between (the main thread runs the DVS over one while the next is made)."""

from __future__ import annotations

import bisect
import threading
from collections.abc import Callable
from concurrent.futures import Future
from dataclasses import dataclass, field, replace
from itertools import pairwise
from typing import TypeVar

import numpy as np

from wander_env.dvs import DVSEmulator, LogFrame
from wander_env.frames.flow_bounds import adaptive_key_ticks, left_to_dvs, view_flow_bounds_px
from wander_env.frames.keyframe_maths import (
    SUBPIXEL_PX,
    Keyframe,
    KeyPair,
    View,
    blend,
    make_keyframe,
    turned,
)
from wander_env.frames.source import FrameParams, FrameSource
from wander_env.frames.stage import Angles, Stage
from wander_env.ptu.unit import Trajectory

__all__ = ["KeyframeFrames", "RenderedKey"]

T = TypeVar("T")


@dataclass(eq=False)
class RenderedKey:
    """A key as rendered: its colour, the colour's DVS input and luminance at ``t_us``
    from the camera at ``angles`` (``view``), drawn on the stage's draw side (``drawn``:
    read when first needed). Its DVS input is made once (``prepare``, the DVS's) by the
    first thread that reads it (the render thread only draws its colour). Its geometry
    (layers and depth, one more draw) is made only when something asks for it
    (:meth:`KeyframeFrames.keyframe`): a synthesised frame between it and a neighbour,
    or the ground truth's mask. ``same_as``: an earlier key whose geometry this one
    shares (nothing moved between them)."""

    t_us: int
    angles: Angles
    view: View
    drawn: Future[np.ndarray]  # its RGB
    shape: tuple[int, int]  # (H, W)
    prepare: Callable[[np.ndarray], LogFrame]  # RGB -> the DVS's input
    same_as: RenderedKey | None = None
    full: Keyframe | None = None  # with its geometry, once made
    geometry: Future[tuple[np.ndarray, np.ndarray] | None] | None = None  # its layers
    # and depth, once asked for
    pair: tuple[RenderedKey, KeyPair] | None = None  # the pair ending here, once made
    _prepared: LogFrame | None = field(default=None, repr=False)
    _lock: threading.Lock = field(default_factory=threading.Lock, repr=False)

    @property
    def rgb(self) -> np.ndarray:
        """The key's colour frame (H, W, 3) uint8."""
        return self.drawn.result()

    @property
    def prepared(self) -> LogFrame:
        """The key's DVS input (made here if no thread has made it yet)."""
        if self._prepared is None:
            rgb = self.drawn.result()
            with self._lock:
                if self._prepared is None:
                    self._prepared = self.prepare(rgb)
        return self._prepared

    @property
    def lum(self) -> np.ndarray:
        """(H, W) float32 linear luminance (a view of ``prepared.lum``)."""
        return self.prepared.lum.reshape(self.shape)


@dataclass
class StepLayout:
    """A step's plan before anything is drawn: its ticks, the camera's angles and views
    there, the ticks drawn as new keys (``idx``), the ticks the keys' blend or the DVS's
    interpolation stands for, and the keys (0: the step's start) whose geometry is
    sure to be needed."""

    ticks: tuple[int, ...]
    angles: list[Angles]
    views: list[View]
    idx: list[int]
    interpolated: set[int] = field(default_factory=set)
    skipped: set[int] = field(default_factory=set)
    need: set[int] = field(default_factory=set)


@dataclass
class _Ahead:
    """The next step's keys drawn on a guessed trajectory, after the key ``ref``."""

    trajectory: Trajectory
    ref: RenderedKey
    layout: StepLayout
    new: list[RenderedKey]
    made: dict[int, Future[LogFrame]]
    epoch: int  # the stage's ahead_epoch when handed over


def _done(value: T) -> Future[T]:
    """A future that holds ``value``."""
    future: Future[T] = Future()
    future.set_result(value)
    return future


def _pair_in(keys: list[RenderedKey], t_us: int) -> tuple[RenderedKey, RenderedKey]:
    """The keys just before and at-or-after ``t_us`` in ``keys`` (in time order)."""
    i = bisect.bisect_left([key.t_us for key in keys], t_us)
    return keys[i - 1], keys[i]


def _same_motion(a: Trajectory, b: Trajectory) -> bool:
    """Whether two trajectories pass the same ticks at the same camera angles."""
    return (a.t0_us, a.t_us, a.pan_deg, a.tilt_deg) == (b.t0_us, b.t_us, b.pan_deg, b.tilt_deg)


class KeyframeFrames(FrameSource):
    """Keys rendered at the step's start along the trajectory where the predicted image
    motion asks for them (:func:`~wander_env.frames.flow_bounds.adaptive_key_ticks`: as
    few as one a step, none while nothing moves; every ``keyframe_us`` where the motion
    has no bound); the frames between them synthesised
    (:class:`~wander_env.frames.keyframe_maths.KeyPair`), and none where nothing moves by
    half a pixel: the DVS interpolates there.

    A key's geometry (layers and depth: a second, single-sample draw) is drawn when first
    needed, with the model posed again at the key's time and angles (the same pixels as
    drawing it with the colour): a synthesised frame needs both its keys', the ground
    truth's mask the step end's; a still camera over slow objects, or ground truth off,
    needs fewer or none."""

    def __init__(
        self,
        stage: Stage,
        dvs: DVSEmulator,
        params: FrameParams,
        geometry_at_keys: bool = False,
        frames_on_draw_side: bool = True,
    ) -> None:
        super().__init__(stage, dvs, params)
        self.geometry_at_keys = geometry_at_keys  # each key's geometry used at its own tick
        # The planned in-between frames synthesised on the draw side (False: a source that
        # composites the keys' layers itself and never asks for them).
        self.frames_on_draw_side = frames_on_draw_side
        self.radii = stage.layer_radii()
        self.keys: list[RenderedKey] = []  # the key at the step's start, then the step's
        self._latest: RenderedKey | None = None  # the latest key rendered
        self._key_at: dict[int, RenderedKey] = {}  # key t_us -> key (this step)
        self._views: dict[int, View] = {}  # tick t_us -> its view (this step)
        self._interpolated: set[int] = set()  # ticks the keys' blend (subpixel from both)
        self._skipped: set[int] = set()  # more ticks the DVS interpolates over
        self._only_keys = False  # the step synthesises no frame (see _start)
        self._made: dict[int, Future[LogFrame]] = {}  # tick -> its frame, on the draw side
        self._ahead: _Ahead | None = None  # the next step's keys, drawn on a guess
        self._mask_ahead: tuple[int, Future[np.ndarray]] | None = None  # (t_us, mask)
        self.keys_ahead_adopted = self.keys_ahead_dropped = 0  # (FrameSource's counts)

    @property
    def camera_frame(self) -> np.ndarray | None:
        """The latest key's colour frame."""
        return None if self._latest is None else self._latest.rgb

    def render_key(self, t_us: int, angles: Angles, view: View, ahead: bool = False) -> RenderedKey:
        """A key of the model posed at ``t_us`` and ``angles``, its colour handed to the
        draw side (read when first needed); ``ahead``: for the next step, on a guess."""
        stage = self.stage
        drawn = stage.submit(stage.colour_at, t_us, angles, ahead=ahead)
        shape = (stage.height, stage.width)
        key = RenderedKey(t_us, angles, view, drawn, shape, self.dvs.prepare)
        if not ahead:
            self._latest = key
        return key

    def keyframe(self, key: RenderedKey) -> Keyframe:
        """``key`` with its geometry: its layers and depth drawn on first use (the model
        posed again at the key's time and angles), made a :class:`Keyframe` by the thread
        that first needs it (the draw side only draws), then kept."""
        if key.full is None:
            if key.same_as is not None:
                key.full = replace(self.keyframe(key.same_as), t_us=key.t_us, view=key.view)
            else:
                drawn = self._geometry_now(key)
                if drawn is not None and key.full is None:  # (else made meanwhile)
                    layers, depth = drawn
                    self._help_until(key.drawn)
                    key.full = make_keyframe(key.t_us, key.lum, key.view, depth, layers)
        return key.full

    def _geometry_now(self, key: RenderedKey) -> tuple[np.ndarray, np.ndarray] | None:
        """The layers and depth of ``key`` (a key that shares none, not yet made), asked
        for if they were not: on the render thread drawn there and then (its queue holds
        the drawing behind the work running now, or the main thread took it; the queued
        one then finds the key made); elsewhere cast here if the render thread has not
        started them, else waited for, doing its casts meanwhile. None where the key was
        made meanwhile."""
        self.request_geometry(key)
        pending = key.geometry
        if self.stage.on_draw_thread and (not pending.done() or pending.cancelled()):
            return self._draw_geometry(key)
        if self._cast_here(key):
            return key.geometry.result()
        self._help_until(pending)
        return pending.result()

    def _cast_here(self, key: RenderedKey) -> bool:
        """(Main thread.) Cast the geometry of ``key`` (a key that shares none) here if
        the render thread has not started drawing it and casting needs no GL; whether
        it was."""
        pending = key.geometry
        if pending is None or key.full is not None or not self.stage.casts_here():
            return False
        if not pending.cancel():  # started or done there
            return False
        key.geometry = _done(self.stage.geometry_here(key.t_us, key.angles))
        return True

    def _mask_is_layers(self, key: RenderedKey | None) -> bool:
        """Whether the ground truth's mask at ``key`` is its ray-cast layers: a key drawn
        at its own pose (not one standing for a still step's end), layers ray cast (the
        caster labels them with the objects' ids, as its masks)."""
        return key is not None and key.same_as is None and self.stage.casts("key_layers")

    def _cast_layers(self, key: RenderedKey) -> np.ndarray:
        """The layers of ``key``'s ray-cast geometry, read from its keyframe or its
        geometry (cast here where the render thread has not started it)."""
        if key.full is None:
            drawn = self._geometry_now(key)
            if drawn is not None:
                return drawn[0]
        return key.full.layers

    def _help_until(self, future: Future) -> None:
        """(Main thread.) While ``future`` (the render thread's) is not done, cast the
        geometry of keys the render thread has not started (the latest first: the
        render thread takes its queue from the front), so that a wait does its work."""
        if future.done() or not self.stage.casts_here():
            return
        ahead = self._ahead.new if self._ahead is not None else []
        for key in reversed([*self.keys, *ahead]):
            if future.done():
                return
            if key.same_as is None:
                self._cast_here(key)

    def request_geometry(self, key: RenderedKey, ahead: bool = False) -> None:
        """Hand the drawing of ``key``'s geometry (that of the key it shares it with) to
        the draw side, once; a frame that needs it reads it with :meth:`keyframe`."""
        root = key if key.same_as is None else key.same_as
        if root.geometry is None and root.full is None:
            root.geometry = self.stage.submit(self._draw_geometry, root, ahead=ahead)

    def _draw_geometry(self, key: RenderedKey) -> tuple[np.ndarray, np.ndarray] | None:
        """(On the draw side.) ``key``'s layers and depth (None where the key was made
        meanwhile)."""
        if key.full is not None:
            return None
        return self.stage.geometry_at(key.t_us, key.angles)

    def start_with(self, keys: list[RenderedKey]) -> None:
        """The stream's keys from here on: ``keys`` (none: no key, nothing planned)."""
        self.keys, self._key_at = keys, {key.t_us: key for key in keys}
        self._views, self._made, self._interpolated, self._skipped = {}, {}, set(), set()

    def key_at(self, t_us: int) -> RenderedKey | None:
        """The key of this step rendered at ``t_us`` (None: none there)."""
        return self._key_at.get(t_us)

    def reset(self, t_us: int, angles: Angles) -> LogFrame:
        self._drop_ahead()
        self._mask_ahead = None
        key = self.render_key(t_us, angles, self.stage.camera_view(t_us, *angles))
        self.start_with([key])
        return key.prepared

    def plan(self, trajectory: Trajectory) -> None:
        ref = self.keys[-1]
        ahead, self._ahead = self._ahead, None
        if (
            ahead is not None
            and ahead.ref is ref
            and ahead.epoch == self.stage.ahead_epoch
            and _same_motion(ahead.trajectory, trajectory)
        ):
            self.stage.adopt_ahead()
            layout, new = ahead.layout, ahead.new
            self.keys_ahead_adopted += len(new)
            if new:
                self._latest = new[-1]
            self._start(ref, layout, new)
            self._made = ahead.made
        else:
            if ahead is not None:
                self._drop(ahead)
            layout = self._key_ticks(ref, trajectory)
            # The first new key goes to the draw side now, before the rest of the plan.
            first = self.render_key(*self._key_of(layout, 0)) if layout.idx else None
            self._frames_plan(ref, layout)
            new = self._draw_keys(layout, first=first)
            self._start(ref, layout, new)
            self._made = self._make_frames(self.keys, layout)
        self._mask_ahead = None
        if self.params.ground_truth and self.stage.casts("ground_truth"):
            end = (layout.ticks[-1], layout.angles[-1])
            key = self._key_at.get(end[0])
            if self._mask_is_layers(key):
                self.request_geometry(key)  # the mask is the key's layers: one cast for both
            else:
                self._mask_ahead = (end[0], self.stage.submit(self.stage.object_mask_at, *end))

    def plan_ahead(self, trajectory: Trajectory) -> None:
        """Draw the next step's keys on a guess of its ``trajectory`` (with the render
        thread; see the module docstring)."""
        if not self.stage.draws_ahead or not self.keys:
            return
        self._drop_ahead()
        ref = self.keys[-1]
        layout = self._key_ticks(ref, trajectory)
        self._frames_plan(ref, layout)
        if 0 in layout.need:
            self.request_geometry(ref, ahead=True)
        new = self._draw_keys(layout, None, ahead=True)
        made = self._make_frames([ref, *new], layout, ahead=True) if new else {}
        self._ahead = _Ahead(trajectory, ref, layout, new, made, self.stage.ahead_epoch)

    def _drop_ahead(self) -> None:
        ahead, self._ahead = self._ahead, None
        if ahead is not None:
            self._drop(ahead)

    def _drop(self, ahead: _Ahead) -> None:
        """Drop the keys drawn on a wrong guess (those not yet drawn never are)."""
        self.stage.drop_ahead()
        self.keys_ahead_dropped += len(ahead.new)

    def _key_ticks(self, ref: RenderedKey, trajectory: Trajectory) -> StepLayout:
        """The step's views and its new keys' ticks after the key ``ref``."""
        p, stage = self.params, self.stage
        ticks = trajectory.t_us
        angles = [trajectory.angles(i) for i in range(len(ticks))]
        views = stage.camera_views(list(ticks), angles)
        shape, k = (stage.height, stage.width), stage.k
        idx = None
        if p.keyframe_px is not None:
            idx = adaptive_key_ticks(
                ref.view, views, k, self.radii, shape, p.keyframe_px, p.key_max_ticks
            )
        if idx is None:
            idx = [i for i, t in enumerate(ticks) if t == ticks[-1] or t % p.keyframe_us == 0]
        return StepLayout(ticks, angles, views, idx)

    @staticmethod
    def _key_of(layout: StepLayout, n: int) -> tuple[int, Angles, View]:
        i = layout.idx[n]
        return layout.ticks[i], layout.angles[i], layout.views[i]

    def _frames_plan(self, ref: RenderedKey, layout: StepLayout) -> None:
        """Fill in ``layout``'s ticks left to the keys' blend and to the DVS, and the keys
        whose geometry is sure to be needed."""
        p, stage = self.params, self.stage
        ticks, views, idx = layout.ticks, layout.views, layout.idx
        shape, k = (stage.height, stage.width), stage.k
        if idx:
            key_t = [ref.t_us, *(ticks[i] for i in idx)]
            key_v = [ref.view, *(views[i] for i in idx)]
        else:  # nothing moves: the start's key is the step's end too
            key_t, key_v = [ref.t_us, ticks[-1]], [ref.view, views[-1]]
        # The ticks between keys whose content moves by less than half a pixel from both.
        at_key = set(key_t)
        between = [(t, v) for t, v in zip(ticks, views, strict=True) if t not in at_key]
        later = [bisect.bisect_left(key_t, t) for t, _ in between]  # each one's later key
        layout.interpolated = set()
        if between:
            tv = [v for _, v in between]
            refs = [key_v[j - 1] for j in later] + [key_v[j] for j in later]
            both = view_flow_bounds_px(refs, tv + tv, k, self.radii, shape)
            bounds = np.maximum(both[: len(tv)], both[len(tv) :])
            layout.interpolated = {
                t
                for (t, v), j, b in zip(between, later, bounds, strict=True)
                if b < SUBPIXEL_PX and not turned(key_v[j - 1], v) and not turned(key_v[j], v)
            }
        layout.skipped = set()
        if p.interpolate_px is not None:
            layout.skipped = self._left_to_dvs(ref.view, layout, at_key)
        # The geometry sure (or all but) to be needed: where any tick is synthesised or
        # the camera turns, every key's (a frame whose change is large has sub-frames
        # synthesised before it, which the plan cannot foresee); the step end's for the
        # ground truth; and with geometry_at_keys (a source compositing the keys' layers
        # at every frame) every new key's.
        need = set(range(1, len(key_t))) if self.geometry_at_keys else set()
        if any(turned(a, b) for a, b in pairwise(key_v)) or any(
            t not in layout.interpolated and t not in layout.skipped for t, _ in between
        ):
            need |= set(range(len(key_t)))
        if p.ground_truth and key_t[-1] == ticks[-1]:
            need.add(len(key_t) - 1)
        layout.need = need

    def _draw_keys(
        self, layout: StepLayout, first: RenderedKey | None, ahead: bool = False
    ) -> list[RenderedKey]:
        """The layout's new keys handed to the draw side in time order (``first`` already
        there), each with its geometry where that is sure to be needed, so that the frames
        up to a key are made while the next one is drawn; ``ahead``: for the next step, on
        a guess."""
        new = []
        for n in range(len(layout.idx)):
            key = first if n == 0 and first is not None else None
            if key is None:
                key = self.render_key(*self._key_of(layout, n), ahead=ahead)
            new.append(key)
            if n + 1 in layout.need:
                self.request_geometry(key, ahead=ahead)
        return new

    def _start(self, ref: RenderedKey, layout: StepLayout, new: list[RenderedKey]) -> None:
        """The step's keys from ``ref`` on: ``new`` (drawn), or where nothing moves the
        start's key standing for the step's end too."""
        ticks, views, need = layout.ticks, layout.views, layout.need
        self.keys = [ref]
        if 0 in need:
            self.request_geometry(ref)
        if not layout.idx:  # its geometry that of the key it was rendered as, however many
            # still steps ago
            root = ref if ref.same_as is None else ref.same_as
            self.keys.append(
                replace(
                    ref,
                    t_us=ticks[-1],
                    view=views[-1],
                    same_as=root,
                    full=None,
                    geometry=None,
                    pair=None,
                )
            )
            if 1 in need:
                self.request_geometry(self.keys[1])
        self.keys.extend(new)
        self._views = dict(zip(ticks, views, strict=True))
        self._interpolated, self._skipped = layout.interpolated, layout.skipped
        self._key_at = {key.t_us: key for key in self.keys}

    def _left_to_dvs(self, start: View, layout: StepLayout, at_key: set[int]) -> set[int]:
        """The ticks (not already the keys' blend) whose frames the DVS goes without
        (:func:`~wander_env.frames.flow_bounds.left_to_dvs`; the keys stay)."""
        stage = self.stage
        ticks, views = layout.ticks, layout.views
        handed = [i for i, t in enumerate(ticks) if t not in layout.interpolated]
        skip = left_to_dvs(
            start,
            [views[i] for i in handed],
            [ticks[i] in at_key for i in handed],
            stage.k,
            self.radii,
            (stage.height, stage.width),
            self.params.interpolate_px,
        )
        return {ticks[handed[j]] for j in skip}

    def pair(self, t_us: int) -> tuple[RenderedKey, RenderedKey]:
        """The keys just before and at-or-after ``t_us`` (inside the planned step)."""
        return _pair_in(self.keys, t_us)

    def _keypair(self, a: RenderedKey, b: RenderedKey) -> KeyPair:
        """The keys' :class:`KeyPair` (with their geometry), made once (kept by ``b``)."""
        if b.pair is None or b.pair[0] is not a:
            b.pair = (
                a,
                KeyPair(self.keyframe(a), self.keyframe(b), self.stage.k, self.stage.k_inv),
            )
        return b.pair[1]

    def _make_frames(
        self, keys: list[RenderedKey], layout: StepLayout, ahead: bool = False
    ) -> dict[int, Future[LogFrame]]:
        """Hand the step's in-between frames (the ticks neither a key, the keys' blend nor
        left to the DVS) to the draw side, after the keys they lie between."""
        if not self.frames_on_draw_side or len(keys) < 2:
            return {}
        at_key = {key.t_us for key in keys}
        skip = at_key | layout.interpolated | layout.skipped
        return {
            t: self.stage.submit(self._made_frame, *_pair_in(keys, t), t, view, ahead=ahead)
            for t, view in zip(layout.ticks, layout.views, strict=True)
            if t not in skip
        }

    def _made_frame(self, a: RenderedKey, b: RenderedKey, t_us: int, view: View) -> LogFrame:
        """The frame of ``view`` at ``t_us`` synthesised between the keys ``a`` and ``b``
        (on the draw side where the plan hands it over)."""
        w = (t_us - a.t_us) / (b.t_us - a.t_us)
        return self.dvs.prepare(self.synthesize(self._keypair(a, b), view, w))

    def interpolated(self, t_us: int) -> bool:
        return t_us in self._interpolated or t_us in self._skipped

    def frame(self, t_us: int, angles: Angles) -> LogFrame:
        """A key's own input at its tick; the keys' blend where nothing moves by half a
        pixel; else a synthesised frame."""
        key = self._key_at.get(t_us)
        if key is not None:
            self._help_until(key.drawn)
            return key.prepared
        made = self._made.pop(t_us, None)
        if made is not None and not made.cancel():  # (not started there: made here)
            return made.result()
        a, b = self.pair(t_us)
        w = (t_us - a.t_us) / (b.t_us - a.t_us)
        if t_us in self._interpolated:
            return self.dvs.prepare(blend(a.lum, b.lum, w))
        view = self._views.get(t_us)
        if view is None:  # a sub-frame inside a tick
            view = self.stage.camera_view(t_us, *angles)
            shape, k = (self.stage.height, self.stage.width), self.stage.k
            bound = view_flow_bounds_px([a.view, b.view], [view, view], k, self.radii, shape)
            if bound.max() < SUBPIXEL_PX and not (turned(a.view, view) or turned(b.view, view)):
                return self.dvs.prepare(blend(a.lum, b.lum, w))
        return self._made_frame(a, b, t_us, view)

    def synthesize(self, pair: KeyPair, view: View, w: float) -> np.ndarray:
        """An in-between frame (a method of its own, for profiling)."""
        return pair.frame(view, w)

    def object_mask(self, t_us: int) -> np.ndarray:
        key = self._key_at.get(t_us)
        if self.stage.casts("ground_truth"):  # ray cast, handed over at the step's start
            if self._mask_ahead is not None and self._mask_ahead[0] == t_us:
                return self._mask_ahead[1].result()
            if self._mask_is_layers(key):
                return self._cast_layers(key).copy()
            if key is not None:  # (a source whose stream ends elsewhere: the key's pose)
                return self.stage.on_draw_side(self.stage.object_mask_at, key.t_us, key.angles)
            return super().object_mask(t_us)
        if key is None:
            return super().object_mask(t_us)
        layers = self.keyframe(key).layers
        return np.where(layers <= self.stage.scene.num_objects, layers, 0).astype(np.int32)
