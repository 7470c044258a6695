"""Scanpath statistics (pure functions over fixation and saccade tables).

Fixations are rows ``(pan_deg, tilt_deg, start_s, duration_s)`` — the standard
fixation-table columns that scanpath-comparison tools (MultiMatch, ScanMatch) read, in
degrees of the pan-tilt unit.

Example:
    >>> import numpy as np
    >>> fx = np.array([[0, 0, 0.0, 0.1], [10, 0, 0.5, 0.1], [0.5, 0, 1.0, 0.1]])
    >>> saccade_amplitudes(fx).round(2).tolist(), revisits(fx, radius_deg=2.0)
    ([10.0, 9.5], 1)
"""

from __future__ import annotations

import math

import numpy as np

FIXATION_COLUMNS = ("pan_deg", "tilt_deg", "start_s", "duration_s")


def _table(fixations: np.ndarray) -> np.ndarray:
    f = np.asarray(fixations, dtype=np.float64)
    if f.ndim != 2 or f.shape[1] != 4:
        raise ValueError(f"fixations must be (n, 4) {FIXATION_COLUMNS}, got shape {f.shape}")
    return f


def saccade_amplitudes(fixations: np.ndarray) -> np.ndarray:
    """Angular distance (degrees) between consecutive fixations (great circle of the
    pan-tilt directions)."""
    f = _table(fixations)
    if len(f) < 2:
        return np.zeros(0)
    return angular_distance(f[:-1, :2], f[1:, :2])


def angular_distance(a_deg: np.ndarray, b_deg: np.ndarray) -> np.ndarray:
    """Great-circle angle (degrees) between pan-tilt directions ``(n, 2)``."""
    a, b = np.radians(np.atleast_2d(a_deg)), np.radians(np.atleast_2d(b_deg))

    def unit(v: np.ndarray) -> np.ndarray:
        pan, tilt = v[:, 0], v[:, 1]
        return np.stack([np.cos(tilt) * np.cos(pan), np.cos(tilt) * np.sin(pan), np.sin(tilt)], 1)

    dot = np.clip(np.sum(unit(a) * unit(b), axis=1), -1.0, 1.0)
    return np.degrees(np.arccos(dot))


def revisits(fixations: np.ndarray, radius_deg: float = 5.0) -> int:
    """Fixations landing within ``radius_deg`` of an earlier, non-consecutive fixation."""
    f = _table(fixations)
    n = 0
    for k in range(2, len(f)):
        if np.any(
            angular_distance(f[: k - 1, :2], np.repeat(f[k : k + 1, :2], k - 1, 0)) <= radius_deg
        ):
            n += 1
    return n


def coverage(fixations: np.ndarray, radius_deg: float = 5.0, cell_deg: float = 1.0) -> float:
    """Solid-angle-free coverage: the area (deg²) of the pan-tilt plane within
    ``radius_deg`` of some fixation, on a ``cell_deg`` grid."""
    f = _table(fixations)
    if len(f) == 0:
        return 0.0
    lo = f[:, :2].min(0) - radius_deg
    hi = f[:, :2].max(0) + radius_deg
    pan = np.arange(lo[0], hi[0] + cell_deg, cell_deg)
    tilt = np.arange(lo[1], hi[1] + cell_deg, cell_deg)
    pp, tt = np.meshgrid(pan, tilt)
    near = np.zeros(pp.shape, bool)
    for p, t in f[:, :2]:
        near |= np.hypot(pp - p, tt - t) <= radius_deg
    return float(near.sum() * cell_deg**2)


def summary(fixations: np.ndarray, hits: list[bool] | None = None) -> dict[str, float]:
    """Count, mean ± std duration, mean ± std saccade amplitude, revisits, coverage and
    (given per-fixation object hits) the object hit rate."""
    f = _table(fixations)
    amp = saccade_amplitudes(f)
    out = {
        "fixations": float(len(f)),
        "fixation_duration_mean_s": float(f[:, 3].mean()) if len(f) else math.nan,
        "fixation_duration_std_s": float(f[:, 3].std()) if len(f) else math.nan,
        "saccade_amplitude_mean_deg": float(amp.mean()) if len(amp) else math.nan,
        "saccade_amplitude_std_deg": float(amp.std()) if len(amp) else math.nan,
        "revisits": float(revisits(f)),
        "coverage_deg2": coverage(f),
    }
    if hits is not None:
        out["object_hit_rate"] = float(np.mean(hits)) if hits else math.nan
    return out
