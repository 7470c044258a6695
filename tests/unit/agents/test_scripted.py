"""Tests for the scripted gaze policies (agents.scripted)."""

from __future__ import annotations

import numpy as np

from agents.scripted import GazePolicy


def test_still_never_moves():
    policy = GazePolicy("still", seed=0, dt_s=0.002, saccade_interval_s=0.5)
    assert not any(policy.act({}, {"moving": False}).any() for _ in range(300))


def test_fixational_steps_only_while_the_unit_rests():
    policy = GazePolicy("fixational", seed=0, dt_s=0.002, saccade_interval_s=0.5)
    assert not any(policy.act({}, {"moving": True}).any() for _ in range(300))
    steps = [policy.act({}, {"moving": False}) for _ in range(300)]
    moved = [a for a in steps if a.any()]
    assert moved and max(np.abs(a).max() for a in moved) < 0.05


def test_saccades_come_once_an_interval_and_are_seeded():
    def run(seed):
        policy = GazePolicy("saccades", seed=seed, dt_s=0.002, saccade_interval_s=0.1)
        return [policy.act({}, {"moving": True}) for _ in range(250)]

    actions = run(3)
    jumps = [k for k, a in enumerate(actions) if a.any()]
    assert jumps == [50, 100, 150, 200]
    assert all(np.abs(actions[k]).max() <= 0.6 for k in jumps)
    assert np.array_equal(np.array(actions), np.array(run(3)))
