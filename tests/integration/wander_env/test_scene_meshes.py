"""Scenes users bring: mesh objects (OBJ, STL) as static and moving props, in the env."""

from __future__ import annotations

import os

os.environ.setdefault("MUJOCO_GL", "egl")  # before mujoco is imported: headless rendering

import math
import pickle
import struct
from pathlib import Path

import cv2
import gymnasium as gym
import mujoco
import numpy as np
import pytest
import yaml
from scene_files import write_cube_obj, write_cube_stl

import wander_env  # noqa: F401  (registers the envs)
from wander_env.config import ConfigError
from wander_env.mjcf import SceneAnimator, build_mjcf, compile_scene, geom_layer_radii
from wander_env.renderer import CameraRenderer
from wander_env.scene_config import SceneConfig
from wander_env.scene_parts import MeshConfig, MovingObjectConfig, StaticObjectConfig
from wander_env.scenes import load_scene_config, scene_config_from_dict
from wander_env.textures import TextureSpec
from wander_env.trajectories import LinearBounceParams, ScriptedParams, make_trajectory
from wander_env.untrusted import LIMITS


def _moving_cube(obj: Path, **changes) -> dict:
    """A moving mesh cube 0.2 m wide, 1 m ahead, sliding left to right across the view."""
    return {
        "name": "mesh_cube",
        "shape": "mesh",
        "mesh": {"file": str(obj), "scale": 0.2},
        "rgba": [0.9, 0.8, 0.2, 1],
        "trajectory": {
            "kind": "linear_bounce",
            "start": [1.0, 0.1, 1.0],
            "velocity": [0.0, -1.0, 0.0],
            "bounds_min": [1.0, -0.4, 1.0],
            "bounds_max": [1.0, 0.4, 1.0],
        },
        **changes,
    }


def _world_bounds(model: mujoco.MjModel, data: mujoco.MjData, geom: int) -> np.ndarray:
    """(2, 3) world bounding box of a mesh geom's vertices."""
    mesh = int(model.geom_dataid[geom])
    adr, n = int(model.mesh_vertadr[mesh]), int(model.mesh_vertnum[mesh])
    verts = model.mesh_vert[adr : adr + n] @ data.geom_xmat[geom].reshape(3, 3).T
    verts = verts + data.geom_xpos[geom]
    return np.stack([verts.min(axis=0), verts.max(axis=0)])


# ----------------------------------------------------------------------------------------
# Building


@pytest.mark.parametrize("writer", [write_cube_obj, write_cube_stl], ids=["obj", "stl"])
def test_a_mesh_is_scaled_and_centred_on_its_position(tmp_path, writer):
    obj = writer(tmp_path / f"cube{'.obj' if writer is write_cube_obj else '.stl'}")
    cfg = scene_config_from_dict(
        {
            "static_objects": [
                {
                    "name": "prop",
                    "shape": "mesh",
                    "mesh": {"file": str(obj), "scale": [0.1, 0.2, 0.3]},
                    "position": [1.5, 0.5, 1.0],
                    "euler_deg": [0, 0, 90],
                }
            ],
            "moving_objects": [_moving_cube(obj)],
        }
    )
    model = compile_scene(cfg)
    data = mujoco.MjData(model)
    SceneAnimator(model, cfg).apply(data, 0.0)
    mujoco.mj_forward(model, data)
    # 0.1 x 0.2 x 0.3 turned 90 deg about z: 0.2 along x, 0.1 along y
    np.testing.assert_allclose(
        _world_bounds(model, data, model.geom("prop").id),
        [[1.4, 0.45, 0.85], [1.6, 0.55, 1.15]],
        atol=1e-6,
    )
    np.testing.assert_allclose(
        _world_bounds(model, data, model.geom("object_1").id),
        [[0.9, 0.0, 0.9], [1.1, 0.2, 1.1]],
        atol=1e-6,
    )
    scene = build_mjcf(cfg)
    assert sorted(scene.assets) == ["mesh_1" + obj.suffix, "mesh_2" + obj.suffix]
    # the two files' meshes, and the PTU base's cylinder as a prism (cylinders_as_prisms)
    assert [model.mesh(i).name for i in range(model.nmesh)] == [
        "mesh_1",
        "mesh_2",
        "wander_cylinder_prism_0",
    ]


def test_a_textured_mesh_renders_its_texture_and_is_segmented(tmp_path):
    obj = write_cube_obj(tmp_path / "cube.obj")
    texture = TextureSpec(kind="checker", colors=((0.1, 0.1, 0.1), (0.9, 0.9, 0.9)), scale=16)
    cfg = SceneConfig(
        name="textured",
        moving_objects=(
            MovingObjectConfig(
                shape="mesh",
                mesh=MeshConfig(file=str(obj), scale=0.4),
                texture=texture,
                trajectory=LinearBounceParams(
                    start=(1.0, 0.0, 1.0),
                    velocity=(0.0, 0.0, 0.0),
                    bounds_min=(1.0, 0.0, 1.0),
                    bounds_max=(1.0, 0.0, 1.0),
                ),
            ),
        ),
    )
    model = compile_scene(cfg)
    data = mujoco.MjData(model)
    SceneAnimator(model, cfg).apply(data, 0.0)
    mujoco.mj_forward(model, data)
    with CameraRenderer(model) as cam:
        rgb, mask = cam.render_with_mask(data)
    inside = cv2.erode((mask == 1).astype(np.uint8), np.ones((3, 3), np.uint8)) > 0
    assert inside.sum() > 100
    grey = rgb.mean(axis=2)[inside]
    # both checker colours on the cube (0.1 and 0.9 under the headlight alone)
    assert (grey < 70).sum() > 20 and (grey > 110).sum() > 20
    assert set(np.unique(mask).tolist()) == {0, 1}


def test_a_relative_mesh_path_in_a_scene_file_is_relative_to_the_file(tmp_path, monkeypatch):
    (tmp_path / "meshes").mkdir()
    write_cube_obj(tmp_path / "meshes" / "cube.obj")
    doc = {"moving_objects": [_moving_cube(Path("meshes/cube.obj"))]}
    (tmp_path / "scene.yaml").write_text(yaml.safe_dump(doc))
    monkeypatch.chdir(Path(__file__).parent)  # elsewhere
    cfg = load_scene_config(tmp_path / "scene.yaml")
    assert cfg.moving_objects[0].mesh.file == str(tmp_path / "meshes" / "cube.obj")


# ----------------------------------------------------------------------------------------
# Bad meshes: one line naming the file, the field and the value


def _mesh_error(tmp_path: Path, mesh: dict, **changes) -> str:
    path = tmp_path / "scene.yaml"
    obj = {**_moving_cube(Path("unused.obj")), "mesh": mesh, **changes}
    path.write_text(yaml.safe_dump({"moving_objects": [obj]}))
    with pytest.raises(ConfigError) as info:
        load_scene_config(path)
    msg = str(info.value)
    assert "\n" not in msg
    return msg


def test_a_missing_mesh_file_is_one_line(tmp_path):
    msg = _mesh_error(tmp_path, {"file": "nope.obj"})
    assert msg == (
        f"{tmp_path / 'scene.yaml'}: moving_objects[0].mesh.file: "
        f"{tmp_path / 'nope.obj'}: no such file"
    )


def test_a_mesh_of_another_format_is_refused(tmp_path):
    (tmp_path / "cube.ply").write_text("ply\n")
    msg = _mesh_error(tmp_path, {"file": "cube.ply"})
    assert msg.endswith(
        f"moving_objects[0].mesh.file: must end in .obj or .stl, got {str(tmp_path / 'cube.ply')!r}"
    )


def test_a_mesh_file_over_the_cap_is_refused_unread(tmp_path):
    big = tmp_path / "big.obj"
    with open(big, "wb") as f:
        f.truncate(LIMITS.mesh_bytes + 1)  # sparse: nothing to read
    msg = _mesh_error(tmp_path, {"file": "big.obj"})
    assert msg.endswith(
        f"moving_objects[0].mesh.file: {big}: {LIMITS.mesh_bytes + 1} bytes; "
        f"at most {LIMITS.mesh_bytes}"
    )


def test_a_directory_or_a_device_is_not_a_mesh(tmp_path):
    (tmp_path / "dir.obj").mkdir()
    msg = _mesh_error(tmp_path, {"file": "dir.obj"})
    assert msg.endswith(
        f"mesh.file: {tmp_path / 'dir.obj'}: not a regular file (a folder): refused"
    )


def test_a_mesh_mujoco_cannot_read_is_one_line(tmp_path):
    (tmp_path / "junk.obj").write_text("hello\nv 1 2\n")
    msg = _mesh_error(tmp_path, {"file": "junk.obj"})
    assert msg.endswith(
        "moving_objects[0].mesh.file: MuJoCo cannot read the mesh (at least 4 vertices "
        f"required; Element name 'junk.obj', id 0), got {str(tmp_path / 'junk.obj')!r}"
    )
    (tmp_path / "junk.stl").write_bytes(b"\0" * 80 + struct.pack("<I", 10**6))
    msg = _mesh_error(tmp_path, {"file": "junk.stl"})
    assert "moving_objects[0].mesh.file: MuJoCo cannot read the mesh (stl_decoder" in msg


def test_mesh_and_shape_must_agree(tmp_path):
    write_cube_obj(tmp_path / "cube.obj")
    msg = _mesh_error(tmp_path, {"file": "cube.obj"}, size=[0.1, 0.1, 0.1])
    assert msg.endswith(
        "moving_objects[0].size: not used by a mesh (its size is the file's times "
        "mesh.scale), got (0.1, 0.1, 0.1)"
    )
    msg = _mesh_error(tmp_path, {"file": "cube.obj"}, shape="box", size=[0.1, 0.1, 0.1])
    assert msg.endswith("moving_objects[0].mesh: only for shape 'mesh', got shape 'box'")
    with pytest.raises(ValueError, match=r"^mesh: required when shape is 'mesh'$"):
        StaticObjectConfig(shape="mesh", position=(0.0, 0.0, 0.0))
    msg = _mesh_error(tmp_path, {"file": "cube.obj", "scale": 0})
    assert "moving_objects[0].mesh.scale" in msg and "greater than 0" in msg


# ----------------------------------------------------------------------------------------
# In the env: gym.make(scene=SceneConfig), both frame modes


def _events_near(events: np.ndarray, near: np.ndarray) -> tuple[int, int]:
    """(events on pixels where ``near`` is set, events elsewhere)."""
    hit = near[events["y"].astype(int), events["x"].astype(int)]
    return int(hit.sum()), int((~hit).sum())


@pytest.mark.parametrize("frames", ["keyframes", "exact"])
def test_a_moving_mesh_is_rendered_segmented_and_makes_events_in_the_env(tmp_path, frames):
    obj = write_cube_obj(tmp_path / "cube.obj")
    cfg = scene_config_from_dict({"name": "mesh_scene", "moving_objects": [_moving_cube(obj)]})
    env = gym.make("wander/Wander-v0", scene=cfg, frames=frames, dvs="ideal")
    try:
        _, info = env.reset(seed=0)
        assert env.unwrapped.scene is cfg
        for _ in range(5):
            _, _, _, _, info = env.step(np.zeros(2, np.float32))
        mask = info["object_mask"]
        (obj_info,) = info["objects"]
        assert obj_info["name"] == "mesh_cube" and obj_info["visible"]
        # the cube (0.2 m at 0.9 m, f = 42.5 px): a ~9.4 px square about its centre
        assert 70 <= obj_info["mask_pixels"] <= 100
        cx, cy = obj_info["centre_px"]
        assert mask[round(cy), round(cx)] == 1
        ys, xs = np.nonzero(mask == 1)
        assert abs(xs.mean() - cx) < 1.0 and abs(ys.mean() - cy) < 1.0
        # events: on and next to the moving cube (it moved up to 2 px in the step), none
        # on the black, still background
        near = cv2.dilate((mask == 1).astype(np.uint8), np.ones((7, 7), np.uint8)) > 0
        on, off = _events_near(info["events"].events, near)
        assert on > 20 and off == 0
    finally:
        env.close()


# ----------------------------------------------------------------------------------------
# A Python callable as a trajectory


def _wave(t: float) -> tuple[float, float, float]:
    return (1.0, 0.3 * math.sin(4.0 * t), 1.0)


def test_a_callable_trajectory_moves_an_object_in_the_env(tmp_path):
    obj = write_cube_obj(tmp_path / "cube.obj")
    cube = MovingObjectConfig(
        name="scripted_cube",
        shape="mesh",
        mesh=MeshConfig(file=str(obj), scale=0.2),
        trajectory=ScriptedParams(_wave),
    )
    cfg = SceneConfig(name="scripted", moving_objects=(cube,))
    env = gym.make("wander/Wander-v0", scene=cfg, frames="keyframes")
    try:
        env.reset(seed=0)
        for _ in range(3):
            _, _, _, _, info = env.step(np.zeros(2, np.float32))
        animator = env.unwrapped.animator
        np.testing.assert_allclose(animator.object_positions(0.03)[0], _wave(0.03))
        assert info["objects"][0]["visible"] and info["events"].events.size > 0
    finally:
        env.close()


def test_a_callable_trajectory_is_checked_at_t_0():
    with pytest.raises(ValueError, match=r"^position: at t = 0 s: expected 3 finite numbers"):
        ScriptedParams(lambda t: (1.0, 2.0))
    with pytest.raises(
        ValueError, match=r"^position: at t = 0 s: ZeroDivisionError: float division by zero$"
    ):
        ScriptedParams(lambda t: (1.0 / t, 0.0, 0.0))
    with pytest.raises(ValueError, match=r"^position: must be a callable t -> \(x, y, z\)"):
        ScriptedParams((1.0, 2.0, 3.0))  # type: ignore[arg-type]
    bad_later = make_trajectory(ScriptedParams(lambda t: (t, 0.0, math.nan if t > 1 else 0.0)))
    with pytest.raises(ValueError, match=r"^scripted trajectory at t = 2.0 s: expected 3 finite"):
        bad_later.position(2.0)


def test_a_scene_file_cannot_hold_a_callable(tmp_path):
    path = tmp_path / "scene.yaml"
    obj = {"shape": "box", "size": [0.1, 0.1, 0.1], "trajectory": {"kind": "scripted"}}
    obj["trajectory"]["position"] = "os:system"
    path.write_text(yaml.safe_dump({"moving_objects": [obj]}))
    with pytest.raises(ConfigError) as info:
        load_scene_config(path)
    assert str(info.value) == (
        f"{path}: moving_objects[0].trajectory.position: expected Callable, got 'os:system'"
    )


def test_an_env_of_a_scene_config_with_a_mesh_pickles(tmp_path):
    obj = write_cube_obj(tmp_path / "cube.obj")
    cfg = scene_config_from_dict({"name": "mesh_scene", "moving_objects": [_moving_cube(obj)]})
    env = gym.make("wander/Wander-v0", scene=cfg)
    try:
        clone = pickle.loads(pickle.dumps(env.unwrapped))
        assert clone.scene == cfg
        clone.close()
    finally:
        env.close()


def test_layer_radii_bound_a_mesh_and_match_the_primitives_sizes(tmp_path):
    obj = write_cube_obj(tmp_path / "cube.obj")
    cfg = scene_config_from_dict({"moving_objects": [_moving_cube(obj)]})
    radii = geom_layer_radii(compile_scene(cfg))
    np.testing.assert_allclose(radii, [np.inf, 0.1 * math.sqrt(3)], rtol=1e-6)
    for name in ("office", "hand"):  # the sizes' half-diagonals, as the env computes them
        cfg = load_scene_config(name)
        want = [0.5 * math.hypot(*o.size) for o in cfg.moving_objects]
        np.testing.assert_allclose(geom_layer_radii(compile_scene(cfg))[1:], want, rtol=1e-9)
    assert geom_layer_radii(compile_scene(load_scene_config("gratings"))).tolist() == [np.inf] * 3
