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
import numba
import numpy as np

from wander_env.actions import action_to_gaze_degrees
from wander_env.camera import SPECK_HFOV_DEG
from wander_env.closing import Closing
from wander_env.config import check_fields
from wander_env.ptu.units import FLIR_RESOLUTION_ARCSEC, positions_to_degrees

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
    c = np.array([(width_px - 1) / 2.0, (height_px - 1) / 2.0])
    return (p - c) / np.array([width_px / 2.0, height_px / 2.0])


def steps_for(duration_s: float, dt: float) -> int:
    """Number of ``dt`` steps in ``duration_s``; it must be a whole multiple (±1e-6 steps).

    >>> steps_for(0.01, 0.001), steps_for(0.0, 0.001)
    (10, 0)
    """
    if not (math.isfinite(duration_s) and duration_s >= 0):
        raise ValueError(f"duration_s must be a finite number >= 0, got {duration_s!r}")
    n = duration_s / dt
    k = round(n)
    if abs(n - k) > 1e-6:
        raise ValueError(f"duration_s={duration_s!r} is not a whole multiple of dt={dt!r}")
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
    per = positions_to_degrees(1.0, resolution_arcsec)
    return math.floor(pan_deg / per), math.floor(tilt_deg / per)


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
    per = positions_to_degrees(1.0, resolution_arcsec)
    return math.floor(k_pan * error_px[0] / per), math.floor(k_tilt * error_px[1] / per)


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
      arithmetic on nengo's own signal arrays (:class:`FusedSteps`, bit for bit nengo's
      reference simulator, ≈2× faster: ``wander perf agent``); ``"nengo"``:
      ``Simulator.run_steps``.
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
        return (self.width_px - 1) / 2.0, (self.height_px - 1) / 2.0


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


class FusedSteps:
    """The sAC simulator's time step as one fused loop: the arithmetic of the 19
    operators nengo's reference simulator runs for this network (time update, resets,
    copies, the two node callbacks, six first-order lowpass filters, the encoder and
    decoder block-sparse products, the LIF update), in an order nengo's dependency graph
    allows, on the simulator's own signal arrays. It skips the per-operator dispatch
    (scipy's sparse ``dot`` and nengo's process wrappers dominate a 1 ms step), so a
    10 ms env step costs a fraction of ``Simulator.run_steps(10)``, with identical
    results: each value is computed by the same floating-point operations (element-wise
    products and sums, the decoders' sums in the sparse kernel's sequential order,
    nengo's own ``LIF.step``). State stays in the simulator (``sim.reset``, ``sim.time``
    and ``run_steps`` keep working, and the two can be interleaved).

    :meth:`build` returns None when the simulator's operators are not exactly the
    expected ones (another network, another nengo): the caller then uses ``run_steps``.
    """

    def __init__(self, sim: nengo.Simulator, ops: dict) -> None:
        self.sim = sim
        sig = sim.signals
        self.dt = float(sim.dt)
        self._step, self._time = sig[sim.model.step], sig[sim.model.time]
        self._J, self._out = sig[ops["neurons"].J], sig[ops["neurons"].output]
        self._voltage = sig[ops["neurons"].state["voltage"]]
        self._refractory = sig[ops["neurons"].state["refractory_time"]]
        self._lif = ops["neurons"].neurons
        self._bias = sig[ops["bias"].src]
        self._ens_in = sig[ops["enc"].X]
        n = self._J.shape[0] // 2
        self._enc = sig[ops["enc"].A].reshape(2 * n)
        self._blk = np.repeat(np.arange(2), n)
        self._dec = sig[ops["dec"].A].reshape(2, n)
        self._weighted = sig[ops["dec"].Y]
        self._u_in = sig[ops["store"].x]
        self._target_out = sig[ops["target"].output]
        self._read_target, self._store = ops["target"].fn, ops["store"].fn
        # The six lowpass filters as one vector: inputs gathered from (target, centre,
        # weighted), outputs scattered into the three merged signals the copies read.
        self._filter_src = [sig[x] for x in ops["filter_src"]]
        self._filter_idx = np.array(ops["filter_idx"])
        self._a = np.array(ops["filter_a"])
        self._b = np.array(ops["filter_b"])
        self._x_state = [sig[x] for x in ops["filter_state"]]
        self._x = np.array([x.item() for x in self._x_state])
        self._filter_dst = [(sig[base], np.array(sel)) for base, sel in ops["filter_dst"]]
        self._ens_src = [sig[x] for x in ops["ens_src"]]
        self._u_src = sig[ops["u_src"]]

    @classmethod
    def build(cls, sim: nengo.Simulator) -> FusedSteps | None:
        """The fused stepper of an :class:`AttentionController`'s simulator, or None
        when its operator list is not the expected one."""
        from nengo.builder.neurons import SimNeurons
        from nengo.builder.operator import BsrDotInc, Copy, Reset, SimPyFunc, TimeUpdate
        from nengo.builder.processes import SimProcess
        from nengo.synapses import LinearFilter

        order = sim.step_order
        kinds = [type(op) for op in order]
        want = {TimeUpdate: 1, Reset: 3, Copy: 4, SimPyFunc: 2, SimProcess: 6, BsrDotInc: 2}
        want[SimNeurons] = 1
        if len(order) != 19 or any(kinds.count(k) != c for k, c in want.items()):
            return None
        neurons = next(op for op in order if isinstance(op, SimNeurons))
        if type(neurons.neurons) is not nengo.LIF or neurons.J.size % 2:
            return None
        ops: dict = {"neurons": neurons}
        for op in order:
            if isinstance(op, BsrDotInc):
                key = (
                    "enc"
                    if _same(op.Y, neurons.J)
                    else "dec"
                    if _same(op.X, neurons.output)
                    else None
                )
                if key is None or list(op.indices) != [0, 1] or list(op.indptr) != [0, 1, 2]:
                    return None
                ops[key] = op
            elif isinstance(op, SimPyFunc):
                ops["target" if op.x is None else "store"] = op
            elif isinstance(op, Copy) and _same(op.dst, neurons.J) and not op.inc:
                ops["bias"] = op
        if not all(k in ops for k in ("enc", "dec", "target", "store", "bias")):
            return None
        n = neurons.J.shape[0] // 2
        if ops["enc"].A.shape != (2, n, 1) or ops["dec"].A.shape != (2, 1, n):
            return None
        if ops["target"].output is None or ops["store"].output is not None:
            return None
        # the three merged filter outputs: copied into the ensemble input (target and
        # centre filters) and into the output node's input (decoded filter)
        copies = [op for op in order if isinstance(op, Copy) and op.inc]
        to_ens = [op.src for op in copies if _same(op.dst, ops["enc"].X)]
        to_u = [op.src for op in copies if _same(op.dst, ops["store"].x)]
        resets = [op.dst for op in order if isinstance(op, Reset)]
        if len(to_ens) != 2 or len(to_u) != 1:
            return None
        for want_reset in (ops["enc"].X, ops["dec"].Y, ops["store"].x):
            if not any(_same(r, want_reset) for r in resets):
                return None
        dst_bases = [x.base for x in to_ens + to_u]
        if any(x.size != 2 or x.elemoffset != 0 or x.base.size != 2 for x in to_ens + to_u):
            return None
        if len({id(b) for b in dst_bases}) != 3:
            return None
        src_bases = [ops["target"].output.base, None, ops["dec"].Y.base]  # None: -centre
        a, b, idx, state = [], [], [], []
        where: dict[tuple[int, int], int] = {}
        for op in order:
            if not isinstance(op, SimProcess):
                continue
            if not (isinstance(op.process, LinearFilter) and op.mode == "update"):
                return None
            if op.input.size != 1 or op.output.size != 1 or list(op.state) != ["X"]:
                return None
            x_state = sim.signals[op.state["X"]]
            f = op.process.make_step(op.input.shape, op.output.shape, sim.dt, None, {"X": x_state})
            if not isinstance(f, LinearFilter.OneXScalar) or op.input.base.size != 2:
                return None
            base = op.input.base
            if src_bases[1] is None and base is not src_bases[0] and base is not src_bases[2]:
                src_bases[1] = base
            k = next((i for i, sb in enumerate(src_bases) if sb is base), None)
            d = next((i for i, db in enumerate(dst_bases) if db is op.output.base), None)
            if k is None or d is None or (d, op.output.elemoffset) in where:
                return None
            where[(d, op.output.elemoffset)] = len(a)
            a.append(f.a)
            b.append(f.b)
            idx.append(2 * k + op.input.elemoffset)
            state.append(op.state["X"])
        if len(where) != 6 or src_bases[1] is None:
            return None
        ops.update(
            filter_src=src_bases,
            filter_idx=idx,
            filter_a=a,
            filter_b=b,
            filter_state=state,
            filter_dst=[(dst_bases[d], [where[(d, 0)], where[(d, 1)]]) for d in range(3)],
            ens_src=to_ens,
            u_src=to_u[0],
        )
        return cls(sim, ops)

    def run(self, n: int) -> None:
        """Advance the simulator ``n`` steps (as ``sim.run_steps(n)``). The target node's
        function is read once (the controller holds the target over a call); the output
        node's function gets each step's time and value after the steps."""
        x = self._x
        for k, xs in enumerate(self._x_state):  # the state as the simulator holds it
            x[k] = xs.item()
        s0 = int(self._step)
        t0 = (s0 + 1) * self.dt
        target = np.asarray(self._read_target(t0), dtype=np.float64)
        u_seq = np.empty((n, self._u_in.size))
        (e1, e2), (d0, d1, d2) = self._ens_src, self._filter_dst
        lif = self._lif
        _fused_sac_steps(
            n,
            self.dt,
            target,
            *self._filter_src,
            self._bias,
            self._enc,
            self._blk,
            self._dec,
            self._a,
            self._b,
            self._filter_idx,
            x,
            self._J,
            self._out,
            self._voltage,
            self._refractory,
            self._ens_in,
            self._weighted,
            self._u_in,
            self._target_out,
            e1,
            e2,
            self._u_src,
            d0[0],
            d0[1],
            d1[0],
            d1[1],
            d2[0],
            d2[1],
            float(lif.tau_rc),
            float(lif.tau_ref),
            float(lif.min_voltage),
            float(lif.amplitude),
            u_seq,
        )
        if not np.isfinite(self._voltage).all():  # Simulator.step raises on these
            raise FloatingPointError("invalid value in the sAC's LIF step")
        self._step[...] = s0 + n
        self._time[...] = self._step * self.dt
        for k in range(n):
            self._store((s0 + k + 1) * self.dt, u_seq[k])
        for k, xs in enumerate(self._x_state):
            xs.flat[0] = x[k]
        self.sim._probe_step_time()  # the simulator's n_steps and time (no probes here)


@numba.njit(cache=True, nogil=True)
def _fused_sac_steps(
    n,
    dt,
    target,
    src_target,
    src_centre,
    src_weighted,
    bias,
    enc,
    blk,
    dec,
    a,
    b,
    idx,
    x,
    J,
    out,
    voltage,
    refractory,
    ens_in,
    weighted,
    u_in,
    target_out,
    e1,
    e2,
    u_src,
    d0,
    sel0,
    d1,
    sel1,
    d2,
    sel2,
    tau_rc,
    tau_ref,
    min_voltage,
    amplitude,
    u_seq,
):
    """:meth:`FusedSteps.run`'s ``n`` steps: per step the operators' arithmetic in
    nengo's order and with its floating-point operations (no contraction: numba's
    default), the LIF update as ``nengo.LIF.step`` (its ``expm1`` and ``log1p`` are the
    C library's, as NumPy's without AVX-512); ``u_seq[k]`` gets the output node's input."""
    src = np.empty(6)
    for k in range(n):
        for i in range(u_in.size):
            u_in[i] = 0.0 + u_src[i]
            u_seq[k, i] = u_in[i]
        for i in range(ens_in.size):
            ens_in[i] = (0.0 + e1[i]) + e2[i]
        for i in range(target_out.size):
            target_out[i] = target[i]
        for i in range(J.size):
            J[i] = bias[i] + enc[i] * ens_in[blk[i]]
        # nengo.LIF.step
        for i in range(J.size):
            refractory[i] -= dt
            delta_t = min(max(dt - refractory[i], 0.0), dt)
            voltage[i] -= (J[i] - voltage[i]) * math.expm1(-delta_t / tau_rc)
            spiked = voltage[i] > 1
            out[i] = amplitude / dt if spiked else 0.0
            t_spike = 0.0
            if spiked:
                t_spike = dt + tau_rc * math.log1p(-(voltage[i] - 1) / (J[i] - 1))
            if voltage[i] < min_voltage:
                voltage[i] = min_voltage
            if spiked:
                voltage[i] = 0.0
                refractory[i] = tau_ref + t_spike
        # decoders: each axis' sum over its neurons in index order
        m = dec.shape[1]
        for r in range(dec.shape[0]):
            acc = dec[r, 0] * out[r * m]
            for j in range(1, m):
                acc += dec[r, j] * out[r * m + j]
            weighted[r] = 0.0 + (acc + 0.0)
        # the six lowpass filters (nengo's "update" mode: read at the next step)
        src[0], src[1] = src_target[0], src_target[1]
        src[2], src[3] = src_centre[0], src_centre[1]
        src[4], src[5] = src_weighted[0], src_weighted[1]
        for f in range(x.size):
            x[f] = a[f] * x[f] + b[f] * src[idx[f]]
        d0[0], d0[1] = x[sel0[0]], x[sel0[1]]
        d1[0], d1[1] = x[sel1[0]], x[sel1[1]]
        d2[0], d2[1] = x[sel2[0]], x[sel2[1]]


def _same(a: nengo.builder.Signal, b: nengo.builder.Signal) -> bool:
    """Whether two nengo signals are the same memory (the optimiser's views differ as
    objects)."""
    return (
        a.base is b.base
        and a.elemoffset == b.elemoffset
        and a.shape == b.shape
        and a.elemstrides == b.elemstrides
    )
