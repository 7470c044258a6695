"""Static cylinders compile to meshes of their faces alone (``cylinders_as_prisms``): the
same pixels and masks as MuJoCo's cylinders in every built-in scene, and the cylinders
the ray caster needs, or that carry a texture, stay cylinders."""

from __future__ import annotations

import os

os.environ.setdefault("MUJOCO_GL", "egl")  # before mujoco is imported: headless rendering

import mujoco
import numpy as np
import pytest

from wander_env.mjcf import build_mjcf, cylinders_as_prisms, prism_mesh
from wander_env.renderer import CameraRenderer
from wander_env.scenes import load_scene_config

CYLINDER, MESH = mujoco.mjtGeom.mjGEOM_CYLINDER, mujoco.mjtGeom.mjGEOM_MESH


def _spec(scene: str) -> mujoco.MjSpec:
    doc = build_mjcf(load_scene_config(scene))
    assert doc.includes == ()  # (a built-in scene: nothing to attach)
    spec = mujoco.MjSpec.from_string(doc.xml, assets=doc.assets)
    spec.assets = dict(doc.assets)
    return spec


def test_the_prisms_faces_point_outwards_and_their_normals_are_the_cylinders():
    vertices, normals, faces = prism_mesh(0.3, 0.5, slices=20)
    assert vertices.shape == (82, 3) and faces.shape == (80, 3)
    tri = vertices[faces]
    outward = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    centre = tri.mean(axis=1)
    side = np.abs(centre[:, 2]) < 0.5 - 1e-9
    assert side.sum() == 40
    # the side's faces point away from the axis, the caps' along +z (top) or -z (bottom)
    assert np.all(np.einsum("ij,ij->i", outward[side, :2], centre[side, :2]) > 0)
    assert np.all(outward[~side, 2] * np.sign(centre[~side, 2]) > 0)
    radial = np.c_[vertices[:40, :2] / 0.3, np.zeros(40)]
    np.testing.assert_allclose(normals[:40], radial, atol=1e-12)
    np.testing.assert_array_equal(normals[40:, 2], np.repeat([1.0, -1.0], 21))
    np.testing.assert_allclose(np.hypot(*vertices[:40, :2].T), 0.3, rtol=1e-12)


@pytest.mark.parametrize(("scene", "count"), [("office", 5), ("shelf", 5), ("hand", 2)])
def test_prisms_render_the_same_pixels_and_masks_as_the_cylinders(scene, count):
    """Each scene's static cylinders (its props and the PTU's base) become meshes; at
    three pans every pixel of colour and mask is the same as with MuJoCo's cylinders."""
    cylinders = _spec(scene).compile()
    spec = _spec(scene)
    assert cylinders_as_prisms(spec) == count
    prisms = spec.compile()
    assert (prisms.geom_type == CYLINDER).sum() == 0
    assert (prisms.geom_type == MESH).sum() - (cylinders.geom_type == MESH).sum() == count
    shots = {}
    for name, model in (("cylinders", cylinders), ("prisms", prisms)):
        data = mujoco.MjData(model)
        pan = model.joint("pan").qposadr[0]
        with CameraRenderer(model) as renderer:
            shots[name] = []
            for deg in (-30.0, 0.0, 30.0):
                data.qpos[pan] = np.radians(deg)
                mujoco.mj_forward(model, data)
                shots[name].append(renderer.render_with_mask(data))
    for (rgb_c, mask_c), (rgb_p, mask_p) in zip(shots["cylinders"], shots["prisms"], strict=True):
        np.testing.assert_array_equal(rgb_p, rgb_c)
        np.testing.assert_array_equal(mask_p, mask_c)


def test_moving_textured_and_fromto_cylinders_stay_cylinders():
    xml = """<mujoco>
      <asset>
        <texture name="checks" type="2d" builtin="checker" width="8" height="8"/>
        <material name="plain" rgba="0.5 0.5 0.5 1"/>
        <material name="textured" texture="checks"/>
      </asset>
      <worldbody>
        <geom name="plain" type="cylinder" size="0.1 0.2" material="plain"/>
        <geom name="textured" type="cylinder" size="0.1 0.2" material="textured"/>
        <geom name="fromto" type="cylinder" size="0.1" fromto="0 0 0 0 0 1"/>
        <body name="object_1" mocap="true">
          <geom name="moving" type="cylinder" size="0.1 0.2"/>
        </body>
      </worldbody></mujoco>"""
    spec = mujoco.MjSpec.from_string(xml)
    assert cylinders_as_prisms(spec) == 1
    model = spec.compile()
    kinds = {model.geom(g).name: int(model.geom_type[g]) for g in range(model.ngeom)}
    assert kinds == {"plain": MESH, "textured": CYLINDER, "fromto": CYLINDER, "moving": CYLINDER}
