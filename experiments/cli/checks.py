"""Checks of the ``wander`` commands' flag values, run while the command line is parsed
(Click callbacks and parsers): each refuses a bad value with a :class:`typer.BadParameter`,
which the command line shows as one line naming the option, what is allowed and the value
(:mod:`experiments.cli.errors`).

Examples:
    >>> check_seconds(2.5), check_dvs("speck"), check_scene("office")
    (2.5, 'speck', 'office')
    >>> try:
    ...     check_seconds(-1.0)
    ... except typer.BadParameter as err:
    ...     print(err)
    must be a finite number of seconds in (0, 86400], got -1.0
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TypeVar

import typer

__all__ = [
    "MAX_SECONDS",
    "MAX_WORKERS",
    "check_dvs",
    "check_positive",
    "check_scene",
    "check_seconds",
    "check_seed",
    "check_wait",
    "check_window",
    "check_workers",
    "comma_list",
    "int_list",
    "int_range",
    "one_of",
    "out_path",
    "seed_list",
]


T = TypeVar("T")

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
    """A seed: an integer in [0, :data:`experiments.studies.framework.MAX_SEED`]."""
    from experiments.studies.framework import MAX_SEED

    if not 0 <= value <= MAX_SEED:
        raise typer.BadParameter(f"must be an integer in [0, {MAX_SEED}], got {value}")
    return value


#: The most worker processes (or local Ray CPUs) a command may start.
MAX_WORKERS = 256


def int_range(minimum: int, maximum: int | None = None) -> Callable[[int | None], int | None]:
    """A check that an integer is in [``minimum``, ``maximum``] (no upper bound without
    ``maximum``; None passes: an optional left unset). Flags use it, not Typer's ``min``
    and ``max``, whose message does not show the value given.

    >>> for check, value in ((int_range(1, 8), 9), (int_range(1), 0)):
    ...     try:
    ...         check(value)
    ...     except typer.BadParameter as err:
    ...         print(err)
    must be an integer in [1, 8], got 9
    must be an integer >= 1, got 0
    """
    allowed = f"in [{minimum}, {maximum}]" if maximum is not None else f">= {minimum}"

    def check(value: int | None) -> int | None:
        if value is not None and not (minimum <= value and (maximum is None or value <= maximum)):
            raise typer.BadParameter(f"must be an integer {allowed}, got {value}")
        return value

    return check


#: A number of worker processes: 1 to :data:`MAX_WORKERS` (None: the default).
check_workers = int_range(1, MAX_WORKERS)


def check_wait(value: float) -> float:
    """A wait (wall seconds): finite and > 0."""
    return check_positive(value, "seconds")  # type: ignore[return-value]


def check_window(value: float) -> float:
    """The fixation window St_w: finite and > 0 seconds."""
    return check_positive(value, "seconds")  # type: ignore[return-value]


def check_scene(value: str) -> str:
    """A scene name (``assets/scenes/NAME.yaml``) or a YAML file that loads
    (:func:`wander_env.env_config.check_scene_name`)."""
    from wander_env.env_config import check_scene_name
    from wander_env.scenes import available_scenes

    try:
        return check_scene_name(value)
    except ValueError as err:
        text = str(err)
        if text.startswith("unknown scene"):
            text = (
                f"unknown scene {value!r}; allowed: {', '.join(available_scenes())} "
                "or a scene .yaml file"
            )
        raise typer.BadParameter(text) from None


def check_dvs(value: str) -> str:
    """A DVS preset name (:func:`wander_env.env_config.check_dvs_preset`)."""
    from wander_env.env_config import check_dvs_preset

    try:
        return check_dvs_preset(value)
    except ValueError as err:
        raise typer.BadParameter(str(err)) from None


def one_of(allowed: Sequence[str]) -> Callable[[str], str]:
    """A check that the value is one of ``allowed``."""

    def check(value: str | None) -> str | None:
        if value is not None and value not in allowed:  # None: an optional left unset
            raise typer.BadParameter(
                f"{value!r} is not allowed; allowed: {', '.join(map(str, allowed))}"
            )
        return value

    return check


def comma_list(text: str, flag: str, what: str, example: str, parse: Callable[[str], T]) -> list[T]:
    """The comma-separated items of option ``flag``, each read by ``parse`` (a
    :class:`typer.BadParameter` of it names ``flag``): at least one, none empty, none
    given twice (``what`` and ``example`` for the messages).

    >>> comma_list("office, hand", "--scenes", "scene", "office,hand", str)
    ['office', 'hand']
    >>> try:
    ...     comma_list("office,,hand", "--scenes", "scene", "office,hand", str)
    ... except typer.BadParameter as err:
    ...     print(err.format_message())
    Invalid value for '--scenes': has an empty scene, got 'office,,hand'
    """
    hint = f"'{flag}'"
    items = [v.strip() for v in text.split(",")]
    if not any(items):
        raise typer.BadParameter(f"needs at least one {what}, e.g. {example}", param_hint=hint)
    if not all(items):
        raise typer.BadParameter(f"has an empty {what}, got {text!r}", param_hint=hint)
    values: list[T] = []
    for item in items:
        try:
            value = parse(item)
        except typer.BadParameter as err:
            raise typer.BadParameter(err.message, param_hint=hint) from None
        if value in values:
            raise typer.BadParameter(f"{what} {item} is given twice, got {text!r}", param_hint=hint)
        values.append(value)
    return values


def int_list(text: str, flag: str, what: str, minimum: int, maximum: int) -> list[int]:
    """Comma-separated integers in [``minimum``, ``maximum``] of option ``flag``
    (:func:`comma_list`: at least one, none empty, none twice).

    >>> int_list("0, 1,2", "--seeds", "seed", 0, 9)
    [0, 1, 2]
    """
    from wander_env.config import MAX_NUMBER_CHARS

    def parse(item: str) -> int:
        if not re.fullmatch(r"[+-]?[0-9]+", item):
            raise typer.BadParameter(
                f"must be integers separated by commas, e.g. 0,1,2, got {text!r}"
            )
        if len(item) > MAX_NUMBER_CHARS:  # int() refuses 4300 digits: said here, on one line
            raise typer.BadParameter(
                f"a number of {len(item)} characters; at most {MAX_NUMBER_CHARS}"
            )
        value = int(item)
        int_range(minimum, maximum)(value)
        return value

    return comma_list(text, flag, what, "0,1,2", parse)


def seed_list(text: str) -> list[int]:
    """A ``--seeds`` (:data:`SeedsOpt`): comma-separated seeds, each an integer in [0,
    :data:`experiments.studies.framework.MAX_SEED`], none twice."""
    from experiments.studies.framework import MAX_SEED

    return int_list(text, "--seeds", "seed", 0, MAX_SEED)


def out_path(text: str) -> Path:
    """An ``--out`` folder: a path, not empty (an empty one would mean the current folder
    unsaid)."""
    if not text:
        raise typer.BadParameter("must name a folder, got ''")
    return Path(text)
