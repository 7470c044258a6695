"""``wander record``: run the environment under a simple gaze policy and keep everything.

Writes, as the run goes, ``events.h5`` (all events, config and seed in its metadata;
``--format aedat4`` / ``evt3`` convert it to ``events.aedat4`` / ``events.raw`` at the
end, ``evimo2`` to the EVIMO2v2 ``dataset_*`` files of
:func:`wander_env.events.formats.write_evimo2_sequence`),
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
from experiments.framework import MAX_SEED
from experiments.runs.folder import RunFolder
from experiments.runs.provenance import run_record
from experiments.runs.signals import DeferredSignals, SignalExit
from experiments.runs.viewer import open_run_log
from wander_env.camera import focal_length_px
from wander_env.config import check_annotated
from wander_env.env_config import WanderConfig
from wander_env.events.formats import write_evimo2_sequence
from wander_env.events.io import read_events, write_events
from wander_env.events.stream import EventStreamWriter, H5Appender, VideoSink

# --format: the events file (events.h5 / .aedat4 / .raw) beside ground_truth.h5, or the
# EVIMO2v2 layout (events + per-step masks) that `wander benchmark evimo` scores.
FORMATS = {"h5": "events.h5", "aedat4": "events.aedat4", "evt3": "events.raw", "evimo2": None}


@dataclass(frozen=True)
class RecordConfig:
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

    def __post_init__(self) -> None:
        check_annotated(self)

    @property
    def seconds(self) -> float:
        """The recording's length: one episode."""
        return self.env.episode_seconds


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
    obs, info = env.reset(seed=config.seed)
    steps = round(config.seconds / dt)
    n_obj = len(base.scene.moving_objects)
    h, w = base.height, base.width
    rec = run_record("wander record", asdict(config), config.seed)
    rec["env"] = {"control_period_s": dt, "dvs": base.dvs_params.to_dict()}
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
    video_path = out_dir / "video.mp4"
    done, error = 0, None
    with (
        EventStreamWriter(out_dir / "events.h5", (w, h, 2), rec) as events,
        H5Appender(out_dir / "ground_truth.h5", fields, attrs, chunk_rows=100) as truth,
    ):
        writer = VideoSink(video_path, fps=round(1 / dt)) if config.video else None
        rrlog = open_run_log(out_dir, env, "wander record")  # run.rrd
        try:
            for k in range(steps):
                signals.check()  # a signal that came during the last step stops here
                obs, _, _, _, info = env.step(policy.act(info))
                rrlog.step(obs, info)
                events.append(info["events"].events)
                centre = np.full((n_obj, 2), np.nan, np.float32)
                pixels = np.zeros(n_obj, np.int32)
                for j, o in enumerate(info["objects"]):
                    centre[j], pixels[j] = o["centre_px"], o["mask_pixels"]
                truth.append(
                    t=info["t"],
                    gaze_deg=obs["gaze"],
                    ptu_positions=info["ptu_positions"],
                    object_mask=info["object_mask"],
                    object_centre_px=centre,
                    object_mask_pixels=pixels,
                )
                if writer is not None:
                    writer.append(env.render())
                done = k + 1
                if progress is not None:
                    progress(k + 1, steps)
        except BaseException as exc:
            error = exc
        finally:
            rrlog.close()
            if writer is not None:
                error = writer.finish(error)
        n_events = events.events_written
        summary: dict[str, Any] = {"events": n_events, "steps": done}
        if writer is not None and writer.complete is not None:
            summary["video_complete"] = writer.complete
        events.close({**rec, "summary": summary})
        truth.close()
    if error is None and config.format != "h5":
        _convert(out_dir, config.format, base, dt)
    folder = RunFolder(out_dir)
    if isinstance(error, KeyboardInterrupt):  # a signal, Ctrl-C
        folder.mark_incomplete(f"{str(error) or 'interrupted'} after {done} of {steps} steps")
    summary["files"] = sorted({p.name for p in out_dir.iterdir()} | {"run.json"})
    if error is not None:
        message = f"{type(error).__name__}: {error}"
        stopped_by = {"signal": error.name} if isinstance(error, SignalExit) else {}
        folder.write_metrics({**summary, "error": message, **stopped_by})
        folder.write_run(rec | {"summary": summary, "error": message})
        raise error
    folder.write_run(rec | {"summary": summary})
    return summary


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
