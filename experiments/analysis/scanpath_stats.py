"""Scanpath statistics (pure functions over fixation and saccade tables), and the
fixation table's file layout: one layout, one sign convention, one set of units for every
file that lists fixations.

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
  box around ``P`` touches a moving object's mask, the union over the window; empty
  where nothing was scored: no ``P``, no moving object in view, no ground truth),
  ``target_object`` (the moving objects that box touches, named as in the scene file,
  ``+``-joined should there be several; empty for none), ``events`` and
  ``oms_events`` (events in the window, all and kept by sOMS); the ``target_*`` cells
  are empty where the window had no ``P``;
- the scanpath experiment's ``fixations/*.csv``: ``aoi``, the scene object under the
  fovea during the fixation, named as in the scene file (static and moving objects
  alike; ``-`` for none: walls, floor, furniture), as in the row's ``aois_json``.

The statistics (:func:`scanpath_summary`, ``wander run``'s ``metrics.json`` ``scanpath``
and the experiment's rows alike) are those of the merged fixations: the windows between
two saccades are one fixation.

Examples:
    >>> import numpy as np
    >>> fx = np.array([[0, 0, 0.0, 0.1], [10, 0, 0.5, 0.1], [0.5, 0, 1.0, 0.1]])
    >>> angular_distance(fx[:-1, :2], fx[1:, :2]).round(2).tolist(), revisits(fx, radius_deg=2.0)
    ([10.0, 9.5], 1)
    >>> fixation_times(-0.01, 0.13)
    (0.0, 0.12)
    >>> normalise_fixations(np.array([[1.5, -2.0, 0.3, 0.9099999999999999]])).tolist()
    [[1.5, -2.0, 0.3, 0.91]]
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping, Sequence

import numpy as np

from experiments.analysis.stats import mean_std

FIXATION_COLUMNS = ("pan_deg", "tilt_deg", "t_start_s", "duration_s")
TIME_DECIMALS = 6  # seconds to the microsecond
ANGLE_DECIMALS = 6  # degrees to the micro-degree


def fixation_times(start_s: float, duration_s: float) -> tuple[float, float]:
    """``(t_start_s, duration_s)`` as written: the start clamped at 0 (the end kept), both
    rounded to the microsecond."""
    start = round(max(float(start_s), 0.0), TIME_DECIMALS)
    end = round(float(start_s) + float(duration_s), TIME_DECIMALS)
    return start + 0.0, round(end - start, TIME_DECIMALS) + 0.0


def normalise_fixations(fixations: np.ndarray) -> np.ndarray:
    """Fixations ``(n, 4)`` ``(pan, tilt, start, duration)`` as every file writes them:
    angles to the micro-degree, times by :func:`fixation_times`."""
    f = np.asarray(fixations, dtype=np.float64).reshape(-1, 4)
    out = np.empty_like(f)
    out[:, :2] = np.round(f[:, :2], ANGLE_DECIMALS) + 0.0
    for k, (start, duration) in enumerate(f[:, 2:]):
        out[k, 2:] = fixation_times(start, duration)
    return out


def fixation_rows(
    fixations: np.ndarray, extra: Mapping[str, Sequence[object]] | None = None
) -> tuple[list[str], list[dict[str, object]]]:
    """The columns and rows of a fixation file, for
    :func:`experiments.runs.tables.write_csv`: ``fixations`` (``(n, 4)``, put through
    :func:`normalise_fixations`) under :data:`FIXATION_COLUMNS`, then each ``extra``
    column (one value per fixation; a ``None`` is left out of its row: an empty cell).

    >>> columns, rows = fixation_rows(np.array([[1, 2, 0.5, 0.1]]), {"aoi": ["-"], "hit": [None]})
    >>> columns[4:], list(rows[0].values())
    (['aoi', 'hit'], [1.0, 2.0, 0.5, 0.1, '-'])
    """
    table = normalise_fixations(fixations)
    extra = dict(extra or {})
    for name, values in extra.items():
        if len(values) != len(table):
            raise ValueError(f"column {name!r} has {len(values)} values for {len(table)} rows")
    rows = [
        {
            **dict(zip(FIXATION_COLUMNS, map(float, row), strict=True)),
            **{name: values[k] for name, values in extra.items() if values[k] is not None},
        }
        for k, row in enumerate(table)
    ]
    return [*FIXATION_COLUMNS, *extra], rows


def _table(fixations: np.ndarray) -> np.ndarray:
    f = np.asarray(fixations, dtype=np.float64)
    if f.ndim != 2 or f.shape[1] != 4:
        raise ValueError(f"fixations must be (n, 4) {FIXATION_COLUMNS}, got shape {f.shape}")
    return f


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


def merge_windows(windows: np.ndarray, ends_fixation: Sequence[bool]) -> np.ndarray:
    """Fixation windows ``(n, 4)`` (pan, tilt, start, duration) -> fixations: each run of
    consecutive windows up to one that ends it (its ``P`` started a saccade) becomes one
    fixation, at the first window's gaze, lasting from its start to the last one's end.

    >>> w = np.array([[0, 0, 0.0, 0.1], [0, 0, 0.1, 0.1], [5, 1, 0.5, 0.1]])
    >>> merge_windows(w, [False, True, True]).tolist()
    [[0.0, 0.0, 0.0, 0.2], [5.0, 1.0, 0.5, 0.1]]
    """
    w = np.asarray(windows, dtype=np.float64).reshape(-1, 4)
    if len(ends_fixation) != len(w):
        raise ValueError(f"{len(w)} windows but {len(ends_fixation)} flags")
    out: list[list[float]] = []
    cur: list[float] | None = None
    for row, end in zip(w, ends_fixation, strict=True):
        if cur is None:
            cur = [row[0], row[1], row[2], row[3]]
        else:
            cur[3] = row[2] + row[3] - cur[2]
        if end:
            out.append(cur)
            cur = None
    if cur is not None:
        out.append(cur)
    return np.array(out, dtype=np.float64).reshape(-1, 4)


def merged_fixations(windows: np.ndarray, ends_fixation: Sequence[bool]) -> np.ndarray:
    """The fixation table of decision windows: :func:`merge_windows`, then
    :func:`normalise_fixations` (what the scanpath experiment's files hold)."""
    return normalise_fixations(merge_windows(windows, ends_fixation))


def _us(seconds: float) -> float:
    """A time in seconds rounded to the microsecond (NaN kept)."""
    return round(seconds, TIME_DECIMALS) + 0.0 if math.isfinite(seconds) else seconds


def scanpath_summary(
    windows: np.ndarray,
    ends_fixation: Sequence[bool],
    saccades_deg: np.ndarray,
    radius_deg: float = 5.0,
) -> dict[str, float]:
    """The scanpath statistics of ``wander run``'s ``metrics.json`` and of the scanpath
    experiment, from the agent's decision windows ``(n, 4)`` (pan, tilt, start, duration),
    whether each ended its fixation (its ``P`` started a saccade) and its saccades
    ``(m, 4)`` (pan, tilt where each started — the PTU's target — then the gaze it
    reached): the windows merged into fixations (:func:`merged_fixations`: a fixation
    that goes on over several windows without a saccade is one fixation), their count and
    mean ± std duration (to the microsecond), the mean ± std saccade amplitude (great
    circle, :func:`angular_distance`), and the fixations' :func:`revisits` and
    :func:`coverage` within ``radius_deg``.

    >>> w = [[0, 0, 0.0, 0.1], [0, 0, 0.1, 0.1], [5, 1, 0.5, 0.1]]
    >>> s = scanpath_summary(w, [False, True, True], np.array([[0, 0, 5, 1]]))
    >>> s["fixations"], s["fixation_duration_mean_s"], round(s["saccade_amplitude_mean_deg"], 2)
    (2, 0.15, 5.1)
    """
    table = merged_fixations(windows, ends_fixation)
    saccades = np.asarray(saccades_deg, dtype=np.float64)
    if saccades.size == 0:
        saccades = saccades.reshape(0, 4)
    if saccades.ndim != 2 or saccades.shape[1] != 4:
        raise ValueError(f"saccades_deg must be (m, 4) (from, to pan-tilt), got {saccades.shape}")
    duration = mean_std(table[:, 3])
    amplitude = mean_std(angular_distance(saccades[:, :2], saccades[:, 2:]))
    return {
        "fixations": len(table),
        "fixation_duration_mean_s": _us(duration[0]),
        "fixation_duration_std_s": _us(duration[1]),
        "saccade_amplitude_mean_deg": amplitude[0],
        "saccade_amplitude_std_deg": amplitude[1],
        "revisits": revisits(table, radius_deg),
        "coverage_deg2": coverage(table, radius_deg),
    }


# ----------------------------------------------------------------------------------------
# Areas of interest (the scene's objects), string edit distance, entropy


BACKGROUND = "-"  # the AOI of a fixation on no object (walls, floor, furniture)


def fixation_aois(window_aois: list[str], ends_fixation: list[bool]) -> list[str]:
    """The AOI of each merged fixation (windows grouped as :func:`merge_windows` does):
    the most frequent AOI of its windows, the earliest on a tie; ``""`` (no object) becomes
    :data:`BACKGROUND`.

    >>> fixation_aois(["cup", "", "", "box"], [False, False, True, True])
    ['-', 'box']
    """
    if len(window_aois) != len(ends_fixation):
        raise ValueError(f"{len(window_aois)} AOI labels but {len(ends_fixation)} flags")
    out: list[str] = []
    cur: list[str] = []
    for label, end in zip(window_aois, ends_fixation, strict=True):
        cur.append(label or BACKGROUND)
        if end:
            out.append(max(dict.fromkeys(cur), key=cur.count))
            cur = []
    if cur:
        out.append(max(dict.fromkeys(cur), key=cur.count))
    return out


def levenshtein(a: list[str], b: list[str]) -> int:
    """String-edit (Levenshtein) distance between two AOI sequences, each AOI one symbol
    (insertions, deletions, substitutions cost 1; :mod:`rapidfuzz`).

    >>> levenshtein(["cup", "box", "-"], ["cup", "-"])
    1
    """
    from rapidfuzz.distance import Levenshtein

    return int(Levenshtein.distance(list(a), list(b)))


def levenshtein_similarity(a: list[str], b: list[str]) -> float:
    """``1 − distance / max(len)``: 1 for equal sequences, 0 for nothing in common (NaN
    when both are empty).

    >>> levenshtein_similarity(["cup", "box", "-"], ["cup", "-"])
    0.6666666666666667
    """
    n = max(len(a), len(b))
    return 1.0 - levenshtein(a, b) / n if n else math.nan


def stationary_entropy(aois: list[str], normalise: bool = True) -> float:
    """Shannon entropy (bits) of the distribution of fixations over AOIs (Krejtz et al.
    2015, "stationary entropy"); ``normalise`` divides by log2 of the number of AOIs
    visited (1 = evenly spread, 0 = one AOI). NaN without fixations; 0 with one AOI.

    >>> stationary_entropy(["a", "b", "a", "b"]), stationary_entropy(["a", "a"])
    (1.0, 0.0)
    """
    if not aois:
        return math.nan
    _, counts = np.unique(np.asarray(aois, dtype=object).astype(str), return_counts=True)
    if len(counts) < 2:
        return 0.0
    p = counts / counts.sum()
    h = float(-(p * np.log2(p)).sum())
    return h / math.log2(len(counts)) if normalise else h


def transition_entropy(aois: list[str], normalise: bool = True) -> float:
    """Entropy (bits) of the AOI transitions, ``H_t = −Σ_i π_i Σ_j p_ij log2 p_ij`` with
    ``π`` the AOI distribution of the transitions' sources and ``p_ij`` the first-order
    transition probabilities (Krejtz et al. 2015); normalised by log2 of the AOIs
    visited. 0 for a fully predictable scanpath; NaN with fewer than two fixations.

    >>> transition_entropy(["a", "b", "a", "b"]), transition_entropy(["a", "b", "a", "a"])
    (0.0, 0.6666666666666666)
    """
    if len(aois) < 2:
        return math.nan
    names = sorted(set(aois))
    if len(names) < 2:
        return 0.0
    idx = {n: i for i, n in enumerate(names)}
    m = np.zeros((len(names), len(names)))
    for s, t in itertools.pairwise(aois):
        m[idx[s], idx[t]] += 1
    rows = m.sum(1)
    pi = rows / rows.sum()
    h = 0.0
    for i in np.nonzero(rows)[0]:
        p = m[i][m[i] > 0] / rows[i]
        h -= float(pi[i]) * float((p * np.log2(p)).sum())
    return float(h / math.log2(len(names))) if normalise else float(h)


# ----------------------------------------------------------------------------------------
# MultiMatch (Jarodzka et al. 2010; Dewhurst et al. 2012), by the multimatch-gaze package

MULTIMATCH_DIMENSIONS = ("vector", "direction", "length", "position", "duration")


def multimatch(
    a: np.ndarray,
    b: np.ndarray,
    screen_deg: tuple[float, float],
    grouping: bool = False,
    t_dir_deg: float = 0.0,
    t_dur_s: float = 0.0,
    t_amp_deg: float = 0.0,
) -> dict[str, float]:
    """MultiMatch similarities (1 = identical) of two fixation tables ``(pan, tilt,
    start, duration)`` on the five dimensions of :data:`MULTIMATCH_DIMENSIONS`, by
    :func:`multimatch_gaze.docomparison` on screen coordinates ``x = −pan``,
    ``y = −tilt`` (degrees, :func:`experiments.paper.scanpath.export_table`); ``screen_deg``
    (width, height) normalises lengths and positions (its diagonal), as the screen does
    in eye tracking. ``grouping`` simplifies both scanpaths first (direction, duration
    and amplitude thresholds). NaN on every dimension when a scanpath has fewer than 3
    fixations (MultiMatch needs two saccades).

    >>> fx = np.array([[0, 0, 0, 0.2], [-10, 0, 0.3, 0.2], [-10, -10, 0.6, 0.4]])
    >>> {k: round(v, 3) for k, v in multimatch(fx, fx + [5, 0, 0, 0], (100, 100)).items()}
    {'vector': 1.0, 'direction': 1.0, 'length': 1.0, 'position': 0.965, 'duration': 1.0}
    """
    import multimatch_gaze

    def fixvec(f: np.ndarray) -> np.ndarray:
        f = _table(f)
        out = np.zeros(len(f), dtype=[("start_x", "f8"), ("start_y", "f8"), ("duration", "f8")])
        out["start_x"], out["start_y"], out["duration"] = -f[:, 0], -f[:, 1], f[:, 3]
        return out

    fa, fb = fixvec(a), fixvec(b)
    if len(fa) < 3 or len(fb) < 3:
        return dict.fromkeys(MULTIMATCH_DIMENSIONS, math.nan)
    res = multimatch_gaze.docomparison(
        fa,
        fb,
        screensize=[float(screen_deg[0]), float(screen_deg[1])],
        grouping=grouping,
        TDir=t_dir_deg,
        TDur=t_dur_s,
        TAmp=t_amp_deg,
    )
    return {k: float(v) for k, v in zip(MULTIMATCH_DIMENSIONS, res, strict=True)}
