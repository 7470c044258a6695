"""The scene's MJCF arena: it composes the entities of a scene config, and
:class:`SceneAnimator` runs their runtimes.

:class:`Arena` lists the scene's parts as entities (:mod:`wander_env.entities`, one per
part, each owning its MJCF fragment) in document order: lights, room, tables, shelves,
static props, moving props, the gratings stimulus, the pan-tilt camera. It writes the
document's header itself (compiler, options, visual quality, headlight) and lets each
entity attach its fragment. :func:`build_mjcf` returns the XML string plus an assets
dict (procedural textures as in-memory PNGs, mesh files' bytes) and the MJCF includes;
:func:`compile_scene` compiles it to a ``mujoco.MjModel`` through ``mujoco.MjSpec``,
attaching the included files' bodies. The env (the task) owns timing: it calls
:meth:`SceneAnimator.apply` with the time it wants shown.

What the model holds (and which entity writes it):

- **The pan-tilt unit** (:class:`~wander_env.entities.PanTiltCamera`; the PTU frame of
  :mod:`wander_env.ptu`: x forward, y left, z up): body ``ptu_base`` at
  ``config.ptu.position`` (the tilt hinge); body ``ptu_pan`` with hinge ``pan`` about
  world z (positive turns left); body ``ptu_tilt`` with hinge ``tilt`` about -y
  (positive raises the optical axis); the camera ``event_camera`` on the tilt body,
  ``camera_forward_m`` ahead of and ``camera_up_m`` above the hinge (the unit's
  :class:`~wander_env.ptu.params.PTUParams`, given to :func:`build_mjcf`; the scene holds
  only where the unit stands), looking along +x at pan = tilt = 0, image x to the right
  (world -y), image y down. No actuators: the env writes the PTU model's angles
  (radians) to ``qpos`` and calls ``mj_forward`` (or ``mj_kinematics``) before rendering.
  Gravity is off and nothing collides, so ``mj_step`` moves nothing by itself. The
  PTU's own geoms are in group 3, which the camera does not render.
- **The camera's field of view**: ``fovy`` is the vertical FOV for the configured
  horizontal FOV and aspect (112.83° both ways for the 128 × 128 Speck).
- **Moving objects** (:class:`~wander_env.entities.MovingProp`): mocap bodies
  ``object_1`` .. ``object_n`` (1-based, config order), one geom each named like its
  body (a primitive or a mesh); their segmentation id is k; :func:`geom_layer_radii`
  bounds each from the compiled model.
- **Included MJCF bodies** (:class:`~wander_env.entities.MJCFInclude`): under a frame
  ``NAME``, their names prefixed ``NAME/``, no joints; segmentation id 0.
- **The gratings screen** (:class:`~wander_env.entities.GratingStimulus`,
  ``config.gratings``): a self-luminous (emission 1) plane on mocap body
  ``grating_background`` textured with one background period tiled across it; it
  slides sideways by (speed · t) mod period, which drifts the bars seamlessly. The
  central patch is body ``object_1``: ``object_strips`` vertical strips (each narrower
  than a pixel) 2 mm in front of the screen, whose colours :class:`SceneAnimator` sets
  every frame from the object grating's phase, so its bars drift inside a fixed window.
  In ``eye-only`` mode the strips show the background grating in phase (the screen
  drifts as one); in ``object-only`` the background stays still. Keep the scene's
  lights off for exact grating intensities.
- **Headless-friendly visuals** (the arena's header): offscreen buffer ≥ the image, no
  shadow map (``shadowsize 0``), no skybox, no reflectance, planes and box faces drawn
  as single quads, coarser sphere/cylinder tessellation, multisampling from
  ``config.camera.antialias_samples``. At compile, every static untextured cylinder
  becomes a mesh of the faces MuJoCo draws for it (:func:`cylinders_as_prisms`): the same
  pixels from a fourteenth of the triangles.

The names (:data:`~wander_env.entities.PAN_JOINT`,
:func:`~wander_env.entities.object_body_name`, ...) live in :mod:`wander_env.entities`,
with the parts they name; the document the parts write into in
:mod:`wander_env.mjcf_document`, the gratings screen's geometry in
:mod:`wander_env.grating_geometry`.

Examples:
    >>> from wander_env.scenes import load_scene_config
    >>> arena = Arena(load_scene_config("office"))
    >>> [type(e).__name__ for e in arena.entities][:4], type(arena.entities[-1]).__name__
    (['Lights', 'Room', 'Table', 'Shelf'], 'PanTiltCamera')
    >>> from wander_env.camera import CAMERA_NAME
    >>> model = compile_scene(load_scene_config("shelf"))
    >>> model.camera(CAMERA_NAME).id >= 0, model.nmocap
    (True, 0)
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable
from dataclasses import dataclass

import mujoco
import numpy as np

from wander_env.entities import (
    GRATING_BACKGROUND_BODY,
    Entity,
    GratingMotion,
    GratingStimulus,
    Lights,
    MJCFInclude,
    MovingProp,
    PanTiltCamera,
    PropMotion,
    Room,
    Shelf,
    StaticProp,
    Table,
    object_index,
)
from wander_env.mjcf_document import MJCFDocument
from wander_env.ptu.params import PTUParams
from wander_env.scene_config import SceneConfig
from wander_env.trajectories import Trajectory, positions_at
from wander_env.untrusted import check_model_size

__all__ = [
    "Arena",
    "MJCFScene",
    "SceneAnimator",
    "build_mjcf",
    "compile_scene",
    "cylinders_as_prisms",
    "geom_layer_ids",
    "geom_layer_radii",
    "geom_object_ids",
    "prism_mesh",
]

_STATISTIC_EXTENT = 4.0  # m; with znear/zfar: near clip 2 cm, far clip 40 m
_ZNEAR = 0.005
_ZFAR = 10.0
# Tessellation of spheres/cylinders: a 20-gon's silhouette is within 1.2 % of the radius
# (0.2 px on a 30 px ball); MuJoCo's 28 x 16 costs ~1 ms more a frame on llvmpipe.
_NUM_SLICES = 20
_NUM_STACKS = 10


def prism_mesh(
    radius: float, half_height: float, slices: int = _NUM_SLICES
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The cylinder MuJoCo draws (``slices`` sides, its vertices on the same angles, axis
    along z) as a mesh of its faces alone: (vertices (V, 3), their normals (V, 3), faces
    (F, 3) counter-clockwise seen from outside). The side is one stack of quads with
    radial normals, each cap a fan with normal ±z: ``4 * slices`` triangles.

    >>> v, n, f = prism_mesh(0.5, 1.0, slices=4)
    >>> v.shape, f.shape, float(v[:, 2].max())
    ((18, 3), (16, 3), 1.0)
    >>> bool(np.allclose(np.linalg.norm(n, axis=1), 1.0))
    True
    """
    angles = 2.0 * np.pi * np.arange(slices) / slices
    c, s = np.cos(angles), np.sin(angles)
    j = np.arange(slices)
    nxt = (j + 1) % slices
    top, bottom = j, slices + j  # the side's two rims
    side_v = np.r_[
        np.c_[radius * c, radius * s, np.full(slices, half_height)],
        np.c_[radius * c, radius * s, np.full(slices, -half_height)],
    ]
    side_n = np.tile(np.c_[c, s, np.zeros(slices)], (2, 1))
    side_f = np.r_[np.c_[top, bottom, bottom[nxt]], np.c_[top, bottom[nxt], top[nxt]]]
    vertices, normals, faces = [side_v], [side_n], [side_f]
    first = 2 * slices
    for sign in (1.0, -1.0):  # each cap: its centre, then its rim
        z = sign * half_height
        vertices.append(np.r_[[[0.0, 0.0, z]], np.c_[radius * c, radius * s, np.full(slices, z)]])
        normals.append(np.tile([0.0, 0.0, sign], (slices + 1, 1)))
        rim, rim_next = first + 1 + j, first + 1 + nxt
        centre = np.full(slices, first)
        faces.append(np.c_[centre, rim, rim_next] if sign > 0 else np.c_[centre, rim_next, rim])
        first += slices + 1
    return np.concatenate(vertices), np.concatenate(normals), np.concatenate(faces)


def cylinders_as_prisms(spec: mujoco.MjSpec) -> int:
    """Make each static, untextured cylinder of ``spec`` a mesh geom of its faces alone
    (:func:`prism_mesh`): 80 triangles where MuJoCo's cylinder has about 1,100 (its side
    in ``_NUM_STACKS`` stacks, each cap in as many rings). Under the scenes' directional
    lights a flat face needs no subdivision: on the office and the shelf at five pans,
    every pixel is the same, and a colour key draws in 1.17–1.22 ms against 1.49–1.58 ms.

    Left as they are: the moving objects' cylinders (the ray caster intersects them as
    cylinders), textured ones (these meshes carry no texture coordinates) and ones given
    by ``fromto``. Returns how many were made meshes.
    """
    textured = {m.name for m in spec.materials if any(m.textures)}
    made = 0
    for geom in spec.geoms:
        body = geom.parent.name
        if (
            geom.type != mujoco.mjtGeom.mjGEOM_CYLINDER
            or object_index(body) > 0
            or body == GRATING_BACKGROUND_BODY
            or geom.material in textured
            or not np.isnan(geom.fromto[0])
        ):
            continue
        vertices, normals, faces = prism_mesh(geom.size[0], geom.size[1])
        mesh = spec.add_mesh()
        mesh.name = f"wander_cylinder_prism_{made}"
        mesh.uservert = vertices.ravel().tolist()
        mesh.usernormal = normals.ravel().tolist()
        mesh.userface = faces.ravel().tolist()
        geom.type = mujoco.mjtGeom.mjGEOM_MESH
        geom.meshname = mesh.name
        made += 1
    return made


# ----------------------------------------------------------------------------------------
# The arena


@dataclass
class MJCFScene:
    """An MJCF document: XML text, its in-memory assets, the MJCF files it includes
    (attached when it compiles), and the config it came from."""

    xml: str
    assets: dict[str, bytes]
    config: SceneConfig
    includes: tuple[MJCFInclude, ...] = ()

    def compile(self) -> mujoco.MjModel:
        """Compile to a ``mujoco.MjModel`` (with the included files' bodies)."""
        spec = mujoco.MjSpec.from_string(self.xml, assets=self.assets)
        assets = dict(self.assets)
        for include in self.includes:
            include.attach_spec(spec)
            assets.update(include.include.assets(include.prefix))
        spec.assets = assets
        cylinders_as_prisms(spec)
        model = spec.compile()
        check_model_size(model, f"scene {self.config.name!r}")
        return model


class Arena:
    """A scene's entities in document order, and the header they share.

    ``entities`` are the :class:`~wander_env.entities.Lights`, the room (if any),
    tables, shelves, static props, moving props (``moving_props``, object order), the
    gratings stimulus (``gratings``, if any) and the pan-tilt camera (``ptu``: the scene's
    mount, with the camera where ``ptu_params``, the unit's parameters, put it on the
    hinge; None: an ideal unit, the camera on the hinge).
    """

    def __init__(self, config: SceneConfig, ptu_params: PTUParams | None = None) -> None:
        self.config = config
        self.ptu = PanTiltCamera(
            config.ptu, config.camera, ptu_params if ptu_params is not None else PTUParams()
        )
        self.moving_props = tuple(
            MovingProp(k, o) for k, o in enumerate(config.moving_objects, start=1)
        )
        g = config.gratings
        self.gratings = GratingStimulus(g, self.ptu) if g is not None else None
        self.includes = tuple(MJCFInclude(i, inc) for i, inc in enumerate(config.mjcf_includes))
        self.entities: tuple[Entity, ...] = (
            Lights(config.lighting),
            *((Room(config.room),) if config.room is not None else ()),
            *(Table(i, t) for i, t in enumerate(config.tables)),
            *(Shelf(i, s) for i, s in enumerate(config.shelves)),
            *(StaticProp(i, o) for i, o in enumerate(config.static_objects)),
            *self.moving_props,
            *((self.gratings,) if self.gratings is not None else ()),
            self.ptu,
        )

    def _header(self, doc: MJCFDocument) -> None:
        cam, light = self.config.camera, self.config.lighting
        root = doc.root
        doc.element(root, "compiler", angle="radian", autolimits="true")
        doc.element(root, "option", timestep="0.001", gravity="0 0 0")
        doc.element(root, "statistic", extent=_STATISTIC_EXTENT, center=(1.0, 0, 1.0))
        visual = doc.element(root, "visual")
        doc.element(
            visual, "global", offwidth=str(max(cam.width, 128)), offheight=str(max(cam.height, 128))
        )
        doc.element(
            visual,
            "quality",
            shadowsize="0",  # no shadow map
            offsamples=str(cam.antialias_samples),
            numquads="1",  # flat faces as single quads (lights are directional)
            numslices=str(_NUM_SLICES),
            numstacks=str(_NUM_STACKS),
        )
        doc.element(visual, "map", znear=_ZNEAR, zfar=_ZFAR)
        doc.element(
            visual,
            "headlight",
            ambient=[light.headlight_ambient] * 3,
            diffuse=[light.headlight_diffuse] * 3,
            specular="0 0 0",
        )
        default = doc.element(root, "default")
        doc.element(default, "geom", contype="0", conaffinity="0")

    def build(self) -> MJCFScene:
        """The header, then every entity's fragment (deterministic)."""
        doc = MJCFDocument(self.config.name)
        self._header(doc)
        doc.open_world()
        for entity in self.entities:
            entity.attach(doc)
        return MJCFScene(doc.text(), doc.assets, self.config, self.includes)


def build_mjcf(config: SceneConfig, ptu_params: PTUParams | None = None) -> MJCFScene:
    """The MJCF XML and assets for ``config`` with the camera where the unit's parameters
    ``ptu_params`` put it on the hinge (None: on the hinge) (deterministic)."""
    return Arena(config, ptu_params).build()


def compile_scene(config: SceneConfig, ptu_params: PTUParams | None = None) -> mujoco.MjModel:
    """``build_mjcf(config, ptu_params).compile()``."""
    return build_mjcf(config, ptu_params).compile()


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


def geom_layer_radii(model: mujoco.MjModel) -> np.ndarray:
    """Bounding radius (m) of each motion layer about its position, (layers,) float64:
    for object k the farthest its geoms reach from body ``object_k``'s origin (a geom's
    distance plus its bounding-sphere radius: meshes included); ``inf`` for the static
    world and, in a gratings model, for every layer (a sliding screen has no bound).

    >>> from wander_env.scenes import load_scene_config
    >>> geom_layer_radii(compile_scene(load_scene_config("office"))).round(4).tolist()
    [inf, 0.2078, 0.28]
    """
    layers = geom_layer_ids(model)
    radii = np.full(int(layers.max(initial=0)) + 1, np.inf)
    if mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, GRATING_BACKGROUND_BODY) >= 0:
        return radii
    reach = np.linalg.norm(model.geom_pos, axis=1) + model.geom_rbound
    for k in range(1, len(radii)):
        radii[k] = reach[layers == k].max()
    return radii


# ----------------------------------------------------------------------------------------
# Runtime


class SceneAnimator:
    """Moves a compiled scene's objects to their state at time t.

    Builds each moving prop's runtime (:class:`~wander_env.entities.PropMotion`; random
    walks draw from ``rng``, in object order) and, for the gratings scene, the
    stimulus's (:class:`~wander_env.entities.GratingMotion`: slides the background and
    recolours the patch strips). :meth:`apply` writes ``data.mocap_pos`` and
    ``model.geom_rgba``; call ``mujoco.mj_forward`` (or ``mj_kinematics``) afterwards,
    before rendering.
    """

    def __init__(
        self, model: mujoco.MjModel, config: SceneConfig, rng: np.random.Generator | None = None
    ) -> None:
        self.model = model
        self.config = config
        rng = rng if rng is not None else np.random.default_rng(0)
        arena = Arena(config)
        self.motions: tuple[PropMotion, ...] = tuple(
            p.motion(model, rng) for p in arena.moving_props
        )
        # the props' mocap slots, in object order (one vectorised write per pose)
        self._mocap = np.array([m.mocap_id for m in self.motions], dtype=int)
        self._positions: dict[float, np.ndarray] = {}  # recent times' object positions
        self._gratings: GratingMotion | None = (
            arena.gratings.motion(model) if arena.gratings is not None else None
        )

    @property
    def trajectories(self) -> tuple[Trajectory, ...]:
        """One trajectory per moving object (object order); assign to replace them."""
        return tuple(m.trajectory for m in self.motions)

    @trajectories.setter
    def trajectories(self, trajectories: Iterable[Trajectory]) -> None:
        new = tuple(trajectories)
        if len(new) != len(self.motions):
            raise ValueError(f"trajectories: need {len(self.motions)}, got {len(new)}")
        self.motions = tuple(
            dataclasses.replace(m, trajectory=tr) for m, tr in zip(self.motions, new, strict=True)
        )
        self._positions.clear()

    def object_positions(self, t: float) -> np.ndarray:
        """(n_objects, 3) world positions (m) of the moving objects at time t (read-only:
        recent times' positions are kept, as posing, views and ground truth ask for the
        same times several times)."""
        cache = self._positions
        pos = cache.get(t)
        if pos is not None:
            return pos
        if not self.motions:
            pos = np.zeros((0, 3))
        else:
            pos = np.stack([m.position(t) for m in self.motions])
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
        if self._gratings is None:
            return np.concatenate([np.zeros((1, 3)), self.object_positions(t)])
        return self._gratings.stimulus.layer_positions(t)

    def layer_positions_at(self, times_s: np.ndarray) -> np.ndarray:
        """(T, layers, 3) :meth:`layer_positions` at each of ``times_s`` (the same numbers;
        the objects' closed forms evaluated for all times at once where they allow it)."""
        times_s = np.asarray(times_s, float)
        if self._gratings is not None:
            return np.stack([self._gratings.stimulus.layer_positions(t) for t in times_s])
        out = np.zeros((len(times_s), len(self.motions) + 1, 3))
        for k, m in enumerate(self.motions, 1):
            out[:, k] = positions_at(m.trajectory, times_s)
        return out

    def apply(self, data: mujoco.MjData, t: float) -> None:
        """Set mocap positions (and grating colours) for time t (s)."""
        if len(self._mocap):
            data.mocap_pos[self._mocap] = self.object_positions(t)
        if self._gratings is not None:
            self._gratings.apply(data, t)
