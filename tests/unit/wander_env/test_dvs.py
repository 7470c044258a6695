"""The DVS emulator against exact expectations of its pixel model."""

from __future__ import annotations

import math

import numpy as np
import pytest

from wander_env.dvs import DVSEmulator, DVSParams, linlog, luminance_tables, srgb_to_linear
from wander_env.events import check_sorted


def one_pixel(th: float = 0.2, **kw) -> DVSEmulator:
    emu = DVSEmulator(1, 1, DVSParams(threshold_on=th, threshold_off=th, **kw))
    emu.reset(np.full((1, 1), 0.5), t_us=0)
    return emu


def level(log_change: float) -> np.ndarray:
    """A 1×1 float frame whose log intensity is ln(0.5) + log_change."""
    return np.full((1, 1), 0.5 * math.exp(log_change))


# -- the change detector ------------------------------------------------------------------


@pytest.mark.parametrize("k", [1, 2, 3, 7])
def test_ramp_of_k_thresholds_gives_k_events_spaced_along_the_ramp(k):
    emu = one_pixel(th=0.2)
    ev = emu.step(level(0.2 * k), t_us=1000)
    assert len(ev) == k
    assert set(ev["p"].tolist()) == {1}
    expected = [round(1000 * j / k) for j in range(1, k + 1)]
    assert ev["t"].tolist() == expected


def test_falling_ramp_gives_off_events():
    emu = one_pixel(th=0.2)
    ev = emu.step(level(-0.6), t_us=900)
    assert ev["p"].tolist() == [0, 0, 0]
    assert ev["t"].tolist() == [300, 600, 900]


def test_residual_change_carries_over_to_the_next_frame():
    emu = one_pixel(th=0.2)
    first = emu.step(level(0.3), t_us=1000)  # crosses 0.2 at 2/3 of the interval
    second = emu.step(level(0.6), t_us=2000)  # 0.4 at 1/3, 0.6 at the end
    assert first["t"].tolist() == [667]
    assert second["t"].tolist() == [1333, 2000]


def test_on_and_off_thresholds_are_separate():
    emu = DVSEmulator(1, 1, DVSParams(threshold_on=0.1, threshold_off=0.3))
    emu.reset(np.full((1, 1), 0.5), 0)
    assert len(emu.step(level(0.5), 1000)) == 5
    assert len(emu.step(level(-0.1), 2000)) == 2  # fell by 0.6 from the last ON level 0.5


def test_refractory_period_drops_crossings_too_close_to_the_last_event():
    emu = one_pixel(th=0.1, refractory_us=250.0)
    ev = emu.step(level(1.0), t_us=1000)  # 10 crossings, 100 µs apart
    assert ev["t"].tolist() == [100, 400, 700, 1000]


def test_an_integer_refractory_period_runs_the_same_compiled_kernel():
    from wander_env.dvs import _emit

    assert type(DVSParams(refractory_us=250).refractory_us) is float
    events = []
    for refractory in (250, 250.0):  # an int, as Python code may give it
        emu = one_pixel(th=0.1, refractory_us=refractory)
        events.append(emu.step(level(1.0), t_us=1000)["t"].tolist())
    assert events == [[100, 400, 700, 1000]] * 2
    assert {str(sig[6]) for sig in _emit.signatures} == {"float64"}


def test_refractory_period_caps_the_rate_of_a_flickering_pixel():
    emu = DVSEmulator(8, 8, DVSParams(threshold_on=0.05, threshold_off=0.05, refractory_us=1000))
    emu.reset(np.full((8, 8), 0.2), 0)
    n = 0
    for i in range(1, 201):  # 200 ms of a 1 kHz-sampled flicker between 0.2 and 0.8
        n += len(emu.step(np.full((8, 8), 0.8 if i % 2 else 0.2), i * 1000))
    assert n <= 64 * 200  # at most one event per pixel per refractory period
    assert n == 64 * 197  # each pixel: 197 of the 200 flips (measured)


def test_static_scene_with_noise_off_emits_nothing():
    params = DVSParams.preset("paper", leak_rate_hz=0.0, shot_rate_hz=0.0)
    emu = DVSEmulator(32, 24, params, seed=3)
    rng = np.random.default_rng(0)
    frame = rng.integers(0, 256, (24, 32, 3), dtype=np.uint8)
    emu.reset(frame, 0)
    assert sum(len(emu.step(frame, i * 1000)) for i in range(1, 301)) == 0
    assert emu.pending == 0


def test_max_log_change_reports_the_largest_input_change():
    emu = DVSEmulator(2, 1)
    emu.reset(np.array([[0.5, 0.5]]), 0)
    frame = np.array([[0.5, 0.25]])
    assert emu.log_change(frame) == pytest.approx(math.log(2), abs=1e-6)
    emu.step(frame, 1000)
    assert emu.max_log_change == pytest.approx(math.log(2), abs=1e-6)
    emu.step(frame, 2000)
    assert emu.max_log_change == 0.0


# -- luminance and log ----------------------------------------------------------------------


def test_srgb_curve_is_undone():
    assert srgb_to_linear(np.array([0.0, 0.5, 1.0])) == pytest.approx(
        [0.0, 0.214041, 1.0], abs=1e-6
    )


def test_one_luminance_table_float32_weighted_in_float32():
    """The emulator's table (and the panorama cube map's, wander_env.frames.cube): each
    code's linear light in float32, times the float32 Rec. 709 weights."""
    lut, wlut = luminance_tables()
    expected_lut = srgb_to_linear(np.arange(256) / 255.0).astype(np.float32)
    assert lut.dtype == wlut.dtype == np.float32 and wlut.shape == (3, 256)
    assert np.array_equal(lut, expected_lut)
    assert np.array_equal(wlut, np.float32([0.2126, 0.7152, 0.0722])[:, None] * expected_lut)
    assert np.array_equal(DVSEmulator(2, 2).channel_luminance, wlut)


def test_linlog_is_finite_at_black_and_continuous_at_the_knee():
    y = linlog(np.array([0.0, 0.01 - 1e-9, 0.01, 0.5]), 0.01)
    assert np.isfinite(y).all()
    assert y[0] == pytest.approx(math.log(0.01) - 1.0)
    assert y[1] == pytest.approx(y[2], abs=1e-6)
    assert y[3] == pytest.approx(math.log(0.5))


def test_rgb_frame_uses_linear_luminance():
    emu = DVSEmulator(1, 1, DVSParams(threshold_on=0.1, threshold_off=0.1))
    grey = np.full((1, 1, 3), 200, np.uint8)
    emu.reset(grey, 0)
    green = np.array([[[0, 200, 0]]], np.uint8)
    # Pure green keeps 0.7152 of the luminance: ln(0.7152) = -0.335 -> 3 OFF events.
    ev = emu.step(green, 1000)
    assert ev["p"].tolist() == [0, 0, 0]
    assert emu.max_log_change == pytest.approx(-math.log(0.7152), abs=1e-4)


def test_grey_uint8_frame_equals_rgb_grey():
    rng = np.random.default_rng(1)
    frames = rng.integers(0, 256, (5, 6, 7), dtype=np.uint8)
    a, b = DVSEmulator(7, 6), DVSEmulator(7, 6)
    a.reset(frames[0], 0)
    b.reset(np.repeat(frames[0][:, :, None], 3, axis=2), 0)
    for i in range(1, 5):
        ea = a.step(frames[i], i * 1000)
        eb = b.step(np.repeat(frames[i][:, :, None], 3, axis=2), i * 1000)
        assert np.array_equal(ea, eb)


def _code_to_linear() -> np.ndarray:
    """The linear light of each 8-bit code, float32 (what the emulator's tables hold)."""
    return srgb_to_linear(np.arange(256) / 255.0).astype(np.float32)


def _reference_luminance(rgb: np.ndarray) -> np.ndarray:
    """Per-pixel Rec. 709 luminance of uint8 sRGB, float32, summed R + G + B: the
    emulator's conversion written out with NumPy (no lookup of weighted shares)."""
    lin = _code_to_linear()
    w = np.float32([0.2126, 0.7152, 0.0722])
    return w[0] * lin[rgb[..., 0]] + w[1] * lin[rgb[..., 1]] + w[2] * lin[rgb[..., 2]]


def _events_and_changes(emu: DVSEmulator, frames) -> tuple[np.ndarray, list[float]]:
    """All events (every third frame through prepare/log_change) and max_log_change."""
    emu.reset(frames[0], 0)
    out, changes = [], []
    for i in range(1, len(frames)):
        f = emu.prepare(frames[i]) if i % 3 == 0 else frames[i]
        out.append(emu.step(f, i * 1000))
        changes.append(emu.max_log_change)
    out.append(emu.flush())
    return np.concatenate(out), changes


@pytest.mark.parametrize("preset", ["ideal", "paper", "speck"])
def test_uint8_srgb_gives_exactly_the_events_of_its_linear_luminance(preset):
    # Colour noise over every code: the lookup tables must reproduce the per-pixel
    # conversion bit for bit, so the events (noise included, same seed) are identical.
    rng = np.random.default_rng(2)
    rgb = rng.integers(0, 256, (12, 24, 32, 3), dtype=np.uint8)
    linear = _reference_luminance(rgb)
    assert linear.dtype == np.float32
    params = DVSParams.preset(preset)
    ea, ca = _events_and_changes(DVSEmulator(32, 24, params, seed=4), rgb)
    eb, cb = _events_and_changes(DVSEmulator(32, 24, params, seed=4), linear)
    assert len(ea) > 1000
    assert np.array_equal(ea, eb)
    assert ca == cb


def test_uint8_grey_gives_exactly_the_events_and_log_of_its_linear_light():
    # Every code, both below and above the linear segment's knee (code 25 ≈ 0.0097).
    rng = np.random.default_rng(3)
    grey = rng.integers(0, 256, (12, 16, 16), dtype=np.uint8)
    grey[0] = np.arange(256, dtype=np.uint8).reshape(16, 16)
    linear = _code_to_linear()[grey]
    emu = DVSEmulator(16, 16, DVSParams.preset("paper"), seed=1)
    a, b = emu.prepare(grey[0]), emu.prepare(linear[0])
    assert np.array_equal(a.lum, b.lum) and np.array_equal(a.log_in, b.log_in)
    ea, ca = _events_and_changes(DVSEmulator(16, 16, DVSParams(), seed=1), grey)
    eb, cb = _events_and_changes(DVSEmulator(16, 16, DVSParams(), seed=1), linear)
    assert len(ea) > 1000
    assert np.array_equal(ea, eb)
    assert ca == cb


def test_photoreceptor_lowpass_is_faster_for_brighter_pixels():
    params = DVSParams(threshold_on=0.01, threshold_off=0.01, cutoff_hz=100.0, cutoff_dark=0.0)
    emu = DVSEmulator(2, 1, params)
    emu.reset(np.array([[0.05, 0.5]]), 0)
    # Both pixels double; in 1 ms the filter covers 1 - exp(-2π·fc·dt) of ln 2.
    ev = emu.step(np.array([[0.1, 1.0]]), 1000)
    counts = np.bincount(ev["x"], minlength=2)
    for x, intensity in ((0, 0.1), (1, 1.0)):
        reached = (1 - math.exp(-2 * math.pi * 100.0 * intensity * 1e-3)) * math.log(2)
        assert counts[x] == math.floor(reached / 0.01 + 1e-5)
    assert counts[1] > 5 * counts[0]


# -- latency, noise, mismatch -------------------------------------------------------------------


def test_latency_delays_events_and_holds_them_for_the_next_call():
    emu = one_pixel(th=0.2, latency_us=300.0)
    first = emu.step(level(0.4), 1000)  # crossings at 500 and 1000 -> 800 and 1300
    assert first["t"].tolist() == [800]
    assert emu.pending == 1
    second = emu.step(level(0.4), 2000)
    assert second["t"].tolist() == [1300]
    emu.step(level(0.6), 2100)  # a crossing at 2100 -> 2400, after the last frame
    assert emu.flush()["t"].tolist() == [2400]


def test_jitter_keeps_the_stream_sorted_and_never_early():
    params = DVSParams(threshold_on=0.05, threshold_off=0.05, latency_us=20, jitter_us=30)
    emu = DVSEmulator(16, 16, params, seed=0)
    rng = np.random.default_rng(0)
    emu.reset(rng.uniform(0.1, 1, (16, 16)), 0)
    chunks = [emu.step(rng.uniform(0.1, 1, (16, 16)), i * 1000) for i in range(1, 50)]
    chunks.append(emu.flush())
    stream = np.concatenate(chunks)
    check_sorted(stream)
    for i, c in enumerate(chunks[:-1]):
        assert (c["t"] > i * 1000).all() and (c["t"] <= (i + 1) * 1000).all()


@pytest.mark.parametrize(
    ("field", "rate", "on_fraction"),
    [("leak_rate_hz", 5.0, 1.0), ("shot_rate_hz", 5.0, 0.5)],
)
def test_background_rate_matches_the_requested_rate(field, rate, on_fraction):
    emu = DVSEmulator(64, 64, DVSParams(**{field: rate}), seed=7)
    frame = np.full((64, 64), 0.3)
    emu.reset(frame, 0)
    ev = np.concatenate([emu.step(frame, i * 10_000) for i in range(1, 1001)])  # 10 s
    measured = len(ev) / (10.0 * 64 * 64)
    assert measured == pytest.approx(rate, rel=0.10)
    assert ev["p"].mean() == pytest.approx(on_fraction, abs=0.02)


def test_leak_events_of_one_pixel_are_periodic():
    emu = DVSEmulator(1, 1, DVSParams(leak_rate_hz=10.0), seed=0)
    emu.reset(np.full((1, 1), 0.3), 0)
    ev = np.concatenate([emu.step(np.full((1, 1), 0.3), i * 1000) for i in range(1, 1001)])
    assert len(ev) == 10  # a random phase (seed 0) puts the first at 36.3 ms
    assert np.diff(ev["t"]) == pytest.approx(100_000, abs=2)


def test_hot_pixels_fire_at_their_rate_and_are_the_requested_fraction():
    params = DVSParams(hot_pixel_fraction=0.01, hot_pixel_rate_hz=100.0)
    emu = DVSEmulator(100, 100, params, seed=2)
    frame = np.full((100, 100), 0.3)
    emu.reset(frame, 0)
    ev = np.concatenate([emu.step(frame, i * 10_000) for i in range(1, 201)])  # 2 s
    assert len(emu.hot_pixels) == 100
    assert set((ev["y"].astype(int) * 100 + ev["x"]).tolist()) <= set(emu.hot_pixels.tolist())
    assert len(ev) / (2.0 * 100) == pytest.approx(100.0, rel=0.10)


def test_threshold_mismatch_has_the_requested_spread():
    params = DVSParams(threshold_on=0.3, threshold_off=0.25, threshold_sigma=0.03)
    emu = DVSEmulator(128, 128, params, seed=5)
    assert emu.th_on.mean() == pytest.approx(0.3, abs=0.001)
    assert emu.th_off.mean() == pytest.approx(0.25, abs=0.001)
    assert emu.th_on.std() == pytest.approx(0.03, rel=0.05)
    assert emu.th_off.std() == pytest.approx(0.03, rel=0.05)


def moving_pattern(n: int, w: int = 48, h: int = 32) -> list[np.ndarray]:
    rng = np.random.default_rng(11)
    base = rng.integers(30, 230, (h, w + n, 3), dtype=np.uint8)
    return [np.ascontiguousarray(base[:, i : i + w]) for i in range(n)]


def run_stream(params: DVSParams, seed: int, frames: list[np.ndarray]) -> np.ndarray:
    emu = DVSEmulator(frames[0].shape[1], frames[0].shape[0], params, seed=seed)
    emu.reset(frames[0], 0)
    out = [emu.step(f, i * 1000) for i, f in enumerate(frames[1:], start=1)]
    return np.concatenate([*out, emu.flush()])


def test_same_seed_gives_identical_events_and_another_seed_does_not():
    frames = moving_pattern(20)
    params = DVSParams.preset("speck", shot_rate_hz=50.0)
    a, b, c = (run_stream(params, s, frames) for s in (42, 42, 43))
    assert len(a) > 1000
    assert np.array_equal(a, b)
    assert not np.array_equal(a, c)


def test_events_are_spread_between_frames_not_on_frame_times():
    ev = run_stream(DVSParams.preset("ideal"), 0, moving_pattern(20))
    on_frame_time = np.mean(ev["t"] % 1000 == 0)
    assert on_frame_time < 0.2


# -- bad input ------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("frame", "message"),
    [
        (np.full((4, 4), np.nan), "NaN"),
        (np.full((4, 5), 0.5), "shape"),
        (np.full((4, 4, 3), 0.5), "shape"),
        (np.full((4, 4), 5, np.int32), "dtype"),
        (np.full((4, 4), -0.1), ">= 0"),
    ],
)
def test_bad_frames_raise_and_change_nothing(frame, message):
    good = DVSEmulator(4, 4, DVSParams(threshold_on=0.1, threshold_off=0.1))
    emu = DVSEmulator(4, 4, DVSParams(threshold_on=0.1, threshold_off=0.1))
    for e in (good, emu):
        e.reset(np.full((4, 4), 0.5), 0)
    with pytest.raises(ValueError, match=message):
        emu.step(frame, 1000)
    bright = np.full((4, 4), 0.9)
    assert np.array_equal(emu.step(bright, 1000), good.step(bright, 1000))


@pytest.mark.parametrize("t_us", [0, -5])
def test_time_must_increase(t_us):
    emu = one_pixel()
    with pytest.raises(ValueError, match="time must increase"):
        emu.step(level(1.0), t_us)
    assert len(emu.step(level(0.2), 10)) == 1


def test_bad_params_name_the_field():
    with pytest.raises(ValueError, match="threshold_on"):
        DVSParams(threshold_on=0.0)
    with pytest.raises(ValueError, match="jitter_us"):
        DVSParams(jitter_us=float("nan"))
    with pytest.raises(ValueError, match="unknown DVS preset 'davis'"):
        DVSParams.preset("davis")


def test_paper_preset_has_the_papers_iebcs_values():
    p = DVSParams.preset("paper")
    assert (p.threshold_on, p.threshold_off, p.threshold_sigma) == (0.1, 0.1, 0.01)
    assert (p.latency_us, p.jitter_us, p.refractory_us) == (100.0, 10.0, 100.0)
    assert 1 / (2 * math.pi * p.cutoff_hz) == pytest.approx(300e-6)
