"""The one episode loop's stop condition and reset options
(:func:`experiments.runs.episode.run_episode`), and the readout recorder's levels and
peaks (:class:`experiments.runs.recorders.ReadoutRecorder`), on a fake env."""

from __future__ import annotations

from typing import Any

import numpy as np

from experiments.runs.episode import Recorder, run_episode
from experiments.runs.recorders import ReadoutRecorder


class CountingEnv:
    """Gymnasium's contract: ``t`` counts steps; ``info["readout"]`` carries per-step
    counters (``in`` = the step's number, ``pending`` = 10 − it), ``options`` the last
    reset's."""

    def __init__(self, horizon: int = 100) -> None:
        self.horizon, self.t, self.options = horizon, 0, "never reset"

    def reset(self, seed: int | None = None, options: dict | None = None) -> tuple[Any, dict]:
        self.t, self.options = 0, options
        return {"t": 0}, {}

    def step(self, action: Any) -> tuple[Any, float, bool, bool, dict]:
        self.t += 1
        readout = {"in": np.int64(self.t), "pending": 10 - self.t, "ok": True, "rate": 0.5}
        return {"t": self.t}, 0.0, False, self.t == self.horizon, {"readout": readout}


class NoOptionsEnv(CountingEnv):
    """An env whose reset takes no ``options`` (the loop passes none unless asked)."""

    def reset(self, seed: int | None = None) -> tuple[Any, dict]:  # type: ignore[override]
        return super().reset(seed)


class Still:
    def act(self, obs: Any, info: dict) -> int:
        return 0


class Seen(Recorder):
    def __init__(self) -> None:
        self.steps: list[int] = []

    def on_step(self, env: Any, policy: Any, obs: Any, info: dict) -> None:
        self.steps.append(obs["t"])


def test_until_ends_the_episode_after_the_step_that_met_it() -> None:
    env, seen = CountingEnv(), Seen()
    done = run_episode(env, Still(), 50, (seen,), until=lambda: env.t >= 4)
    assert done == 4 and seen.steps == [1, 2, 3, 4]  # the recorders saw the last step


def test_without_until_the_episode_runs_its_steps_or_to_truncation() -> None:
    assert run_episode(CountingEnv(), Still(), 7) == 7
    assert run_episode(CountingEnv(horizon=3), Still(), 7, until=lambda: False) == 3


def test_reset_options_reach_the_env_and_are_not_passed_unless_given() -> None:
    env = CountingEnv()
    run_episode(env, Still(), 1, options={"gaze_deg": (1.0, -2.0)})
    assert env.options == {"gaze_deg": (1.0, -2.0)}
    run_episode(env, Still(), 1)
    assert env.options is None
    assert run_episode(NoOptionsEnv(), Still(), 2) == 2


def test_readout_sums_counters_keeps_levels_last_and_peaks() -> None:
    summed, levels = ReadoutRecorder(), ReadoutRecorder(levels=("pending",))
    run_episode(CountingEnv(), Still(), 4, (summed, levels))
    assert summed.totals == {"in": 1 + 2 + 3 + 4, "pending": 9 + 8 + 7 + 6}
    assert levels.totals == {"in": 10, "pending": 6}  # held at the last step's end
    assert levels.peaks == summed.peaks == {"in": 4, "pending": 9}
    assert all(type(v) is int for v in [*levels.totals.values(), *levels.peaks.values()])
