"""`wander rig` with a readout: SpeckSource writes the readout's samna fields to the chip's
configuration, clocks the filter, and reads the DVS layer's pre-processed events (the fake
samna of tests/fake_samna.py)."""

from __future__ import annotations

import time

import numpy as np
import pytest
from fake_samna import FakeSamna, FakeSpeck, install
from polling import LIMIT_S

from hardware.speck import SpeckParams, SpeckSource
from hardware.speck_config import write_readout_config
from wander_env.config import validate
from wander_env.events import EVENT_DTYPE
from wander_env.readout import DvsFilterParams, DvsLayerParams, ReadoutParams

READOUT = ReadoutParams(
    dvs_layer=DvsLayerParams(
        origin=(16, 8),
        cut=(111, 119),
        mirror=(True, False),
        mirror_diagonal=True,
        merge=False,
        off_channel=False,
    ),
    dvs_filter=DvsFilterParams(
        enable=True, filter_size=(5, 3), hot_pixel_filter_enable=True, threshold=7
    ),
    slow_clk_rate_hz=2000,
)


def _events(n: int = 400) -> np.ndarray:
    rng = np.random.default_rng(3)
    ev = np.empty(n, EVENT_DTYPE)
    # inside the readout's output grid (112 wide, 96 high): the fake does not process them
    ev["x"], ev["y"], ev["p"] = (
        rng.integers(0, 112, n),
        rng.integers(0, 96, n),
        rng.integers(0, 2, n),
    )
    ev["t"] = np.sort(rng.integers(1_000, 100_000, n))
    return ev


@pytest.fixture
def fake(monkeypatch) -> FakeSamna:
    speck = FakeSpeck(_events(), speed=5.0, other_every=50)
    return install(monkeypatch, FakeSamna([("Speck2fDevKit", "sf-1", speck)]))


def test_the_readouts_samna_fields_are_written_and_the_filter_clocked(fake):
    with SpeckSource(readout=READOUT) as src:
        handle = fake.handles[-1]
        config = handle.applied[-1]
        dvs, filt = config.dvs_layer, config.dvs_filter
        assert (dvs.origin.x, dvs.origin.y, dvs.cut.x, dvs.cut.y) == (16, 8, 111, 119)
        assert (dvs.pooling.x, dvs.pooling.y) == (1, 1)
        assert (dvs.mirror.x, dvs.mirror.y, dvs.mirror_diagonal) == (True, False, True)
        assert (dvs.merge, dvs.on_channel, dvs.off_channel) == (False, True, False)
        assert (filt.enable, filt.hot_pixel_filter_enable, filt.low_pass_mode_enable) == (
            True,
            True,
            False,
        )
        assert (filt.filter_size.x, filt.filter_size.y, filt.threshold) == (5, 3, 7)
        # the pre-processed stream, not the raw one; no core fed, none monitored
        assert dvs.monitor_enable is True and dvs.raw_monitor_enable is False
        assert not any(d.enable for d in dvs.destinations)
        assert (handle.get_io_module().slow_clock, handle.get_io_module().slow_clk_rate) == (
            True,
            2000,
        )
        # the region, swapped by mirror_diagonal: 96 wide, 112 high -> (112, 96)
        assert src.sensor_size == (112, 96, 2)


def test_the_dvs_layers_spikes_are_read_as_events(fake):
    events = _events()
    with SpeckSource(readout=READOUT, latency_margin_us=200_000) as src:
        t_end, got = time.monotonic() + LIMIT_S, []
        while sum(map(len, got)) < len(events) and time.monotonic() < t_end:
            got.append(src.read(duration_us=20_000))
        stats = src.stats
    got = np.concatenate(got)
    # the fake passes events through unprocessed, as Spike(layer 13, feature = p)
    for f in ("x", "y", "t", "p"):
        assert np.array_equal(got[f], events[f]), f
    assert stats["other_events"] == {"Spike": 8, "ReadoutPinValue": 2}  # layer-2 spikes etc.
    assert stats["out_of_range"] == 0 and stats["received"] == len(events)


def test_raw_stream_without_a_readout(fake):
    with SpeckSource():
        config = fake.handles[-1].applied[-1]
        assert config.dvs_layer.raw_monitor_enable and not config.dvs_layer.monitor_enable
        assert config.dvs_filter.enable is False
        assert fake.handles[-1].get_io_module().slow_clock is False


def test_what_the_chip_cannot_show_is_refused():
    with pytest.raises(ValueError, match=r"readout.dvs_layer.pooling: \(2, 2\) is not shown"):
        SpeckParams(readout=ReadoutParams(dvs_layer=DvsLayerParams(pooling=(2, 2))))
    with pytest.raises(ValueError, match=r"readout\.kill_pixels: the kill bits have no public"):
        SpeckParams(readout=ReadoutParams(kill_pixels=((1, 2),)))


def test_one_readout_block_configures_the_sim_and_the_chip():
    block = {"dvs_layer": {"origin": [4, 4], "cut": [99, 99]}, "dvs_filter": {"enable": True}}
    sim = validate(ReadoutParams, block)
    rig = validate(SpeckParams, {"readout": block}).readout
    assert sim == rig

    class _Cfg:  # write_readout_config on a samna-shaped object
        def __init__(self) -> None:
            from fake_samna import DvsFilterConfig, DvsLayerConfig

            self.dvs_layer, self.dvs_filter = DvsLayerConfig(), DvsFilterConfig()

    cfg = _Cfg()
    write_readout_config(cfg, sim)
    assert (cfg.dvs_layer.cut.x, cfg.dvs_filter.enable) == (99, True)
