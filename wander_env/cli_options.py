"""Command-line options shared by the commands that run the agent (``wander run``,
``wander evaluate``, ``wander rig``): one definition of each flag and its help.

Example:
    >>> agent_alpha(None), agent_alpha(0.8)
    ({}, {'alpha': 0.8})
"""

from __future__ import annotations

from typing import Annotated

import typer

__all__ = [
    "AgentAlphaOpt",
    "FixationalOpt",
    "SomsNormOpt",
    "StreamlinedOpt",
    "VideoOpt",
    "WindowOpt",
    "agent_alpha",
]

WindowOpt = Annotated[float, typer.Option(help="Fixation window St_w in seconds.")]
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


def _choice(flag: str, value: str, allowed: tuple[str, ...]) -> str:
    if value not in allowed:
        raise typer.BadParameter(f"{flag} must be one of {', '.join(allowed)}, got {value!r}")
    return value


SomsNormOpt = Annotated[
    str,
    typer.Option(
        "--soms-norm",
        callback=lambda v: _choice("--soms-norm", v, ("quantile", "minmax")),
        help="sOMS norm: quantile (the agent's) or minmax (the paper-literal sOMS).",
    ),
]


def agent_alpha(alpha: float | None) -> dict[str, float]:
    """The config keyword for an ``--alpha`` given on the command line (None: the
    config's own default, :data:`agents.attention.AGENT_SOMS_ALPHA`)."""
    return {} if alpha is None else {"alpha": alpha}
