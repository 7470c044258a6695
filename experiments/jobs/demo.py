"""``wander demo``: the run folder of the DVS demo (:mod:`experiments.jobs.dvs_demo`).

``events.h5`` (with the run record), ``events.png`` (titled event frames) and ``run.json``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import asdict
from pathlib import Path
from typing import Any

from experiments.jobs.dvs_demo import DemoConfig, demo_events, plot_event_panels
from experiments.runs.folder import RunFolder
from experiments.runs.provenance import run_record
from wander_env.events.io import EventRecording, write_events

__all__ = ["run_demo"]


def run_demo(
    out_dir: Path, config: DemoConfig, progress: Callable[[int, int], None] | None = None
) -> dict[str, Any]:
    """Write ``events.h5``, ``events.png`` and ``run.json`` to ``out_dir``; return a summary."""
    folder = RunFolder(out_dir)
    folder.create()
    events, params = demo_events(config, progress)
    n = round(config.seconds * config.frame_rate_hz)
    dt_us = round(1e6 / config.frame_rate_hz)
    size = (config.width, config.height, 2)
    record = run_record("wander demo", asdict(config) | {"dvs": params.to_dict()}, config.seed)
    write_events(folder.path / "events.h5", EventRecording(events, size, record))
    plot_event_panels(
        folder.path / "events.png", events, size, config, step_us=(n * dt_us) // config.panels
    )
    summary = {
        "events": len(events),
        "on_fraction": float(events["p"].mean()) if len(events) else 0.0,
        "events_per_frame": len(events) / n,
        "files": ["events.h5", "events.png", "run.json"],
    }
    folder.write_run(record | {"summary": summary})
    return summary
