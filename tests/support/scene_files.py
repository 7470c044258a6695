"""Scene files the scene tests write: meshes (OBJ, STL) and an MJCF file."""

from __future__ import annotations

import struct
from pathlib import Path

# A unit cube with one corner at the origin (its bounding box's centre is (0.5, 0.5, 0.5)).
_CORNERS = [(x, y, z) for x in (0, 1) for y in (0, 1) for z in (0, 1)]
_QUADS = [(1, 3, 4, 2), (5, 6, 8, 7), (1, 2, 6, 5), (3, 7, 8, 4), (1, 5, 7, 3), (2, 4, 8, 6)]


def write_cube_obj(path: Path) -> Path:
    """A Wavefront OBJ of the unit cube [0, 1]^3 (quad faces)."""
    lines = [f"v {x} {y} {z}" for x, y, z in _CORNERS]
    lines += ["f " + " ".join(str(i) for i in q) for q in _QUADS]
    path.write_text("\n".join(lines) + "\n")
    return path


def write_cube_stl(path: Path) -> Path:
    """A binary STL of the unit cube [0, 1]^3 (12 triangles)."""
    tris = [(q[0], q[1], q[2]) for q in _QUADS] + [(q[0], q[2], q[3]) for q in _QUADS]
    body = b"".join(
        struct.pack("<12fH", 0, 0, 0, *(c for i in t for c in _CORNERS[i - 1]), 0) for t in tris
    )
    path.write_bytes(b"\0" * 80 + struct.pack("<I", len(tris)) + body)
    return path


# A robot-like file with its own conventions: degrees, a material, a mesh beside it
# (relative path), joints, an actuator and a keyframe.
_ARM = """<mujoco model="arm">
  <compiler angle="degree"/>
  <asset>
    <material name="red" rgba="0.9 0.1 0.1 1"/>
    <mesh name="tetra" file="tetra.obj"/>
  </asset>
  <worldbody>
    <light name="lamp" pos="0 0 3"/>
    <body name="base" pos="0 0 0">
      <geom name="base_geom" type="box" size="0.1 0.1 0.1" material="red"/>
      <body name="link" pos="0 0 0.2" euler="0 0 90">
        <joint name="hinge" type="hinge" axis="0 0 1"/>
        <geom name="link_geom" type="box" size="0.2 0.02 0.02" pos="0.2 0 0"/>
      </body>
    </body>
    <body name="tool" pos="0 0.5 0">
      <freejoint/>
      <geom name="tool_geom" type="mesh" mesh="tetra"/>
    </body>
  </worldbody>
  <actuator><motor joint="hinge"/></actuator>
  <sensor><jointpos joint="hinge"/><framepos objtype="body" objname="tool"/></sensor>
  <keyframe><key name="home" qpos="0.3 0 0.5 0 1 0 0 0"/></keyframe>
</mujoco>
"""
_TETRA = "v 0 0 0\nv 0.1 0 0\nv 0 0.1 0\nv 0 0 0.1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n"


def write_arm(folder: Path) -> Path:
    (folder / "tetra.obj").write_text(_TETRA)
    path = folder / "arm.xml"
    path.write_text(_ARM)
    return path
