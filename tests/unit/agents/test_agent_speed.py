"""The agent's fast paths give the old implementations' results on seeded input: the
separable pooling (against the FFT pair it replaced and conv2d), the partition quantile
(bit for bit np.quantile), the NumPy LIF step (bit for bit sinabs' forward), the fused
sAC stepper (bit for bit nengo's simulator)."""

from __future__ import annotations

import nengo
import numpy as np
import pytest
import torch
import torch.nn.functional as F

from agents.attention import AGENT_SOMS
from agents.control import AttentionController, ControlParams
from agents.control_fused import FusedSteps
from agents.kernels import FFTConv2d, SeparableConv2d, gaussian_kernel, gaussian_kernel_1d
from agents.soms import SOMS, _quantile_linear, lif_layer, lif_step, peak_scale


@pytest.mark.parametrize(("size", "sigma"), [(37, 6.0), (8, 1.0), (8, 4.0), (5, 0.7)])
def test_gaussian_factor_outer_is_the_2d_kernel(size: int, sigma: float) -> None:
    g = gaussian_kernel_1d(size, sigma)
    assert g.shape == (size,) and g.sum() == pytest.approx(1.0, abs=1e-15)
    np.testing.assert_allclose(np.outer(g, g), gaussian_kernel(size, sigma), rtol=1e-12, atol=0)


@pytest.mark.parametrize(
    ("size", "sigma", "shape"), [(37, 6.0, (2, 40, 33)), (8, 1.0, (3, 17, 20))]
)
def test_separable_conv_equals_torch_same_conv(size: int, sigma: float, shape: tuple) -> None:
    g = gaussian_kernel_1d(size, sigma)
    g = g / g.max()  # peak-normalised, like the sOMS kernels (even 8: torch's alignment)
    x = np.random.default_rng(3).integers(0, 4, shape).astype(np.float32)
    y = SeparableConv2d(g, g)(x)
    w = torch.from_numpy(np.outer(g, g)).float()[None, None]
    ref = F.conv2d(torch.from_numpy(x)[:, None].double(), w.double(), padding="same")[:, 0]
    assert y.shape == shape and y.dtype == np.float32
    assert np.abs(y - ref.numpy()).max() <= 2e-6 * float(ref.abs().max())
    # (H, W) input, tensors, and a clear error for other shapes
    np.testing.assert_array_equal(SeparableConv2d(g, g)(torch.from_numpy(x[0])), y[0])
    with pytest.raises(ValueError, match="expected"):
        SeparableConv2d(g, g)(np.zeros((1, 2, 3, 4), np.float32))


def test_partition_quantile_is_np_quantile_bit_for_bit() -> None:
    rng = np.random.default_rng(0)
    for i in range(300):
        n = int(rng.integers(1, 5000))
        a = (rng.standard_normal(n) * 10 ** rng.uniform(-3, 3)).astype(np.float32)
        if i % 3 == 0:
            a = np.round(a * 4) / 4  # ties
        for q in (0.0, 0.9, 1.0, float(rng.random())):
            assert _quantile_linear(a, q) == float(np.quantile(a, q)), (i, n, q)
    with pytest.raises(ValueError, match="empty"):
        _quantile_linear(np.zeros(0, np.float32), 0.9)


@pytest.mark.parametrize("threshold", [1.0, 0.75])
def test_lif_step_is_the_sinabs_forward_bit_for_bit(threshold: float) -> None:
    ref, fast = lif_layer(0.1, 0.013, threshold), lif_layer(0.1, 0.013, threshold)
    for layer in (ref, fast):
        layer.init_state_with_shape((1, 2, 3, 50, 40))
    rng = np.random.default_rng(1)
    for k in range(25):
        current = (rng.standard_normal((2, 3, 50, 40)) * 10 ** (k % 4)).astype(np.float32)
        if k == 12:  # a new step length, as SaliencyPipeline sets it
            for layer in (ref, fast):
                layer.tau_mem.fill_(3.0)
        if k == 18:
            ref.reset_states()
            fast.reset_states()
        want = ref(torch.from_numpy(current)[None, None])[0, 0]
        got = lif_step(fast, current)
        assert np.array_equal(got[0], want.numpy()), k
        assert np.array_equal(fast.v_mem.numpy(), ref.v_mem.numpy()), k
        assert got.max() > 1.0  # several spikes a step somewhere


@pytest.mark.slow
def test_soms_quantile_outputs_equal_the_fft_pooling_and_np_quantile() -> None:
    """The agent's sOMS against the implementation it replaced (FFT pooling, np.quantile)
    on 40 seeded event maps: identical OMS maps, score within float32 rounding."""
    soms = SOMS(AGENT_SOMS, 128, 128)
    old_pool = FFTConv2d(soms.pool_weight, 128, 128)
    p = AGENT_SOMS
    rng = np.random.default_rng(5)
    worst = 0.0
    for k in range(40):
        x = (rng.random((2, 128, 128)) < 0.02 + 0.01 * (k % 5)).astype(np.float32)
        x[:, 40:70, 50:90] *= 3.0
        out = soms.step(x)
        pooled = old_pool(-out.diff.unsqueeze(1))[:, 0]
        new = soms.pool(-out.diff)
        exact = F.conv2d(-out.diff.double()[:, None], soms.pool_weight.double(), padding="same")
        tol = 1e-6 * max(1.0, float(exact.abs().max()))  # float32 rounding
        assert float((new - pooled).abs().max()) <= tol
        assert float((new - exact[:, 0]).abs().max()) <= tol / 2
        a = pooled.numpy().ravel()
        q = float(np.quantile(a, p.quantile))
        scale = peak_scale(q, float(a.max()), p.gain, p.peak_ratio, p.floor_spikes)
        score = torch.clamp(pooled / scale, 0.0, 1.0)
        worst = max(worst, float((out.score - score).abs().max()))
        oms = ((torch.from_numpy(x) > 0) & (score >= p.alpha)).float()
        assert torch.equal(out.oms, oms), k
    assert worst <= 1e-5


def _voltages(c: AttentionController) -> np.ndarray:
    sig = c.sim.model.sig
    return np.concatenate([c.sim.signals[sig[e.neurons]["voltage"]] for e in c.network.ensembles])


#: How far the fused steps' membrane voltages may be from nengo's. Both run the same
#: float64 operations, but numpy picks its SIMD kernels (and so the order of a dot
#: product's additions) by CPU: on an AMD EPYC with AVX-512, 1-2 of 100 voltages differed
#: from nengo's by up to 3.3e-15 (about 15 ulps of 1.0, the threshold) while every action
#: was identical. 1e-12 is 300 times that and a million times smaller than any change a
#: spike makes (it resets a voltage by O(1)), so a real divergence still fails.
VOLTAGE_ATOL = 1e-12


@pytest.mark.parametrize("seed", [0, 3])
def test_fused_sac_steps_are_nengos(seed: int) -> None:
    """The actions are nengo's bit for bit (spikes decide them); the voltages within
    :data:`VOLTAGE_ATOL` (the rounding of a dot product, which differs by CPU)."""
    ref = AttentionController(ControlParams(seed=seed, stepper="nengo"))
    fast = AttentionController(ControlParams(seed=seed))
    assert ref._fused is None and isinstance(fast._fused, FusedSteps)
    rng = np.random.default_rng(seed)
    for k in range(120):
        target = None if rng.random() < 0.4 else tuple(rng.uniform(0.0, 128.0, 2))
        if k == 70:
            ref.reset()
            fast.reset()
        fused = fast._fused
        if k % 25 == 3:  # the simulator's own stepping in between keeps the same state
            fast._fused = None
        u_ref, u_fast = ref.step(target, 0.01), fast.step(target, 0.01)
        fast._fused = fused
        assert np.array_equal(u_ref, u_fast), k
    np.testing.assert_allclose(_voltages(fast), _voltages(ref), rtol=0, atol=VOLTAGE_ATOL)
    assert (fast.n_steps, fast.time) == (ref.n_steps, ref.time) == (500, pytest.approx(0.5))
    ref.close()
    fast.close()


def test_fused_steps_only_for_the_sac_network() -> None:
    with nengo.Network(seed=0) as net:
        a = nengo.Ensemble(10, 1)
        nengo.Connection(nengo.Node(0.5), a)
        nengo.Probe(a)
    with nengo.Simulator(net, progress_bar=False) as sim:
        assert FusedSteps.build(sim) is None
    with pytest.raises(ValueError, match="stepper"):
        ControlParams(stepper="fast")


def test_compare_impls_times_old_and_new_on_the_same_inputs() -> None:
    from experiments.perf.agent import compare_impls

    rng = np.random.default_rng(2)
    diffs = [
        torch.from_numpy(rng.integers(-2, 3, (2, 64, 64)).astype(np.float32)) for _ in range(4)
    ]
    events = [(rng.random((2, 64, 64)) < 0.05).astype(np.float32) * 2 for _ in range(3)]
    calls = [(None if k % 3 else (float(k), 100.0 - k), 0.01) for k in range(12)]
    record = {"events": events, "diff": diffs, "control": calls}
    rows = {r.part: r for r in compare_impls(record, seed=1)}
    filters = rows["sOMS centre + surround filters"]
    soms, sac = rows["sOMS score: pooling + quantile"], rows["sAC: nengo steps"]
    # the FFT pair differs from conv2d's currents by its rounding; the 1-D passes do not
    assert len(filters.old_s) == len(filters.new_s) == 3 and 0.0 < filters.max_abs_diff <= 1e-5
    assert len(soms.old_s) == len(soms.new_s) == 4 and 0.0 < soms.max_abs_diff <= 1e-5
    assert len(sac.old_s) == len(sac.new_s) == 12 and sac.max_abs_diff == 0.0
