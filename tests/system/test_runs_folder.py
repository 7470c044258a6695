"""The run folder (:class:`experiments.runs.folder.RunFolder`): one naming for every
command, ``--force``, strict records, the failure said in the folder."""

from __future__ import annotations

import json
import re
import signal

import pytest
from typer.testing import CliRunner

from experiments.runs.folder import CurrentRun, RunFolder
from experiments.runs.signals import SignalExit
from wander_env.untrusted import UntrustedFileError

STAMP = r"\d{8}-\d{6}"


@pytest.mark.parametrize(
    "command", ["run", "record", "rig", "evaluate", "demo", "benchmark-suppression"]
)
def test_a_job_or_a_benchmark_gets_a_new_time_stamped_folder(tmp_path, command):
    first = RunFolder.new(command, root=tmp_path)
    assert re.fullmatch(rf"{command}-{STAMP}", first.path.name) and first.path.parent == tmp_path
    first.create()
    second = RunFolder.new(command, root=tmp_path)
    assert re.fullmatch(rf"{command}-{STAMP}(-2)?", second.path.name) and second.path != first.path


def test_an_experiment_folder_is_grouped_by_experiment(tmp_path):
    run = RunFolder.for_experiment("scanpath", 3, root=tmp_path)
    assert run.path.parent == tmp_path / "scanpath"
    assert re.fullmatch(rf"{STAMP}-seed3", run.path.name)


def test_an_earlier_run_is_kept_unless_forced(tmp_path):
    RunFolder(tmp_path).write_metrics({"steps": 1})
    with pytest.raises(FileExistsError, match="pass --force"):
        RunFolder.new("run", tmp_path)
    forced = RunFolder.new("run", tmp_path, force=True)
    assert forced.final == tmp_path and forced.path.parent == tmp_path.parent
    assert forced.path.name.startswith(".wander-new-") and forced.path.is_dir()
    (tmp_path / "file").write_text("x")
    with pytest.raises(FileExistsError, match="not a folder"):
        RunFolder.new("run", tmp_path / "file", force=True)


def _siblings(path):
    return sorted(p.name for p in path.parent.iterdir() if p.name != path.name)


def test_force_replaces_every_file_of_the_earlier_run(tmp_path):
    """The issue's case: an old INCOMPLETE and run.mp4 stayed beside the new run's files."""
    out = tmp_path / "run"
    old = RunFolder.new("run", out)
    old.write_metrics({"steps": 230, "error": "stopped"})
    old.mark_incomplete("stopped after 230 of 500 steps")
    (out / "run.mp4").write_bytes(b"old video")
    new = RunFolder.new("run", out, force=True)
    assert sorted(p.name for p in out.iterdir()) == ["INCOMPLETE", "metrics.json", "run.mp4"]
    new.write_metrics({"steps": 500})
    assert new.finish() == out and new.path == out
    assert sorted(p.name for p in out.iterdir()) == ["metrics.json"]
    assert new.read_json("metrics.json") == {"steps": 500}
    assert _siblings(out) == []  # neither the build nor the earlier run is left beside it


def test_a_forced_run_that_wrote_nothing_leaves_the_earlier_run(tmp_path):
    out = tmp_path / "run"
    RunFolder.new("run", out).write_metrics({"steps": 3})
    RunFolder.new("run", out, force=True).finish()
    assert sorted(p.name for p in out.iterdir()) == ["metrics.json"] and _siblings(out) == []


def test_a_swap_the_file_system_refuses_keeps_the_earlier_run(tmp_path, monkeypatch):
    import os

    out = tmp_path / "run"
    RunFolder.new("run", out).write_metrics({"steps": 3})
    new = RunFolder.new("run", out, force=True)
    new.write_metrics({"steps": 5})
    real_rename = os.rename

    def refuse_the_build(src, dst):
        if str(src) == str(new.path):
            raise OSError(18, "Invalid cross-device link")
        real_rename(src, dst)

    monkeypatch.setattr(os, "rename", refuse_the_build)
    build = new.path
    assert new.finish() == build  # never raises; the new run stays where it was built
    assert RunFolder(out).read_json("metrics.json") == {"steps": 3}
    assert RunFolder(build).read_json("metrics.json") == {"steps": 5}
    assert _siblings(out) == [build.name]  # no .wander-old-* left


def test_a_made_folder_left_empty_is_removed_and_an_empty_one_given_is_kept(tmp_path):
    made = RunFolder.new("run", root=tmp_path)
    assert made.path.is_dir()
    made.finish()
    assert list(tmp_path.iterdir()) == []  # a run refused in its set-up leaves nothing
    given = tmp_path / "mine"
    given.mkdir()
    run = RunFolder.new("run", given)
    assert run.path == given and not run.made
    run.finish()
    assert given.is_dir()


@pytest.mark.parametrize(
    ("out", "problem"),
    [
        ("file/run", "cannot create '{tmp}/file/run': Not a directory"),
        ("file", "'{tmp}/file' exists and is not a folder"),
        ("x" * 300, "cannot create '{tmp}/" + "x" * 300 + "': File name too long"),
    ],
)
def test_a_folder_that_cannot_be_made_is_one_error_naming_it(tmp_path, out, problem):
    from experiments.cli.options import folder_problem

    (tmp_path / "file").write_text("x")
    with pytest.raises(OSError) as err:
        RunFolder.new("run", tmp_path / out)
    assert folder_problem(err.value) == problem.format(tmp=tmp_path)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["file"]


CLAIM = """
import os, sys, time, types
import experiments.runs.folder as folder
folder.time = types.SimpleNamespace(strftime=lambda fmt: "20260101-120000")  # one second
start = float(sys.argv[2])
time.sleep(max(0.0, start - time.time()))
run = folder.RunFolder.new("run", root=folder.Path(sys.argv[1]))
run.write_metrics({"pid": os.getpid()})
if os.getpid() % 2:  # half of them fail: each marks its own folder only
    run.record_failure(OSError(28, "No space left on device"))
run.finish()
print(os.getpid(), run.path.name)
"""


@pytest.mark.slow
def test_twenty_processes_in_the_same_second_get_twenty_folders_of_their_own(tmp_path):
    """The issue's bar at the folder layer: twenty runs named in one second (the stamp is
    fixed) each create their own folder (``os.mkdir``, suffix on collision), and a
    failing one marks only its own."""
    import os
    import subprocess
    import sys
    import time

    start = f"{time.time() + 3.0}"  # every process names its folder at the same instant
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)}
    procs = [
        subprocess.Popen(
            [sys.executable, "-c", CLAIM, str(tmp_path), start],
            stdout=subprocess.PIPE,
            text=True,
            env=env,
        )
        for _ in range(20)
    ]
    claimed = {}
    for proc in procs:
        out, _ = proc.communicate(timeout=120)
        assert proc.returncode == 0
        pid, name = out.split()
        claimed[name] = int(pid)
    stamp = "run-20260101-120000"
    assert set(claimed) == {stamp, *(f"{stamp}-{k}" for k in range(2, 21))}
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(claimed)
    for name, pid in claimed.items():
        run = RunFolder(tmp_path / name)
        assert run.read_json("metrics.json")["pid"] == pid
        assert run.incomplete() == bool(pid % 2)


def test_a_folder_named_with_the_command_registers_itself(tmp_path):
    current = CurrentRun()
    assert current.folder is None
    run = RunFolder.new("run", root=tmp_path, current=current)
    assert current.folder is run


def test_the_records_are_strict_json(tmp_path):
    run = RunFolder(tmp_path / "r")
    run.write_run({"x": float("inf"), "y": [float("nan")]})
    assert json.loads((tmp_path / "r" / "run.json").read_text()) == {"x": None, "y": [None]}


def test_a_signal_before_the_folder_existed_creates_it_and_says_so(tmp_path):
    run = RunFolder(tmp_path / "new")
    run.record_failure(SignalExit(signal.SIGTERM))
    metrics = run.read_json("metrics.json")
    assert metrics["signal"] == "SIGTERM" and not run.incomplete()


def test_a_resumed_run_moves_the_former_stop_into_the_history(tmp_path):
    run = RunFolder(tmp_path)
    run.record_failure(SignalExit(signal.SIGINT))
    run.mark_incomplete("stopped")
    run.take_stop()
    assert not (tmp_path / "metrics.json").exists() and not run.incomplete()
    (stop,) = run.read_json("run.json")["stops"]
    assert stop["signal"] == "SIGINT" and stop["incomplete"] == "stopped"


def test_read_json_is_empty_only_for_a_file_not_written_yet(tmp_path):
    run = RunFolder(tmp_path)
    assert run.read_json("run.json") == {}
    (tmp_path / "run.json").write_text('{"seed": 1}\n')
    assert run.read_json("run.json") == {"seed": 1}


@pytest.mark.parametrize(
    ("text", "problem"),
    [
        (
            '{"seed": 1, "stops": [',
            "not valid JSON, cut short or damaged (Expecting value: line 1 column 23 (char 22))",
        ),
        ('["a run"]', "expected a JSON object, got list"),
        ('{"seed": 1, "seed": 2}', "the key 'seed' is given twice"),
        ("[" * 65 + "]" * 65, "JSON nested 65 deep; at most 64"),
    ],
)
def test_a_damaged_run_json_is_an_error_naming_it_not_an_empty_record(tmp_path, text, problem):
    run = RunFolder(tmp_path)
    (tmp_path / "run.json").write_text(text)
    with pytest.raises(UntrustedFileError) as info:
        run.read_json("run.json")
    assert str(info.value) == f"{tmp_path / 'run.json'}: {problem}"
    (tmp_path / "metrics.json").write_text('{"steps": 3}')
    with pytest.raises(UntrustedFileError) as info:  # a resumed run keeps its stops or stops
        run.take_stop()
    assert str(info.value) == f"{tmp_path / 'run.json'}: {problem}"
    assert run.read_json("metrics.json") == {"steps": 3}  # nothing moved, nothing lost


def test_a_damaged_metrics_json_is_recorded_as_such_by_the_failure_and_the_stop(tmp_path):
    run = RunFolder(tmp_path)
    (tmp_path / "metrics.json").write_text('{"steps": 3')
    run.record_failure(SignalExit(signal.SIGTERM))
    damaged = (
        "not valid JSON, cut short or damaged (Expecting ',' delimiter: line 1 column 12 (char 11))"
    )
    assert run.read_json("metrics.json") == {
        "unreadable_metrics": damaged,
        "error": "SignalExit: stopped by SIGTERM (signal 15)",
        "signal": "SIGTERM",
    }
    (tmp_path / "metrics.json").write_text('{"steps": 3')
    run.take_stop()
    assert run.read_json("run.json") == {
        "stops": [{"error": f"unreadable metrics.json: {damaged}"}]
    }
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.json"]


def test_wander_demo_without_out_writes_runs_demo_date_time(tmp_path, monkeypatch):
    from experiments.cli.main import app

    monkeypatch.chdir(tmp_path)
    result = CliRunner().invoke(app, ["demo", "--seconds", "0.2"])
    assert result.exit_code == 0, result.output
    (folder,) = (tmp_path / "runs").iterdir()
    assert re.fullmatch(rf"demo-{STAMP}", folder.name)
    assert {p.name for p in folder.iterdir()} == {"events.h5", "events.png", "run.json"}
    assert json.loads((folder / "run.json").read_text())["command"] == "wander demo"


REFUSED = "Invalid value for '--out': 'full' is not empty: pass --force to replace it, or "
REFUSED += "leave --out out for a new folder"


@pytest.mark.parametrize(
    "args",
    [
        ["demo"],
        ["record"],
        ["run"],
        ["evaluate"],
        ["rig", "--ptu", "emulate", "--camera", "replay:x.npz"],
        ["experiment", "detection"],
        ["benchmark", "evimo", "nodir"],
        ["benchmark", "llevos", "nodir"],
        ["benchmark", "events", "x.npz", "--masks", "nodir"],
        ["benchmark", "suppression", "nodir"],
    ],
)
def test_every_command_refuses_a_non_empty_out_without_force(tmp_path, monkeypatch, args):
    from experiments.cli.main import app

    monkeypatch.chdir(tmp_path)
    (tmp_path / "full").mkdir()
    (tmp_path / "full" / "results.csv").write_text("earlier\n")
    (tmp_path / "x.npz").write_bytes(b"")
    result = CliRunner().invoke(app, [*args, "--out", "full"], prog_name="wander")
    assert result.exit_code == 2, result.output
    command = " ".join(args[:2]) if args[0] == "benchmark" else args[0]
    assert result.stderr.splitlines() == [f"wander {command}: {REFUSED}"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["full", "x.npz"]
    assert (tmp_path / "full" / "results.csv").read_text() == "earlier\n"


@pytest.mark.parametrize(
    ("out", "problem"),
    [
        ("x" * 300, "cannot create '" + "x" * 300 + "': File name too long"),
        ("file/results", "cannot create 'file/results': Not a directory"),
        ("/proc/wander", "cannot create '/proc/wander': No such file or directory"),
    ],
)
def test_an_out_that_cannot_be_made_is_refused_before_any_trial(
    tmp_path, monkeypatch, out, problem
):
    from experiments.cli.main import app

    monkeypatch.chdir(tmp_path)
    (tmp_path / "file").write_text("x")
    args = ["experiment", "detection", "--out", out]
    result = CliRunner().invoke(app, args, prog_name="wander")
    assert result.exit_code == 2, result.output
    assert result.stderr.splitlines() == [
        f"wander experiment: Invalid value for '--out': {problem}"
    ]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["file"]  # no results/, no trial


def test_force_over_a_stopped_run_leaves_no_file_of_it(tmp_path, monkeypatch):
    from experiments.cli.main import app

    monkeypatch.chdir(tmp_path)
    out = tmp_path / "stopped"
    out.mkdir()
    (out / "INCOMPLETE").write_text("stopped by SIGTERM after 230 of 500 steps\n")
    (out / "run.mp4").write_bytes(b"old video")
    (out / "metrics.json").write_text('{"steps": 230, "signal": "SIGTERM"}\n')
    args = ["demo", "--seconds", "0.2", "--out", "stopped", "--force"]
    result = CliRunner().invoke(app, args, prog_name="wander")
    assert result.exit_code == 0, result.output
    assert sorted(p.name for p in out.iterdir()) == ["events.h5", "events.png", "run.json"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["stopped"]  # nothing left beside
    assert "-> stopped/events.h5, stopped/events.png" in " ".join(result.stdout.split())


@pytest.mark.slow
def test_four_experiments_started_together_keep_four_result_folders(tmp_path):
    """The issue's bar: four ``wander experiment detection`` without ``--out`` in the same
    second (a one-trial config) each exit 0 with a complete folder of its own."""
    import os
    import subprocess
    import sys

    small = ["--set", "scenes=[gratings]", "--set", "camera_speeds_deg_s=[0.0]"]
    small += ["--set", "duration_s=0.4", "--set", "warmup_s=0.1", "--set", "repeats=1"]
    code = "from experiments.cli.main import main; main()"
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)}
    procs = [
        subprocess.Popen(
            [sys.executable, "-c", code, "experiment", "detection", *small],
            cwd=tmp_path,
            env=env,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.PIPE,
            text=True,
        )
        for _ in range(4)
    ]
    for proc in procs:
        _, err = proc.communicate(timeout=600)
        assert proc.returncode == 0, err
    folders = sorted((tmp_path / "results" / "detection").iterdir())
    assert len(folders) == 4
    for folder in folders:
        assert re.fullmatch(rf"{STAMP}-seed0(-[234])?", folder.name)
        assert {"results.csv", "run.json", "config.json", "summary.md"} <= {
            p.name for p in folder.iterdir()
        }
        assert not (folder / "INCOMPLETE").exists()
        assert len((folder / "results.csv").read_text().splitlines()) == 2  # header, 1 trial
