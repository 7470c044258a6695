"""The readout's effect on the agent (experiments/paper/readout_effect.py), run tiny."""

from __future__ import annotations

import math

import pytest

from experiments.paper.readout_effect import (
    CASES,
    PRESETS,
    CaseResult,
    figure,
    identity_gap,
    main,
    run_case,
    shares,
    table,
)
from wander_env.readout import LOST


@pytest.mark.slow
def test_every_case_and_preset_accounts_for_every_event() -> None:
    results = [run_case(case, preset, 0, 4, 1) for case in CASES for preset in PRESETS]
    assert len(results) == 9
    for r in results:
        t = r.totals
        # in = out + dropped + filtered + killed + channel_off + outside_roi + Δpending
        assert identity_gap(t) == 0, (r.case, r.preset, t)
        assert t["in"] == t["out"] + sum(t[k] for k in LOST) + t["pending"]
        assert t["in"] > 0, (r.case, r.preset)
        assert r.peak_in_step <= t["in"]
        assert r.peak_eps == r.peak_in_step / 0.01
        if r.preset == "ideal":  # the reference: nothing lost, nothing held
            assert all(t[k] == 0 for k in LOST), t
            assert t["pending"] == 0 and r.peak_pending == 0
            assert t["out"] == t["in"]
    # The readout comes after the DVS: every preset sees the same events in.
    for case in CASES:
        ins = {r.totals["in"] for r in results if r.case == case.name}
        assert len(ins) == 1, (case.name, ins)
    text = table(results).splitlines()
    assert len(text) == 2 + 9
    assert text[2].startswith("| hand | ideal |")
    # one seed: the shares carry no interval, and say so
    assert "n too small for an interval" in text[2]
    n_in = results[0].totals["in"]
    assert f"| {n_in:,}: 100.00% (n = 1: n too small for an interval) |" in text[2]
    assert "| 0: 0.00% (n = 1" in text[2]


def test_bad_arguments_exit_2_with_one_line(capsys) -> None:
    with pytest.raises(SystemExit) as e:
        main(["--seeds", "0"])
    assert e.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].endswith(
        "--seeds 0 and --steps 100 must be >= 1 and --saccade-step 5 in [0, steps)"
    )


def test_saccade_step_outside_the_episode_is_refused() -> None:
    with pytest.raises(ValueError, match=r"saccade_step: 4 must be in \[0, steps=4\)"):
        run_case(CASES[0], "ideal", 0, 4, 4)


def test_an_episode_with_no_events_in_has_no_share_in_the_table_or_the_figure(tmp_path) -> None:
    """One rule for the shares (NaN with no events in, left out of the mean over seeds)
    in the table and the figure; the figure goes through save_figure."""
    keys = ("in", "out", "pending", *LOST)
    full = CaseResult("hand", "speck", 0, dict.fromkeys(keys, 0) | {"in": 8, "out": 6}, 8, 0, 0.01)
    empty = CaseResult("hand", "speck", 1, dict.fromkeys(keys, 0), 0, 0, 0.01)
    assert shares([full, empty], ("out",))[0] == 0.75
    assert math.isnan(shares([full, empty], ("out",))[1])
    assert "| 3: 75.00% (n = 1: n too small for an interval) |" in table([full, empty])
    out = figure([full, empty], tmp_path / "fig" / "readout.png", 2, 1.0)
    assert out == tmp_path / "fig" / "readout.png" and out.stat().st_size > 1000
