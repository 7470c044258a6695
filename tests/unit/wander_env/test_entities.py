"""Scene entities: each part's MJCF fragment and runtime, and the arena that composes them."""

from __future__ import annotations

import os

os.environ.setdefault("MUJOCO_GL", "egl")  # before mujoco is imported: headless rendering

import dataclasses
import math
import xml.etree.ElementTree as ET

import mujoco
import numpy as np
import pytest

from wander_env.entities import (
    GRATING_BACKGROUND_BODY,
    GRATING_STRIP_PREFIX,
    GratingStimulus,
    MovingProp,
    PanTiltCamera,
    Table,
)
from wander_env.grating_geometry import grating_state
from wander_env.mjcf import Arena, SceneAnimator, build_mjcf, compile_scene
from wander_env.mjcf_document import MJCFDocument, fmt
from wander_env.ptu.params import PTUParams
from wander_env.scene_config import CameraConfig, PTUMountConfig
from wander_env.scenes import load_scene_config
from wander_env.textures import TextureSpec


def _doc() -> MJCFDocument:
    doc = MJCFDocument("test")
    doc.open_world()
    return doc


def test_pan_tilt_camera_fragment_has_two_hinges_and_the_camera():
    ptu = PanTiltCamera(
        PTUMountConfig(position=(0.1, -0.2, 1.1)),
        CameraConfig(width=200, height=100, hfov_deg=90.0),
        PTUParams(camera_forward_m=0.03, camera_up_m=0.05),
    )
    doc = _doc()
    ptu.attach(doc)
    (base,) = doc.world
    assert (base.tag, base.get("name"), base.get("pos")) == ("body", "ptu_base", "0.1 -0.2 1.1")
    joints = [(j.get("name"), j.get("type"), j.get("axis")) for j in base.iter("joint")]
    assert joints == [("pan", "hinge", "0 0 1"), ("tilt", "hinge", "0 -1 0")]
    cams = list(base.iter("camera"))
    assert len(cams) == 1
    assert cams[0].get("name") == "event_camera"
    assert cams[0].get("pos") == "0.03 0 0.05"
    # fovy: the vertical FOV of 90° horizontal at 2:1, 2·atan(tan 45° / 2) = 53.1301°
    assert cams[0].get("fovy") == "53.1301"
    assert ptu.fovy_deg == pytest.approx(2 * math.degrees(math.atan(0.5)), abs=1e-12)
    assert {g.get("group") for g in base.iter("geom")} == {"3"}
    assert ptu.camera_position() == pytest.approx((0.13, -0.2, 1.15), abs=1e-15)
    # one material for the unit, numbered first
    assert [m.get("name") for m in doc.asset] == ["mat_1"]


def test_pan_tilt_camera_position_is_where_mujoco_puts_the_camera():
    cfg = load_scene_config("office")
    cfg = dataclasses.replace(cfg, ptu=PTUMountConfig(position=(0.2, 0.1, 1.2)))
    hinge = PTUParams(camera_forward_m=0.04, camera_up_m=0.06)
    arena = Arena(cfg, hinge)
    model = compile_scene(cfg, hinge)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    cam = model.camera("event_camera").id
    np.testing.assert_allclose(data.cam_xpos[cam], arena.ptu.camera_position(), atol=1e-12)
    # MJCF numbers carry 6 significant digits: 112.8267° is written as 112.827
    assert model.cam_fovy[cam] == float(fmt(arena.ptu.fovy_deg)) == 112.827


def test_arena_lists_the_entities_in_document_order():
    office = Arena(load_scene_config("office"))
    names = [type(e).__name__ for e in office.entities]
    assert names == ["Lights", "Room", "Table", "Shelf"] + ["StaticProp"] * 15 + [
        "MovingProp",
        "MovingProp",
        "PanTiltCamera",
    ]
    assert [p.index for p in office.moving_props] == [1, 2]
    assert office.entities[-1] is office.ptu
    assert office.gratings is None
    gratings = Arena(load_scene_config("gratings"))
    assert [type(e).__name__ for e in gratings.entities] == [
        "Lights",
        "GratingStimulus",
        "PanTiltCamera",
    ]
    assert gratings.gratings.ptu is gratings.ptu


def test_arena_document_is_the_entities_fragments_in_order():
    world = ET.fromstring(build_mjcf(load_scene_config("hand")).xml).find("worldbody")
    assert [(e.tag, e.get("name")) for e in world] == [
        ("light", "light_0"),
        ("body", "room"),
        ("body", "table_0"),
        ("geom", "mug"),
        ("geom", "book"),
        ("geom", "crate"),
        ("geom", "poster"),
        ("body", "object_1"),
        ("body", "ptu_base"),
    ]


def test_document_numbers_materials_and_keeps_texture_assets():
    doc = _doc()
    plain = doc.material((1, 0, 0, 1))
    tex = TextureSpec(kind="checker", colors=((0, 0, 0), (1, 1, 1)), scale=8, size_px=32)
    textured = doc.material((1, 1, 1, 1), tex, (1.0, 1.0), cube=True)
    assert (plain, textured) == ("mat_1", "mat_2")
    assert list(doc.assets) == ["tex_2.png"]
    (texture,) = doc.asset.iter("texture")
    assert (texture.get("name"), texture.get("type"), texture.get("file")) == (
        "tex_2",
        "cube",
        "tex_2.png",
    )
    assert fmt((0.1, 2, 1 / 3)) == "0.1 2 0.333333"
    with pytest.raises(RuntimeError, match="already open"):
        doc.open_world()
    with pytest.raises(RuntimeError, match="open_world"):
        _ = MJCFDocument("x").world


def test_table_fragment_has_a_top_and_four_legs():
    cfg = load_scene_config("office")
    t = cfg.tables[0]
    doc = _doc()
    Table(3, t).attach(doc)
    (body,) = doc.world
    assert body.get("name") == "table_3"
    geoms = [g.get("name") for g in body]
    assert geoms == ["table_3_top"] + [f"table_3_leg_{j}" for j in range(4)]
    assert body[0].get("pos") == fmt((0, 0, t.height - t.thickness / 2))


def test_moving_prop_runtime_writes_its_trajectory_into_mocap_pos():
    cfg = load_scene_config("office")
    model = compile_scene(cfg)
    data = mujoco.MjData(model)
    prop = MovingProp(2, cfg.moving_objects[1])
    motion = prop.motion(model, np.random.default_rng(0))
    assert prop.body_name == "object_2"
    assert motion.mocap_id == int(model.body_mocapid[model.body("object_2").id]) == 1
    for t in (0.0, 0.37, 1.9):
        motion.apply(data, t)
        np.testing.assert_array_equal(data.mocap_pos[1], motion.trajectory.position(t))
    mujoco.mj_kinematics(model, data)
    np.testing.assert_array_equal(data.xpos[model.body("object_2").id], motion.position(1.9))
    # the other prop's slot is untouched (still the body's initial position)
    np.testing.assert_array_equal(data.mocap_pos[0], model.body_pos[model.body("object_1").id])


def test_moving_prop_fragment_is_a_mocap_body_at_its_start():
    cfg = load_scene_config("office")
    doc = _doc()
    MovingProp(1, cfg.moving_objects[0]).attach(doc)
    (body,) = doc.world
    assert (body.get("name"), body.get("mocap")) == ("object_1", "true")
    assert body.get("pos") == fmt(cfg.moving_objects[0].trajectory.start)
    assert [(g.get("name"), g.get("type")) for g in body] == [("object_1", "box")]


def test_grating_stimulus_sits_ahead_of_the_camera_and_its_runtime_slides_and_recolours():
    cfg = load_scene_config("gratings")
    arena = Arena(cfg)
    stim = arena.gratings
    assert isinstance(stim, GratingStimulus)
    layout = stim.layout()
    cx, cy, cz = arena.ptu.camera_position()
    assert layout.center == pytest.approx((cx + cfg.gratings.distance_m, cy, cz), abs=1e-15)
    model = compile_scene(cfg)
    data = mujoco.MjData(model)
    motion = stim.motion(model)
    assert len(motion.strip_geoms) == cfg.gratings.object_strips
    assert model.geom(int(motion.strip_geoms[0])).name == f"{GRATING_STRIP_PREFIX}0"
    t = 0.4
    motion.apply(data, t)
    slide, level = grating_state(cfg.gratings, layout, t)
    bg = int(model.body_mocapid[model.body(GRATING_BACKGROUND_BODY).id])
    np.testing.assert_array_equal(data.mocap_pos[bg], (layout.center[0], cy - slide, cz))
    np.testing.assert_array_equal(model.geom_rgba[motion.strip_geoms, 0], level)
    v_b, v_o = (v * cfg.gratings.metres_per_deg for v in cfg.gratings.effective_speeds_deg_s())
    np.testing.assert_allclose(
        stim.layer_positions(t), [[0, 0, 0], [0, -v_o * t, 0], [0, -v_b * t, 0]], atol=1e-15
    )


def test_animator_replacing_trajectories_forgets_cached_positions():
    cfg = load_scene_config("office")
    animator = SceneAnimator(compile_scene(cfg), cfg, np.random.default_rng(0))
    before = animator.object_positions(1.0).copy()

    class Frozen:
        def position(self, t: float) -> np.ndarray:
            return np.array([1.0, 2.0, 3.0])

    animator.trajectories = (Frozen(), Frozen())
    np.testing.assert_array_equal(animator.object_positions(1.0), [[1, 2, 3], [1, 2, 3]])
    assert not np.array_equal(before, animator.object_positions(1.0))
    assert animator.motions[1].mocap_id == 1
    with pytest.raises(ValueError, match="trajectories: need 2, got 1"):
        animator.trajectories = (Frozen(),)


@pytest.mark.parametrize(("scene", "layers"), [("office", 3), ("hand", 2), ("gratings", 3)])
def test_layer_positions_at_many_times_are_those_at_each_time_bit_for_bit(
    scene: str, layers: int
) -> None:
    """The camera views' one evaluation over a step's ticks (linear bounces at once,
    the other trajectories per time) gives layer_positions(t)'s numbers exactly."""
    cfg = load_scene_config(scene)
    animator = SceneAnimator(build_mjcf(cfg).compile(), cfg, np.random.default_rng(3))
    times = np.arange(1, 41, dtype=np.int64) * 1000 * 1e-6 + 7.25
    many = animator.layer_positions_at(times)
    each = np.stack([animator.layer_positions(float(t)) for t in times])
    assert many.shape == each.shape == (40, layers, 3)
    assert many.tobytes() == each.tobytes()
    assert len(np.unique(many[:, -1], axis=0)) == 40  # the last layer moves at every tick
