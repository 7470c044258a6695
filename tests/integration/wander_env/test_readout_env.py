"""The readout in the env: off, events are bit-identical to the DVS's; on, its counters
are in ``info["readout"]``; the config field takes None, a preset or a block."""

import hashlib

import gymnasium
import numpy as np
import pytest

import wander_env  # noqa: F401  (registers the envs)
from wander_env.config import ConfigError, validate
from wander_env.env_config import WanderConfig
from wander_env.readout import COUNTERS, LOST, ReadoutParams


def _run(readout) -> tuple[str, list[dict]]:
    env = gymnasium.make("wander/Wander-v0", scene="shelf", ground_truth=False, readout=readout)
    try:
        _, info = env.reset(seed=0)
        digest, counts = hashlib.sha256(), [info.get("readout")]
        for action in ([0.4, -0.3], [0.0, 0.0], [0.0, 0.0]):
            obs, _, _, _, info = env.step(np.array(action, np.float32))
            ev = info["events"].events
            digest.update(ev.tobytes())
            digest.update(obs["events"].tobytes())
            counts.append(info.get("readout"))
        return digest.hexdigest(), counts
    finally:
        env.close()


def test_readout_off_leaves_the_events_bit_identical():
    none, counts_none = _run(None)
    off, counts_off = _run(ReadoutParams())
    ideal, _ = _run("ideal")
    assert none == off == ideal
    assert counts_none == [None] * 4
    assert counts_off[0] == dict.fromkeys(COUNTERS, 0)
    assert all(c["in"] == c["out"] > 0 for c in counts_off[1:])


def test_readout_counters_reach_info():
    params = ReadoutParams(throughput_eps=2e5, queue_depth=16)
    _, counts = _run(params)
    step = counts[1]
    assert list(step) == list(COUNTERS)
    assert step["dropped_queue"] > 0
    pending = 0
    for c in counts[1:]:
        assert all(isinstance(v, int) for v in c.values())
        # every event accounted for; only the queue loses any (the rest is off)
        assert c["in"] == c["out"] + c["dropped_queue"] + c["pending"] - pending
        assert [c[k] for k in LOST if k != "dropped_queue"] == [0] * (len(LOST) - 1)
        assert c["pending"] <= 16 and c["out"] <= 2000  # queue_depth; 2e5 ev/s for 10 ms
        pending = c["pending"]
    # the saccade's events fill the queue: the last two steps deliver at the full rate
    assert [c["out"] for c in counts[2:]] == [2000, 2000]


def test_the_config_field_takes_none_a_preset_or_a_block():
    assert WanderConfig().readout is None and WanderConfig().readout_params is None
    assert WanderConfig(readout="speck").readout_params == ReadoutParams.preset("speck")
    cfg = validate(
        WanderConfig,
        {"readout": {"dvs_layer": {"pooling": [2, 2]}, "dvs_filter": {"enable": True}}},
    )
    assert cfg.readout_params.dvs_layer.pooling == (2, 2)
    assert cfg.readout_params.dvs_filter.enable
    with pytest.raises(ValueError, match="unknown readout preset 'fast'"):
        WanderConfig(readout="fast")
    with pytest.raises(
        ConfigError,
        match=r"c\.yaml: readout\.dvs_layer\.pooling\[0\]: expected one of 1, 2, 4, got 3",
    ):
        validate(WanderConfig, {"readout": {"dvs_layer": {"pooling": [3, 1]}}}, where="c.yaml")
