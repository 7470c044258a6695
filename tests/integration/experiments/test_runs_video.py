"""The run's video writer (experiments.runs.video): the frames it is given, its refusals, a hung
or signalled ffmpeg."""

from __future__ import annotations

import signal
from pathlib import Path

import imageio_ffmpeg
import numpy as np
import pytest
from polling import wait_until

from experiments.runs.signals import SignalExit
from experiments.runs.video import VideoSink
from wander_env.events.io import OutputError


def test_video_sink_writes_the_frames_it_is_given(tmp_path):
    import imageio.v2 as imageio

    path = tmp_path / "v.mp4"
    sink = VideoSink(path, fps=10)
    for k in range(5):
        sink.append(np.full((24, 32, 3), 40 * k, np.uint8))
    assert sink.finish(None) is None
    frames = imageio.mimread(path, memtest=False)
    assert len(frames) == 5 and frames[0].shape == (24, 32, 3)
    assert [int(np.median(f)) for f in frames] == pytest.approx([0, 40, 80, 120, 160], abs=3)
    # encoded with libx264's "ultrafast" preset at CRF 28 (x264 writes its options into the
    # stream): no CABAC, diamond search, no subpixel refinement (its default: CABAC, hex, 7)
    options = path.read_bytes().split(b"options: ", 1)[1].split(b"\x00", 1)[0]
    assert b"cabac=0 " in options and b" me=dia subme=0 " in options
    assert b" crf=28.0 " in options


def test_video_sink_refuses_a_frame_of_another_size_or_type(tmp_path):
    sink = VideoSink(tmp_path / "v.mp4", fps=10)
    sink.append(np.zeros((16, 16, 3), np.uint8))
    with pytest.raises(ValueError, match=r"v.mp4: frame of 32x16 px after frames of 16x16 px"):
        sink.append(np.zeros((16, 32, 3), np.uint8))
    with pytest.raises(ValueError, match=r"must be \(H, W, 3\) uint8, got \(16, 16, 3\) float64"):
        sink.append(np.zeros((16, 16, 3)))
    with pytest.raises(ValueError, match=r"v.mp4: .*width and height must be even .*got 17x15 px"):
        VideoSink(tmp_path / "v.mp4", fps=10).append(np.zeros((15, 17, 3), np.uint8))
    assert sink.finish(None) is None


def test_a_hung_ffmpeg_is_ended_after_the_close_timeout_and_the_video_named(tmp_path, monkeypatch):
    """ffmpeg that never exits (here a stand-in that reads its input, then sleeps): the
    close gives up after close_timeout_s and says the video is incomplete."""
    fake = tmp_path / "ffmpeg"
    pid_file = tmp_path / "ffmpeg.pid"
    real = imageio_ffmpeg.get_ffmpeg_exe()  # answers imageio's probes for an H.264 encoder
    fake.write_text(
        f'#!/bin/sh\ncase "$*" in *-encoders*|*" null "*) exec {real} "$@";; esac\n'
        f"echo $$ > {pid_file}\ncat > /dev/null\nexec sleep 600\n"
    )
    fake.chmod(0o755)
    monkeypatch.setenv("IMAGEIO_FFMPEG_EXE", str(fake))
    sink = VideoSink(tmp_path / "v.mp4", fps=10, close_timeout_s=1.0)
    sink.append(np.zeros((16, 16, 3), np.uint8))
    err = sink.finish(None)
    # Killed, not waited for (its sleep would last 10 minutes): soon gone, or a zombie.
    stat = Path(f"/proc/{int(pid_file.read_text())}/stat")

    def ended() -> bool:
        try:
            return stat.read_text().rsplit(")", 1)[1].split()[0] == "Z"
        except FileNotFoundError:
            return True

    assert wait_until(ended)
    assert isinstance(err, OutputError)
    assert str(err) == (
        f"cannot write {tmp_path / 'v.mp4'}: ffmpeg did not finish the video within 1 s and "
        "was ended; the file is incomplete"
    )
    run_error = RuntimeError("the run's own")
    assert VideoSink(tmp_path / "w.mp4", fps=10).finish(run_error) is run_error  # no frames


def test_a_signal_while_the_video_closes_is_handed_back_not_raised(tmp_path):
    class SignalledClose:
        def close(self):
            raise SignalExit(signal.SIGTERM)

    sink = VideoSink(tmp_path / "v.mp4", fps=10)
    sink._frames = SignalledClose()  # a SIGTERM lands while ffmpeg finishes the file
    err = sink.finish(None)
    assert isinstance(err, SignalExit) and err.name == "SIGTERM"
