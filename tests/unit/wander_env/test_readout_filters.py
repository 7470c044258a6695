"""The readout's DVS filter (noise, noise + hot pixel, flicker), timed by the slow clock,
against hand-worked cases."""

import numpy as np
import pytest

from wander_env.events import make_events
from wander_env.readout import DvsFilterParams, ReadoutParams, SpeckReadout


def _readout(**filt) -> SpeckReadout:
    params = ReadoutParams(slow_clk_rate_hz=1000, dvs_filter=DvsFilterParams(enable=True, **filt))
    ro = SpeckReadout(16, 16, params)
    ro.reset(0)
    return ro


# (x, y, t µs). The slow clock ticks every 1000 µs: ticks 0, 1, 1, 3, 3.
_CASE = ([5, 6, 9, 6, 6], [5, 5, 9, 6, 6], [0, 1000, 1500, 3000, 3500])


def _run(ro: SpeckReadout) -> np.ndarray:
    x, y, t = _CASE
    return ro.step(make_events(x, y, t, [1] * len(t)), t_us=4000)


def test_noise_filter_passes_events_with_recent_support_in_the_window():
    # 3 x 3 window, threshold 2 ticks:
    #  A (5,5) tick 0: nothing has fired -> noise.
    #  B (6,5) tick 1: A at (5,5) is in its window, 1 tick ago (< 2) -> pass.
    #  C (9,9) tick 1: nothing near -> noise.
    #  D (6,6) tick 3: A 3 ticks ago, B 2 ticks ago (not < 2) -> noise.
    #  E (6,6) tick 3: D, its own pixel, 0 ticks ago: the window includes the pixel -> pass.
    ro = _readout(filter_size=(3, 3), threshold=2)
    out = _run(ro)
    assert list(zip(out["x"].tolist(), out["t"].tolist(), strict=True)) == [(6, 1000), (6, 3500)]
    assert ro.counts["filtered_noise"] == 3 and ro.counts["filtered_hot"] == 0


def test_hot_pixel_mode_refuses_support_from_the_pixel_itself():
    # Same events: E's only support is its own pixel's D -> counted as a hot-pixel event.
    ro = _readout(filter_size=(3, 3), threshold=2, hot_pixel_filter_enable=True)
    out = _run(ro)
    assert out["t"].tolist() == [1000]
    assert ro.counts["filtered_noise"] == 3 and ro.counts["filtered_hot"] == 1


def test_a_one_pixel_window_passes_only_repeats_of_the_pixel():
    ro = _readout(filter_size=(1, 1), threshold=2)
    out = _run(ro)  # only E (D fired at its pixel in the same tick)
    assert out["t"].tolist() == [3500]


def test_a_wider_window_reaches_further():
    # 5 x 5, threshold 4: D (6,6) tick 3 sees A (5,5) at tick 0 (3 < 4) -> pass; C (9,9)
    # is 3 from (6,6): outside D's window, and D/E come after C anyway; C has no support.
    ro = _readout(filter_size=(5, 5), threshold=4)
    out = _run(ro)
    assert out["t"].tolist() == [1000, 3000, 3500]


def test_flicker_filter_blocks_a_pixel_repeating_within_the_period():
    # Datasheet example: 1 kHz slow clock, threshold 25 -> 25 ms. One pixel at 0, 10, 30,
    # 56 and 70 ms: ticks 0, 10, 30, 56, 70. Gaps 10 (< 25: blocked), 20 (blocked; the
    # memory holds the last event, filtered or not), 26 (pass), 14 (blocked).
    ro = _readout(filter_size=(0, 0), threshold=25, low_pass_mode_enable=True)
    t = [0, 10_000, 30_000, 56_000, 70_000]
    out = ro.step(make_events([3] * 5, [3] * 5, t, [1] * 5), t_us=80_000)
    assert out["t"].tolist() == [0, 56_000]
    assert ro.counts["filtered_flicker"] == 3


def test_the_slow_clock_rate_sets_the_window():
    # At 100 Hz a tick is 10 ms: A at 0 and B at 15 ms are 1 tick apart (< 2) -> B passes;
    # at 1 kHz they are 15 ticks apart -> B is noise.
    ev = make_events([5, 6], [5, 5], [0, 15_000], [1, 0])
    for rate, passed in ((100, [15_000]), (1000, [])):
        params = ReadoutParams(
            slow_clk_rate_hz=rate, dvs_filter=DvsFilterParams(enable=True, threshold=2)
        )
        ro = SpeckReadout(16, 16, params)
        ro.reset(0)
        assert ro.step(ev, t_us=20_000)["t"].tolist() == passed


def test_filter_memory_lasts_across_steps_and_clears_at_reset():
    ro = _readout(filter_size=(3, 3), threshold=5)
    ro.step(make_events([5], [5], [100], [1]), t_us=1000)
    assert len(ro.step(make_events([6], [5], [2000], [1]), t_us=3000)) == 1
    ro.reset(0)
    assert len(ro.step(make_events([6], [5], [2000], [1]), t_us=3000)) == 0


def test_one_filter_mode_at_a_time():
    with pytest.raises(ValueError, match="one mode at a time"):
        DvsFilterParams(enable=True, hot_pixel_filter_enable=True, low_pass_mode_enable=True)
    with pytest.raises(ValueError, match="filter_size"):
        DvsFilterParams(enable=True, filter_size=(0, 3))
