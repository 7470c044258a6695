"""``wander record``: run the environment under a simple gaze policy and keep everything.

Writes ``events.h5`` (all events, config and seed in its metadata),
``ground_truth.h5`` (per step: time, gaze, PTU positions, object-id mask, each
moving object's pixel centre, mask size and visibility), ``video.mp4`` (camera |
events, with the fovea marked) and ``run.json``.

Policies:
- ``still``: the camera holds its gaze;
- ``fixational``: fixational eye movements only (a new 8-step random walk of
  ±60 PTU positions every 124 ms, :mod:`agents.fixation`);
- ``saccades``: a saccade to a random pixel every ``saccade_interval_s``, with
  fixational movements in between.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import gymnasium as gym
import h5py
import imageio.v2 as imageio
import numpy as np

import wander_env  # noqa: F401  (registers the environments)
from agents.fixation import FixationalMovements, FixationParams
from wander_env.env import WanderConfig
from wander_env.event_io import EventRecording, write_events
from wander_env.events import concatenate
from wander_env.runinfo import run_record, write_json

POLICIES = ("still", "fixational", "saccades")


@dataclass(frozen=True)
class RecordConfig:
    scene: str = "office"
    seconds: float = 5.0
    policy: str = "fixational"
    dvs: str = "ideal"
    seed: int = 0
    saccade_interval_s: float = 0.5
    video: bool = True
    frames: str = WanderConfig.frames  # the env's frame source (keyframes or exact)
    keyframe_ms: float = WanderConfig.keyframe_ms

    def __post_init__(self) -> None:
        if self.policy not in POLICIES:
            raise ValueError(f"policy must be one of {POLICIES}, got {self.policy!r}")
        if not self.seconds > 0:
            raise ValueError(f"seconds must be > 0, got {self.seconds}")


class GazePolicy:
    """The simple policies of :data:`POLICIES`, seeded."""

    def __init__(self, name: str, seed: int, dt_s: float, saccade_interval_s: float) -> None:
        self.name, self.dt_s, self.interval = name, dt_s, saccade_interval_s
        self.rng = np.random.default_rng(seed)
        self.fixation = FixationalMovements(FixationParams(), self.rng)
        self.fixation.start()
        self.t_fix = 0.0
        self.t = 0.0

    def act(self, info: dict[str, Any]) -> np.ndarray:
        action = np.zeros(2, np.float32)
        if self.name == "saccades" and self.t > 0 and self.t % self.interval < self.dt_s / 2:
            action = self.rng.uniform(-0.6, 0.6, 2).astype(np.float32)
            self.fixation.start()
            self.t_fix = self.t
        elif self.name != "still" and not info["moving"]:
            if self.fixation.done:
                self.fixation.start(after_saccade=False)
                self.t_fix = self.t
            if self.fixation.due(self.t - self.t_fix):
                action = np.asarray(self.fixation.next_offset().action, np.float32)
        self.t += self.dt_s
        return np.clip(action, -1.0, 1.0)


def record(
    out_dir: Path, config: RecordConfig, progress: Callable[[int, int], None] | None = None
) -> dict[str, Any]:
    """Run and write the recording folder; returns a summary."""
    out_dir.mkdir(parents=True, exist_ok=True)
    env = gym.make(
        "wander/Wander-v0",
        scene=config.scene,
        dvs=config.dvs,
        render_mode="rgb_array" if config.video else None,
        episode_seconds=config.seconds,
        frames=config.frames,
        keyframe_ms=config.keyframe_ms,
    )
    base = env.unwrapped
    dt = base.config.control_period_s
    policy = GazePolicy(config.policy, config.seed + 1, dt, config.saccade_interval_s)
    obs, info = env.reset(seed=config.seed)
    steps = round(config.seconds / dt)
    n_obj = len(base.scene.moving_objects)
    h, w = base.height, base.width
    truth = {
        "t": np.zeros(steps),
        "gaze_deg": np.zeros((steps, 2), np.float32),
        "ptu_positions": np.zeros((steps, 2), np.int32),
        "object_mask": np.zeros((steps, h, w), np.uint8),
        "object_centre_px": np.full((steps, n_obj, 2), np.nan, np.float32),
        "object_mask_pixels": np.zeros((steps, n_obj), np.int32),
    }
    chunks = []
    writer = (
        imageio.get_writer(out_dir / "video.mp4", fps=round(1 / dt), macro_block_size=1)
        if config.video
        else None
    )
    try:
        for k in range(steps):
            obs, _, _, _, info = env.step(policy.act(info))
            chunks.append(info["events"])
            truth["t"][k] = info["t"]
            truth["gaze_deg"][k] = obs["gaze"]
            truth["ptu_positions"][k] = info["ptu_positions"]
            truth["object_mask"][k] = info["object_mask"]
            for j, o in enumerate(info["objects"]):
                truth["object_centre_px"][k, j] = o["centre_px"]
                truth["object_mask_pixels"][k, j] = o["mask_pixels"]
            if writer is not None:
                writer.append_data(env.render())
            if progress is not None:
                progress(k + 1, steps)
    finally:
        if writer is not None:
            writer.close()
        env.close()
    events = concatenate(chunks)
    rec = run_record("wander record", asdict(config), config.seed)
    rec["env"] = {"control_period_s": dt, "dvs": base.dvs_params.to_dict()}
    write_events(out_dir / "events.h5", EventRecording(events, (w, h, 2), rec))
    with h5py.File(out_dir / "ground_truth.h5", "w") as f:
        for name, arr in truth.items():
            f.create_dataset(name, data=arr, compression="gzip" if arr.ndim > 2 else None)
        f.attrs["object_names"] = [o.name for o in base.scene.moving_objects]
        f.attrs["mask_ids"] = "0 = background, k = moving object k (1-based)"
    summary = {
        "events": len(events),
        "steps": steps,
        "files": sorted({p.name for p in out_dir.iterdir()} | {"run.json"}),
    }
    write_json(out_dir / "run.json", rec | {"summary": summary})
    return summary
