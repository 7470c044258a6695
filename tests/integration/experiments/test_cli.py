"""The ``wander`` command line: help, the demo's outputs, the benchmark table."""

from __future__ import annotations

import json

import cv2
import pytest
from typer.testing import CliRunner

from experiments.cli.main import app
from wander_env.events.io import read_events

runner = CliRunner()


def test_help_lists_the_commands():
    result = runner.invoke(app, ["--help"])
    assert result.exit_code == 0
    for name in ("demo", "perf", "benchmark"):
        assert name in result.output
    assert "bench " not in result.output  # the former name of perf, hidden
    assert runner.invoke(app, ["perf", "dvs", "--help"]).exit_code == 0


def test_bench_runs_perf_with_a_one_line_notice():
    result = runner.invoke(app, ["bench", "dvs", "--help"])
    assert result.exit_code == 0
    assert result.stderr.splitlines() == ["wander bench is now wander perf"]
    assert "bench dvs [OPTIONS]" in result.stdout and "--frames" in result.stdout


def test_demo_writes_events_picture_and_record(tmp_path):
    out = tmp_path / "demo"
    result = runner.invoke(app, ["demo", "--out", str(out), "--seconds", "0.2", "--seed", "3"])
    assert result.exit_code == 0, result.output
    rec = read_events(out / "events.h5")
    run = json.loads((out / "run.json").read_text())
    assert rec.sensor_size == (128, 128, 2)
    assert len(rec.events) == run["summary"]["events"] > 10_000
    assert rec.events["t"].max() <= 200_000 + 1000  # 0.2 s, plus at most the latency tail
    assert run["seed"] == 3 and run["config"]["preset"] == "paper"
    assert run["config"]["dvs"]["latency_us"] == 100.0
    assert run["git_revision"]
    picture = cv2.imread(str(out / "events.png"))
    # 2 rows of 4 titled panels and a legend: a 12 x 6.8 inch figure at 110 dpi.
    assert picture.shape == (748, 1320, 3)
    # The legend's ON and OFF swatches are in the picture, in the event colours.
    rgb = cv2.cvtColor(picture, cv2.COLOR_BGR2RGB).reshape(-1, 3)
    colours = {tuple(c) for c in rgb[-60 * 1320 :].tolist()}
    assert (220, 30, 30) in colours and (30, 60, 220) in colours


def test_demo_is_reproducible(tmp_path):
    for name in ("a", "b"):
        runner.invoke(app, ["demo", "--out", str(tmp_path / name), "--seconds", "0.2"])
    a, b = (read_events(tmp_path / n / "events.h5").events for n in ("a", "b"))
    assert (a == b).all() and len(a) > 0


def test_demo_rejects_a_bad_preset(tmp_path):
    result = runner.invoke(
        app, ["demo", "--out", str(tmp_path), "--preset", "davis"], prog_name="wander"
    )
    assert result.exit_code == 2
    assert result.stderr.strip().splitlines() == [
        "wander demo: Invalid value for '--preset': unknown DVS preset 'davis'; "
        "choose one of ['ideal', 'paper', 'speck']"
    ]


def test_perf_dvs_prints_every_row():
    result = runner.invoke(app, ["perf", "dvs", "--frames", "20", "--repeats", "1"])
    assert result.exit_code == 0, result.output
    # 4 scene/noise rows and 3 input paths per sensor
    assert result.output.count("128x128") == 7
    assert result.output.count("346x260") == 7
    assert result.output.count("uint8 sRGB") == 2
    # headers keep their units' capitals
    assert "Mev/s" in result.output and "peak MiB" in result.output
    assert "mev per s" not in result.output and "peak mib" not in result.output


def test_markdown_tables_are_printed_as_tables():
    from experiments.cli.console import console, print_markdown

    with console.capture() as captured:
        print_markdown("# title\n\n| result | ours |\n|---|---|\n| hit rate | 94% |\n")
    text = captured.get()
    assert "title" in text and "hit rate" in text and "94%" in text
    assert "|" not in text and "───" in text  # drawn by rich, not the raw pipes


@pytest.mark.slow
def test_perf_dvs_peers_prints_a_row_per_peer_and_sensor():
    # a peer that is not installed still gets its rows ("–" and a note)
    result = runner.invoke(app, ["perf", "dvs", "--frames", "5", "--repeats", "1", "--peers"])
    assert result.exit_code == 0, result.output
    assert result.output.count("ESIM") == 2
    assert result.output.count("EventEmulator") == 2


def test_version_prints_the_version_and_the_git_revision():
    from importlib.metadata import version

    from experiments.runs.provenance import git_revision

    result = runner.invoke(app, ["--version"])
    assert result.exit_code == 0, result.output
    assert result.output == f"wander {version('wander')} (git {git_revision()})\n"


def test_run_reads_a_config_file_and_flags_override_it(tmp_path):
    config = tmp_path / "run.yaml"
    config.write_text(
        "env: {scene: shelf, episode_seconds: 0.3}\nseed: 3\nvideo: false\n"
        "agent: {window_s: 0.05, soms: {norm: minmax}}\n"
    )
    out = tmp_path / "run"
    args = ["run", "--config", str(config), "--seed", "5", "--out", str(out)]
    result = runner.invoke(app, args)
    assert result.exit_code == 0, result.output
    got = json.loads((out / "run.json").read_text())["config"]
    assert (got["env"]["scene"], got["env"]["episode_seconds"]) == ("shelf", 0.3)
    assert (got["seed"], got["video"]) == (5, False)  # the flag given on the command line wins
    assert (got["agent"]["window_s"], got["agent"]["soms"]["norm"]) == (0.05, "minmax")
    # neither file nor flag: the config's defaults
    assert got["env"]["dvs"] == "ideal" and got["agent"]["soms"]["alpha"] == 0.8
    assert not (out / "run.mp4").exists() and "real-time factor" in result.output


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("scen: shelf\n", "unknown key 'scen' for RunConfig; allowed keys: env (WanderConfig), "),
        ("env: {episode_seconds: abc}\n", "env.episode_seconds: expected float, got 'abc'"),
        ("env: {scene: offce}\n", "env.scene: unknown scene 'offce'; available: "),
        (
            "env: {frames: abc}\n",
            "env.frames: expected one of 'keyframes', 'exact', 'panorama', got 'abc'",
        ),
        ("env: {episode_seconds: -1}\n", "env.episode_seconds: input should be greater than 0"),
    ],
)
def test_run_refuses_a_bad_config_file_in_one_line(tmp_path, text, message):
    config = tmp_path / "run.yaml"
    config.write_text(text)
    result = runner.invoke(app, ["run", "--config", str(config), "--out", str(tmp_path / "r")])
    assert result.exit_code == 2
    assert f" run: error: {config}: {message}" in result.output  # the test runner names it root
    assert result.output.count("\n") == 1 and not (tmp_path / "r").exists()
    missing = runner.invoke(app, ["run", "--config", str(tmp_path / "no.yaml")])
    assert missing.exit_code == 2 and missing.output.endswith(
        f" run: Invalid value for '--config': file '{tmp_path / 'no.yaml'}' does not exist.\n"
    )
