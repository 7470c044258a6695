"""Every command builds its config through the one layered path
(:func:`experiments.cli.options.command_config`): the config class's defaults <- the
``--config`` file <- the flags given (each sets its :class:`ConfigKey`) <- ``--set``
items; ``wander experiment`` (its default file, ``configs/NAME.yaml``), ``wander perf
agent`` and ``wander perf env`` included. ``--set agent.soms.alpha=0.5`` reaches the
agent, and run.json says so."""

from __future__ import annotations

import inspect
import json
from pathlib import Path

import pytest
import typer
from typer.testing import CliRunner

from experiments.cli import perf
from experiments.cli.main import app
from experiments.cli.options import ConfigKey, flag_keys
from experiments.perf import agent as perf_agent
from experiments.perf import env as perf_env
from experiments.perf.agent import AgentBenchConfig
from experiments.perf.env import EnvBenchConfig

RUNNER = CliRunner()


def _perf_agent_config(monkeypatch: pytest.MonkeyPatch, args: list[str]) -> AgentBenchConfig:
    """The config ``wander perf agent ARGS`` hands to the bench (which is not run)."""
    seen: list[AgentBenchConfig] = []

    def bench(config: AgentBenchConfig) -> None:
        seen.append(config)
        raise typer.Exit(0)

    monkeypatch.setattr(perf_agent, "bench_agent", bench)
    result = RUNNER.invoke(app, ["perf", "agent", *args], prog_name="wander")
    assert result.exit_code == 0, result.output
    (config,) = seen
    return config


def test_perf_agent_flags_declare_their_keys_and_default_to_the_configs_values():
    keys = flag_keys(perf.bench_agent)
    assert keys == {
        "scene": ConfigKey("env.scene"),
        "seconds": ConfigKey("env.episode_seconds"),
        "seed": ConfigKey("seed"),
        "keyframe_ms": ConfigKey("env.keyframe_ms"),
    }
    sig = inspect.signature(perf.bench_agent)
    assert all(sig.parameters[name].default is None for name in keys)


def test_perf_agent_without_flags_runs_the_config_classes_defaults(monkeypatch):
    assert _perf_agent_config(monkeypatch, []) == AgentBenchConfig()
    assert (AgentBenchConfig().seconds, AgentBenchConfig().env.ground_truth) == (5.0, True)


def test_perf_agent_layers_file_flags_and_set_in_order(monkeypatch, tmp_path: Path):
    path = tmp_path / "bench.yaml"
    path.write_text("env: {scene: shelf, episode_seconds: 0.4}\nseed: 3\nagent: {window_s: 0.05}\n")
    args = ["--config", str(path), "--seed", "4", "--seconds", "0.2"]
    sets = ["--set", "agent.soms.alpha=0.5", "--set", "env.episode_seconds=0.3"]
    config = _perf_agent_config(monkeypatch, [*args, *sets])
    assert (config.env.scene, config.seed, config.agent.window_s) == ("shelf", 4, 0.05)
    assert (config.env.episode_seconds, config.agent.soms.alpha) == (0.3, 0.5)
    # Everything no layer named keeps the class's value.
    assert config.env.keyframe_ms == AgentBenchConfig().env.keyframe_ms
    assert config.agent.proto == AgentBenchConfig().agent.proto


def test_perf_agent_refuses_a_bad_key_on_one_line(monkeypatch):
    monkeypatch.setattr(perf_agent, "bench_agent", lambda config: pytest.fail("it ran"))
    result = RUNNER.invoke(
        app, ["perf", "agent", "--set", "agent.soms.alpha=2"], prog_name="wander"
    )
    assert (result.exit_code, result.output.strip()) == (
        2,
        "wander perf agent: error: --set: agent.soms.alpha: alpha must be in [0, 1], got 2.0",
    )


def test_experiment_layers_its_file_and_set(tmp_path: Path):
    path = tmp_path / "sac.yaml"
    path.write_text("repeats: 2\nagent: {soms: {alpha: 0.6}, window_s: 0.05}\n")
    args = ["experiment", "sac_accuracy", "--show-config", "--config", str(path)]
    result = RUNNER.invoke(app, [*args, "--set", "agent.soms.alpha=0.5"], prog_name="wander")
    assert result.exit_code == 0, result.output
    shown = json.loads(result.output)
    assert (shown["repeats"], shown["agent"]["window_s"]) == (2, 0.05)
    assert shown["agent"]["soms"]["alpha"] == 0.5


def test_set_agent_soms_alpha_is_read_back_from_an_experiments_run_json(tmp_path: Path):
    out = tmp_path / "sac"
    sets = ["repeats=1", "conditions=[ideal]", "agent.soms.alpha=0.5"]
    args = ["experiment", "sac_accuracy", "--out", str(out)]
    result = RUNNER.invoke(app, [*args, *(a for s in sets for a in ("--set", s))])
    assert result.exit_code == 0, result.output
    record = json.loads((out / "run.json").read_text())
    assert record["config"]["agent"]["soms"]["alpha"] == 0.5
    assert record["config"]["repeats"] == 1


def test_perf_env_layers_its_env_block_and_refuses_the_keys_its_rows_set(monkeypatch):
    assert flag_keys(perf.bench_env) == {
        "scene": ConfigKey("env.scene"),
        "seconds": ConfigKey("seconds"),
        "ground_truth": ConfigKey("env.ground_truth"),
        "antialias": ConfigKey("env.antialias_samples"),
        "keyframe_ms": ConfigKey("env.keyframe_ms"),
        "keyframe_px": ConfigKey("env.keyframe_px"),
    }
    seen: list[tuple[EnvBenchConfig, tuple[int, ...]]] = []

    def bench(config: EnvBenchConfig, env_counts: tuple[int, ...]) -> None:
        seen.append((config, env_counts))
        raise typer.Exit(0)

    monkeypatch.setattr(perf_env, "bench_env", bench)
    args = ["perf", "env", "--no-breakdown", "--envs", "1", "--scene", "shelf"]
    sets = ["--no-ground-truth", "--set", "env.render_rate_hz=2000", "--set", "seconds=0.5"]
    result = RUNNER.invoke(app, [*args, *sets], prog_name="wander")
    assert result.exit_code == 0, result.output
    ((config, counts),) = seen
    assert counts == (1,) and config.seconds == 0.5
    assert (config.env.scene, config.env.ground_truth, config.env.render_rate_hz) == (
        "shelf",
        False,
        2000.0,
    )
    assert config.env.keyframe_px == EnvBenchConfig().env.keyframe_px == 2.0
    bad = RUNNER.invoke(app, ["perf", "env", "--set", "env.frames=exact"], prog_name="wander")
    assert (bad.exit_code, bad.output.strip()) == (
        2,
        "wander perf env: error: env.frames='exact': each row sets dvs, frames itself",
    )
    assert len(seen) == 1
