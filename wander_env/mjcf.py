"""MJCF for a :class:`~wander_env.scene_config.SceneConfig`, and its runtime animation.

:func:`build_mjcf` returns the XML string plus an assets dict (procedural textures as
in-memory PNGs); :func:`compile_scene` compiles it to a ``mujoco.MjModel``.

What the model holds:

- **The pan-tilt unit** (the PTU frame of :mod:`wander_env.ptu`: x forward, y left,
  z up): body ``ptu_base`` at ``config.ptu.position`` (the tilt hinge); body
  ``ptu_pan`` with hinge ``pan`` about world z (positive turns left); body
  ``ptu_tilt`` with hinge ``tilt`` about -y (positive raises the optical axis); the
  camera ``event_camera`` on the tilt body, ``camera_forward_m`` ahead of and
  ``camera_up_m`` above the hinge, looking along +x at pan = tilt = 0, image x to the
  right (world -y), image y down. No actuators: the env writes the PTU model's angles
  (radians) to ``qpos`` and calls ``mj_forward`` (or ``mj_kinematics``) before
  rendering. Gravity is off and nothing collides, so ``mj_step`` moves nothing by
  itself. The PTU's own geoms are in group 3, which the camera does not render.
- **The camera's field of view**: ``fovy`` is the vertical FOV for the configured
  horizontal FOV and aspect (112.83° both ways for the 128 × 128 Speck).
- **Moving objects**: mocap bodies ``object_1`` .. ``object_n`` (1-based, config
  order), one geom each named like its body; their segmentation id is k.
- **The gratings screen** (``config.gratings``): a self-luminous (emission 1) plane on
  mocap body ``grating_background`` textured with one background period tiled across
  it; it slides sideways by (speed · t) mod period, which drifts the bars seamlessly.
  The central patch is body ``object_1``: ``object_strips`` vertical strips (each
  narrower than a pixel) 2 mm in front of the screen, whose colours
  :class:`SceneAnimator` sets every frame from the object grating's phase, so its bars
  drift inside a fixed window. In ``eye-only`` mode the strips show the background
  grating in phase (the screen drifts as one); in ``object-only`` the background
  stays still. Keep the scene's lights off for exact grating intensities.
- **Headless-friendly visuals**: offscreen buffer ≥ the image, no shadow map
  (``shadowsize 0``), no skybox, no reflectance, planes and box faces drawn as single
  quads, coarser sphere/cylinder tessellation, multisampling from
  ``config.camera.antialias_samples``.

Example:
    >>> from wander_env.scene_config import load_scene_config
    >>> model = compile_scene(load_scene_config("shelf"))
    >>> model.camera(CAMERA_NAME).id >= 0, model.nmocap
    (True, 0)
"""

from __future__ import annotations

import os

os.environ.setdefault("MUJOCO_GL", "egl")  # before mujoco is imported: headless rendering

import math
import re
import xml.etree.ElementTree as ET
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field

import mujoco
import numpy as np

from wander_env.scene_config import (
    GratingConfig,
    MovingObjectConfig,
    RoomConfig,
    SceneConfig,
    ShelfConfig,
    StaticObjectConfig,
    TableConfig,
)
from wander_env.textures import (
    TextureSpec,
    add_png_asset,
    grating,
    grating_profile,
    make_texture,
)
from wander_env.trajectories import (
    LinearBounceParams,
    RandomWalkParams,
    Trajectory,
    make_trajectory,
)

CAMERA_NAME = "event_camera"
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
_STATISTIC_EXTENT = 4.0  # m; with znear/zfar: near clip 2 cm, far clip 40 m
_ZNEAR = 0.005
_ZFAR = 10.0
# Tessellation of spheres/cylinders: a 20-gon's silhouette is within 1.2 % of the radius
# (0.2 px on a 30 px ball); MuJoCo's 28 x 16 costs ~1 ms more a frame on llvmpipe.
_NUM_SLICES = 20
_NUM_STACKS = 10


# ----------------------------------------------------------------------------------------
# Names and small maths


def object_body_name(k: int) -> str:
    """Body (and geom) name of segmentable object ``k`` (1-based)."""
    if k < 1:
        raise ValueError(f"object ids start at 1, got {k}")
    return f"{OBJECT_BODY_PREFIX}{k}"


def object_index(body_name: str) -> int:
    """Object id (1-based) of a body name, 0 when it is not an object body."""
    m = _OBJECT_RE.match(body_name)
    return int(m.group(1)) if m else 0


def vertical_fov_deg(hfov_deg: float, width: int, height: int) -> float:
    """Vertical FOV (MuJoCo ``fovy``) for a horizontal FOV and image size (square pixels).

    >>> round(vertical_fov_deg(112.83, 128, 128), 2), round(vertical_fov_deg(90.0, 200, 100), 2)
    (112.83, 53.13)
    """
    half = math.radians(hfov_deg) / 2.0
    return math.degrees(2.0 * math.atan(math.tan(half) * height / width))


def _fmt(values: float | Iterable[float]) -> str:
    if isinstance(values, (int, float)):
        values = (values,)
    return " ".join(f"{float(v):.6g}" for v in values)


def _half_size(shape: str, size: Sequence[float]) -> tuple[float, ...]:
    """Full extents (config) -> MuJoCo size: box half-extents, sphere radius, cylinder r, h/2."""
    if shape == "box":
        return tuple(s / 2.0 for s in size)
    if shape == "sphere":
        return (size[0] / 2.0,)
    return (size[0] / 2.0, size[1] / 2.0)


def _texture_face(shape: str, size: Sequence[float]) -> tuple[float, float]:
    """The face size (m) a texture's ``tile_m`` is measured against, per shape."""
    if shape == "box":
        s = sorted(size, reverse=True)
        return (s[0], s[1])
    if shape == "sphere":
        return (math.pi * size[0], math.pi * size[0] / 2.0)
    return (math.pi * size[0], size[1])


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


# ----------------------------------------------------------------------------------------
# Grating geometry (pure)


@dataclass(frozen=True)
class GratingLayout:
    """Metric layout of the gratings screen for a :class:`GratingConfig` and camera."""

    center: tuple[float, float, float]
    background_period_m: float
    background_periods: int  # even: the plane's centre is at phase 0
    screen_half_height_m: float
    object_period_m: float
    object_side_m: float
    strip_offsets_m: tuple[float, ...]  # strip centres, image-right from the centre

    @property
    def screen_half_width_m(self) -> float:
        """Half the background plane's width (m)."""
        return self.background_periods * self.background_period_m / 2.0


def grating_layout(
    g: GratingConfig, camera_position: Sequence[float], hfov_deg: float, vfov_deg: float
) -> GratingLayout:
    """Place the screen ``distance_m`` ahead of the camera (at pan = tilt = 0)."""
    d = g.distance_m
    mpd = g.metres_per_deg
    p_b = 1.0 / g.background_cycles_per_deg * mpd
    p_o = 1.0 / g.object_cycles_per_deg * mpd
    half_w = d * math.tan(math.radians(min(hfov_deg / 2.0 + g.margin_deg, 85.0)))
    half_h = d * math.tan(math.radians(min(vfov_deg / 2.0 + g.margin_deg, 85.0)))
    periods = 2 * math.ceil((half_w + p_b) / p_b)
    side = g.object_size_deg * mpd
    n = g.object_strips
    offsets = tuple(-side / 2.0 + (i + 0.5) * side / n for i in range(n))
    cx, cy, cz = camera_position
    return GratingLayout(
        center=(cx + d, cy, cz),
        background_period_m=p_b,
        background_periods=periods,
        screen_half_height_m=half_h,
        object_period_m=p_o,
        object_side_m=side,
        strip_offsets_m=offsets,
    )


def grating_state(g: GratingConfig, layout: GratingLayout, t: float) -> tuple[float, np.ndarray]:
    """(background slide in m, image-right; strip intensities in [0, 1]) at time t.

    The background shows phase (x - v_b t) / P_b at image-right offset x; the strips
    show (x - v_o t) / P_o, or the background's phase in ``eye-only`` mode.
    """
    v_b, v_o = (v * g.metres_per_deg for v in g.effective_speeds_deg_s())
    p_b, p_o = layout.background_period_m, layout.object_period_m
    slide = math.fmod(v_b * t, p_b)
    x = np.asarray(layout.strip_offsets_m)
    if g.mode == "eye-only":
        phase = (x - slide) / p_b
    else:
        phase = (x - math.fmod(v_o * t, p_o)) / p_o
    return slide, grating_profile(phase, g.profile, g.contrast, g.mean)


# ----------------------------------------------------------------------------------------
# Building


@dataclass
class MJCFScene:
    """An MJCF document: XML text, its in-memory assets, and the config it came from."""

    xml: str
    assets: dict[str, bytes]
    config: SceneConfig

    def compile(self) -> mujoco.MjModel:
        """Compile to a ``mujoco.MjModel``."""
        return mujoco.MjModel.from_xml_string(self.xml, self.assets)


@dataclass
class _Builder:
    config: SceneConfig
    assets: dict[str, bytes] = field(default_factory=dict)
    root: ET.Element = field(default_factory=lambda: ET.Element("mujoco"))

    def __post_init__(self) -> None:
        self.root.set("model", self.config.name)
        self.asset = ET.SubElement(self.root, "asset")
        self.world: ET.Element | None = None
        self._n_materials = 0

    # -- materials ------------------------------------------------------------------------

    def material(
        self,
        rgba: Sequence[float],
        texture: TextureSpec | None = None,
        face: tuple[float, float] = (1.0, 1.0),
        cube: bool = False,
        emission: float = 0.0,
    ) -> str:
        """A new matte material (optionally textured); returns its name."""
        self._n_materials += 1
        name = f"mat_{self._n_materials}"
        attrs = {
            "name": name,
            "rgba": _fmt(rgba),
            "specular": "0.05",
            "shininess": "0.1",
            "reflectance": "0",
            "emission": _fmt(emission),
        }
        if texture is not None:
            tex = f"tex_{self._n_materials}"
            file = add_png_asset(self.assets, tex, make_texture(texture))
            ttype = "cube" if cube else "2d"
            ET.SubElement(self.asset, "texture", name=tex, type=ttype, file=file)
            attrs["texture"] = tex
            attrs["texrepeat"] = _fmt(texture.texrepeat(face))
        ET.SubElement(self.asset, "material", **attrs)
        return name

    def geom(self, parent: ET.Element, **attrs: object) -> ET.Element:
        """A geom with formatted attributes."""
        return ET.SubElement(
            parent, "geom", **{k: v if isinstance(v, str) else _fmt(v) for k, v in attrs.items()}
        )

    # -- sections -------------------------------------------------------------------------

    def header(self) -> None:
        cam = self.config.camera
        ET.SubElement(self.root, "compiler", angle="radian", autolimits="true")
        ET.SubElement(self.root, "option", timestep="0.001", gravity="0 0 0")
        ET.SubElement(
            self.root, "statistic", extent=_fmt(_STATISTIC_EXTENT), center=_fmt((1.0, 0, 1.0))
        )
        visual = ET.SubElement(self.root, "visual")
        ET.SubElement(
            visual,
            "global",
            offwidth=str(max(cam.width, 128)),
            offheight=str(max(cam.height, 128)),
        )
        ET.SubElement(
            visual,
            "quality",
            shadowsize="0",  # no shadow map
            offsamples=str(cam.antialias_samples),
            numquads="1",  # flat faces as single quads (lights are directional)
            numslices=str(_NUM_SLICES),
            numstacks=str(_NUM_STACKS),
        )
        ET.SubElement(visual, "map", znear=_fmt(_ZNEAR), zfar=_fmt(_ZFAR))
        light = self.config.lighting
        ET.SubElement(
            visual,
            "headlight",
            ambient=_fmt([light.headlight_ambient] * 3),
            diffuse=_fmt([light.headlight_diffuse] * 3),
            specular="0 0 0",
        )
        default = ET.SubElement(self.root, "default")
        ET.SubElement(default, "geom", contype="0", conaffinity="0")
        self.world = ET.SubElement(self.root, "worldbody")

    def lights(self) -> None:
        assert self.world is not None
        for i, lc in enumerate(self.config.lighting.lights):
            ET.SubElement(
                self.world,
                "light",
                name=f"light_{i}",
                pos=_fmt(lc.position),
                dir=_fmt(lc.direction),
                type="directional",
                castshadow="false",
                diffuse=_fmt([lc.diffuse] * 3),
                specular="0 0 0",
            )

    def room(self, room: RoomConfig) -> None:
        assert self.world is not None
        sx, sy, sz = room.size
        cx, cy = room.center_xy
        body = ET.SubElement(self.world, "body", name="room")
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
            mat = self.material((1, 1, 1, 1), tex or room.wall_texture, face)
            self.geom(
                body,
                name=name,
                type="plane",
                pos=pos,
                xyaxes=axes,
                size=(face[0] / 2, face[1] / 2, max(face)),  # 3rd: grid step -> one quad
                material=mat,
            )

    def table(self, i: int, t: TableConfig) -> None:
        assert self.world is not None
        body = ET.SubElement(self.world, "body", name=f"table_{i}", pos=_fmt((*t.center_xy, 0)))
        top = (t.top_size[0], t.top_size[1])
        mat = self.material(t.rgba, t.texture, top)
        self.geom(
            body,
            name=f"table_{i}_top",
            type="box",
            pos=(0, 0, t.height - t.thickness / 2),
            size=(top[0] / 2, top[1] / 2, t.thickness / 2),
            material=mat,
        )
        leg_h = t.height - t.thickness
        for j, (sx, sy) in enumerate(((1, 1), (1, -1), (-1, 1), (-1, -1))):
            self.geom(
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

    def shelf(self, i: int, s: ShelfConfig) -> None:
        assert self.world is not None
        body = ET.SubElement(
            self.world,
            "body",
            name=f"shelf_{i}",
            pos=_fmt((*s.center_xy, 0)),
            euler=_fmt((0, 0, math.radians(s.yaw_deg))),
        )
        mat = self.material(s.rgba, s.texture, (s.width, s.height))
        t, w, d, h = s.thickness, s.width, s.depth, s.height
        for j, side in enumerate((1, -1)):
            self.geom(
                body,
                name=f"shelf_{i}_side_{j}",
                type="box",
                pos=(0, side * (w / 2 - t / 2), h / 2),
                size=(d / 2, t / 2, h / 2),
                material=mat,
            )
        self.geom(
            body,
            name=f"shelf_{i}_back",
            type="box",
            pos=(d / 2 - t / 2, 0, h / 2),
            size=(t / 2, w / 2 - t, h / 2),
            material=mat,
        )
        for j, level in enumerate(s.levels):
            z = max(level, t) - t / 2
            self.geom(
                body,
                name=f"shelf_{i}_board_{j}",
                type="box",
                pos=(0, 0, z),
                size=(d / 2, w / 2 - t, t / 2),
                material=mat,
            )

    def static_object(self, i: int, o: StaticObjectConfig) -> None:
        assert self.world is not None
        mat = self.material(
            o.rgba, o.texture, _texture_face(o.shape, o.size), cube=o.shape != "box"
        )
        self.geom(
            self.world,
            name=o.name or f"static_{i}",
            type=o.shape,
            pos=o.position,
            euler=tuple(math.radians(a) for a in o.euler_deg),
            size=_half_size(o.shape, o.size),
            material=mat,
        )

    def moving_object(self, k: int, o: MovingObjectConfig) -> None:
        assert self.world is not None
        name = object_body_name(k)
        body = ET.SubElement(
            self.world,
            "body",
            name=name,
            mocap="true",
            pos=_fmt(_initial_position(o.trajectory)),
        )
        mat = self.material(
            o.rgba, o.texture, _texture_face(o.shape, o.size), cube=o.shape != "box"
        )
        self.geom(body, name=name, type=o.shape, size=_half_size(o.shape, o.size), material=mat)

    def camera_position(self) -> tuple[float, float, float]:
        p = self.config.ptu
        x, y, z = p.position
        return (x + p.camera_forward_m, y, z + p.camera_up_m)

    def gratings(self, g: GratingConfig) -> None:
        assert self.world is not None
        cam = self.config.camera
        layout = grating_layout(
            g,
            self.camera_position(),
            cam.hfov_deg,
            vertical_fov_deg(cam.hfov_deg, cam.width, cam.height),
        )
        # background: one period per texture image, tiled; a self-luminous plane
        img = grating(8, _GRATING_TEXELS, _GRATING_TEXELS, 0.0, g.profile, g.contrast, g.mean)
        file = add_png_asset(self.assets, "grating_background", img)
        ET.SubElement(self.asset, "texture", name="grating_background", type="2d", file=file)
        ET.SubElement(
            self.asset,
            "material",
            name="grating_background",
            texture="grating_background",
            texrepeat=_fmt((layout.background_periods, 1)),
            rgba="1 1 1 1",
            emission="1",
            specular="0",
            shininess="0",
            reflectance="0",
        )
        ET.SubElement(
            self.asset,
            "material",
            name="grating_strip",
            rgba="0.5 0.5 0.5 1",
            emission="1",
            specular="0",
            shininess="0",
            reflectance="0",
        )
        bg = ET.SubElement(
            self.world, "body", name=GRATING_BACKGROUND_BODY, mocap="true", pos=_fmt(layout.center)
        )
        hw, hh = layout.screen_half_width_m, layout.screen_half_height_m
        self.geom(
            bg,
            name="grating_screen",
            type="plane",
            xyaxes=(0, -1, 0, 0, 0, 1),  # local x = image right, normal towards the camera
            size=(hw, hh, 2 * max(hw, hh)),
            material="grating_background",
        )
        # central patch: vertical strips, coloured at run time by SceneAnimator
        cx, cy, cz = layout.center
        patch = ET.SubElement(
            self.world, "body", name=object_body_name(1), pos=_fmt((cx - SCREEN_GAP_M, cy, cz))
        )
        strip_w = layout.object_side_m / len(layout.strip_offsets_m)
        _, level = grating_state(g, layout, 0.0)
        for j, (x, v) in enumerate(zip(layout.strip_offsets_m, level, strict=True)):
            self.geom(
                patch,
                name=f"{GRATING_STRIP_PREFIX}{j}",
                type="box",
                pos=(0, -x, 0),  # image right = world -y
                size=(SCREEN_GAP_M / 4, strip_w / 2, layout.object_side_m / 2),
                material="grating_strip",
                rgba=(v, v, v, 1.0),
            )

    def ptu(self) -> None:
        assert self.world is not None
        p, cam = self.config.ptu, self.config.camera
        grey = self.material((0.2, 0.2, 0.22, 1))
        base = ET.SubElement(self.world, "body", name=PTU_BASE_BODY, pos=_fmt(p.position))
        g = str(PTU_GEOM_GROUP)
        self.geom(
            base, type="cylinder", pos=(0, 0, -0.12), size=(0.04, 0.03), material=grey, group=g
        )
        pan = ET.SubElement(base, "body", name=PAN_BODY)
        ET.SubElement(pan, "inertial", pos="0 0 0", mass="0.5", diaginertia="1e-3 1e-3 1e-3")
        ET.SubElement(pan, "joint", name=PAN_JOINT, type="hinge", axis="0 0 1")
        self.geom(
            pan, type="box", pos=(0, 0, -0.06), size=(0.03, 0.05, 0.03), material=grey, group=g
        )
        tilt = ET.SubElement(pan, "body", name=TILT_BODY)
        ET.SubElement(tilt, "inertial", pos="0 0 0", mass="0.2", diaginertia="1e-4 1e-4 1e-4")
        ET.SubElement(tilt, "joint", name=TILT_JOINT, type="hinge", axis="0 -1 0")
        cam_pos = (p.camera_forward_m, 0.0, p.camera_up_m)
        self.geom(
            tilt,
            type="box",
            pos=(cam_pos[0] - 0.03, 0, cam_pos[2]),
            size=(0.025, 0.025, 0.025),
            material=grey,
            group=g,
        )
        ET.SubElement(
            tilt,
            "camera",
            name=CAMERA_NAME,
            pos=_fmt(cam_pos),
            xyaxes="0 -1 0 0 0 1",  # image right = -y, image up = +z, looking along +x
            fovy=_fmt(vertical_fov_deg(cam.hfov_deg, cam.width, cam.height)),
        )

    def build(self) -> MJCFScene:
        c = self.config
        self.header()
        self.lights()
        if c.room is not None:
            self.room(c.room)
        for i, t in enumerate(c.tables):
            self.table(i, t)
        for i, s in enumerate(c.shelves):
            self.shelf(i, s)
        for i, o in enumerate(c.static_objects):
            self.static_object(i, o)
        for k, o in enumerate(c.moving_objects, start=1):
            self.moving_object(k, o)
        if c.gratings is not None:
            self.gratings(c.gratings)
        self.ptu()
        ET.indent(self.root)
        return MJCFScene(ET.tostring(self.root, encoding="unicode"), self.assets, c)


def build_mjcf(config: SceneConfig) -> MJCFScene:
    """The MJCF XML and assets for ``config`` (deterministic)."""
    return _Builder(config).build()


def compile_scene(config: SceneConfig) -> mujoco.MjModel:
    """``build_mjcf(config).compile()``."""
    return build_mjcf(config).compile()


def geom_object_ids(model: mujoco.MjModel) -> np.ndarray:
    """Object id per geom, (ngeom,) int32: k for geoms of body ``object_k``, else 0."""
    ids = np.zeros(model.ngeom, dtype=np.int32)
    for g in range(model.ngeom):
        ids[g] = object_index(model.body(int(model.geom_bodyid[g])).name)
    return ids


def geom_layer_ids(model: mujoco.MjModel) -> np.ndarray:
    """Motion layer per geom, (ngeom,) int32: 0 static, k object k, and ``n + 1`` for
    the gratings screen (it slides) when the model has one (``n`` = objects).

    A layer moves rigidly: see :meth:`SceneAnimator.layer_positions`.
    """
    ids = geom_object_ids(model)
    bg = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, GRATING_BACKGROUND_BODY)
    if bg >= 0:
        ids[np.asarray(model.geom_bodyid) == bg] = int(ids.max(initial=0)) + 1
    return ids


# ----------------------------------------------------------------------------------------
# Runtime


class SceneAnimator:
    """Moves a compiled scene's objects to their state at time t.

    Builds one trajectory per moving object (random walks draw from ``rng``, in object
    order) and, for the gratings scene, slides the background and recolours the patch
    strips. :meth:`apply` writes ``data.mocap_pos`` and ``model.geom_rgba``; call
    ``mujoco.mj_forward`` (or ``mj_kinematics``) afterwards, before rendering.
    """

    def __init__(
        self, model: mujoco.MjModel, config: SceneConfig, rng: np.random.Generator | None = None
    ) -> None:
        self.model = model
        self.config = config
        rng = rng if rng is not None else np.random.default_rng(0)
        self.trajectories: tuple[Trajectory, ...] = tuple(
            make_trajectory(o.trajectory, rng) for o in config.moving_objects
        )
        self._mocap = np.array(
            [
                model.body_mocapid[model.body(object_body_name(k)).id]
                for k in range(1, len(config.moving_objects) + 1)
            ],
            dtype=int,
        )
        self._positions: dict[float, np.ndarray] = {}  # recent times' object positions
        self._layout: GratingLayout | None = None
        if config.gratings is not None:
            cam = config.camera
            p = config.ptu
            self._layout = grating_layout(
                config.gratings,
                (p.position[0] + p.camera_forward_m, p.position[1], p.position[2] + p.camera_up_m),
                cam.hfov_deg,
                vertical_fov_deg(cam.hfov_deg, cam.width, cam.height),
            )
            self._bg_mocap = int(model.body_mocapid[model.body(GRATING_BACKGROUND_BODY).id])
            n = config.gratings.object_strips
            self._strips = np.array(
                [model.geom(f"{GRATING_STRIP_PREFIX}{j}").id for j in range(n)], dtype=int
            )

    def object_positions(self, t: float) -> np.ndarray:
        """(n_objects, 3) world positions (m) of the moving objects at time t (read-only:
        recent times' positions are kept, as posing, views and ground truth ask for the
        same times several times)."""
        cache = self._positions
        pos = cache.get(t)
        if pos is not None:
            return pos
        if not self.trajectories:
            pos = np.zeros((0, 3))
        else:
            pos = np.stack([tr.position(t) for tr in self.trajectories])
        pos.setflags(write=False)
        if len(cache) >= 64:
            cache.clear()
        cache[t] = pos
        return pos

    def layer_positions(self, t: float) -> np.ndarray:
        """(layers, 3) world positions (m) of what each motion layer shows at time t.

        Row 0 (the static world) is zero; row k is object k's position; with gratings,
        row 1 is the patch's content (its bars drift inside the fixed patch) and row 2 the
        screen's, both unwrapped (no jump back by a period): between two times a
        layer's content moves rigidly by the difference of its rows (see
        :func:`geom_layer_ids`).
        """
        g = self.config.gratings
        if g is None or self._layout is None:
            return np.concatenate([np.zeros((1, 3)), self.object_positions(t)])
        v_b, v_o = (v * g.metres_per_deg for v in g.effective_speeds_deg_s())
        right = np.array([0.0, -1.0, 0.0])  # image right is world -y
        return np.stack([np.zeros(3), v_o * t * right, v_b * t * right])

    def apply(self, data: mujoco.MjData, t: float) -> None:
        """Set mocap positions (and grating colours) for time t (s)."""
        if len(self._mocap):
            data.mocap_pos[self._mocap] = self.object_positions(t)
        g = self.config.gratings
        if g is not None and self._layout is not None:
            slide, level = grating_state(g, self._layout, t)
            cx, cy, cz = self._layout.center
            data.mocap_pos[self._bg_mocap] = (cx, cy - slide, cz)
            self.model.geom_rgba[self._strips, :3] = level[:, None]
