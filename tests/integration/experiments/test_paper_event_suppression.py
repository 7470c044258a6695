"""event_suppression: the hand scene's speeds, the phase schedule, the per-phase scorer."""

from __future__ import annotations

import math
import re
from dataclasses import replace

import numpy as np
import pytest

from agents.soms import SOMSParams
from experiments.paper.event_suppression import (
    EXPERIMENT,
    EventSuppressionConfig,
    compare,
    image_speeds,
    record,
    schedule,
)
from experiments.paper.event_suppression_protocol import PhaseClock, Segment, Shake, recording
from experiments.paper.event_suppression_scoring import pooled_mean_std, score, trial_figures
from experiments.studies.framework import make_trials, resolve_config, run_spec
from wander_env.camera import focal_length_px
from wander_env.config import ConfigError, parse_sets, validate
from wander_env.scenes import assets_dir, load_scene_config


def stated_speeds() -> tuple[float, float]:
    """The image speeds hand.yaml states: (hand, shake) px/s at the sensor centre."""
    m = re.search(
        r"image speeds at the sensor centre: hand ([\d.]+) px/s; shake ([\d.]+) px/s",
        (assets_dir() / "scenes" / "hand.yaml").read_text(),
    )
    assert m, "hand.yaml must state its image speeds"
    return float(m.group(1)), float(m.group(2))


def test_scene_file_states_the_speeds_its_geometry_gives():
    hand, shake = image_speeds(load_scene_config("hand"), EventSuppressionConfig().shake)
    assert stated_speeds() == (170.0, 14.0)
    assert hand == pytest.approx(42.5 * 0.6 / 0.15, rel=1e-3)  # f v / d
    assert shake == pytest.approx(13.98, abs=0.01)  # f ω, ω = 18.85°/s


def test_simulated_hand_and_camera_speeds_are_within_5_percent_of_the_scene_file():
    """The hand's image centre (env ground truth, camera still) and the camera's gaze
    (the PTU model following the shake's actions) over a short hand and shake phase."""
    cfg = EventSuppressionConfig(
        shake_s=(0.2, 0.2), hand_s=(0.2, 0.2), both_s=(0.02, 0.02), pause_s=(0.02, 0.02)
    )
    hand_stated, shake_stated = stated_speeds()
    f = focal_length_px(128)
    rec = record(cfg, "hand", 1)
    lead = 50
    step = np.diff(rec.hand_px[lead:, 0]) / cfg.window_s
    moving = np.abs(step) > 0  # 2 windows at a turn are shorter steps
    assert np.median(np.abs(step[moving])) == pytest.approx(hand_stated, rel=0.05)
    assert np.ptp(rec.gaze[lead:], axis=0).tolist() == [0.0, 0.0]  # camera still
    rec = record(cfg, "shake", 1)
    gaze = rec.gaze[lead::10]  # every 20 ms: chords of a 21.6° arc (0.6 % short)
    deg_s = np.linalg.norm(np.diff(gaze, axis=0), axis=1).mean() / 0.02
    assert f * math.radians(deg_s) == pytest.approx(shake_stated, rel=0.05)


def test_schedule_is_drawn_from_the_seed():
    cfg = EventSuppressionConfig()
    assert schedule(cfg, 0) == (
        Segment("shake", 0.96),
        Segment("both", 0.6),
        Segment("hand", 0.66),
        Segment("pause", 0.38),
    )
    assert schedule(cfg, 0) == schedule(cfg, 0)
    scheds = [schedule(cfg, s) for s in range(20)]
    assert len({tuple(x.phase for x in sc) for sc in scheds}) > 5  # orders vary
    for sc in scheds:
        assert sorted(x.phase for x in sc) == ["both", "hand", "pause", "shake"]
        for x in sc:
            lo, hi = cfg.phase_range(x.phase)
            assert lo - 0.01 <= x.length_s <= hi + 0.01
            assert x.length_s / 0.02 == pytest.approx(round(x.length_s / 0.02))


def test_a_rows_recording_starts_where_the_trial_put_the_clocks():
    sched = (
        Segment("hand", 0.5),
        Segment("pause", 0.2),
        Segment("shake", 0.4),
        Segment("both", 0.6),
    )
    assert recording(sched, "hand", 0.1) == (
        (Segment("pause", 0.1), Segment("hand", 0.5)),
        0.0,
        0.0,
    )
    assert recording(sched, "shake", 0.1) == (
        (Segment("pause", 0.1), Segment("shake", 0.4)),
        0.0,
        0.5,
    )
    segs, shake0, hand0 = recording(sched, "both", 0.1)
    assert (segs, shake0, hand0) == ((Segment("shake", 0.1), Segment("both", 0.6)), 0.3, 0.5)
    shake, hand = PhaseClock(segs, {"shake", "both"}, shake0), PhaseClock(segs, {"both"}, hand0)
    assert [shake(t) for t in (0.0, 0.1, 0.4)] == pytest.approx([0.3, 0.4, 0.7])
    assert [hand(t) for t in (0.0, 0.1, 0.4)] == pytest.approx([0.5, 0.5, 0.8])


def test_shake_circles_at_its_speed():
    s = Shake(amplitude_deg=2.0, speed_deg_s=18.85)
    assert s.hz == pytest.approx(1.5, rel=1e-3)
    pts = np.array([s.angles(t, 0.7, -1) for t in np.linspace(0, 1 / s.hz, 1001)])
    assert pts[0] == pytest.approx([0, 0], abs=1e-12) and pts[-1] == pytest.approx([0, 0], abs=1e-9)
    centre = -2.0 * np.array([math.cos(0.7), math.sin(0.7)])
    assert np.linalg.norm(pts - centre, axis=1) == pytest.approx(2.0)
    length = np.linalg.norm(np.diff(pts, axis=0), axis=1).sum()
    assert length * s.hz == pytest.approx(18.85, rel=1e-4)
    with pytest.raises(ValueError, match=r"shake\.amplitude_deg"):
        Shake(amplitude_deg=0.0)


class FixedMap:
    """A stand-in sOMS whose map is given: fires on ``oms`` every step."""

    def __init__(self, oms: np.ndarray) -> None:
        self.oms, self.inputs = oms, []

    def step(self, event_map: np.ndarray):
        self.inputs.append(event_map.copy())
        return type("Out", (), {"oms": self.oms})()


def test_the_per_phase_scorer_on_a_hand_made_stream():
    """4 windows of 2 ms, 2 per sOMS step; the first step is the lead-in. The hand is a
    4×4 square moving 1 px right per window; the map keeps a 4×6 strip over it and one
    background pixel."""
    n, h, w = 4, 16, 16
    masks = np.zeros((n, h, w), bool)
    for k in range(n):
        masks[k, 6:10, 4 + k : 8 + k] = True
    counts = np.zeros((n, 2, h, w), np.uint16)
    counts[:, 1][masks] = 1  # one ON event on every hand pixel of every window
    counts[:, 0, 0, 0] = 3  # 3 OFF events a window at a background corner ...
    counts[:, 0, 15, 15] = 2  # ... and 2 at the opposite one
    oms = np.zeros((2, h, w), bool)
    oms[:, 6:10, 6:12] = True  # over the hand in the scored windows
    oms[0, 15, 15] = True  # and one background pixel
    model = FixedMap(oms)
    row = score(counts, masks, model, 2, 1, True, 2.0)
    assert len(model.inputs) == 2 and model.inputs[1].sum() == 2 * 16 + 2 * 5
    # scored windows 2 and 3: hand columns 6..9 and 7..10; kept columns 6..11
    assert row["_events_in"].tolist() == [21, 21] and row["_events_out"].tolist() == [18, 18]
    assert (row["windows"], row["events_in"], row["events_out"]) == (2, 42, 36)
    assert row["events_in_mean"] == 21.0 and row["events_in_std"] == 0.0
    assert row["suppressed_pct"] == pytest.approx(100 * 6 / 42)
    assert (row["object_events_in"], row["object_events_out"]) == (32, 32)
    assert (row["background_events_in"], row["background_events_out"]) == (10, 4)
    assert row["object_kept_pct"] == 100.0 and row["background_kept_pct"] == 40.0
    # the densest point of the map lies on the hand: one scored step, a hit
    assert (row["hit_steps"], row["hand_hits"], row["hand_hit_pct"]) == (1, 1, 100.0)
    assert row["hand_hit_ci_low"] == pytest.approx(20.65, abs=0.01)  # Wilson, 1 of 1
    # a margin makes the hand's events those within 1 px of its swept mask
    wide = score(counts, masks, FixedMap(oms), 2, 1, False, 2.0, margin_px=1)
    assert (wide["object_events_in"], wide["hit_steps"]) == (32, 0)
    with pytest.raises(ValueError, match="whole sOMS steps"):
        score(counts[:3], masks[:3], FixedMap(oms), 2, 1, True, 2.0)


def test_trial_figures_and_the_comparison_pool_the_phase_rows():
    def row(seed: int, phase: str, ins: int, outs: int, hand: tuple[int, int], hits=(0, 0)):
        return {
            "seed": seed,
            "repeat": seed,
            "phase": phase,
            "windows": 10,
            "events_in": ins,
            "events_out": outs,
            "events_in_mean": ins / 10,
            "events_in_std": 1.0,
            "events_out_mean": outs / 10,
            "events_out_std": 0.0,
            "suppressed_pct": 100 * (1 - outs / ins),
            "object_events_in": hand[0],
            "object_events_out": hand[1],
            "object_kept_pct": 100 * hand[1] / hand[0] if hand[0] else math.nan,
            "background_events_in": ins - hand[0],
            "background_events_out": outs - hand[1],
            "background_kept_pct": 100 * (outs - hand[1]) / (ins - hand[0]),
            "hit_steps": hits[1],
            "hand_hits": hits[0],
            "hand_hit_pct": 100 * hits[0] / hits[1] if hits[1] else math.nan,
        }

    rows = [
        row(0, "shake", 1000, 20, (0, 0)),
        row(0, "hand", 200, 120, (150, 100), (9, 10)),
        row(0, "both", 800, 60, (100, 50), (10, 10)),
        row(0, "pause", 100, 0, (0, 0)),
        row(1, "shake", 1000, 40, (0, 0)),
        row(1, "hand", 200, 100, (160, 90), (10, 10)),
        row(1, "both", 800, 100, (120, 70), (8, 10)),
        row(1, "pause", 100, 10, (0, 0)),
    ]
    figs = trial_figures(rows)
    assert figs[0]["suppressed"] == pytest.approx(100 * (1 - 200 / 2100))
    assert figs[0]["hit"] == 95.0 and figs[1]["hit"] == 90.0
    assert figs[0]["hand_kept"] == 60.0 and figs[1]["hand_kept"] == pytest.approx(100 * 160 / 280)
    assert figs[0]["shake_suppressed"] == 98.0 and figs[1]["shake_suppressed"] == 96.0
    cfg = EventSuppressionConfig(repeats=2)
    comps = {c.result: c for c in compare(cfg, rows)}
    assert comps["trials"].ours == "2"
    assert comps["events suppressed"].paper == "85.16 %"
    hit = comps["hand hit, hand-moving phases (8×8 box around the OMS map's densest point)"]
    assert hit.ours == (
        "92.5 % [90.0, 95.0] (n = 2); pooled 92.5 % of 40 sOMS steps (Wilson 80.1–97.4 %)"
    )
    assert comps["shake-only events suppressed"].ours == "97.0 % [96.0, 98.0] (n = 2)"
    assert comps["events in per 2 ms"].ours.startswith("52.5 ± ")


def test_pooled_mean_std_equals_the_statistics_of_the_union():
    rng = np.random.default_rng(0)
    groups = [rng.normal(5.0, 2.0, n) for n in (10, 50, 7)]
    m, s = pooled_mean_std(
        np.array([g.mean() for g in groups]),
        np.array([g.std() for g in groups]),
        np.array([len(g) for g in groups]),
    )
    union = np.concatenate(groups)
    assert m == pytest.approx(union.mean()) and s == pytest.approx(union.std())


def test_the_agent_variant_uses_the_agents_soms():
    from agents.attention import AgentParams

    p = EventSuppressionConfig(agent=AgentParams(soms="agent")).soms_params()
    assert p == replace(AgentParams().soms, dt=0.02)
    assert EventSuppressionConfig().soms_params() == SOMSParams(dt=0.02)  # the paper's table
    sets = parse_sets(["agent.soms=agent"], EventSuppressionConfig)
    assert validate(EventSuppressionConfig, sets).soms_params() == p
    with pytest.raises(ValueError, match="soms must be one of"):
        EventSuppressionConfig(agent=AgentParams(soms="other"))  # type: ignore[arg-type]


def test_config_checks_windows_steps_and_phases():
    with pytest.raises(ValueError, match=r"soms_step_s=0\.003 must be a whole number of windows"):
        validate(EventSuppressionConfig, {"soms_step_s": 0.003})
    cfg = validate(EventSuppressionConfig, {"agent": {"soms": {"alpha": 0.5}}})
    assert cfg.soms_params() == SOMSParams(alpha=0.5, dt=0.02)
    with pytest.raises(ValueError, match="phases must be"):
        EventSuppressionConfig(phases=("wave",))
    with pytest.raises(ValueError, match="hand_s must be"):
        EventSuppressionConfig(hand_s=(1.0, 0.5))
    with pytest.raises(ValueError, match="lead_s must be a whole number"):
        EventSuppressionConfig(lead_s=0.03)
    assert EventSuppressionConfig().windows_per_step == 10
    cfg = validate(
        EventSuppressionConfig, parse_sets(["shake.amplitude_deg=2"], EventSuppressionConfig)
    )
    assert cfg.shake == Shake(amplitude_deg=2.0, speed_deg_s=18.85)


def test_hand_scene_has_one_hand_sized_moving_object():
    scene = load_scene_config("hand")
    (hand,) = scene.moving_objects
    assert hand.name == "hand" and hand.size == (0.02, 0.09, 0.19)


@pytest.mark.slow
def test_short_trial_rows_per_phase(tmp_path):
    """Phases of 40 ms after a 20 ms lead-in: four rows, one per phase."""
    sets = [
        "repeats=1",
        "shake_s=[0.04, 0.04]",
        "hand_s=[0.04, 0.04]",
        "both_s=[0.04, 0.04]",
        "pause_s=[0.04, 0.04]",
        "lead_s=0.02",
        "agent.soms=agent",
        "second_agent.soms={norm: minmax}",
    ]
    cfg = resolve_config(EXPERIMENT, sets=sets)
    specs = make_trials(EXPERIMENT, cfg, 3)
    rows = {str(s.params["phase"]): run_spec(s) for s in specs}
    assert list(rows) == ["shake", "hand", "both", "pause"]
    assert {r["seed"] for r in rows.values()} == {3}
    for r in rows.values():
        assert r["windows"] == len(r["_events_in"]) == 20
        assert np.all(r["_events_out"] <= r["_events_in"])
        assert r["events_in"] == r["object_events_in"] + r["background_events_in"]
    assert rows["pause"]["events_in_mean"] < rows["shake"]["events_in_mean"]
    assert rows["hand"]["hit_steps"] == rows["both"]["hit_steps"] == 2
    assert rows["shake"]["hit_steps"] == rows["pause"]["hit_steps"] == 0
    assert sorted(r["phase_index"] for r in rows.values()) == [0, 1, 2, 3]
    # the paper-literal sOMS scored on the same windows: same events in, its own out
    both = rows["both"]
    assert both["second:events_in"] == both["events_in"]
    assert both["second:hit_steps"] == both["hit_steps"]
    assert both["second:events_out"] != both["events_out"]
    assert cfg.second_params() == SOMSParams(dt=0.02)  # at the first's step


def test_soms_is_a_block_or_a_preset_name_and_bad_values_say_which():
    with pytest.raises(ConfigError) as e:
        validate(EventSuppressionConfig, {"agent": {"soms": "bogus"}}, where="--set")
    assert str(e.value) == (
        "--set: agent.soms: soms must be one of ['agent', 'paper', 'speck'] or a parameter "
        "block, got 'bogus'"
    )
    sets = parse_sets(["agent.soms.alpha=0.3"], EventSuppressionConfig)
    cfg = validate(EventSuppressionConfig, sets)
    assert (cfg.soms_params().alpha, cfg.soms_params().norm, cfg.windows_per_step) == (
        0.3,
        "minmax",
        10,
    )
