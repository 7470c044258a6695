"""The camera model (wander_env.camera): Speck's field of view, the pinhole's
pixel <-> angle conversions and their checks."""

from __future__ import annotations

import math

import numpy as np
import pytest

from wander_env.camera import (
    SPECK_HFOV_DEG,
    check_hfov_deg,
    degrees_to_pixels,
    focal_length_px,
    pixel_to_rotation,
    pixels_to_degrees,
)


def test_speck_field_of_view():
    assert SPECK_HFOV_DEG == pytest.approx(math.degrees(2 * math.atan(5.12 / 3.4)))
    assert SPECK_HFOV_DEG == pytest.approx(112.8267, abs=1e-4)
    # f = 1.7 mm over a 40 µm pixel pitch (5.12 mm / 128).
    assert focal_length_px(128) == pytest.approx(42.5)


def test_pixels_degrees_pinhole():
    assert pixels_to_degrees(0.0, 128) == 0.0
    assert pixels_to_degrees(64, 128) == pytest.approx(SPECK_HFOV_DEG / 2)
    assert pixels_to_degrees(-64, 128) == pytest.approx(-SPECK_HFOV_DEG / 2)
    assert pixels_to_degrees(1, 128) == pytest.approx(math.degrees(math.atan(1 / 42.5)))
    assert degrees_to_pixels(45.0, 100, hfov_deg=90.0) == pytest.approx(50.0)
    assert isinstance(pixels_to_degrees(3, 128), float)


def test_pixels_degrees_round_trip_on_arrays():
    px = np.linspace(-64, 64, 17)
    deg = pixels_to_degrees(px, 128)
    assert isinstance(deg, np.ndarray) and deg.shape == px.shape
    np.testing.assert_allclose(degrees_to_pixels(deg, 128), px, atol=1e-9)


def test_angle_conversions_reject_bad_geometry():
    with pytest.raises(ValueError, match=r"^hfov_deg: must be in \(0, 180\) degrees, got 180.0$"):
        pixels_to_degrees(1, 128, hfov_deg=180.0)
    with pytest.raises(ValueError, match="width_px"):
        degrees_to_pixels(1.0, 0)


def test_pixel_to_rotation_puts_the_pixels_ray_on_the_optical_axis():
    """Rotate a pan-tilt camera by the returned angles: its new forward axis is the ray
    that went through the pixel (to 1e-9), for pixels anywhere and any starting tilt."""
    f = focal_length_px(128)

    def axes(pan_deg: float, tilt_deg: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        p, t = np.radians(pan_deg), np.radians(tilt_deg)  # world: x forward, y left, z up
        fwd = np.array([np.cos(t) * np.cos(p), np.cos(t) * np.sin(p), np.sin(t)])
        right = np.array([np.sin(p), -np.cos(p), 0.0])
        up = np.cross(right, fwd)
        return fwd, right, up

    rng = np.random.default_rng(0)
    for _ in range(50):
        dx, dy = rng.uniform(-64, 64, 2)
        pan0, tilt0 = rng.uniform(-90, 90), rng.uniform(-40, 40)
        fwd, right, up = axes(pan0, tilt0)
        ray = f * fwd + dx * right - dy * up
        dpan, dtilt = pixel_to_rotation(dx, dy, tilt0)
        new_fwd, _, _ = axes(pan0 + dpan, tilt0 + dtilt)
        assert np.allclose(new_fwd, ray / np.linalg.norm(ray), atol=1e-9)
    # Near the centre it agrees with converting each axis alone; at a corner it does not.
    assert pixel_to_rotation(1.0, 1.0, 0.0) == pytest.approx(
        (-np.degrees(np.arctan(1 / f)), -np.degrees(np.arctan(1 / f))), abs=1e-3
    )
    assert abs(pixel_to_rotation(64.0, 64.0, 0.0)[1] + np.degrees(np.arctan(64 / f))) > 10


@pytest.mark.parametrize("value", [1e-9, 90, 179.999])
def test_check_hfov_deg_takes_the_open_interval(value):
    assert check_hfov_deg(value) == value


@pytest.mark.parametrize("value", [0, 0.0, -1.0, 180, 180.0, 200.0, math.nan, math.inf, True, "90"])
def test_check_hfov_deg_names_the_field_and_the_value(value):
    with pytest.raises(ValueError) as info:
        check_hfov_deg(value, "RigConfig.hfov_deg")
    assert str(info.value) == f"RigConfig.hfov_deg: must be in (0, 180) degrees, got {value!r}"
