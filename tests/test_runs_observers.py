"""Observers of a closed-loop run (:mod:`experiments.runs.observers`): the hooks come in
Gymnasium's order, a step at a time, and the run's own watchers fill the folder."""

from __future__ import annotations

import gymnasium as gym

import wander_env  # noqa: F401  (registers the environments)
from agents.attention import AgentParams, AttentionAgent
from experiments.jobs.run_agent import run_closed_loop
from experiments.runs.observers import RunObserver


class Calls(RunObserver):
    def __init__(self) -> None:
        self.calls: list[str] = []
        self.decisions = 0
        self.closed_with: list[BaseException | None] = []

    def on_reset(self, env, agent, obs, info) -> None:
        self.calls.append("reset")

    def on_act(self, env, agent, obs, info) -> None:
        self.calls.append("act")
        self.decisions += bool(agent.decided)

    def on_step(self, env, agent, obs, info) -> None:
        self.calls.append("step")

    def close(self, error):
        self.closed_with.append(error)
        return error


def test_an_observer_sees_reset_then_act_and_step_each_step_then_close(tmp_path):
    env = gym.make("wander/Wander-v0", scene="office", episode_seconds=2.0)
    agent = AttentionAgent(AgentParams.for_env(env, window_s=0.05), seed=1)
    watch = Calls()
    try:
        run = run_closed_loop(
            env, agent, 0.3, tmp_path, {}, video=False, seed=1, observers=(watch,)
        )
    finally:
        agent.close()
        env.close()
    steps = run.metrics["steps"]
    assert steps == 30
    assert watch.calls == ["reset", *["act", "step"] * steps]
    assert watch.closed_with == [None]
    assert watch.decisions == run.metrics["decisions"] > 0
    assert {"events.h5", "metrics.json", "run.json", "run.rrd", "fixations.csv"} <= {
        p.name for p in tmp_path.iterdir()
    }
