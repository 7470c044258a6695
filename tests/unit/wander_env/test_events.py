"""Event arrays: the shared format and its helpers."""

from __future__ import annotations

import numpy as np
import pytest

from wander_env.events import (
    EVENT_DTYPE,
    concatenate,
    make_events,
    merge,
    time_window,
    to_frame,
    validate_events,
)


def sample() -> np.ndarray:
    return make_events(
        x=[0, 3, 3, 1, 2], y=[0, 1, 1, 2, 0], t=[5, 10, 10, 20, 30], p=[1, 0, 0, 1, 1]
    )


def test_dtype_is_the_tonic_convention():
    assert EVENT_DTYPE.names == ("x", "y", "t", "p")
    assert EVENT_DTYPE["t"] == np.int64
    assert EVENT_DTYPE["x"] == np.int16


def test_to_frame_counts_per_polarity():
    frame = to_frame(sample(), (4, 3, 2))
    assert frame.shape == (2, 3, 4)
    assert frame[0, 1, 3] == 2  # two OFF events at (3, 1)
    assert frame[1].sum() == 3
    assert frame[1, 0, 0] == 1 and frame[1, 2, 1] == 1 and frame[1, 0, 2] == 1


def test_time_window_is_half_open():
    ev = time_window(sample(), 10, 30)
    assert ev["t"].tolist() == [10, 10, 20]
    assert len(time_window(sample(), 31, 100)) == 0


def test_merge_sorts_and_keeps_everything():
    a = make_events([0, 0], [0, 0], [1, 9], [1, 1])
    b = make_events([1, 1, 1], [0, 0, 0], [0, 5, 9], [0, 0, 0])
    m = merge(a, b)
    assert m["t"].tolist() == [0, 1, 5, 9, 9]
    assert m["x"].tolist() == [1, 0, 1, 0, 1]  # stable: a's t=9 before b's t=9


def test_concatenate_keeps_order_and_refuses_overlap():
    a = make_events([0], [0], [1], [1])
    b = make_events([0], [0], [1], [0])
    c = make_events([0], [0], [0], [0])
    assert concatenate([a, b])["p"].tolist() == [1, 0]
    with pytest.raises(ValueError, match="chunk 1 starts at t=0 before chunk 0 ends at t=1"):
        concatenate([a, c])


def test_make_events_refuses_unsorted_time():
    with pytest.raises(ValueError, match=r"t\[1\]=5 > t\[2\]=4"):
        make_events([0, 0, 0], [0, 0, 0], [1, 5, 4], [1, 1, 1])


def test_validate_names_out_of_range_coordinates_and_polarity():
    ev = sample()
    with pytest.raises(ValueError, match=r"x\[1\]=3 is outside the sensor \(0..2\)"):
        validate_events(ev, (3, 3, 2))
    ev["p"][2] = 2
    with pytest.raises(ValueError, match=r"p\[2\]=2"):
        validate_events(ev, (4, 3, 2))
