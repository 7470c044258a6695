"""Scene configs: frozen, validated dataclasses loaded from ``assets/scenes/NAME.yaml``.

A :class:`SceneConfig` describes one world: the pan-tilt unit's mount and camera, the
lighting, an optional textured room, tables and shelves, static clutter, the moving
objects (each with a trajectory, see :mod:`wander_env.trajectories`) and, for the
``gratings`` scene, a :class:`GratingConfig`. :mod:`wander_env.mjcf` turns it into MJCF.

Conventions: metres, degrees, seconds; the world frame has z up, and the PTU looks along
+x at pan = tilt = 0 (+y is to its left, i.e. the image's left). Sizes are full extents
(not MuJoCo half-sizes): a box ``[sx, sy, sz]``, a sphere ``[diameter]``, a cylinder
``[diameter, height]`` (axis along z).

Errors: a bad value, a missing required key or an unknown key raises ``ValueError``
whose message starts with the field's path, e.g.
``moving_objects[1].trajectory.kind: must be one of (...), got 'zigzag'``.

Example:
    >>> cfg = load_scene_config("office")
    >>> cfg.name, len(cfg.moving_objects)
    ('office', 2)
"""

from __future__ import annotations

import importlib.resources
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal, TypeVar

import yaml

from wander_env.textures import TEXTURE_KINDS, TextureSpec
from wander_env.trajectories import (
    PLANES,
    TRAJECTORY_KINDS,
    CircularParams,
    LinearBounceParams,
    RandomWalkParams,
    TrajectoryParams,
    WaypointsParams,
)

Vec2 = tuple[float, float]
Vec3 = tuple[float, float, float]
RGBA = tuple[float, float, float, float]

SHAPES = ("box", "sphere", "cylinder")
SHAPE_SIZE_LEN = {"box": 3, "sphere": 1, "cylinder": 2}
GRATING_MODES = ("eye+object", "eye-only", "object-only")
# Speck: 5.12 mm sensor behind a 1.7 mm lens -> 2 atan(5.12 / 3.4) ≈ 112.83° horizontally
# (f = 1.7 mm / 40 µm pixels = 42.5 px).
SPECK_HFOV_DEG = math.degrees(2.0 * math.atan(5.12 / 3.4))
DEFAULT_SCENE = "office"

T = TypeVar("T")


# ----------------------------------------------------------------------------------------
# Dataclasses


@dataclass(frozen=True)
class _ShapedBody:
    """The shape and full-extent size (m) that a prop and a moving object both start with,
    checked together (a sphere has 1 extent, a cylinder 2, a box 3)."""

    shape: Literal["box", "sphere", "cylinder"]
    size: tuple[float, ...]

    def __post_init__(self) -> None:
        if self.shape not in SHAPES:
            raise ValueError(f"shape must be one of {SHAPES}, got {self.shape!r}")
        n = SHAPE_SIZE_LEN[self.shape]
        if len(self.size) != n or not all(math.isfinite(v) and v > 0 for v in self.size):
            raise ValueError(
                f"size of a {self.shape} must be {n} extents > 0 (m), got {tuple(self.size)}"
            )


@dataclass(frozen=True)
class CameraConfig:
    """The event camera: image size (px), horizontal field of view (deg), anti-aliasing.

    ``antialias_samples`` is MuJoCo's offscreen multisampling (``offsamples``): 4 gives
    edges graded coverage, so sub-pixel motion changes pixel values smoothly as on a real
    sensor; 0 renders about twice as fast on a CPU (llvmpipe).
    """

    width: int = 128
    height: int = 128
    hfov_deg: float = SPECK_HFOV_DEG
    antialias_samples: int = 4


@dataclass(frozen=True)
class PTUMountConfig:
    """Where the pan-tilt unit stands and where its camera sits.

    ``position`` is the tilt hinge in the world (the hinge lies on the pan axis); the
    camera's centre is ``camera_forward_m`` along the optical axis and ``camera_up_m``
    above it (at tilt 0) from the hinge, as in :class:`wander_env.ptu.PTUParams`.
    """

    position: Vec3 = (0.0, 0.0, 1.0)
    camera_forward_m: float = 0.0
    camera_up_m: float = 0.0


@dataclass(frozen=True)
class LightConfig:
    """A directional light shining along ``direction`` (``position`` only places it)."""

    position: Vec3 = (0.0, 0.0, 2.5)
    direction: Vec3 = (0.0, 0.0, -1.0)
    diffuse: float = 0.5


@dataclass(frozen=True)
class LightingConfig:
    """Headlight (follows the camera) intensities and extra lights (no shadows)."""

    headlight_ambient: float = 0.35
    headlight_diffuse: float = 0.35
    lights: tuple[LightConfig, ...] = ()


@dataclass(frozen=True)
class RoomConfig:
    """A closed box room ``size`` (x, y, z) m: floor at z = 0, walls and ceiling, textured.

    Set a texture's ``tile_m`` to fix how many metres one image spans on the surfaces.
    """

    size: Vec3 = (4.0, 4.0, 2.6)
    center_xy: Vec2 = (1.0, 0.0)
    wall_texture: TextureSpec = field(default_factory=lambda: TextureSpec(tile_m=1.0))
    floor_texture: TextureSpec = field(
        default_factory=lambda: TextureSpec(kind="checker", tile_m=1.0)
    )
    ceiling_texture: TextureSpec = field(default_factory=lambda: TextureSpec(kind="plain"))


@dataclass(frozen=True)
class TableConfig:
    """A table: top ``top_size`` (x, y) at ``height`` (top surface), four legs."""

    center_xy: Vec2 = (1.0, 0.0)
    top_size: Vec2 = (0.8, 1.4)
    height: float = 0.72
    thickness: float = 0.04
    leg_width: float = 0.05
    rgba: RGBA = (1.0, 1.0, 1.0, 1.0)
    texture: TextureSpec | None = None


@dataclass(frozen=True)
class ShelfConfig:
    """An open shelf facing -x (towards a PTU at the origin): sides, back and boards.

    ``levels`` are the heights (m, top surfaces) of the boards; ``yaw_deg`` turns it
    about z (0 = facing -x).
    """

    center_xy: Vec2 = (2.0, 0.0)
    width: float = 1.6
    depth: float = 0.35
    height: float = 1.8
    levels: tuple[float, ...] = (0.05, 0.5, 0.95, 1.4, 1.8)
    thickness: float = 0.03
    yaw_deg: float = 0.0
    rgba: RGBA = (1.0, 1.0, 1.0, 1.0)
    texture: TextureSpec | None = None


@dataclass(frozen=True)
class StaticObjectConfig(_ShapedBody):
    """A static prop: shape, full-extent size (m), centre, orientation (xyz Euler, deg)."""

    position: Vec3
    euler_deg: Vec3 = (0.0, 0.0, 0.0)
    rgba: RGBA = (0.7, 0.7, 0.7, 1.0)
    texture: TextureSpec | None = None
    name: str = ""


@dataclass(frozen=True)
class MovingObjectConfig(_ShapedBody):
    """A moving object (a mocap body): shape, full-extent size (m), look, trajectory.

    Object k (1-based, in list order) has id k in segmentation masks.
    """

    trajectory: TrajectoryParams
    rgba: RGBA = (1.0, 1.0, 1.0, 1.0)
    texture: TextureSpec | None = None
    name: str = ""


@dataclass(frozen=True)
class GratingConfig:
    """The sOMS characterisation stimulus (after Ölveczky et al. 2003; the paper's Fig.).

    A screen ``distance_m`` in front of the camera (at pan = tilt = 0) shows a grating of
    vertical bars; a square central patch ``object_size_deg`` wide shows the object
    grating. Spatial frequencies are in cycles per degree and speeds in degrees per
    second of visual angle at the screen centre, converted to metres linearly
    (``distance_m · π/180`` m per degree, as PsychoPy's ``deg`` units do). A positive
    speed drifts the bars to the right in the image. Temporal frequency =
    cycles_per_deg · speed_deg_s (Hz); the paper's speed s in cycles/frame at 60 fps is
    ``speed_deg_s = 60 s / cycles_per_deg``.

    Modes (which parts move; the camera itself moves only when the PTU does):

    - ``eye+object``: background drifts at ``background_speed_deg_s``, the patch's grating
      at ``object_speed_deg_s`` inside the fixed patch;
    - ``eye-only``: the whole screen drifts coherently at the background speed: the patch
      shows the background grating in phase with it (the patch is invisible; object
      settings are ignored), which is what a moving eye sees of a static screen;
    - ``object-only``: the background is static, the patch's grating drifts.
    """

    mode: Literal["eye+object", "eye-only", "object-only"] = "eye+object"
    distance_m: float = 1.0
    background_cycles_per_deg: float = 0.05
    background_speed_deg_s: float = 10.0
    object_size_deg: float = 40.0
    object_cycles_per_deg: float = 0.1
    object_speed_deg_s: float = 30.0
    profile: Literal["sine", "square"] = "square"
    contrast: float = 1.0
    mean: float = 0.5
    margin_deg: float = 20.0
    object_strips: int = 128

    def __post_init__(self) -> None:
        if self.mode not in GRATING_MODES:
            raise ValueError(f"mode must be one of {GRATING_MODES}, got {self.mode!r}")
        if self.profile not in ("sine", "square"):
            raise ValueError(f"profile must be one of ('sine', 'square'), got {self.profile!r}")
        for name in (
            "distance_m",
            "background_cycles_per_deg",
            "object_size_deg",
            "object_cycles_per_deg",
        ):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"{name} must be > 0, got {v!r}")
        for name in ("background_speed_deg_s", "object_speed_deg_s", "margin_deg"):
            if not math.isfinite(getattr(self, name)):
                raise ValueError(f"{name} must be finite, got {getattr(self, name)!r}")
        for name in ("contrast", "mean"):
            if not 0.0 <= getattr(self, name) <= 1.0:
                raise ValueError(f"{name} must be in [0, 1], got {getattr(self, name)!r}")
        if isinstance(self.object_strips, bool) or not isinstance(self.object_strips, int):
            raise ValueError(f"object_strips must be an int, got {self.object_strips!r}")
        if self.object_strips < 2:
            raise ValueError(f"object_strips must be >= 2, got {self.object_strips}")

    @property
    def metres_per_deg(self) -> float:
        """Screen metres per degree of visual angle at the centre (linear, PsychoPy-like)."""
        return self.distance_m * math.pi / 180.0

    def effective_speeds_deg_s(self) -> tuple[float, float]:
        """(background, object) drift speeds (deg/s) in this mode (object = bg in eye-only)."""
        if self.mode == "eye-only":
            return self.background_speed_deg_s, self.background_speed_deg_s
        if self.mode == "object-only":
            return 0.0, self.object_speed_deg_s
        return self.background_speed_deg_s, self.object_speed_deg_s


@dataclass(frozen=True)
class SceneConfig:
    """One scene: everything :func:`wander_env.mjcf.build_mjcf` needs."""

    name: str
    description: str = ""
    camera: CameraConfig = field(default_factory=CameraConfig)
    ptu: PTUMountConfig = field(default_factory=PTUMountConfig)
    lighting: LightingConfig = field(default_factory=LightingConfig)
    room: RoomConfig | None = None
    tables: tuple[TableConfig, ...] = ()
    shelves: tuple[ShelfConfig, ...] = ()
    static_objects: tuple[StaticObjectConfig, ...] = ()
    moving_objects: tuple[MovingObjectConfig, ...] = ()
    gratings: GratingConfig | None = None

    @property
    def num_objects(self) -> int:
        """Number of segmentable objects (ids 1..n): moving objects, or the grating patch."""
        return 1 if self.gratings is not None else len(self.moving_objects)


# ----------------------------------------------------------------------------------------
# Locating and loading


def assets_dir() -> Path:
    """The scene assets: ``wander_env/assets`` of an installed wheel (package data), else
    the checkout's top-level ``assets/`` (a source tree or an editable install)."""
    installed = Path(str(importlib.resources.files("wander_env").joinpath("assets")))
    source = Path(__file__).resolve().parents[1] / "assets"
    for path in (installed, source):
        if (path / "scenes").is_dir():
            return path
    raise FileNotFoundError(
        f"scene assets not found at {installed} (installed package) or {source} (checkout)"
    )


def available_scenes() -> tuple[str, ...]:
    """Names of the scenes in ``assets/scenes``."""
    return tuple(sorted(p.stem for p in (assets_dir() / "scenes").glob("*.yaml")))


def load_scene_config(path_or_name: str | Path = DEFAULT_SCENE) -> SceneConfig:
    """Load a scene by name (``assets/scenes/NAME.yaml``) or from a YAML file path."""
    text = str(path_or_name)
    is_path = isinstance(path_or_name, Path) or text.endswith((".yaml", ".yml")) or "/" in text
    if is_path:
        path = Path(path_or_name)
        if not path.is_file():
            raise FileNotFoundError(f"scene file not found: {path}")
    else:
        path = assets_dir() / "scenes" / f"{text}.yaml"
        if not path.is_file():
            raise ValueError(f"unknown scene {text!r}; available: {', '.join(available_scenes())}")
    with open(path, encoding="utf-8") as f:
        data = yaml.safe_load(f)
    try:
        return scene_config_from_dict(data, default_name=path.stem)
    except ValueError as e:
        raise ValueError(f"{path}: {e}") from None


# ----------------------------------------------------------------------------------------
# Parsing


_MISSING: Any = object()


class _Fields:
    """Reads typed values from one mapping, tracking its path and the keys read."""

    def __init__(self, data: Any, path: str) -> None:
        if not isinstance(data, Mapping):
            raise ValueError(f"{path or '<scene>'}: expected a mapping, got {data!r}")
        bad = [k for k in data if not isinstance(k, str)]
        if bad:
            raise ValueError(f"{path or '<scene>'}: keys must be strings, got {bad!r}")
        self.data = data
        self.path = path
        self.known: set[str] = set()

    def at(self, key: str) -> str:
        """The path of ``key``."""
        return f"{self.path}.{key}" if self.path else key

    def raw(self, key: str, default: Any = _MISSING) -> Any:
        """The value of ``key`` (``default`` when absent; required when no default)."""
        self.known.add(key)
        if key in self.data and self.data[key] is not None:
            return self.data[key]
        if key in self.data and default is None:
            return None
        if default is _MISSING:
            raise ValueError(f"{self.at(key)}: required")
        return default

    def number(
        self,
        key: str,
        default: Any = _MISSING,
        *,
        lo: float | None = None,
        hi: float | None = None,
        positive: bool = False,
    ) -> float:
        """A finite float, optionally in [lo, hi] or > 0."""
        return _number(self.raw(key, default), self.at(key), lo=lo, hi=hi, positive=positive)

    def integer(self, key: str, default: Any = _MISSING, *, lo: int | None = None) -> int:
        """An int (bools refused)."""
        v = self.raw(key, default)
        if isinstance(v, bool) or not isinstance(v, int):
            raise ValueError(f"{self.at(key)}: must be an integer, got {v!r}")
        if lo is not None and v < lo:
            raise ValueError(f"{self.at(key)}: must be >= {lo}, got {v}")
        return v

    def boolean(self, key: str, default: Any = _MISSING) -> bool:
        """A bool."""
        v = self.raw(key, default)
        if not isinstance(v, bool):
            raise ValueError(f"{self.at(key)}: must be true or false, got {v!r}")
        return v

    def string(self, key: str, default: Any = _MISSING) -> str:
        """A string."""
        v = self.raw(key, default)
        if not isinstance(v, str):
            raise ValueError(f"{self.at(key)}: must be a string, got {v!r}")
        return v

    def choice(self, key: str, allowed: Sequence[str], default: Any = _MISSING) -> str:
        """One of ``allowed``."""
        v = self.raw(key, default)
        if v not in allowed:
            raise ValueError(f"{self.at(key)}: must be one of {tuple(allowed)}, got {v!r}")
        return v

    def vector(
        self, key: str, n: int | None, default: Any = _MISSING, **bounds: Any
    ) -> tuple[float, ...]:
        """A list of ``n`` finite floats (any length >= 1 when n is None)."""
        return _vector(self.raw(key, default), self.at(key), n, **bounds)

    def sub(self, key: str, default: Any = _MISSING) -> _Fields | None:
        """The nested mapping at ``key`` (None when absent and ``default`` is None)."""
        v = self.raw(key, default)
        return None if v is None else _Fields(v, self.at(key))

    def items(self, key: str) -> list[tuple[str, Any]]:
        """(path, element) for each element of the list at ``key`` (empty when absent)."""
        v = self.raw(key, [])
        if not isinstance(v, list):
            raise ValueError(f"{self.at(key)}: must be a list, got {v!r}")
        return [(f"{self.at(key)}[{i}]", e) for i, e in enumerate(v)]

    def done(self) -> None:
        """Refuse keys that were never read."""
        unknown = sorted(set(self.data) - self.known)
        if unknown:
            raise ValueError(
                f"{self.path or '<scene>'}: unknown key(s) {unknown}; allowed: {sorted(self.known)}"
            )


def _number(
    v: Any,
    path: str,
    *,
    lo: float | None = None,
    hi: float | None = None,
    positive: bool = False,
) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise ValueError(f"{path}: must be a finite number, got {v!r}")
    if positive and v <= 0:
        raise ValueError(f"{path}: must be > 0, got {v!r}")
    if (lo is not None and v < lo) or (hi is not None and v > hi):
        raise ValueError(f"{path}: must be in [{lo}, {hi}], got {v!r}")
    return float(v)


def _vector(v: Any, path: str, n: int | None, **bounds: Any) -> tuple[float, ...]:
    if isinstance(v, (int, float)) and not isinstance(v, bool) and n in (1, None):
        v = [v]
    if not isinstance(v, (list, tuple)) or (n is not None and len(v) != n) or not v:
        want = f"a list of {n} numbers" if n is not None else "a non-empty list of numbers"
        raise ValueError(f"{path}: must be {want}, got {v!r}")
    return tuple(_number(c, f"{path}[{i}]", **bounds) for i, c in enumerate(v))


def _build(cls: Callable[..., T], path: str, **kwargs: Any) -> T:
    """``cls(**kwargs)``, its own ValueErrors prefixed with ``path``."""
    try:
        return cls(**kwargs)
    except ValueError as e:
        raise ValueError(f"{path}: {e}") from None


def _texture(f: _Fields, key: str) -> TextureSpec | None:
    t = f.sub(key, None)
    if t is None:
        return None
    colors = tuple(_vector(c, p, 3, lo=0.0, hi=1.0) for p, c in t.items("colors"))
    kw: dict[str, Any] = {
        "kind": t.choice("kind", TEXTURE_KINDS),
        "colors": colors,
        "scale": t.number("scale", 24.0, positive=True),
        "size_px": t.integer("size_px", 256, lo=8),
        "seed": t.integer("seed", 0, lo=0),
        "repeat": t.vector("repeat", 2, (1.0, 1.0), positive=True),
        "tile_m": t.number("tile_m", 0.0, lo=0.0),
    }
    t.done()
    return _build(TextureSpec, t.path, **kw)


def _size(f: _Fields, shape: str) -> tuple[float, ...]:
    n = SHAPE_SIZE_LEN[shape]
    return f.vector("size", n, positive=True)


def _trajectory(f: _Fields) -> TrajectoryParams:
    kind = f.choice("kind", TRAJECTORY_KINDS)
    params: TrajectoryParams
    if kind == "linear_bounce":
        kw = {
            "start": f.vector("start", 3),
            "velocity": f.vector("velocity", 3),
            "bounds_min": f.vector("bounds_min", 3),
            "bounds_max": f.vector("bounds_max", 3),
        }
        f.done()
        params = _build(LinearBounceParams, f.path, **kw)
    elif kind == "circular":
        kw = {
            "centre": f.vector("centre", 3),
            "radius": f.number("radius", lo=0.0),
            "angular_speed_rad_s": f.number("angular_speed_rad_s", 1.0),
            "plane": f.choice("plane", PLANES, "yz"),
            "phase_deg": f.number("phase_deg", 0.0),
        }
        f.done()
        params = _build(CircularParams, f.path, **kw)
    elif kind == "random_walk":
        start = f.raw("start", None)
        kw = {
            "bounds_min": f.vector("bounds_min", 3),
            "bounds_max": f.vector("bounds_max", 3),
            "speed_m_s": f.number("speed_m_s", 0.2, lo=0.0),
            "turn_rate_rad_s": f.number("turn_rate_rad_s", 2.0, lo=0.0),
            "start": None if start is None else _vector(start, f.at("start"), 3),
            "dt_s": f.number("dt_s", 0.005, positive=True),
        }
        f.done()
        params = _build(RandomWalkParams, f.path, **kw)
    else:
        points = tuple(_vector(p, path, 3) for path, p in f.items("points"))
        kw = {
            "points": points,
            "speed_m_s": f.number("speed_m_s", 0.2, positive=True),
            "closed": f.boolean("closed", True),
        }
        f.done()
        params = _build(WaypointsParams, f.path, **kw)
    return params


def _rgba(f: _Fields, default: RGBA) -> RGBA:
    return f.vector("rgba", 4, default, lo=0.0, hi=1.0)  # type: ignore[return-value]


def _static_object(f: _Fields) -> StaticObjectConfig:
    shape = f.choice("shape", SHAPES)
    obj = _build(
        StaticObjectConfig,
        f.path,
        shape=shape,  # type: ignore[arg-type]
        size=_size(f, shape),
        position=f.vector("position", 3),  # type: ignore[arg-type]
        euler_deg=f.vector("euler_deg", 3, (0.0, 0.0, 0.0)),  # type: ignore[arg-type]
        rgba=_rgba(f, (0.7, 0.7, 0.7, 1.0)),
        texture=_texture(f, "texture"),
        name=f.string("name", ""),
    )
    f.done()
    return obj


def _moving_object(f: _Fields) -> MovingObjectConfig:
    shape = f.choice("shape", SHAPES)
    traj = f.sub("trajectory")
    assert traj is not None
    obj = _build(
        MovingObjectConfig,
        f.path,
        shape=shape,  # type: ignore[arg-type]
        size=_size(f, shape),
        trajectory=_trajectory(traj),
        rgba=_rgba(f, (1.0, 1.0, 1.0, 1.0)),
        texture=_texture(f, "texture"),
        name=f.string("name", ""),
    )
    f.done()
    return obj


def _table(f: _Fields) -> TableConfig:
    d = TableConfig()
    obj = TableConfig(
        center_xy=f.vector("center_xy", 2, d.center_xy),  # type: ignore[arg-type]
        top_size=f.vector("top_size", 2, d.top_size, positive=True),  # type: ignore[arg-type]
        height=f.number("height", d.height, positive=True),
        thickness=f.number("thickness", d.thickness, positive=True),
        leg_width=f.number("leg_width", d.leg_width, positive=True),
        rgba=_rgba(f, d.rgba),
        texture=_texture(f, "texture"),
    )
    f.done()
    if obj.thickness >= obj.height:
        raise ValueError(f"{f.at('thickness')}: must be < height, got {obj.thickness}")
    return obj


def _shelf(f: _Fields) -> ShelfConfig:
    d = ShelfConfig()
    obj = ShelfConfig(
        center_xy=f.vector("center_xy", 2, d.center_xy),  # type: ignore[arg-type]
        width=f.number("width", d.width, positive=True),
        depth=f.number("depth", d.depth, positive=True),
        height=f.number("height", d.height, positive=True),
        levels=f.vector("levels", None, d.levels, lo=0.0),
        thickness=f.number("thickness", d.thickness, positive=True),
        yaw_deg=f.number("yaw_deg", d.yaw_deg),
        rgba=_rgba(f, d.rgba),
        texture=_texture(f, "texture"),
    )
    f.done()
    if max(obj.levels) > obj.height + 1e-9:
        raise ValueError(f"{f.at('levels')}: must be <= height {obj.height}, got {obj.levels}")
    return obj


def _room(f: _Fields) -> RoomConfig:
    d = RoomConfig()
    obj = RoomConfig(
        size=f.vector("size", 3, d.size, positive=True),  # type: ignore[arg-type]
        center_xy=f.vector("center_xy", 2, d.center_xy),  # type: ignore[arg-type]
        wall_texture=_texture(f, "wall_texture") or d.wall_texture,
        floor_texture=_texture(f, "floor_texture") or d.floor_texture,
        ceiling_texture=_texture(f, "ceiling_texture") or d.ceiling_texture,
    )
    f.done()
    return obj


def _lighting(f: _Fields) -> LightingConfig:
    d = LightingConfig()
    lights = []
    for path, data in f.items("lights"):
        g = _Fields(data, path)
        lights.append(
            LightConfig(
                position=g.vector("position", 3, LightConfig().position),  # type: ignore[arg-type]
                direction=g.vector("direction", 3, LightConfig().direction),  # type: ignore[arg-type]
                diffuse=g.number("diffuse", LightConfig().diffuse, lo=0.0, hi=1.0),
            )
        )
        g.done()
        if not any(lights[-1].direction):
            raise ValueError(f"{g.at('direction')}: must not be the zero vector")
    obj = LightingConfig(
        headlight_ambient=f.number("headlight_ambient", d.headlight_ambient, lo=0.0, hi=1.0),
        headlight_diffuse=f.number("headlight_diffuse", d.headlight_diffuse, lo=0.0, hi=1.0),
        lights=tuple(lights),
    )
    f.done()
    return obj


def _gratings(f: _Fields, hfov_deg: float) -> GratingConfig:
    d = GratingConfig()
    obj = _build(
        GratingConfig,
        f.path,
        mode=f.choice("mode", GRATING_MODES, d.mode),  # type: ignore[arg-type]
        distance_m=f.number("distance_m", d.distance_m, positive=True),
        background_cycles_per_deg=f.number(
            "background_cycles_per_deg", d.background_cycles_per_deg, positive=True
        ),
        background_speed_deg_s=f.number("background_speed_deg_s", d.background_speed_deg_s),
        object_size_deg=f.number("object_size_deg", d.object_size_deg, positive=True),
        object_cycles_per_deg=f.number(
            "object_cycles_per_deg", d.object_cycles_per_deg, positive=True
        ),
        object_speed_deg_s=f.number("object_speed_deg_s", d.object_speed_deg_s),
        profile=f.choice("profile", ("sine", "square"), d.profile),  # type: ignore[arg-type]
        contrast=f.number("contrast", d.contrast, lo=0.0, hi=1.0),
        mean=f.number("mean", d.mean, lo=0.0, hi=1.0),
        margin_deg=f.number("margin_deg", d.margin_deg, lo=0.0, hi=60.0),
        object_strips=f.integer("object_strips", d.object_strips, lo=2),
    )
    f.done()
    if obj.object_size_deg >= hfov_deg:
        raise ValueError(
            f"{f.at('object_size_deg')}: must be smaller than the field of view "
            f"({hfov_deg:.1f} deg), got {obj.object_size_deg}"
        )
    return obj


def scene_config_from_dict(data: Any, default_name: str = "scene") -> SceneConfig:
    """Validate a parsed YAML mapping into a :class:`SceneConfig` (ValueError naming the field)."""
    f = _Fields(data, "")
    cam = f.sub("camera", {})
    assert cam is not None
    camera = CameraConfig(
        width=cam.integer("width", 128, lo=1),
        height=cam.integer("height", 128, lo=1),
        hfov_deg=cam.number("hfov_deg", SPECK_HFOV_DEG, positive=True, hi=179.0),
        antialias_samples=cam.integer("antialias_samples", 4, lo=0),
    )
    cam.done()
    ptu = f.sub("ptu", {})
    assert ptu is not None
    mount = PTUMountConfig(
        position=ptu.vector("position", 3, PTUMountConfig().position),  # type: ignore[arg-type]
        camera_forward_m=ptu.number("camera_forward_m", 0.0),
        camera_up_m=ptu.number("camera_up_m", 0.0),
    )
    ptu.done()
    lighting = f.sub("lighting", {})
    assert lighting is not None
    room = f.sub("room", None)
    grat = f.sub("gratings", None)
    cfg = SceneConfig(
        name=f.string("name", default_name),
        description=f.string("description", ""),
        camera=camera,
        ptu=mount,
        lighting=_lighting(lighting),
        room=None if room is None else _room(room),
        tables=tuple(_table(_Fields(d, p)) for p, d in f.items("tables")),
        shelves=tuple(_shelf(_Fields(d, p)) for p, d in f.items("shelves")),
        static_objects=tuple(_static_object(_Fields(d, p)) for p, d in f.items("static_objects")),
        moving_objects=tuple(_moving_object(_Fields(d, p)) for p, d in f.items("moving_objects")),
        gratings=None if grat is None else _gratings(grat, camera.hfov_deg),
    )
    f.done()
    if cfg.gratings is not None and cfg.moving_objects:
        raise ValueError(
            "moving_objects: must be empty when gratings is set (the grating patch is object 1)"
        )
    return cfg
