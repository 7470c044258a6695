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
    assert RunFolder.new("run", tmp_path, force=True).path == tmp_path
    (tmp_path / "file").write_text("x")
    with pytest.raises(FileExistsError, match="not a folder"):
        RunFolder.new("run", tmp_path / "file", force=True)


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


def test_wander_demo_without_out_writes_runs_demo_date_time(tmp_path, monkeypatch):
    from experiments.cli.main import app

    monkeypatch.chdir(tmp_path)
    result = CliRunner().invoke(app, ["demo", "--seconds", "0.2"])
    assert result.exit_code == 0, result.output
    (folder,) = (tmp_path / "runs").iterdir()
    assert re.fullmatch(rf"demo-{STAMP}", folder.name)
    assert {p.name for p in folder.iterdir()} == {"events.h5", "events.png", "run.json"}
    assert json.loads((folder / "run.json").read_text())["command"] == "wander demo"
