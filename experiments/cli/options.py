"""Command-line options shared by the ``wander`` commands (the agent's flags, the
env's ``--frames`` and ``--keyframe-ms``, scenes, presets, run folders): one definition
of each flag, its help and its check. Flags that several commands take together (the
agent's switches, the frame source) are option groups, added to a command by
:func:`with_options`.

A job command's flag declares the config key it sets beside its option
(:class:`ConfigKey` in its ``Annotated`` metadata: ``--frames`` sets ``env.frames``,
``--alpha`` ``agent.soms.alpha``); unset (``None``, its default) it leaves the config's
value, so the config class holds the one set of defaults. The flags given go through the
one validator (:func:`command_config`, which also reads ``--config`` files and ``--set``
items); other checks run while the command line is parsed (a Click callback). Either
way a bad value is refused before any work starts, with one line naming the option, the
allowed values and the value (:mod:`experiments.cli.errors`).
The checks of single values (seconds, seeds, scenes, comma lists, ``--out``) are
:mod:`experiments.cli.checks`.
"""

from __future__ import annotations

import inspect
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Any, TypeVar

import typer

from experiments.cli.checks import (
    check_dvs,
    check_scene,
    check_seconds,
    check_seed,
    check_window,
    one_of,
    out_path,
)
from experiments.cli.console import step_progress
from experiments.runs.folder import CurrentRun, RunFolder
from wander_env.frames.registry import frame_modes_help

__all__ = [
    "AGENT_OPTIONS",
    "FRAME_OPTIONS",
    "AgentAlphaOpt",
    "ConfigFileOpt",
    "ConfigKey",
    "DvsOpt",
    "FixationalOpt",
    "ForceOpt",
    "FramesOpt",
    "KeyframeMsOpt",
    "QualityOpt",
    "RunDirOpt",
    "SceneOpt",
    "SecondsOpt",
    "SeedOpt",
    "SeedsOpt",
    "SetOpt",
    "SomsNormOpt",
    "StreamlinedOpt",
    "VideoOpt",
    "WindowOpt",
    "command_config",
    "config_flag",
    "flag_keys",
    "flag_name",
    "option",
    "resolve_out",
    "run_env_job",
    "seconds_flag",
    "seed_flag",
    "with_options",
]


@dataclass(frozen=True)
class ConfigKey:
    """The dotted key of a job's config that a flag sets (``--alpha`` sets
    ``agent.soms.alpha``), and ``convert``, how the flag's value becomes the key's
    (``--streamlined`` sets ``agent.proto.polarity_split`` to its negation). It rides in
    the flag's ``Annotated`` metadata beside its ``typer.Option`` (Typer ignores it;
    :func:`flag_keys` reads it): the flag and its key are declared in one place.

    >>> ConfigKey("agent.proto.polarity_split", negate=True).value(True)
    False
    """

    key: str
    negate: bool = False

    def value(self, flag_value: Any) -> Any:
        """The key's value for the flag's value."""
        return not flag_value if self.negate else flag_value


def _unset_or(check: Callable[[Any], Any]) -> Callable[[Any], Any]:
    """``check`` for a flag whose ``None`` means "unset: the config's value"."""
    return lambda value: None if value is None else check(value)


def config_flag(
    kind: Any,
    key: str,
    help: str,
    *names: str,
    check: Callable[[Any], Any] | None = None,
    negate: bool = False,
    **option: Any,
) -> Any:
    """A job's flag that sets the config's ``key`` (:class:`ConfigKey`, ``negate`` as
    there): of type ``kind`` or ``None``, its default, which leaves the config's value;
    ``check`` checks a value given; ``names`` (e.g. ``"--hfov"``) and ``option`` go to its
    ``typer.Option``: ``video: config_flag(bool, "video", "Write run.mp4.") = None``."""
    if check is not None:
        option["callback"] = _unset_or(check)
    return Annotated[kind | None, typer.Option(*names, help=help, **option), ConfigKey(key, negate)]


SceneOpt = config_flag(
    str, "env.scene", "office, gratings, shelf, hand, or a scene YAML file.", check=check_scene
)
DvsOpt = config_flag(str, "env.dvs", "DVS preset: ideal, paper or speck.", check=check_dvs)


def seconds_flag(help: str, key: str = "env.episode_seconds") -> Any:
    """A ``--seconds`` (checked: :func:`check_seconds`) that sets the config's ``key``, with
    a command's own help: ``seconds: seconds_flag("Simulated seconds per row.") = None``."""
    return config_flag(float, key, help, check=check_seconds)


def seed_flag(help: str) -> Any:
    """A job's ``--seed``, which sets the config's ``seed``, with a command's own help:
    ``seed: seed_flag("Seed of the agent.") = None`` (checked: :func:`check_seed`)."""
    return config_flag(int, "seed", help, check=check_seed)


SecondsOpt = seconds_flag("Simulated seconds.")
SeedOpt = Annotated[
    int, typer.Option(callback=check_seed, help="Base seed (repeat r uses seed + r).")
]
#: ``--seeds``: a command's seeds, comma-separated (read with :func:`seed_list`).
SeedsOpt = Annotated[str, typer.Option(help="Comma-separated seeds, none twice.")]
RunDirOpt = Annotated[
    Path | None,
    typer.Option(
        parser=out_path,
        help="The run folder (default: a new time-stamped runs/COMMAND-DATE-TIME/; an "
        "existing non-empty folder needs --force).",
    ),
]
ForceOpt = Annotated[
    bool,
    typer.Option(
        "--force",
        help="Replace an existing, non-empty --out folder (the new run is built beside it, "
        "then swapped in: nothing of the earlier run remains); not the current folder, nor "
        "one that holds it.",
    ),
]
WindowOpt = config_flag(
    float,
    "agent.window_s",
    "Fixation window St_w in seconds (agent.window_s; default: the config's).",
    check=check_window,
)
FixationalOpt = config_flag(
    bool,
    "agent.fixational",
    "Fixational eye movements during fixations (agent.fixational; default: the config's).",
)
StreamlinedOpt = config_flag(
    bool,
    "agent.proto.polarity_split",
    "Streamlined proto-object model (V = V+ or V-, the paper's) instead of one "
    "population per polarity (agent.proto.polarity_split = not streamlined; default: "
    "the config's).",
    negate=True,
)
VideoOpt = config_flag(bool, "video", "Write run.mp4 (default: the config's).")
AgentAlphaOpt = config_flag(
    float,
    "agent.soms.alpha",
    "sOMS threshold α of Eq. (1) (agent.soms.alpha; default: the config's, the "
    "paper's table value).",
)
SomsNormOpt = config_flag(
    str,
    "agent.soms.norm",
    "sOMS norm: quantile (the agent's) or minmax (the paper-literal sOMS) "
    "(agent.soms.norm; default: the config's).",
    "--soms-norm",
    check=one_of(("quantile", "minmax")),
)


FramesOpt = config_flag(
    str, "env.frames", "How the env makes its frames: " + frame_modes_help() + "."
)
QualityOpt = config_flag(
    str,
    "env.quality",
    "Rendering quality: fast (4 samples a pixel, as exact rendering) or fine "
    "(16 samples a pixel: closer to the world, about 3x the rendering time).",
)
KeyframeMsOpt = config_flag(
    float,
    "env.keyframe_ms",
    "Key interval (ms) of --frames keyframes where the image motion has no bound.",
)
ConfigFileOpt = Annotated[
    Path | None,
    typer.Option(
        "--config",
        exists=True,
        dir_okay=False,
        help="A YAML file of the command's config keys (its env and agent blocks, seed, "
        "...). Flags given on the command line and --set override it.",
    ),
]
SetOpt = Annotated[
    list[str] | None,
    typer.Option(
        "--set",
        help="Set any key of the command's config by its dotted path: --set "
        "env.keyframe_px=4, --set agent.soms.alpha=0.5 where the config holds those "
        "blocks (repeatable; applied last; an unknown key lists the keys).",
    ),
]


T = TypeVar("T")
F = TypeVar("F", bound=Callable[..., Any])


def option(name: str, annotation: Any, default: Any = None) -> inspect.Parameter:
    """One shared flag of an option group: the keyword ``name``, its ``Annotated`` alias
    and its default (None for a flag with a :class:`ConfigKey`: unset, the config's
    value) (:func:`with_options`)."""
    kind = inspect.Parameter.KEYWORD_ONLY
    return inspect.Parameter(name, kind, default=default, annotation=annotation)


def with_options(*groups: Sequence[inspect.Parameter]) -> Callable[[F], F]:
    """Give a Typer command the flags of ``groups`` after its own, in order: its
    ``**shared`` keyword receives them (Typer reads the command's signature, which
    this sets; the flags are defined once, in their group).

    >>> @with_options((option("force", ForceOpt, False),))
    ... def command(out: RunDirOpt = None, **shared: Any) -> dict[str, Any]:
    ...     return {"out": out, **shared}
    >>> list(inspect.signature(command).parameters)
    ['out', 'force']
    >>> command(force=True)
    {'out': None, 'force': True}
    """

    def deco(fn: F) -> F:
        sig = inspect.signature(fn, eval_str=True)  # the aliases, not their names
        own = [p for p in sig.parameters.values() if p.kind is not p.VAR_KEYWORD]
        shared = [p for group in groups for p in group]
        fn.__signature__ = sig.replace(parameters=[*own, *shared])  # type: ignore[attr-defined]
        return fn

    return deco


# The agent's switches (``wander run``, ``wander evaluate``) and the env's frame source
# with the run folder's --force and --set (``wander record``, ``run``, ``evaluate``). A
# flag with a ConfigKey is unset (None) by default: the run gets the config's value.
AGENT_OPTIONS = (
    option("window", WindowOpt),
    option("fixational", FixationalOpt),
    option("streamlined", StreamlinedOpt),
    option("alpha", AgentAlphaOpt),
    option("soms_norm", SomsNormOpt),
)
FRAME_OPTIONS = (
    option("force", ForceOpt, False),
    option("frames", FramesOpt),
    option("keyframe_ms", KeyframeMsOpt),
    option("quality", QualityOpt),
    option("set_", SetOpt),
)


def flag_keys(command: Callable[..., Any]) -> dict[str, ConfigKey]:
    """Each flag of ``command`` (a Typer command's function, by parameter name) that
    declares a :class:`ConfigKey`, and that key.

    >>> def command(alpha: AgentAlphaOpt = None, force: ForceOpt = False) -> None: ...
    >>> flag_keys(command)
    {'alpha': ConfigKey(key='agent.soms.alpha', negate=False)}
    """
    sig = inspect.signature(command, eval_str=True)
    out = {}
    for name, param in sig.parameters.items():
        meta = getattr(param.annotation, "__metadata__", ())
        keys = [m for m in meta if isinstance(m, ConfigKey)]
        if keys:
            out[name] = keys[0]
    return out


def flag_name(param: str) -> str:
    """The command-line spelling of the flag of parameter ``param``.

    >>> flag_name("keyframe_ms"), flag_name("hfov_deg")
    ('--keyframe-ms', '--hfov')
    """
    return "--hfov" if param == "hfov_deg" else "--" + param.replace("_", "-")


def _flag_values(ctx: typer.Context) -> tuple[dict[str, Any], dict[str, str]]:
    """The dotted keys and values the command's flags set (a flag left unset, ``None``,
    sets nothing), and each key's flag (for messages)."""
    values, flags = {}, {}
    for name, key in flag_keys(ctx.command.callback).items():  # type: ignore[arg-type]
        value = ctx.params.get(name)
        if value is not None:
            values[key.key] = key.value(value)
            flags[key.key] = flag_name(name)
    return values, flags


def _flags_error(text: str, flags: dict[str, str]) -> typer.BadParameter:
    """A config error of the flags' layer as a usage error on the flag that set the key."""
    for key, flag in flags.items():
        if text.startswith(f"{key}: "):
            return typer.BadParameter(text[len(key) + 2 :], param_hint=f"'{flag}'")
    return typer.BadParameter(text)


def command_config(
    ctx: typer.Context,
    cls: Callable[..., T],
    defaults: Mapping[str, Any] | None = None,
    config_file: Path | None = None,
) -> T:
    """A job's config ``cls`` from its command line, in layers: the class's defaults <-
    the command's own ``defaults`` (dotted keys: ``{"env.episode_seconds": 20.0}``, for a
    command whose runs differ from the class's) <- the ``--config`` file <- the flags given
    (each sets the key of its :class:`ConfigKey`) <- ``--set`` items. Each layer goes
    through the one validator (:func:`wander_env.config.validate`), so a bad value is one
    line naming its flag, file or ``--set`` (exit 2) before anything runs."""
    from experiments.cli.errors import fail
    from experiments.studies.framework import load_yaml_mapping
    from wander_env.config import ConfigError, parse_sets, validate

    config: Any = None
    lead = dict(defaults or {})  # validated with the next layer (it may not stand alone)
    try:
        if config_file is not None:
            file_values = load_yaml_mapping(config_file)
            config = validate(cls, {**lead, **file_values}, None, str(config_file))  # type: ignore[arg-type]
            lead = {}
    except ConfigError as err:
        raise fail(err, ctx) from None
    values, flags = _flag_values(ctx)
    try:
        config = validate(cls, {**lead, **values}, config)  # type: ignore[arg-type]
    except ConfigError as err:
        raise _flags_error(str(err), flags) from None
    try:
        sets = ctx.params.get("set_") or []
        if sets:
            config = validate(cls, parse_sets(sets, cls), config, "--set")  # type: ignore[arg-type]
    except ConfigError as err:
        raise fail(err, ctx) from None
    return config


def own_folder(ctx: typer.Context, make: Callable[[CurrentRun | None], RunFolder]) -> RunFolder:
    """The run folder ``make(current)`` names and creates
    (:class:`experiments.runs.folder.RunFolder`; ``current``: the :class:`CurrentRun` of
    the command of ``ctx``, where it registers), with its
    :meth:`~experiments.runs.folder.RunFolder.finish` called when the command ends, however
    it ends; or a one-line usage error on ``--out`` when the folder is refused (it holds an
    earlier run, it is a file) or cannot be created (under a file, in ``/proc``, a name too
    long), before anything runs."""
    from experiments.cli.errors import current_run

    try:
        folder = make(current_run(ctx))
    except OSError as err:
        raise typer.BadParameter(folder_problem(err), param_hint="'--out'") from None
    ctx.call_on_close(folder.finish)
    return folder


def folder_problem(err: OSError) -> str:
    """What an :class:`OSError` of creating a folder says, on one line: the refusal's own
    words, or the path and the system's reason.

    >>> folder_problem(NotADirectoryError(20, "Not a directory", "/etc/passwd/x"))
    "cannot create '/etc/passwd/x': Not a directory"
    """
    if err.errno is None:
        return str(err)
    return f"cannot create {str(err.filename)!r}: {err.strerror}"


def resolve_out(ctx: typer.Context, out: Path | None, command: str, force: bool) -> RunFolder:
    """The command's run folder (:meth:`experiments.runs.folder.RunFolder.new` through
    :func:`own_folder`): a job writes into its ``path``, the command names its ``final``."""
    return own_folder(ctx, lambda current: RunFolder.new(command, out, force, current=current))


def run_env_job(
    ctx: typer.Context,
    job: Callable[..., T],
    config: Any,
    out: Path | None,
    force: bool,
    command: str,
    title: str,
) -> tuple[Path, T]:
    """Run ``job(folder, config, progress=...)`` in a new run folder of ``out`` and
    ``force`` (:func:`resolve_out`) under one progress bar of the config's env steps;
    returns the folder's final path and the job's result."""
    folder = resolve_out(ctx, out, command, force)
    steps = round(config.env.episode_seconds / config.env.control_period_s)
    with step_progress(title, steps) as progress:
        return folder.final, job(folder.path, config, progress=progress)
