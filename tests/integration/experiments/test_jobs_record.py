"""``wander record``: the folder it writes and what is in it."""

from __future__ import annotations

import json

import h5py
import imageio.v2 as imageio
import numpy as np
import pytest

from experiments.jobs.record import RecordConfig, record
from wander_env.env_config import WanderConfig
from wander_env.events.io import read_events


def test_record_writes_events_truth_and_video(tmp_path):
    summary = record(
        tmp_path,
        RecordConfig(WanderConfig(scene="office", episode_seconds=0.2), policy="fixational"),
    )
    assert sorted(summary["files"]) == [
        "events.h5",
        "ground_truth.h5",
        "run.json",
        "run.rrd",
        "video.mp4",
    ]
    rec = read_events(tmp_path / "events.h5")
    assert len(rec.events) == summary["events"] > 0
    assert rec.events["t"].max() <= 200_000
    with h5py.File(tmp_path / "ground_truth.h5") as f:
        assert f["object_mask"].shape == (20, 128, 128)
        assert f["t"][-1] == pytest.approx(0.2)
        ids = np.unique(f["object_mask"][()])
        assert set(ids.tolist()) <= {0, 1, 2}
        masks, pixels = f["object_mask"][()], f["object_mask_pixels"][()]
        for k in (1, 2):
            assert np.array_equal(pixels[:, k - 1], (masks == k).sum(axis=(1, 2)))
    assert len(imageio.mimread(tmp_path / "video.mp4")) == 20
    run = json.loads((tmp_path / "run.json").read_text())
    assert run["config"]["policy"] == "fixational" and run["seed"] == 0


def test_fixational_policy_moves_the_gaze_within_its_range(tmp_path):
    record(
        tmp_path,
        RecordConfig(
            WanderConfig(scene="shelf", episode_seconds=0.3), policy="fixational", video=False
        ),
    )
    with h5py.File(tmp_path / "ground_truth.h5") as f:
        pos = f["ptu_positions"][()]
    assert np.abs(pos).max() > 0  # it moved
    assert np.abs(pos).max() <= 8 * 60  # at most N steps of 60 positions from the start


def test_unknown_policy_is_named():
    with pytest.raises(
        ValueError,
        match=r"^policy: expected one of .still., .fixational., .saccades., got .wander.$",
    ):
        RecordConfig(policy="wander")
