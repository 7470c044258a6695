"""The camera model (wander_env.camera): Speck's field of view, the pinhole's
pixel <-> angle conversions and their checks."""

from __future__ import annotations

import math

import numpy as np
import pytest

from wander_env.camera import SPECK_HFOV_DEG, degrees_to_pixels, focal_length_px, pixels_to_degrees


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
    with pytest.raises(ValueError, match="hfov_deg"):
        pixels_to_degrees(1, 128, hfov_deg=180.0)
    with pytest.raises(ValueError, match="width_px"):
        degrees_to_pixels(1.0, 0)
