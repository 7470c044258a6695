"""The fixation table: one layout, one sign convention, one set of units for every file
that lists fixations.

Three places hold fixations: ``wander run``'s ``fixations.csv`` (one row per decision
window), the scanpath experiment's ``fixations/<scene>_<condition>_seed<N>.csv`` (the
windows between two saccades merged into one fixation) and that experiment's
``results.csv`` column ``scanpath_json`` (the same merged fixations as JSON rows
``[pan_deg, tilt_deg, t_start_s, duration_s]``). All of them use:

============== ===== ==================================================================
column         unit  meaning
============== ===== ==================================================================
``pan_deg``    °     the gaze's pan during the fixation, the PTU's sign: **+ = left**
``tilt_deg``   °     the gaze's tilt, the PTU's sign: **+ = up**
``t_start_s``  s     start, simulated time since the env's reset; never negative
``duration_s`` s     how long the fixation lasted
============== ===== ==================================================================

Angles are the pan-tilt unit's own (the figures' axes: pan grows to the left, tilt
upwards); nothing is mirrored into screen axes. Times are rounded to the microsecond (the
event clock's unit), angles to the micro-degree. The agent's first window counts the
observation of the env's reset, one control step before t = 0, in which no event can
arrive: the table starts it at 0 (its end kept), so no fixation starts before the run.

Each file adds columns of its own after these four:

- ``wander run``'s ``fixations.csv``: ``target_x_px``, ``target_y_px`` (the salient
  point ``P`` on the sensor: x right, y down, origin top-left), ``target_pan_deg``,
  ``target_tilt_deg`` (``P``'s direction, same signs as the gaze), ``hit`` (1/0: the 8×8
  box around ``P`` touches a moving object's mask; empty without ground truth),
  ``target_object`` (that moving object's name in the scene file), ``events`` and
  ``oms_events`` (events in the window, all and kept by sOMS); empty where the window
  had no ``P``;
- the scanpath experiment's ``fixations/*.csv``: ``aoi``, the scene object under the
  fovea during the fixation, named as in the scene file (static and moving objects
  alike; ``-`` for none: walls, floor, furniture), as in the row's ``aois_json``.

Example:
    >>> fixation_times(-0.01, 0.13)
    (0.0, 0.12)
    >>> normalise(np.array([[1.5, -2.0, 0.3, 0.9099999999999999]])).tolist()
    [[1.5, -2.0, 0.3, 0.91]]
"""

from __future__ import annotations

import csv
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

__all__ = [
    "FIXATION_COLUMNS",
    "fixation_times",
    "normalise",
    "write_fixations",
]

FIXATION_COLUMNS = ("pan_deg", "tilt_deg", "t_start_s", "duration_s")
TIME_DECIMALS = 6  # seconds to the microsecond
ANGLE_DECIMALS = 6  # degrees to the micro-degree


def fixation_times(start_s: float, duration_s: float) -> tuple[float, float]:
    """``(t_start_s, duration_s)`` as written: the start clamped at 0 (the end kept), both
    rounded to the microsecond."""
    start = round(max(float(start_s), 0.0), TIME_DECIMALS)
    end = round(float(start_s) + float(duration_s), TIME_DECIMALS)
    return start + 0.0, round(end - start, TIME_DECIMALS) + 0.0


def normalise(fixations: np.ndarray) -> np.ndarray:
    """Fixations ``(n, 4)`` ``(pan, tilt, start, duration)`` as every file writes them:
    angles to the micro-degree, times by :func:`fixation_times`."""
    f = np.asarray(fixations, dtype=np.float64).reshape(-1, 4)
    out = np.empty_like(f)
    out[:, :2] = np.round(f[:, :2], ANGLE_DECIMALS) + 0.0
    for k, (start, duration) in enumerate(f[:, 2:]):
        out[k, 2:] = fixation_times(start, duration)
    return out


def write_fixations(
    path: Path, fixations: np.ndarray, extra: Mapping[str, Sequence[object]] | None = None
) -> Path:
    """Write ``fixations`` (``(n, 4)``, :func:`normalise`\\ d here) as CSV: the columns
    :data:`FIXATION_COLUMNS`, then each ``extra`` column (one value per fixation; ``None``
    is written empty)."""
    table = normalise(fixations)
    extra = dict(extra or {})
    for name, values in extra.items():
        if len(values) != len(table):
            raise ValueError(f"column {name!r} has {len(values)} values for {len(table)} rows")
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("w", newline="") as fh:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow([*FIXATION_COLUMNS, *extra])
        for k, row in enumerate(table):
            cells = [repr(float(v)) for v in row]
            cells += ["" if v[k] is None else str(v[k]) for v in extra.values()]
            w.writerow(cells)
    return path
