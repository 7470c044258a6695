"""Fitting background activity and hot pixels to a recording (experiments.benchmark.noise_fit)."""

import numpy as np
import pytest

from experiments.benchmark.noise_fit import IEBCS_FREQ_HZ, fit_noise, rates_from_interval_histogram
from wander_env.events import make_events


def _recording() -> np.ndarray:
    """2 s on a 10 x 10 sensor: a hot pixel (2, 2) at 100 Hz ON; four isolated events
    (two ON, two OFF, far apart in space and time); a pair at (7, 7) and (8, 7) 1 ms apart
    (the second is supported)."""
    rows = [(2, 2, t, 1) for t in range(0, 2_000_000, 10_000)]
    rows += [(5, 0, 100_001, 1), (0, 8, 500_001, 1), (9, 4, 900_001, 0), (4, 9, 1_300_001, 0)]
    rows += [(7, 7, 1_600_001, 0), (8, 7, 1_601_001, 0)]
    rows.sort(key=lambda r: r[2])
    x, y, t, p = zip(*rows, strict=True)
    return make_events(x, y, t, p)


def test_hot_pixels_and_background_rates_are_counted_exactly():
    fit = fit_noise(_recording(), (10, 10), duration_s=2.0)
    assert fit.hot_pixels == ((2, 2),) and fit.hot_rates_hz == (100.0,)
    # Background over the 99 other pixels and 2 s: ON 2 events, OFF 3 (the pair's first).
    assert fit.background_on_hz == pytest.approx(2 / (99 * 2.0), rel=1e-12)
    assert fit.background_off_hz == pytest.approx(3 / (99 * 2.0), rel=1e-12)
    assert fit.rate_hz[7, 8] == 0.5 and fit.rate_hz.shape == (10, 10)


def test_the_fit_as_emulator_terms():
    fit = fit_noise(_recording(), (10, 10), duration_s=2.0)
    terms = fit.dvs_overrides()
    assert terms["shot_rate_hz"] == pytest.approx(2 * 3 / 198, rel=1e-12)
    assert terms["leak_rate_hz"] == 0.0  # fewer ON than OFF
    assert terms["hot_pixel_fraction"] == 0.01 and terms["hot_pixel_rate_hz"] == 100.0


def test_a_busy_neighbourhood_is_not_a_hot_pixel():
    # A 3 x 3 block all at 100 Hz: each pixel's neighbours fire as fast -> none is hot.
    rows = [
        (x, y, t + 3 * y + x, 1)
        for t in range(0, 1_000_000, 10_000)
        for y in range(3)
        for x in range(3)
    ]
    x, y, t, p = zip(*rows, strict=True)
    fit = fit_noise(make_events(x, y, t, p), (6, 6), duration_s=1.0)
    assert fit.hot_pixels == ()


def test_bad_recordings_are_refused():
    with pytest.raises(ValueError, match="no events"):
        fit_noise(make_events([], [], [], []), (4, 4))
    with pytest.raises(ValueError, match="outside the 4x4 sensor"):
        fit_noise(make_events([4], [0], [0], [1]), (4, 4), duration_s=1.0)
    with pytest.raises(ValueError, match="sorted"):
        fit_noise(make_events([0, 0], [0, 0], [5, 1], [1, 1]), (4, 4))


def test_interval_histograms_give_the_inverse_mean_interval():
    h = np.zeros((2, 72))
    h[0, 27:] = 3  # three intervals of 1 s (1 Hz bin) ...
    h[0, 45:] = 4  # ... and one of 1/100 s (100 Hz bin): mean 0.7525 s
    h[:, -1] = 0  # IEBCS's unused last element; row 1 has no data
    assert IEBCS_FREQ_HZ[27] == 1.0 and IEBCS_FREQ_HZ[45] == 100.0
    rates = rates_from_interval_histogram(h)
    assert rates[0] == pytest.approx(1 / 0.7525, rel=1e-12) and rates[1] == 0.0
