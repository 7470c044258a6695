"""What watches a closed-loop run: observers with Gymnasium-style hooks.

:func:`experiments.jobs.run_agent.run_closed_loop` calls, for every observer, in order:
:meth:`RunObserver.on_reset` after ``env.reset`` and ``agent.reset``;
:meth:`RunObserver.on_act` after ``agent.act`` (the env still in the pose the agent
decided in, ``obs``/``info`` the ones the agent saw); :meth:`RunObserver.on_step` after
``env.step`` (``obs``/``info`` the step's); :meth:`RunObserver.close` once when the loop
ended, with the loop's error (``None``: none), returning the error to raise (an observer
whose file failed to close hands back its own when the run had none).

The run's own watchers are here: the events file (:class:`EventsObserver`), the video
(:class:`VideoObserver`), the Rerun log (:class:`RerunObserver`) and detection scoring
(:class:`DetectionObserver`); a study adds
its own (the scanpath experiment's :class:`experiments.paper.scanpath.ScanpathObserver`).
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from agents.attention import AttentionAgent, Phase
from experiments.metrics import detection_hit
from experiments.runs.viewer import open_run_log
from wander_env.entities import object_body_name
from wander_env.events.stream import EventStreamWriter, OutputError, VideoSink

__all__ = [
    "DetectionObserver",
    "EventsObserver",
    "RerunObserver",
    "RunObserver",
    "VideoObserver",
]


class RunObserver:
    """An observer that watches nothing (override the hooks it needs)."""

    def on_reset(self, env: Any, agent: AttentionAgent, obs: dict, info: dict) -> None:
        """After ``env.reset`` and ``agent.reset``."""

    def on_act(self, env: Any, agent: AttentionAgent, obs: dict, info: dict) -> None:
        """After ``agent.act(obs, info)``, before the env steps."""

    def on_step(self, env: Any, agent: AttentionAgent, obs: dict, info: dict) -> None:
        """After ``env.step``: ``obs`` and ``info`` of the step."""

    def close(self, error: BaseException | None) -> BaseException | None:
        """The loop ended (with ``error``); returns the error to raise."""
        return error


class EventsObserver(RunObserver):
    """``path``: every event of the run, written as it goes
    (:class:`~wander_env.events.stream.EventStreamWriter`: memory does not grow with the
    run's length); ``events``: how many. The file stays open after :meth:`close` until
    :meth:`finish` writes the run's record into it (the loop calls it first in a step, so
    a step counts once its events are on disk)."""

    def __init__(self, path: Path, sensor_size: tuple[int, int, int], record: dict) -> None:
        self.stream = EventStreamWriter(path, sensor_size, record)
        self.events = 0

    def on_step(self, env: Any, agent: AttentionAgent, obs: dict, info: dict) -> None:
        step_events = info["events"].events
        self.stream.append(step_events)
        self.events += len(step_events)

    def finish(self, record: dict | None = None) -> None:
        """Close the file with ``record`` (after a failure: ``None``, and a close that
        cannot write either is not raised: the run's own error is)."""
        if record is not None:
            self.stream.close(record)
            return
        try:
            self.stream.close()
        except OutputError:
            pass


class VideoObserver(RunObserver):
    """``path`` (an MP4 at ``fps``): one frame a step, ``frame(agent, obs, env, info)``.
    ``complete`` after :meth:`close`: whether the file is a whole MP4."""

    def __init__(
        self,
        path: Path,
        fps: int,
        frame: Callable[[AttentionAgent, dict, Any, dict], np.ndarray],
    ) -> None:
        self.sink = VideoSink(path, fps=fps)
        self.frame = frame
        self.complete: bool | None = None

    def on_step(self, env: Any, agent: AttentionAgent, obs: dict, info: dict) -> None:
        self.sink.append(self.frame(agent, obs, env.unwrapped, info))

    def close(self, error: BaseException | None) -> BaseException | None:
        error = self.sink.finish(error)
        self.complete = self.sink.complete
        return error


class RerunObserver(RunObserver):
    """``out_dir/run.rrd`` (:func:`~experiments.runs.viewer.open_run_log`); ``sightings``
    after :meth:`close`: the ground truth the run saw."""

    def __init__(self, out_dir: Path, env: Any, title: str) -> None:
        self.log = open_run_log(out_dir, env, title)
        self.sightings: list[tuple] = []

    def on_step(self, env: Any, agent: AttentionAgent, obs: dict, info: dict) -> None:
        self.log.step(obs, info, agent)

    def close(self, error: BaseException | None) -> BaseException | None:
        self.log.close()
        self.sightings = self.log.sightings
        return error


class DetectionObserver(RunObserver):
    """Scores each decision: whether the 8×8 box around ``P`` touches a moving object's
    mask (the union over the fixation window, the latest step's ids on top), and which.

    Per decision: ``maps`` (the saliency), ``hits`` (``None``: no mask or no ``P``),
    ``hit_objects`` (named as in the scene file, ``+``-joined; "" for none); per saccade:
    ``clipped`` (its target lay beyond the PTU's range).
    """

    def __init__(self) -> None:
        self.maps: list[np.ndarray] = []
        self.hits: list[bool | None] = []
        self.hit_objects: list[str] = []
        self.clipped: list[bool] = []
        self._phase: Phase | None = None
        self._saccades = 0
        self._window: np.ndarray | None = None
        self._clipping = False

    def on_reset(self, env: Any, agent: AttentionAgent, obs: dict, info: dict) -> None:
        self._phase, self._saccades = agent.phase, len(agent.saccades)

    def on_act(self, env: Any, agent: AttentionAgent, obs: dict, info: dict) -> None:
        mask = info.get("object_mask")
        if mask is not None and self._phase is Phase.FIXATE:  # the step went into the window
            self._window = mask if self._window is None else np.where(mask > 0, mask, self._window)
        if len(agent.saccades) > self._saccades:  # a saccade ended at this step
            self.clipped.append(self._clipping)
        if agent.decided:
            self.maps.append(agent.saliency.copy())
            hit, hit_object = None, ""
            window = self._window
            if window is not None and window.any() and agent.target is not None:
                hit = detection_hit(agent.target, window > 0)
                hit_object = objects_hit(agent.target, window, info)
            self.hits.append(hit)
            self.hit_objects.append(hit_object)
            self._window = None
            self._clipping = False
        self._phase, self._saccades = agent.phase, len(agent.saccades)

    def on_step(self, env: Any, agent: AttentionAgent, obs: dict, info: dict) -> None:
        if agent.phase is Phase.SACCADE:
            self._clipping |= bool(info.get("target_clipped", False))


def objects_hit(target: tuple[int, int], ids: np.ndarray, info: dict) -> str:
    """The moving objects (named as in the scene file, ``+``-joined in id order) whose
    masks in ``ids`` (object ids, 0 = none) the detection box around ``target`` touches
    (:func:`~experiments.metrics.detection_hit`); "" for none."""
    names = {o["id"]: str(o["name"]) for o in info.get("objects", ())}
    hit = [int(k) for k in np.unique(ids[ids > 0]) if detection_hit(target, ids == k)]
    return "+".join(names.get(k) or object_body_name(k) for k in hit)
