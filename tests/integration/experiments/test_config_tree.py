"""One config tree from flag to env and agent: every job and experiment config holds the
env's settings as one ``env`` block (:class:`wander_env.env_config.WanderConfig`) and a
job's agent settings as one ``agent`` block (:class:`agents.attention.AgentParams`), each
flag declares the dotted key it sets (:class:`experiments.cli.options.ConfigKey`) and
takes its default from the config, and ``--set env.frames=exact`` / ``--set
agent.soms.alpha=0.5`` reach the env and the agent from every command that makes one."""

from __future__ import annotations

import ast
import dataclasses
import inspect
import json
import typing
from dataclasses import replace
from pathlib import Path

import pytest
from locations import ROOT
from typer.testing import CliRunner

from agents.attention import AgentParams
from experiments.benchmark.model import ModelConfig
from experiments.cli.main import app
from experiments.cli.options import ConfigKey, flag_keys
from experiments.jobs.dvs_demo import DemoConfig
from experiments.jobs.evaluate_agent import EvaluateConfig
from experiments.jobs.record import RecordConfig
from experiments.jobs.rig import RigRunConfig
from experiments.jobs.run_agent import RunConfig
from experiments.studies.framework import EXPERIMENT_NAMES, get_experiment, resolve_config
from hardware.rig_env import RigConfig
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
        "experiments/perf/env.py:EnvBenchRow",
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


#: The agent's own settings (not the sensor's geometry, which is the env's), and the flat
#: names they once had in the job configs.
AGENT_SETTINGS = {
    f.name for f in dataclasses.fields(AgentParams) if f.name not in {"width_px", "height_px"}
} - {"hfov_deg", "step_s"} | {"alpha", "soms_norm", "streamlined", "polarity_split"}
JOB_CONFIGS = [RunConfig, RigRunConfig, ModelConfig]


def _field_names(cls: type, skip: tuple[str, ...] = ("agent",)) -> list[str]:
    """The dotted names of every field of dataclass ``cls``, through nested dataclass
    blocks (each member of a union), except under the fields ``skip``."""
    out = []
    hints = typing.get_type_hints(cls)
    for f in dataclasses.fields(cls):
        out.append(f.name)
        tp = hints[f.name]
        blocks = [t for t in (typing.get_args(tp) or (tp,)) if dataclasses.is_dataclass(t)]
        if f.name not in skip:
            out += [f"{f.name}.{n}" for b in blocks for n in _field_names(b, skip=())]
    return out


@pytest.mark.parametrize("cls", JOB_CONFIGS, ids=lambda c: c.__name__)
def test_the_agent_settings_are_one_block_in_every_job_config(cls: type) -> None:
    """No flat agent field anywhere in a job's config tree: the agent's settings are its
    ``agent`` block, an AgentParams."""
    names = _field_names(cls)
    flat = [n for n in names if n.split(".")[-1] in AGENT_SETTINGS]
    assert flat == []
    assert typing.get_type_hints(cls)["agent"] is AgentParams


#: The experiments that run the attention agent; the others study some of its components
#: alone (the sOMS, the saliency front end), which they read from the agent's block.
AGENT_EXPERIMENTS = {"sac_accuracy", "saccade_speed", "scanpath"}
COMPONENT_STUDIES = {
    "oms_characterisation": ("soms",),
    "event_suppression": ("soms",),
    "detection": ("soms", "proto"),
    "oms_scorecard": ("soms",),
}
#: Fields whose name an agent setting shares and which are not one: the hand trials'
#: event-count window (2 ms), not the agent's fixation window.
NOT_AGENT_SETTINGS = {"event_suppression": ["window_s"]}


def _agent_blocks(cls: type) -> list[str]:
    """The fields of ``cls`` that are agent blocks (AgentParams, or AgentParams | None)."""
    hints = typing.get_type_hints(cls)
    return [
        f.name
        for f in dataclasses.fields(cls)
        if AgentParams in (typing.get_args(hints[f.name]) or (hints[f.name],))
    ]


def test_every_experiment_is_an_agent_experiment_or_a_component_study() -> None:
    assert sorted(AGENT_EXPERIMENTS | set(COMPONENT_STUDIES)) == sorted(EXPERIMENT_NAMES)


@pytest.mark.parametrize("name", EXPERIMENT_NAMES)
def test_every_experiment_holds_the_agent_settings_as_agent_blocks(name: str) -> None:
    """Every experiment config is walked: its ``agent`` block is an AgentParams (the hand
    trials' optional ``second_agent`` too), and no agent setting stands outside them."""
    cls = get_experiment(name).config_type
    blocks = _agent_blocks(cls)
    assert blocks == (["agent", "second_agent"] if name == "event_suppression" else ["agent"])
    flat = [n for n in _field_names(cls, skip=tuple(blocks)) if n.split(".")[-1] in AGENT_SETTINGS]
    assert flat == NOT_AGENT_SETTINGS.get(name, [])


@pytest.mark.parametrize("name", sorted(COMPONENT_STUDIES))
def test_a_component_study_refuses_an_agent_setting_it_ignores(name: str) -> None:
    """A study of the agent's components reads only them: ``agent.window_s`` (the
    fixation window, no part of any) is one line, exit 2; its components are listed."""
    bad = RUNNER.invoke(
        app, ["experiment", name, "--set", "agent.window_s=0.05"], prog_name="wander"
    )
    used = ", ".join(f"agent.{b}" for b in COMPONENT_STUDIES[name])
    assert bad.exit_code == 2
    assert bad.output.strip() == (
        f"wander experiment: error: --set: agent.window_s: 0.05 plays no part here (only "
        f"{used} do); leave it at its default, 0.124"
    )


@pytest.mark.parametrize(
    ("args", "field", "value", "default"),
    [
        (["run", "--seconds", "0.1"], "width_px", "64", "128"),
        (["evaluate", "--seconds", "0.1"], "step_s", "0.02", "0.01"),
        (["experiment", "scanpath"], "hfov_deg", "90", "112.82670869275442"),
        (["experiment", "saccade_speed"], "height_px", "64", "128"),
        (
            ["experiment", "sac_accuracy"],
            "ptu_resolution_arcsec",
            "[46.3, 46.3]",
            "(92.5714, 92.5714)",
        ),
    ],
)
def test_an_agent_runs_with_the_envs_sensor_step_lens_and_ptu(args, field, value, default):
    """What the env sets (agents.attention.ENV_FIELDS) is refused in an agent block whose
    agent runs on an env (on_env would drop it): one line, exit 2, nothing run."""
    bad = RUNNER.invoke(app, [*args, "--set", f"agent.{field}={value}"], prog_name="wander")
    assert bad.exit_code == 2, bad.output
    shown = bad.output.strip().split(f"agent.{field}: ", 1)[1]
    assert shown.endswith(
        "is the env's to set (its camera, PTU and control period), not the agent block's; "
        f"leave it at its default, {default}"
    )


@pytest.mark.parametrize("name", EXPERIMENT_NAMES)
def test_set_agent_soms_alpha_reaches_every_experiment(name: str) -> None:
    result = RUNNER.invoke(
        app,
        ["experiment", name, "--show-config", "--set", "agent.soms.alpha=0.5"],
        prog_name="wander",
    )
    assert result.exit_code == 0, result.output
    shown = json.loads(result.output)
    assert shown["agent"]["soms"]["alpha"] == 0.5
    default = resolve_config(get_experiment(name)).agent.soms
    assert resolve_config(get_experiment(name), sets=["agent.soms.alpha=0.5"]).agent.soms == (
        replace(default, alpha=0.5)
    )
    bad = RUNNER.invoke(
        app, ["experiment", name, "--set", "agent.soms.alpha=x"], prog_name="wander"
    )
    assert bad.exit_code == 2
    assert bad.output.strip() == (
        "wander experiment: error: --set: agent.soms.alpha: expected float, got 'x'"
    )


@pytest.mark.parametrize(
    ("args", "line"),
    [
        (
            ["run", "--set", "agent.soms.alpha=x"],
            "wander run: error: --set: agent.soms.alpha: expected float, got 'x'",
        ),
        (
            ["evaluate", "--set", "agent.soms=bogus"],
            "wander evaluate: error: --set: agent.soms: soms must be one of ['agent', "
            "'paper', 'speck'] or a parameter block, got 'bogus'",
        ),
        (
            ["benchmark", "suppression", ".", "--set", "agent.soms.alpha=2"],
            "wander benchmark suppression: error: --set: agent.soms.alpha: alpha must be in "
            "[0, 1], got 2.0",
        ),
        (
            ["benchmark", "suppression", ".", "--set", "agent.window_s=0.05"],
            "wander benchmark suppression: error: --set: agent.window_s: 0.05 plays no part "
            "here (only agent.soms, agent.proto do); leave it at its default, 0.124",
        ),
        (
            ["experiment", "detection", "--set", "agent.soms=speck"],
            "wander experiment: error: --set: agent.soms: the sOMS pipeline runs here; the "
            "front end on Speck's cores (SpeckFrontParams) is not one",
        ),
        (
            ["run", "--set", "soms.alpha=0.5"],
            "wander run: error: --set: unknown key 'soms' for RunConfig; allowed keys: env "
            "(WanderConfig), seed (int), video (bool), video_fps (int), agent (AgentParams)",
        ),
    ],
    ids=["run", "evaluate", "benchmark", "benchmark-ignored", "detection-speck", "flat"],
)
def test_a_bad_agent_value_is_one_line_naming_the_key_and_value(
    args: list[str], line: str, tmp_path: Path
) -> None:
    result = RUNNER.invoke(app, [*args, "--out", str(tmp_path / "out")], prog_name="wander")
    assert (result.exit_code, result.output.strip()) == (2, line)
    assert not (tmp_path / "out").exists()


def _command(name: str):
    return next(c for c in app.registered_commands if (c.name or c.callback.__name__) == name)


def _at(config: object, dotted: str) -> object:
    for part in dotted.split("."):
        config = getattr(config, part)
    return config


@pytest.mark.parametrize(
    ("command", "config", "flags"),
    [
        (
            "run",
            RunConfig(),
            "scene seconds seed dvs window fixational video video_fps streamlined alpha "
            "soms_norm frames keyframe_ms quality",
        ),
        (
            "record",
            RecordConfig(),
            "scene seconds policy dvs seed video format frames keyframe_ms quality",
        ),
        (
            "evaluate",
            EvaluateConfig(),
            "scene seconds dvs window fixational streamlined alpha soms_norm frames "
            "keyframe_ms quality",
        ),
        ("demo", DemoConfig(), "seconds preset seed"),
        (
            "rig",
            RigRunConfig(RigConfig(ptu_port="emulate", camera="speck", replay="fast")),
            "ptu camera replay seconds hfov_deg seed window fixational streamlined alpha "
            "soms_norm video",
        ),
    ],
)
def test_every_flag_sets_a_key_of_its_config_and_defaults_to_the_configs_value(
    command: str, config: object, flags: str
) -> None:
    """Each job flag declares the key it sets on its option, and is unset by default (the
    run gets the config's value: no second set of defaults); rig's --ptu and --camera
    are required."""
    callback = _command(command).callback
    keys = flag_keys(callback)
    assert sorted(keys) == sorted(flags.split())
    sig = inspect.signature(callback)
    for name, key in keys.items():
        default = sig.parameters[name].default
        assert default is (inspect.Parameter.empty if name in ("ptu", "camera") else None)
        _at(config, key.key)  # a key of the config
    if "streamlined" in keys:
        assert keys["streamlined"] == ConfigKey("agent.proto.polarity_split", negate=True)
        assert keys["alpha"] == ConfigKey("agent.soms.alpha")


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
    agent = args[0] != "record"  # record runs a gaze policy, no agent
    if agent:
        sets += ["--set", "agent.soms.alpha=0.5", "--window", "0.02", "--streamlined"]
    result = RUNNER.invoke(app, [*args, "--seconds", "0.03", "--out", str(out), *sets])
    assert result.exit_code == 0, result.output
    run_json = out / ("0" if args[0] == "evaluate" else "") / "run.json"
    if args[0] == "evaluate":
        run_json = next(out.rglob("run.json"))
    record = json.loads(run_json.read_text())
    env = record["config"]["env"]
    assert (env["frames"], env["keyframe_px"], env["episode_seconds"]) == ("exact", 4.0, 0.03)
    if agent:  # the agent block, as configured and as the agent ran
        for block in (record["config"]["agent"], record["agent"]):
            assert (block["soms"]["alpha"], block["window_s"]) == (0.5, 0.02)
            assert block["proto"]["polarity_split"] is False


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
