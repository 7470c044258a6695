"""Scene configs: frozen, validated dataclasses loaded from ``assets/scenes/NAME.yaml``.

A :class:`SceneConfig` describes one world: the pan-tilt unit's mount and camera, the
lighting, an optional textured room, tables and shelves, static clutter, the moving
objects (each with a trajectory, see :mod:`wander_env.trajectories`) and, for the
``gratings`` scene, a :class:`GratingConfig`. :mod:`wander_env.mjcf` turns it into MJCF.

Conventions: metres, degrees, seconds; the world frame has z up, and the PTU looks along
+x at pan = tilt = 0 (+y is to its left, i.e. the image's left). Sizes are full extents
(not MuJoCo half-sizes): a box ``[sx, sy, sz]``, a sphere ``[diameter]``, a cylinder
``[diameter, height]`` (axis along z).

Validation: :func:`wander_env.config.validate_paths` (pydantic, strict, unknown keys
refused, numbers finite) reads a scene file into these dataclasses; single-field bounds
are ``Annotated`` constraints on the fields, cross-field rules are ``__post_init__``
checks, and a trajectory is a union tagged by its ``kind``. A bad value, a missing
required key or an unknown key raises :class:`wander_env.config.ConfigError` (a
``ValueError``) whose message starts with the field's path, e.g.
``moving_objects[1].trajectory.kind: expected one of 'circular', ..., got 'zigzag'``.

Example:
    >>> cfg = load_scene_config("office")
    >>> cfg.name, len(cfg.moving_objects)
    ('office', 2)
"""

from __future__ import annotations

import importlib.resources
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated, Any, Literal

import pydantic

from wander_env.camera import SPECK_HFOV_DEG
from wander_env.config import check_annotated, load_yaml, validate_paths
from wander_env.textures import TextureSpec
from wander_env.trajectories import TrajectoryParams

Finite = Annotated[float, pydantic.Field(allow_inf_nan=False)]
Positive = Annotated[float, pydantic.Field(gt=0)]
NonNegative = Annotated[float, pydantic.Field(ge=0)]
Unit = Annotated[float, pydantic.Field(ge=0, le=1)]
Vec2 = tuple[float, float]
Vec3 = tuple[float, float, float]
RGBA = tuple[Unit, Unit, Unit, Unit]

SHAPES = ("box", "sphere", "cylinder")
SHAPE_SIZE_LEN = {"box": 3, "sphere": 1, "cylinder": 2}
GRATING_MODES = ("eye+object", "eye-only", "object-only")
DEFAULT_SCENE = "office"


# ----------------------------------------------------------------------------------------
# Dataclasses


def _check_shape(shape: str, size: Sequence[float]) -> None:
    if shape not in SHAPES:
        raise ValueError(f"shape must be one of {SHAPES}, got {shape!r}")
    n = SHAPE_SIZE_LEN[shape]
    if len(size) != n or not all(math.isfinite(v) and v > 0 for v in size):
        raise ValueError(f"size of a {shape} must be {n} extents > 0 (m), got {tuple(size)}")


class _Body:
    """Base of the prop configs: their ``shape`` and full-extent ``size`` (m), checked
    together on construction."""

    shape: str
    size: tuple[float, ...]

    def __post_init__(self) -> None:
        _check_shape(self.shape, self.size)


@dataclass(frozen=True)
class CameraConfig:
    """The event camera: image size (px), horizontal field of view (deg), anti-aliasing.

    ``antialias_samples`` is MuJoCo's offscreen multisampling (``offsamples``): 4 gives
    edges graded coverage, so sub-pixel motion changes pixel values smoothly as on a real
    sensor; 0 renders about twice as fast on a CPU (llvmpipe).
    """

    width: Annotated[int, pydantic.Field(ge=1)] = 128
    height: Annotated[int, pydantic.Field(ge=1)] = 128
    hfov_deg: Annotated[float, pydantic.Field(gt=0, le=179)] = SPECK_HFOV_DEG
    antialias_samples: Annotated[int, pydantic.Field(ge=0)] = 4


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
    diffuse: Unit = 0.5

    def __post_init__(self) -> None:
        if not any(self.direction):
            raise ValueError(f"direction: must not be the zero vector, got {self.direction}")


@dataclass(frozen=True)
class LightingConfig:
    """Headlight (follows the camera) intensities and extra lights (no shadows)."""

    headlight_ambient: Unit = 0.35
    headlight_diffuse: Unit = 0.35
    lights: tuple[LightConfig, ...] = ()


@dataclass(frozen=True)
class RoomConfig:
    """A closed box room ``size`` (x, y, z) m: floor at z = 0, walls and ceiling, textured.

    Set a texture's ``tile_m`` to fix how many metres one image spans on the surfaces.
    """

    size: tuple[Positive, Positive, Positive] = (4.0, 4.0, 2.6)
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
    top_size: tuple[Positive, Positive] = (0.8, 1.4)
    height: Positive = 0.72
    thickness: Positive = 0.04
    leg_width: Positive = 0.05
    rgba: RGBA = (1.0, 1.0, 1.0, 1.0)
    texture: TextureSpec | None = None

    def __post_init__(self) -> None:
        if self.thickness >= self.height:
            raise ValueError(f"thickness: must be < height ({self.height}), got {self.thickness}")


@dataclass(frozen=True)
class ShelfConfig:
    """An open shelf facing -x (towards a PTU at the origin): sides, back and boards.

    ``levels`` are the heights (m, top surfaces) of the boards; ``yaw_deg`` turns it
    about z (0 = facing -x).
    """

    center_xy: Vec2 = (2.0, 0.0)
    width: Positive = 1.6
    depth: Positive = 0.35
    height: Positive = 1.8
    levels: Annotated[tuple[NonNegative, ...], pydantic.Field(min_length=1)] = (
        0.05,
        0.5,
        0.95,
        1.4,
        1.8,
    )
    thickness: Positive = 0.03
    yaw_deg: float = 0.0
    rgba: RGBA = (1.0, 1.0, 1.0, 1.0)
    texture: TextureSpec | None = None

    def __post_init__(self) -> None:
        if self.levels and max(self.levels) > self.height + 1e-9:
            raise ValueError(f"levels: must be <= height ({self.height}), got {self.levels}")


@dataclass(frozen=True)
class StaticObjectConfig(_Body):
    """A static prop: shape, full-extent size (m), centre, orientation (xyz Euler, deg)."""

    shape: Literal["box", "sphere", "cylinder"]
    size: Annotated[tuple[Positive, ...], pydantic.Field(min_length=1)]
    position: Vec3
    euler_deg: Vec3 = (0.0, 0.0, 0.0)
    rgba: RGBA = (0.7, 0.7, 0.7, 1.0)
    texture: TextureSpec | None = None
    name: str = ""


@dataclass(frozen=True)
class MovingObjectConfig(_Body):
    """A moving object (a mocap body): shape, full-extent size (m), look, trajectory.

    Object k (1-based, in list order) has id k in segmentation masks.
    """

    shape: Literal["box", "sphere", "cylinder"]
    size: Annotated[tuple[Positive, ...], pydantic.Field(min_length=1)]
    trajectory: Annotated[TrajectoryParams, pydantic.Field(discriminator="kind")]
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
    distance_m: Positive = 1.0
    background_cycles_per_deg: Positive = 0.05
    background_speed_deg_s: Finite = 10.0
    object_size_deg: Positive = 40.0
    object_cycles_per_deg: Positive = 0.1
    object_speed_deg_s: Finite = 30.0
    profile: Literal["sine", "square"] = "square"
    contrast: Unit = 1.0
    mean: Unit = 0.5
    margin_deg: Annotated[float, pydantic.Field(ge=0, le=60)] = 20.0
    object_strips: Annotated[int, pydantic.Field(ge=2)] = 128

    def __post_init__(self) -> None:
        check_annotated(self)

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

    def __post_init__(self) -> None:
        if self.gratings is not None and self.moving_objects:
            raise ValueError(
                "moving_objects: must be empty when gratings is set (the grating patch is object 1)"
            )
        if self.gratings is not None and self.gratings.object_size_deg >= self.camera.hfov_deg:
            raise ValueError(
                "gratings.object_size_deg: must be smaller than the field of view "
                f"({self.camera.hfov_deg:.1f} deg), got {self.gratings.object_size_deg}"
            )

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
    data = load_yaml(path, "scene file")
    return scene_config_from_dict(data, default_name=path.stem, where=str(path))


# ----------------------------------------------------------------------------------------
# Parsing


def scene_config_from_dict(
    data: Any, default_name: str = "scene", where: str | None = None
) -> SceneConfig:
    """Validate a parsed YAML mapping into a :class:`SceneConfig` (``name`` defaults to
    ``default_name``); ConfigError (a ValueError) starting with ``where: `` (the file)
    when given, then the field's path.

    >>> scene_config_from_dict({"camera": {"width": 64}}).camera.width
    64
    >>> bad = {"moving_objects": [{"shape": "box", "size": [1, 1, 1], "trajectory": {}}]}
    >>> try:
    ...     scene_config_from_dict(bad, where="my.yaml")
    ... except ValueError as e:
    ...     print(e)  # doctest: +NORMALIZE_WHITESPACE
    my.yaml: moving_objects[0].trajectory.kind: required
    (one of 'linear_bounce', 'circular', 'random_walk', 'waypoints')
    """
    if isinstance(data, Mapping) and "name" not in data:
        data = {"name": default_name, **data}
    return validate_paths(SceneConfig, data, where=where)
