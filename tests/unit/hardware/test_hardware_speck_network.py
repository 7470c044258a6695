"""Deploying the Speck front end (hardware/speck_network.py) against the stand-in samna of
tests/fake_samna.py: the offline check first, sinabs' DynapcnnNetwork and make_config,
and the rig's path that reads the monitored cores back into the agent."""

from __future__ import annotations

import ast
import subprocess
import sys

import numpy as np
import pytest
import torch
from fake_samna import FakeSamna, FakeSpeck, forget_dynapcnn, install, spike
from locations import ROOT

from agents.attention import AgentParams, AttentionAgent
from agents.speck_front import SpeckFront, SpeckFrontParams, build_front
from agents.speck_limits import SpeckLimitError
from hardware.samna_import import SamnaUnavailableError
from hardware.speck import SpeckParams, SpeckSource
from hardware.speck_network import ChipPipeline, deploy, spike_counts
from wander_env.events import EVENT_DTYPE
from wander_env.readout import ReadoutParams


@pytest.fixture
def fake(monkeypatch) -> FakeSamna:
    speck = FakeSpeck(events=np.zeros(0, EVENT_DTYPE))
    forget_dynapcnn(monkeypatch)
    return install(monkeypatch, FakeSamna([("Speck2fModuleDevKit", "0001", speck)]))


def test_make_config_writes_the_quantised_model_to_three_cores(fake):
    dep = deploy(SpeckFrontParams(), "speck2fmodule")
    assert dep.layer2core == {1: 0, 2: 1, 3: 2} and (dep.oms_core, dep.saliency_core) == (0, 2)
    assert dep.report.cores == (0, 1, 2)
    assert fake.validated == [dep.config]
    model = build_front(SpeckFrontParams())
    convs = [m for m in model if isinstance(m, torch.nn.Conv2d)]
    cores = dep.config.cnn_layers
    for i, conv in enumerate(convs):
        # sinabs writes weights (out, in, x, y): the model's transposed, unchanged
        assert cores[i].weights == conv.weight.transpose(2, 3).int().tolist()
        assert cores[i].biases == conv.bias.int().tolist() and cores[i].leak_enable is True
    assert [c.threshold_high for c in cores[:3]] == [172, 126, 143]
    assert [c.threshold_low for c in cores[:3]] == [-172, -126, -143]
    assert [c.monitor_enable for c in cores[:3]] == [True, False, True]
    dest = [
        (d.enable, d.layer, d.pooling) for d in (cores[0].destinations[0], cores[1].destinations[0])
    ]
    assert dest == [(True, 1, 1), (True, 2, 1)]
    assert not any(d.enable for d in cores[2].destinations)
    assert not any(c.weights for c in cores[3:])  # six cores left free
    dims = cores[1].dimensions
    assert dims["output_shape"] == {"size": {"x": 64, "y": 64}, "feature_count": 8}
    assert dims["padding"] == {"x": 7, "y": 7} and dims["kernel_size"] == 15
    # the chip's own pixel array feeds core 0
    dvs = dep.config.dvs_layer
    assert dvs.destinations[0].enable and dvs.destinations[0].layer == 0
    assert dvs.pass_sensor_events is True


def test_the_discretised_network_computes_what_the_simulation_computes(fake):
    from sinabs.backend.dynapcnn import DynapcnnNetwork

    net = DynapcnnNetwork(build_front(SpeckFrontParams()), (2, 128, 128), 1, discretize=True)
    front = SpeckFront()
    rng = np.random.default_rng(3)
    fired = 0.0
    for _ in range(4):
        x = torch.from_numpy(rng.poisson(0.1, (2, 128, 128)).astype(np.float32))
        ours = front.step(x).grouping
        assert torch.equal(net(x[None])[0], ours)  # same ops on the same integers
        fired += float(ours.sum())
    assert fired == 40.0  # the seeded input's grouping spikes (integer arithmetic)


def test_the_offline_check_refuses_before_samna_is_touched(monkeypatch):
    monkeypatch.setitem(sys.modules, "samna", None)  # samna missing
    with pytest.raises(SpeckLimitError) as info:
        deploy(SpeckFrontParams(bo_kernel_px=31))
    assert str(info.value) == "layer 1 (conv 31x31): kernel 31 px > Speck's 16 px limit"
    with pytest.raises(SamnaUnavailableError, match="samna is not installed"):
        deploy(SpeckFrontParams())


def test_the_rig_reads_the_monitored_cores_into_the_agent(fake):
    samna = sys.modules["samna"]
    handle = samna.device.open_device(samna.device.get_unopened_devices()[0])
    dep = deploy()
    chip = ChipPipeline(handle, dep)
    with pytest.raises(RuntimeError, match="start"):
        chip.oms_step(np.zeros((2, 128, 128)))
    chip.start()
    assert handle.applied == [dep.config]
    sink = handle._sinks[0]
    fam = "speck2f"
    sink._buffer += [spike(fake, fam, 0, 1, 10, 5, 100), spike(fake, fam, 7, 0, 1, 1, 101)]
    sink._buffer += [spike(fake, fam, 2, 0, 40, 20, 102 + i) for i in range(3)]
    oms = chip.oms_step(np.zeros((2, 128, 128), np.float32)).numpy()
    assert oms.sum() == 4 and oms[1, 10:12, 20:22].sum() == 4  # DoG (x 10, y 5), ON
    assert chip.spikes_read == 4  # core 7 is not monitored
    sal = chip.saliency_of(oms)
    assert float(sal.sum()) == 12.0 and chip.argmax() == (80, 40)
    # the agent takes the chip's pipeline in place of its own
    agent = AttentionAgent(AgentParams(soms="speck", window_s=0.02, fixational=False), 0, chip)
    sink._buffer += [spike(fake, fam, 2, 0, 30, 50, 200) for _ in range(2)]
    obs = {"events": np.zeros((2, 128, 128), np.float32), "gaze": np.zeros(2)}
    agent.act(obs, {"moving": False})
    agent.act(obs, {"moving": False})
    assert agent.decided and agent.target == (60, 100)
    agent.close()


def test_the_camera_applies_one_configuration_with_the_cores_and_the_dvs_monitor(fake):
    dep = deploy()
    source = SpeckSource(config=dep.config)
    source.start()
    try:
        handle = source.device
        assert handle.applied == [dep.config]  # once, by the camera
        dvs = handle.applied[0].dvs_layer
        assert (dvs.raw_monitor_enable, dvs.monitor_enable, dvs.pass_sensor_events) == (
            True,
            False,
            True,
        )
        assert dvs.destinations[0].enable and dvs.destinations[0].layer == 0  # feeds core 0
        monitored = [c.monitor_enable for c in handle.applied[0].cnn_layers]
        assert monitored == [True, False, True] + [False] * 6  # DoG and grouping
        assert source.sensor_size == (128, 128, 2)
        # the pipeline on the same device does not apply it again (that would be the same
        # object here, but on a chip a second apply restarts it)
        chip = ChipPipeline(handle, dep, configured=True)
        chip.start()
        assert handle.applied == [dep.config] and len(handle._sinks) == 2
    finally:
        source.close()
    # with a readout: its fields written, and the pre-processed monitor instead of the raw one
    dep = deploy()
    readout = ReadoutParams()
    source = SpeckSource(SpeckParams(readout=readout), config=dep.config)
    source.start()
    try:
        dvs = source.device.applied[0].dvs_layer
        assert (dvs.raw_monitor_enable, dvs.monitor_enable) == (False, True)
        assert dvs.destinations[0].enable
    finally:
        source.close()


def test_a_configuration_for_another_chip_is_refused_before_it_is_applied(monkeypatch):
    forget_dynapcnn(monkeypatch)
    speck = FakeSpeck(events=np.zeros(0, EVENT_DTYPE))
    fake = install(monkeypatch, FakeSamna([("Speck2eDevKit", "e1", speck)]))
    dep = deploy()  # for speck2fmodule
    source = SpeckSource(config=dep.config)
    with pytest.raises(RuntimeError, match=r"not samna\.speck2e's SpeckConfiguration"):
        source.start()
    assert fake.handles == []  # the device was not opened


def test_spikes_outside_the_grid_are_an_error_not_dropped(fake):
    e = spike(fake, "speck2f", 2, 0, 64, 0, 0)
    with pytest.raises(ValueError, match="outside"):
        spike_counts([e], 2, (1, 64, 64))
    assert spike_counts([e], 1, (1, 64, 64)).sum() == 0  # another core's spike


def test_nothing_outside_hardware_imports_samna_or_the_dynapcnn_backend():
    banned = ("samna", "sinabs.backend.dynapcnn")
    for top in ("agents", "wander_env", "experiments"):
        for path in (ROOT / top).rglob("*.py"):
            tree = ast.parse(path.read_text(encoding="utf-8"))
            for node in ast.walk(tree):
                names = []
                if isinstance(node, ast.Import):
                    names = [a.name for a in node.names]
                elif isinstance(node, ast.ImportFrom) and node.module:
                    names = [node.module]
                bad = [n for n in names if n.split(".")[0] == "samna" or n.startswith(banned[1])]
                assert not bad, f"{path.relative_to(ROOT)} imports {bad}"
    code = (
        "import sys, agents.speck_front, agents.speck_limits, hardware.speck_network; "
        "assert 'samna' not in sys.modules; "
        "assert 'sinabs.backend.dynapcnn' not in sys.modules"
    )
    subprocess.run([sys.executable, "-c", code], cwd=ROOT, check=True, timeout=120)
