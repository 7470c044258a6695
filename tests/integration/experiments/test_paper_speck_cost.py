"""The on-chip cost table (experiments/paper/speck_cost.py) from hand-made rows and files."""

from __future__ import annotations

import json
import math

import pytest

from experiments.paper.speck_cost import (
    Cost,
    detection_costs,
    hand_costs,
    plot,
    read_costs,
    table,
    write_costs,
)


def phase(seed: int, name: str, ins: int, outs: int, hits: int, steps: int, second_out: int):
    row = {
        "seed": seed,
        "phase": name,
        "events_in": ins,
        "events_out": outs,
        "hit_steps": steps,
        "hand_hits": hits,
        "object_events_in": ins // 2,
        "object_events_out": outs // 2,
        "background_events_in": ins - ins // 2,
        "background_events_out": outs - outs // 2,
    }
    second = {**row, "events_out": second_out, "hand_hits": steps, "object_events_out": 0}
    second["background_events_out"] = second_out
    return row | {f"second:{k}": v for k, v in second.items() if k not in ("seed", "phase")}


def test_hand_costs_pair_the_speck_and_the_host_figures_per_trial():
    rows = [
        phase(0, "shake", 100, 20, 0, 0, 10),
        phase(0, "hand", 100, 60, 8, 10, 40),
        phase(1, "shake", 100, 40, 0, 0, 10),
        phase(1, "hand", 100, 60, 6, 10, 40),
    ]
    costs = {c.measure: c for c in hand_costs(rows)}
    sup = costs["events suppressed over a trial"]
    assert sup.speck[0] == pytest.approx(55.0) and sup.speck[3] == 2  # 60 %, 50 %
    assert sup.host[0] == pytest.approx(75.0)  # 50 of 200 kept in each trial
    assert sup.speck[1] <= 55.0 <= sup.speck[2]
    assert costs["hand hit (hand-moving sOMS steps)"].speck[0] == pytest.approx(70.0)
    assert costs["hand hit (hand-moving sOMS steps)"].host[0] == pytest.approx(100.0)
    assert costs["shake-only events suppressed"].speck[0] == pytest.approx(70.0)
    with pytest.raises(ValueError, match=r"second_agent\.soms=agent"):
        hand_costs([{"seed": 0, "phase": "hand", "events_in": 1}])


def quality(path, seeds, acc, lo, hi, scored, sup):
    rows = [{"seed": s, "soms_suppression": v} for s, v in zip(seeds, sup, strict=True)]
    pooled = {
        "detection_accuracy": acc,
        "detection_ci_low": lo,
        "detection_ci_high": hi,
        "scored": scored,
    }
    path.write_text(json.dumps({"rows": rows, "pooled": pooled}))
    return path


def test_detection_costs_need_the_same_seeds(tmp_path):
    a = quality(tmp_path / "a.json", [0, 1], 0.5, 0.3, 0.7, 20, [0.4, 0.6])
    b = quality(tmp_path / "b.json", [0, 1], 0.9, 0.7, 0.97, 21, [0.9, 0.9])
    acc, sup = detection_costs(a, b)
    assert acc.speck == (50.0, 30.0, 70.0, 20) and acc.host == (90.0, 70.0, 97.0, 21)
    assert sup.speck[0] == pytest.approx(50.0) and sup.host[0] == pytest.approx(90.0)
    c = quality(tmp_path / "c.json", [0, 2], 0.9, 0.7, 0.97, 21, [0.9, 0.9])
    with pytest.raises(ValueError, match="different seeds"):
        detection_costs(a, c)


def test_detection_costs_read_quality_files_as_wander_evaluate_writes_them(tmp_path):
    """A seed whose sOMS saw no event has its suppression null (strict JSON): read as NaN
    and left out of the mean; a file that is not a quality.json is refused by name."""
    a = quality(tmp_path / "a.json", [0, 1], 0.5, 0.3, 0.7, 20, [0.4, None])
    b = quality(tmp_path / "b.json", [0, 1], 0.9, 0.7, 0.97, 21, [0.9, 0.8])
    _, sup = detection_costs(a, b)
    assert sup.speck[0] == pytest.approx(40.0) and sup.speck[3] == 1
    assert sup.host[0] == pytest.approx(85.0) and sup.host[3] == 2
    (tmp_path / "list.json").write_text("[1, 2]")
    with pytest.raises(ValueError) as e:
        detection_costs(a, tmp_path / "list.json")
    assert str(e.value) == (
        f"host_quality: {tmp_path / 'list.json'}: not the quality.json of a wander evaluate run"
    )


def test_table_and_plot(tmp_path):
    costs = [
        Cost("x", "a", "%", (50.0, 40.0, 60.0, 3), (90.0, math.nan, math.nan, 1), "trials"),
        Cost("x", "b", "%", (math.nan, math.nan, math.nan, 0), (1.0, 0.5, 1.5, 2), "trials"),
    ]
    lines = table(costs).splitlines()
    assert lines[2] == (
        "| x | a (%) | 50.0 [40.0, 60.0] (n = 3) | 90.0 (n = 1: n too small for an interval) "
        "| trials |"
    )
    assert lines[3] == "| x | b (%) | — | 1.0 [0.5, 1.5] (n = 2) | trials |"
    back = read_costs(write_costs(costs, tmp_path / "c.json"))
    assert table(back) == table(costs) and back[0].speck == costs[0].speck
    # strict JSON: an infinite bound is written as null, never as Infinity
    inf = [Cost("x", "c", "%", (1.0, math.inf, 2.0, 2), (1.0, 1.0, 1.0, 1), "trials")]
    text = write_costs(inf, tmp_path / "inf.json").read_text()
    assert json.loads(text)[0]["speck"] == [1.0, None, 2.0, 2] and "Infinity" not in text
    out = plot(costs, tmp_path / "p.png")
    assert out.is_file() and out.stat().st_size > 1000
