"""Command-line options shared by the ``wander`` commands (the agent's flags, the
env's ``--frames`` and ``--keyframe-ms``, scenes, presets, run folders): one definition
of each flag, its help and its check. Flags that several commands take together (the
agent's switches, the frame source) are option groups, added to a command by
:func:`with_options`.

Every check runs while the command line is parsed (a Click callback), so a bad value
is refused before any work starts, with one line naming the option, the allowed values
and the value (:mod:`experiments.cli.errors`).

Examples:
    >>> agent_alpha(None), agent_alpha(0.8)
    ({}, {'alpha': 0.8})
    >>> check_seconds(2.5), check_dvs("speck"), check_scene("office")
    (2.5, 'speck', 'office')
    >>> check_seconds(-1.0)
    Traceback (most recent call last):
    ...
    typer._click.exceptions.BadParameter: must be a finite number of seconds in (0, 86400], got -1.0
"""

from __future__ import annotations

import inspect
import math
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Annotated, Any, TypeVar

import typer

from experiments.cli.console import step_progress
from experiments.framework import MAX_SEED

__all__ = [
    "AGENT_OPTIONS",
    "FRAME_OPTIONS",
    "MAX_SECONDS",
    "MAX_WORKERS",
    "AgentAlphaOpt",
    "DvsOpt",
    "FixationalOpt",
    "ForceOpt",
    "FramesOpt",
    "KeyframeMsOpt",
    "RunDirOpt",
    "SceneOpt",
    "SecondsOpt",
    "SeedOpt",
    "SomsNormOpt",
    "StreamlinedOpt",
    "VideoOpt",
    "WindowOpt",
    "agent_alpha",
    "check_dvs",
    "check_positive",
    "check_scene",
    "check_seconds",
    "check_seed",
    "check_wait",
    "check_workers",
    "frames_kwargs",
    "int_list",
    "job_config",
    "one_of",
    "option",
    "resolve_out",
    "run_env_job",
    "seconds_option",
    "with_options",
]


#: The longest run a ``--seconds`` may ask for (simulated seconds: a day).
MAX_SECONDS = 86400.0


def check_positive(
    value: float | None, unit: str = "", maximum: float | None = None
) -> float | None:
    """A finite number > 0 and <= ``maximum`` when given (``None`` passes: an unset
    optional)."""
    if value is None:
        return None
    if not (math.isfinite(value) and value > 0 and (maximum is None or value <= maximum)):
        of = f" of {unit}" if unit else ""
        bound = f" in (0, {maximum:g}]" if maximum is not None else " > 0"
        raise typer.BadParameter(f"must be a finite number{of}{bound}, got {value!r}")
    return value


def check_seconds(value: float) -> float:
    """Simulated or run seconds: finite, > 0 and at most :data:`MAX_SECONDS`."""
    return check_positive(value, "seconds", MAX_SECONDS)  # type: ignore[return-value]


def check_seed(value: int) -> int:
    """A seed: an integer in [0, :data:`experiments.framework.MAX_SEED`]."""
    if not 0 <= value <= MAX_SEED:
        raise typer.BadParameter(f"must be an integer in [0, {MAX_SEED}], got {value}")
    return value


#: The most worker processes (or local Ray CPUs) a command may start.
MAX_WORKERS = 256


def check_workers(value: int | None) -> int | None:
    """A number of worker processes: 1 to :data:`MAX_WORKERS` (None: the default)."""
    if value is not None and not 1 <= value <= MAX_WORKERS:
        raise typer.BadParameter(f"must be an integer in [1, {MAX_WORKERS}], got {value}")
    return value


def check_wait(value: float) -> float:
    """A wait (wall seconds): finite and > 0."""
    return check_positive(value, "seconds")  # type: ignore[return-value]


def check_window(value: float) -> float:
    """The fixation window St_w: finite and > 0 seconds."""
    return check_positive(value, "seconds")  # type: ignore[return-value]


def check_scene(value: str) -> str:
    """A scene name (``assets/scenes/NAME.yaml``) or a YAML file that loads."""
    from wander_env.scene_config import available_scenes, load_scene_config

    try:
        load_scene_config(value)
    except FileNotFoundError as err:
        raise typer.BadParameter(
            f"{err}; allowed: {', '.join(available_scenes())} or a scene .yaml file"
        ) from None
    except ValueError as err:
        text = str(err)
        if text.startswith("unknown scene"):
            text = (
                f"unknown scene {value!r}; allowed: {', '.join(available_scenes())} "
                "or a scene .yaml file"
            )
        raise typer.BadParameter(text) from None
    return value


def check_dvs(value: str) -> str:
    """A DVS preset name (:meth:`wander_env.dvs.DVSParams.preset`)."""
    from wander_env.dvs import DVSParams

    try:
        DVSParams.preset(value)
    except ValueError as err:
        raise typer.BadParameter(str(err)) from None
    return value


def one_of(allowed: Sequence[str]) -> Callable[[str], str]:
    """A check that the value is one of ``allowed``."""

    def check(value: str | None) -> str | None:
        if value is not None and value not in allowed:  # None: an optional left unset
            raise typer.BadParameter(
                f"{value!r} is not allowed; allowed: {', '.join(map(str, allowed))}"
            )
        return value

    return check


def int_list(text: str, flag: str, what: str = "value", minimum: int | None = None) -> list[int]:
    """Comma-separated integers of option ``flag`` (at least one; each >= ``minimum``).

    >>> int_list("0, 1,2", "--seeds")
    [0, 1, 2]
    """
    try:
        values = [int(v) for v in text.split(",") if v.strip()]
    except ValueError as err:
        msg = f"must be integers separated by commas, e.g. 0,1,2, got {text!r}"
        raise typer.BadParameter(msg, param_hint=f"'{flag}'") from err
    if not values:
        raise typer.BadParameter(f"needs at least one {what}, e.g. 0,1,2", param_hint=f"'{flag}'")
    if minimum is not None and min(values) < minimum:
        msg = f"must be integers >= {minimum}, got {text!r}"
        raise typer.BadParameter(msg, param_hint=f"'{flag}'")
    return values


SceneOpt = Annotated[
    str,
    typer.Option(callback=check_scene, help="office, gratings, shelf, hand, or a scene YAML file."),
]
DvsOpt = Annotated[str, typer.Option(callback=check_dvs, help="DVS preset: ideal, paper or speck.")]


def seconds_option(help: str) -> Any:
    """The ``--seconds`` option (checked: :func:`check_seconds`) with a command's own help,
    for ``Annotated[float, seconds_option("...")]``."""
    return typer.Option(callback=check_seconds, help=help)


SecondsOpt = Annotated[float, seconds_option("Simulated seconds.")]
SeedOpt = Annotated[
    int, typer.Option(callback=check_seed, help="Base seed (repeat r uses seed + r).")
]
RunDirOpt = Annotated[
    Path | None,
    typer.Option(
        help="The run folder (default: a new time-stamped runs/COMMAND-DATE-TIME/; an "
        "existing non-empty folder needs --force)."
    ),
]
ForceOpt = Annotated[
    bool, typer.Option("--force", help="Write into an existing, non-empty --out folder.")
]
WindowOpt = Annotated[
    float, typer.Option(callback=check_window, help="Fixation window St_w in seconds.")
]
FixationalOpt = Annotated[bool, typer.Option(help="Fixational eye movements during fixations.")]
StreamlinedOpt = Annotated[
    bool, typer.Option(help="Streamlined proto-object model (no polarity split).")
]
VideoOpt = Annotated[bool, typer.Option(help="Write run.mp4.")]
AgentAlphaOpt = Annotated[
    float | None,
    typer.Option(
        min=0.0,
        max=1.0,
        help="sOMS threshold α (default: the paper's table 0.8, on the agent's quantile norm).",
    ),
]


SomsNormOpt = Annotated[
    str,
    typer.Option(
        "--soms-norm",
        callback=one_of(("quantile", "minmax")),
        help="sOMS norm: quantile (the agent's) or minmax (the paper-literal sOMS).",
    ),
]


FRAME_MODES = ("keyframes", "exact")  # as wander_env.env.FRAME_MODES (no env import here)
FramesOpt = Annotated[
    str | None,
    typer.Option(
        callback=one_of(("keyframes", "exact")),
        help="How the env makes its frames: keyframes (render every --keyframe-ms, "
        "synthesise the rest) or exact (render every frame; the reference). "
        "Default: the env's (keyframes).",
    ),
]
QualityOpt = Annotated[
    str,
    typer.Option(
        callback=one_of(("fast", "fine")),
        help="Rendering quality: fast (4 samples a pixel, as exact rendering) or fine "
        "(16 samples a pixel: closer to the world, about 3x the rendering time).",
    ),
]
KeyframeMsOpt = Annotated[
    float | None,
    typer.Option(min=0.001, help="Keyframe interval (ms) of --frames keyframes (default 2)."),
]


def frames_kwargs(frames: str | None, keyframe_ms: float | None) -> dict[str, object]:
    """The env config keywords for ``--frames``/``--keyframe-ms`` (only those given).

    >>> frames_kwargs("exact", None), frames_kwargs(None, 5.0)
    ({'frames': 'exact'}, {'keyframe_ms': 5.0})
    """
    out: dict[str, object] = {}
    if frames is not None:
        if frames not in FRAME_MODES:
            raise typer.BadParameter(f"--frames must be one of {FRAME_MODES}, got {frames!r}")
        out["frames"] = frames
    if keyframe_ms is not None:
        if abs(keyframe_ms - round(keyframe_ms)) > 1e-9 or round(keyframe_ms) < 1:
            msg = f"--keyframe-ms must be a whole number of 1 ms render ticks, got {keyframe_ms}"
            raise typer.BadParameter(msg)
        out["keyframe_ms"] = float(keyframe_ms)
    return out


def agent_alpha(alpha: float | None) -> dict[str, float]:
    """The config keyword for an ``--alpha`` given on the command line (None: the
    config's own default, :data:`agents.attention.AGENT_SOMS_ALPHA`)."""
    return {} if alpha is None else {"alpha": alpha}


T = TypeVar("T")
F = TypeVar("F", bound=Callable[..., Any])


def option(name: str, annotation: Any, default: Any) -> inspect.Parameter:
    """One shared flag of an option group: the keyword ``name``, its ``Annotated`` alias
    and its default (:func:`with_options`)."""
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
# with the run folder's --force (``wander record``, ``run``, ``evaluate``).
AGENT_OPTIONS = (
    option("streamlined", StreamlinedOpt, False),
    option("alpha", AgentAlphaOpt, None),
    option("soms_norm", SomsNormOpt, "quantile"),
)
FRAME_OPTIONS = (
    option("force", ForceOpt, False),
    option("frames", FramesOpt, None),
    option("keyframe_ms", KeyframeMsOpt, None),
    option("quality", QualityOpt, "fast"),
)

# Flags named otherwise than the config field they set.
FIELD_OF_FLAG = {"window": "window_s"}


def job_config(cls: Callable[..., T], flags: Mapping[str, Any], **fixed: Any) -> T:
    """A job's config ``cls`` from a command's flags (``locals()`` on entry): every
    keyword of ``cls`` that a flag of the same name sets (``--window`` sets ``window_s``);
    ``--alpha``, ``--frames`` and ``--keyframe-ms`` only when given (:func:`agent_alpha`,
    :func:`frames_kwargs`: the config's defaults otherwise); ``fixed`` sets keywords the
    command fixes. Flags that are no keyword of ``cls`` (``--out``, ``--force``) are left.

    >>> from dataclasses import dataclass
    >>> @dataclass
    ... class Job:
    ...     seconds: float = 1.0
    ...     window_s: float = 0.1
    ...     alpha: float = 0.8
    ...     video: bool = True
    >>> job_config(Job, {"seconds": 2.0, "window": 0.2, "alpha": None, "force": True})
    Job(seconds=2.0, window_s=0.2, alpha=0.8, video=True)
    >>> job_config(Job, {"alpha": 0.5, "video": True}, video=False)
    Job(seconds=1.0, window_s=0.1, alpha=0.5, video=False)
    """
    special = ("alpha", "frames", "keyframe_ms")
    keywords = set(inspect.signature(cls).parameters)
    kwargs: dict[str, Any] = {
        FIELD_OF_FLAG.get(flag, flag): value
        for flag, value in flags.items()
        if FIELD_OF_FLAG.get(flag, flag) in keywords and flag not in special
    }
    if "alpha" in flags:
        kwargs.update(agent_alpha(flags["alpha"]))
    if "frames" in flags or "keyframe_ms" in flags:
        kwargs.update(frames_kwargs(flags.get("frames"), flags.get("keyframe_ms")))
    return cls(**{**kwargs, **fixed})


def resolve_out(out: Path | None, command: str, force: bool) -> Path:
    """The path of the run folder (:meth:`experiments.runs.folder.RunFolder.new`, registered
    as the command's current run), or a usage error on ``--out`` when it holds an earlier
    run."""
    from experiments.cli.errors import current_run
    from experiments.runs.folder import RunFolder

    try:
        return RunFolder.new(command, out, force, current=current_run()).path
    except FileExistsError as err:
        raise typer.BadParameter(str(err), param_hint="'--out'") from None


def run_env_job(
    job: Callable[..., T],
    cls: Callable[..., Any],
    flags: Mapping[str, Any],
    command: str,
    title: str,
) -> tuple[Path, T]:
    """Run ``job(folder, config, progress=...)`` with the config ``cls`` of a command's
    ``flags`` (:func:`job_config`) in a new run folder of its ``--out`` and ``--force``
    (:func:`resolve_out`) under one progress bar of ``config.seconds`` in env steps of
    10 ms; returns the folder and what the job returned."""
    config = job_config(cls, flags)
    folder = resolve_out(flags["out"], command, flags["force"])
    with step_progress(title, round(config.seconds / 0.01)) as progress:
        return folder, job(folder, config, progress=progress)
