"""``wander perf panorama``: every frame mode timed on both motions, the background
compared with a render for each way of lighting the faces (exact expectations)."""

from __future__ import annotations

import math

import pytest
from typer.testing import CliRunner

from experiments.cli.main import app
from experiments.perf.panorama import VARIANTS, headlight_rows, step_rows


@pytest.mark.slow
def test_step_rows_time_every_mode_on_both_motions_against_the_default() -> None:
    rows = step_rows("shelf", 1)
    assert [(r.motion, r.frames) for r in rows] == [
        (m, name) for m in ("still", "walk") for name in VARIANTS
    ]
    assert [r.x_default for r in rows if r.frames == "keyframes (default)"] == [1.0, 1.0]
    assert all(r.ms_per_step > 0 and math.isfinite(r.reset_ms) for r in rows)


@pytest.mark.slow
def test_headlight_rows_and_the_command() -> None:
    rows = headlight_rows("shelf")
    assert [r.headlight for r in rows] == ["camera", "face", "off"]
    camera, face, _ = rows
    assert camera.median < face.median  # the headlight held along the camera's axis
    result = CliRunner().invoke(app, ["perf", "panorama", "--scene", "shelf", "--steps", "1"])
    assert result.exit_code == 0, result.output
    assert "panorama, 4x4 bilinear rays" in result.output and "lum panorama" in result.output
