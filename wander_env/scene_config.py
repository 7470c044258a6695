"""Scene configs: frozen, validated dataclasses loaded from ``assets/scenes/NAME.yaml``.

A :class:`SceneConfig` describes one world: the pan-tilt unit's mount and camera, the
lighting, an optional textured room, tables and shelves, static clutter, the moving
objects (each with a trajectory, see :mod:`wander_env.trajectories`), the bodies of
existing MJCF files (:class:`MJCFIncludeConfig`) and, for the ``gratings`` scene, a
:class:`GratingConfig`. A static or moving prop is a box, sphere, cylinder or a mesh
(:class:`MeshConfig`: an OBJ or STL file that MuJoCo reads, with a scale).
:mod:`wander_env.mjcf` turns it into MJCF. :func:`load_scene_config` takes a name, a
YAML file, a parsed mapping or a :class:`SceneConfig` (so ``gymnasium.make(
"wander/Wander-v0", scene=SceneConfig(...))`` works).

Every field carries its description, unit and example (``field_doc``):
``docs/gen_scene_reference.py`` writes the reference page ``docs/scenes.md`` from them.

Conventions: metres, degrees, seconds; the world frame has z up, and the PTU looks along
+x at pan = tilt = 0 (+y is to its left, i.e. the image's left). Sizes are full extents
(not MuJoCo half-sizes): a box ``[sx, sy, sz]``, a sphere ``[diameter]``, a cylinder
``[diameter, height]`` (axis along z).

Validation: :func:`wander_env.config.validate` (pydantic, strict, unknown keys
refused, numbers finite) reads a scene file into these dataclasses; single-field bounds
are ``Annotated`` constraints on the fields, cross-field rules are ``__post_init__``
checks, and a trajectory is a union tagged by its ``kind``. A bad value, a missing
required key or an unknown key raises :class:`wander_env.config.ConfigError` (a
``ValueError``) whose message starts with the field's path, e.g.
``moving_objects[1].trajectory.kind: expected one of 'circular', ..., got 'zigzag'``.
Mesh and MJCF files are read once, when validated, through :mod:`wander_env.untrusted`
(regular files within :data:`wander_env.untrusted.LIMITS`, an MJCF file with every file it
names, checked before MuJoCo compiles them from memory); relative paths in a YAML file are
relative to its folder. :meth:`SceneConfig.files_read` lists them with their SHA-256.

Size limits (what the work holds, checked at validation; the lists' lengths before the
rest, so that a million objects cost no more than the file): camera sides
<= :data:`MAX_CAMERA_SIDE` px and at most :data:`MAX_CAMERA_PIXELS` pixels; at most
:data:`MAX_PARTS` tables, shelves, static or moving objects or includes and
:data:`MAX_LIGHTS` lights; at most :data:`MAX_MATERIALS` materials and
:data:`MAX_TEXTURES` textures in all (MuJoCo's renderer's limits).

Examples:
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
from typing import Annotated, Any, ClassVar, Literal, TypeVar

import mujoco
import numpy as np
import pydantic

from wander_env.camera import SPECK_HFOV_DEG
from wander_env.config import MAX_YAML_BYTES, ConfigError, check_annotated, parse_yaml, validate
from wander_env.config_messages import shown
from wander_env.field_doc import field_doc
from wander_env.textures import TextureSpec
from wander_env.trajectories import TrajectoryParams
from wander_env.untrusted import (
    LIMITS,
    FileRecord,
    MJCFFiles,
    ReadLog,
    UntrustedFileError,
    check_model_size,
    load_mjcf,
    read_bytes,
)

Finite = Annotated[float, pydantic.Field(allow_inf_nan=False)]
Positive = Annotated[float, pydantic.Field(gt=0)]
NonNegative = Annotated[float, pydantic.Field(ge=0)]
Unit = Annotated[float, pydantic.Field(ge=0, le=1)]
Vec2 = tuple[float, float]
Vec3 = tuple[float, float, float]
RGBA = tuple[Unit, Unit, Unit, Unit]
#: The parts' default colour: white, which leaves a texture's own colours as they are.
WHITE: RGBA = (1.0, 1.0, 1.0, 1.0)

SHAPES = ("box", "sphere", "cylinder", "mesh")
SHAPE_SIZE_LEN = {"box": 3, "sphere": 1, "cylinder": 2}
MESH_SUFFIXES = (".obj", ".stl")
# Scene size limits (validated): the work holds these.
MAX_CAMERA_SIDE = 4096  # px, each side (within llvmpipe's 16384 offscreen limit)
MAX_CAMERA_PIXELS = 2048 * 2048  # the env takes ~0.3 kB a pixel: 2048^2 is ~1.7 GB
MAX_MATERIALS = 1000  # MuJoCo's renderer refuses a model with more (mjMAXMATERIAL)
MAX_TEXTURES = 1000  # likewise (mjMAXTEXTURE)
MAX_PARTS = MAX_MATERIALS  # each table, shelf and prop takes one material
MAX_LIGHTS = 100  # mjMAXLIGHT
GRATING_MODES = ("eye+object", "eye-only", "object-only")
DEFAULT_SCENE = "office"
T = TypeVar("T")
_PART_LISTS = ("tables", "shelves", "static_objects", "moving_objects", "mjcf_includes")


# ----------------------------------------------------------------------------------------
# Dataclasses


def _check_shape(shape: str, size: Sequence[float], mesh: MeshConfig | None) -> None:
    if shape not in SHAPES:
        raise ValueError(f"shape must be one of {SHAPES}, got {shape!r}")
    if shape == "mesh":
        if mesh is None:
            raise ValueError("mesh: required when shape is 'mesh'")
        if size:
            raise ValueError(
                f"size: not used by a mesh (its size is the file's times mesh.scale), got {size}"
            )
        return
    if mesh is not None:
        raise ValueError(f"mesh: only for shape 'mesh', got shape {shape!r}")
    n = SHAPE_SIZE_LEN[shape]
    if len(size) != n or not all(math.isfinite(v) and v > 0 for v in size):
        raise ValueError(f"size of a {shape} must be {n} extents > 0 (m), got {tuple(size)}")


def checked_file(file: str, suffixes: tuple[str, ...]) -> Path:
    """The absolute path of ``file`` (relative paths: to the current directory) if it ends
    in one of ``suffixes``; ValueError ``file: what is wrong, got value`` otherwise (nothing
    is read: :mod:`wander_env.untrusted` reads it)."""
    path = Path(file).expanduser()
    if path.suffix.lower() not in suffixes:
        raise ValueError(f"file: must end in {' or '.join(suffixes)}, got {file!r}")
    try:
        return path.resolve()
    except (OSError, RuntimeError) as e:
        raise ValueError(f"file: cannot be read ({e.strerror or e}), got {file!r}") from None


def _untrusted(e: UntrustedFileError) -> ValueError:
    """A refused file as the ``file`` field's error."""
    return ValueError(f"file: {e}")


def _mujoco_error(e: Exception) -> str:
    """MuJoCo's error as one line (its lines joined by ``; ``, no ``Error:`` lead, at
    most 300 characters)."""
    lines = [line.strip() for line in str(e).removeprefix("Error: ").splitlines()]
    text = "; ".join(line for line in lines if line)
    return text if len(text) <= 300 else text[:297] + "..."


def mesh_bounds(path: Path, data: bytes, scale: Vec3) -> tuple[np.ndarray, np.ndarray]:
    """(min, max) corners (m) of the bounding box of mesh file ``path`` (OBJ or STL, its
    contents ``data``) in its file's frame, times ``scale``, as MuJoCo reads it; ValueError
    ``file: ...`` when MuJoCo cannot read it."""
    spec = mujoco.MjSpec()
    spec.assets = {path.name: data}
    spec.add_mesh(
        name=path.name,
        file=path.name,
        scale=scale,
        inertia=mujoco.mjtMeshInertia.mjMESH_INERTIA_SHELL,
    )
    body = spec.worldbody.add_body(mocap=True)
    body.add_geom(type=mujoco.mjtGeom.mjGEOM_MESH, meshname=path.name, contype=0, conaffinity=0)
    try:
        model = spec.compile()
    except ValueError as e:
        raise ValueError(
            f"file: MuJoCo cannot read the mesh ({_mujoco_error(e)}), got {str(path)!r}"
        ) from None
    adr, num = int(model.mesh_vertadr[0]), int(model.mesh_vertnum[0])
    rot = np.zeros(9)
    mujoco.mju_quat2Mat(rot, model.geom_quat[0])
    verts = model.mesh_vert[adr : adr + num].astype(float) @ rot.reshape(3, 3).T + model.geom_pos[0]
    if not np.isfinite(verts).all():
        raise ValueError(f"file: the mesh has vertices that are not finite, got {str(path)!r}")
    return verts.min(axis=0), verts.max(axis=0)


def mjcf_counts(files: MJCFFiles) -> tuple[int, int]:
    """(materials, textures) of the MJCF file read as ``files`` as MuJoCo compiles it
    alone; ValueError ``file: ...`` when MuJoCo cannot, or the model is larger than
    :data:`wander_env.untrusted.LIMITS` allows."""
    try:
        model = files.spec().compile()
    except ValueError as e:
        raise ValueError(
            f"file: MuJoCo cannot read the MJCF ({_mujoco_error(e)}), got {files.path!r}"
        ) from None
    try:
        check_model_size(model, files.path)
    except UntrustedFileError as e:
        raise _untrusted(e) from None
    return int(model.nmat), int(model.ntex)


@dataclass(frozen=True)
class MeshConfig:
    """A mesh file (Wavefront OBJ or STL) that MuJoCo reads, and its scale.

    The file's coordinates times ``scale`` are metres; the object's ``position`` is the
    centre of the scaled mesh's bounding box. OBJ texture coordinates are not used: a
    ``texture`` is wrapped round the mesh as a cube map.
    """

    # the file as read and its bounds, instance attributes set by __post_init__ (ClassVar
    # keeps them out of the fields, so they are no part of the config's value, repr,
    # schema or asdict)
    _bounds: ClassVar[tuple[np.ndarray, np.ndarray]]
    _data: ClassVar[bytes]
    _record: ClassVar[FileRecord]
    file: Annotated[
        str,
        field_doc(
            "Path of a Wavefront OBJ or STL file of at most 16 MiB that MuJoCo reads; "
            "relative: to the scene file's folder (in Python, to the current directory)",
            example="meshes/bunny.obj",
        ),
    ]
    scale: Annotated[
        Positive | tuple[Positive, Positive, Positive],
        field_doc(
            "Multiplies the file's coordinates into metres: one factor, or one per axis",
            unit="m per file unit",
            example=0.001,
        ),
    ] = 1.0

    def __post_init__(self) -> None:
        check_annotated(self)
        path = checked_file(self.file, MESH_SUFFIXES)
        log = ReadLog()
        try:
            data = read_bytes(path, LIMITS.mesh_bytes, log=log)
        except UntrustedFileError as e:
            raise _untrusted(e) from None
        object.__setattr__(self, "file", str(path))
        # read once, here: the build uses these bytes and bounds
        object.__setattr__(self, "_data", data)
        object.__setattr__(self, "_record", log.records[0])
        object.__setattr__(self, "_bounds", mesh_bounds(path, data, self.scale_xyz))

    @property
    def data(self) -> bytes:
        """The file's contents, as read when the config was made."""
        return self._data

    def files_read(self) -> tuple[FileRecord, ...]:
        """The file, as read when the config was made (path, size, SHA-256)."""
        return (self._record,)

    @property
    def scale_xyz(self) -> Vec3:
        """``scale`` per axis."""
        s = self.scale
        return (s, s, s) if isinstance(s, (int, float)) else s

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """(min, max) corners (m) of the scaled mesh's bounding box in its file's frame,
        as read when the config was made."""
        lo, hi = self._bounds
        return lo.copy(), hi.copy()


class _Body:
    """Base of the prop configs: their ``shape``, full-extent ``size`` (m) and ``mesh``,
    checked together on construction."""

    shape: str
    size: tuple[float, ...]
    mesh: MeshConfig | None

    def __post_init__(self) -> None:
        _check_shape(self.shape, self.size, self.mesh)


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
        field_doc("Horizontal field of view (the Speck's by default)", unit="deg", gt=0, le=179),
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


# The look every part's config declares: a colour, and for tables and shelves a texture.
PartRGBA = Annotated[RGBA, field_doc("Colour (red, green, blue, alpha), times the texture's")]
PartTexture = Annotated[TextureSpec | None, field_doc("A procedural texture (none: rgba alone)")]


@dataclass(frozen=True)
class TableConfig:
    """A table: top ``top_size`` (x, y) at ``height`` (top surface), four legs."""

    center_xy: Annotated[Vec2, field_doc("Centre of the top (x, y)", unit="m")] = (1.0, 0.0)
    top_size: Annotated[
        tuple[Positive, Positive], field_doc("Extents of the top (x, y)", unit="m")
    ] = (0.8, 1.4)
    height: Annotated[Positive, field_doc("Height of the top surface", unit="m")] = 0.72
    thickness: Annotated[Positive, field_doc("Thickness of the top (< height)", unit="m")] = 0.04
    leg_width: Annotated[
        Positive,
        field_doc("Side of the legs' square section; set in by it from the corners", unit="m"),
    ] = 0.05
    rgba: PartRGBA = WHITE
    texture: PartTexture = None

    def __post_init__(self) -> None:
        if self.thickness >= self.height:
            raise ValueError(f"thickness: must be < height ({self.height}), got {self.thickness}")


@dataclass(frozen=True)
class ShelfConfig:
    """An open shelf facing -x (towards a PTU at the origin): sides, back and boards.

    ``levels`` are the heights (m, top surfaces) of the boards; ``yaw_deg`` turns it
    about z (0 = facing -x).
    """

    center_xy: Annotated[Vec2, field_doc("Centre on the floor (x, y)", unit="m")] = (2.0, 0.0)
    width: Annotated[Positive, field_doc("Width (along y at yaw 0)", unit="m")] = 1.6
    depth: Annotated[Positive, field_doc("Depth (along x at yaw 0)", unit="m")] = 0.35
    height: Annotated[Positive, field_doc("Height of the sides and back", unit="m")] = 1.8
    levels: Annotated[
        tuple[NonNegative, ...],
        field_doc("Heights of the boards' top surfaces (each <= height)", unit="m", min_length=1),
    ] = (
        0.05,
        0.5,
        0.95,
        1.4,
        1.8,
    )
    thickness: Annotated[Positive, field_doc("Thickness of boards, sides and back", unit="m")] = (
        0.03
    )
    yaw_deg: Annotated[
        float, field_doc("Turn about z (0: it faces -x, towards a PTU at the origin)", unit="deg")
    ] = 0.0
    rgba: PartRGBA = WHITE
    texture: PartTexture = None

    def __post_init__(self) -> None:
        if self.levels and max(self.levels) > self.height + 1e-9:
            raise ValueError(f"levels: must be <= height ({self.height}), got {self.levels}")


Shape = Literal["box", "sphere", "cylinder", "mesh"]
Size = Annotated[tuple[Positive, ...], pydantic.Field(max_length=3)]


# The fields static and moving props share, each with its documentation.
BodyShape = Annotated[Shape, field_doc("box, sphere, cylinder, or mesh (then give mesh, not size)")]
BodySize = Annotated[
    Size,
    field_doc(
        "Full extents: a box [x, y, z], a sphere [diameter], a cylinder [diameter, height] "
        "(axis along z); none for a mesh",
        unit="m",
    ),
]
BodyMesh = Annotated[MeshConfig | None, field_doc("The mesh file and its scale (shape mesh only)")]
BodyTexture = Annotated[
    TextureSpec | None,
    field_doc("A procedural texture (none: rgba alone); cube-mapped except on a box"),
]


@dataclass(frozen=True, kw_only=True)
class StaticObjectConfig(_Body):
    """A static prop: shape, full-extent size (m) or mesh, centre, orientation (xyz
    Euler, deg)."""

    shape: BodyShape
    size: BodySize = ()
    mesh: BodyMesh = None
    position: Annotated[
        Vec3,
        field_doc(
            "Centre (a mesh: its bounding box's centre)", unit="m", example=[1.0, 0.45, 0.775]
        ),
    ]
    euler_deg: Annotated[Vec3, field_doc("Orientation, xyz Euler angles", unit="deg")] = (
        0.0,
        0.0,
        0.0,
    )
    rgba: PartRGBA = (
        0.7,
        0.7,
        0.7,
        1.0,
    )
    texture: BodyTexture = None
    name: Annotated[str, field_doc("Its geom's name (default static_i, i from 0)")] = ""


@dataclass(frozen=True, kw_only=True)
class MovingObjectConfig(_Body):
    """A moving object (a mocap body): shape, full-extent size (m) or mesh, look,
    trajectory.

    Object k (1-based, in list order) has id k in segmentation masks.
    """

    shape: BodyShape
    size: BodySize = ()
    mesh: BodyMesh = None
    trajectory: Annotated[
        TrajectoryParams,
        field_doc("Where its centre is at time t: one of the kinds below, chosen by kind"),
        pydantic.Field(discriminator="kind"),
    ]
    rgba: PartRGBA = WHITE
    texture: BodyTexture = None
    name: Annotated[
        str, field_doc("Its name in the ground truth and results (its body is object_k)")
    ] = ""


@dataclass(frozen=True, kw_only=True)
class MJCFIncludeConfig:
    """The bodies of an existing MJCF file's worldbody, attached to the scene as static
    parts (their joints are removed; nothing of theirs moves) under a frame at
    ``position`` turned by ``euler_deg``, their names prefixed ``NAME/``. Their
    materials and textures count towards MuJoCo's limits; geoms in groups above 2 are
    not rendered by the camera; mask id 0 (not an object)."""

    # (materials, textures) of the file and the files read, instance attributes set by
    # __post_init__ (ClassVar keeps them out of the fields)
    _counts: ClassVar[tuple[int, int]]
    _files: ClassVar[MJCFFiles]
    file: Annotated[
        str,
        field_doc(
            "Path of an MJCF file (.xml, .mjcf) of at most 8 MiB that MuJoCo compiles alone; "
            "relative: to the scene file's folder (in Python, to the current directory)",
            example="robots/arm.xml",
        ),
    ]
    position: Annotated[Vec3, field_doc("Where the file's world origin goes", unit="m")] = (
        0.0,
        0.0,
        0.0,
    )
    euler_deg: Annotated[
        Vec3, field_doc("Turn of the file's world, xyz Euler angles", unit="deg")
    ] = (0.0, 0.0, 0.0)
    name: Annotated[
        str,
        field_doc(
            "Prefix of the names it brings, NAME/... (default include_i, i from 0)",
            example="arm",
        ),
    ] = ""

    def __post_init__(self) -> None:
        check_annotated(self)
        path = checked_file(self.file, (".xml", ".mjcf"))
        try:
            files = load_mjcf(path)  # read once, here: every build compiles these bytes
        except UntrustedFileError as e:
            raise _untrusted(e) from None
        object.__setattr__(self, "file", str(path))
        object.__setattr__(self, "_files", files)
        object.__setattr__(self, "_counts", mjcf_counts(files))

    def spec(self, prefix: str = "") -> mujoco.MjSpec:
        """A fresh ``mujoco.MjSpec`` of the file as read when the config was made, its
        assets' files renamed ``prefix + name`` (see :meth:`assets`)."""
        return self._files.spec(prefix)

    def assets(self, prefix: str) -> dict[str, bytes]:
        """The bytes of the files :meth:`spec` with ``prefix`` names (meshes, textures)."""
        return self._files.prefixed_assets(prefix)

    def files_read(self) -> tuple[FileRecord, ...]:
        """The file and every file it names, as read when the config was made."""
        return self._files.records

    def counts(self) -> tuple[int, int]:
        """(materials, textures) the file brings, counted as it compiled alone when the
        config was made (an upper bound: assets its bodies do not use stay behind)."""
        return self._counts


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
        int, field_doc("Vertical strips the patch is drawn with (each narrower than a pixel)", ge=2)
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


def include_name(index: int, include: MJCFIncludeConfig) -> str:
    """The name of include ``index`` (from 0) in a scene: its own, else ``include_i``."""
    return include.name or f"include_{index}"


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


def load_scene_config(
    scene: str | Path | Mapping[str, Any] | SceneConfig = DEFAULT_SCENE,
    log: ReadLog | None = None,
) -> SceneConfig:
    """The scene ``scene`` names: a :class:`SceneConfig` as it is, a mapping (a parsed
    scene document) validated, a name (``assets/scenes/NAME.yaml``) or a YAML file path.

    Relative mesh and MJCF file paths in a YAML file are relative to its folder. ``log``
    records every file the scene read (the YAML file, meshes, MJCF includes and the files
    they name) with its SHA-256.
    """
    if isinstance(scene, (SceneConfig, Mapping)):
        config = scene if isinstance(scene, SceneConfig) else scene_config_from_dict(scene)
        if log is not None:
            for record in config.files_read():
                log.add_record(record)
        return config
    text = str(scene)
    is_path = isinstance(scene, Path) or text.endswith((".yaml", ".yml")) or "/" in text
    if is_path:
        path = Path(scene)
        try:
            found = path.is_file()
        except OSError as e:  # a name too long for the file system, say
            raise FileNotFoundError(
                f"scene file not readable: {text[:200]!r}: {e.strerror}"
            ) from None
        if not found:
            raise FileNotFoundError(f"scene file not found: {path}")
    else:
        path = assets_dir() / "scenes" / f"{text}.yaml"
        if len(text) > 255 or not path.is_file():
            raise ValueError(
                f"unknown scene {text[:200]!r}; available: {', '.join(available_scenes())}"
            )
    try:
        text = read_bytes(path, MAX_YAML_BYTES, log=log)
    except UntrustedFileError as e:
        raise ConfigError(str(e)) from None
    data = _files_relative_to(parse_yaml(text, str(path)), path.parent)
    config = scene_config_from_dict(data, default_name=path.stem, where=str(path))
    if log is not None:
        for record in config.files_read():
            log.add_record(record)
    return config


def _files_relative_to(data: Any, folder: Path) -> Any:
    """``data`` (a parsed scene document, not yet validated) with the relative ``file``
    paths of its meshes and MJCF includes made relative to ``folder``."""
    if not isinstance(data, Mapping):
        return data

    def rebase(block: Any) -> Any:
        file = block.get("file") if isinstance(block, Mapping) else None
        if not isinstance(file, str) or Path(file).expanduser().is_absolute():
            return block
        return {**block, "file": str(folder / file)}

    def with_mesh(item: Any) -> Any:
        return (
            {**item, "mesh": rebase(item["mesh"])}
            if isinstance(item, Mapping) and "mesh" in item
            else item
        )

    out = dict(data)
    for key in ("static_objects", "moving_objects"):
        if isinstance(out.get(key), list):
            out[key] = [with_mesh(item) for item in out[key]]
    if isinstance(out.get("mjcf_includes"), list):
        out["mjcf_includes"] = [rebase(item) for item in out["mjcf_includes"]]
    return out


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
    (one of 'linear_bounce', 'circular', 'random_walk', 'waypoints',
    'scripted')
    """
    if isinstance(data, Mapping) and "name" not in data:
        data = {"name": default_name, **data}
    _refuse_hinge_offset(data, where)
    _check_lengths(data, where)
    return validate(SceneConfig, data, where=where)


def _check_lengths(data: Any, where: str | None) -> None:
    """The lists of parts and lights within their limits, checked on the parsed document
    before it is validated (so that a million objects cost no more than the file).
    ConfigError ``where: key: ...``."""
    if not isinstance(data, Mapping):
        return
    lighting = data.get("lighting")
    why = f"MuJoCo renders at most {MAX_MATERIALS} materials, one a part"
    lists = {key: (data.get(key), MAX_PARTS, why) for key in _PART_LISTS}
    if isinstance(lighting, Mapping):
        lights = lighting.get("lights")
        lists["lighting.lights"] = (lights, MAX_LIGHTS, f"MuJoCo's limit is {MAX_LIGHTS}")
    head = f"{where}: " if where else ""
    for key, (items, limit, reason) in lists.items():
        if isinstance(items, (list, tuple)) and len(items) > limit:
            raise ConfigError(f"{head}{key}: at most {limit} items ({reason}), got {len(items)}")


#: The camera's offset from the tilt hinge: a scene's ``ptu`` block held it once; it is
#: :class:`wander_env.ptu.params.PTUParams`' alone.
_HINGE_OFFSET_KEYS = ("camera_forward_m", "camera_up_m")


def _refuse_hinge_offset(data: Any, where: str | None) -> None:
    """ConfigError ``where: ptu.KEY: ...`` naming where the hinge offset is given now, when
    the parsed document gives it in its ``ptu`` block (nested or as a dotted key)."""
    if not isinstance(data, Mapping):
        return
    ptu = data.get("ptu")
    block = ptu if isinstance(ptu, Mapping) else {}
    for key in _HINGE_OFFSET_KEYS:
        if key in block:
            value = block[key]
        elif f"ptu.{key}" in data:
            value = data[f"ptu.{key}"]
        else:
            continue
        head = f"{where}: " if where else ""
        raise ConfigError(
            f"{head}ptu.{key}: the camera's offset from the hinge is the PTU's, not the "
            f"scene's: give it in the env's ptu block (env.ptu.{key}, or --set "
            f"env.ptu.{key}=...), got {shown(value)}"
        )
