"""The agent's behaviour is pinned: on a seeded synthetic event stream (ego-motion
texture, a denser moving square, the PTU reported moving during saccades) the same seed
gives the actions, decisions and saliency peaks recorded before the step was made faster
(``tests/data/agent_trace.json``, recorded at commit 4875f07)."""

from __future__ import annotations

import json

import numpy as np
from locations import DATA

from agents.attention import AgentParams, AttentionAgent

H = W = 128
TRACE = DATA / "agent_trace.json"


def synthetic_counts(k: int, rng: np.random.Generator) -> np.ndarray:
    """Step ``k``'s event counts ``(2, H, W)``: sparse texture events everywhere (the
    room sliding by) and a 14 px square whose events are denser, drifting right."""
    ev = (rng.random((2, H, W)) < 0.04).astype(np.float32)
    x0 = 20 + (3 * k) % 80
    y0 = 50 + (k // 7) % 30
    patch = rng.random((2, 14, 14)) < 0.6
    ev[:, y0 : y0 + 14, x0 : x0 + 14] += patch * (1.0 + (k % 3))
    return ev


def run_trace(steps: int = 120, seed: int = 4) -> dict:
    """Actions, decisions (step, target, peak) of the default agent on the stream."""
    rng = np.random.default_rng(seed)
    agent = AttentionAgent(AgentParams(), seed=seed)
    actions, decisions = [], []
    moving_until = -1
    try:
        for k in range(steps):
            obs = {"events": synthetic_counts(k, rng), "gaze": np.zeros(2, np.float32)}
            info = {"moving": k < moving_until, "t": 0.01 * (k + 1)}
            a = agent.act(obs, info)
            actions.append([float(v) for v in a])
            if agent.decided:
                target = None if agent.target is None else list(agent.target)
                decisions.append([k, target, agent.fixations[-1].peak])
                moving_until = k + 14  # the PTU reports motion past the settle time
    finally:
        agent.close()
    return {"seed": seed, "steps": steps, "actions": actions, "decisions": decisions}


def test_same_seed_same_actions_and_saliency_peaks_as_recorded() -> None:
    want = json.loads(TRACE.read_text())
    got = run_trace(want["steps"], want["seed"])
    assert got["decisions"] == want["decisions"]
    assert got["actions"] == want["actions"]
