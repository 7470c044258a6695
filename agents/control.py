"""Spiking attention control (sAC): an NEF proportional controller in nengo.

The paper (``../shared/seed/paper.tex``, §"Spiking Attention Control") drives the PTU
with a proportional controller, one 50-neuron LIF population per axis::

    [u_pan, u_tilt]ᵀ = diag(K_pan, K_tilt) · [x_obj − x_center, y_obj − y_center]ᵀ

with ``K_pan = K_tilt = 1``. Each population represents its axis' error; the error is
formed by Kirchhoff summation of input currents (a target connection plus a constant
``−centre`` connection); the decoders ``w`` solve the least-squares problem
``argmin_w ‖K·ε − w·(h ∗ a(⟨e, ε⟩))‖²`` (nengo's L2-regularised least squares), and the
decoded, synapse-filtered value is ``u``. The paper then commands ``cmd = ⌊u⌋`` PTU
positions.

Here the error is normalised to the half sensor size,
``e = (P − c) / (W/2, H/2)`` with ``c = ((W−1)/2, (H−1)/2)`` (so ``e ∈ (−1, 1)`` on the
sensor and the population radius is 1), and ``u = K·e`` is returned **in env action
units**: ``u`` *is* the action that brings ``P`` to the fovea when ``K = 1`` (positive x
looks right, positive y looks down). Mapping to the paper's ``cmd = ⌊u⌋``: the env (or
the hardware backend) turns the action into angles with the pinhole model,
``angle = atan(u·(W/2) / f_px)``, then into PTU positions (92.5714″ each) with the PTU
signs (positive pan = left, positive tilt = up); :func:`command_positions` does exactly
that and applies the paper's floor. The floor is a bias of at most one position
(0.026° ≈ 0.02 px at the fovea). Note the paper's decoder target
``K/degrees_per_pos · ε`` with ``ε`` in pixels treats 1 px as 1°, whereas the Speck's
pinhole gives ≈1.35°/px at the fovea, so the paper's effective gain near the centre is
≈0.74 (see :func:`paper_command_positions`); with the pinhole mapping ``K = 1`` foveates
in one saccade.

Time: :meth:`AttentionController.step` advances the nengo simulator by exactly the
requested duration (an integer number of ``dt`` steps), in lockstep with the env; no
probes are used — the output node stores the latest filtered decoded value and a running
sum over the averaging window — so memory stays constant however long it runs. The
simulator is built once; :meth:`reset` only resets its state.

Examples:
    >>> ctrl = AttentionController(ControlParams(seed=0))
    >>> for _ in range(10):  # 100 ms with the target 32 px right of and 16 px above the fovea
    ...     u = ctrl.step((63.5 + 32, 63.5 - 16), 0.01)
    >>> bool(abs(u[0] - 0.5) < 0.1 and abs(u[1] + 0.25) < 0.1), round(ctrl.time, 6)
    (True, 0.1)
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import nengo
import numpy as np

from agents.control_fused import FusedSteps
from wander_env.actions import action_to_gaze_degrees
from wander_env.camera import SPECK_HFOV_DEG, principal_point
from wander_env.closing import Closing
from wander_env.config import check_fields
from wander_env.ptu.units import FLIR_RESOLUTION_ARCSEC, degrees_to_positions

__all__ = [
    "AttentionController",
    "ControlParams",
    "command_positions",
    "normalised_error",
    "paper_command_positions",
    "steps_for",
]


# ----------------------------------------------------------------------------------------
# Pure maths


def normalised_error(
    target_xy_px: tuple[float, float] | np.ndarray, width_px: int = 128, height_px: int = 128
) -> np.ndarray:
    """``e = (P − c) / (W/2, H/2)``, ``c = ((W−1)/2, (H−1)/2)``: the action foveating ``P``.

    >>> normalised_error((127, 0)).tolist()
    [0.9921875, -0.9921875]
    """
    p = np.asarray(target_xy_px, dtype=np.float64).reshape(2)
    c = np.array(principal_point(width_px, height_px))
    return (p - c) / np.array([width_px / 2.0, height_px / 2.0])


def steps_for(duration_s: float, dt: float, name: str = "duration_s") -> int:
    """Number of ``dt`` steps in ``duration_s``; it must be a whole multiple (±1e-6 steps).
    ValueError naming ``name`` (what ``duration_s`` is) and the value otherwise.

    >>> steps_for(0.01, 0.001), steps_for(0.0, 0.001)
    (10, 0)
    >>> steps_for(0.0125, 0.001, "AgentParams.step_s")
    Traceback (most recent call last):
    ...
    ValueError: AgentParams.step_s=0.0125 is not a whole multiple of dt=0.001
    """
    if not (math.isfinite(duration_s) and duration_s >= 0):
        raise ValueError(f"{name} must be a finite number >= 0, got {duration_s!r}")
    n = duration_s / dt
    k = round(n)
    if abs(n - k) > 1e-6:
        raise ValueError(f"{name}={duration_s!r} is not a whole multiple of dt={dt!r}")
    return int(k)


def command_positions(
    u: np.ndarray | tuple[float, float],
    width_px: int = 128,
    height_px: int = 128,
    hfov_deg: float = SPECK_HFOV_DEG,
    resolution_arcsec: float = FLIR_RESOLUTION_ARCSEC,
) -> tuple[int, int]:
    """The paper's ``cmd = ⌊u⌋``: action-unit ``u`` -> relative PTU positions (pan, tilt).

    ``u`` -> pixel offset ``u·(W/2, H/2)`` -> angle ``atan(d / f_px)`` (PTU signs:
    look right = negative pan, look down = negative tilt) -> positions -> floor.

    >>> command_positions((0.5, 0.0))  # 32 px right: atan(32/42.5) = 36.98° right
    (-1439, 0)
    """
    pan_deg, tilt_deg = action_to_gaze_degrees(u, width_px, height_px, hfov_deg)
    pan, tilt = (degrees_to_positions(d, resolution_arcsec) for d in (pan_deg, tilt_deg))
    return math.floor(pan), math.floor(tilt)


def paper_command_positions(
    error_px: tuple[float, float],
    k_pan: float = 1.0,
    k_tilt: float = 1.0,
    resolution_arcsec: float = FLIR_RESOLUTION_ARCSEC,
) -> tuple[int, int]:
    """The paper's decoder target read literally: ``⌊K · ε / degrees_per_pos⌋``, ε in px.

    For comparison only (it treats one pixel as one degree); signs as in the paper's
    ε (x right, y down), not PTU signs.

    >>> paper_command_positions((1.0, -1.0))
    (38, -39)
    """
    pan = degrees_to_positions(k_pan * error_px[0], resolution_arcsec)
    tilt = degrees_to_positions(k_tilt * error_px[1], resolution_arcsec)
    return math.floor(pan), math.floor(tilt)


# ----------------------------------------------------------------------------------------
# Parameters


@dataclass(frozen=True)
class ControlParams:
    """sAC parameters; paper values as defaults (Table "params", sAC column).

    - ``n_neurons`` 50 LIF neurons per axis (one population each for pan and tilt);
    - ``k_pan = k_tilt = 1`` (proportional gains);
    - ``width_px``/``height_px`` 128 (Speck), centre ``((W−1)/2, (H−1)/2)`` = 63.5 (the
      paper uses 64 for the pixel grid's centre);
    - ``radius`` 1.0: the normalised error spans (−1, 1) on the sensor;
    - ``tau_input_s`` 0.005 s (input current filter) and ``tau_output_s`` 0.01 s
      (decoding filter ``h(t)``); our choice — the paper gives no time constants;
    - ``average_s`` 0.01 s: :meth:`AttentionController.step` returns the mean of the
      filtered decoded value over the last ``average_s`` of the step (the public code
      averaged the last 10 ms of its probe); 0 returns the latest value. It cuts the
      spike noise of ``u`` from ≈0.02 to ≈0.005 (action units; ×64 for pixels);
    - ``solver_reg`` 0.03: L2 regularisation of the decoder least squares (relative to
      the peak rate; nengo's default is 0.1). Over 20 seeds, 0.03 halves the static
      decoding bias at ``e = 0`` (max 0.024 -> 0.012) at little extra noise; this bias
      is what remains as foveation error in closed loop.

    With these, ``|u − K·e| < 0.1`` from 50 ms after a step in ``e`` for
    ``|e| ≤ 0.99`` (worst over 20 seeds ≈ 0.06).
    - ``dt`` 0.001 s nengo step; ``seed`` for encoders, gains, biases, initial voltages.
    - ``stepper`` ``"fused"``: the simulator's steps run as one fused loop over the same
      arithmetic on nengo's own signal arrays (:class:`~agents.control_fused.FusedSteps`,
      bit for bit nengo's reference simulator, ≈2× faster: ``wander perf agent``);
      ``"nengo"``: ``Simulator.run_steps``.
    """

    n_neurons: int = 50
    k_pan: float = 1.0
    k_tilt: float = 1.0
    width_px: int = 128
    height_px: int = 128
    radius: float = 1.0
    tau_input_s: float | None = 0.005
    tau_output_s: float | None = 0.01
    average_s: float = 0.01
    solver_reg: float = 0.03
    dt: float = 0.001
    seed: int | None = 0
    stepper: str = "fused"

    def __post_init__(self) -> None:
        if self.stepper not in ("fused", "nengo"):
            raise ValueError(
                f"ControlParams.stepper must be 'fused' or 'nengo', got {self.stepper!r}"
            )
        check_fields(self, ("n_neurons", "width_px", "height_px"), integer=True, minimum=1)
        check_fields(self, ("k_pan", "k_tilt"))
        check_fields(self, ("average_s", "solver_reg"), minimum=0)
        check_fields(self, ("radius", "dt"), positive=True)
        check_fields(self, ("tau_input_s", "tau_output_s"), positive=True, allow_none=True)

    @property
    def centre_px(self) -> tuple[float, float]:
        """The fovea ``((W−1)/2, (H−1)/2)``."""
        return principal_point(self.width_px, self.height_px)


# ----------------------------------------------------------------------------------------
# Controller


class AttentionController(Closing):
    """The sAC network (2 × ``n_neurons`` LIF), stepped in lockstep with the env.

    ``step(P, duration_s)`` sets the target pixel ``P`` (held constant over the step),
    runs the simulator for exactly ``duration_s`` and returns the decoded ``u`` (2,) in
    action units. ``P = None`` means "no target": zero error (the output decays to 0).

    >>> ctrl = AttentionController()
    >>> ctrl.step((63.5, 63.5), 0.01).shape, ctrl.n_steps
    ((2,), 10)
    """

    def __init__(self, params: ControlParams | None = None):
        self.params = p = params if params is not None else ControlParams()
        # Python-side buffers read/written by the nodes (the only mutable state).
        self._target = np.zeros(2)  # P / (W/2, H/2)
        self._u = np.zeros(2)  # latest filtered decoded value
        self._acc = np.zeros(2)  # sum over the averaging window of the current step
        self._n_acc = 0
        self._skip = 0  # nengo steps of the current step.run before the window opens
        self._avg_steps = max(1, round(p.average_s / p.dt)) if p.average_s > 0 else 0
        half = np.array([p.width_px / 2.0, p.height_px / 2.0])
        self._half = half
        self._centre_norm = np.array(p.centre_px) / half
        self._idle_target = self._centre_norm.copy()
        self._target[:] = self._idle_target

        net = nengo.Network(label="sAC", seed=p.seed)
        with net:
            target = nengo.Node(self._read_target, size_in=0, size_out=2, label="target")
            centre = nengo.Node(-self._centre_norm, label="-centre")
            out = nengo.Node(self._store_output, size_in=2, size_out=0, label="u")
            for axis, k in ((0, p.k_pan), (1, p.k_tilt)):
                name = ("pan", "tilt")[axis]
                ens = nengo.Ensemble(
                    p.n_neurons, 1, radius=p.radius, neuron_type=nengo.LIF(), label=name
                )
                # Kirchhoff: the error is the sum of the two input currents.
                nengo.Connection(target[axis], ens, synapse=p.tau_input_s)
                nengo.Connection(centre[axis], ens, synapse=p.tau_input_s)
                nengo.Connection(
                    ens,
                    out[axis],
                    function=lambda x, k=k: k * x,
                    synapse=p.tau_output_s,
                    solver=nengo.solvers.LstsqL2(reg=p.solver_reg),
                )
        self.network = net
        self.sim = nengo.Simulator(net, dt=p.dt, seed=p.seed, progress_bar=False)
        self._fused = FusedSteps.build(self.sim) if p.stepper == "fused" else None

    # nengo node callbacks ------------------------------------------------------------

    def _read_target(self, t: float) -> np.ndarray:
        return self._target

    def _store_output(self, t: float, x: np.ndarray) -> None:
        self._u[:] = x
        if self._skip > 0:
            self._skip -= 1
        else:
            self._acc += x
            self._n_acc += 1

    # public API ----------------------------------------------------------------------

    @property
    def time(self) -> float:
        """Simulated controller time in seconds (``n_steps · dt``)."""
        return float(self.sim.time)

    @property
    def n_steps(self) -> int:
        """Number of nengo steps run since the last reset."""
        return int(self.sim.n_steps)

    @property
    def output(self) -> np.ndarray:
        """The latest decoded, filtered ``u`` (action units), a copy."""
        return self._u.copy()

    def step(
        self, target_xy_px: tuple[float, float] | np.ndarray | None, duration_s: float = 0.01
    ) -> np.ndarray:
        """Hold target pixel ``P`` for ``duration_s`` (a multiple of ``dt``); return ``u`` (2,).

        ``u`` is the mean of the filtered decoded value over the last
        ``min(duration_s, average_s)`` (the latest value when ``average_s = 0``).
        ``duration_s = 0`` runs nothing and returns the latest value. Errors beyond the
        population radius (targets off the sensor) are not represented faithfully:
        the decoded value saturates there.
        """
        n = steps_for(duration_s, self.params.dt)
        if target_xy_px is None:
            self._target[:] = self._idle_target
        else:
            p = np.asarray(target_xy_px, dtype=np.float64).reshape(2)
            if not np.all(np.isfinite(p)):
                raise ValueError(f"target_xy_px must be finite, got {target_xy_px!r}")
            self._target[:] = p / self._half
        if n == 0:
            return self._u.copy()
        self._acc[:] = 0.0
        self._n_acc = 0
        self._skip = n - min(n, self._avg_steps) if self._avg_steps else n
        if self._fused is not None:
            self._fused.run(n)
        else:
            self.sim.run_steps(n)
        if self._n_acc == 0:
            return self._u.copy()
        return self._acc / self._n_acc

    def reset(self, seed: int | None = None) -> None:
        """Reset the simulator state (no rebuild); ``seed`` defaults to ``params.seed``."""
        self.sim.reset(seed=self.params.seed if seed is None else seed)
        self._target[:] = self._idle_target
        self._u[:] = 0.0
        self._acc[:] = 0.0
        self._n_acc = 0
        self._skip = 0

    def close(self) -> None:
        """Release the simulator."""
        self.sim.close()
