"""A run reproducible from its folder: run.json holds the resolved scene and the SHA-256
of every file the run read; ``wander rerun RUN_DIR`` runs it again with identical events,
and refuses (one line) when a file it read changed."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import h5py
import pytest
import yaml
from scene_files import write_arm, write_cube_obj
from typer.testing import CliRunner

from experiments.cli.main import app
from experiments.runs.provenance import input_record
from wander_env.config import to_plain
from wander_env.scenes import load_scene_config


def sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def events_digest(folder: Path) -> str:
    """SHA-256 of events.h5's x, y, t and p arrays."""
    with h5py.File(folder / "events.h5", "r") as f:
        return hashlib.sha256(b"".join(f["events"][k][()].tobytes() for k in "xytp")).hexdigest()


def write_scene(folder: Path) -> Path:
    """A scene file with a moving mesh cube and an included MJCF arm (with its mesh)."""
    write_cube_obj(folder / "cube.obj")
    (folder / "robots").mkdir()
    write_arm(folder / "robots")
    scene = {
        "moving_objects": [
            {
                "name": "cube",
                "shape": "mesh",
                "mesh": {"file": "cube.obj", "scale": 0.2},
                "trajectory": {
                    "kind": "linear_bounce",
                    "start": [1.0, 0.1, 1.0],
                    "velocity": [0.0, -1.0, 0.0],
                    "bounds_min": [1.0, -0.4, 1.0],
                    "bounds_max": [1.0, 0.4, 1.0],
                },
            }
        ],
        "mjcf_includes": [{"file": "robots/arm.xml", "name": "arm", "position": [1.5, 0.5, 0.8]}],
    }
    path = folder / "scene.yaml"
    path.write_text(yaml.safe_dump(scene))
    return path


def test_the_inputs_are_the_resolved_scene_and_every_file_it_read(tmp_path):
    scene = write_scene(tmp_path)
    inputs = input_record({"env": {"scene": str(scene)}, "camera": "replay:" + str(scene)})
    read = [
        scene,
        tmp_path / "cube.obj",
        tmp_path / "robots/arm.xml",
        tmp_path / "robots/tetra.obj",
    ]
    assert inputs["files"] == {str(p): sha256(p) for p in read}
    assert inputs["scenes"] == {str(scene): to_plain(load_scene_config(scene))}
    assert inputs["scenes"][str(scene)]["moving_objects"][0]["mesh"]["file"] == str(
        tmp_path / "cube.obj"
    )


@pytest.mark.slow
def test_a_run_reruns_from_its_folder_with_identical_events(tmp_path, monkeypatch):
    write_scene(tmp_path)
    monkeypatch.chdir(tmp_path)
    runner = CliRunner()
    args = ["--seconds", "0.2", "--no-video", "--seed", "3"]
    first = runner.invoke(app, ["run", "--scene", "scene.yaml", *args, "--out", "A"])
    assert first.exit_code == 0, first.output
    record = json.loads((tmp_path / "A" / "run.json").read_text())
    assert sorted(record["inputs"]["files"]) == sorted(
        str(tmp_path / p) for p in ("scene.yaml", "cube.obj", "robots/arm.xml", "robots/tetra.obj")
    )
    assert record["inputs"]["scenes"]["scene.yaml"]["mjcf_includes"][0]["name"] == "arm"

    again = runner.invoke(app, ["rerun", "A", "--out", "B"])
    assert again.exit_code == 0, again.output
    assert events_digest(tmp_path / "B") == events_digest(tmp_path / "A")
    rerun = json.loads((tmp_path / "B" / "run.json").read_text())
    # the rerun reads the scene from run.json (as it resolved), then the files it names
    read = {k: v for k, v in record["inputs"]["files"].items() if not k.endswith("scene.yaml")}
    assert rerun["seed"] == 3 and rerun["inputs"]["files"] == read

    before = sha256(tmp_path / "robots" / "tetra.obj")
    with open(tmp_path / "robots" / "tetra.obj", "a") as f:
        f.write("# edited\n")
    refused = runner.invoke(app, ["rerun", "A", "--out", "C"], prog_name="wander")
    assert refused.exit_code == 2
    assert refused.stderr.splitlines() == [
        f"wander rerun: error: A/run.json: inputs.files: {tmp_path / 'robots' / 'tetra.obj'} "
        f"changed since the run (SHA-256 {before[:12]}..., now "
        f"{sha256(tmp_path / 'robots' / 'tetra.obj')[:12]}...): the rerun would differ"
    ]
    assert not (tmp_path / "C").exists()


def test_a_folder_of_another_command_is_refused(tmp_path):
    (tmp_path / "run.json").write_text(json.dumps({"command": "wander demo", "config": {}}))
    result = CliRunner().invoke(app, ["rerun", str(tmp_path)], prog_name="wander")
    assert result.exit_code == 2
    assert result.stderr.splitlines() == [
        f"wander rerun: error: {tmp_path / 'run.json'}: command: 'wander demo' is not a "
        "'wander run' run"
    ]
