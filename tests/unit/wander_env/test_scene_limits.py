"""Scene size limits: what the work holds, refused in one line at validation."""

from __future__ import annotations

import os

os.environ.setdefault("MUJOCO_GL", "egl")  # before mujoco is imported: headless rendering

import dataclasses
import resource

import pytest
import yaml

from wander_env.config import ConfigError
from wander_env.mjcf import compile_scene
from wander_env.scene_config import MAX_CAMERA_PIXELS, CameraConfig
from wander_env.scenes import load_scene_config, scene_config_from_dict

_BOX = {"shape": "box", "size": [0.01, 0.01, 0.01], "position": [1.0, 0.0, 1.0]}


def _error(data: dict) -> str:
    with pytest.raises(ConfigError) as info:
        scene_config_from_dict(data, where="s.yaml")
    msg = str(info.value)
    assert "\n" not in msg
    return msg


@pytest.mark.parametrize("side", [20000, 100000])
def test_a_huge_camera_is_refused_in_one_line(side):
    assert _error({"camera": {"width": side, "height": side}}) == (
        f"s.yaml: camera.width: input should be less than or equal to 4096, got {side}; "
        f"camera.height: input should be less than or equal to 4096, got {side}"
    )


def test_the_camera_pixel_budget():
    assert _error({"camera": {"width": 4096, "height": 2048}}) == (
        "s.yaml: camera.width: width x height must be <= 4194304 pixels (2048 x 2048; the "
        "env takes ~0.3 kB a pixel), got 4096 x 2048"
    )
    cfg = scene_config_from_dict({"camera": {"width": 4096, "height": 1024}})
    assert cfg.camera.width * cfg.camera.height == MAX_CAMERA_PIXELS
    with pytest.raises(ValueError, match=r"^width: width x height must be <= 4194304"):
        CameraConfig(width=3000, height=3000)
    with pytest.raises(ValueError, match=r"^antialias_samples: input should be less than"):
        CameraConfig(antialias_samples=64)


@pytest.mark.parametrize("n", [10**4, 10**6])
def test_too_many_objects_are_refused_before_validation(n):
    before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    msg = _error({"static_objects": [_BOX] * n})
    assert msg == (
        "s.yaml: static_objects: at most 1000 items (MuJoCo renders at most 1000 "
        f"materials, one a part), got {n}"
    )
    # nothing allocated in proportion to n (the list itself holds n references)
    assert resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - before < 50_000  # kB
    assert _error({"moving_objects": (_BOX,) * n}).startswith(
        "s.yaml: moving_objects: at most 1000 items"
    )


def test_too_many_lights_are_refused():
    light = {"direction": [0, 0, -1]}
    assert _error({"lighting": {"lights": [light] * 101}}) == (
        "s.yaml: lighting.lights: at most 100 items (MuJoCo's limit is 100), got 101"
    )


def test_the_material_limit_has_its_own_message():
    room = {"size": [4, 4, 2.6]}
    assert _error({"room": room, "static_objects": [_BOX] * 994}) == (
        "s.yaml: static_objects: the scene needs 1001 materials, MuJoCo renders at most 1000 "
        "(one a table, shelf and object, 6 for a room, 1 for the pan-tilt unit, 2 for "
        "gratings, and the mjcf_includes' own): use fewer parts"
    )
    cfg = scene_config_from_dict({"room": room, "static_objects": [_BOX] * 993})
    assert cfg.own_materials() == 1000


def test_the_texture_limit_has_its_own_message(tmp_path):
    # an included file that brings 995 textures (and no material)
    textures = "".join(
        f'<texture name="t{i}" type="2d" builtin="flat" width="8" height="8"/>' for i in range(995)
    )
    path = tmp_path / "textures.xml"
    path.write_text(f"<mujoco><asset>{textures}</asset><worldbody/></mujoco>")
    room = {"size": [4, 4, 2.6]}
    assert _error({"room": room, "mjcf_includes": [{"file": str(path)}]}) == (
        "s.yaml: static_objects: the scene needs 1001 textures, MuJoCo renders at most 1000 "
        "(one a textured part, 6 for a room, 1 for gratings, and the mjcf_includes' own): "
        "use fewer textured parts"
    )
    # counted as the file compiles alone: an upper bound (unused assets stay behind)
    cfg = scene_config_from_dict({"mjcf_includes": [{"file": str(path)}]})
    assert cfg.mjcf_includes[0].counts() == (0, 995)
    assert compile_scene(cfg).ntex == 0


@pytest.mark.parametrize("name", ["office", "hand", "gratings", "shelf"])
def test_material_and_texture_counts_match_the_compiled_model(name):
    cfg = load_scene_config(name)
    model = compile_scene(cfg)
    assert (cfg.own_materials(), cfg.own_textures()) == (model.nmat, model.ntex)


def test_a_scene_name_too_long_for_the_file_system_is_one_line(tmp_path):
    with pytest.raises(ValueError, match=r"^unknown scene 'xxxx") as info:
        load_scene_config("x" * 5000)
    assert len(str(info.value)) < 400
    with pytest.raises(FileNotFoundError, match=r"^scene file not readable: .*File name too long"):
        load_scene_config(str(tmp_path / ("y" * 5000)) + ".yaml")


def test_a_scene_is_a_config_a_mapping_a_name_or_a_file(tmp_path):
    cfg = load_scene_config("office")
    assert load_scene_config(cfg) is cfg
    path = tmp_path / "office_copy.yaml"
    path.write_text(yaml.safe_dump(dataclasses.asdict(cfg)))
    assert load_scene_config(path) == cfg
    assert load_scene_config(dataclasses.asdict(cfg)) == cfg
