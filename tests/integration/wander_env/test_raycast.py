"""Ground truth and key geometry by ray casting (wander_env.frames.raycast) against the GL pass."""

from __future__ import annotations

import os

os.environ.setdefault("MUJOCO_GL", "egl")  # before mujoco is imported: headless rendering

import math

import gymnasium as gym
import mujoco
import numpy as np
import pytest
from scene_files import write_cube_obj

import wander_env  # noqa: F401  (registers the envs)
from wander_env.camera import intrinsics
from wander_env.frames.raycast import (
    PrimitiveCaster,
    RaycastParams,
    cast_layers,
    unsupported_geoms,
)
from wander_env.frames.stage import Stage
from wander_env.gl_process import ForkedGLError
from wander_env.mjcf import SceneAnimator, build_mjcf
from wander_env.ptu.params import PTUParams
from wander_env.renderer import RenderParams
from wander_env.scenes import load_scene_config, scene_config_from_dict

SPHERE, CAPSULE, CYLINDER, BOX = (
    int(getattr(mujoco.mjtGeom, n))
    for n in ("mjGEOM_SPHERE", "mjGEOM_CAPSULE", "mjGEOM_CYLINDER", "mjGEOM_BOX")
)


def _cast(gtype, size, pos, mat=None, far=100.0, n=9, fovy=90.0):
    """One geom cast from the origin looking along +z (camera axes = world axes) into an
    ``n × n`` image before a static wall ``far`` m away."""
    k = intrinsics(n, n, fovy)
    layers = np.empty((n, n), np.int32)
    depth = np.empty((n, n))
    rho = np.full((n, n), 1.0 / far)
    mat = np.eye(3) if mat is None else np.asarray(mat, float)
    size = np.array([list(size) + [0.0] * (3 - len(size))], float)
    rbound = float(np.linalg.norm(size[0])) * 2
    args = (np.eye(3), np.zeros(3), np.zeros(3), k[0, 0], k[0, 2], k[1, 2], 0.02)
    geoms = (np.array([gtype]), size, np.array([pos], float), mat[None], np.array([rbound]))
    cast_layers(layers, depth, rho, *args, *geoms, np.array([3], np.int32))
    return layers, depth, k


def test_the_kernel_meets_each_primitive_where_geometry_says():
    """Rays from the origin along +z (pixel centres: x = (i - 4) / f, f = 4.5 px at 90°
    over 9 px): each primitive's near surface at its exact depth on the centre ray, and
    the first pixels off its silhouette hit the wall behind (label 0, depth 100)."""
    # Sphere r = 0.5 at z = 2: the centre ray at 1.5; pixel i hits iff |x| f-ray passes
    # within 0.5 of the centre: (i - 4) / 4.5 * 2 < 0.5 / cos -> |i - 4| <= 1.
    layers, depth, _ = _cast(SPHERE, [0.5], [0, 0, 2])
    assert depth[4, 4] == pytest.approx(1.5, abs=1e-12) and layers[4, 4] == 3
    assert layers[4].tolist() == [0, 0, 0, 3, 3, 3, 0, 0, 0] and depth[4, 0] == pytest.approx(100)
    # Box half-sizes (0.5, 0.5, 0.25) at z = 2: its face at 1.75; x / z <= 0.5 / 1.75.
    layers, depth, _ = _cast(BOX, [0.5, 0.5, 0.25], [0, 0, 2])
    assert depth[4, 4] == pytest.approx(1.75, abs=1e-12)
    assert layers[4].tolist() == [0, 0, 0, 3, 3, 3, 0, 0, 0]
    # The box turned 45° about y: its edge towards the camera at 2 - 0.5·√2·... (x = 0).
    c, s = math.cos(math.pi / 4), math.sin(math.pi / 4)
    turned = [[c, 0, s], [0, 1, 0], [-s, 0, c]]
    _, depth, _ = _cast(BOX, [0.5, 0.5, 0.5], [0, 0, 2], turned)
    assert depth[4, 4] == pytest.approx(2 - math.sqrt(0.5), abs=1e-12)
    # Cylinder r = 0.5, half-length 1 along its local z, laid along the image's y axis
    # (local z = world y): the centre ray meets its side at 1.5; a column of hits.
    along_y = [[1, 0, 0], [0, 0, -1], [0, 1, 0]]
    layers, depth, _ = _cast(CYLINDER, [0.5, 1.0], [0, 0, 2], along_y)
    assert depth[4, 4] == pytest.approx(1.5, abs=1e-12)
    assert layers[:, 4].tolist() == [0] + [3] * 7 + [0]  # |y| f-ray * z <= 1 at z ~ 1.5-2
    # Seen end on (its axis along the ray), its flat cap at 2 - 1 = 1.
    _, depth, _ = _cast(CYLINDER, [0.5, 1.0], [0, 0, 2])
    assert depth[4, 4] == pytest.approx(1.0, abs=1e-12)
    # Capsule end on: the hemisphere's pole at 2 - 1 - 0.5 = 0.5; the next pixel's ray
    # (0.222, 0, 1) meets that hemisphere (centre z = 1) where 1.0494 t² - 2t + 0.75 = 0.
    _, depth, _ = _cast(CAPSULE, [0.5, 1.0], [0, 0, 2.0])
    assert depth[4, 4] == pytest.approx(0.5, abs=1e-12)
    a = 1 + (1 / 4.5) ** 2
    assert depth[4, 5] == pytest.approx((2 - math.sqrt(4 - 3 * a)) / (2 * a), abs=1e-12)
    # Across: the side at 1.5, as the cylinder's.
    _, depth, _ = _cast(CAPSULE, [0.5, 1.0], [0, 0, 2], along_y)
    assert depth[4, 4] == pytest.approx(1.5, abs=1e-12)


def test_near_clip_and_static_occlusion():
    """A hit nearer than the near plane (0.02 m) does not count (the ray's exit does: GL
    clips the near side away); a static wall in front hides the object."""
    _, depth, _ = _cast(SPHERE, [0.5], [0, 0, 0.3])  # near side at -0.2: clipped
    assert depth[4, 4] == pytest.approx(0.8, abs=1e-12)
    layers, depth, _ = _cast(SPHERE, [0.5], [0, 0, 2], far=1.2)
    assert not layers.any() and np.allclose(depth, 1.2)


def _stage(name: str, **hinge) -> Stage:
    cfg = load_scene_config(name)
    stage = Stage(build_mjcf(cfg, PTUParams(**hinge)).compile(), cfg, RenderParams())
    stage.begin_episode(SceneAnimator(stage.model, cfg, np.random.default_rng(0)))
    return stage


def _rim(*masks: np.ndarray) -> np.ndarray:
    """Pixels with a 4-neighbour of another id in any of ``masks``."""
    out = np.zeros(masks[0].shape, bool)
    for m in masks:
        p = np.pad(m, 1, mode="edge")
        for dy, dx in ((0, 1), (1, 0), (0, -1), (-1, 0)):
            out |= p[1 + dy : 1 + dy + m.shape[0], 1 + dx : 1 + dx + m.shape[1]] != m
    return out


POSES = [
    (t, a) for t in (0, 130_000, 370_000, 810_000) for a in ((0, 0), (20, -8), (-35, 12), (10, -25))
]


@pytest.mark.slow
@pytest.mark.parametrize("scene", ["office", "hand", "shelf"])
def test_the_cast_mask_and_depth_match_the_gl_pass_but_for_rim_pixels(scene):
    """Office, hand, shelf at 4 times × 4 gazes: the cast mask is the GL segmentation's
    but for at most 2 % of the mask's pixels (office measured: 10-38 of 1,057-2,692), each
    with a neighbour of another id; on object pixels inside both masks (rims excluded) the
    depth is GL's within 1e-4 on boxes (the GL depth buffer's precision) and, on spheres
    and cylinders (GL draws them as 20-gons), within 1.5 % at the median and 6 % at
    most (the facets' sagitta, largest at grazing rays); the static world's depth (from
    the cube) within 0.5 % at the median."""
    stage = _stage(scene)
    caster = stage.caster
    assert caster is not None and caster.exact_depth
    box = np.isin(np.arange(stage.model.ngeom), np.flatnonzero(stage.model.geom_type == BOX))
    box_layers = set(stage.layer_lut[box & (stage.layer_lut > 0)].tolist())
    try:
        for t_us, (pan, tilt) in POSES:
            stage.pose(t_us, pan, tilt)
            gl = stage.renderer.segment(stage.draw_data)
            mask = stage.object_mask()
            _, gl_depth = stage.renderer.segment_depth_current(stage.layer_lut)
            layers, depth = caster.geometry(stage.draw_data)
            assert np.array_equal(mask, layers)
            diff = gl != mask
            assert diff.sum() <= 0.02 * max((gl > 0).sum(), 1)
            assert not (diff & ~_rim(gl, mask)).any()
            inner = ~_rim(gl, mask)
            for k in range(1, int(stage.layer_lut.max()) + 1):
                on = inner & (gl == k) & (mask == k)
                if not on.any():
                    continue
                rel = np.abs(depth[on] - gl_depth[on]) / gl_depth[on]
                if k in box_layers:
                    assert rel.max() <= 1e-4
                else:
                    assert np.median(rel) <= 0.015 and rel.max() <= 0.06
            static = inner & (gl == 0) & (mask == 0)
            assert np.median(np.abs(depth[static] - gl_depth[static]) / gl_depth[static]) <= 5e-3
    finally:
        stage.close()


@pytest.mark.slow
def test_a_hinge_offset_casts_masks_from_the_true_centre_and_keeps_gl_key_geometry():
    """Office with the camera 5 cm ahead of and 3 cm above its tilt hinge: the static cube
    is rendered from the hinge, each hit point is found from the camera's own centre and
    looked up in the cube along the hinge's ray. The mask is GL's but for rim pixels
    (≤ 2 %); the keys' layers and depth stay GL's (the static world's depth seen from the
    camera is not the cube's), so geometry() by ray casting refuses."""
    stage = _stage("office", camera_forward_m=0.05, camera_up_m=0.03)
    caster = stage.caster
    try:
        assert caster is not None and not caster.exact_depth
        assert stage.casts("ground_truth") and not stage.casts("key_layers")
        for t_us, (pan, tilt) in POSES:
            stage.pose(t_us, pan, tilt)
            gl = stage.renderer.segment(stage.draw_data)
            mask = stage.object_mask()
            diff = gl != mask
            assert diff.sum() <= 0.02 * max((gl > 0).sum(), 1)
            assert not (diff & ~_rim(gl, mask)).any()
        with pytest.raises(ValueError, match="camera on its hinge"):
            caster.geometry(stage.draw_data)
        draws = stage.geometry_draws
        stage.geometry()  # GL
        assert stage.geometry_draws == draws + 1
    finally:
        stage.close()


def test_meshes_and_the_gratings_screen_keep_the_gl_pass(tmp_path):
    """A moving mesh, the gratings' sliding screen (a plane): named, and no caster (the GL
    pass draws their masks); the built-in primitive scenes all have one."""
    obj = write_cube_obj(tmp_path / "cube.obj")
    mesh_obj = {
        "name": "mesh_cube",
        "shape": "mesh",
        "mesh": {"file": str(obj), "scale": 0.2},
        "trajectory": {
            "kind": "linear_bounce",
            "start": [1.0, 0.1, 1.0],
            "velocity": [0, -1, 0],
            "bounds_min": [1.0, -0.4, 1.0],
            "bounds_max": [1.0, 0.4, 1.0],
        },
    }
    cfg = scene_config_from_dict({"name": "mesh_scene", "moving_objects": [mesh_obj]})
    stage = Stage(build_mjcf(cfg).compile(), cfg, RenderParams())
    assert unsupported_geoms(stage.model) == ["object_1 (mesh)"]
    assert stage.caster is None and not stage.casts("ground_truth")
    with pytest.raises(
        ValueError, match=r"^ray casting cannot draw the moving geoms object_1 \(mesh\)$"
    ):
        PrimitiveCaster(stage.model, 128, 128)
    grat = load_scene_config("gratings")
    assert unsupported_geoms(build_mjcf(grat).compile()) == ["grating_screen (plane)"]
    for name in ("office", "hand", "shelf"):
        assert (
            Stage(
                build_mjcf(load_scene_config(name)).compile(),
                load_scene_config(name),
                RenderParams(),
            ).caster
            is not None
        )
    off = RaycastParams(ground_truth=False, key_layers=False)
    office = load_scene_config("office")
    assert Stage(build_mjcf(office).compile(), office, RenderParams(), raycast=off).caster is None


def _run(scene: str, raycast: RaycastParams | None, actions: list[np.ndarray], frames: str):
    """Per step (events, mask) of a run from seed 3; ``raycast`` None: GL draws all;
    and the GL layer-and-depth draws of its last step."""
    env = gym.make("wander/Wander-v0", scene=scene, frames=frames)
    try:
        stage = env.unwrapped.stage
        if raycast is None:
            stage.caster = None
        else:
            stage.caster.params = raycast
        env.reset(seed=3)
        out = []
        for a in actions:
            info = env.step(a)[4]
            out.append((info["events"].events.copy(), info["object_mask"].copy()))
        return out, stage.geometry_draws
    finally:
        env.close()


# A still step, a saccade and a walk.
ACTIONS = [np.zeros(2, np.float32), np.array([0.4, -0.2], np.float32)] + [
    np.array([0.02, 0.01], np.float32)
] * 3


@pytest.mark.slow
@pytest.mark.parametrize("frames", ["keyframes", "exact"])
def test_cast_ground_truth_leaves_the_events_bit_identical(frames):
    """Office, ground truth on: the same events with the masks ray cast (the keys'
    geometry left to GL) as with GL; the masks the same but for rim pixels."""
    cast, _ = _run("office", RaycastParams(key_layers=False), ACTIONS, frames)
    gl, _ = _run("office", None, ACTIONS, frames)
    for (ev_c, m_c), (ev_g, m_g) in zip(cast, gl, strict=True):
        assert np.array_equal(ev_c, ev_g)
        assert (m_c != m_g).sum() <= 0.02 * max((m_g > 0).sum(), 1)
        assert not ((m_c != m_g) & ~_rim(m_c, m_g)).any()


@pytest.mark.slow
def test_cast_key_layers_draw_no_gl_geometry_and_keep_the_events():
    """The default (keys' layers and depth ray cast too): no GL geometry draw in a walk
    step that synthesises frames, and every step's events within 1 % of GL's layers'
    (measured: the same events; a rim pixel's layer differs, its nearest-pixel source
    rarely does)."""
    cast, draws = _run("office", RaycastParams(), ACTIONS, "keyframes")
    gl, gl_draws = _run("office", None, ACTIONS, "keyframes")
    assert draws == 0 and gl_draws >= 2
    for (ev_c, _), (ev_g, _) in zip(cast, gl, strict=True):
        assert abs(len(ev_c) - len(ev_g)) <= 0.01 * len(ev_g)


def _cube_in_child(stage: Stage, out) -> None:
    """In a forked child: the caster asked for a new cube (a reset) after its parent
    rendered one."""
    try:
        stage.caster.reset()
        stage.object_mask()
        out.put("rendered")
    except ForkedGLError as e:
        out.put(f"ForkedGLError: {e}")


def test_the_cube_refuses_a_process_forked_after_it_rendered():
    """A child forked after the parent rendered the static cube raises ForkedGLError
    (naming spawn) when it would render its own, as the stage's renderer does."""
    import multiprocessing

    stage = _stage("office")
    try:
        stage.pose(0, 0.0, 0.0)
        stage.object_mask()  # the parent renders the cube
        ctx = multiprocessing.get_context("fork")
        out = ctx.Queue()
        child = ctx.Process(target=_cube_in_child, args=(stage, out))
        child.start()
        got = out.get(timeout=60)
        child.join(timeout=60)
        assert got.startswith("ForkedGLError: ") and "context='spawn'" in got
    finally:
        stage.close()
