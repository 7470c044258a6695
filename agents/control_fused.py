"""The sAC simulator's time step as one fused loop (numba), bit for bit nengo's.

:class:`FusedSteps` recognises the operators nengo's reference simulator runs for the
network of :class:`agents.control.AttentionController` and runs their arithmetic in one
compiled loop on the simulator's own signal arrays (:func:`_fused_sac_steps`); for any
other operator list :meth:`FusedSteps.build` returns None and the controller runs
``Simulator.run_steps``.
"""

from __future__ import annotations

import math

import nengo
import numba
import numpy as np

__all__ = ["FusedSteps"]


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
        """The fused stepper of an :class:`~agents.control.AttentionController`'s simulator, or None
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
