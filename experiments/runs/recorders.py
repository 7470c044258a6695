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
:class:`experiments.paper.scanpath_recorder.ScanpathRecorder`, the rig's
:class:`experiments.jobs.rig.RigCounters`).
"""

from __future__ import annotations

import math
import queue
import threading
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Any

import numpy as np
import pydantic

from experiments.analysis.metrics import detection_hit
from experiments.runs.episode import Recorder
from experiments.runs.folder import RunFolder
from experiments.runs.signals import SignalExit
from experiments.runs.video import VideoSink
from experiments.runs.viewer import StepRow, open_run_log
from wander_env.config import check_annotated
from wander_env.entities import object_body_name
from wander_env.events.stream import EventStreamWriter, H5Appender

__all__ = [
    "DetectionRecorder",
    "EventsRecorder",
    "FolderRecorder",
    "GroundTruthRecorder",
    "ReadoutRecorder",
    "RerunRecorder",
    "VideoRecorder",
    "WriteParams",
    "Writer",
    "objects_hit",
    "open_recorders",
    "video_frames",
]


@dataclass(frozen=True)
class WriteParams:
    """How a run's files are written: on a writer thread (``threaded``, at most
    ``queue_jobs`` writes waiting: the loop waits when it is that far ahead) or in the
    loop; the events and the Rerun rows in batches of ``batch_s`` simulated seconds (0:
    every step) or ``batch_events`` events, whichever comes first. The files are the
    same either way (tested). Rerun rows in batches of 0.5 s rather than 0.1 s took the
    writer 0.42-0.43 s of CPU instead of 0.59-0.60 s on a 10 s run (one column send per
    entity and batch); the events' batches are a chunk of ``events.h5`` either way."""

    threaded: bool = True
    batch_s: Annotated[float, pydantic.Field(ge=0)] = 0.5
    batch_events: Annotated[int, pydantic.Field(ge=1)] = 1 << 16
    queue_jobs: Annotated[int, pydantic.Field(ge=1)] = 32

    def __post_init__(self) -> None:
        check_annotated(self)

    def batch_steps(self, step_s: float) -> int:
        """Steps in a batch of ``batch_s`` for steps of ``step_s`` (at least 1)."""
        return max(1, round(self.batch_s / step_s))

    def writer(self) -> Writer | None:
        """A new :class:`Writer` (``None`` unless ``threaded``)."""
        return Writer(self.queue_jobs) if self.threaded else None


class Writer(Recorder):
    """A run's file writes on one thread, in the order they came (a bounded queue of
    ``jobs``: :meth:`submit` waits while it is full). A write that fails is raised in the
    loop at the next :meth:`submit` (the same error, so the same one line); the writes
    after it still run, so that every file is closed. :meth:`close` (after the recorders
    that write through it) waits for every write, then hands back the loop's error, or a
    write's when the loop had none."""

    def __init__(self, jobs: int = 32) -> None:
        self._queue: queue.Queue[Callable[[], None] | None] = queue.Queue(jobs)
        self._error: BaseException | None = None
        self._raised = False
        self._thread = threading.Thread(target=self._work, name="wander-writer", daemon=True)
        self._thread.start()

    def submit(self, job: Callable[[], None], check: bool = True) -> None:
        """Queue ``job``; with ``check``, first raise a write's error not raised yet."""
        if check and self._error is not None and not self._raised:
            self._raised = True
            raise self._error
        self._queue.put(job)

    def _work(self) -> None:
        while (job := self._queue.get()) is not None:
            try:
                job()
            except BaseException as err:  # handed to the loop (submit, close)
                if self._error is None:
                    self._error = err

    def close(self, error: BaseException | None) -> BaseException | None:
        if self._thread.is_alive():
            self._queue.put(None)
            self._thread.join()
        if error is None and not self._raised:
            self._raised = True
            return self._error
        return error


def open_recorders(
    makers: Sequence[Callable[[], Recorder]], writer: Writer | None = None
) -> list[Recorder]:
    """The recorders ``makers`` make (opening their files), in order. When one fails,
    those already made and ``writer`` are closed with its error, which is raised."""
    made: list[Recorder] = []
    try:
        for make in makers:
            made.append(make())
    except BaseException as exc:
        for r in [*made, *([writer] if writer is not None else [])]:
            r.close(exc)
        raise
    return made


class _FileRecorder(Recorder):
    """A recorder whose writes run through ``writer`` (:class:`Writer`; ``None``: at
    once, in the loop), a batch of ``batch_steps`` rows (or ``batch_events`` events)
    at a time: :meth:`write` a batch, :meth:`finish` closes the file."""

    def __init__(self, writer: Writer | None, batch_steps: int = 1, batch_events: int = 0) -> None:
        self.writer = writer
        self.batch_steps, self.batch_events = batch_steps, batch_events
        self._rows: list[Any] = []
        self._events = 0

    def write(self, rows: list[Any]) -> None:
        raise NotImplementedError

    def finish(self) -> None:
        raise NotImplementedError

    def _add(self, row: Any, events: int = 0) -> None:
        self._rows.append(row)
        self._events += events
        if len(self._rows) >= self.batch_steps or (
            self.batch_events and self._events >= self.batch_events
        ):
            self._flush()

    def _flush(self, check: bool = True) -> None:
        rows, self._rows, self._events = self._rows, [], 0
        if rows:
            self._do(lambda: self.write(rows), check)

    def _do(self, job: Callable[[], None], check: bool = True) -> None:
        if self.writer is None:
            job()
        else:
            self.writer.submit(job, check)

    def close(self, error: BaseException | None) -> BaseException | None:
        """Write the last batch and close the file (through the writer: queued, its
        errors the writer's); the loop's error, or a failed write's or close's."""
        failed: BaseException | None = None
        try:
            self._flush(check=False)
        except Exception as err:  # written in the loop: a failed write
            failed = err
        try:
            self._do(self.finish, check=False)
        except Exception as err:  # closed in the loop: a failed close
            failed = failed or err
        return error or failed


class EventsRecorder(_FileRecorder):
    """``path`` (``events.h5``): every event of the run, written as it goes
    (:class:`~wander_env.events.stream.EventStreamWriter`: memory does not grow with the
    run's length); ``events``: how many. :meth:`close` stores ``record`` with the run's
    ``summary`` (steps, events) in the file's metadata."""

    def __init__(
        self,
        path: Path,
        sensor_size: tuple[int, int, int],
        record: dict,
        writer: Writer | None = None,
        batch_steps: int = 1,
        batch_events: int = 0,
    ) -> None:
        super().__init__(writer, batch_steps, batch_events)
        self.stream = EventStreamWriter(path, sensor_size, record)
        self.record = record
        self.events = 0
        self.steps = 0

    def on_step(self, env: Any, policy: Any, obs: Any, info: dict) -> None:
        step_events = info["events"].events
        self.events += len(step_events)
        self.steps += 1
        self._add(np.array(step_events) if self.writer else step_events, len(step_events))

    def write(self, rows: list[np.ndarray]) -> None:
        self.stream.append(rows[0] if len(rows) == 1 else np.concatenate(rows))

    def finish(self) -> None:
        summary = {"steps": self.steps, "events": self.events}
        self.stream.close(self.record | {"summary": summary})

    def metrics(self) -> dict[str, Any]:
        return {"events": self.events}


class GroundTruthRecorder(_FileRecorder):
    """``path`` (``ground_truth.h5``): per step the time, gaze, PTU positions, object-id
    mask, each moving object's pixel centre, mask size and visibility."""

    def __init__(
        self, path: Path, env: Any, writer: Writer | None = None, batch_steps: int = 1
    ) -> None:
        super().__init__(writer, batch_steps)
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
        self._add(
            {
                "t": info["t"],
                "gaze_deg": np.array(obs["gaze"]),
                "ptu_positions": np.array(info["ptu_positions"]),
                "object_mask": np.array(info["object_mask"]),
                "object_centre_px": centre,
                "object_mask_pixels": pixels,
            }
        )

    def write(self, rows: list[dict[str, Any]]) -> None:
        for row in rows:
            self.truth.append(**row)

    def finish(self) -> None:
        self.truth.close()


def video_frames(steps: int, step_s: float, fps: float) -> int:
    """The frames a video at ``fps`` holds after ``steps`` steps of ``step_s``: frame ``n``
    shows the time ``n / fps``, taken at the end of the step it falls in.

    >>> video_frames(150, 0.01, 30), video_frames(150, 0.01, 100), video_frames(1, 0.01, 30)
    (45, 150, 1)
    """
    return math.ceil(round(steps * step_s * fps, 6))


class VideoRecorder(_FileRecorder):
    """``path``: an MP4 at ``fps`` frames per simulated second (its metadata says
    ``fps``), a frame taken only when one is due (:func:`video_frames`; at more frames a
    second than steps, a step's frame is repeated): ``capture(env, policy, obs, info)``
    copies what it shows in the loop, ``compose(captured)`` makes the RGB image (on the
    writer's thread; ``None``: the capture is the image). ``complete`` after
    :meth:`close`: whether the file is a whole MP4."""

    def __init__(
        self,
        path: Path,
        fps: int,
        step_s: float,
        capture: Callable[[Any, Any, Any, dict], Any],
        compose: Callable[[Any], np.ndarray] | None = None,
        writer: Writer | None = None,
    ) -> None:
        super().__init__(writer)
        self.sink = VideoSink(path, fps=fps)
        self.fps, self.step_s = fps, step_s
        self.capture, self.compose = capture, compose
        self.steps = self.frames = 0
        self.complete: bool | None = None

    def on_step(self, env: Any, policy: Any, obs: Any, info: dict) -> None:
        self.steps += 1
        due = video_frames(self.steps, self.step_s, self.fps) - self.frames
        if due > 0:
            self.frames += due
            self._add((self.capture(env, policy, obs, info), due))

    def write(self, rows: list[tuple[Any, int]]) -> None:
        for captured, repeat in rows:
            image = captured if self.compose is None else self.compose(captured)
            for _ in range(repeat):
                self.sink.append(image)

    def finish(self) -> None:
        error = self.sink.finish(None)
        self.complete = self.sink.complete
        if error is not None:
            raise error

    def close(self, error: BaseException | None) -> BaseException | None:
        if self.writer is not None:
            return super().close(error)
        try:  # in the loop: ffmpeg's close hands back the run's error or its own
            self._flush(False)
        except Exception as err:
            error = error or err
        error = self.sink.finish(error)
        self.complete = self.sink.complete
        return error

    def metrics(self) -> dict[str, Any]:
        return {} if self.complete is None else {"video_complete": self.complete}


class RerunRecorder(_FileRecorder):
    """``out_dir/run.rrd`` (:func:`~experiments.runs.viewer.open_run_log`), with the
    agent's maps, decisions and movements when ``agent`` (the policy is an
    :class:`~agents.attention.AttentionAgent`); ``sightings``: the ground truth the run
    saw."""

    def __init__(
        self,
        out_dir: Path,
        env: Any,
        title: str,
        agent: bool = True,
        writer: Writer | None = None,
        batch_steps: int = 1,
    ) -> None:
        super().__init__(writer, batch_steps)
        self.log = open_run_log(out_dir, env, title)
        self.agent = agent
        self.sightings = self.log.sightings

    def on_step(self, env: Any, policy: Any, obs: Any, info: dict) -> None:
        self._add(self.log.row(obs, info, policy if self.agent else None))

    def write(self, rows: list[StepRow]) -> None:
        self.log.write(rows)

    def finish(self) -> None:
        self.log.close()


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
    a sensor's readout dropped or filtered) over the run, in memory; the counters named in
    ``levels`` (what is held at a step's end, e.g. ``("pending",)``) are kept as their
    last step's value instead. ``peaks``: each counter's most in one step.
    ``metrics()``: ``{"readout": totals}``, nothing when no step had a readout."""

    def __init__(self, levels: Sequence[str] = ()) -> None:
        self.levels = frozenset(levels)
        self.totals: dict[str, int] | None = None
        self.peaks: dict[str, int] = {}

    def on_step(self, env: Any, policy: Any, obs: Any, info: dict) -> None:
        counters = info.get("readout")
        if not isinstance(counters, dict):
            return
        totals = self.totals if self.totals is not None else {}
        peaks = self.peaks
        for name, value in counters.items():
            if isinstance(value, (int, np.integer)) and not isinstance(value, bool):
                v = int(value)
                totals[name] = v if name in self.levels else totals.get(name, 0) + v
                peaks[name] = max(peaks.get(name, v), v)
        self.totals = totals

    def metrics(self) -> dict[str, Any]:
        return {} if self.totals is None else {"readout": dict(self.totals)}


class FolderRecorder(Recorder):
    """The run folder, closed last: ``metrics.json`` (:meth:`figures` and what the
    ``parts`` add, ``error`` and ``signal`` when the run stopped on one; written always,
    or, with ``metrics_on_success`` false, only then), the ``INCOMPLETE`` marker of a run
    stopped by a signal, ``run.json`` (``record`` with the run's ``summary``).
    :meth:`write_files` writes what a subclass adds (a figure, a table).

    ``steps``: the steps taken of ``asked``.
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
    (:func:`~experiments.analysis.metrics.detection_hit`); "" for none."""
    names = {o["id"]: str(o["name"]) for o in info.get("objects", ())}
    hit = [int(k) for k in np.unique(ids[ids > 0]) if detection_hit(target, ids == k)]
    return "+".join(names.get(k) or object_body_name(k) for k in hit)
