"""Any event file :func:`wander_env.events.io.read_events` reads + a folder of window masks.

The mask folder follows :mod:`experiments.benchmark.datasets.masks` (``NNNNNN_T.png``, ``T`` =
window end in µs, covering ``T − window ≤ t < T``), e.g. ``../shared/realdata/
eed_ball_net/ref_masks_tt_adapt`` with ``events_txyp.npy`` next to it.

Sensor size: given, else what the event file says. A bare ``.npy`` has no sensor size
and :func:`read_events` then infers one from the largest coordinates, which is too small
whenever the border rows/columns saw no event; in that case, when the events fit in the
masks' grid, the masks' size is taken as the sensor size (and noted).
"""

from __future__ import annotations

import os
from pathlib import Path

from experiments.benchmark.datasets.base import SequenceData
from experiments.benchmark.datasets.masks import mask_fit, read_mask_folder
from wander_env.events import SensorSize
from wander_env.events.io import read_events


def load_generic(
    events_path: str | os.PathLike,
    masks_dir: str | os.PathLike,
    sensor_size: SensorSize | None = None,
    window_us: int | None = None,
    name: str | None = None,
    subset: str = "generic",
    dataset: str = "generic",
) -> SequenceData:
    """One sequence from an event file and a mask folder (see the module docstring)."""
    events_path = Path(events_path)
    windows = read_mask_folder(masks_dir, window_us)
    h, w = windows[0].shape
    notes: list[str] = []
    if sensor_size is None:
        rec = read_events(events_path)
        sensor = rec.sensor_size
        if rec.metadata.get("sensor_size_inferred"):
            if sensor[0] <= w and sensor[1] <= h:
                notes.append(
                    f"sensor size taken from the masks ({w}x{h}); the event file gives none "
                    f"(its coordinates reach {sensor[0]}x{sensor[1]})"
                )
                sensor = (w, h, 2)
            else:
                notes.append(f"sensor size {sensor[0]}x{sensor[1]} inferred from the events")
    else:
        rec = read_events(events_path, sensor_size)
        sensor = rec.sensor_size
    fit = mask_fit((h, w), sensor)
    if fit.changed:
        notes.append(f"{fit.describe()} (the benchmark protocol does this, window by window)")
    return SequenceData(
        dataset=dataset,
        subset=subset,
        name=name or events_path.stem,
        sensor_size=sensor,
        events=rec.events,
        windows=windows,
        source=str(events_path),
        notes=notes,
    )
