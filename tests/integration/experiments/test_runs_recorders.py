"""Recorders of a run (:mod:`experiments.runs.recorders`) in the one episode loop
(:mod:`experiments.runs.episode`): the hooks come in Gymnasium's order, a step at a time;
the loop's error path closes every recorder with the error; recorders compose."""

from __future__ import annotations

import json

import gymnasium as gym
import numpy as np
import pytest

import wander_env  # noqa: F401  (registers the environments)
from agents.attention import AgentParams, AttentionAgent
from agents.scripted import GazePolicy
from experiments.jobs.run_agent import closed_loop_metrics, run_closed_loop
from experiments.runs.episode import Recorder, run_episode
from experiments.runs.recorders import ReadoutRecorder, video_frames


class Calls(Recorder):
    def __init__(self) -> None:
        self.calls: list[str] = []
        self.decisions = 0
        self.closed_with: list[BaseException | None] = []

    def on_reset(self, env, agent, obs, info) -> None:
        self.calls.append("reset")

    def on_act(self, env, agent, obs, info) -> None:
        self.calls.append("act")
        self.decisions += bool(getattr(agent, "decided", False))

    def on_step(self, env, agent, obs, info) -> None:
        self.calls.append("step")

    def close(self, error):
        self.closed_with.append(error)
        return error


def test_a_recorder_sees_reset_then_act_and_step_each_step_then_close(tmp_path):
    env = gym.make("wander/Wander-v0", scene="office", episode_seconds=2.0)
    agent = AttentionAgent(AgentParams.for_env(env, window_s=0.05), seed=1)
    watch = Calls()
    try:
        run = run_closed_loop(
            env, agent, 0.3, tmp_path, {}, video=False, seed=1, recorders=(watch,)
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
    assert "readout" not in run.metrics  # the env's info has no readout counters


def test_an_experiment_reads_the_metrics_in_memory_and_they_equal_the_folders(tmp_path):
    """The in-memory figures of a trial are the run folder's (but the wall time), and a
    trial writes no file."""
    env = gym.make("wander/Wander-v0", scene="office", episode_seconds=2.0)
    try:
        agent = AttentionAgent(AgentParams.for_env(env, window_s=0.05), seed=2)
        folder = run_closed_loop(env, agent, 0.3, tmp_path / "run", {}, video=False, seed=2)
        agent.close()
        agent = AttentionAgent(AgentParams.for_env(env, window_s=0.05), seed=2)
        memory = closed_loop_metrics(env, agent, 0.3, seed=2)
        agent.close()
    finally:
        env.close()
    timing = {"wall_s", "real_time_factor"}
    written = {k: v for k, v in folder.metrics.items() if k not in timing}
    assert {k: v for k, v in memory.items() if k not in timing} == written
    assert memory["steps"] == 30 and memory["events"] > 0


class _Failing(gym.Wrapper):
    def __init__(self, env, at: int) -> None:
        super().__init__(env)
        self.at, self.k = at, 0

    def step(self, action):
        self.k += 1
        if self.k == self.at:
            raise TimeoutError("PTU did not answer within 1.0 s")
        return self.env.step(action)


def test_the_loop_halts_then_closes_every_recorder_with_the_error_and_raises_it():
    env = _Failing(gym.make("wander/Wander-v0", scene="shelf", ground_truth=False), at=4)
    first, second = Calls(), Calls()
    halted: list[int] = []
    try:
        policy = GazePolicy("fixational", 1, 0.01, 0.5)
        with pytest.raises(TimeoutError, match="PTU did not answer"):
            run_episode(
                env, policy, 10, (first, second), halt=lambda: halted.append(len(first.calls))
            )
    finally:
        env.close()
    assert first.calls == ["reset", *["act", "step"] * 3, "act"]
    assert halted == [len(first.calls)]  # at once, before the recorders close
    assert [type(e) for e in first.closed_with + second.closed_with] == [TimeoutError] * 2


class _Counters(gym.Wrapper):
    """An env whose step info carries a readout's counters."""

    def step(self, action):
        obs, r, term, trunc, info = self.env.step(action)
        k = round(info["t"] * 100)
        info["readout"] = {"dropped": k, "filtered": np.int64(2), "rate_hz": 1.5, "ok": True}
        return obs, r, term, trunc, info


def test_readout_counters_are_summed_over_the_run_integers_only():
    env = _Counters(gym.make("wander/Wander-v0", scene="shelf", ground_truth=False))
    readout, none = ReadoutRecorder(), ReadoutRecorder()
    try:
        run_episode(env, GazePolicy("still", 0, 0.01, 0.5), 5, (readout,), seed=0)
        run_episode(env.env, GazePolicy("still", 0, 0.01, 0.5), 2, (none,), seed=0)
    finally:
        env.close()
    assert readout.metrics() == {"readout": {"dropped": 1 + 2 + 3 + 4 + 5, "filtered": 10}}
    assert none.metrics() == {}


def test_video_frames_follow_the_chosen_rate():
    assert video_frames(150, 0.01, 30) == 45
    assert video_frames(300, 0.01, 25) == 75
    assert [video_frames(k, 0.01, 30) for k in range(1, 8)] == [1, 1, 1, 2, 2, 2, 3]
    assert video_frames(100, 0.01, 100) == 100
    assert video_frames(3, 0.01, 250) == 8  # more frames than steps: a step's is repeated


def test_a_runs_metrics_json_gets_the_readout_totals(tmp_path):
    env = _Counters(gym.make("wander/Wander-v0", scene="shelf", ground_truth=False))
    agent = AttentionAgent(AgentParams.for_env(env), seed=0)
    try:
        run_closed_loop(env, agent, 0.1, tmp_path, {}, video=False, seed=0)
    finally:
        agent.close()
        env.close()
    m = json.loads((tmp_path / "metrics.json").read_text())
    assert m["steps"] == 10
    assert m["readout"] == {"dropped": sum(range(1, 11)), "filtered": 20}
