"""Signals that land in foreign code, in the video and in the finishing phase.

A signal handler that raises where the signal lands turns a SIGTERM inside a ctypes call
(EGL's ``eglMakeCurrent`` converting its arguments) into ``ctypes.ArgumentError``, kills
ffmpeg in the middle of ``run.mp4`` and cuts the writing of the run folder short. Inside
:class:`~experiments.runs.signals.DeferredSignals` a signal only sets a flag: the run loops
take it up between steps, finish the video and the folder, and exit with 128 + signal.
"""

from __future__ import annotations

import ctypes
import json
import os
import random
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import imageio_ffmpeg
import numpy as np
import pytest
import typer
from locations import ROOT
from typer.testing import CliRunner

from experiments.cli.errors import long_command
from experiments.cli.main import app
from experiments.jobs.run_agent import VIDEO_FPS
from experiments.runs.folder import RunFolder
from experiments.runs.recorders import video_frames
from experiments.runs.signals import DeferredSignals, SignalExit, handle_signals
from experiments.runs.video import VideoSink, mp4_complete
from experiments.runs.viewer import RRD_MAGIC
from hardware.rig_env import RigConfig
from wander_env.env_config import WanderConfig
from wander_env.events.io import OutputError, read_events

STOPPED = "SignalExit: stopped by SIGTERM (signal 15)"


def strict_json(path: Path) -> dict:
    def refuse(name: str) -> None:
        raise ValueError(f"{path}: {name} is not JSON")

    return json.loads(path.read_text(), parse_constant=refuse)


def frames_in(path: Path) -> int:
    """The frames ffmpeg decodes from ``path``, to its last one."""
    return imageio_ffmpeg.count_frames_and_secs(str(path))[0]


def exit_code_of(command: Callable[[], None]) -> int:
    """``command`` as a long command (``wander run``'s signal handling): its exit code."""
    wrapped = long_command("wander run")(command)
    with pytest.raises(typer.Exit) as info:
        wrapped()
    return info.value.exit_code


def self_signalling_abs(then: Callable[[], Any] | None = None) -> Any:
    """libc ``abs`` whose argument conversion (Python code run inside the ctypes call, as
    PyOpenGL's converters are for EGL) sends SIGTERM to this process and runs on until
    the signal's Python handler has run there (then calls ``then``, still inside)."""

    class SignalsWhileConverting:
        @classmethod
        def from_param(cls, value: int) -> ctypes.c_int:
            os.kill(os.getpid(), signal.SIGTERM)
            for _ in range(10_000):  # the handler runs at a bytecode boundary in here
                pass
            if then is not None:
                then()
            return ctypes.c_int(value)

    fn = ctypes.CDLL(None).abs
    fn.argtypes = [SignalsWhileConverting]
    fn.restype = ctypes.c_int
    return fn


# ----------------------------------------------------------------------------------------
# The mechanism


def test_a_signal_raised_inside_a_ctypes_call_comes_out_as_argument_error():
    """The fault of the issue, for reference: raising where the signal lands."""
    with pytest.raises(ctypes.ArgumentError, match="SignalExit"):
        with handle_signals():
            self_signalling_abs()(-3)


def test_a_deferred_signal_inside_a_ctypes_call_is_raised_between_steps():
    steps = []
    with pytest.raises(SignalExit) as info:
        with handle_signals(), DeferredSignals() as signals:
            for k in range(3):
                signals.check()
                steps.append(self_signalling_abs()(-k))  # the call itself completes
    assert steps == [0] and info.value.name == "SIGTERM"


def test_a_signal_after_the_loop_is_raised_when_the_block_has_finished_its_writes():
    written = []
    before = signal.getsignal(signal.SIGHUP)
    with pytest.raises(SignalExit) as info:
        with handle_signals(), DeferredSignals() as signals:
            os.kill(os.getpid(), signal.SIGHUP)  # lands while the "folder" is written
            for name in ("metrics.json", "scanpath.png", "run.json"):
                time.sleep(0.01)  # a wait does not raise it either
                written.append(name)
            assert signals.pending and signals.signum == signal.SIGHUP
    assert written == ["metrics.json", "scanpath.png", "run.json"]
    assert info.value.exit_code == 129
    assert signal.getsignal(signal.SIGHUP) is before  # both blocks restored it


def test_a_second_signal_wakes_a_wait_the_first_did_not(capfd):
    with pytest.raises(SignalExit) as info:
        with handle_signals(), DeferredSignals(wake_after_s=0.1) as signals:
            os.kill(os.getpid(), signal.SIGTERM)
            time.sleep(0.05)  # the first does not end a wait
            assert signals.pending
            sender = threading.Timer(0.1, os.kill, (os.getpid(), signal.SIGINT))
            sender.start()
            time.sleep(300)  # the second does
    assert info.value.name == "SIGTERM"  # the first is what stops the run
    assert capfd.readouterr().err == ""


def test_two_signals_back_to_back_inside_a_ctypes_call_stop_between_steps(capfd):
    def twice() -> None:  # the converter sends a second SIGTERM right after
        os.kill(os.getpid(), signal.SIGTERM)
        for _ in range(10_000):
            pass

    steps = []
    with pytest.raises(SignalExit) as info:
        with handle_signals(), DeferredSignals() as signals:
            for k in range(3):
                signals.check()
                steps.append(self_signalling_abs(then=twice)(-k))
    assert steps == [0] and info.value.name == "SIGTERM"
    assert signals.raised is info.value
    said = "SIGTERM: already stopping at the end of this step\n"
    assert capfd.readouterr().err == said


def test_the_episode_loop_reports_the_signal_that_foreign_code_turned_into_another_error():
    from experiments.runs.episode import run_episode

    class Env:
        def reset(self, seed=None):
            return 0, {}

        def step(self, action):
            os.kill(os.getpid(), signal.SIGTERM)  # the first: deferred
            self_signalling_abs()(-1)  # the second, raised in a ctypes call: ArgumentError
            return 0, 0.0, False, False, {}

    class Policy:
        def act(self, obs, info):
            return 0

    with pytest.raises(SignalExit) as info:
        with handle_signals(), DeferredSignals(wake_after_s=0.0) as signals:
            run_episode(Env(), Policy(), 5, signals=signals)
    assert info.value.name == "SIGTERM" and signals.raised is info.value


def test_a_second_signal_after_the_first_was_taken_up_is_reported_and_ignored(capfd):
    written = []
    with pytest.raises(SignalExit, match=r"^stopped by SIGTERM \(signal 15\)$"):
        with handle_signals(), DeferredSignals() as signals:
            os.kill(os.getpid(), signal.SIGTERM)
            try:
                signals.check()
            finally:  # the clean-up: a second signal does not cut it short
                os.kill(os.getpid(), signal.SIGTERM)
                time.sleep(0.01)
                written.append("metrics.json")
    assert written == ["metrics.json"]
    said = "SIGTERM: already shutting down (a third signal exits at once)\n"
    assert capfd.readouterr().err == said


def test_long_command_reports_a_signal_that_foreign_code_turned_into_another_error():
    assert exit_code_of(lambda: self_signalling_abs()(-3)) == 143


def test_long_command_reports_a_signal_that_foreign_code_dropped():
    def drops_it() -> None:
        try:
            self_signalling_abs()(-3)
        except ctypes.ArgumentError:  # as a library that logs and goes on would
            pass

    assert exit_code_of(drops_it) == 143


# ----------------------------------------------------------------------------------------
# The video


def test_a_video_whose_close_was_cut_short_is_marked_incomplete(tmp_path):
    path = tmp_path / "run.mp4"
    sink = VideoSink(path, fps=100, close_timeout_s=0.001)  # ffmpeg is ended at once
    rng = np.random.default_rng(0)
    for _ in range(40):  # large noise frames: libx264 is far from done when ffmpeg is ended
        sink.append(rng.integers(0, 256, (1024, 1024, 3), dtype=np.uint8))
    error = sink.finish(None)
    assert isinstance(error, OutputError) and "incomplete" in str(error)
    assert sink.complete is False and not mp4_complete(path)


# ----------------------------------------------------------------------------------------
# The run loop, in this process (many tries)


@pytest.fixture(scope="module")
def env_and_agent() -> Iterator[tuple[Any, Any]]:
    import gymnasium as gym

    import wander_env  # noqa: F401  (registers the environments)
    from agents.attention import AttentionAgent
    from experiments.jobs.run_agent import RunConfig

    config = RunConfig(WanderConfig(episode_seconds=2.0))
    env = gym.make("wander/Wander-v0", **config.env)
    agent = AttentionAgent(config.agent_params(env), seed=0)
    yield env, agent
    agent.close()
    env.close()


class RenderSignaller:
    """Sends SIGTERM from a thread to the main thread while that is inside EGL's
    ``eglMakeCurrent`` (the ctypes call of every render), converting its context argument:
    Python code that ctypes runs, where a raised exception comes out as
    ``ctypes.ArgumentError``. It happens at the ``at``-th call (of :meth:`arm`)."""

    def __init__(self, monkeypatch: pytest.MonkeyPatch) -> None:
        from mujoco.egl import egl_ext

        self.calls = 0
        self.at = 0
        self.go = threading.Event()
        self.sent = threading.Event()
        # PyOpenGL resolves the function on its first call into a ctypes function that it
        # calls from then on; load() resolves it (again) and returns that function.
        fn = egl_ext.eglMakeCurrent.load()
        *head, context_type = fn.argtypes
        signaller = self

        class Context:
            @classmethod
            def from_param(cls, value: Any) -> Any:
                signaller.calls += 1
                if signaller.calls == signaller.at:
                    signaller.go.set()
                    signaller.sent.wait(300)  # the signal lands in here, inside the call
                return context_type.from_param(value)

        monkeypatch.setattr(fn, "argtypes", (*head, Context))

    def arm(self, at: int) -> threading.Thread:
        self.calls, self.at = 0, at
        self.go.clear()
        self.sent.clear()
        main = threading.main_thread().ident

        def send() -> None:
            if self.go.wait(300):
                signal.pthread_kill(main, signal.SIGTERM)
                self.sent.set()

        thread = threading.Thread(target=send, daemon=True)
        thread.start()
        return thread


TRIES = 24


@pytest.mark.slow
def test_sigterm_sent_during_rendering_always_exits_143_with_the_folder_finished(
    tmp_path, monkeypatch, env_and_agent
):
    from experiments.jobs.run_agent import run_closed_loop

    env, agent = env_and_agent
    signaller = RenderSignaller(monkeypatch)
    rng = random.Random(27)
    stopped_at: list[int] = []
    for k in range(TRIES):
        out = tmp_path / f"try-{k}"
        sender = signaller.arm(at=rng.randint(1, 40))

        def job(out: Path = out, seed: int = k) -> None:
            run_closed_loop(env, agent, 2.0, out, {"command": "wander run"}, seed=seed)

        assert exit_code_of(job) == 143, k
        sender.join(60)
        assert signaller.sent.is_set()
        m = strict_json(out / "metrics.json")
        assert (m["signal"], m["error"]) == ("SIGTERM", STOPPED), k
        steps = m["steps"]  # 0 when it came while env.reset rendered
        assert steps < 200, k
        why = f"{STOPPED[12:]} after {steps} of 200 steps\n"
        assert (out / "INCOMPLETE").read_text() == why, k
        assert strict_json(out / "run.json")["summary"]["steps"] == steps
        assert "incomplete" not in read_events(out / "events.h5").metadata
        if steps:
            assert m["video_complete"] is True, k
            # the frames due at VIDEO_FPS a simulated second, to the last
            assert frames_in(out / "run.mp4") == video_frames(steps, 0.01, VIDEO_FPS), k
        else:
            assert "video_complete" not in m and not (out / "run.mp4").exists(), k
        stopped_at.append(steps)
    assert sum(s > 0 for s in stopped_at) >= TRIES // 2, stopped_at  # mostly mid-run


@pytest.mark.slow
def test_a_signal_while_the_run_folder_is_written_waits_for_run_json(
    tmp_path, monkeypatch, env_and_agent
):
    from experiments.jobs import run_agent

    env, agent = env_and_agent
    write_json = RunFolder.write_json

    def write_then_signal(folder: RunFolder, name: str, data: dict) -> Path:
        if name == "metrics.json":  # the first write of the finishing phase
            os.kill(os.getpid(), signal.SIGTERM)
        return write_json(folder, name, data)

    monkeypatch.setattr(RunFolder, "write_json", write_then_signal)
    out = tmp_path / "run"

    def job() -> None:
        run_agent.run_closed_loop(env, agent, 1.0, out, {"command": "wander run"}, seed=1)

    assert exit_code_of(job) == 143
    m = strict_json(out / "metrics.json")
    assert (m["steps"], m["signal"], m["error"]) == (100, "SIGTERM", STOPPED)
    assert {"run.json", "scanpath.png", "run.mp4", "events.h5", "INCOMPLETE"} <= {
        p.name for p in out.iterdir()
    }
    assert (out / "INCOMPLETE").read_text() == (
        f"{STOPPED[12:]} while the run folder was written, after the run's 100 steps; "
        "every file was finished\n"
    )
    assert strict_json(out / "run.json")["summary"]["steps"] == 100
    assert read_events(out / "events.h5").metadata["summary"]["steps"] == 100
    assert frames_in(out / "run.mp4") == video_frames(100, 0.01, VIDEO_FPS) == VIDEO_FPS


# ----------------------------------------------------------------------------------------
# wander record


@pytest.mark.slow
def test_record_stopped_during_rendering_finishes_its_video(tmp_path, monkeypatch):
    from experiments.jobs.record import RecordConfig, record

    signaller = RenderSignaller(monkeypatch)
    out = tmp_path / "rec"
    sender = signaller.arm(at=30)
    assert exit_code_of(lambda: record(out, RecordConfig(WanderConfig(episode_seconds=1.0)))) == 143
    sender.join(60)
    assert signaller.sent.is_set()
    m = strict_json(out / "metrics.json")
    assert (m["signal"], m["error"]) == ("SIGTERM", STOPPED)
    assert 0 < m["steps"] < 100 and m["video_complete"] is True
    assert (out / "INCOMPLETE").read_text() == f"{STOPPED[12:]} after {m['steps']} of 100 steps\n"
    assert strict_json(out / "run.json")["summary"]["steps"] == m["steps"]
    assert frames_in(out / "video.mp4") == m["steps"]


@pytest.mark.slow
def test_record_signalled_before_run_json_still_writes_it(tmp_path, monkeypatch):
    from experiments.jobs import record as record_job

    write_json = RunFolder.write_json

    def signal_then_write(folder: RunFolder, name: str, data: dict) -> Path:
        os.kill(os.getpid(), signal.SIGTERM)  # lands just before run.json is written
        return write_json(folder, name, data)

    monkeypatch.setattr(RunFolder, "write_json", signal_then_write)
    out = tmp_path / "rec"
    config = record_job.RecordConfig(WanderConfig(episode_seconds=0.3), video=False)
    assert exit_code_of(lambda: record_job.record(out, config)) == 143
    assert strict_json(out / "run.json")["summary"]["steps"] == 30
    m = strict_json(out / "metrics.json")
    assert (m["signal"], m["error"]) == ("SIGTERM", STOPPED)
    assert (out / "INCOMPLETE").read_text() == (
        f"{STOPPED[12:]} while the folder was written, after the recording's 30 steps; "
        "every file was finished\n"
    )


# ----------------------------------------------------------------------------------------
# The CLI


@pytest.mark.slow
def test_wander_run_stopped_by_sigterm_leaves_a_playable_video(tmp_path):
    out = tmp_path / "run"
    env = {**os.environ, "PYTHONPATH": str(ROOT), "MUJOCO_GL": "egl"}
    code = "import sys; from experiments.cli.main import app; sys.argv[0] = 'wander'; app()"
    proc = subprocess.Popen(
        [sys.executable, "-c", code, "run", "--seconds", "20", "--out", str(out)],
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    deadline = time.monotonic() + 300
    while not (out / "run.mp4").exists():  # the first frame went to ffmpeg: the loop runs
        assert proc.poll() is None, proc.communicate()
        assert time.monotonic() < deadline, "the run did not start"
        time.sleep(0.1)
    time.sleep(2.0)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=240)
    assert proc.returncode == 143, err
    assert err.splitlines()[-1] == (
        f"wander run: stopped by SIGTERM (signal 15); '{out}' holds what was recorded"
    )
    m = strict_json(out / "metrics.json")
    assert m["signal"] == "SIGTERM" and m["video_complete"] is True
    assert frames_in(out / "run.mp4") == video_frames(m["steps"], 0.01, VIDEO_FPS) > 0


def test_view_without_a_display_prints_the_web_viewer_command_and_the_copy_hint(tmp_path):
    (tmp_path / "run.rrd").write_bytes(RRD_MAGIC + b"2")  # the viewer reads the rest
    rrd = (tmp_path / "run.rrd").resolve()
    result = CliRunner().invoke(
        app, ["view", str(tmp_path)], env={"DISPLAY": "", "WAYLAND_DISPLAY": ""}
    )
    assert result.exit_code == 0, result.output
    lines = result.stdout.splitlines()
    assert len(lines) == 2 and lines[0].endswith(f" {rrd}")
    assert lines[1] == lines[0].replace(f" {rrd}", f" --web-viewer {rrd}")
    assert result.stderr.splitlines() == [
        "no display (DISPLAY unset); open the recording with:",
        "or in a browser (the viewer prints the address to open):",
        f"or copy {rrd} to a machine with a display and open it there with: rerun run.rrd",
    ]


# ----------------------------------------------------------------------------------------
# wander rig


@pytest.mark.slow
def test_a_signal_halts_the_rig_before_its_folder_is_written(tmp_path, monkeypatch):
    from experiments.jobs.rig import RigRunConfig, run_rig
    from hardware.ptu_emulator import PTUEmulator
    from wander_env.events import make_events
    from wander_env.events.io import EventRecording, write_events

    rng = np.random.default_rng(0)
    n = 30_000
    t = np.sort(rng.integers(0, 3_000_000, n))
    events = make_events(rng.integers(60, 70, n), rng.integers(60, 70, n), t, rng.integers(0, 2, n))
    write_events(tmp_path / "walk.npz", EventRecording(events, (128, 128, 2)))
    halts_when_written: list[int] = []
    write_json = RunFolder.write_json
    with PTUEmulator() as emu:

        def noting(folder: RunFolder, name: str, data: dict) -> Path:
            if name == "metrics.json":
                halts_when_written.append(emu.commands.count("H"))
            return write_json(folder, name, data)

        def stop_at_step_20(k: int, total: int) -> None:
            if k == 20:
                os.kill(os.getpid(), signal.SIGTERM)

        monkeypatch.setattr(RunFolder, "write_json", noting)
        out = tmp_path / "rig"
        config = RigRunConfig(
            RigConfig(ptu_port=emu.port, camera=f"replay:{tmp_path / 'walk.npz'}"), video=False
        )
        assert exit_code_of(lambda: run_rig(out, config, progress=stop_at_step_20)) == 143
    # halted as the loop stopped, before the folder (metrics.json holds the rig's counters)
    assert halts_when_written == [1]
    m = strict_json(out / "metrics.json")
    assert (m["steps"], m["signal"], m["error"]) == (20, "SIGTERM", STOPPED)
    assert m["rig"]["ptu_halt"] == "halt (H) acknowledged"
    assert (out / "INCOMPLETE").read_text() == f"{STOPPED[12:]} after 20 of 1000 steps\n"
