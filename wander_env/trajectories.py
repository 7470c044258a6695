"""Trajectories of the moving objects: a 3D position (metres, world frame) at time t.

Five kinds, each a frozen params dataclass (validated on construction) plus a small
evaluator built by :func:`make_trajectory`: ``linear_bounce``
(:class:`LinearBounceParams`), ``circular`` (:class:`CircularParams`), ``random_walk``
(:class:`RandomWalkParams`), ``waypoints`` (:class:`WaypointsParams`) and ``scripted``
(:class:`ScriptedParams`, a Python callable). What each kind does and what its fields
mean is written on the fields (``field_doc``), from which ``docs/gen_scene_reference.py``
generates the scene reference page, ``docs/scenes.md``.

Every evaluator has ``position(t) -> np.ndarray`` of shape (3,), for any t >= 0 (the
closed-form ones for any t, in any order).

Examples:
    >>> traj = make_trajectory(CircularParams(centre=(1.0, 0.0, 1.0), radius=0.2))
    >>> traj.position(0.0).round(6).tolist()
    [1.0, 0.2, 1.0]
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Annotated, Literal, Protocol

import numpy as np
import pydantic

from wander_env.field_doc import field_doc

Vec3 = tuple[float, float, float]

TRAJECTORY_KINDS = ("linear_bounce", "circular", "random_walk", "waypoints", "scripted")
PLANES = ("xy", "xz", "yz")
_PLANE_AXES = {"xy": (0, 1), "xz": (0, 2), "yz": (1, 2)}


def _check_vec3(name: str, v: Vec3) -> None:
    if len(v) != 3 or not all(math.isfinite(float(c)) for c in v):
        raise ValueError(f"{name} must be 3 finite numbers, got {v!r}")


def _check_bounds(lo: Vec3, hi: Vec3) -> None:
    _check_vec3("bounds_min", lo)
    _check_vec3("bounds_max", hi)
    if any(a > b for a, b in zip(lo, hi, strict=True)):
        raise ValueError(f"bounds_min must be <= bounds_max on every axis, got {lo} and {hi}")


def _check_inside(name: str, p: Vec3, lo: Vec3, hi: Vec3) -> None:
    if any(not a <= c <= b for c, a, b in zip(p, lo, hi, strict=True)):
        raise ValueError(f"{name} {p} lies outside the bounds {lo}..{hi}")


# ----------------------------------------------------------------------------------------
# Params


@dataclass(frozen=True)
class LinearBounceParams:
    """Params of a ``linear_bounce`` trajectory (its fields say what it does)."""

    start: Annotated[
        Vec3, field_doc("Position at t = 0 (inside the bounds)", unit="m", example=[0.5, 0.2, 1.0])
    ]
    velocity: Annotated[
        Vec3,
        field_doc("Velocity (0 on an axis of zero extent)", unit="m/s", example=[0.0, -0.12, 0.05]),
    ]
    bounds_min: Annotated[
        Vec3,
        field_doc("Lower corner of the box it bounces in", unit="m", example=[0.5, -0.45, 0.92]),
    ]
    bounds_max: Annotated[
        Vec3,
        field_doc("Upper corner of the box it bounces in", unit="m", example=[0.5, 0.45, 1.12]),
    ]
    kind: Annotated[
        Literal["linear_bounce"],
        field_doc(
            "Constant velocity from start, reflecting off the faces of the box "
            "bounds_min..bounds_max (closed form)"
        ),
    ] = "linear_bounce"

    def __post_init__(self) -> None:
        _check_vec3("start", self.start)
        _check_vec3("velocity", self.velocity)
        _check_bounds(self.bounds_min, self.bounds_max)
        _check_inside("start", self.start, self.bounds_min, self.bounds_max)
        axes = zip(self.velocity, self.bounds_min, self.bounds_max, strict=True)
        for i, (v, lo, hi) in enumerate(axes):
            if hi == lo and v != 0:
                raise ValueError(f"velocity[{i}] must be 0 on an axis of zero extent, got {v}")


@dataclass(frozen=True)
class CircularParams:
    """Params of a ``circular`` trajectory (its fields say what it does)."""

    centre: Annotated[Vec3, field_doc("Centre of the circle", unit="m", example=[0.9, -0.2, 1.3])]
    radius: Annotated[float, field_doc("Radius (>= 0)", unit="m", example=0.22)]
    angular_speed_rad_s: Annotated[
        float, field_doc("Angular speed (negative: the other way round)", unit="rad/s")
    ] = 1.0
    plane: Annotated[
        Literal["xy", "xz", "yz"],
        field_doc(
            "Plane of the circle: position = centre + radius (cos θ e1 + sin θ e2), "
            "θ = phase + ω t, (e1, e2) the plane's axes in order (yz: e1 = y, e2 = z)"
        ),
    ] = "yz"
    phase_deg: Annotated[float, field_doc("Angle θ at t = 0", unit="deg")] = 0.0
    kind: Annotated[
        Literal["circular"], field_doc("A circle at constant angular speed (closed form)")
    ] = "circular"

    def __post_init__(self) -> None:
        _check_vec3("centre", self.centre)
        if not (math.isfinite(self.radius) and self.radius >= 0):
            raise ValueError(f"radius must be >= 0, got {self.radius!r}")
        if not math.isfinite(self.angular_speed_rad_s):
            raise ValueError(f"angular_speed_rad_s must be finite, got {self.angular_speed_rad_s}")
        if self.plane not in PLANES:
            raise ValueError(f"plane must be one of {PLANES}, got {self.plane!r}")


@dataclass(frozen=True)
class RandomWalkParams:
    """Params of a ``random_walk`` trajectory (its fields say what it does)."""

    bounds_min: Annotated[
        Vec3, field_doc("Lower corner of the box it walks in", unit="m", example=[0.6, -0.4, 0.8])
    ]
    bounds_max: Annotated[
        Vec3, field_doc("Upper corner of the box it walks in", unit="m", example=[1.2, 0.4, 1.3])
    ]
    speed_m_s: Annotated[float, field_doc("Constant speed (>= 0)", unit="m/s")] = 0.2
    turn_rate_rad_s: Annotated[
        float,
        field_doc(
            "How fast the heading diffuses: about the rms angle it turns in 1 s", unit="rad/s"
        ),
    ] = 2.0
    start: Annotated[
        Vec3 | None,
        field_doc(
            "Position at t = 0 (none: drawn uniformly inside the bounds)",
            unit="m",
            example=[0.9, 0.0, 1.0],
        ),
    ] = None
    dt_s: Annotated[
        float, field_doc("Step of the internal grid (linearly interpolated between)", unit="s")
    ] = 0.005
    kind: Annotated[
        Literal["random_walk"],
        field_doc(
            "A smooth random walk at constant speed whose heading diffuses, reflecting off "
            "the bounds (axes of zero extent frozen); integrated on a fixed grid from the "
            "env's random generator, so it is deterministic for a seed whatever the query "
            "times"
        ),
    ] = "random_walk"

    def __post_init__(self) -> None:
        _check_bounds(self.bounds_min, self.bounds_max)
        if self.start is not None:
            _check_vec3("start", self.start)
            _check_inside("start", self.start, self.bounds_min, self.bounds_max)
        if not (math.isfinite(self.speed_m_s) and self.speed_m_s >= 0):
            raise ValueError(f"speed_m_s must be >= 0, got {self.speed_m_s!r}")
        if not (math.isfinite(self.turn_rate_rad_s) and self.turn_rate_rad_s >= 0):
            raise ValueError(f"turn_rate_rad_s must be >= 0, got {self.turn_rate_rad_s!r}")
        if not (math.isfinite(self.dt_s) and self.dt_s > 0):
            raise ValueError(f"dt_s must be > 0, got {self.dt_s!r}")


@dataclass(frozen=True)
class WaypointsParams:
    """Params of a ``waypoints`` trajectory (its fields say what it does)."""

    points: Annotated[
        tuple[Vec3, ...],
        field_doc(
            "The waypoints (at least 2); it starts at the first",
            unit="m",
            example=[[0.25, 0.15, 1.0], [0.25, -0.15, 1.0]],
        ),
    ]
    speed_m_s: Annotated[float, field_doc("Constant speed (> 0)", unit="m/s")] = 0.2
    closed: Annotated[
        bool, field_doc("true: loop from the last point to the first; false: back and forth")
    ] = True
    kind: Annotated[
        Literal["waypoints"],
        field_doc("Piecewise linear through the points at constant speed, looping (closed form)"),
    ] = "waypoints"

    def __post_init__(self) -> None:
        if len(self.points) < 2:
            raise ValueError(f"points needs at least 2 waypoints, got {len(self.points)}")
        for i, p in enumerate(self.points):
            _check_vec3(f"points[{i}]", p)
        if not (math.isfinite(self.speed_m_s) and self.speed_m_s > 0):
            raise ValueError(f"speed_m_s must be > 0, got {self.speed_m_s!r}")


@dataclass(frozen=True)
class ScriptedParams:
    """Params of a ``scripted`` trajectory: a Python callable (its fields say more)."""

    position: Annotated[
        Callable[[float], Sequence[float]],
        pydantic.WithJsonSchema({"type": "string", "format": "python-callable"}),
        field_doc(
            "A Python callable t (s) -> (x, y, z) (m), called once at t = 0 to check it",
            example="lambda t: (1.0, 0.3 * math.sin(4 * t), 1.0)",
        ),
    ]
    kind: Annotated[
        Literal["scripted"],
        field_doc(
            "Python only (a SceneConfig built in code, not a scene file): the callable "
            "gives the position; it should be a pure function of t (the env asks for "
            "times in any order); a scene holding one is not serialisable into YAML or "
            "run.json unless the callable is"
        ),
    ] = "scripted"

    def __post_init__(self) -> None:
        if not callable(self.position):
            raise ValueError(f"position: must be a callable t -> (x, y, z), got {self.position!r}")
        try:
            scripted_position(self.position, 0.0)
        except ValueError as e:
            raise ValueError(f"position: at t = 0 s: {e}") from None
        except Exception as e:  # the user's code: any error is a bad value here
            raise ValueError(f"position: at t = 0 s: {type(e).__name__}: {e}") from None


TrajectoryParams = (
    LinearBounceParams | CircularParams | RandomWalkParams | WaypointsParams | ScriptedParams
)


# ----------------------------------------------------------------------------------------
# Pure maths


def fold(u: np.ndarray | float, lo: np.ndarray | float, hi: np.ndarray | float) -> np.ndarray:
    """Reflect coordinates ``u`` into [lo, hi] (a triangle wave; zero extent gives lo).

    >>> fold(np.array([1.5, -0.25, 2.5]), 0.0, 1.0).tolist()
    [0.5, 0.25, 0.5]
    """
    u, lo, hi = np.asarray(u, float), np.asarray(lo, float), np.asarray(hi, float)
    length = hi - lo
    safe = np.where(length > 0, length, 1.0)
    r = np.mod(u - lo, 2.0 * safe)
    r = np.where(r > safe, 2.0 * safe - r, r)
    return np.where(length > 0, lo + r, lo)


def bounce_position(
    start: np.ndarray, velocity: np.ndarray, lo: np.ndarray, hi: np.ndarray, t: float
) -> np.ndarray:
    """Position at time t of a point moving at ``velocity`` from ``start``, bouncing in [lo, hi]."""
    return fold(np.asarray(start, float) + np.asarray(velocity, float) * t, lo, hi)


def first_bounce_time(start: float, velocity: float, lo: float, hi: float) -> float:
    """Time (s) at which a 1-D bouncing point first reaches a wall (inf if it never moves)."""
    if velocity > 0:
        return (hi - start) / velocity
    if velocity < 0:
        return (lo - start) / velocity
    return math.inf


def circle_position(
    centre: np.ndarray, radius: float, theta: float, plane: str = "yz"
) -> np.ndarray:
    """Point at angle ``theta`` (rad) on a circle about ``centre`` in an axis plane."""
    a, b = _PLANE_AXES[plane]
    p = np.array(centre, dtype=float)
    p[a] += radius * math.cos(theta)
    p[b] += radius * math.sin(theta)
    return p


def polyline_position(points: np.ndarray, s: float) -> np.ndarray:
    """Point at arc length ``s`` along an open polyline (clamped to its ends)."""
    pts = np.asarray(points, float)
    seg = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    s = min(max(s, 0.0), cum[-1])
    i = int(np.searchsorted(cum, s, side="right")) - 1
    i = min(max(i, 0), len(seg) - 1)
    frac = 0.0 if seg[i] == 0 else (s - cum[i]) / seg[i]
    return pts[i] + frac * (pts[i + 1] - pts[i])


def waypoint_arrival_times(points: np.ndarray, speed: float) -> np.ndarray:
    """Times at which a constant-speed walk along ``points`` reaches each one (first = 0)."""
    seg = np.linalg.norm(np.diff(np.asarray(points, float), axis=0), axis=1)
    return np.concatenate([[0.0], np.cumsum(seg)]) / speed


def scripted_position(position: Callable[[float], Sequence[float]], t: float) -> np.ndarray:
    """``position(t)`` as a (3,) float array; ValueError unless it is 3 finite numbers."""
    p = np.asarray(position(t), dtype=float)
    if p.shape != (3,) or not np.isfinite(p).all():
        raise ValueError(f"expected 3 finite numbers (m), got {p.tolist()!r}")
    return p


# ----------------------------------------------------------------------------------------
# Evaluators


class Trajectory(Protocol):
    """Anything with ``position(t) -> (3,)`` in metres."""

    def position(self, t: float) -> np.ndarray: ...


class LinearBounce:
    """Evaluator of :class:`LinearBounceParams` (closed form)."""

    def __init__(self, params: LinearBounceParams) -> None:
        self.params = params
        self._args = tuple(
            np.asarray(v, float)
            for v in (params.start, params.velocity, params.bounds_min, params.bounds_max)
        )

    def position(self, t: float) -> np.ndarray:
        """Position at time t (s)."""
        return bounce_position(*self._args, t)

    def positions(self, times_s: np.ndarray) -> np.ndarray:
        """(T, 3) positions at each of ``times_s`` in one evaluation (the same numbers as
        :meth:`position` at each time: element-wise IEEE arithmetic)."""
        start, velocity, lo, hi = self._args
        return fold(start + velocity * np.asarray(times_s, float)[:, None], lo, hi)


class Circular:
    """Evaluator of :class:`CircularParams` (closed form)."""

    def __init__(self, params: CircularParams) -> None:
        self.params = params

    def position(self, t: float) -> np.ndarray:
        """Position at time t (s)."""
        p = self.params
        theta = math.radians(p.phase_deg) + p.angular_speed_rad_s * t
        return circle_position(np.asarray(p.centre, float), p.radius, theta, p.plane)


class Waypoints:
    """Evaluator of :class:`WaypointsParams` (closed form, periodic)."""

    def __init__(self, params: WaypointsParams) -> None:
        self.params = params
        pts = np.asarray(params.points, float)
        path = np.vstack([pts, pts[:1]]) if params.closed else np.vstack([pts, pts[-2::-1]])
        self._path = path
        self._length = float(np.linalg.norm(np.diff(path, axis=0), axis=1).sum())

    @property
    def period_s(self) -> float:
        """Time for one full loop (s)."""
        return self._length / self.params.speed_m_s

    def position(self, t: float) -> np.ndarray:
        """Position at time t (s)."""
        if self._length == 0:
            return self._path[0].copy()
        s = math.fmod(self.params.speed_m_s * t, self._length)
        return polyline_position(self._path, s + self._length if s < 0 else s)


class RandomWalk:
    """Evaluator of :class:`RandomWalkParams`; draws from ``rng`` lazily, in fixed chunks."""

    _CHUNK = 256

    def __init__(self, params: RandomWalkParams, rng: np.random.Generator) -> None:
        self.params = params
        self._rng = rng
        self._lo = np.asarray(params.bounds_min, float)
        self._hi = np.asarray(params.bounds_max, float)
        self._free = (self._hi > self._lo).astype(float)
        start = (
            np.asarray(params.start, float)
            if params.start is not None
            else self._lo + rng.random(3) * (self._hi - self._lo)
        )
        self._heading = self._normalise(rng.standard_normal(3))
        self._buf = np.empty((self._CHUNK + 1, 3))
        self._buf[0] = start
        self._n = 1

    def _normalise(self, d: np.ndarray) -> np.ndarray:
        d = d * self._free
        n = float(np.linalg.norm(d))
        return d / n if n > 0 else d

    def _extend(self) -> None:
        """Integrate one more chunk of the walk."""
        p = self.params
        noise = self._rng.standard_normal((self._CHUNK, 3))
        sigma = p.turn_rate_rad_s * math.sqrt(p.dt_s)
        if self._n + self._CHUNK > len(self._buf):
            self._buf = np.concatenate([self._buf, np.empty_like(self._buf)])
        pos = self._buf[self._n - 1].copy()
        out = self._buf[self._n : self._n + self._CHUNK]
        heading = self._heading
        for k in range(self._CHUNK):
            heading = self._normalise(heading + sigma * noise[k])
            pos = pos + p.speed_m_s * p.dt_s * heading
            # reflect the position and the heading off the bounds
            below, above = pos < self._lo, pos > self._hi
            pos = fold(pos, self._lo, self._hi)
            heading = np.where(below | above, -heading, heading)
            out[k] = pos
        self._heading = heading
        self._n += self._CHUNK

    def position(self, t: float) -> np.ndarray:
        """Position at time t >= 0 (s), linearly interpolated on the internal grid."""
        if t < 0:
            raise ValueError(f"random_walk is defined for t >= 0, got {t}")
        u = t / self.params.dt_s
        i = math.floor(u)
        while i + 1 >= self._n:
            self._extend()
        s = self._buf
        frac = u - i
        return s[i] + frac * (s[i + 1] - s[i])


class Scripted:
    """Evaluator of :class:`ScriptedParams`: the callable, its value checked."""

    def __init__(self, params: ScriptedParams) -> None:
        self.params = params

    def position(self, t: float) -> np.ndarray:
        """Position at time t (s); ValueError naming t when the callable's value is bad."""
        try:
            return scripted_position(self.params.position, t)
        except ValueError as e:
            raise ValueError(f"scripted trajectory at t = {t} s: {e}") from None


def positions_at(trajectory: Trajectory, times_s: np.ndarray) -> np.ndarray:
    """(T, 3) positions of ``trajectory`` at each of ``times_s``: in one evaluation where
    it has one (a linear bounce), else :meth:`~Trajectory.position` per time.

    >>> lb = LinearBounce(LinearBounceParams([0, 0, 0], [1, 0, 0], [0, 0, 0], [1, 0, 0]))
    >>> positions_at(lb, np.array([0.25, 1.5]))[:, 0].tolist()
    [0.25, 0.5]
    """
    if isinstance(trajectory, LinearBounce):
        return trajectory.positions(times_s)
    return np.stack([np.asarray(trajectory.position(float(t)), float) for t in times_s])


def make_trajectory(params: TrajectoryParams, rng: np.random.Generator | None = None) -> Trajectory:
    """The evaluator for ``params``; ``rng`` is required by (and only used by) random walks."""
    if isinstance(params, ScriptedParams):
        return Scripted(params)
    if isinstance(params, LinearBounceParams):
        return LinearBounce(params)
    if isinstance(params, CircularParams):
        return Circular(params)
    if isinstance(params, WaypointsParams):
        return Waypoints(params)
    if isinstance(params, RandomWalkParams):
        if rng is None:
            raise ValueError("a random_walk trajectory needs a numpy Generator (rng)")
        return RandomWalk(params, rng)
    raise TypeError(f"not trajectory params: {params!r}")
