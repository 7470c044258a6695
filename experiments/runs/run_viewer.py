"""The run folder's ``run.rrd``: what ``wander run``, ``record`` and ``rig`` log to Rerun.

A thin layer over :class:`wander_env.viewer.RunLog` that knows where things are in an
env step (``obs``, ``info``, the env's camera frame) and in the
:class:`~agents.attention.AttentionAgent` (OMS window map, saliency, P, fixations,
saccades): the run-folder writers call :func:`open_run_log` once and
:meth:`StepLogger.step` after each env step.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from wander_env.viewer import RRD_NAME, RunLog

__all__ = ["StepLogger", "open_run_log"]


class StepLogger:
    """Logs each step of a run (and, with an agent, its decisions and movements)."""

    def __init__(self, log: RunLog, env: Any) -> None:
        self.log = log
        self.base = env.unwrapped
        self._fixations = 0
        self._saccades = 0
        #: Ground truth seen at each step: (object name, t, gaze pan, gaze tilt, centre x,
        #: centre y), the object's pixel centre where it is in front of the camera.
        self.sightings: list[tuple[str, float, float, float, float, float]] = []

    def step(self, obs: dict, info: dict, agent: Any = None) -> None:
        """Log the step just taken (``obs``, ``info`` from ``env.step``) and what the
        agent decided in it."""
        t = float(info.get("t", 0.0))
        self.log.step(
            t,
            camera=getattr(self.base, "camera_frame", None),
            events=obs.get("events"),
            oms=None if agent is None else agent.oms_map,
            gaze_deg=obs.get("gaze"),
            ptu_target_deg=info.get("ptu_target_deg"),
            object_mask=info.get("object_mask"),
        )
        gaze = obs.get("gaze")
        for o in info.get("objects", ()) if gaze is not None else ():
            cx, cy = o["centre_px"]
            if math.isfinite(cx) and math.isfinite(cy):
                self.sightings.append((o["name"], t, float(gaze[0]), float(gaze[1]), cx, cy))
        if agent is None:
            return
        if agent.decided and agent.saliency is not None:
            self.log.decision(t, agent.saliency, agent.target)
        for fx in agent.fixations[self._fixations :]:
            where = "nothing salient" if fx.target_px is None else f"P = {tuple(fx.target_px)}"
            self.log.annotate(
                t,
                f"fixation {fx.index}: {fx.t_start:.3f}–{fx.t_end:.3f} s at pan "
                f"{fx.gaze_deg[0]:.2f}°, tilt {fx.gaze_deg[1]:.2f}°; {where}",
            )
        for sc in agent.saccades[self._saccades :]:
            self.log.annotate(
                t,
                f"saccade {sc.index}: {sc.t_start:.3f}–{sc.t_end:.3f} s to P = "
                f"{tuple(sc.target_px)}, reached pan {sc.to_gaze_deg[0]:.2f}°, tilt "
                f"{sc.to_gaze_deg[1]:.2f}°",
            )
        self._fixations, self._saccades = len(agent.fixations), len(agent.saccades)

    def close(self) -> None:
        self.log.close()


def open_run_log(out_dir: Path, env: Any, title: str) -> StepLogger:
    """Start ``out_dir/run.rrd`` for a run of ``env`` (object names from its scene)."""
    base = env.unwrapped
    scene = getattr(base, "scene", None)
    names = [o.name for o in getattr(scene, "moving_objects", ())]
    return StepLogger(RunLog(Path(out_dir) / RRD_NAME, title=title, object_names=names), env)
