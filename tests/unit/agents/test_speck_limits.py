"""Wander's offline chip check (agents/speck_limits.py) against Speck's documented limits,
and sinabs' own per-layer memory check (it runs without samna)."""

from __future__ import annotations

import numpy as np
import pytest
import sinabs.layers as sl
import torch
from sinabs.utils import validate_memory_mapping_speck
from torch import nn

from agents.kernels import gaussian_kernel
from agents.speck_front import SpeckFrontParams, build_front
from agents.speck_limits import (
    SpeckLimitError,
    check_network,
    core_layers,
    kernel_memory,
    neuron_memory,
    violations,
)

IN = (2, 128, 128)


def core(c_in: int, c_out: int, k: int, stride: int = 1, padding: int = 0, **iaf) -> list:
    """One Speck-legal core: int weights, IAF with a nonzero lower threshold."""
    conv = nn.Conv2d(c_in, c_out, k, stride=stride, padding=padding, bias=False)
    with torch.no_grad():
        conv.weight.fill_(1.0)
    kw = {"spike_threshold": torch.tensor(10.0), "min_v_mem": -10.0, **iaf}
    return [conv, sl.IAFSqueeze(batch_size=1, **kw)]


def paper_literal_soms() -> nn.Sequential:
    """The paper's sOMS in sinabs layers: 8 px Gaussian centre and surround per polarity,
    LIF (tau 20 ms at 10 ms steps), 'same' padding, the 128×128 sensor grid."""
    conv = nn.Conv2d(2, 4, 8, padding="same", bias=False)
    kc, ks = gaussian_kernel(8, 1.0), gaussian_kernel(8, 4.0)
    w = np.zeros((4, 2, 8, 8))
    for p in range(2):
        w[2 * p, p], w[2 * p + 1, p] = kc / kc.max(), ks / ks.max()
    with torch.no_grad():
        conv.weight.copy_(torch.from_numpy(w))
    return nn.Sequential(conv, sl.LIFSqueeze(tau_mem=2.0, batch_size=1))


def test_the_speck_front_end_passes_on_three_cores():
    report = check_network(build_front(SpeckFrontParams()), IN)
    assert report.cores == (0, 1, 2)
    shapes = [(lay.in_shape, lay.out_shape) for lay in report.layers]
    assert shapes == [
        ((2, 128, 128), (2, 64, 64)),
        ((2, 64, 64), (8, 64, 64)),
        ((8, 64, 64), (1, 64, 64)),
    ]
    assert violations(build_front(SpeckFrontParams()), IN) == []


def test_the_paper_literal_soms_is_refused_for_its_neurons_first():
    net = paper_literal_soms()
    with pytest.raises(SpeckLimitError) as info:
        check_network(net, IN)
    assert str(info.value) == "layer 0 (conv 8x8): LIFSqueeze neurons; Speck's cores have IAF only"
    assert violations(net, IN) == [
        "layer 0 (conv 8x8): LIFSqueeze neurons; Speck's cores have IAF only",
        "layer 0 (conv 8x8): padding 'same' with an even kernel is asymmetric; Speck pads evenly",
        "layer 0 (conv 8x8): output 128x128 > Speck's 64x64 limit",
        "layer 0 (conv 8x8): weights are not 8-bit integers (quantise first)",
    ]  # its memory fits: 4 maps × 128 × 128 = 64 Ki neurons, core 0's size


def test_a_31px_kernel_is_refused():
    with pytest.raises(SpeckLimitError) as info:
        check_network(build_front(SpeckFrontParams(bo_kernel_px=31)), IN)
    assert str(info.value) == "layer 1 (conv 31x31): kernel 31 px > Speck's 16 px limit"


def test_a_128px_output_is_refused_and_border_ownership_does_not_fit_there():
    net = build_front(SpeckFrontParams(dog_stride=1))
    with pytest.raises(SpeckLimitError) as info:
        check_network(net, IN)
    assert str(info.value) == "layer 0 (conv 9x9): output 128x128 > Speck's 64x64 limit"
    assert (
        "layer 1 (conv 15x15): neuron memory 128 Ki words > Speck's largest core (64 Ki)"
        in violations(net, IN)
    )


@pytest.mark.parametrize(
    ("layers", "message"),
    [
        (core(2, 2, 3, stride=3), "layer 0 (conv 3x3): stride 3 not in Speck's (1, 2, 4, 8)"),
        (
            core(2, 2, 17, stride=2, padding=8),
            "layer 0 (conv 17x17): kernel 17 px > Speck's 16 px limit",
        ),
        (
            core(2, 2, 15, stride=2, padding=8),
            "layer 0 (conv 15x15): padding 8 px > Speck's 7 px limit",
        ),
        (
            [*core(2, 2, 3, stride=2, padding=1), sl.SumPool2d(3)],
            "layer 0 (conv 3x3): sum-pool 3 not in Speck's (1, 2, 4)",
        ),
        (core(2, 1025, 1, stride=8), "layer 0 (conv 1x1): 1025 features > Speck's 1024"),
        (
            core(2, 2, 3, stride=2, padding=1, min_v_mem=0.0),
            "layer 0 (conv 3x3): threshold_low (min_v_mem) 0 hits Speck's known threshold_low bug",
        ),
        (
            core(2, 2, 3, stride=2, padding=1, spike_threshold=torch.tensor(10.5)),
            "layer 0 (conv 3x3): thresholds are not 16-bit integers",
        ),
        (
            core(2, 2, 3, stride=2, padding=1, spike_threshold=torch.tensor(40000.0)),
            "layer 0 (conv 3x3): thresholds are not 16-bit integers",
        ),
        ([*core(2, 2, 3, stride=2, padding=1), nn.ReLU()], "layer 1: ReLU where a core needs"),
    ],
)
def test_each_limit_is_refused_with_one_line(layers, message):
    with pytest.raises(SpeckLimitError) as info:
        check_network(nn.Sequential(*layers), IN)
    assert str(info.value).startswith(message)
    assert "\n" not in str(info.value)


def test_weights_beyond_int8_and_a_large_input_are_refused():
    layers = core(2, 2, 3, stride=2, padding=1)
    with torch.no_grad():
        layers[0].weight[0, 0, 0, 0] = 128.0
    assert violations(nn.Sequential(*layers), IN) == [
        "layer 0 (conv 3x3): weights are not 8-bit integers (quantise first)"
    ]
    net = nn.Sequential(*core(2, 2, 3, stride=4, padding=1))
    assert violations(net, (2, 256, 256)) == ["input 256x256 > Speck's 128x128 limit"]


def test_the_memory_table_decides_the_core_assignment():
    # 64 Ki neurons (16 × 64 × 64) fit only cores 0–2: a fourth such layer fits nowhere
    big = [*core(2, 16, 1, stride=2)]
    layers = big + [m for _ in range(3) for m in core(16, 16, 1)]
    with pytest.raises(SpeckLimitError) as info:
        check_network(nn.Sequential(*layers), IN)
    assert str(info.value) == (
        "network: no assignment of its 4 layers to Speck's 9 cores fits the kernel/neuron "
        "memory table"
    )
    assert check_network(nn.Sequential(*layers[:6]), IN).cores == (0, 1, 2)
    ten = core(2, 2, 1, stride=2) + [m for _ in range(9) for m in core(2, 2, 1)]
    assert violations(nn.Sequential(*ten), IN) == ["network: 10 layers > Speck's 9 cores"]


def test_memory_words_are_rounded_to_powers_of_two():
    assert kernel_memory(2, 8, 15, 15) == 2 * 2 ** (8 + 3)  # 225 -> 256 taps, 8 features
    assert kernel_memory(8, 1, 15, 15) == 8 * 256
    assert kernel_memory(3, 5, 3, 3) == 3 * 16 * 8
    assert neuron_memory(8, 64, 64) == 32 * 1024
    assert neuron_memory(2, 63, 33) == 2 * 64 * 64
    layers = core_layers(build_front(SpeckFrontParams()), IN)
    assert [(lay.kernel_memory, lay.neuron_memory) for lay in layers] == [
        (512, 8192),
        (4096, 32768),
        (2048, 4096),
    ]


def test_sinabs_memory_check_runs_without_samna_and_agrees():
    for lay in core_layers(build_front(SpeckFrontParams()), IN):
        msg = validate_memory_mapping_speck(
            lay.in_shape[0], lay.out_shape[0], lay.kernel, lay.stride, lay.padding, lay.in_shape[1:]
        )
        assert msg.startswith("Layer can be mapped successfully")
    # sinabs raises a bare Exception: its message is what identifies the refusal
    with pytest.raises(Exception, match=r"^Neuron memory is 128Ki and can not be mapped on chip"):
        validate_memory_mapping_speck(2, 8, (15, 15), (1, 1), (7, 7), [128, 128])
