"""Fault injection, signals: SIGTERM, SIGHUP, SIGINT and SIGKILL sent to a running CLI.

Each long command (here ``wander run``, ``wander rig``, ``wander record``) must halt,
flush and close its files, write ``metrics.json`` (strict JSON) naming the signal and
exit with 128 + the signal; after SIGKILL the streamed ``events.h5`` is still readable
up to its last flushed chunk and says where it stops. A crash in native code prints every
thread's Python stack.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from locations import ROOT

from experiments.runs.folder import RunFolder
from experiments.runs.signals import SignalExit, handle_signals
from wander_env.env_config import WanderConfig
from wander_env.events import make_events
from wander_env.events.io import EventRecording, read_events, write_events


def strict_json(path: Path) -> dict:
    def refuse(name: str) -> None:
        raise ValueError(f"{path}: {name} is not JSON")

    return json.loads(path.read_text(), parse_constant=refuse)


@pytest.mark.parametrize(
    ("sig", "code"), [(signal.SIGINT, 130), (signal.SIGTERM, 143), (signal.SIGHUP, 129)]
)
def test_each_signal_raises_signal_exit_and_handlers_come_back(sig, code):
    before = signal.getsignal(sig)
    with pytest.raises(SignalExit) as info:
        with handle_signals():
            os.kill(os.getpid(), sig)
            for _ in range(1000):  # the handler runs at the next bytecode
                time.sleep(0.01)
    assert (info.value.signum, info.value.exit_code) == (sig, code)
    assert info.value.name == signal.Signals(sig).name
    assert isinstance(info.value, KeyboardInterrupt)  # the Ctrl-C clean-up paths apply
    assert signal.getsignal(sig) is before


def test_a_signal_dropped_in_a_weakref_callback_is_delivered_again():
    import weakref

    class Thing:
        pass

    def callback(_ref) -> None:
        os.kill(os.getpid(), signal.SIGTERM)
        for _ in range(100):  # the handler raises in here, where Python drops exceptions
            time.sleep(0.001)

    with pytest.raises(SignalExit) as info:
        with handle_signals():
            thing = Thing()
            ref = weakref.ref(thing, callback)
            del thing
            for _ in range(1000):
                time.sleep(0.01)
    assert info.value.name == "SIGTERM" and ref() is None


def test_a_second_signal_during_clean_up_is_ignored(capfd):
    done = []
    with pytest.raises(SignalExit, match=r"^stopped by SIGTERM \(signal 15\)$"):
        with handle_signals():
            try:
                os.kill(os.getpid(), signal.SIGTERM)
                time.sleep(10)
            finally:
                os.kill(os.getpid(), signal.SIGTERM)  # clean-up goes on
                time.sleep(0.05)
                done.append(True)
    assert done == [True]
    assert "already shutting down" in capfd.readouterr().err


def test_record_failure_adds_the_signal_as_strict_json(tmp_path):
    (tmp_path / "metrics.json").write_text('{"steps": 3, "rate": NaN}')
    RunFolder(tmp_path).record_failure(SignalExit(signal.SIGTERM))
    m = strict_json(tmp_path / "metrics.json")
    assert m == {
        "steps": 3,
        "rate": None,
        "error": "SignalExit: stopped by SIGTERM (signal 15)",
        "signal": "SIGTERM",
    }
    fresh = tmp_path / "not-yet"  # a signal during set-up: the folder says so
    RunFolder(fresh).record_failure(SignalExit(signal.SIGHUP))
    assert strict_json(fresh / "metrics.json")["signal"] == "SIGHUP"


def start(args: list[str], out: Path) -> subprocess.Popen:
    env = {**os.environ, "PYTHONPATH": str(ROOT), "MUJOCO_GL": "egl"}
    code = "import sys; from experiments.cli.main import app; sys.argv[0] = 'wander'; app()"
    return subprocess.Popen(
        [sys.executable, "-c", code, *args, "--out", str(out)],
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


def after_start(proc: subprocess.Popen, out: Path, seconds: float, limit_s: float = 300.0):
    """Wait until the run's events.h5 has grown (a chunk of steps was flushed: the loop
    runs), then ``seconds`` more."""
    deadline = time.monotonic() + limit_s
    path = out / "events.h5"
    while not path.exists():
        assert proc.poll() is None, proc.communicate()
        assert time.monotonic() < deadline, "the run did not start"
        time.sleep(0.1)
    size = path.stat().st_size
    while path.stat().st_size == size:
        assert proc.poll() is None, proc.communicate()
        assert time.monotonic() < deadline, "the run made no events"
        time.sleep(0.1)
    time.sleep(seconds)


@pytest.mark.slow
def test_sigterm_mid_run_exits_143_and_keeps_the_folder(tmp_path):
    out = tmp_path / "run"
    proc = start(["run", "--seconds", "20", "--no-video"], out)
    after_start(proc, out, 3.0)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=240)
    assert proc.returncode == 143, err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    want = f"wander run: stopped by SIGTERM (signal 15); '{out}' holds what was recorded"
    assert lines[-1] == want
    m = strict_json(out / "metrics.json")
    assert m["signal"] == "SIGTERM" and m["error"].startswith("SignalExit: stopped by SIGTERM")
    assert 0 < m["steps"] < 2000
    rec = read_events(out / "events.h5")
    assert "incomplete" not in rec.metadata  # closed cleanly
    assert len(rec.events) == m["events"] == rec.metadata["summary"]["events"]
    assert rec.events["t"][-1] <= m["steps"] * 10_000
    assert "run.json" in {p.name for p in out.iterdir()}


@pytest.fixture
def replay_file(tmp_path) -> str:
    rng = np.random.default_rng(0)
    n = 60_000
    t = np.sort(rng.integers(0, 30_000_000, n))
    ev = make_events(rng.integers(60, 70, n), rng.integers(60, 70, n), t, rng.integers(0, 2, n))
    path = tmp_path / "walk.npz"
    write_events(path, EventRecording(ev, (128, 128, 2)))
    return f"replay:{path}"


@pytest.mark.slow
def test_sighup_to_the_rig_halts_the_ptu_and_exits_129(tmp_path, replay_file):
    out = tmp_path / "rig"
    args = ["rig", "--ptu", "emulate", "--camera", replay_file, "--replay", "realtime"]
    proc = start([*args, "--seconds", "30", "--no-video"], out)
    after_start(proc, out, 2.0)
    proc.send_signal(signal.SIGHUP)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 129, err
    assert "stopped by SIGHUP (signal 1); the PTU was halted" in err
    m = strict_json(out / "metrics.json")
    assert m["signal"] == "SIGHUP"
    assert m["rig"]["ptu_halt"].startswith("halt (H) ")  # attempted and recorded
    assert len(read_events(out / "events.h5").events) == m["events"]


@pytest.mark.slow
def test_sigkill_leaves_a_readable_stream_that_says_where_it_stops(tmp_path):
    out = tmp_path / "rec"
    proc = start(["record", "--seconds", "30", "--no-video"], out)
    after_start(proc, out, 5.0)
    proc.kill()
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == -signal.SIGKILL, err  # (a crash before the kill: its stacks)
    rec = read_events(out / "events.h5")
    stop = rec.metadata["incomplete"]
    assert stop["events"] == len(rec.events) > 0
    assert stop["last_t_us"] == rec.events["t"][-1] < 30_000_000


def _python(code: str) -> subprocess.CompletedProcess[str]:
    """``code`` run by this Python with the project importable, faulthandler left to
    the code (not enabled from the environment)."""
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    env.pop("PYTHONFAULTHANDLER", None)
    return subprocess.run(
        [sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=120
    )


def test_a_native_crash_in_a_command_prints_every_threads_python_stack():
    code = (
        "import ctypes, sys, threading\n"
        "from experiments.cli.main import app\n"
        "@app.command('crash-here')\n"
        "def crash_here():\n"
        "    threading.Thread(target=threading.Event().wait, name='idle', daemon=True).start()\n"
        "    ctypes.string_at(0)  # reads address 0: SIGSEGV\n"
        "sys.argv = ['wander', 'crash-here']\n"
        "app()\n"
    )
    proc = _python(code)
    assert proc.returncode == -signal.SIGSEGV, proc.stderr
    assert "Fatal Python error: Segmentation fault" in proc.stderr
    crashed, other = proc.stderr.split("Current thread 0x")[1], proc.stderr.split("Thread 0x")
    assert "in crash_here" in crashed  # the crashing thread's stack
    assert len(other) == 2 and "in wait" in other[1]  # and the idle thread's


def test_a_command_runs_where_there_is_no_stderr_to_print_a_crash_on():
    code = (
        "import sys\n"
        "from experiments.cli.main import app\n"
        "sys.stderr = None  # as under a launcher that closed it\n"
        "sys.argv = ['wander', 'run', '--help']\n"
        "app()\n"
    )
    proc = _python(code)
    assert proc.returncode == 0, proc.stderr
    assert "Usage: wander run" in proc.stdout


def test_a_signal_while_setting_up_still_leaves_a_folder(tmp_path, monkeypatch):
    import experiments.jobs.run_agent as run_agent

    def stopped(*args, **kwargs):
        raise SignalExit(signal.SIGTERM)  # as if it came while the agent was being built

    monkeypatch.setattr(run_agent, "AttentionAgent", stopped)
    out = tmp_path / "run"
    with pytest.raises(SignalExit, match=r"^stopped by SIGTERM \(signal 15\)$"):
        run_agent.run(out, run_agent.RunConfig(WanderConfig(episode_seconds=1.0), video=False))
    m = strict_json(out / "metrics.json")
    assert m == {
        "steps": 0,
        "events": 0,
        "stage": "set-up",
        "error": "SignalExit: stopped by SIGTERM (signal 15) (while setting up)",
        "signal": "SIGTERM",
    }
    rec = read_events(out / "events.h5")
    assert len(rec.events) == 0 and rec.sensor_size == (128, 128, 2)
    assert rec.metadata["summary"] == {"steps": 0, "events": 0}


TWICE = 8  # runs, each sent two SIGTERMs back to back


@pytest.mark.slow
def test_two_sigterms_back_to_back_record_the_first_and_mark_the_folder_every_time(tmp_path):
    """The second signal of a pair lands while the first is being taken up (in a render's
    ctypes call, in the folder's writing): it never turns into another error."""
    for k in range(TWICE):
        out = tmp_path / f"run-{k}"
        proc = start(["run", "--seconds", "20", "--no-video"], out)
        after_start(proc, out, 0.1 * k)  # at different points of a step
        os.kill(proc.pid, signal.SIGTERM)
        os.kill(proc.pid, signal.SIGTERM)
        _, err = proc.communicate(timeout=240)
        assert proc.returncode == 143, (k, err)
        m = strict_json(out / "metrics.json")
        assert m["signal"] == "SIGTERM", (k, m["error"])
        assert m["error"] == "SignalExit: stopped by SIGTERM (signal 15)", k
        steps = m["steps"]
        assert (out / "INCOMPLETE").read_text() == (
            f"stopped by SIGTERM (signal 15) after {steps} of 2000 steps\n"
        ), k
