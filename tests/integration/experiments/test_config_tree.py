"""One config tree from flag to env: every job and experiment config holds the env's
settings as one ``env`` block (:class:`wander_env.env_config.WanderConfig`), the CLI maps
each flag to one dotted key (:data:`experiments.cli.options.FLAG_KEYS`), and ``--set
env.frames=exact`` reaches the env from every command that makes one."""

from __future__ import annotations

import ast
import dataclasses
import inspect
import json
from pathlib import Path

import pytest
from locations import ROOT
from typer.testing import CliRunner

from experiments.cli.main import app
from experiments.cli.options import FLAG_KEYS
from experiments.framework import EXPERIMENT_NAMES, get_experiment, resolve_config
from experiments.jobs.record import RecordConfig
from experiments.jobs.rig import RigRunConfig
from experiments.jobs.run_agent import RunConfig
from wander_env.env_config import WanderConfig

RUNNER = CliRunner()

#: The env's settings that once were copied flat into the job and experiment configs.
ENV_SETTINGS = {
    "scene",
    "dvs",
    "frames",
    "keyframe_ms",
    "keyframe_px",
    "keyframe_max_ms",
    "quality",
    "render_rate_hz",
    "control_period_s",
    "episode_seconds",
}
CONFIGS = [RunConfig, RecordConfig, RigRunConfig] + [
    get_experiment(name).config_type for name in EXPERIMENT_NAMES
]


@pytest.mark.parametrize("cls", CONFIGS, ids=lambda c: c.__name__)
def test_the_env_settings_are_one_block_in_every_job_and_experiment_config(cls: type) -> None:
    names = {f.name for f in dataclasses.fields(cls)}
    assert names & ENV_SETTINGS == set()
    env_types = {"WanderConfig", "RigConfig"}
    env = {f.name: f.type for f in dataclasses.fields(cls)}.get("env")
    uses_env = cls.__name__ != "OMSScorecardConfig"  # the scorecard makes no env
    if uses_env:
        assert str(env).split(".")[-1] in env_types


def test_keyframe_px_is_defined_once_as_a_field() -> None:
    """The setting ``keyframe_px`` is declared by WanderConfig alone (FrameParams, the frame
    source's own parameters, is built from it; the env benchmark's row reports it)."""
    owners = []
    for top in ("wander_env", "agents", "hardware", "experiments"):
        for path in (ROOT / top).rglob("*.py"):
            tree = ast.parse(path.read_text(encoding="utf-8"))
            for node in ast.walk(tree):
                if isinstance(node, ast.ClassDef):
                    for item in node.body:
                        target = getattr(item, "target", None)
                        if isinstance(target, ast.Name) and target.id == "keyframe_px":
                            owners.append(f"{path.relative_to(ROOT)}:{node.name}")
    assert sorted(owners) == [
        "experiments/bench/env.py:EnvBenchRow",
        "wander_env/env_config.py:WanderConfig",
        "wander_env/frames/source.py:FrameParams",
    ]


def test_no_command_hands_its_locals_on() -> None:
    calls = []
    for path in (ROOT / "experiments" / "cli").glob("*.py"):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Call) and getattr(node.func, "id", None) == "locals":
                calls.append(f"{path.name}:{node.lineno}")
    assert calls == []


def _defaults(command: str) -> dict[str, object]:
    cmd = next(c for c in app.registered_commands if (c.name or c.callback.__name__) == command)
    sig = inspect.signature(cmd.callback)  # type: ignore[arg-type]
    return {n: p.default for n, p in sig.parameters.items() if n in FLAG_KEYS}


def _at(config: object, dotted: str) -> object:
    for part in dotted.split("."):
        config = getattr(config, part)
    return config


@pytest.mark.parametrize(
    ("command", "config"),
    [
        ("run", RunConfig()),
        ("record", RecordConfig()),
        ("evaluate", RunConfig(env=WanderConfig(episode_seconds=20.0), video=False)),
    ],
)
def test_every_flag_default_is_the_configs_value(command: str, config: object) -> None:
    """``--help`` shows the value the run gets: each flag's default is the value at its
    dotted key in the command's config (None: an optional flag that leaves the key)."""
    defaults = _defaults(command)
    assert len(defaults) >= 7
    for name, default in defaults.items():
        if default is not None:
            assert default == _at(config, FLAG_KEYS[name]), name


@pytest.mark.parametrize("name", EXPERIMENT_NAMES)
def test_set_env_frames_reaches_every_experiment_config(name: str) -> None:
    exp = get_experiment(name)
    if not any(f.name == "env" for f in dataclasses.fields(exp.config_type)):
        pytest.skip(f"{name} makes no env")
    cfg = resolve_config(exp, sets=["env.frames=exact"])
    assert cfg.env.frames == "exact"
    assert cfg.env == dataclasses.replace(resolve_config(exp).env, frames="exact")


@pytest.mark.parametrize(
    "args",
    [
        ["run", "--no-video"],
        ["record", "--policy", "still", "--no-video"],
        ["evaluate", "--seeds", "0"],
    ],
    ids=lambda a: a[0],
)
def test_set_env_frames_reaches_the_env_of_run_record_and_evaluate(
    args: list[str], tmp_path: Path
) -> None:
    out = tmp_path / "out"
    sets = ["--set", "env.frames=exact", "--set", "env.keyframe_px=4"]
    result = RUNNER.invoke(app, [*args, "--seconds", "0.03", "--out", str(out), *sets])
    assert result.exit_code == 0, result.output
    run_json = out / ("0" if args[0] == "evaluate" else "") / "run.json"
    if args[0] == "evaluate":
        run_json = next(out.rglob("run.json"))
    env = json.loads(run_json.read_text())["config"]["env"]
    assert (env["frames"], env["keyframe_px"], env["episode_seconds"]) == ("exact", 4.0, 0.03)


@pytest.mark.parametrize(
    ("args", "line"),
    [
        (
            ["run", "--frames", "fast"],
            "wander run: Invalid value for '--frames': expected one of 'keyframes', 'exact', "
            "'panorama', got 'fast'",
        ),
        (
            ["record", "--set", "env.frames=fast"],
            "wander record: error: --set: env.frames: expected one of 'keyframes', 'exact', "
            "'panorama', got 'fast'",
        ),
        (
            ["evaluate", "--set", "env.keyframe_px=-1"],
            "wander evaluate: error: --set: env.keyframe_px: input should be greater than 0, "
            "got -1",
        ),
    ],
)
def test_a_bad_env_value_is_one_line_naming_its_flag_or_key(
    args: list[str], line: str, tmp_path: Path
) -> None:
    result = RUNNER.invoke(app, [*args, "--out", str(tmp_path / "out")], prog_name="wander")
    assert result.exit_code == 2
    assert result.output.strip() == line
    assert not (tmp_path / "out").exists()


def test_the_env_is_made_from_the_block_alone() -> None:
    cfg = WanderConfig(scene="shelf", frames="exact", keyframe_px=None)
    assert dict(**cfg) == {f.name: getattr(cfg, f.name) for f in dataclasses.fields(cfg)}
    assert WanderConfig(**cfg) == cfg
