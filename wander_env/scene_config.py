"""Scene configs: a :class:`SceneConfig` describes one world, frozen and validated.

It holds the pan-tilt unit's mount and the camera, the lighting, an optional textured
room, the parts (:mod:`wander_env.scene_parts`: tables and shelves, static clutter, the
moving objects, the bodies of existing MJCF files) and, for the ``gratings`` scene, a
:class:`GratingConfig`. :mod:`wander_env.mjcf` turns it into MJCF;
:func:`wander_env.scenes.load_scene_config` reads one from a name, a YAML file or a
mapping (a :class:`SceneConfig` built in code works too: ``gymnasium.make(
"wander/Wander-v0", scene=SceneConfig(...))``).

Every field carries its description, unit and example (``field_doc``):
``docs/gen_scene_reference.py`` writes the reference page ``docs/scenes.md`` from them.

Conventions: metres, degrees, seconds; the world frame has z up, and the PTU looks along
+x at pan = tilt = 0 (+y is to its left, i.e. the image's left).

Validation: :func:`wander_env.config.validate` (pydantic, strict, unknown keys
refused, numbers finite) reads a scene document into these dataclasses; single-field
bounds are ``Annotated`` constraints on the fields, cross-field rules are
``__post_init__`` checks, and a trajectory is a union tagged by its ``kind``. A bad value,
a missing required key or an unknown key raises :class:`wander_env.config.ConfigError` (a
``ValueError``) whose message starts with the field's path, e.g.
``moving_objects[1].trajectory.kind: expected one of 'circular', ..., got 'zigzag'``.
:meth:`SceneConfig.files_read` lists the mesh and MJCF files read, with their SHA-256.

Size limits (what the work holds, checked at validation; the lists' lengths before the
rest, so that a million objects cost no more than the file): camera sides
<= :data:`MAX_CAMERA_SIDE` px and at most :data:`MAX_CAMERA_PIXELS` pixels; at most
:data:`MAX_PARTS` tables, shelves, static or moving objects or includes and
:data:`MAX_LIGHTS` lights; at most :data:`MAX_MATERIALS` materials and
:data:`MAX_TEXTURES` textures in all (MuJoCo's renderer's limits); at most
:data:`MAX_GRATING_STRIPS` strips in the gratings patch.

Examples:
    >>> cfg = SceneConfig(name="empty", camera=CameraConfig(width=64))
    >>> cfg.camera.width, cfg.num_objects, cfg.own_materials()
    (64, 0, 1)
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Annotated, Literal, TypeVar

import pydantic

from wander_env.camera import SPECK_HFOV_DEG, check_hfov_deg
from wander_env.config import check_annotated
from wander_env.field_doc import field_doc
from wander_env.scene_parts import (
    MJCFIncludeConfig,
    MovingObjectConfig,
    Positive,
    ShelfConfig,
    StaticObjectConfig,
    TableConfig,
    Unit,
    Vec2,
    Vec3,
    include_name,
)
from wander_env.textures import TextureSpec
from wander_env.untrusted import FileRecord

# Scene size limits (validated): the work holds these.
MAX_CAMERA_SIDE = 4096  # px, each side (within llvmpipe's 16384 offscreen limit)
MAX_CAMERA_PIXELS = 2048 * 2048  # the env takes ~0.3 kB a pixel: 2048^2 is ~1.7 GB
MAX_MATERIALS = 1000  # MuJoCo's renderer refuses a model with more (mjMAXMATERIAL)
MAX_TEXTURES = 1000  # likewise (mjMAXTEXTURE)
MAX_PARTS = MAX_MATERIALS  # each table, shelf and prop takes one material
MAX_LIGHTS = 100  # mjMAXLIGHT
MAX_GRATING_STRIPS = MAX_CAMERA_SIDE  # the gratings patch's strips: narrower than a pixel
GRATING_MODES = ("eye+object", "eye-only", "object-only")
Finite = Annotated[float, pydantic.Field(allow_inf_nan=False)]
T = TypeVar("T")


@dataclass(frozen=True)
class CameraConfig:
    """The event camera: image size (px), horizontal field of view (deg), anti-aliasing.

    ``antialias_samples`` is MuJoCo's offscreen multisampling (``offsamples``): 4 gives
    edges graded coverage, so sub-pixel motion changes pixel values smoothly as on a real
    sensor; 0 renders about twice as fast on a CPU (llvmpipe).
    """

    width: Annotated[
        int,
        field_doc(
            "Image width; width x height at most 2048 x 2048 pixels",
            unit="px",
            ge=1,
            le=MAX_CAMERA_SIDE,
        ),
    ] = 128
    height: Annotated[int, field_doc("Image height", unit="px", ge=1, le=MAX_CAMERA_SIDE)] = 128
    hfov_deg: Annotated[
        float,
        field_doc("Horizontal field of view, in (0, 180) (the Speck's by default)", unit="deg"),
    ] = SPECK_HFOV_DEG
    antialias_samples: Annotated[
        int,
        field_doc(
            "MuJoCo's offscreen multisampling: 4 grades edge coverage, so sub-pixel motion "
            "changes pixels smoothly; 0 renders about twice as fast on a CPU",
            unit="samples",
            ge=0,
            le=16,
        ),
    ] = 4

    def __post_init__(self) -> None:
        check_annotated(self)
        check_hfov_deg(self.hfov_deg)
        if self.width * self.height > MAX_CAMERA_PIXELS:
            raise ValueError(
                f"width: width x height must be <= {MAX_CAMERA_PIXELS} pixels (2048 x 2048; "
                f"the env takes ~0.3 kB a pixel), got {self.width} x {self.height}"
            )


@dataclass(frozen=True)
class PTUMountConfig:
    """Where the pan-tilt unit stands: its tilt hinge in the world (on the pan axis).
    Where the camera sits on the hinge is the unit's own, not the scene's: the env's
    ``ptu`` block (``env.ptu.camera_forward_m``, ``env.ptu.camera_up_m``: see
    :class:`wander_env.ptu.params.PTUParams`).
    """

    position: Annotated[
        Vec3, field_doc("The tilt hinge in the world (on the pan axis)", unit="m")
    ] = (
        0.0,
        0.0,
        1.0,
    )


@dataclass(frozen=True)
class LightConfig:
    """A directional light shining along ``direction`` (``position`` only places it)."""

    position: Annotated[
        Vec3,
        field_doc("Where the light is (a directional light shines alike everywhere)", unit="m"),
    ] = (0.0, 0.0, 2.5)
    direction: Annotated[
        Vec3, field_doc("Direction it shines along (not the zero vector)", unit="vector")
    ] = (0.0, 0.0, -1.0)
    diffuse: Annotated[Unit, field_doc("Diffuse intensity (grey)")] = 0.5

    def __post_init__(self) -> None:
        if not any(self.direction):
            raise ValueError(f"direction: must not be the zero vector, got {self.direction}")


@dataclass(frozen=True)
class LightingConfig:
    """Headlight (follows the camera) intensities and extra lights (no shadows)."""

    headlight_ambient: Annotated[
        Unit, field_doc("Ambient intensity of the headlight (it follows the camera)")
    ] = 0.35
    headlight_diffuse: Annotated[Unit, field_doc("Diffuse intensity of the headlight")] = 0.35
    lights: Annotated[
        tuple[LightConfig, ...],
        field_doc("Directional lights (no shadows), MuJoCo's 100 at most", max_length=MAX_LIGHTS),
    ] = ()


@dataclass(frozen=True)
class RoomConfig:
    """A closed box room ``size`` (x, y, z) m: floor at z = 0, walls and ceiling, textured.

    Set a texture's ``tile_m`` to fix how many metres one image spans on the surfaces.
    """

    size: Annotated[
        tuple[Positive, Positive, Positive],
        field_doc("Full extents (x, y, z): the floor at z = 0, the ceiling at z", unit="m"),
    ] = (4.0, 4.0, 2.6)
    center_xy: Annotated[Vec2, field_doc("Centre of the floor (x, y)", unit="m")] = (1.0, 0.0)
    wall_texture: Annotated[TextureSpec, field_doc("Texture of the four walls")] = field(
        default_factory=lambda: TextureSpec(tile_m=1.0)
    )
    floor_texture: Annotated[TextureSpec, field_doc("Texture of the floor")] = field(
        default_factory=lambda: TextureSpec(kind="checker", tile_m=1.0)
    )
    ceiling_texture: Annotated[TextureSpec, field_doc("Texture of the ceiling")] = field(
        default_factory=lambda: TextureSpec(kind="plain")
    )


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

    mode: Annotated[
        Literal["eye+object", "eye-only", "object-only"],
        field_doc(
            "Which parts move: eye+object (the background and the patch's grating drift at "
            "their speeds), eye-only (the whole screen drifts at the background speed), "
            "object-only (only the patch's grating drifts)"
        ),
    ] = "eye+object"
    distance_m: Annotated[Positive, field_doc("Screen distance ahead of the camera", unit="m")] = (
        1.0
    )
    background_cycles_per_deg: Annotated[
        Positive, field_doc("Background spatial frequency", unit="cycles/deg")
    ] = 0.05
    background_speed_deg_s: Annotated[
        Finite, field_doc("Background drift (positive: bars move right in the image)", unit="deg/s")
    ] = 10.0
    object_size_deg: Annotated[
        Positive, field_doc("Side of the square central patch (< the field of view)", unit="deg")
    ] = 40.0
    object_cycles_per_deg: Annotated[
        Positive, field_doc("Patch grating's spatial frequency", unit="cycles/deg")
    ] = 0.1
    object_speed_deg_s: Annotated[
        Finite, field_doc("Patch grating's drift (positive: to the right)", unit="deg/s")
    ] = 30.0
    profile: Annotated[Literal["sine", "square"], field_doc("Bar profile")] = "square"
    contrast: Annotated[Unit, field_doc("Contrast of the bars about the mean")] = 1.0
    mean: Annotated[Unit, field_doc("Mean intensity")] = 0.5
    margin_deg: Annotated[
        float, field_doc("Screen beyond the field of view on each side", unit="deg", ge=0, le=60)
    ] = 20.0
    object_strips: Annotated[
        int,
        field_doc(
            "Vertical strips the patch is drawn with (each narrower than a pixel); at most "
            f"{MAX_GRATING_STRIPS}, the widest camera's pixels (the patch is narrower than the "
            "view): each strip is a geom drawn every frame",
            ge=2,
            le=MAX_GRATING_STRIPS,
        ),
    ] = 128

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


Parts = Annotated[tuple[T, ...], pydantic.Field(max_length=MAX_PARTS)]


@dataclass(frozen=True)
class SceneConfig:
    """One scene: everything :func:`wander_env.mjcf.build_mjcf` needs."""

    name: Annotated[str, field_doc("The scene's name (default: the file's name)", example="office")]
    description: Annotated[str, field_doc("One line about the scene")] = ""
    camera: Annotated[CameraConfig, field_doc("The event camera")] = field(
        default_factory=CameraConfig
    )
    ptu: Annotated[PTUMountConfig, field_doc("The pan-tilt unit's mount")] = field(
        default_factory=PTUMountConfig
    )
    lighting: Annotated[LightingConfig, field_doc("Headlight and lights")] = field(
        default_factory=LightingConfig
    )
    room: Annotated[
        RoomConfig | None, field_doc("A closed, textured room (none: black beyond the parts)")
    ] = None
    tables: Annotated[Parts[TableConfig], field_doc("Tables")] = ()
    shelves: Annotated[Parts[ShelfConfig], field_doc("Open shelves")] = ()
    static_objects: Annotated[
        Parts[StaticObjectConfig], field_doc("Static props: boxes, spheres, cylinders, meshes")
    ] = ()
    moving_objects: Annotated[
        Parts[MovingObjectConfig],
        field_doc(
            "Props on trajectories; object k (from 1, in list order) has id k in the "
            "segmentation masks"
        ),
    ] = ()
    mjcf_includes: Annotated[
        Parts[MJCFIncludeConfig],
        field_doc("MJCF files whose worldbody bodies are attached as static parts"),
    ] = ()
    gratings: Annotated[
        GratingConfig | None,
        field_doc("The sOMS characterisation stimulus (then no moving_objects)"),
    ] = None

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
        prefixes = [include_name(i, inc) for i, inc in enumerate(self.mjcf_includes)]
        statics = [o.name or f"static_{i}" for i, o in enumerate(self.static_objects)]
        movers = [o.name for o in self.moving_objects if o.name]
        for key, names in (
            ("name", [self.name]),
            ("mjcf_includes", prefixes),
            ("static_objects", statics),
            ("moving_objects", movers),
        ):
            odd = next((n for n in names if any(c < " " or c == "\x7f" for c in n)), None)
            if odd is not None:
                raise ValueError(f"{key}: a name must not hold control characters, got {odd!r}")
            twice = sorted({n for n in names if names.count(n) > 1})
            if twice:
                raise ValueError(f"{key}: names must differ, got {', '.join(twice)} twice")
        included = [inc.counts() for inc in self.mjcf_includes]
        materials = self.own_materials() + sum(m for m, _ in included)
        if materials > MAX_MATERIALS:
            raise ValueError(
                f"static_objects: the scene needs {materials} materials, MuJoCo renders at most "
                f"{MAX_MATERIALS} (one a table, shelf and object, 6 for a room, 1 for the "
                "pan-tilt unit, 2 for gratings, and the mjcf_includes' own): use fewer parts"
            )
        textures = self.own_textures() + sum(t for _, t in included)
        if textures > MAX_TEXTURES:
            raise ValueError(
                f"static_objects: the scene needs {textures} textures, MuJoCo renders at most "
                f"{MAX_TEXTURES} (one a textured part, 6 for a room, 1 for gratings, and the "
                "mjcf_includes' own): use fewer textured parts"
            )

    def own_materials(self) -> int:
        """Materials the scene's own parts make (without the mjcf_includes')."""
        parts = (self.tables, self.shelves, self.static_objects, self.moving_objects)
        room = 6 if self.room is not None else 0
        return room + sum(len(p) for p in parts) + 1 + (2 if self.gratings is not None else 0)

    def own_textures(self) -> int:
        """Textures the scene's own parts make (without the mjcf_includes')."""
        parts = (*self.tables, *self.shelves, *self.static_objects, *self.moving_objects)
        room = 6 if self.room is not None else 0
        textured = sum(p.texture is not None for p in parts)
        return room + textured + (1 if self.gratings is not None else 0)

    def files_read(self) -> tuple[FileRecord, ...]:
        """The files the scene's meshes and MJCF includes read when it was made (each
        with its SHA-256), in config order."""
        meshes = [
            p.mesh.files_read()
            for p in (*self.static_objects, *self.moving_objects)
            if p.mesh is not None
        ]
        includes = [inc.files_read() for inc in self.mjcf_includes]
        return tuple(r for group in (*meshes, *includes) for r in group)

    @property
    def num_objects(self) -> int:
        """Number of segmentable objects (ids 1..n): moving objects, or the grating patch."""
        return 1 if self.gratings is not None else len(self.moving_objects)
