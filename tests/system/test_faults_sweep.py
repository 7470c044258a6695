"""Fault injection, sweeps: damaged trial files are set aside and rerun; a sweep that is
stopped (SIGTERM) or killed (SIGKILL) leaves no worker process behind; waits are bounded."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest
from locations import ROOT, SUPPORT
from test_sweep import TOY_SWEEP, CountingRunner

from experiments.runs.trials import MAX_TRIAL_FILE_BYTES
from experiments.studies.framework import TrialSpec
from experiments.studies.sweep import (
    TrialCrashed,
    expand,
    local_executor,
    run_sweep,
    sweep_from_dict,
)


@pytest.mark.parametrize(
    ("damage", "why"),
    [
        (b"", "Expecting value"),
        (b'{"spec": {"experiment": "event_suppr', "Unterminated string"),
        (b"\x00\xff garbage \xfe", "not UTF-8 text (invalid start byte at byte 1)"),
        (b'{"spec": {}, "row": 3}', "no 'row' object"),
        (b'{"row": {}}', "its row has no 'trial_id'"),  # crashed every resume
        (b"[" * 3000 + b"]" * 3000, "JSON nested 3000 deep; at most 64"),
    ],
)
def test_a_damaged_trial_file_is_named_set_aside_and_rerun(tmp_path, damage, why):
    sweep = sweep_from_dict(TOY_SWEEP)
    runner = CountingRunner()
    first = run_sweep(sweep, tmp_path, backend="serial", runner=runner)
    table = (tmp_path / "results.csv").read_bytes()
    victim = first.rows[4]["trial_id"]
    path = tmp_path / "trials" / f"{victim}.json"
    path.write_bytes(damage)
    runner.calls.clear()
    with pytest.warns(RuntimeWarning) as warned:
        res = run_sweep(sweep, tmp_path, backend="serial", runner=runner)
    (message,) = [str(w.message) for w in warned]
    assert message.startswith(f"{path}: damaged trial file (")
    assert why in message and f"set aside as {victim}.json.corrupt" in message
    assert runner.calls == [victim] and (res.ran, res.skipped) == (1, len(first.rows) - 1)
    assert (tmp_path / "trials" / f"{victim}.json.corrupt").read_bytes() == damage
    assert (tmp_path / "results.csv").read_bytes() == table  # the rerun row is the same


def test_a_trial_file_too_large_is_set_aside_unread(tmp_path):
    sweep = sweep_from_dict(TOY_SWEEP)
    first = run_sweep(sweep, tmp_path, backend="serial", runner=CountingRunner())
    victim = first.rows[2]["trial_id"]
    path = tmp_path / "trials" / f"{victim}.json"
    os.truncate(path, MAX_TRIAL_FILE_BYTES + 1)  # sparse: no disk space, no read
    with pytest.warns(RuntimeWarning) as warned:
        res = run_sweep(sweep, tmp_path, backend="serial", runner=CountingRunner())
    assert [str(w.message) for w in warned] == [
        f"{path}: damaged trial file ({MAX_TRIAL_FILE_BYTES + 1} bytes; at most "
        f"{MAX_TRIAL_FILE_BYTES}); set aside as {victim}.json.corrupt, the trial is rerun"
    ]
    assert (res.ran, res.skipped) == (1, len(first.rows) - 1)


def test_no_trial_finishing_within_the_timeout_is_an_error_and_ends_the_workers(
    tmp_path, monkeypatch
):
    monkeypatch.setenv("SWEEP_PIDS", str(tmp_path))
    from sweep_workers import sleepy

    spec = TrialSpec("event_suppression", {}, {}, 0)
    stream = local_executor([spec], workers=1, runner=sleepy, timeout_s=3.0)
    with pytest.raises(TimeoutError, match=r"no trial finished within 3 s \(1 not done\)"):
        next(stream)
    pids = wait_for_pids(tmp_path, 1, limit_s=1.0)
    assert not any(alive(p) for p in pids)


def wait_for_pids(folder: Path, n: int, limit_s: float = 120.0) -> list[int]:
    deadline = time.monotonic() + limit_s
    while len(pids := [int(p.stem) for p in folder.glob("*.pid")]) < n:
        if time.monotonic() > deadline:
            break
        time.sleep(0.1)
    return pids


def alive(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as fh:
            return fh.read().split(") ")[-1][0] != "Z"  # a zombie is gone but not reaped
    except FileNotFoundError:
        return False


SCRIPT = textwrap.dedent(
    """
    import sys
    from pathlib import Path
    sys.path.insert(0, {here!r})
    from sweep_workers import sleepy
    from experiments.studies.sweep import run_sweep, sweep_from_dict
    from experiments.runs.signals import SignalExit, handle_signals
    sweep = sweep_from_dict({sweep!r})
    try:
        with handle_signals():
            run_sweep(sweep, Path({out!r}), backend="local", workers=2, runner=sleepy)
    except SignalExit as stop:
        sys.exit(stop.exit_code)
    """
)


@pytest.mark.slow
@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGKILL])
def test_a_stopped_or_killed_sweep_leaves_no_worker(tmp_path, sig):
    pids_dir = tmp_path / "pids"
    pids_dir.mkdir()
    code = SCRIPT.format(here=str(SUPPORT), sweep=TOY_SWEEP, out=str(tmp_path / "sweep"))
    env = {**os.environ, "PYTHONPATH": str(ROOT), "SWEEP_PIDS": str(pids_dir)}
    proc = subprocess.Popen([sys.executable, "-c", code], env=env, stderr=subprocess.PIPE)
    pids = wait_for_pids(pids_dir, 2)
    assert len(pids) == 2 and all(alive(p) for p in pids)
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == (143 if sig == signal.SIGTERM else -9), err
    if sig == signal.SIGTERM:  # the pool's threads end quietly: no traceback after the stop
        assert b"Traceback" not in err, err.decode()
    deadline = time.monotonic() + 30.0
    while any(alive(p) for p in pids) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert [p for p in pids if alive(p)] == []


@pytest.mark.slow
def test_a_worker_killed_in_a_trial_costs_that_trial_one_more_run_and_the_sweep_goes_on(
    tmp_path, monkeypatch
):
    """As the out-of-memory killer would: SIGKILL in trial 1's first attempt."""
    attempts = tmp_path / "attempts"
    attempts.mkdir()
    monkeypatch.setenv("SWEEP_PIDS", str(attempts))
    from sweep_workers import killed_first_time

    sweep = sweep_from_dict(TOY_SWEEP)
    with pytest.warns(RuntimeWarning) as warned:
        res = run_sweep(
            sweep, tmp_path / "out", backend="local", workers=1, runner=killed_first_time
        )
    victim = res.rows[1]["trial_id"]
    assert [str(w.message) for w in warned] == [
        f"trial {victim} (event_suppression #1, seed 1): its worker process died (killed by "
        "SIGKILL, as the out-of-memory killer does); running it once more"
    ]
    runs = {r["trial_id"]: len(list(attempts.glob(f"{r['trial_id']}.*"))) for r in res.rows}
    assert runs == {r["trial_id"]: 2 if r["trial"] == 1 else 1 for r in res.rows}
    assert (res.ran, res.skipped, len(res.rows)) == (12, 0, 12)


@pytest.mark.slow
def test_a_trial_whose_worker_dies_twice_ends_the_sweep_with_one_line(tmp_path, monkeypatch):
    attempts = tmp_path / "attempts"
    attempts.mkdir()
    monkeypatch.setenv("SWEEP_PIDS", str(attempts))
    from sweep_workers import killed_always

    sweep = sweep_from_dict(TOY_SWEEP)
    out = tmp_path / "out"
    with pytest.warns(RuntimeWarning), pytest.raises(TrialCrashed) as raised:
        run_sweep(sweep, out, backend="local", workers=1, runner=killed_always)
    first, victim = (s.id for s in expand(sweep)[:2])
    assert str(raised.value) == (
        f"trial {victim} (event_suppression #1, seed 1): its worker process died twice "
        "(killed by SIGKILL, as the out-of-memory killer does); the trials that finished are "
        "kept: rerun the same command to resume"
    )
    assert len(list(attempts.glob(f"{victim}.*"))) == 2
    assert [p.name for p in (out / "trials").iterdir()] == [f"{first}.json"]  # kept
    again = CountingRunner()
    res = run_sweep(sweep, out, backend="serial", runner=again)
    assert (res.ran, res.skipped) == (11, 1) and first not in again.calls


def _kill_own_dashboard_agent(deadline_s: float) -> list[int]:
    """SIGKILL the Ray dashboard agent started by this process (none other's), once a
    trial's worker runs; the agents killed."""
    import psutil

    me = psutil.Process()
    deadline = time.monotonic() + deadline_s
    while time.monotonic() < deadline:
        procs = me.children(recursive=True)
        running = [p for p in procs if _cmdline(p)[:1] == ["ray::_timed"]]
        agents = [p for p in procs if any("dashboard/agent.py" in a for a in _cmdline(p))]
        agents = [p for p in agents if "python" in (_cmdline(p)[:1] or [""])[0]]
        if running and agents:
            for p in agents:
                p.kill()
            return [p.pid for p in agents]
        time.sleep(0.2)
    return []


def _cmdline(proc) -> list[str]:
    import psutil

    try:
        return proc.cmdline()
    except psutil.Error:
        return []


@pytest.mark.slow
def test_ray_dashboard_agent_killed_mid_sweep_is_one_line(tmp_path, capfd):
    """Killing the node's dashboard agent (Ray starts one even without the dashboard)
    takes its raylet down: the sweep ends with one line, not Ray's traceback; Ray's own
    block (the dead raylet's log tail) goes to the log, not the terminal."""
    import threading

    ray = pytest.importorskip("ray")
    from experiments.studies.sweep import BackendFailed, ray_executor

    if ray.is_initialized():  # the session's shared instance: this test needs its own
        ray.shutdown()  # (the next test that asks for ``ray_instance`` starts it again)
    killed: list[int] = []
    killer = threading.Thread(target=lambda: killed.extend(_kill_own_dashboard_agent(240.0)))
    killer.start()
    finished = []
    try:
        with pytest.raises(BackendFailed) as info:
            log = tmp_path / "ray.log"
            for spec, _, _ in ray_executor([20.0] * 3, workers=2, runner=time.sleep, log=log):
                finished.append(spec)
    finally:
        killer.join()
    left = 3 - len(finished)  # the trials that ran to the end before the raylet went
    assert len(killed) == 1
    text = str(info.value)
    assert "\n" not in text and len(text) < 600
    assert text.startswith("the Ray instance failed mid-sweep (LocalRayletDiedError")
    assert text.endswith(
        f"{left} trial(s) not finished, the finished ones are kept: rerun to resume"
    )
    assert not ray.is_initialized()  # shut down on the way out
    out, err = capfd.readouterr()
    assert "raylet" not in out + err and "Started a local Ray instance" not in out + err
    # (the dead raylet's block comes when Ray's error listener gets it: here or not yet)
    assert "INFO worker.py" in log.read_text() and "Started a local Ray instance" in log.read_text()
