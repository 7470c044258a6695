"""The first main job: a synthetic moving pattern through the DVS emulator.

No renderer is involved: a textured background drifts (as if the camera moved)
while a textured disc circles the centre. The events go to an HDF5 file and a
PNG of event frames (red ON, blue OFF); ``run.json`` records config, seed and
git revision.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path

import cv2

from wander_env.dvs import DVSEmulator, DVSParams
from wander_env.event_io import EventRecording, write_events
from wander_env.events import concatenate, time_window, to_frame
from wander_env.runinfo import run_record, write_json
from wander_env.synthetic import disc_over_texture
from wander_env.viz import event_image, tile, upscale


@dataclass(frozen=True)
class DemoConfig:
    seconds: float = 1.0
    frame_rate_hz: float = 1000.0
    width: int = 128
    height: int = 128
    preset: str = "paper"
    seed: int = 0
    panels: int = 8  # event frames in the picture
    panel_ms: float = 20.0  # each shows this much time

    def __post_init__(self) -> None:
        if self.seconds <= 0 or self.frame_rate_hz <= 0:
            raise ValueError(
                f"seconds and frame_rate_hz must be > 0, got {self.seconds}, {self.frame_rate_hz}"
            )
        if self.panels < 1 or self.panel_ms * self.panels > self.seconds * 1000:
            raise ValueError(
                f"{self.panels} panels of {self.panel_ms} ms do not fit in {self.seconds} s"
            )


def run_demo(
    out_dir: Path, config: DemoConfig, progress: Callable[[int, int], None] | None = None
) -> dict:
    """Write ``events.h5``, ``events.png`` and ``run.json`` to ``out_dir``; return a summary."""
    out_dir.mkdir(parents=True, exist_ok=True)
    n = round(config.seconds * config.frame_rate_hz)
    dt_us = round(1e6 / config.frame_rate_hz)
    frames = disc_over_texture(
        config.width, config.height, n + 1,
        background_speed_px=0.05, disc_radius_px=config.width / 8,
        orbit_px=config.width / 4, orbit_frames=n // 2, seed=config.seed,
    )  # fmt: skip
    params = DVSParams.preset(config.preset)
    emu = DVSEmulator(config.width, config.height, params, seed=config.seed)
    emu.reset(frames[0], 0)
    chunks = []
    for i in range(1, n + 1):
        chunks.append(emu.step(frames[i], i * dt_us))
        if progress is not None:
            progress(i, n)
    chunks.append(emu.flush())
    events = concatenate(chunks)
    size = (config.width, config.height, 2)
    record = run_record("wander demo", asdict(config) | {"dvs": params.to_dict()}, config.seed)
    write_events(out_dir / "events.h5", EventRecording(events, size, record))

    panels = []
    step_us = (n * dt_us) // config.panels
    for k in range(config.panels):
        t0 = k * step_us
        window = time_window(events, t0, t0 + round(config.panel_ms * 1000))
        panels.append(upscale(event_image(to_frame(window, size)), 2))
    picture = tile(panels, columns=min(4, config.panels))
    cv2.imwrite(str(out_dir / "events.png"), cv2.cvtColor(picture, cv2.COLOR_RGB2BGR))

    summary = {
        "events": len(events),
        "on_fraction": float(events["p"].mean()) if len(events) else 0.0,
        "events_per_frame": len(events) / n,
        "files": ["events.h5", "events.png", "run.json"],
    }
    write_json(out_dir / "run.json", record | {"summary": summary})
    return summary
