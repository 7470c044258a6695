"""Fixational eye movements: a bounded random walk of the PTU after each saccade.

The paper (``../shared/seed/paper.tex``, §"Real-world demonstrator") models fixational
eye movements as a random walk: after a saccade, for each of ``N = 8`` movements both
pan and tilt are updated by a perturbation ``r_i`` drawn uniformly from
``[−60, 60]`` PTU positions (the paper's text says "degrees"; the public code and the
PTU protocol work in positions, 60 × 92.5714″ ≈ 1.54°)::

    for i in 1..N:  pan ← pan + r_i,  tilt ← tilt + r_i

Two traps of the public code are avoided here: a *new* sequence is drawn at the start
of every fixation (not once per run), and the offsets are *relative* steps whose sum
is the walk (not absolute commands). Pan and tilt draw independent perturbations by
default; ``FixationParams.shared_axes=True`` reproduces the paper's formula literally
(the same ``r_i`` on both axes, i.e. a walk along the diagonal only).

Units and signs: PTU positions and degrees use the PTU's convention (positive pan
turns LEFT, positive tilt is UP, see :mod:`wander_env.ptu`); env action units are the
relative gaze offset scaled to the half field of view (positive x looks RIGHT,
positive y looks DOWN), converted with the pinhole model (pixel offset ``d`` ↔ angle
``atan(d / f_px)``) — see :func:`wander_env.actions.gaze_degrees_to_action`, the exact
inverse of the env's action → angle mapping :func:`wander_env.actions.action_to_gaze_degrees`.

Examples:
    >>> import numpy as np
    >>> fix = FixationalMovements(FixationParams(), np.random.default_rng(0))
    >>> fix.start()
    >>> steps = [fix.next_offset() for _ in range(fix.params.n_steps)]
    >>> fix.done, len(steps), all(abs(p) <= 60 for s in steps for p in s.delta_pos)
    (True, 8, True)
    >>> bool(np.array_equal(fix.cumulative_pos, np.sum([s.delta_pos for s in steps], axis=0)))
    True
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from wander_env.actions import gaze_degrees_to_action
from wander_env.camera import SPECK_HFOV_DEG, check_hfov_deg
from wander_env.config import check_fields
from wander_env.ptu.units import FLIR_RESOLUTION_ARCSEC, positions_to_degrees
from wander_env.trajectories import fold

__all__ = [
    "FIXATION_WINDOW_S",
    "FixationParams",
    "FixationStep",
    "FixationalMovements",
    "check_resolution_arcsec",
    "draw_perturbations",
    "positions_to_action",
]


#: St_w = t_w: the paper's fixation window, seconds (its demonstrator's latency): one
#: fixational walk, and the attention agent's default window.
FIXATION_WINDOW_S = 0.124


# ----------------------------------------------------------------------------------------
# Pure maths


def positions_to_action(
    delta_pos: np.ndarray | tuple[float, float],
    resolution_arcsec: tuple[float, float] = (FLIR_RESOLUTION_ARCSEC, FLIR_RESOLUTION_ARCSEC),
    width_px: int = 128,
    height_px: int = 128,
    hfov_deg: float = SPECK_HFOV_DEG,
) -> np.ndarray:
    """Relative PTU positions ``(pan, tilt)`` -> env action units (positions -> ° -> action),
    each axis at its own ``resolution_arcsec`` (pan, tilt).

    Examples:
        >>> a = positions_to_action((-60, 60))  # 60 positions (≈ 1.54°) right and up
        >>> [round(float(v), 5) for v in a]
        [0.01789, -0.01789]
    """
    p, t = (float(v) for v in np.asarray(delta_pos, dtype=np.float64).reshape(2))
    return gaze_degrees_to_action(
        positions_to_degrees(p, resolution_arcsec[0]),
        positions_to_degrees(t, resolution_arcsec[1]),
        width_px,
        height_px,
        hfov_deg,
    )


def check_resolution_arcsec(
    resolution_arcsec: tuple[float, float], name: str = "resolution_arcsec"
) -> tuple[float, float]:
    """``resolution_arcsec`` when it is a PTU's (pan, tilt) arc-seconds per position: a
    tuple of two finite numbers > 0 (not bools); ValueError naming ``name`` and the value
    otherwise.

    >>> check_resolution_arcsec((92.5714, 46.2857))
    (92.5714, 46.2857)
    >>> check_resolution_arcsec(92.5714)
    Traceback (most recent call last):
    ...
    ValueError: resolution_arcsec: must be (pan, tilt) arc-seconds > 0, got 92.5714
    """
    pair = isinstance(resolution_arcsec, tuple) and len(resolution_arcsec) == 2
    if not pair or not all(
        isinstance(r, (int, float)) and not isinstance(r, bool) and 0 < r < math.inf
        for r in resolution_arcsec
    ):
        raise ValueError(f"{name}: must be (pan, tilt) arc-seconds > 0, got {resolution_arcsec!r}")
    return resolution_arcsec


def draw_perturbations(
    rng: np.random.Generator,
    n_steps: int,
    max_step_pos: int,
    integer: bool = True,
    shared_axes: bool = False,
) -> np.ndarray:
    """``(n_steps, 2)`` perturbations ``r_i`` (pan, tilt), uniform in ``[−max, max]`` positions.

    ``integer=True`` draws whole positions (inclusive bounds, as the stepper moves);
    ``shared_axes=True`` uses the same ``r_i`` for pan and tilt (the paper's formula).

    >>> r = draw_perturbations(np.random.default_rng(1), 8, 60)
    >>> r.shape, int(np.abs(r).max()) <= 60
    ((8, 2), True)
    """
    cols = 1 if shared_axes else 2
    if integer:
        r = rng.integers(-max_step_pos, max_step_pos, size=(n_steps, cols), endpoint=True)
    else:
        r = rng.uniform(-max_step_pos, max_step_pos, size=(n_steps, cols))
    return np.repeat(r, 2, axis=1) if shared_axes else r


# ----------------------------------------------------------------------------------------
# Parameters and state


@dataclass(frozen=True)
class FixationParams:
    """Fixational eye-movement parameters (paper defaults).

    - ``n_steps`` N = 8 perturbations per fixation;
    - ``max_step_pos`` 60: each perturbation uniform in ``[−60, 60]`` PTU positions;
    - ``resolution_arcsec`` (pan, tilt) 92.5714″ per position on both axes (0.025714°;
      60 positions ≈ 1.543°): the PTU's (the attention agent sets it from the env's);
    - ``interval_s``: dwell of each perturbation; 0.0155 s so that the 8 steps fill the
      saliency window St_w = 124 ms of the paper's demonstrator (an assumption: the
      paper gives only the window);
    - ``max_excursion_pos``: optional bound on the walk relative to the fixation point
      (a reflecting wall: :func:`wander_env.trajectories.fold`); ``None`` = free walk (paper);
    - ``integer_positions``: draw whole positions; ``shared_axes``: same ``r_i`` on both
      axes (the paper's formula read literally; default independent axes);
    - sensor geometry for the action conversion: 128×128 Speck, HFOV 112.83°
      (:func:`wander_env.camera.check_hfov_deg`).
    """

    n_steps: int = 8
    max_step_pos: int = 60
    resolution_arcsec: tuple[float, float] = (FLIR_RESOLUTION_ARCSEC, FLIR_RESOLUTION_ARCSEC)
    interval_s: float = FIXATION_WINDOW_S / 8
    max_excursion_pos: int | None = None
    integer_positions: bool = True
    shared_axes: bool = False
    width_px: int = 128
    height_px: int = 128
    hfov_deg: float = SPECK_HFOV_DEG

    def __post_init__(self) -> None:
        check_fields(self, ("n_steps", "max_step_pos"), integer=True, minimum=0)
        check_fields(self, ("width_px", "height_px"), integer=True, minimum=1)
        check_fields(self, ("interval_s",), positive=True)
        check_fields(self, ("max_excursion_pos",), integer=True, minimum=0, allow_none=True)
        check_resolution_arcsec(self.resolution_arcsec, "FixationParams.resolution_arcsec")
        check_hfov_deg(self.hfov_deg, "FixationParams.hfov_deg")

    @property
    def deg_per_pos(self) -> tuple[float, float]:
        """Degrees per PTU position, (pan, tilt) (0.025714 each by default)."""
        pan, tilt = self.resolution_arcsec
        return positions_to_degrees(1.0, pan), positions_to_degrees(1.0, tilt)

    @property
    def duration_s(self) -> float:
        """Length of one fixation, ``n_steps · interval_s`` (0.124 s by default)."""
        return self.n_steps * self.interval_s


@dataclass(frozen=True)
class FixationStep:
    """One fixational movement: relative offset in positions, degrees and action units.

    ``delta_pos``/``delta_deg`` are ``(pan, tilt)`` in PTU signs (positive = left / up);
    ``action`` is the env's ``(x, y)`` (positive = look right / down); ``cumulative_pos``
    is the walk relative to the fixation point after this step; ``t_s`` the step's
    scheduled time since the fixation started (``index · interval_s``).
    """

    index: int
    delta_pos: tuple[float, float]
    delta_deg: tuple[float, float]
    action: np.ndarray
    cumulative_pos: tuple[float, float]
    t_s: float


class FixationalMovements:
    """Random walk of ``N`` relative PTU perturbations after each saccade.

    ``start()`` draws a new sequence from the given generator; ``next_offset()`` returns
    the next relative step (positions, degrees, action units) until ``done``. The walk
    (``cumulative_pos``) is the sum of the steps; with ``max_excursion_pos`` it is folded
    back at a reflecting wall so it stays within ±bound of the fixation point, and the
    returned step is the *actual* change (so the steps still sum to the walk).

    >>> fix = FixationalMovements(FixationParams(n_steps=2), np.random.default_rng(0))
    >>> fix.start(); s = fix.next_offset(); s.index, fix.done
    (0, False)
    """

    def __init__(
        self, params: FixationParams | None = None, rng: np.random.Generator | None = None
    ):
        self.params = params if params is not None else FixationParams()
        self._rng = rng if rng is not None else np.random.default_rng()
        self._seq = np.zeros((0, 2))
        self._i = 0
        self._cum = np.zeros(2)

    @property
    def sequence(self) -> np.ndarray:
        """The raw perturbations ``r_i`` (n_steps, 2) of the current fixation (a copy)."""
        return self._seq.copy()

    @property
    def cumulative_pos(self) -> np.ndarray:
        """Walk position (pan, tilt) relative to the fixation point, PTU positions."""
        return self._cum.copy()

    @property
    def cumulative_deg(self) -> np.ndarray:
        """Walk position relative to the fixation point, degrees (PTU signs)."""
        return self._cum * np.array(self.params.deg_per_pos)

    @property
    def index(self) -> int:
        """Number of steps used in the current fixation."""
        return self._i

    @property
    def done(self) -> bool:
        """Whether the current fixation's steps are used up (True before any start)."""
        return self._i >= len(self._seq)

    def start(self, after_saccade: bool = True) -> None:
        """Begin a fixation: draw a new sequence of ``n_steps`` perturbations.

        ``after_saccade=True`` (a new fixation point) resets the walk to 0;
        ``False`` continues the walk around the same fixation point (e.g. no salient
        point was found), so the bound still applies to the original point.
        """
        p = self.params
        self._seq = draw_perturbations(
            self._rng, p.n_steps, p.max_step_pos, p.integer_positions, p.shared_axes
        ).astype(np.float64)
        self._i = 0
        if after_saccade:
            self._cum = np.zeros(2)

    def due(self, elapsed_s: float) -> bool:
        """Whether the next step's scheduled time (``index · interval_s``) has come."""
        return not self.done and elapsed_s + 1e-9 >= self._i * self.params.interval_s

    def next_offset(self) -> FixationStep:
        """The next relative step; raises ``RuntimeError`` when ``done``."""
        if self.done:
            raise RuntimeError("fixation finished: call start() for a new one")
        p = self.params
        new = self._cum + self._seq[self._i]
        if p.max_excursion_pos is not None:
            new = fold(new, -p.max_excursion_pos, p.max_excursion_pos)
        delta = new - self._cum
        self._cum = new
        idx = self._i
        self._i += 1
        dp, dt = float(delta[0]), float(delta[1])
        return FixationStep(
            index=idx,
            delta_pos=(dp, dt),
            delta_deg=(
                positions_to_degrees(dp, p.resolution_arcsec[0]),
                positions_to_degrees(dt, p.resolution_arcsec[1]),
            ),
            action=positions_to_action(
                delta, p.resolution_arcsec, p.width_px, p.height_px, p.hfov_deg
            ),
            cumulative_pos=(float(new[0]), float(new[1])),
            t_s=idx * p.interval_s,
        )
