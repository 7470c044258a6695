"""The fixation table: one layout, one sign convention and the scene's object names in
``wander run``'s ``fixations.csv``, the scanpath experiment's ``fixations/*.csv`` and its
``results.csv``."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from experiments.cli.main import app
from experiments.fixation_table import (
    FIXATION_COLUMNS,
    fixation_times,
    normalise,
    write_fixations,
)
from wander_env.scene_config import load_scene_config


def test_times_start_at_zero_and_are_rounded_to_the_microsecond() -> None:
    assert fixation_times(-0.01, 0.13) == (0.0, 0.12)  # the end is kept
    assert fixation_times(0.7100000000000001, 0.9099999999999999) == (0.71, 0.91)
    got = normalise(np.array([[1.23456789, -0.5, -0.01, 0.13], [-2.0, 3.0, 0.5, 0.2]]))
    assert got.tolist() == [[1.234568, -0.5, 0.0, 0.12], [-2.0, 3.0, 0.5, 0.2]]


def test_write_fixations_writes_the_four_columns_then_the_extra_ones(tmp_path: Path) -> None:
    fx = np.array([[10.0, 5.0, -0.01, 0.26], [-3.0, 0.0, 0.25, 0.5]])
    path = write_fixations(tmp_path / "f.csv", fx, {"aoi": ["mug", "-"], "hit": [1, None]})
    assert path.read_text() == (
        "pan_deg,tilt_deg,t_start_s,duration_s,aoi,hit\n"
        "10.0,5.0,0.0,0.25,mug,1\n"
        "-3.0,0.0,0.25,0.5,-,\n"
    )
    with pytest.raises(ValueError, match="column 'aoi' has 1 values for 2 rows"):
        write_fixations(tmp_path / "g.csv", fx, {"aoi": ["mug"]})


def _csv(path: Path) -> list[dict[str, str]]:
    with path.open() as fh:
        return list(csv.DictReader(fh))


@pytest.fixture(scope="module")
def folders(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """One short ``wander run`` and one short scanpath experiment, office, seed 4."""
    root = tmp_path_factory.mktemp("naming")
    run, exp = root / "run", root / "exp"
    args = ["run", "--out", str(run), "--seconds", "1.5", "--seed", "4", "--no-video"]
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 0, result.output
    sets = ["scenes=[office]", "conditions=[fixational]", "repeats=1", "duration_s=1.5"]
    args = ["experiment", "scanpath", "--out", str(exp), "--seed", "4"]
    result = CliRunner().invoke(app, args + [x for s in sets for x in ("--set", s)])
    assert result.exit_code == 0, result.output
    return run, exp


def test_run_and_experiment_share_names_signs_and_units(folders: tuple[Path, Path]) -> None:
    run, exp = folders
    scene = load_scene_config("office")
    names = {o.name for o in (*scene.static_objects, *scene.moving_objects)}
    moving = {o.name for o in scene.moving_objects}
    assert moving == {"cube", "beach_ball"}

    run_rows = _csv(run / "fixations.csv")
    exp_rows = _csv(exp / "fixations" / "office_fixational_seed4.csv")
    (result,) = _csv(exp / "results.csv")
    assert list(run_rows[0])[:4] == list(exp_rows[0])[:4] == list(FIXATION_COLUMNS)
    assert list(exp_rows[0]) == [*FIXATION_COLUMNS, "aoi"]

    # Object names: the scene file's, in every file (never the model's object_k).
    run_objects = [r["target_object"] for r in run_rows]
    exp_aois = [r["aoi"] for r in exp_rows]
    assert exp_aois == json.loads(result["aois_json"]) == ["-", "cube"]
    assert run_objects == ["cube", "beach_ball"]
    assert set(run_objects) | set(exp_aois) <= names | {"-"}

    # One sign convention and the same units: the same agent and seed give the same
    # fixations in both files and in results.csv (each window here ended in a saccade).
    table = [[float(r[k]) for k in FIXATION_COLUMNS] for r in exp_rows]
    assert table == [[float(r[k]) for k in FIXATION_COLUMNS] for r in run_rows]
    assert table == json.loads(result["scanpath_json"])
    assert table == [[0.0, 0.0, 0.0, 0.12], [23.322849, 1.105714, 0.71, 0.13]]
    # + pan = left, + tilt = up: a P left of / above the fovea lies at a larger pan / tilt.
    for r in run_rows:
        x, y = float(r["target_x_px"]), float(r["target_y_px"])
        dpan = float(r["target_pan_deg"]) - float(r["pan_deg"])
        dtilt = float(r["target_tilt_deg"]) - float(r["tilt_deg"])
        assert (x < 63.5) == (dpan > 0) and (y < 63.5) == (dtilt > 0)
    # Times to the microsecond in results.csv too (no 9e-17 spread of equal durations).
    assert (result["fixation_duration_mean_s"], result["fixation_duration_std_s"]) == (
        "0.125",
        "0.005",
    )
