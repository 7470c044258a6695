"""The readout's kill mask and DVS layer (polarity, sum pooling, region, mirroring)
against hand-made event arrays."""

import numpy as np
import pytest

from wander_env.events import make_events
from wander_env.readout import DvsLayerParams, ReadoutParams, SpeckReadout

# Five events on an 8 x 8 array: (x, y, p).
_X, _Y, _P = [0, 3, 5, 7, 6], [0, 1, 2, 7, 4], [1, 0, 1, 0, 1]


def _run(width=8, height=8, **params) -> tuple[np.ndarray, SpeckReadout]:
    ro = SpeckReadout(width, height, ReadoutParams(**params))
    ro.reset(0)
    ev = make_events(_X, _Y, [1, 2, 3, 4, 5], _P)
    return ro.step(ev, t_us=10), ro


def _xyp(ev: np.ndarray) -> list[tuple[int, int, int]]:
    return list(zip(ev["x"].tolist(), ev["y"].tolist(), ev["p"].tolist(), strict=True))


def test_killed_pixels_send_nothing():
    out, ro = _run(kill_pixels=((3, 1), (7, 7)))
    assert _xyp(out) == [(0, 0, 1), (5, 2, 1), (6, 4, 1)]
    assert ro.counts["killed"] == 2


def test_kill_pixels_outside_the_array_are_refused():
    with pytest.raises(ValueError, match=r"kill_pixels: \(8, 0\) is outside the 8x8 array"):
        SpeckReadout(8, 8, ReadoutParams(kill_pixels=((8, 0),)))
    with pytest.raises(ValueError, match="listed twice"):
        ReadoutParams(kill_pixels=((1, 1), (1, 1)))


def test_channels_off_and_merge():
    out, ro = _run(dvs_layer=DvsLayerParams(off_channel=False))
    assert _xyp(out) == [(0, 0, 1), (5, 2, 1), (6, 4, 1)] and ro.counts["channel_off"] == 2
    out, ro = _run(dvs_layer=DvsLayerParams(on_channel=False))
    assert _xyp(out) == [(3, 1, 0), (7, 7, 0)] and ro.counts["channel_off"] == 3
    out, _ = _run(dvs_layer=DvsLayerParams(merge=True))
    assert out["p"].tolist() == [0, 0, 0, 0, 0]


def test_sum_pooling_maps_each_event_to_its_block():
    out, ro = _run(dvs_layer=DvsLayerParams(pooling=(2, 4)))
    assert _xyp(out) == [(0, 0, 1), (1, 0, 0), (2, 0, 1), (3, 1, 0), (3, 1, 1)]
    assert ro.output_size == (4, 2)
    out, _ = _run(dvs_layer=DvsLayerParams(pooling=(4, 4)))
    assert _xyp(out) == [(0, 0, 1), (0, 0, 0), (1, 0, 1), (1, 1, 0), (1, 1, 1)]


def test_region_of_interest_crops_and_shifts_to_the_origin():
    # origin (2, 1), cut (6, 4) inclusive: (3,1) -> (1,0), (5,2) -> (3,1), (6,4) -> (4,3).
    out, ro = _run(dvs_layer=DvsLayerParams(origin=(2, 1), cut=(6, 4)))
    assert _xyp(out) == [(1, 0, 0), (3, 1, 1), (4, 3, 1)]
    assert ro.counts["outside_roi"] == 2 and ro.output_size == (5, 4)


def test_region_is_on_the_pooled_grid():
    # pooling 2: events at pooled (0,0) (1,0) (2,1) (3,3) (3,2); region (1,0)-(3,2).
    out, _ = _run(dvs_layer=DvsLayerParams(pooling=(2, 2), origin=(1, 0), cut=(3, 2)))
    assert _xyp(out) == [(0, 0, 0), (1, 1, 1), (2, 2, 1)]


def test_mirroring_flips_the_region_then_swaps_the_axes():
    out, _ = _run(dvs_layer=DvsLayerParams(mirror=(True, False)))
    assert _xyp(out) == [(7, 0, 1), (4, 1, 0), (2, 2, 1), (0, 7, 0), (1, 4, 1)]
    out, _ = _run(dvs_layer=DvsLayerParams(mirror=(False, True)))
    assert _xyp(out) == [(0, 7, 1), (3, 6, 0), (5, 5, 1), (7, 0, 0), (6, 3, 1)]
    out, ro = _run(dvs_layer=DvsLayerParams(mirror_diagonal=True, cut=(6, 4)))
    assert _xyp(out) == [(0, 0, 1), (1, 3, 0), (2, 5, 1), (4, 6, 1)]
    assert ro.output_size == (5, 7)
    # Within a region: flip x of the 5-wide region (2..6), then swap.
    out, _ = _run(
        dvs_layer=DvsLayerParams(
            origin=(2, 1), cut=(6, 4), mirror=(True, False), mirror_diagonal=True
        )
    )
    assert _xyp(out) == [(0, 3, 0), (1, 1, 1), (3, 0, 1)]


def test_a_cut_beyond_the_grid_is_refused():
    with pytest.raises(ValueError, match=r"dvs_layer.cut: \(4, 3\) is outside the pooled 4x4"):
        SpeckReadout(8, 8, ReadoutParams(dvs_layer=DvsLayerParams(pooling=(2, 2), cut=(4, 3))))
    with pytest.raises(
        ValueError, match=r"cut: \(4, 9\) must not be left of or above origin \(5, 5\)"
    ):
        DvsLayerParams(origin=(5, 5), cut=(4, 9))
    with pytest.raises(ValueError, match="pooling"):
        DvsLayerParams(pooling=(3, 1))
    with pytest.raises(ValueError, match="the swapped 6x8 region does not fit the 8x6 array"):
        SpeckReadout(8, 6, ReadoutParams(dvs_layer=DvsLayerParams(mirror_diagonal=True)))


def test_events_outside_the_array_are_refused():
    ro = SpeckReadout(8, 8, ReadoutParams())
    ro.reset(0)
    with pytest.raises(ValueError, match="events outside the 8x8 array"):
        ro.step(make_events([8], [0], [1], [1]), t_us=10)
    with pytest.raises(ValueError, match="events after the window's end: t=11 > 10"):
        ro.step(make_events([1], [0], [11], [1]), t_us=10)
