"""event_suppression: the pause clock, pooled statistics, and a short trial."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from agents.soms import SOMSParams
from experiments.framework import make_trials, resolve_config, run_spec
from experiments.paper.event_suppression import (
    EXPERIMENT,
    EventSuppressionConfig,
    PausedTrajectory,
    active_time,
    compare,
    is_active,
    pooled_mean_std,
)
from wander_env.config import ConfigError, parse_sets, validate
from wander_env.scene_config import load_scene_config


def test_the_pause_clock_stops_during_pauses():
    ts = [0.0, 0.5, 1.0, 1.2, 1.5, 1.75, 2.7, 3.2]
    got = [active_time(t, 1.0, 0.5) for t in ts]
    assert got == pytest.approx([0.0, 0.5, 1.0, 1.0, 1.0, 1.25, 2.0, 2.2])
    active = [is_active(t, 1.0, 0.5) for t in ts]
    assert active == [True, True, False, False, True, True, False, True]
    assert active_time(2.0, 1.0, 0.0) == 2.0


def test_paused_trajectory_holds_still_during_a_pause():
    class Line:
        def position(self, t: float) -> np.ndarray:
            return np.array([t, 0.0, 0.0])

    tr = PausedTrajectory(Line(), 0.2, 0.1)
    assert tr.position(0.21)[0] == tr.position(0.29)[0] == pytest.approx(0.2)
    assert tr.position(0.35)[0] == pytest.approx(0.25)


def test_pooled_mean_std_equals_the_statistics_of_the_union():
    rng = np.random.default_rng(0)
    groups = rng.normal(5.0, 2.0, (4, 50))
    m, s = pooled_mean_std(groups.mean(axis=1), groups.std(axis=1))
    assert m == pytest.approx(groups.mean()) and s == pytest.approx(groups.std())


def test_the_agent_variant_uses_the_agents_soms():
    from agents.attention import AgentParams

    p = EventSuppressionConfig(soms="agent").soms_params
    assert p == replace(AgentParams().soms, dt=0.02)
    assert EventSuppressionConfig().soms_params.norm == "minmax"
    from_set = validate(EventSuppressionConfig, parse_sets(["soms=agent"], EventSuppressionConfig))
    assert from_set.soms == p
    with pytest.raises(ValueError, match="soms"):
        EventSuppressionConfig(soms="other")  # type: ignore[arg-type]


def test_config_checks_windows_and_steps():
    with pytest.raises(ValueError, match="whole number of windows"):
        validate(EventSuppressionConfig, {"soms_step_s": 0.003})  # the former name of soms.dt
    assert validate(EventSuppressionConfig, {"alpha": 0.5}).soms == SOMSParams(alpha=0.5, dt=0.02)
    with pytest.raises(ValueError, match="shake must be"):
        EventSuppressionConfig(shake="wild")
    assert EventSuppressionConfig().windows_per_step == 10


def test_hand_scene_has_one_hand_sized_moving_object():
    scene = load_scene_config("hand")
    (hand,) = scene.moving_objects
    assert hand.name == "hand" and hand.size == (0.03, 0.11, 0.19)


def test_short_trial_counts_events_per_window_and_pauses_are_quiet():
    """0.06 s, still camera: 20 ms of the hand moving, 10 ms pause, 20 ms, 10 ms pause."""
    sets = ["duration_s=0.06", "active_s=0.02", "pause_s=0.01", "repeats=1", "shake=still"]
    cfg = resolve_config(EXPERIMENT, sets=sets)
    (spec,) = make_trials(EXPERIMENT, cfg, 0)
    row = run_spec(spec)
    ins, outs = row["_events_in"], row["_events_out"]
    assert row["windows"] == len(ins) == len(outs) == 30
    assert np.all(outs <= ins)
    assert row["events_in_mean"] == pytest.approx(ins.mean())
    assert row["suppressed_pct"] == pytest.approx(100 * (1 - outs.sum() / ins.sum()))
    assert 0 < row["suppressed_pct"] < 100
    assert row["events_in_active_mean"] > row["events_in_pause_mean"]
    assert row["object_events_in"] > 0
    # three 20 ms sOMS steps; the hand is scored in the two that end in an active phase
    assert row["hit_steps"] == 2 and 0 <= row["hand_hits"] <= 2
    comps = {c.result: c for c in compare(cfg, [row])}
    assert comps["events suppressed"].paper == "85.16 %"
    assert comps["trials"].ours == "1"


def test_hand_hit_scores_the_box_around_the_oms_maps_densest_point():
    from experiments.paper.event_suppression import hand_hit, oms_point

    oms = np.zeros((2, 64, 64), bool)
    oms[0, 30:36, 40:46] = True  # a dense patch of kept events (OFF) ...
    oms[1, 5, 5] = True  # ... and one stray kept event
    assert oms_point(oms, 2.0) == (42, 32)  # box: x in [38, 45], y in [28, 35]
    hand = np.zeros((64, 64), bool)
    hand[36:50, 20:38] = True  # just below-left of the box: a miss
    assert not hand_hit(oms, hand, 2.0)
    hand[35, 37] = False
    hand[35, 38] = True  # one pixel in the box's corner: a hit
    assert hand_hit(oms, hand, 2.0)
    assert not hand_hit(np.zeros_like(oms), hand, 2.0)  # nothing kept: a miss
    with pytest.raises(ValueError, match="mask"):
        hand_hit(oms, hand[None], 2.0)


def test_soms_is_a_block_or_a_preset_name_and_bad_values_say_which():
    with pytest.raises(ConfigError) as e:
        validate(EventSuppressionConfig, {"soms": "bogus"}, where="--set")
    assert str(e.value) == (
        "--set: bad value for key 'soms': expected SOMSParams or one of 'table', 'agent', "
        "got 'bogus'"
    )
    with pytest.raises(ConfigError, match=r"^--set: unknown key 'soms.alph' for SOMSParams;"):
        validate(EventSuppressionConfig, {"soms": {"alph": 1.0}}, where="--set")
    cfg = validate(EventSuppressionConfig, parse_sets(["soms.alpha=0.3"], EventSuppressionConfig))
    assert (cfg.soms_params.alpha, cfg.soms_params.norm, cfg.windows_per_step) == (
        0.3,
        "minmax",
        10,
    )
