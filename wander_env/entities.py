"""The scene's parts as entities: each owns its MJCF fragment and, if it moves, its runtime.

The split follows dm_control composer (an entity builds its own MJCF; an arena composes
entities; the task owns timing) in wander's own terms, without dm_control: an entity
is a small frozen dataclass over its part of the :class:`~wander_env.scene_config.SceneConfig`
whose :meth:`attach` writes its fragment into the one
:class:`~wander_env.mjcf_document.MJCFDocument` (:mod:`wander_env.mjcf_document`: the
shared XML root, ``<asset>`` section, in-memory PNG assets and material/texture/geom
helpers).
:class:`wander_env.mjcf.Arena` composes them in scene order; the env (the task) decides
when things happen and asks a moving entity's runtime for its state at time t.

- :class:`PanTiltCamera`: bodies ``ptu_base`` / ``ptu_pan`` / ``ptu_tilt``, hinges
  ``pan`` and ``tilt``, camera ``event_camera``; it answers the camera's world position
  at pan = tilt = 0 and its MuJoCo ``fovy``.
- :class:`Lights`, :class:`Room`, :class:`Table`, :class:`Shelf`, :class:`StaticProp`:
  static fragments (a prop's mesh goes in as an in-memory ``<mesh>`` asset, centred on
  its bounding box: :meth:`~wander_env.mjcf_document.MJCFDocument.shape_geom`).
- :class:`MJCFInclude`: an MJCF file's worldbody bodies, attached to the compiled
  scene's ``MjSpec`` (not to the XML) as static parts.
- :class:`MovingProp`: mocap body ``object_k``; :meth:`MovingProp.motion` gives its
  runtime (:class:`PropMotion`: its trajectory and mocap id; writes its position at t).
- :class:`GratingStimulus`: the self-luminous screen and the patch strips;
  :meth:`GratingStimulus.motion` gives its runtime (:class:`GratingMotion`: slides the
  screen, recolours the strips); the screen's geometry and state at t are pure maths in
  :mod:`wander_env.grating_geometry`.

Examples:
    >>> from wander_env.scenes import load_scene_config
    >>> cfg = load_scene_config("office")
    >>> ptu = PanTiltCamera(cfg.ptu, cfg.camera)
    >>> doc = MJCFDocument(cfg.name)
    >>> _ = doc.open_world()
    >>> ptu.attach(doc)
    >>> [j.get("name") for j in doc.world.iter("joint")], doc.world.find(".//camera").get("name")
    (['pan', 'tilt'], 'event_camera')
"""

from __future__ import annotations

import math
import re
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from typing import Protocol

import mujoco
import numpy as np

from wander_env.camera import CAMERA_NAME, vertical_fov_deg
from wander_env.grating_geometry import GratingLayout, grating_layout, grating_state
from wander_env.mjcf_document import MJCFDocument, fmt
from wander_env.ptu.params import PTUParams
from wander_env.scene_config import (
    CameraConfig,
    GratingConfig,
    LightingConfig,
    PTUMountConfig,
    RoomConfig,
)
from wander_env.scene_parts import (
    MJCFIncludeConfig,
    MovingObjectConfig,
    ShelfConfig,
    StaticObjectConfig,
    TableConfig,
    include_name,
)
from wander_env.textures import grating
from wander_env.trajectories import (
    LinearBounceParams,
    RandomWalkParams,
    Trajectory,
    make_trajectory,
)

__all__ = [
    "GRATING_BACKGROUND_BODY",
    "GRATING_STRIP_PREFIX",
    "OBJECT_BODY_PREFIX",
    "PAN_BODY",
    "PAN_JOINT",
    "PTU_BASE_BODY",
    "PTU_GEOM_GROUP",
    "SCREEN_GAP_M",
    "TILT_BODY",
    "TILT_JOINT",
    "Entity",
    "GratingMotion",
    "GratingStimulus",
    "Lights",
    "MJCFInclude",
    "MovingProp",
    "PanTiltCamera",
    "PropMotion",
    "Room",
    "Shelf",
    "StaticProp",
    "Table",
    "object_body_name",
    "object_index",
]

PAN_JOINT = "pan"
TILT_JOINT = "tilt"
PTU_BASE_BODY = "ptu_base"
PAN_BODY = "ptu_pan"
TILT_BODY = "ptu_tilt"
GRATING_BACKGROUND_BODY = "grating_background"
GRATING_STRIP_PREFIX = "grating_strip_"
PTU_GEOM_GROUP = 3  # not rendered by the event camera (MjvOption shows groups 0-2)
OBJECT_BODY_PREFIX = "object_"
_OBJECT_RE = re.compile(rf"^{OBJECT_BODY_PREFIX}(\d+)$")

SCREEN_GAP_M = 0.002  # the grating patch's distance in front of the screen
_GRATING_TEXELS = 64  # texels per background period


# ----------------------------------------------------------------------------------------
# Names, and a trajectory's start


def object_body_name(k: int) -> str:
    """Body (and geom) name of segmentable object ``k`` (1-based)."""
    if k < 1:
        raise ValueError(f"object ids start at 1, got {k}")
    return f"{OBJECT_BODY_PREFIX}{k}"


def object_index(body_name: str) -> int:
    """Object id (1-based) of a body name, 0 when it is not an object body."""
    m = _OBJECT_RE.match(body_name)
    return int(m.group(1)) if m else 0


def _initial_position(params: object) -> tuple[float, float, float]:
    """A trajectory's position at t = 0 without randomness (random walks: start or centre)."""
    if isinstance(params, RandomWalkParams):
        if params.start is not None:
            return params.start
        lo, hi = np.asarray(params.bounds_min), np.asarray(params.bounds_max)
        return tuple(float(v) for v in (lo + hi) / 2.0)  # type: ignore[return-value]
    if isinstance(params, LinearBounceParams):
        return params.start
    p = make_trajectory(params).position(0.0)  # type: ignore[arg-type]
    return (float(p[0]), float(p[1]), float(p[2]))


class Entity(Protocol):
    """A scene part that writes its own MJCF fragment."""

    def attach(self, doc: MJCFDocument) -> None:
        """Write this part's assets and bodies into ``doc``."""


# ----------------------------------------------------------------------------------------
# The pan-tilt unit and its camera


@dataclass(frozen=True)
class PanTiltCamera:
    """The pan-tilt unit with the event camera on its tilt body (one entity).

    Body ``ptu_base`` at ``mount.position`` (the tilt hinge); body ``ptu_pan`` with hinge
    ``pan`` about world z; body ``ptu_tilt`` with hinge ``tilt`` about -y; camera
    ``event_camera`` ``params.camera_forward_m`` ahead of and ``params.camera_up_m``
    above the hinge (the unit's parameters), looking along +x at pan = tilt = 0. Its
    geoms are in group 3 (not rendered).
    """

    mount: PTUMountConfig
    camera: CameraConfig
    params: PTUParams = field(default_factory=PTUParams)

    @property
    def fovy_deg(self) -> float:
        """The camera's vertical field of view (MuJoCo ``fovy``, deg)."""
        c = self.camera
        return vertical_fov_deg(c.hfov_deg, c.width, c.height)

    def camera_position(self) -> tuple[float, float, float]:
        """The camera's world position (m) at pan = tilt = 0."""
        x, y, z = self.mount.position
        return (x + self.params.camera_forward_m, y, z + self.params.camera_up_m)

    def attach(self, doc: MJCFDocument) -> None:
        """Write the PTU's bodies, joints, geoms and the camera."""
        p = self.mount
        grey = doc.material((0.2, 0.2, 0.22, 1))
        base = doc.element(doc.world, "body", name=PTU_BASE_BODY, pos=p.position)
        g = str(PTU_GEOM_GROUP)
        doc.geom(
            base, type="cylinder", pos=(0, 0, -0.12), size=(0.04, 0.03), material=grey, group=g
        )
        pan = ET.SubElement(base, "body", name=PAN_BODY)
        ET.SubElement(pan, "inertial", pos="0 0 0", mass="0.5", diaginertia="1e-3 1e-3 1e-3")
        ET.SubElement(pan, "joint", name=PAN_JOINT, type="hinge", axis="0 0 1")
        doc.geom(
            pan, type="box", pos=(0, 0, -0.06), size=(0.03, 0.05, 0.03), material=grey, group=g
        )
        tilt = ET.SubElement(pan, "body", name=TILT_BODY)
        ET.SubElement(tilt, "inertial", pos="0 0 0", mass="0.2", diaginertia="1e-4 1e-4 1e-4")
        ET.SubElement(tilt, "joint", name=TILT_JOINT, type="hinge", axis="0 -1 0")
        cam_pos = (self.params.camera_forward_m, 0.0, self.params.camera_up_m)
        doc.geom(
            tilt,
            type="box",
            pos=(cam_pos[0] - 0.03, 0, cam_pos[2]),
            size=(0.025, 0.025, 0.025),
            material=grey,
            group=g,
        )
        doc.element(
            tilt,
            "camera",
            name=CAMERA_NAME,
            pos=cam_pos,
            xyaxes="0 -1 0 0 0 1",  # image right = -y, image up = +z, looking along +x
            fovy=self.fovy_deg,
        )


# ----------------------------------------------------------------------------------------
# Static parts


@dataclass(frozen=True)
class Lights:
    """The scene's directional lights (no shadows), ``light_0`` ...."""

    lighting: LightingConfig

    def attach(self, doc: MJCFDocument) -> None:
        """Write one ``<light>`` per configured light."""
        for i, lc in enumerate(self.lighting.lights):
            doc.element(
                doc.world,
                "light",
                name=f"light_{i}",
                pos=lc.position,
                dir=lc.direction,
                type="directional",
                castshadow="false",
                diffuse=[lc.diffuse] * 3,
                specular="0 0 0",
            )


@dataclass(frozen=True)
class Room:
    """Body ``room``: floor, ceiling and four walls as planes facing inwards."""

    room: RoomConfig

    def attach(self, doc: MJCFDocument) -> None:
        """Write the six textured planes."""
        room = self.room
        sx, sy, sz = room.size
        cx, cy = room.center_xy
        body = ET.SubElement(doc.world, "body", name="room")
        # (name, centre, xyaxes (normal = x × y, facing into the room), face size, texture)
        faces = [
            ("floor", (cx, cy, 0.0), (1, 0, 0, 0, 1, 0), (sx, sy), room.floor_texture),
            ("ceiling", (cx, cy, sz), (1, 0, 0, 0, -1, 0), (sx, sy), room.ceiling_texture),
            ("wall_front", (cx + sx / 2, cy, sz / 2), (0, -1, 0, 0, 0, 1), (sy, sz), None),
            ("wall_back", (cx - sx / 2, cy, sz / 2), (0, 1, 0, 0, 0, 1), (sy, sz), None),
            ("wall_left", (cx, cy + sy / 2, sz / 2), (1, 0, 0, 0, 0, 1), (sx, sz), None),
            ("wall_right", (cx, cy - sy / 2, sz / 2), (-1, 0, 0, 0, 0, 1), (sx, sz), None),
        ]
        for name, pos, axes, face, tex in faces:
            mat = doc.material((1, 1, 1, 1), tex or room.wall_texture, face)
            doc.geom(
                body,
                name=name,
                type="plane",
                pos=pos,
                xyaxes=axes,
                size=(face[0] / 2, face[1] / 2, max(face)),  # 3rd: grid step -> one quad
                material=mat,
            )


@dataclass(frozen=True)
class Table:
    """Body ``table_i`` on the floor at ``center_xy``: a top ``height`` high and four legs
    set in by ``leg_width`` from its corners."""

    index: int
    table: TableConfig

    def attach(self, doc: MJCFDocument) -> None:
        """Write the top and the legs (one material)."""
        i, t = self.index, self.table
        top = (t.top_size[0], t.top_size[1])
        mat = doc.material(t.rgba, t.texture, top)
        body = doc.element(doc.world, "body", name=f"table_{i}", pos=(*t.center_xy, 0))
        doc.geom(
            body,
            name=f"table_{i}_top",
            type="box",
            pos=(0, 0, t.height - t.thickness / 2),
            size=(top[0] / 2, top[1] / 2, t.thickness / 2),
            material=mat,
        )
        leg_h = t.height - t.thickness
        for j, (sx, sy) in enumerate(((1, 1), (1, -1), (-1, 1), (-1, -1))):
            doc.geom(
                body,
                name=f"table_{i}_leg_{j}",
                type="box",
                pos=(
                    sx * (top[0] / 2 - t.leg_width),
                    sy * (top[1] / 2 - t.leg_width),
                    leg_h / 2,
                ),
                size=(t.leg_width / 2, t.leg_width / 2, leg_h / 2),
                material=mat,
            )


@dataclass(frozen=True)
class Shelf:
    """Body ``shelf_i``: two sides, a back and the boards, turned by ``yaw_deg``."""

    index: int
    shelf: ShelfConfig

    def attach(self, doc: MJCFDocument) -> None:
        """Write the sides, back and boards (one material)."""
        i, s = self.index, self.shelf
        body = doc.element(
            doc.world,
            "body",
            name=f"shelf_{i}",
            pos=(*s.center_xy, 0),
            euler=(0, 0, math.radians(s.yaw_deg)),
        )
        mat = doc.material(s.rgba, s.texture, (s.width, s.height))
        t, w, d, h = s.thickness, s.width, s.depth, s.height
        for j, side in enumerate((1, -1)):
            doc.geom(
                body,
                name=f"shelf_{i}_side_{j}",
                type="box",
                pos=(0, side * (w / 2 - t / 2), h / 2),
                size=(d / 2, t / 2, h / 2),
                material=mat,
            )
        doc.geom(
            body,
            name=f"shelf_{i}_back",
            type="box",
            pos=(d / 2 - t / 2, 0, h / 2),
            size=(t / 2, w / 2 - t, h / 2),
            material=mat,
        )
        for j, level in enumerate(s.levels):
            z = max(level, t) - t / 2
            doc.geom(
                body,
                name=f"shelf_{i}_board_{j}",
                type="box",
                pos=(0, 0, z),
                size=(d / 2, w / 2 - t, t / 2),
                material=mat,
            )


@dataclass(frozen=True)
class StaticProp:
    """One world geom (box, sphere or cylinder of full extents ``size``) at ``position``,
    turned by ``euler_deg``, named ``name`` or ``static_i``."""

    index: int
    prop: StaticObjectConfig

    def attach(self, doc: MJCFDocument) -> None:
        """Write the geom and its material (and mesh)."""
        o = self.prop
        doc.shape_geom(
            doc.world,
            o.shape,
            o.size,
            o.mesh,
            o.rgba,
            o.texture,
            name=o.name or f"static_{self.index}",
            pos=o.position,
            euler=tuple(math.radians(a) for a in o.euler_deg),
        )


@dataclass(frozen=True)
class MJCFInclude:
    """The worldbody bodies of an MJCF file, joints removed, under frame ``NAME`` (or
    ``include_i``) at ``position`` turned by ``euler_deg``, names prefixed ``NAME/``.

    It attaches to the compiled scene's :class:`mujoco.MjSpec` (MuJoCo keeps the file's
    own compiler settings, asset paths and defaults), not to the XML document.
    """

    index: int
    include: MJCFIncludeConfig

    @property
    def prefix(self) -> str:
        """``NAME/``, the prefix of everything it brings."""
        return f"{include_name(self.index, self.include)}/"

    def attach_spec(self, spec: mujoco.MjSpec) -> None:
        """Attach the file's bodies to ``spec``'s worldbody (static: no joints)."""
        inc = self.include
        child = inc.spec(self.prefix)  # its files' bytes: inc.assets(self.prefix)
        for joint in list(child.joints):
            child.delete(joint)
        for key in list(child.keys):  # their qpos sizes no longer fit
            child.delete(key)
        quat = np.zeros(4)
        mujoco.mju_euler2Quat(quat, np.radians(inc.euler_deg), "xyz")
        frame = spec.worldbody.add_frame(name=self.prefix[:-1], pos=inc.position, quat=quat)
        body = child.worldbody.first_body()
        while body is not None:
            frame.attach_body(body, self.prefix, "")
            body = child.worldbody.next_body(body)


# ----------------------------------------------------------------------------------------
# Moving parts and their runtimes


@dataclass(frozen=True)
class PropMotion:
    """A moving prop's runtime: its trajectory and the mocap slot it writes."""

    trajectory: Trajectory
    mocap_id: int

    def position(self, t: float) -> np.ndarray:
        """World position (m) at time t (s)."""
        return self.trajectory.position(t)

    def apply(self, data: mujoco.MjData, t: float) -> None:
        """Write the position at time t into ``data.mocap_pos``."""
        data.mocap_pos[self.mocap_id] = self.position(t)


@dataclass(frozen=True)
class MovingProp:
    """Mocap body ``object_k`` (k = ``index``, 1-based) with one geom of the same name,
    placed at its trajectory's start; :meth:`motion` moves it at run time."""

    index: int
    prop: MovingObjectConfig

    @property
    def body_name(self) -> str:
        """``object_k``."""
        return object_body_name(self.index)

    def attach(self, doc: MJCFDocument) -> None:
        """Write the mocap body, its geom and material (and mesh)."""
        o, name = self.prop, self.body_name
        body = doc.element(
            doc.world, "body", name=name, mocap="true", pos=_initial_position(o.trajectory)
        )
        doc.shape_geom(body, o.shape, o.size, o.mesh, o.rgba, o.texture, name=name)

    def motion(self, model: mujoco.MjModel, rng: np.random.Generator) -> PropMotion:
        """The runtime in a compiled ``model`` (random walks draw from ``rng``)."""
        trajectory = make_trajectory(self.prop.trajectory, rng)
        return PropMotion(trajectory, int(model.body_mocapid[model.body(self.body_name).id]))


@dataclass(frozen=True)
class GratingMotion:
    """The gratings' runtime in a compiled model: slides the screen, recolours the strips."""

    stimulus: GratingStimulus
    layout: GratingLayout
    model: mujoco.MjModel
    background_mocap: int
    strip_geoms: np.ndarray

    def apply(self, data: mujoco.MjData, t: float) -> None:
        """Write the screen's position into ``data.mocap_pos`` and the strips' grey
        levels into ``model.geom_rgba`` for time t (s)."""
        slide, level = grating_state(self.stimulus.grating, self.layout, t)
        cx, cy, cz = self.layout.center
        data.mocap_pos[self.background_mocap] = (cx, cy - slide, cz)
        self.model.geom_rgba[self.strip_geoms, :3] = level[:, None]


@dataclass(frozen=True)
class GratingStimulus:
    """The gratings screen ``distance_m`` ahead of the PTU's camera, and its patch.

    A self-luminous plane on mocap body ``grating_background`` tiled with one background
    period per texture image; body ``object_1`` holds ``object_strips`` vertical strips
    2 mm in front of it whose colours :class:`GratingMotion` sets every frame.
    """

    grating: GratingConfig
    ptu: PanTiltCamera

    def layout(self) -> GratingLayout:
        """The screen's metric layout for the PTU's camera."""
        cam = self.ptu.camera
        return grating_layout(
            self.grating, self.ptu.camera_position(), cam.hfov_deg, self.ptu.fovy_deg
        )

    def attach(self, doc: MJCFDocument) -> None:
        """Write the screen's texture, materials, body and the patch strips."""
        g = self.grating
        layout = self.layout()
        # background: one period per texture image, tiled; a self-luminous plane
        img = grating(8, _GRATING_TEXELS, _GRATING_TEXELS, 0.0, g.profile, g.contrast, g.mean)
        doc.png_texture("grating_background", img)
        ET.SubElement(
            doc.asset,
            "material",
            name="grating_background",
            texture="grating_background",
            texrepeat=fmt((layout.background_periods, 1)),
            rgba="1 1 1 1",
            emission="1",
            specular="0",
            shininess="0",
            reflectance="0",
        )
        ET.SubElement(
            doc.asset,
            "material",
            name="grating_strip",
            rgba="0.5 0.5 0.5 1",
            emission="1",
            specular="0",
            shininess="0",
            reflectance="0",
        )
        bg = doc.element(
            doc.world, "body", name=GRATING_BACKGROUND_BODY, mocap="true", pos=layout.center
        )
        hw, hh = layout.screen_half_width_m, layout.screen_half_height_m
        doc.geom(
            bg,
            name="grating_screen",
            type="plane",
            xyaxes=(0, -1, 0, 0, 0, 1),  # local x = image right, normal towards the camera
            size=(hw, hh, 2 * max(hw, hh)),
            material="grating_background",
        )
        # central patch: vertical strips, coloured at run time by GratingMotion
        cx, cy, cz = layout.center
        patch = doc.element(
            doc.world, "body", name=object_body_name(1), pos=(cx - SCREEN_GAP_M, cy, cz)
        )
        strip_w = layout.object_side_m / len(layout.strip_offsets_m)
        _, level = grating_state(g, layout, 0.0)
        for j, (x, v) in enumerate(zip(layout.strip_offsets_m, level, strict=True)):
            doc.geom(
                patch,
                name=f"{GRATING_STRIP_PREFIX}{j}",
                type="box",
                pos=(0, -x, 0),  # image right = world -y
                size=(SCREEN_GAP_M / 4, strip_w / 2, layout.object_side_m / 2),
                material="grating_strip",
                rgba=(v, v, v, 1.0),
            )

    def layer_positions(self, t: float) -> np.ndarray:
        """(3, 3): the static world (zero), the patch's content and the screen's, at time
        t, unwrapped (no jump back by a period)."""
        v_b, v_o = (v * self.grating.metres_per_deg for v in self.grating.effective_speeds_deg_s())
        right = np.array([0.0, -1.0, 0.0])  # image right is world -y
        return np.stack([np.zeros(3), v_o * t * right, v_b * t * right])

    def motion(self, model: mujoco.MjModel) -> GratingMotion:
        """The runtime in a compiled ``model``."""
        strips = [
            model.geom(f"{GRATING_STRIP_PREFIX}{j}").id for j in range(self.grating.object_strips)
        ]
        return GratingMotion(
            self,
            self.layout(),
            model,
            int(model.body_mocapid[model.body(GRATING_BACKGROUND_BODY).id]),
            np.array(strips, dtype=int),
        )
