"""``run.rrd`` and ``wander view``: the recording read back with Rerun's own reader."""

from __future__ import annotations

import io
from pathlib import Path

import h5py
import numpy as np
import pytest
from PIL import Image

from experiments.jobs.record import RecordConfig, record
from experiments.runs.viewer import RRD_MAGIC, RunLog, view
from experiments.runs.viewer import read_recording as read_rrd
from wander_env.env_config import WanderConfig
from wander_env.events import time_window, to_frame
from wander_env.events.io import read_events
from wander_env.viz import polarity_codes


def labels(value: object) -> np.ndarray:
    return np.asarray(value[0], dtype=np.uint8).reshape(128, 128)


@pytest.fixture(scope="module")
def recorded(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("record")
    record(
        out,
        RecordConfig(
            WanderConfig(scene="office", episode_seconds=0.3), policy="fixational", video=False
        ),
    )
    return out


def test_record_rrd_holds_every_step_exactly(recorded: Path) -> None:
    data = read_rrd(recorded / "run.rrd")
    with h5py.File(recorded / "ground_truth.h5") as f:
        t_s, gaze, mask = f["t"][()], f["gaze_deg"][()], f["object_mask"][()]
    steps = len(t_s)
    assert steps == 30
    t_ns = [round(t * 1e9) for t in t_s]
    # Time series: one value per step, the step's gaze, on the simulated-time timeline.
    for axis, col in (("pan", 0), ("tilt", 1)):
        rows = data[(f"/gaze/{axis}", "Scalars:scalars")]
        assert [t for t, _ in rows] == t_ns
        assert [v[0] for _, v in rows] == [float(g) for g in gaze[:, col]]
        assert len(data[(f"/ptu_target/{axis}", "Scalars:scalars")]) == steps
    # Object masks, exactly those of ground_truth.h5.
    masks = data[("/object_mask", "SegmentationImage:buffer")]
    assert len(masks) == steps
    for k, (_, v) in enumerate(masks):
        assert np.array_equal(labels(v), mask[k])
    # Event frames: each step's events (t_{k-1}, t_k] as 0 none / 1 OFF / 2 ON.
    rec = read_events(recorded / "events.h5")
    frames = data[("/events", "SegmentationImage:buffer")]
    assert len(frames) == steps
    edges_us = [0, *[round(t * 1e6) for t in t_s]]
    for k, (_, v) in enumerate(frames):
        window = time_window(rec.events, edges_us[k] + 1, edges_us[k + 1] + 1)
        assert np.array_equal(labels(v), polarity_codes(to_frame(window, rec.sensor_size)))
    assert sum(int((labels(v) > 0).sum()) for _, v in frames) > 0
    # The camera: a JPEG per step that decodes to the sensor's size.
    cams = data[("/camera", "EncodedImage:blob")]
    assert [t for t, _ in cams] == t_ns
    image = Image.open(io.BytesIO(bytes(cams[0][1][0])))
    assert image.size == (128, 128) and image.mode == "RGB"


def test_decisions_and_annotations_round_trip(tmp_path: Path) -> None:
    log = RunLog(tmp_path / "run.rrd", object_names=["ball"])
    saliency = np.zeros((128, 128), np.float32)
    saliency[40, 90] = 0.75
    log.steps([0.01], gaze_deg=[(1.5, -2.25)])
    log.decision(0.13, saliency, (90, 40))
    log.annotate(0.13, "fixation 0")
    log.decision(0.50, saliency * 0, None)
    log.close()
    log.close()  # idempotent
    data = read_rrd(tmp_path / "run.rrd")
    assert data[("/gaze/pan", "Scalars:scalars")] == [(10_000_000, [1.5])]
    assert data[("/gaze/tilt", "Scalars:scalars")] == [(10_000_000, [-2.25])]
    maps = data[("/saliency", "Image:buffer")]
    assert [t for t, _ in maps] == [130_000_000, 500_000_000]
    first = np.frombuffer(bytes(maps[0][1][0]), np.float32).reshape(128, 128)
    assert np.array_equal(first, saliency)
    assert data[("/saliency/P", "Boxes2D:centers")] == [(130_000_000, [[90.0, 40.0]])]
    assert data[("/annotations", "TextLog:text")] == [(130_000_000, ["fixation 0"])]


def test_view_prints_the_command_headless_and_spawns_with_a_display(tmp_path, monkeypatch):
    (tmp_path / "run.rrd").write_bytes(RRD_MAGIC + b"2")  # the viewer reads the rest
    what, command = view(tmp_path, env={})
    assert what == "headless" and command[-1] == str((tmp_path / "run.rrd").resolve())
    started = []
    monkeypatch.setattr("subprocess.Popen", lambda cmd, **kw: started.append((cmd, kw)))
    what, command = view(tmp_path, env={"DISPLAY": ":0"})
    assert what == "spawned" and started[0][0] == command
    assert started[0][1]["env"]["DISPLAY"] == ":0"
    with pytest.raises(FileNotFoundError, match=r"no run\.rrd in"):
        view(tmp_path / "empty", env={})


def test_view_refuses_what_it_cannot_open_in_one_line(tmp_path, monkeypatch):
    """Empty, not a recording, a folder, unreadable: each a one-line ValueError naming the
    file, before a viewer is started (tests run as root: a read that fails is made so)."""
    from experiments.runs import viewer

    rrd = tmp_path / "run.rrd"
    rrd.write_bytes(b"")
    with pytest.raises(ValueError, match=rf"^'{rrd}' is empty: the run wrote no recording$"):
        view(tmp_path, env={})
    rrd.write_bytes(b"PK\x03\x04")
    with pytest.raises(ValueError, match=r"is not a Rerun recording: it starts with b'PK\\x03'"):
        view(tmp_path, env={})
    rrd.write_bytes(RRD_MAGIC + b"2")

    def denied(*args, **kwargs):
        raise PermissionError(13, "Permission denied", str(rrd))

    monkeypatch.setattr(viewer, "open", denied, raising=False)
    with pytest.raises(ValueError, match=rf"^cannot read '{rrd}': Permission denied$"):
        view(tmp_path, env={})
    monkeypatch.undo()
    rrd.unlink()
    rrd.mkdir()
    with pytest.raises(ValueError, match=rf"^'{rrd}' is not a regular file$"):
        view(tmp_path, env={})
