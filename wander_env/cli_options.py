"""Command-line options shared by the commands that run the agent (``wander run``,
``wander evaluate``, ``wander rig``) and build envs (``--frames``, ``--keyframe-ms``): one
definition of each flag and its help.

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
    "FramesOpt",
    "KeyframeMsOpt",
    "StreamlinedOpt",
    "VideoOpt",
    "WindowOpt",
    "agent_alpha",
    "frames_kwargs",
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
        help="sOMS threshold α (default: the agent's calibrated 0.5; the paper's table: 0.8).",
    ),
]


FRAME_MODES = ("keyframes", "exact")  # as wander_env.env.FRAME_MODES (no env import here)
FramesOpt = Annotated[
    str | None,
    typer.Option(
        help="How the env makes its frames: keyframes (render every --keyframe-ms, "
        "synthesise the rest) or exact (render every frame; the reference). "
        "Default: the env's (keyframes)."
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
