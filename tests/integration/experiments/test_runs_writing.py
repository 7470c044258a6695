"""A run's files off the step's critical path (:class:`experiments.runs.recorders.Writer`,
:class:`~experiments.runs.recorders.WriteParams`): the same ``events.h5`` and ``run.rrd``
with and without batches and the writer thread; the video at the chosen rate; a write
that fails on the thread is the run's one error, with the folder finished."""

from __future__ import annotations

import json
from pathlib import Path

import gymnasium as gym
import imageio.v2 as imageio
import numpy as np
import pytest
from typer.testing import CliRunner

import wander_env  # noqa: F401  (registers the environments)
from agents.attention import AgentParams, AttentionAgent
from experiments.cli.main import app
from experiments.cli.run import MAX_VIDEO_FPS
from experiments.jobs.run_agent import RunConfig, run_closed_loop
from experiments.runs.recorders import WriteParams, Writer, video_frames
from experiments.runs.viewer import read_recording
from wander_env.events.io import read_events
from wander_env.events.stream import EventStreamWriter, OutputError


def _run(out: Path, writing: WriteParams, seed: int = 3) -> dict:
    env = gym.make("wander/Wander-v0", scene="office", episode_seconds=2.0)
    agent = AttentionAgent(AgentParams.for_env(env, window_s=0.05), seed=seed)
    try:
        result = run_closed_loop(
            env, agent, 0.5, out, {"seed": seed}, video=False, seed=seed, writing=writing
        )
    finally:
        agent.close()
        env.close()
    return result.metrics


@pytest.mark.slow
def test_batches_on_the_writer_thread_write_the_same_events_and_rerun_log(tmp_path):
    inline = _run(tmp_path / "inline", WriteParams(threaded=False, batch_s=0.0))
    # batches of 7 steps, or of 500 events when those come first; a queue of 2 writes
    batched = _run(tmp_path / "batched", WriteParams(batch_s=0.07, batch_events=500, queue_jobs=2))
    assert inline["steps"] == batched["steps"] == 50 and inline["events"] > 500
    a, b = read_events(tmp_path / "inline/events.h5"), read_events(tmp_path / "batched/events.h5")
    assert np.array_equal(a.events, b.events) and len(a.events) == inline["events"]
    assert a.metadata == b.metadata and a.metadata["summary"] == {
        "steps": 50,
        "events": len(a.events),
    }
    ra, rb = (
        read_recording(tmp_path / "inline/run.rrd"),
        read_recording(tmp_path / "batched/run.rrd"),
    )
    assert ra.keys() == rb.keys() and len(ra[("/events", "SegmentationImage:buffer")]) == 50
    for key in ra:
        assert ra[key] == rb[key], key
    drop = ("wall_s", "real_time_factor")
    assert {k: v for k, v in inline.items() if k not in drop} == {
        k: v for k, v in batched.items() if k not in drop
    }


def test_wander_run_writes_the_video_at_the_chosen_rate(tmp_path):
    out = tmp_path / "run"
    args = ["run", "--out", str(out), "--seconds", "0.5", "--video-fps", "25", "--scene", "shelf"]
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 0, result.output
    m = json.loads((out / "metrics.json").read_text())
    assert m["steps"] == 50 and m["video_complete"] is True
    reader = imageio.get_reader(out / "run.mp4")
    try:
        assert reader.get_meta_data()["fps"] == 25.0
        assert reader.count_frames() == video_frames(50, 0.01, 25) == 13
    finally:
        reader.close()


def test_a_bad_video_rate_is_one_line_before_anything_runs(tmp_path):
    result = CliRunner().invoke(app, ["run", "--video-fps", "0", "--out", str(tmp_path / "r")])
    assert result.exit_code == 2 and "'--video-fps'" in result.output
    assert "must be 1 to 1000 frames a second, got 0" in result.output
    assert not (tmp_path / "r").exists()
    # the config's bound is the flag's
    assert RunConfig(video_fps=MAX_VIDEO_FPS).video_fps == MAX_VIDEO_FPS == 1000
    with pytest.raises(ValueError, match=r"^video_fps: .*1000, got 1001$"):
        RunConfig(video_fps=MAX_VIDEO_FPS + 1)
    # and its default the one the flag's help names
    help_text = " ".join(
        CliRunner().invoke(app, ["run", "--help"]).output.replace("│", " ").split()
    )
    assert RunConfig().video_fps == 25 and "default: the config's, 25)" in help_text


def test_a_write_that_fails_on_the_thread_is_the_runs_error_and_the_folder_is_finished(
    tmp_path, monkeypatch
):
    append = EventStreamWriter.append
    calls = []

    def full_at_the_third(self, events):
        calls.append(len(events))
        if len(calls) == 3:
            raise OutputError(self.path, OSError(28, "No space left on device"))
        append(self, events)

    monkeypatch.setattr(EventStreamWriter, "append", full_at_the_third)
    out = tmp_path / "run"
    with pytest.raises(OutputError, match=r"cannot write .*events\.h5: No space left on device$"):
        _run(out, WriteParams(batch_s=0.05))
    m = json.loads((out / "metrics.json").read_text())
    # raised in the loop at a write after it (or, the thread that far behind, at the close)
    assert m["error"].startswith("OutputError: cannot write") and m["steps"] >= 10
    assert json.loads((out / "run.json").read_text())["summary"]["steps"] == m["steps"]


def test_the_writer_runs_jobs_in_order_and_hands_back_the_first_error():
    done: list[int] = []
    writer = Writer(jobs=1)
    for k in range(5):
        writer.submit(lambda k=k: done.append(k))
    assert writer.close(None) is None and done == [0, 1, 2, 3, 4]

    def fail() -> None:
        raise ValueError("first")

    writer = Writer(jobs=4)
    writer.submit(fail)
    writer.submit(lambda: done.append(5))  # still runs: files get closed after a failure
    error = writer.close(None)
    assert isinstance(error, ValueError) and str(error) == "first" and done[-1] == 5
    writer = Writer()
    writer.submit(fail)
    loop_error = KeyError("loop")
    assert writer.close(loop_error) is loop_error  # the loop's own error comes first
