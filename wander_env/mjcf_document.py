"""One MJCF document under construction, and the helpers every scene part writes through.

:class:`MJCFDocument` holds the ``<mujoco>`` root, its ``<asset>`` section and the
in-memory assets (PNG textures, mesh files); its helpers write elements with numbers
formatted by :func:`fmt`, numbered materials (optionally textured), meshes and a prop's
geom of any shape. The scene's parts (:mod:`wander_env.entities`) attach into it;
:class:`wander_env.mjcf.Arena` composes them.

Examples:
    >>> doc = MJCFDocument("demo")
    >>> body = doc.element(doc.open_world(), "body", name="b", pos=(0, 0, 0.5))
    >>> _ = doc.geom(body, type="sphere", size=0.1, material=doc.material((1, 0, 0, 1)))
    >>> print(doc.text())  # doctest: +NORMALIZE_WHITESPACE
    <mujoco model="demo">
      <asset>
        <material name="mat_1" rgba="1 0 0 1" specular="0.05" shininess="0.1"
                  reflectance="0" emission="0" />
      </asset>
      <worldbody>
        <body name="b" pos="0 0 0.5">
          <geom type="sphere" size="0.1" material="mat_1" />
        </body>
      </worldbody>
    </mujoco>
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from collections.abc import Iterable, Sequence
from pathlib import Path

import mujoco
import numpy as np

from wander_env.scene_parts import MeshConfig
from wander_env.textures import TextureSpec, add_png_asset, make_texture

__all__ = ["MJCFDocument", "fmt"]


def fmt(values: float | Iterable[float]) -> str:
    """MJCF text for a number or a vector (6 significant digits).

    >>> fmt(0.5), fmt((1, 2.0, 1 / 3))
    ('0.5', '1 2 0.333333')
    """
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
    """The face size (m) a texture's ``tile_m`` is measured against, per shape (a mesh:
    its bounding box's extents, as a box)."""
    if shape in ("box", "mesh"):
        s = sorted(size, reverse=True)
        return (s[0], s[1])
    if shape == "sphere":
        return (math.pi * size[0], math.pi * size[0] / 2.0)
    return (math.pi * size[0], size[1])


class MJCFDocument:
    """One MJCF document under construction: the ``<mujoco>`` root, its ``<asset>``
    section with the in-memory assets, and the helpers every entity attaches through
    (materials are numbered ``mat_1``, ``mat_2``, ... in the order they are made)."""

    def __init__(self, model_name: str) -> None:
        self.root = ET.Element("mujoco")
        self.root.set("model", model_name)
        self.asset = ET.SubElement(self.root, "asset")
        self.assets: dict[str, bytes] = {}
        self._world: ET.Element | None = None
        self._n_materials = 0
        self._n_meshes = 0

    def open_world(self) -> ET.Element:
        """Append the ``<worldbody>`` (after the header sections) and return it."""
        if self._world is not None:
            raise RuntimeError("the worldbody is already open")
        self._world = ET.SubElement(self.root, "worldbody")
        return self._world

    @property
    def world(self) -> ET.Element:
        """The ``<worldbody>`` (see :meth:`open_world`)."""
        if self._world is None:
            raise RuntimeError("open_world() first: the header sections come before it")
        return self._world

    def element(self, parent: ET.Element, tag: str, **attrs: object) -> ET.Element:
        """A child element; numbers and vectors are formatted with :func:`fmt`."""
        return ET.SubElement(
            parent, tag, **{k: v if isinstance(v, str) else fmt(v) for k, v in attrs.items()}
        )

    def geom(self, parent: ET.Element, **attrs: object) -> ET.Element:
        """A geom with formatted attributes."""
        return self.element(parent, "geom", **attrs)

    def png_texture(self, name: str, image: np.ndarray, ttype: str = "2d") -> None:
        """An in-memory PNG asset and the ``<texture>`` that names it."""
        file = add_png_asset(self.assets, name, image)
        ET.SubElement(self.asset, "texture", name=name, type=ttype, file=file)

    def mesh(self, mesh: MeshConfig) -> tuple[str, np.ndarray, np.ndarray]:
        """A ``<mesh>`` asset of ``mesh`` (its file's bytes in memory, ``mesh_N.EXT``):
        (its name, the (min, max) corners (m) of its scaled bounding box in its frame)."""
        self._n_meshes += 1
        name = f"mesh_{self._n_meshes}"
        path = Path(mesh.file)
        file = f"{name}{path.suffix.lower()}"
        self.assets[file] = mesh.data
        lo, hi = mesh.bounds()
        # "shell" inertia: MuJoCo then also takes open and flat meshes (nothing here has mass)
        self.element(
            self.asset, "mesh", name=name, file=file, scale=mesh.scale_xyz, inertia="shell"
        )
        return name, lo, hi

    def shape_geom(
        self,
        parent: ET.Element,
        shape: str,
        size: Sequence[float],
        mesh: MeshConfig | None,
        rgba: Sequence[float],
        texture: TextureSpec | None,
        **attrs: object,
    ) -> ET.Element:
        """A prop's geom and its material: a box, sphere or cylinder of full extents
        ``size``, or ``mesh`` with its bounding box's centre at the geom's ``pos``
        (default the parent's origin), turned by ``euler`` (rad, when given)."""
        if mesh is None:
            mat = self.material(rgba, texture, _texture_face(shape, size), cube=shape != "box")
            return self.geom(
                parent, type=shape, size=_half_size(shape, size), material=mat, **attrs
            )
        name, lo, hi = self.mesh(mesh)
        mat = self.material(rgba, texture, _texture_face("mesh", hi - lo), cube=True)
        centre = (lo + hi) / 2.0
        quat = np.array([1.0, 0.0, 0.0, 0.0])
        if "euler" in attrs:
            mujoco.mju_euler2Quat(quat, np.asarray(attrs["euler"], float), "xyz")
        rot = np.zeros(9)
        mujoco.mju_quat2Mat(rot, quat)
        pos = np.asarray(attrs.pop("pos", (0.0, 0.0, 0.0)), float) - rot.reshape(3, 3) @ centre
        return self.geom(parent, type="mesh", mesh=name, pos=pos, material=mat, **attrs)

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
            "rgba": fmt(rgba),
            "specular": "0.05",
            "shininess": "0.1",
            "reflectance": "0",
            "emission": fmt(emission),
        }
        if texture is not None:
            tex = f"tex_{self._n_materials}"
            self.png_texture(tex, make_texture(texture), "cube" if cube else "2d")
            attrs["texture"] = tex
            attrs["texrepeat"] = fmt(texture.texrepeat(face))
        ET.SubElement(self.asset, "material", **attrs)
        return name

    def text(self) -> str:
        """The document as indented XML text."""
        ET.indent(self.root)
        return ET.tostring(self.root, encoding="unicode")
