"""The parts of a scene: frozen, validated dataclasses of what stands and moves in it.

Tables (:class:`TableConfig`) and open shelves (:class:`ShelfConfig`); static and moving
props (:class:`StaticObjectConfig`, :class:`MovingObjectConfig`: a box, sphere, cylinder
or a mesh, each moving one with a trajectory of :mod:`wander_env.trajectories`); meshes
(:class:`MeshConfig`: an OBJ or STL file that MuJoCo reads, with a scale) and the bodies
of existing MJCF files (:class:`MJCFIncludeConfig`). :class:`wander_env.scene_config.SceneConfig`
lists them; :mod:`wander_env.entities` turns each into its MJCF fragment.

Sizes are full extents (not MuJoCo half-sizes): a box ``[sx, sy, sz]``, a sphere
``[diameter]``, a cylinder ``[diameter, height]`` (axis along z); metres and degrees.

Mesh and MJCF files are read once, when validated, through :mod:`wander_env.untrusted`
(regular files within :data:`wander_env.untrusted.LIMITS`, an MJCF file with every file it
names, checked before MuJoCo compiles them from memory); :func:`mesh_bounds` and
:func:`mjcf_counts` ask MuJoCo what it reads of them. A bad value raises a ``ValueError``
whose message starts with the field, e.g. ``file: must end in .obj or .stl, got 'a.ply'``.

Examples:
    >>> StaticObjectConfig(shape="sphere", size=(0.1,), position=(1.0, 0.0, 1.0)).size
    (0.1,)
    >>> StaticObjectConfig(shape="sphere", size=(0.1, 0.2), position=(1.0, 0.0, 1.0))
    Traceback (most recent call last):
    ValueError: size of a sphere must be 1 extents > 0 (m), got (0.1, 0.2)
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, ClassVar, Literal

import mujoco
import numpy as np
import pydantic

from wander_env.config import check_annotated
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


def include_name(index: int, include: MJCFIncludeConfig) -> str:
    """The name of include ``index`` (from 0) in a scene: its own, else ``include_i``."""
    return include.name or f"include_{index}"
