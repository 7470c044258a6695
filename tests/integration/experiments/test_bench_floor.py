"""``wander perf floor``: every part timed, the bounds from the parts, the panorama's
cube map sampled where its rays point (exact expectations)."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest
from typer.testing import CliRunner

from experiments.cli.main import app
from experiments.perf.floor import render_floor
from wander_env.frames.cube import cube_warp


def test_cube_warp_samples_the_face_the_rays_point_at() -> None:
    """Looking down +z with no rotation, every ray of a 90-degree view lands on the +z
    face (index 4); one face per constant value gives that value everywhere, with one
    bilinear sample or 2 x 2 nearest ones."""
    faces = np.stack([np.full((8, 8), float(k), np.float32) for k in range(6)])
    out = np.empty((4, 4), np.float32)
    f = 2.0 / math.tan(math.radians(45))
    for s, bilinear in ((1, True), (2, False)):
        cube_warp(out, faces, np.eye(3), f, 1.5, 1.5, s, bilinear)
        assert np.all(out == 4.0)
    turn = np.array([[0.0, 0, 1], [0, 1, 0], [-1, 0, 0]])  # +z of the camera to world +x
    cube_warp(out, faces, turn, f, 1.5, 1.5, 1, False)
    assert np.all(out == 0.0)


@pytest.mark.slow
def test_render_floor_times_every_part_and_bounds_each_step() -> None:
    rows, bounds = render_floor(scene="shelf", calls=2, repeats=1)
    assert len(rows) == 11 and all(r.ms_median > 0 for r in rows)
    assert rows[2].part == "key geometry by ray casting (wander_env.frames.raycast)"
    colour, geometry = rows[0].ms_median, rows[1].ms_median
    by = {b.step: b for b in bounds}
    still = by["default, still camera, ground truth on"]
    assert still.gl_ms == pytest.approx(2 * colour + geometry)
    assert still.rtf_bound == pytest.approx(10.0 / still.gl_ms)
    # Beside each wall time, the CPU time of the same runs and the load average.
    assert still.gl_cpu_ms == pytest.approx(2 * rows[0].cpu_ms_median + rows[1].cpu_ms_median)
    load = r"^\d+\.\d\d-\d+\.\d\d$"
    assert all(re.match(load, r.load) and r.cpu_ms_median >= 0 for r in rows)
    assert all(re.match(load, b.load) for b in bounds)


@pytest.mark.slow
def test_bench_floor_prints_both_tables() -> None:
    result = CliRunner().invoke(
        app, ["perf", "floor", "--scene", "shelf", "--calls", "1", "--repeats", "1"]
    )
    assert result.exit_code == 0, result.output
    assert "colour key" in result.output and "real-time factor" in result.output
    assert "load average" in result.output
