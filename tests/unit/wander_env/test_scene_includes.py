"""Scenes users bring: an existing MJCF file's bodies included in a scene."""

from __future__ import annotations

import os

os.environ.setdefault("MUJOCO_GL", "egl")  # before mujoco is imported: headless rendering


import mujoco
import numpy as np
import pytest
import yaml
from scene_files import write_arm

from wander_env.config import ConfigError
from wander_env.mjcf import compile_scene, geom_object_ids
from wander_env.renderer import CameraRenderer
from wander_env.scenes import load_scene_config, scene_config_from_dict


def test_an_included_mjcf_file_is_attached_static_at_its_frame(tmp_path):
    arm = write_arm(tmp_path)
    include = {
        "file": str(arm),
        "name": "arm",
        "position": [1.5, 0.0, 0.8],
        "euler_deg": [0, 0, 90],
    }
    cfg = scene_config_from_dict({"mjcf_includes": [include]})
    model = compile_scene(cfg)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    names = [model.body(i).name for i in range(model.nbody)]
    assert names[-3:] == ["arm/base", "arm/link", "arm/tool"]
    # joints removed: only the pan-tilt unit's hinges; no actuator
    assert [model.joint(j).name for j in range(model.njnt)] == ["pan", "tilt"]
    assert model.nu == 0
    # the file's degrees are kept; the include's frame turns its bodies 90 deg about z
    np.testing.assert_allclose(data.xpos[model.body("arm/base").id], [1.5, 0.0, 0.8], atol=1e-9)
    np.testing.assert_allclose(data.xpos[model.body("arm/tool").id], [1.0, 0.0, 0.8], atol=1e-9)
    link_x = data.xmat[model.body("arm/link").id].reshape(3, 3)[:, 0]
    np.testing.assert_allclose(link_x, [-1.0, 0.0, 0.0], atol=1e-9)  # 90 + 90 deg about z
    assert model.material("arm/red").id >= 0
    assert model.nmat == cfg.own_materials() + 1
    # static (object id 0), and the camera sees it
    assert geom_object_ids(model)[model.geom("arm/base_geom").id] == 0
    with CameraRenderer(model) as cam:
        rgb, mask = cam.render_with_mask(data)
    assert (rgb[..., 0] > 100).sum() > 20 and mask.max() == 0


def test_an_include_path_in_a_scene_file_is_relative_to_the_file(tmp_path):
    (tmp_path / "robots").mkdir()
    write_arm(tmp_path / "robots")
    (tmp_path / "scene.yaml").write_text(
        yaml.safe_dump({"mjcf_includes": [{"file": "robots/arm.xml"}]})
    )
    cfg = load_scene_config(tmp_path / "scene.yaml")
    assert cfg.mjcf_includes[0].file == str(tmp_path / "robots" / "arm.xml")
    model = compile_scene(cfg)
    assert model.body("include_0/base").id > 0


@pytest.mark.parametrize(
    ("name", "content", "expected"),
    [
        ("missing.xml", None, "{path}: no such file"),
        ("arm.txt", "<mujoco/>", "must end in .xml or .mjcf, got {path!r}"),
        (
            "broken.xml",
            "<mujoco><worldbody><body>",
            "{path}: not well-formed XML (no element found: line 1, column 25)",
        ),
        (
            "bad_geom.xml",
            '<mujoco><worldbody><body><geom type="box"/></body></worldbody></mujoco>',
            "MuJoCo cannot read the MJCF (size 0 must be positive in geom; "
            "Element name '', id 0, line 1), got {path!r}",
        ),
    ],
)
def test_a_bad_include_is_one_line_naming_file_field_and_value(tmp_path, name, content, expected):
    if content is not None:
        (tmp_path / name).write_text(content)
    scene = tmp_path / "scene.yaml"
    scene.write_text(yaml.safe_dump({"mjcf_includes": [{"file": name}]}))
    with pytest.raises(ConfigError) as info:
        load_scene_config(scene)
    problem = expected.format(path=str(tmp_path / name))
    assert str(info.value) == f"{scene}: mjcf_includes[0].file: {problem}"


def test_two_includes_of_one_name_are_refused(tmp_path):
    arm = str(write_arm(tmp_path))
    includes = [{"file": arm, "name": "arm"}, {"file": arm}, {"file": arm, "name": "arm"}]
    with pytest.raises(ConfigError) as info:
        scene_config_from_dict({"mjcf_includes": includes}, where="s.yaml")
    assert str(info.value) == "s.yaml: mjcf_includes: names must differ, got arm twice"
    # the default names are the list positions: include_1 here
    cfg = scene_config_from_dict({"mjcf_includes": includes[:2]})
    assert compile_scene(cfg).body("include_1/base").id > 0
