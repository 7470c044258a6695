"""The attention front end shaped for Speck's cores (agents/speck_front.py): its
quantisation, its maps on the sensor grid, and its use as the agent's front end."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import sinabs.layers as sl
import torch
from torch import nn

from agents.attention import AgentParams, AttentionAgent, soms_block
from agents.speck_front import (
    SpeckFront,
    SpeckFrontParams,
    SpeckPipeline,
    build_front,
    int8_scale,
    quantisation_report,
    to_sensor_grid,
)


def ring(cx: int, cy: int, r: float, size: int = 128) -> np.ndarray:
    yy, xx = np.mgrid[0:size, 0:size]
    return np.abs(np.hypot(xx - cx, yy - cy) - r) < 1.0


def test_the_network_is_plain_sinabs_layers_with_int8_weights_and_one_threshold_each():
    model = build_front(SpeckFrontParams())
    kinds = [type(m) for m in model]
    assert kinds == [nn.Conv2d, sl.IAFSqueeze] * 3
    convs = [m for m in model if isinstance(m, nn.Conv2d)]
    assert [tuple(c.weight.shape) for c in convs] == [(2, 2, 9, 9), (8, 2, 15, 15), (1, 8, 15, 15)]
    assert [c.stride for c in convs] == [(2, 2), (1, 1), (1, 1)]
    assert [c.padding for c in convs] == [(4, 4), (7, 7), (7, 7)]
    for c in convs:
        w = c.weight.detach().numpy()
        assert np.array_equal(w, np.round(w)) and w.min() >= -128 and w.max() <= 127
        assert w.max() == 127 or w.min() == -128  # the extreme weight on the int8 grid
    iafs = [m for m in model if isinstance(m, sl.IAF)]
    # thresholds: round(1 · 127 / 0.7381) for the DoG, gate 16 and grouping 2 likewise
    assert [float(m.spike_threshold) for m in iafs] == [172.0, 126.0, 143.0]
    assert [float(m.min_v_mem) for m in iafs] == [-172.0, -126.0, -143.0]
    # leaks: round(threshold · dt / (2 tau)): 172·0.01/0.04 = 43, 126·0.05 = 6.3, 143·0.05 = 7.15
    assert [c.bias.tolist() for c in convs] == [[-43.0] * 2, [-6.0] * 8, [-7.0]]


def test_quantisation_report_figures():
    dog, border, grouping = quantisation_report(SpeckFrontParams())
    assert (dog.excitatory_taps, dog.excitatory_zeros) == (18, 0)  # 9 per polarity
    assert 0.017 < dog.rel_l1_error < 0.018
    assert (border.excitatory_taps, border.excitatory_zeros, border.levels) == (1024, 352, 127)
    assert (grouping.excitatory_taps, grouping.excitatory_zeros) == (875, 40)
    # without the gate, the sketch: excitation gets 18 levels, 78 of 507 excitatory
    # taps per polarity round to 0
    no_gate = quantisation_report(SpeckFrontParams(gate=0.0, bo_threshold=1.0))[1]
    assert (no_gate.levels, no_gate.excitatory_taps, no_gate.excitatory_zeros) == (18, 1014, 156)


def test_int8_scale_puts_the_extreme_weight_on_the_grid():
    assert int8_scale(np.array([2.0, -1.0])) == 63.5
    assert int8_scale(np.array([1.0, -4.0])) == 32.0
    with pytest.raises(ValueError, match="all zero"):
        int8_scale(np.zeros(3))


def test_a_leak_beyond_the_int8_bias_range_is_refused():
    with pytest.raises(ValueError, match=r"dog: the leak 172 per step .* shorter step"):
        build_front(SpeckFrontParams(dt=0.04))


def test_even_kernels_and_bad_fields_are_refused():
    with pytest.raises(ValueError, match="dog_kernel_px must be odd"):
        SpeckFrontParams(dog_kernel_px=8)
    with pytest.raises(ValueError, match=r"SpeckFrontParams\.sigma_s"):
        SpeckFrontParams(sigma_s=0.0)


def test_the_balanced_dog_ignores_a_uniform_event_field():
    front = SpeckFront()
    out = front.step(np.ones((2, 128, 128), np.float32))
    dog = out.dog.numpy()
    assert dog[:, 3:-3, 3:-3].sum() == 0  # the interior: centre and surround cancel
    # one event under a cell's centre (0.74 of the threshold) does not fire; two do
    front.reset()
    x = np.zeros((2, 128, 128), np.float32)
    x[1, 40, 60] = 1.0
    assert front.step(x).dog.sum() == 0
    front.reset()
    x[1, 40, 60] = 2.0
    dog = front.step(x).dog.numpy()
    assert dog.sum() == 1 and dog[1, 20, 30] == 1


def test_maps_go_to_the_sensor_grid_by_2x2_blocks():
    m = np.zeros((64, 64), np.float32)
    m[20, 40] = 3.0
    up = to_sensor_grid(m, 2, 128, 128)
    assert up.shape == (128, 128) and up.sum() == 12.0
    assert np.array_equal(np.argwhere(up > 0), [[40, 80], [40, 81], [41, 80], [41, 81]])
    odd = to_sensor_grid(np.ones((2, 3)), 2, 5, 5)  # 4 rows padded to 5, 6 columns cut to 5
    assert odd.shape == (5, 5) and odd[-1].sum() == 0 and odd[:4].sum() == 20


def test_the_saliency_of_a_ring_peaks_at_its_centre():
    pipe = SpeckPipeline(SpeckFrontParams())
    ev = np.zeros((2, 128, 128), np.float32)
    ev[1][ring(80, 40, 8)] = 1.0
    for _ in range(13):
        oms = pipe.oms_step(ev)
    assert oms.shape == (2, 128, 128) and float(oms[0].sum()) == 0.0
    sal = pipe.saliency_of(oms)
    assert tuple(sal.shape) == (128, 128)
    x, y = pipe.argmax()
    assert abs(x - 80) <= 1 and abs(y - 40) <= 1
    assert float(pipe.saliency_of(oms).sum()) == 0.0  # the sum starts again
    pipe.reset()
    assert pipe.argmax() is None


def test_the_agent_runs_the_speck_front_end_by_name():
    assert AgentParams(soms="speck").soms == SpeckFrontParams()
    with pytest.raises(ValueError, match="soms must be one of"):
        AgentParams(soms="chip")
    p = AgentParams(soms=soms_block("speck"), window_s=0.05, step_s=0.01, fixational=False)
    assert p.resolved().soms == replace(SpeckFrontParams(), dt=0.01)
    agent = AttentionAgent(p, seed=0)
    assert isinstance(agent.pipeline, SpeckPipeline) and agent.proto is None
    ev = np.zeros((2, 128, 128), np.float32)
    ev[1][ring(40, 90, 8)] = 1.0
    for _ in range(5):
        agent.act({"events": ev, "gaze": np.zeros(2)}, {"moving": False})
    assert agent.decided and abs(agent.target[0] - 40) <= 1 and abs(agent.target[1] - 90) <= 1
    # integer weights, thresholds and counts: the kept count is exact on any CPU
    assert agent.events_in == 5 * int(ev.sum()) == 500 and agent.events_oms == 405
    agent.close()


def test_front_end_rejects_the_wrong_input_shape():
    with pytest.raises(ValueError, match=r"event counts must be \(2, 128, 128\)"):
        SpeckFront().step(torch.zeros(2, 64, 64))


def test_the_experiments_score_the_speck_front_end_by_name():
    from agents.attention import AgentParams
    from experiments.paper.event_suppression import EventSuppressionConfig
    from experiments.paper.event_suppression_scoring import map_model
    from experiments.paper.oms_family import measure
    from experiments.paper.oms_stimuli import Stimulus

    cfg = EventSuppressionConfig(
        agent=AgentParams(soms="speck"), second_agent=AgentParams(soms="agent")
    )
    assert cfg.soms_params() == SpeckFrontParams(dt=0.02)
    assert cfg.second_params().dt == 0.02 and cfg.windows_per_step == 10
    model = map_model(cfg.soms_params(), 96, 80)
    assert isinstance(model, SpeckFront) and model.step(np.zeros((2, 96, 80))).oms.shape == (
        2,
        96,
        80,
    )
    from experiments.paper.oms_scorecard import OMSScorecardConfig, variants

    assert list(variants("speck")) == ["speck", "agent"]
    assert variants("speck")["speck"] == SpeckFrontParams()
    with pytest.raises(ValueError, match="compare must be one of"):
        OMSScorecardConfig(compare="chip")
    s = Stimulus("sine", "patch", 16, "ratio-4", "ideal", seed=0, duration_s=0.05)
    m = measure(s, {"speck": SpeckFrontParams(), "agent": AgentParams().soms})
    # measured 69239 events in, 39344 kept; the ideal DVS's float64 log may round a
    # threshold crossing differently on another CPU: 0.1 % stated
    assert m["speck"].events_in == m["agent"].events_in
    assert m["speck"].events_in == pytest.approx(69239, rel=1e-3)
    assert m["speck"].kept == pytest.approx(39344, rel=1e-3)


def test_wander_run_and_evaluate_pick_the_front_end_by_soms():
    from types import SimpleNamespace

    from experiments.jobs.run_agent import RunConfig

    space = {"events": SimpleNamespace(shape=(2, 128, 128))}
    env = SimpleNamespace(observation_space=space)
    env.unwrapped = SimpleNamespace(
        config=SimpleNamespace(control_period_s=0.01),
        hfov_deg=AgentParams.hfov_deg,
        ptu_resolution_arcsec=AgentParams.ptu_resolution_arcsec,
    )
    from wander_env.config import parse_sets, validate

    def agent(*sets: str) -> object:
        return validate(RunConfig, parse_sets(sets, RunConfig), None, "--set").agent_params(env)

    assert agent("agent.soms=speck").soms == SpeckFrontParams()
    assert agent("agent.soms=speck", "agent.window_s=0.05").window_s == 0.05
    host = agent("agent.soms.alpha=0.6").soms
    assert (host.alpha, host.norm) == (0.6, "quantile")
