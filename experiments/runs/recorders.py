"""What watches a run: recorders, opt-in, composed by :func:`~experiments.runs.episode.run_episode`.

The hooks (:class:`~experiments.runs.episode.Recorder`) come in Gymnasium's order:
``on_reset``, then per step ``on_act`` and ``on_step``, then ``close(error)`` once;
``metrics()`` is what a recorder adds to the run's ``metrics.json``
(:class:`FolderRecorder` gathers them).

The files of a run folder: the events (:class:`EventsRecorder`), the ground truth
(:class:`GroundTruthRecorder`), the video (:class:`VideoRecorder`), the Rerun log
(:class:`RerunRecorder`), and the folder itself (:class:`FolderRecorder`: ``metrics.json``,
``run.json``, the ``INCOMPLETE`` marker; closed last). In memory: detection scoring
(:class:`DetectionRecorder`), the env's readout counters (:class:`ReadoutRecorder`); a study
or a command adds its own (the scanpath experiment's
:class:`experiments.paper.scanpath.ScanpathRecorder`, the rig's
:class:`experiments.jobs.rig.RigCounters`).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from experiments.metrics import detection_hit
from experiments.runs.episode import Recorder
from experiments.runs.folder import RunFolder
from experiments.runs.signals import SignalExit
from experiments.runs.viewer import open_run_log
from wander_env.entities import object_body_name
from wander_env.events.stream import EventStreamWriter, H5Appender, OutputError, VideoSink

__all__ = [
    "DetectionRecorder",
    "EventsRecorder",
    "FolderRecorder",
    "GroundTruthRecorder",
    "ReadoutRecorder",
    "RerunRecorder",
    "VideoRecorder",
    "objects_hit",
    "video_frames",
]


class EventsRecorder(Recorder):
    """``path`` (``events.h5``): every event of the run, written as it goes
    (:class:`~wander_env.events.stream.EventStreamWriter`: memory does not grow with the
    run's length); ``events``: how many. :meth:`close` stores ``record`` with the run's
    ``summary`` (steps, events) in the file's metadata."""

    def __init__(self, path: Path, sensor_size: tuple[int, int, int], record: dict) -> None:
        self.stream = EventStreamWriter(path, sensor_size, record)
        self.record = record
        self.events = 0
        self.steps = 0

    def on_step(self, env: Any, policy: Any, obs: Any, info: dict) -> None:
        step_events = info["events"].events
        self.stream.append(step_events)
        self.events += len(step_events)
        self.steps += 1

    def close(self, error: BaseException | None) -> BaseException | None:
        summary = {"steps": self.steps, "events": self.events}
        try:
            self.stream.close(self.record | {"summary": summary})
        except OutputError as err:
            return error or err
        return error

    def metrics(self) -> dict[str, Any]:
        return {"events": self.events}


class GroundTruthRecorder(Recorder):
    """``path`` (``ground_truth.h5``): per step the time, gaze, PTU positions, object-id
    mask, each moving object's pixel centre, mask size and visibility."""

    def __init__(self, path: Path, env: Any) -> None:
        base = env.unwrapped
        self.n_obj = n_obj = len(base.scene.moving_objects)
        h, w = base.height, base.width
        fields = {
            "t": (np.float64, ()),
            "gaze_deg": (np.float32, (2,)),
            "ptu_positions": (np.int32, (2,)),
            "object_mask": (np.uint8, (h, w)),
            "object_centre_px": (np.float32, (n_obj, 2)),
            "object_mask_pixels": (np.int32, (n_obj,)),
        }
        attrs = {
            "object_names": [o.name for o in base.scene.moving_objects],
            "mask_ids": "0 = background, k = moving object k (1-based)",
        }
        self.truth = H5Appender(path, fields, attrs, chunk_rows=100)

    def on_step(self, env: Any, policy: Any, obs: Any, info: dict) -> None:
        centre = np.full((self.n_obj, 2), np.nan, np.float32)
        pixels = np.zeros(self.n_obj, np.int32)
        for j, o in enumerate(info["objects"]):
            centre[j], pixels[j] = o["centre_px"], o["mask_pixels"]
        self.truth.append(
            t=info["t"],
            gaze_deg=obs["gaze"],
            ptu_positions=info["ptu_positions"],
            object_mask=info["object_mask"],
            object_centre_px=centre,
            object_mask_pixels=pixels,
        )

    def close(self, error: BaseException | None) -> BaseException | None:
        try:
            self.truth.close()
        except OutputError as err:
            return error or err
        return error


def video_frames(steps: int, step_s: float, fps: float) -> int:
    """The frames a video at ``fps`` holds after ``steps`` steps of ``step_s``: frame ``n``
    shows the time ``n / fps``, taken at the end of the step it falls in.

    >>> video_frames(150, 0.01, 30), video_frames(150, 0.01, 100), video_frames(1, 0.01, 30)
    (45, 150, 1)
    """
    return math.ceil(round(steps * step_s * fps, 6))


class VideoRecorder(Recorder):
    """``path``: an MP4 at ``fps`` frames per simulated second, ``frame(env, policy, obs,
    info)`` composed only when a frame is due (:func:`video_frames`; at more frames a
    second than steps, a step's frame is repeated). ``complete`` after :meth:`close`:
    whether the file is a whole MP4."""

    def __init__(
        self,
        path: Path,
        fps: int,
        step_s: float,
        frame: Callable[[Any, Any, Any, dict], np.ndarray],
    ) -> None:
        self.sink = VideoSink(path, fps=fps)
        self.fps, self.step_s = fps, step_s
        self.frame = frame
        self.steps = self.frames = 0
        self.complete: bool | None = None

    def on_step(self, env: Any, policy: Any, obs: Any, info: dict) -> None:
        self.steps += 1
        due = video_frames(self.steps, self.step_s, self.fps) - self.frames
        if due > 0:
            image = self.frame(env, policy, obs, info)
            for _ in range(due):
                self.sink.append(image)
            self.frames += due

    def close(self, error: BaseException | None) -> BaseException | None:
        error = self.sink.finish(error)
        self.complete = self.sink.complete
        return error

    def metrics(self) -> dict[str, Any]:
        return {} if self.complete is None else {"video_complete": self.complete}


class RerunRecorder(Recorder):
    """``out_dir/run.rrd`` (:func:`~experiments.runs.viewer.open_run_log`), with the
    agent's maps, decisions and movements when ``agent`` (the policy is an
    :class:`~agents.attention.AttentionAgent`); ``sightings`` after :meth:`close`: the
    ground truth the run saw."""

    def __init__(self, out_dir: Path, env: Any, title: str, agent: bool = True) -> None:
        self.log = open_run_log(out_dir, env, title)
        self.agent = agent
        self.sightings: list[tuple] = []

    def on_step(self, env: Any, policy: Any, obs: Any, info: dict) -> None:
        self.log.step(obs, info, policy if self.agent else None)

    def close(self, error: BaseException | None) -> BaseException | None:
        self.log.close()
        self.sightings = self.log.sightings
        return error


class DetectionRecorder(Recorder):
    """Scores each decision of an :class:`~agents.attention.AttentionAgent`: whether the
    8×8 box around ``P`` touches a moving object's mask (the union over the fixation
    window, the latest step's ids on top), and which.

    Per decision: ``maps`` (the saliency), ``hits`` (``None``: no mask or no ``P``),
    ``hit_objects`` (named as in the scene file, ``+``-joined; "" for none); per saccade:
    ``clipped`` (its target lay beyond the PTU's range).
    """

    def __init__(self) -> None:
        from agents.attention import Phase  # torch: only where an agent runs

        self._phases = Phase
        self.maps: list[np.ndarray] = []
        self.hits: list[bool | None] = []
        self.hit_objects: list[str] = []
        self.clipped: list[bool] = []
        self._fixating = False
        self._saccades = 0
        self._window: np.ndarray | None = None
        self._clipping = False

    def on_reset(self, env: Any, agent: Any, obs: Any, info: dict) -> None:
        self._note(agent)

    def _note(self, agent: Any) -> None:
        self._fixating = agent.phase is self._phases.FIXATE
        self._saccades = len(agent.saccades)

    def on_act(self, env: Any, agent: Any, obs: Any, info: dict) -> None:
        mask = info.get("object_mask")
        if mask is not None and self._fixating:  # the step went into the window
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
        self._note(agent)

    def on_step(self, env: Any, agent: Any, obs: Any, info: dict) -> None:
        if agent.phase is self._phases.SACCADE:
            self._clipping |= bool(info.get("target_clipped", False))


class ReadoutRecorder(Recorder):
    """Sums the integer counters of the env's ``info["readout"]`` (a dict; e.g. the events
    a sensor's readout dropped or filtered) over the run; ``metrics()``:
    ``{"readout": totals}``, nothing when no step had a readout."""

    def __init__(self) -> None:
        self.totals: dict[str, int] | None = None

    def on_step(self, env: Any, policy: Any, obs: Any, info: dict) -> None:
        counters = info.get("readout")
        if not isinstance(counters, dict):
            return
        totals = self.totals if self.totals is not None else {}
        for name, value in counters.items():
            if isinstance(value, (int, np.integer)) and not isinstance(value, bool):
                totals[name] = totals.get(name, 0) + int(value)
        self.totals = totals

    def metrics(self) -> dict[str, Any]:
        return {} if self.totals is None else {"readout": dict(self.totals)}


class FolderRecorder(Recorder):
    """The run folder, closed last: ``metrics.json`` (:meth:`figures` and what the
    ``parts`` add, ``error`` and ``signal`` when the run stopped on one; written always,
    or, with ``metrics_on_success`` false, only then), the ``INCOMPLETE`` marker of a run
    stopped by a signal, ``run.json`` (``record`` with the run's ``summary``).
    :meth:`write_files` writes what a subclass adds (a figure, a table).

    ``steps``: the steps taken of ``asked``; ``wall_s``: from its creation (just before
    the loop) to its close (the other recorders closed).
    """

    def __init__(
        self,
        out_dir: Path,
        record: dict[str, Any],
        asked: int,
        parts: Sequence[Recorder] = (),
        metrics_on_success: bool = True,
    ) -> None:
        self.folder = RunFolder(out_dir)
        self.record = record
        self.asked = asked
        self.parts = parts
        self.metrics_on_success = metrics_on_success
        self.steps = 0
        self.written: dict[str, Any] | None = None  # metrics.json as written
        self._t0 = time.perf_counter()
        self.wall_s = 0.0

    def on_step(self, env: Any, policy: Any, obs: Any, info: dict) -> None:
        self.steps += 1

    def figures(self, error: BaseException | None) -> dict[str, Any]:
        """The run's own figures (subclasses); by default ``steps``."""
        return {"steps": self.steps}

    def summary(self, metrics: dict[str, Any]) -> dict[str, Any]:
        """What ``run.json`` says of the run."""
        return {k: metrics[k] for k in ("steps", "events") if k in metrics}

    def write_files(self, metrics: dict[str, Any], error: BaseException | None) -> None:
        """Write the folder's other files (subclasses)."""

    def close(self, error: BaseException | None) -> BaseException | None:
        self.wall_s = time.perf_counter() - self._t0
        try:
            self._write(error)
        except Exception as write_error:
            if error is None:
                return write_error
            path = self.folder.path
            error.add_note(f"writing the run folder {path} also failed: {write_error!r}")
            error.__cause__ = write_error
        return error

    def _write(self, error: BaseException | None) -> None:
        metrics = self.figures(error)
        for part in self.parts:
            metrics |= part.metrics()
        if error is not None:
            metrics["error"] = f"{type(error).__name__}: {error}"
            if isinstance(error, SignalExit):
                metrics["signal"] = error.name
        if isinstance(error, KeyboardInterrupt):  # a signal, Ctrl-C
            self.folder.mark_incomplete(
                f"{str(error) or 'interrupted'} after {self.steps} of {self.asked} steps"
            )
        if error is not None or self.metrics_on_success:
            self.folder.write_metrics(metrics)
        self.written = metrics
        self.write_files(metrics, error)
        run = self.record | {"summary": self.summary(metrics)}
        if error is not None:
            run["error"] = metrics["error"]
        self.folder.write_run(run)


def objects_hit(target: tuple[int, int], ids: np.ndarray, info: dict) -> str:
    """The moving objects (named as in the scene file, ``+``-joined in id order) whose
    masks in ``ids`` (object ids, 0 = none) the detection box around ``target`` touches
    (:func:`~experiments.metrics.detection_hit`); "" for none."""
    names = {o["id"]: str(o["name"]) for o in info.get("objects", ())}
    hit = [int(k) for k in np.unique(ids[ids > 0]) if detection_hit(target, ids == k)]
    return "+".join(names.get(k) or object_body_name(k) for k in hit)
