"""``wander record``: run the environment under a simple gaze policy and keep everything.

Writes, as the run goes, ``events.h5`` (all events, config and seed in its metadata;
``--format aedat4`` / ``evt3`` convert it to ``events.aedat4`` / ``events.raw`` at the
end, ``evimo2`` to the EVIMO2v2 ``dataset_*`` files of
:func:`wander_env.events.evimo2.write_evimo2_sequence`),
``ground_truth.h5`` (per step: time, gaze, PTU positions, object-id mask, each
moving object's pixel centre, mask size and visibility), ``video.mp4`` (camera |
events, with the fovea marked) and ``run.json``.

The policies are :class:`agents.scripted.GazePolicy`'s: ``still``, ``fixational`` and
``saccades``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Annotated, Any, Literal

import gymnasium as gym
import h5py
import numpy as np
import pydantic

import wander_env  # noqa: F401  (registers the environments)
from agents.scripted import GazePolicy, Policy
from experiments.runs.episode import OneEpisode, Recorder, run_episode
from experiments.runs.folder import RunFolder
from experiments.runs.provenance import run_record
from experiments.runs.recorders import (
    EventsRecorder,
    FolderRecorder,
    GroundTruthRecorder,
    RerunRecorder,
    VideoRecorder,
    WriteParams,
    open_recorders,
)
from experiments.runs.signals import DeferredSignals
from experiments.studies.framework import MAX_SEED
from wander_env.camera import focal_length_px
from wander_env.env_config import WanderConfig
from wander_env.events.evimo2 import write_evimo2_sequence
from wander_env.events.io import read_events, write_events

# --format: the events file (events.h5 / .aedat4 / .raw) beside ground_truth.h5, or the
# EVIMO2v2 layout (events + per-step masks) that `wander benchmark evimo` scores.
FORMATS = {"h5": "events.h5", "aedat4": "events.aedat4", "evt3": "events.raw", "evimo2": None}


@dataclass(frozen=True)
class RecordConfig(OneEpisode):
    """What ``wander record`` records: the env's block (its ``episode_seconds`` is the
    recording's length: 5 s by default), the gaze policy
    (:data:`agents.scripted.POLICIES`) and its seed, the seconds between its saccades, the
    video and the events' format (:data:`FORMATS`)."""

    env: WanderConfig = field(default_factory=lambda: WanderConfig(episode_seconds=5.0))
    policy: Policy = "fixational"
    seed: Annotated[int, pydantic.Field(ge=0, le=MAX_SEED)] = 0
    saccade_interval_s: Annotated[float, pydantic.Field(gt=0)] = 0.5
    video: bool = True
    format: Literal["h5", "aedat4", "evt3", "evimo2"] = "h5"


def record(
    out_dir: Path, config: RecordConfig, progress: Callable[[int, int], None] | None = None
) -> dict[str, Any]:
    """Run and write the recording folder; returns a summary.

    Events and ground truth go to disk as they are made (memory does not grow with
    ``seconds``). A failure or a signal mid-way still closes both files with what was
    recorded, writes ``run.json`` and ``metrics.json`` with the error, then raises it.
    A signal only sets a flag (:class:`~experiments.runs.signals.DeferredSignals`), taken up
    between two steps: ffmpeg finishes ``video.mp4`` (``video_complete`` in the summary);
    one that comes after the loop waits until ``run.json`` is written. A recording
    stopped by a signal is marked with an ``INCOMPLETE`` file saying when it stopped.
    """
    RunFolder(out_dir).create()
    render_mode = "rgb_array" if config.video else None
    env = gym.make("wander/Wander-v0", render_mode=render_mode, **config.env)
    try:
        with DeferredSignals() as signals:  # a signal sets a flag; the loop takes it up
            summary = _record(out_dir, config, env, progress, signals)
            if signals.pending:  # it came after the loop: the folder is finished
                RunFolder(out_dir).record_late_signal(
                    signals.signum,
                    f"the folder was written, after the recording's {summary['steps']} steps",
                )
        return summary  # unless the pending signal, raised on leaving the block
    finally:
        env.close()


def _record(
    out_dir: Path,
    config: RecordConfig,
    env: Any,
    progress: Callable[[int, int], None] | None,
    signals: DeferredSignals,
) -> dict[str, Any]:
    base = env.unwrapped
    dt = base.config.control_period_s
    policy = GazePolicy(config.policy, config.seed + 1, dt, config.saccade_interval_s)
    steps = round(config.seconds / dt)
    h, w = base.height, base.width
    rec = run_record("wander record", asdict(config), config.seed)
    rec["env"] = {"control_period_s": dt, "dvs": base.dvs_params.to_dict()}
    writing = WriteParams()
    writer, batch = writing.writer(), writing.batch_steps(dt)
    makers: list[Callable[[], Recorder]] = [
        lambda: EventsRecorder(
            out_dir / "events.h5", (w, h, 2), rec, writer, batch, writing.batch_events
        ),
        lambda: GroundTruthRecorder(out_dir / "ground_truth.h5", env, writer, batch),
        lambda: RerunRecorder(out_dir, env, "wander record", False, writer, batch),  # run.rrd
    ]
    if config.video:  # a frame a step
        mp4 = out_dir / "video.mp4"
        makers.append(lambda: VideoRecorder(mp4, round(1 / dt), dt, _camera_view, writer=writer))
    opened = open_recorders(makers, writer)
    folder = _RecordFolder(out_dir, rec, steps, config.format, base, dt, opened)
    recorders = [*opened, *([writer] if writer else []), folder]
    run_episode(env, policy, steps, recorders, signals, seed=config.seed, progress=progress)
    return folder.written_summary


def _camera_view(env: Any, policy: Any, obs: Any, info: dict) -> np.ndarray:
    return env.render()


class _RecordFolder(FolderRecorder):
    """The recording's folder: ``run.json`` with the summary (events, steps, whether the
    video is complete, the files); ``metrics.json`` only when it stopped on an error; the
    events converted to ``fmt`` after a whole recording."""

    def __init__(
        self,
        out_dir: Path,
        record: dict[str, Any],
        asked: int,
        fmt: str,
        base: Any,
        dt: float,
        parts: list[Recorder],
    ) -> None:
        super().__init__(out_dir, record, asked, parts, metrics_on_success=False)
        self.fmt, self.base, self.dt = fmt, base, dt
        self.written_summary: dict[str, Any] = {}

    def write_files(self, metrics: dict[str, Any], error: BaseException | None) -> None:
        if error is None and self.fmt != "h5":
            _convert(self.folder.path, self.fmt, self.base, self.dt)

    def summary(self, metrics: dict[str, Any]) -> dict[str, Any]:
        out = {k: metrics[k] for k in ("events", "steps", "video_complete") if k in metrics}
        names = {p.name for p in self.folder.path.iterdir()} | {"run.json"}
        self.written_summary = out | {"files": sorted(names)}
        return self.written_summary


def _convert(out_dir: Path, fmt: str, base: Any, dt: float) -> None:
    """Rewrite the streamed ``events.h5`` as ``fmt`` (the recording is read back whole)."""
    recording = read_events(out_dir / "events.h5")
    if fmt == "evimo2":
        with h5py.File(out_dir / "ground_truth.h5", "r") as f:
            t, masks = f["t"][()], f["object_mask"][()]
        f_px = focal_length_px(base.width, base.scene.camera.hfov_deg)
        write_evimo2_sequence(out_dir, recording, t, masks, f_px, dt)
    else:
        write_events(out_dir / FORMATS[fmt], recording)
    (out_dir / "events.h5").unlink()
