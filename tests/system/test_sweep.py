"""Sweeps: grid expansion, validation, resuming, and the local / Ray backends agreeing."""

from __future__ import annotations

import pytest

from experiments.runs.tables import read_csv
from experiments.studies.framework import ConfigError, TrialSpec
from experiments.studies.sweep import expand, load_sweep, run_sweep, sweep_from_dict

# Two real, tiny trials (event_suppression: the hand phase, 10 windows of 2 ms each).
TINY_SWEEP = {
    "name": "tiny",
    "seeds": [0],
    "experiments": [
        {
            "experiment": "event_suppression",
            "set": {"repeats": 1, "phases": ["hand"], "hand_s": [0.02, 0.02], "lead_s": 0.0},
            "grid": {"agent.soms.alpha": [0.5, 0.8]},
        }
    ],
}

TOY_SWEEP = {
    "name": "toy",
    "seeds": [0, 1],
    "experiments": [
        {
            "experiment": "event_suppression",
            "set": {"repeats": 2, "phases": ["hand"]},
            "grid": {"agent.soms.alpha": [0.5, 0.8], "env.scene": ["hand", "office"]},
        }
    ],
}


class CountingRunner:
    """Stands in for ``run_spec``: no simulation, a row from the spec, calls counted."""

    def __init__(self) -> None:
        self.calls: list[str] = []

    def __call__(self, spec: TrialSpec) -> dict:
        self.calls.append(spec.id)
        row = {"trial": spec.index, "trial_id": spec.id, "repeat": spec.repeat, "seed": spec.seed}
        alpha = spec.config["agent"]["soms"]["alpha"]
        return {**row, **spec.extra, **spec.params, "value": alpha * 10 + spec.seed}


def test_expand_is_grid_times_seeds_times_repeats_in_order_without_duplicates():
    specs = expand(sweep_from_dict(TOY_SWEEP))
    # seeds [0, 1] x 2 repeats give trial seeds 0, 1 and 1, 2: seed 1's trial is the
    # same trial (same id) and is kept once -> 2 alphas x 2 scenes x 3 seeds
    assert len(specs) == 12 == len({s.id for s in specs})
    assert [s.index for s in specs] == list(range(12))
    assert [s.seed for s in specs[:3]] == [0, 1, 2]
    first = specs[0]
    assert first.extra == {
        "experiment": "event_suppression",
        "cfg.agent.soms.alpha": 0.5,
        "cfg.env.scene": "hand",
    }
    assert (first.repeat, first.config["repeats"], first.params) == (0, 2, {"phase": "hand"})
    assert [(s.extra["cfg.agent.soms.alpha"], s.extra["cfg.env.scene"]) for s in specs[::3]] == [
        (0.5, "hand"),
        (0.5, "office"),
        (0.8, "hand"),
        (0.8, "office"),
    ]


def test_sweep_file_errors_name_the_field(tmp_path):
    bad = {**TOY_SWEEP, "seed": [0]}
    with pytest.raises(ConfigError, match=r"sweep: unknown key\(s\) \['seed'\]"):
        sweep_from_dict(bad)
    bad = {**TOY_SWEEP, "experiments": [{"experiment": "detection", "grid": {"alpah": [1]}}]}
    with pytest.raises(ConfigError, match=r"experiments\[0\]: unknown key 'alpah'"):
        sweep_from_dict(bad)
    bad = {**TOY_SWEEP, "experiments": [{"experiment": "detection", "grid": {"alpha": 0.5}}]}
    with pytest.raises(ConfigError, match=r"grid.alpha: must be a non-empty list"):
        sweep_from_dict(bad)
    path = tmp_path / "s.yaml"
    path.write_text("name: x\nexperiments: [{experiment: nope}]\n")
    with pytest.raises(ConfigError, match="unknown experiment 'nope'"):
        load_sweep(path)


DETECTION = {"repeats": 1, "duration_s": 0.3, "scenes": ["gratings"], "camera_speeds_deg_s": [0]}


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (
            {"seeds": [0, 1, 0]},
            "s.yaml.seeds: must list each seed once (0 twice), got [0, 1, 0]",
        ),
        (
            {"experiments": [{"experiment": "detection", "grid": {"box": [4, 8, 4]}}]},
            "s.yaml.experiments[0].grid.box: must list each value once (4 twice), got [4, 8, 4]",
        ),
        (
            {"experiments": [{"experiment": "detection", "set": DETECTION, "grid": {"box": [0]}}]},
            "s.yaml.experiments[0]: box: must be in [1, 4096] px, got 0",
        ),
        (
            {"experiments": [{"experiment": "detection", "grid": {"box": [8, -3]}}]},
            "s.yaml.experiments[0].grid.box[1]: box: must be in [1, 4096] px, got -3",
        ),
        (
            {"experiments": [{"experiment": "detection", "grid": {"scenes": [["office"], []]}}]},
            "s.yaml.experiments[0].grid.scenes[1]: scenes: must list at least one value, got []",
        ),
    ],
)
def test_repeated_seeds_or_grid_values_and_bad_grid_values_are_one_line(change, message):
    with pytest.raises(ConfigError) as err:
        sweep_from_dict({**TOY_SWEEP, **change}, where="s.yaml")
    assert str(err.value) == message


@pytest.mark.parametrize(
    ("text", "line"),
    [
        (
            "name: x\nseeds: [0, 0]\nexperiments: [{experiment: detection}]\n",
            "wander sweep: error: s.yaml.seeds: must list each seed once (0 twice), got [0, 0]",
        ),
        (
            "name: x\nexperiments: [{experiment: detection, grid: {box: [0]}}]\n",
            "wander sweep: error: s.yaml.experiments[0]: box: must be in [1, 4096] px, got 0",
        ),
    ],
)
def test_cli_sweep_refuses_them_in_one_line_before_making_its_folder(
    text, line, tmp_path, monkeypatch
):
    from typer.testing import CliRunner

    from experiments.cli.main import app

    monkeypatch.chdir(tmp_path)
    (tmp_path / "s.yaml").write_text(text)
    res = CliRunner().invoke(app, ["sweep", "s.yaml"], prog_name="wander")
    assert (res.exit_code, res.stderr.splitlines(), res.stdout) == (2, [line], "")
    assert [p.name for p in tmp_path.iterdir()] == ["s.yaml"]  # no sweep folder


def test_a_grid_point_that_only_fails_in_combination_is_refused_before_any_trial(tmp_path):
    grid = {"step_s": [0.02, 0.5], "duration_s": [2.0, 0.3]}  # 0.5 s steps in a 0.3 s trial
    sweep = sweep_from_dict(
        {"name": "c", "experiments": [{"experiment": "detection", "set": DETECTION, "grid": grid}]},
        where="c.yaml",
    )
    runner = CountingRunner()
    with pytest.raises(ConfigError) as err:
        run_sweep(sweep, tmp_path / "out", backend="serial", runner=runner)
    assert str(err.value) == (
        "c.yaml.experiments[0].grid {'step_s': 0.5, 'duration_s': 0.3}: step_s: must be <= "
        "duration_s (0.3: one window at least), got 0.5"
    )
    assert runner.calls == [] and not (tmp_path / "out").exists()


def test_an_out_that_is_a_file_is_refused_naming_it(tmp_path):
    afile = tmp_path / "afile"
    afile.write_text("kept\n")
    with pytest.raises(FileExistsError) as err:
        run_sweep(sweep_from_dict(TOY_SWEEP), afile, backend="serial", runner=CountingRunner())
    assert str(err.value) == f"{str(afile)!r} exists and is not a folder"
    assert afile.read_text() == "kept\n"


def test_resume_skips_finished_trials_and_runs_only_missing_or_new_ones(tmp_path):
    sweep = sweep_from_dict(TOY_SWEEP)
    runner = CountingRunner()
    res = run_sweep(sweep, tmp_path, backend="serial", runner=runner)
    n = len(res.rows)
    assert (res.ran, res.skipped, len(runner.calls)) == (n, 0, n)
    table = (tmp_path / "results.csv").read_bytes()

    runner.calls.clear()
    res = run_sweep(sweep, tmp_path, backend="serial", runner=runner)
    assert (res.ran, res.skipped, runner.calls) == (0, n, [])
    assert (tmp_path / "results.csv").read_bytes() == table

    victim = res.rows[5]["trial_id"]
    (tmp_path / "trials" / f"{victim}.json").unlink()  # as if interrupted before it finished
    res = run_sweep(sweep, tmp_path, backend="serial", runner=runner)
    assert runner.calls == [victim] and (tmp_path / "results.csv").read_bytes() == table

    runner.calls.clear()
    grown = {**TOY_SWEEP, "experiments": [dict(TOY_SWEEP["experiments"][0])]}
    grown["experiments"][0]["grid"] = {
        "agent.soms.alpha": [0.5, 0.8, 0.9],
        "env.scene": ["hand", "office"],
    }
    res = run_sweep(sweep_from_dict(grown), tmp_path, backend="serial", runner=runner)
    assert len(runner.calls) == n // 2 and res.skipped == n
    rows = read_csv(tmp_path / "results.csv")
    assert [r["trial"] for r in rows] == list(range(len(rows)))
    assert list(rows[0])[:8] == [
        "trial",
        "trial_id",
        "repeat",
        "seed",
        "experiment",
        "cfg.agent.soms.alpha",
        "cfg.env.scene",
        "phase",
    ]


def test_local_processes_give_the_same_table_as_this_process(tmp_path):
    sweep = sweep_from_dict(TINY_SWEEP)
    run_sweep(sweep, tmp_path / "serial", backend="serial")
    run_sweep(sweep, tmp_path / "local", backend="local", workers=2)
    serial = (tmp_path / "serial" / "results.csv").read_bytes()
    assert serial == (tmp_path / "local" / "results.csv").read_bytes()
    rows = read_csv(tmp_path / "serial" / "results.csv")
    assert [(r["cfg.agent.soms.alpha"], r["windows"]) for r in rows] == [(0.5, 10), (0.8, 10)]


@pytest.mark.slow  # ~10 s on an idle machine, 20-40 s when the 2 cores are shared
def test_ray_backend_with_a_local_instance_gives_the_same_table(tmp_path, ray_instance):
    sweep = sweep_from_dict(TINY_SWEEP)
    run_sweep(sweep, tmp_path / "serial", backend="serial")
    res = run_sweep(sweep, tmp_path / "ray", backend="ray", workers=2)
    assert res.ran == 2
    serial = (tmp_path / "serial" / "results.csv").read_bytes()
    assert (tmp_path / "ray" / "results.csv").read_bytes() == serial
