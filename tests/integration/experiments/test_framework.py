"""The experiment framework: typed --set overrides, trials, tables, result folders, CLI."""

from __future__ import annotations

import json
import math
import shutil
from dataclasses import dataclass
from typing import Literal

import numpy as np
import pytest
import typer
from typer.testing import CliRunner

from experiments.cli.experiment import register
from experiments.runs.folder import RunFolder
from experiments.runs.tables import read_csv, write_csv
from experiments.studies import framework
from experiments.studies.framework import (
    EXPERIMENT_NAMES,
    Comparison,
    ConfigError,
    Experiment,
    TrialSpec,
    coerce,
    config_from_dict,
    configs_dir,
    get_experiment,
    hold_folder,
    is_unfinished_run,
    load_artifacts,
    make_trials,
    parse_sets,
    resolve_config,
    run_experiment,
    run_spec,
    serial_executor,
    trial_id,
    unfinished_folder,
    write_result_folder,
)

# A tiny event_suppression run: the hand phase alone, 20 windows of 2 ms (two sOMS steps).
TINY = ["repeats=2", "phases=[hand]", "hand_s=[0.04, 0.04]", "lead_s=0"]


@dataclass(frozen=True)
class ToyConfig:
    """A config with one field of each supported kind."""

    n: int = 3
    x: float = 0.5
    name: str = "a"
    flag: bool = False
    mode: Literal["p", "q"] = "p"
    pairs: tuple[tuple[float, float], ...] = ((1.0, 2.0),)
    repeats: int = 2

    def __post_init__(self) -> None:
        if self.n < 0:
            raise ValueError(f"n must be >= 0, got {self.n}")


def toy_experiment() -> Experiment:
    def grid(cfg: ToyConfig) -> list[dict]:
        return [{"k": k} for k in range(cfg.n)]

    def run_trial(cfg: ToyConfig, spec: TrialSpec) -> dict:
        return {"value": spec.params["k"] * cfg.x + spec.seed, "_series": [1, 2, 3]}

    def compare(cfg: ToyConfig, rows: list) -> list[Comparison]:
        return [Comparison("sum", "6", str(sum(r["value"] for r in rows)))]

    return Experiment("toy", "A toy.", ToyConfig, grid, run_trial, compare=compare)


# ----------------------------------------------------------------------------------------
# Typed values and config resolution


def test_coerce_accepts_the_declared_types_and_refuses_others():
    assert coerce(2, float) == 2.0 and isinstance(coerce(2, float), float)
    assert coerce("1e-3", float) == 0.001
    assert coerce([[1, 2]], tuple[tuple[float, float], ...]) == ((1.0, 2.0),)
    assert coerce("q", Literal["p", "q"]) == "q"
    assert coerce(None, int | None) is None
    for value, tp, message in [
        (True, int, "expected int"),
        (1.5, int, "expected int"),
        ("x", float, "expected float"),
        ("r", Literal["p", "q"], "expected one of 'p', 'q'"),
        (1, bool, "expected bool"),
    ]:
        with pytest.raises(TypeError) as e:
            coerce(value, tp)
        assert str(e.value) == message, (value, tp)
    with pytest.raises(TypeError, match=r"expected list \[float, float\]"):
        coerce([1, 2, 3], tuple[float, float])


def test_parse_sets_reads_yaml_except_for_string_fields():
    got = parse_sets(["n=4", "pairs=[[0.5, 1]]", "flag=true", "name=on", "x=1e-3"], ToyConfig)
    assert got == {"n": 4, "pairs": [[0.5, 1]], "flag": True, "name": "on", "x": "1e-3"}
    cfg = config_from_dict(ToyConfig, got)
    assert cfg == ToyConfig(n=4, x=0.001, name="on", flag=True, pairs=((0.5, 1.0),))


def test_unknown_key_is_named_with_the_allowed_keys_and_types():
    with pytest.raises(ConfigError) as e:
        config_from_dict(ToyConfig, parse_sets(["nn=4"], ToyConfig), where="--set")
    msg = str(e.value)
    assert "unknown key 'nn'" in msg and msg.startswith("--set")
    assert (
        "allowed keys: n (int), x (float), name (str), flag (bool), mode (one of 'p', 'q')" in msg
    )
    assert "pairs (list of list [float, float])" in msg


def test_bad_value_names_the_key_the_type_and_the_value():
    with pytest.raises(ConfigError, match=r"x: expected float, got 'abc'"):
        config_from_dict(ToyConfig, parse_sets(["x=abc"], ToyConfig))
    with pytest.raises(ConfigError, match=r"mode: expected one of 'p', 'q'"):
        config_from_dict(ToyConfig, {"mode": "r"})
    with pytest.raises(ConfigError, match=r"n must be >= 0, got -1"):  # the dataclass's own check
        config_from_dict(ToyConfig, {"n": -1})
    with pytest.raises(ConfigError, match="expected key=value"):
        parse_sets(["n"], ToyConfig)


def test_every_registered_experiment_has_a_default_config_file_equal_to_its_defaults():
    for name in EXPERIMENT_NAMES:
        exp = get_experiment(name)
        assert (configs_dir() / f"{name}.yaml").is_file()
        assert resolve_config(exp) == exp.config_type()
        assert exp.name == name and callable(exp.compare) and callable(exp.plot)


def test_config_file_then_set_override_the_defaults(tmp_path):
    exp = get_experiment("event_suppression")
    path = tmp_path / "c.yaml"
    path.write_text("agent: {soms: {alpha: 0.5}}\nrepeats: 3\n")
    cfg = resolve_config(exp, path, ["repeats=4"])
    assert (cfg.agent.soms.alpha, cfg.repeats, cfg.window_s) == (0.5, 4, 0.002)
    path.write_text("alpah: 0.5\n")
    with pytest.raises(ConfigError, match=rf"{path}: unknown key 'alpah'"):
        resolve_config(exp, path)


def test_unknown_experiment_lists_the_known_ones():
    with pytest.raises(ConfigError, match="unknown experiment 'nope'; available: oms_char"):
        get_experiment("nope")


# ----------------------------------------------------------------------------------------
# Trials and tables


def test_trials_repeat_the_grid_with_consecutive_seeds_and_stable_ids():
    specs = make_trials(toy_experiment(), ToyConfig(n=2, repeats=2), seed=10)
    assert [(s.params["k"], s.repeat, s.seed, s.index) for s in specs] == [
        (0, 0, 10, 0),
        (0, 1, 11, 1),
        (1, 0, 10, 2),
        (1, 1, 11, 3),
    ]
    assert len({s.id for s in specs}) == 4
    assert specs[0].id == trial_id("toy", specs[0].config, {"k": 0}, 10)
    assert specs[0].id != trial_id("toy", {**specs[0].config, "x": 0.6}, {"k": 0}, 10)
    assert len(specs[0].id) == 16


def test_csv_round_trip_keeps_types_and_exact_floats(tmp_path):
    rows = [
        {"a": 1, "b": 0.1 + 0.2, "c": "eye+object", "d": True, "e": math.nan},
        {"a": 2, "b": 1e-17, "c": "x,y", "d": False, "e": 3.0},
    ]
    path = write_csv(rows, tmp_path / "t.csv")
    assert path.read_text().splitlines()[1] == "1,0.30000000000000004,eye+object,true,"
    back = read_csv(path)
    assert back[1] == rows[1]
    assert back[0]["b"] == 0.1 + 0.2 and math.isnan(back[0]["e"]) and back[0]["d"] is True


def test_csv_columns_fix_order_and_header_and_refuse_other_keys(tmp_path):
    rows = [{"b": np.float64(0.1), "a": 1}, {"a": 2, "_art": [1]}]
    path = write_csv(rows, tmp_path / "t.csv", columns=["a", "b", "c"])
    assert path.read_text() == "a,b,c\n1,0.1,\n2,,\n"  # NumPy's float64 as the float
    assert write_csv([], tmp_path / "e.csv", columns=["a", "b"]).read_text() == "a,b\n"
    with pytest.raises(ValueError, match=r"row keys \['b'\] are not among the columns \['a'\]"):
        write_csv(rows, tmp_path / "x.csv", columns=["a"])


def test_trial_ids_that_look_like_numbers_read_back_as_text(tmp_path):
    """A trial id is 16 hex digits: all digits, or digits around one ``e``, it read back
    as an int or a float (``inf``), and the report refused the sweep's table."""
    ids = ["8462951001639847", "12e4567890123456", "96fb95b94aed619d"]
    rows = [{"trial": i, "trial_id": t, "value": 0.5} for i, t in enumerate(ids)]
    back = read_csv(write_csv(rows, tmp_path / "results.csv"))
    assert [r["trial_id"] for r in back] == ids
    assert back == rows


def test_result_folder_has_table_config_run_record_summary_and_artifacts(tmp_path):
    exp = toy_experiment()
    cfg = ToyConfig(n=3, repeats=1)
    rows = [
        {"trial": s.index, "trial_id": s.id, **s.params, **exp.run_trial(cfg, s)}
        for s in make_trials(exp, cfg, 0)
    ]
    write_result_folder(tmp_path, exp, cfg, rows, 0, "wander experiment toy", {"total_s": 1.0})
    assert read_csv(tmp_path / "results.csv") == [
        {"trial": i, "trial_id": rows[i]["trial_id"], "k": i, "value": 0.5 * i} for i in range(3)
    ]
    assert json.loads((tmp_path / "config.json").read_text())["pairs"] == [[1.0, 2.0]]
    run = json.loads((tmp_path / "run.json").read_text())
    assert run["seed"] == 0 and run["git_revision"] and run["command"] == "wander experiment toy"
    assert run["experiment"] == "toy" and run["timing"] == {"total_s": 1.0}
    assert "| sum | 6 | 1.5 |" in (tmp_path / "summary.md").read_text()
    assert load_artifacts(tmp_path, rows[2])["series"].tolist() == [1, 2, 3]


def test_same_seed_gives_identical_csv_bytes_and_another_seed_does_not(tmp_path):
    exp = get_experiment("event_suppression")
    cfg = resolve_config(exp, sets=TINY)
    run_experiment("event_suppression", cfg, 3, tmp_path / "a")
    run_experiment("event_suppression", cfg, 3, tmp_path / "b")
    assert (tmp_path / "a" / "results.csv").read_bytes() == (
        tmp_path / "b" / "results.csv"
    ).read_bytes()
    rows = read_csv(tmp_path / "a" / "results.csv")
    assert [(r["trial"], r["repeat"], r["seed"], r["windows"]) for r in rows] == [
        (0, 0, 3, 20),
        (1, 1, 4, 20),
    ]
    assert rows[0]["events_in_mean"] != rows[1]["events_in_mean"]  # seeds 3 and 4 differ
    assert sorted(p.name for p in (tmp_path / "a").iterdir()) == [
        "artifacts",
        "config.json",
        "event_suppression.png",
        "results.csv",
        "run.json",
        "summary.md",
        "trials",
    ]


class StoppingRunner:
    """Stands in for ``run_spec``: a row from the spec (no simulation), calls counted; a
    KeyboardInterrupt (a Ctrl-C) in call number ``stop_at``."""

    def __init__(self, stop_at: int | None = None) -> None:
        self.calls: list[str] = []
        self.stop_at = stop_at

    def __call__(self, spec: TrialSpec) -> dict:
        if len(self.calls) + 1 == self.stop_at:
            raise KeyboardInterrupt
        self.calls.append(spec.id)
        row = {"trial": spec.index, "trial_id": spec.id, "repeat": spec.repeat, "seed": spec.seed}
        return {**row, **spec.params, "value": spec.index * 0.1 + spec.seed, "nan": math.nan}


def _run(cfg, out, runner):  # type: ignore[no-untyped-def]
    return run_experiment("toy", cfg, 7, out, executor=lambda s: serial_executor(s, runner))


def test_a_stopped_experiment_reruns_to_completion_keeping_its_finished_trials(
    tmp_path, monkeypatch
):
    toy = toy_experiment()
    monkeypatch.setattr(framework, "get_experiment", lambda name: toy)
    cfg, other = ToyConfig(n=4, repeats=1), ToyConfig(n=4, repeats=1, x=0.25)
    ids = [s.id for s in make_trials(toy, cfg, 7)]
    root = tmp_path / "results"
    out = root / "toy" / "20260101-000000-seed7"
    stopped = StoppingRunner(stop_at=3)
    with pytest.raises(KeyboardInterrupt):
        _run(cfg, out, stopped)
    assert stopped.calls == ids[:2]
    assert sorted(p.name for p in (out / "trials").iterdir()) == sorted(
        f"{i}.json" for i in ids[:2]
    )
    assert not (out / "results.csv").exists()
    RunFolder(out).record_failure(RuntimeError("stopped"))  # as the CLI records a stop
    # A rerun finds the folder: the one given, or the newest unfinished one of the default name
    assert unfinished_folder("toy", cfg, 7, out) == out
    assert unfinished_folder("toy", cfg, 7, None, root=root) == out
    assert unfinished_folder("toy", cfg, 8, None, root=root) is None  # another seed
    assert unfinished_folder("toy", other, 7, None, root=root) is None  # another config
    with hold_folder(out):  # a run still writing there is not resumed
        assert unfinished_folder("toy", cfg, 7, out) is None
    # a damaged folder beside it is not resumed, and does not stop the search
    damaged = root / "toy" / "20260102-000000-seed7"
    damaged.mkdir()
    (damaged / "config.json").write_text('{"experiment": "toy", "n": ')
    assert not is_unfinished_run(damaged, "toy", cfg, 7)
    assert unfinished_folder("toy", cfg, 7, None, root=root) == out
    shutil.rmtree(damaged)
    rerun = StoppingRunner()
    rows, _ = _run(cfg, out, rerun)
    assert rerun.calls == ids[2:]  # the two finished trials were not run again
    assert [r["trial_id"] for r in rows] == ids and math.isnan(rows[0]["nan"])
    whole = StoppingRunner()
    _run(cfg, tmp_path / "whole", whole)
    assert whole.calls == ids
    assert (out / "results.csv").read_bytes() == (tmp_path / "whole" / "results.csv").read_bytes()
    run = json.loads((out / "run.json").read_text())
    assert (run["timing"]["ran"], run["timing"]["resumed"], run["seed"]) == (2, 2, 7)
    assert run["stops"] == [{"error": "RuntimeError: stopped"}]
    assert not (out / "metrics.json").exists()  # the folder says only how this run ended
    assert not is_unfinished_run(out, "toy", cfg, 7)  # finished: a rerun starts anew


# ----------------------------------------------------------------------------------------
# Command line


def _app() -> typer.Typer:
    app = typer.Typer(pretty_exceptions_enable=False)
    register(app)
    return app


def test_cli_experiment_writes_the_folder_and_report_reads_it(tmp_path):
    runner = CliRunner()
    out = tmp_path / "results" / "event_suppression" / "run1"
    args = ["experiment", "event_suppression", "--seed", "5", "--out", str(out)]
    for s in [*TINY, "repeats=1"]:
        args += ["--set", s]
    res = runner.invoke(_app(), args)
    assert res.exit_code == 0, res.output
    assert json.loads((out / "run.json").read_text())["seed"] == 5
    assert json.loads((out / "config.json").read_text())["repeats"] == 1
    report = tmp_path / "REPORT.md"
    res = runner.invoke(
        _app(), ["report", "--results", str(tmp_path / "results"), "--out", str(report)]
    )
    assert res.exit_code == 0, res.output
    text = report.read_text()
    assert "## event_suppression" in text and "| events suppressed | 85.16 % |" in text
    assert "Not run yet: `wander experiment detection`." in text
    assert (tmp_path / "report_figures" / "event_suppression" / "event_suppression.png").is_file()


def test_cli_rejects_unknown_keys_and_bad_values_by_name():
    runner = CliRunner()
    res = runner.invoke(_app(), ["experiment", "detection", "--set", "alph=1"])
    assert res.exit_code == 2
    assert "unknown key 'alph'" in res.output and "agent (AgentParams)" in res.output
    res = runner.invoke(_app(), ["experiment", "detection", "--set", "agent.soms.alpha=abc"])
    assert res.exit_code == 2 and "agent.soms.alpha: expected float, got 'abc'" in res.output
    res = runner.invoke(_app(), ["experiment", "detection", "--set", "agent.soms.alpha=2"])
    assert res.exit_code == 2
    assert "agent.soms.alpha: alpha must be in [0, 1], got 2.0" in res.output
    res = runner.invoke(_app(), ["experiment", "detection", "--show-config", "--set", "repeats=1"])
    assert res.exit_code == 0 and '"repeats": 1' in res.output


def test_check_lists_refuses_empty_lists_and_values_listed_twice():
    @dataclass(frozen=True)
    class Lists:
        scenes: tuple[str, ...] = ("office",)
        pairs: tuple[tuple[float, float], ...] = ()

        def __post_init__(self) -> None:
            framework.check_lists(self, ("scenes",))
            framework.check_lists(self, ("pairs",), allow_empty=True)

    assert Lists().pairs == ()
    for kwargs, message in (
        ({"scenes": ()}, "scenes: must list at least one value, got []"),
        (
            {"pairs": ((1.0, 2.0), (3.0, 4.0), (1.0, 2.0))},
            "pairs: must list each value once ((1.0, 2.0) twice), got [(1.0, 2.0), "
            "(3.0, 4.0), (1.0, 2.0)]",
        ),
    ):
        with pytest.raises(ValueError) as err:
            Lists(**kwargs)
        assert str(err.value) == message
    assert framework.repeated([0, 1, 0, 0, {"a": [1]}, {"a": [1]}]) == [0, {"a": [1]}]


_ERR = "wander experiment: error:"
# (command line, the one line on stderr): each a config whose trials cannot run or would
# run nothing, or the same trials twice
REFUSED = [
    (["detection", "--set", "box=0"], f"{_ERR} --set: box: must be in [1, 4096] px, got 0"),
    (
        ["detection", "--set", "step_s=1e30"],
        f"{_ERR} --set: step_s: must be a whole number of ms in (0, 1] s, got 1e+30",
    ),
    (
        ["detection", "--set", "scenes=[]"],
        f"{_ERR} --set: scenes: must list at least one value, got []",
    ),
    (
        ["oms_characterisation", "--set", "groups=[]"],
        f"{_ERR} --set: groups: must list at least one value, got []",
    ),
    (
        ["oms_characterisation", "--set", "frequency_pairs=[[0,1]]"],
        f"{_ERR} --set: frequency_pairs[0]: (background, object) cycles/deg must be > 0, "
        "got [0.0, 1.0]",
    ),
    (
        ["oms_scorecard", "--set", "periods=[0]"],
        f"{_ERR} --set: periods: must be in [2, 256] px (the texture tile), got [0]",
    ),
    (
        ["oms_scorecard", "--set", "parts=[real]", "--set", "real_dir=nodir"],
        f"{_ERR} real_dir: nodir/poster_6dof_events_txyp.npy not found (the real part reads "
        "it: set real_dir, or leave real out of parts), got 'nodir'",
    ),
    (
        ["oms_scorecard", "--set", "parts=[office]", "--set", "office_results=[no.json]"],
        f"{_ERR} office_results[0]: no.json: no such file",
    ),
    (
        ["scanpath", "--set", "conditions=[]"],
        f"{_ERR} --set: conditions: must list at least one value, got []",
    ),
    (
        ["sac_accuracy", "--set", "conditions=[ideal, ideal]"],
        f"{_ERR} --set: conditions: must list each value once ('ideal' twice), got "
        "['ideal', 'ideal']",
    ),
    (
        ["saccade_speed", "--set", "speeds_pos_s=[]"],
        f"{_ERR} --set: speeds_pos_s: must list at least one value, got []",
    ),
]


@pytest.mark.parametrize(("args", "line"), REFUSED)
def test_cli_refuses_such_a_config_in_one_line_before_making_its_folder(
    args, line, tmp_path, monkeypatch
):
    from experiments.cli.main import app

    monkeypatch.chdir(tmp_path)
    res = CliRunner().invoke(app, ["experiment", *args], prog_name="wander")
    assert (res.exit_code, res.stderr.splitlines(), res.stdout) == (2, [line], "")
    assert list(tmp_path.iterdir()) == []  # no result folder


@pytest.mark.slow
def test_cli_experiment_resumes_the_run_it_stopped(tmp_path):
    exp = get_experiment("event_suppression")
    cfg = resolve_config(exp, sets=TINY)  # 2 trials
    out = tmp_path / "run"
    calls: list[str] = []

    def first_only(spec: TrialSpec) -> dict:
        if calls:
            raise KeyboardInterrupt
        calls.append(spec.id)
        return run_spec(spec)

    with pytest.raises(KeyboardInterrupt):
        run_experiment(
            "event_suppression", cfg, 0, out, executor=lambda s: serial_executor(s, first_only)
        )
    args = ["experiment", "event_suppression", "--out", str(out)]
    for s in TINY:
        args += ["--set", s]
    res = CliRunner().invoke(_app(), args)
    assert res.exit_code == 0, res.output
    assert "2 trials, 1 kept from the stopped run ->" in " ".join(res.output.split())
    run = json.loads((out / "run.json").read_text())
    assert (run["timing"]["ran"], run["timing"]["resumed"]) == (1, 1)
    assert [r["trial_id"] for r in read_csv(out / "results.csv")] == [
        s.id for s in make_trials(exp, cfg, 0)
    ]
