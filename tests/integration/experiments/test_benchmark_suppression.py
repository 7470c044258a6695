"""Tests for the event-suppression measurement (experiments.benchmark.suppression)."""

from __future__ import annotations

import numpy as np
from test_benchmark_protocol import OMS, SENSOR, FakeModel

from experiments.benchmark.protocol import Maps
from experiments.benchmark.runner import SUPPRESSION_COLUMNS, write_suppression_csv
from experiments.benchmark.suppression import event_suppression, render_suppression_markdown
from experiments.runs.tables import read_csv
from wander_env.events import make_events


def test_event_suppression_counts():
    # static scene: events everywhere, OMS active on a 4 x 8 patch only
    events = make_events(
        x=[5, 6, 20, 5, 30, 31, 4, 4],
        y=[5, 5, 5, 6, 20, 20, 4, 4],
        t=[0, 100, 500, 1999, 2000, 2500, 4000, 4001],
        p=[1, 0, 1, 1, 0, 1, 1, 0],
    )
    model = FakeModel(OMS, None)
    res = event_suppression(events, SENSOR, model, window_us=2000)
    assert res.n_windows == 3
    assert res.events_in.tolist() == [4, 2, 2]
    assert res.events_out.tolist() == [3, 0, 2]
    assert (res.total_in, res.total_out) == (8, 5)
    assert res.fraction_suppressed == 1 - 5 / 8
    assert res.per_window()["events_in_mean"] == 8 / 3
    assert [c[1] for c in model.calls] == [0.002] * 3
    md = render_suppression_markdown(res, "poster")
    assert "37.50 %" in md and "85.16 %" in md


def test_suppression_csv_is_the_house_table(tmp_path):
    events = make_events(x=[5, 20, 5], y=[5, 5, 6], t=[0, 500, 2500], p=[1, 1, 0])
    res = event_suppression(events, SENSOR, FakeModel(OMS, None), window_us=2000)
    path = write_suppression_csv(tmp_path / "s.csv", [("poster", res, 100)])
    assert path.read_text() == (
        "recording,window,t_start_us,t_end_us,events_in,events_out\n"
        "poster,0,100,2100,2,1\n"
        "poster,1,2100,4100,1,1\n"
    )
    assert read_csv(path)[1] == {
        "recording": "poster",
        "window": 1,
        "t_start_us": 2100,
        "t_end_us": 4100,
        "events_in": 1,
        "events_out": 1,
    }
    empty = write_suppression_csv(tmp_path / "e.csv", [])
    assert empty.read_text() == ",".join(SUPPRESSION_COLUMNS) + "\n"


class _OffOnly:
    """The OMS fired in the OFF map alone, over the whole sensor."""

    def reset(self) -> None:
        pass

    def process(self, event_counts, dt_s):
        polarity = np.zeros((2, *OMS.shape), bool)
        polarity[0] = True
        return Maps(polarity.any(axis=0), polarity, np.zeros(OMS.shape, np.float32))


def test_an_event_is_kept_only_where_the_map_of_its_polarity_fired():
    """The agent's rule (agents.suppression.kept_events): an ON event at a pixel where only
    the OFF map fired is suppressed."""
    events = make_events(x=[5, 5, 6, 7], y=[5, 5, 5, 9], t=[0, 10, 20, 30], p=[1, 0, 1, 0])
    res = event_suppression(events, SENSOR, _OffOnly(), window_us=2000)
    assert res.events_in.tolist() == [4] and res.events_out.tolist() == [2]  # the OFF two
    assert res.fraction_suppressed == 0.5
