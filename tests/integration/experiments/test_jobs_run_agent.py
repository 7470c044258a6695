"""``wander run``: the run folder, determinism, faults, scanpath statistics and figure."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import imageio.v2 as imageio
import numpy as np
import pytest
from typer.testing import CliRunner

from agents.attention import AGENT_SOMS_ALPHA
from experiments.analysis import scanpath_stats
from experiments.cli.main import app
from experiments.cli.options import AgentAlphaOpt, ConfigKey
from experiments.jobs.run_agent import RunConfig, run, run_closed_loop, video_frame
from experiments.jobs.scanpath_figure import saliency_mosaic
from wander_env.camera import pixel_to_world_angles
from wander_env.config import ConfigError, validate
from wander_env.env_config import WanderConfig
from wander_env.events.io import read_events


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("run")
    result = CliRunner().invoke(app, ["run", "--out", str(out), "--seconds", "1.5", "--seed", "4"])
    assert result.exit_code == 0, result.output
    return out


def test_run_folder_contents(run_dir: Path) -> None:
    names = {p.name for p in run_dir.iterdir()}
    assert {"run.json", "metrics.json", "scanpath.png", "run.mp4", "events.h5"} <= names
    m = json.loads((run_dir / "metrics.json").read_text())
    assert m["steps"] == 150 and m["simulated_s"] == pytest.approx(1.5)
    rec = read_events(run_dir / "events.h5")
    assert len(rec.events) == m["events"] and rec.sensor_size == (128, 128, 2)
    # Every event reached the agent but those of the last step (no action follows it).
    last_step = rec.events["t"] > round((m["steps"] - 1) * 1e4)
    assert m["events_into_agent"] == m["events"] - int(last_step.sum())
    assert 0 < m["events_kept_by_soms"] < m["events"]
    kept = m["events_kept_by_soms"] / m["events_into_agent"]
    assert m["soms_suppression"] == pytest.approx(1 - kept)
    run_json = json.loads((run_dir / "run.json").read_text())
    assert run_json["seed"] == 4 and run_json["config"]["env"]["scene"] == "office"
    assert run_json["git_revision"] and run_json["agent"]["window_s"] == 0.124
    soms = run_json["config"]["agent"]["soms"]
    assert soms["alpha"] == run_json["agent"]["soms"]["alpha"] == 0.8
    assert soms["norm"] == run_json["agent"]["soms"]["norm"] == "quantile"
    frames = imageio.mimread(run_dir / "run.mp4", memtest=False)
    assert len(frames) == 38  # 1.5 s at 25 frames a simulated second (--video-fps): 37.5
    assert frames[0].shape == (24 + 2 * 128 + 24, 4 * 2 * 128 + 3 * 4, 3)
    # One decision per window: the first after 13 steps, then after each saccade.
    assert m["decisions"] >= 1
    with open(run_dir / "fixations.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == m["decisions"]
    # the first window starts at the reset (t = 0) and lasts 12 steps of the run
    assert (rows[0]["t_start_s"], rows[0]["duration_s"]) == ("0.0", "0.12")
    # metrics.json's scanpath: the windows merged up to each that has a P (a saccade)
    windows = [[float(r[k]) for k in scanpath_stats.FIXATION_COLUMNS] for r in rows]
    merged = scanpath_stats.merged_fixations(windows, [r["target_x_px"] != "" for r in rows])
    assert m["scanpath"]["fixations"] == len(merged)
    assert m["scanpath"]["coverage_deg2"] == scanpath_stats.coverage(merged)


def test_alpha_is_checked_and_reaches_the_agent() -> None:
    with pytest.raises(
        ConfigError, match=r"^x: agent.soms.alpha: alpha must be in \[0, 1\], got 1\.5$"
    ):
        validate(RunConfig, {"agent": {"soms": {"alpha": 1.5}}}, where="x")
    result = CliRunner().invoke(app, ["run", "--alpha", "1.5", "--seconds", "0.1"])
    assert result.exit_code == 2 and result.output.endswith(
        " run: Invalid value for '--alpha': alpha must be in [0, 1], got 1.5\n"
    )
    # --alpha sets the agent block's key; unset, the run gets the agent's default.
    assert AgentAlphaOpt.__metadata__[1] == ConfigKey("agent.soms.alpha")
    assert RunConfig().agent.soms.alpha == AGENT_SOMS_ALPHA


def test_frame_source_reaches_the_env() -> None:
    # `wander run --frames/--keyframe-ms` (and evaluate, which runs `run` per seed) build
    # the env with them; before, RunConfig recorded them and gym.make never saw them.
    import gymnasium as gym

    config = RunConfig(
        WanderConfig(scene="shelf", episode_seconds=0.5, frames="exact", keyframe_ms=4.0)
    )
    kw = dict(**config.env)
    assert (kw["scene"], kw["frames"], kw["keyframe_ms"], kw["episode_seconds"]) == (
        "shelf",
        "exact",
        4.0,
        0.5,
    )
    env = gym.make("wander/Wander-v0", **kw)
    try:
        cfg = env.unwrapped.config
        assert (cfg.frames, cfg.keyframe_ms, cfg.episode_seconds) == ("exact", 4.0, 0.5)
        assert cfg.keyframe_px == 2.0
    finally:
        env.close()


def test_same_seed_same_scanpath(run_dir: Path, tmp_path: Path) -> None:
    run(tmp_path, RunConfig(WanderConfig(episode_seconds=1.5), seed=4, video=False))
    assert (tmp_path / "fixations.csv").read_text() == (run_dir / "fixations.csv").read_text()
    assert not (tmp_path / "run.mp4").exists()


class _FailingEnv:
    """Wraps an env and raises (like a PTU that stops answering) at a given step."""

    def __init__(self, env, fail_at: int) -> None:
        self.env, self.fail_at, self.k = env, fail_at, 0
        self.unwrapped = env.unwrapped
        self.observation_space = env.observation_space

    def reset(self, seed=None):
        return self.env.reset(seed=seed)

    def step(self, action):
        self.k += 1
        if self.k == self.fail_at:
            raise TimeoutError("PTU did not answer within 1.0 s")
        return self.env.step(action)


def test_fault_mid_run_still_writes_the_folder(tmp_path: Path) -> None:
    import gymnasium as gym

    from agents.attention import AgentParams, AttentionAgent

    env = gym.make("wander/Wander-v0", scene="shelf", ground_truth=False)
    agent = AttentionAgent(AgentParams.for_env(env), seed=0)
    with pytest.raises(TimeoutError, match="PTU did not answer"):
        run_closed_loop(_FailingEnv(env, 21), agent, 1.0, tmp_path, {"seed": 0}, video=False)
    m = json.loads((tmp_path / "metrics.json").read_text())
    assert m["steps"] == 20 and m["error"] == "TimeoutError: PTU did not answer within 1.0 s"
    assert len(read_events(tmp_path / "events.h5").events) == m["events"]
    agent.close()
    env.close()


def test_video_frame_marks_fovea_and_target() -> None:
    ev = np.zeros((2, 128, 128), np.float32)
    frame = video_frame(ev, ev, np.zeros((128, 128)), None, (100, 20), "t = 0.01 s", scale=2)
    assert frame.shape == (24 + 2 * 128 + 24, 3 * 256 + 2 * 4, 3)
    events_panel = frame[24 : 24 + 256, :256]  # below the 24-px header of panel names
    assert tuple(events_panel[128, 128]) == (0, 200, 0)  # fovea cross
    assert tuple(events_panel[(20 - 4) * 2, (100 - 4) * 2 + 5]) == (255, 0, 255)  # P box


def test_scanpath_statistics_exact() -> None:
    fx = np.array(
        [
            [0.0, 0.0, 0.0, 0.13],
            [10.0, 0.0, 1.0, 0.13],
            [10.0, 10.0, 2.0, 0.26],
            [1.0, 0.0, 3.0, 0.13],
        ]
    )
    amp = scanpath_stats.angular_distance(fx[:-1, :2], fx[1:, :2])
    assert amp[0] == pytest.approx(10.0) and amp[1] == pytest.approx(10.0)
    assert scanpath_stats.revisits(fx, radius_deg=2.0) == 1  # the 4th returns near the 1st
    s = scanpath_stats.scanpath_summary(fx, [True] * 4, np.zeros((0, 4)))
    assert s["fixations"] == 4 and s["fixation_duration_mean_s"] == 0.1625
    one = scanpath_stats.coverage(fx[:1], radius_deg=5.0, cell_deg=0.1)
    assert one == pytest.approx(np.pi * 25, rel=0.02)
    with pytest.raises(ValueError, match=r"\(n, 4\)"):
        scanpath_stats.revisits(np.zeros((3, 3)))


def test_saliency_mosaic_places_maps_by_gaze() -> None:
    f = 42.5
    m = np.zeros((128, 128))
    m[63, 63] = 1.0  # at the fovea
    grid = saliency_mosaic([m, m], [(0.0, 0.0), (20.0, -10.0)], focal_px=f, step_deg=0.5)

    def at(pan: float, tilt: float) -> float:
        return grid.values[np.abs(grid.tilt - tilt).argmin(), np.abs(grid.pan - pan).argmin()]

    assert at(0.0, 0.0) == 1.0 and at(20.0, -10.0) == 1.0 and at(10.0, -5.0) == 0.0
    # Every peak cell lies within one pixel's angle (≈1.35°) of a gaze direction.
    for i, j in np.argwhere(grid.values == 1.0):
        d = min(np.hypot(grid.pan[j] - p, grid.tilt[i] - t) for p, t in ((0, 0), (20, -10)))
        assert d < 1.5 * np.sqrt(2)
    pan, tilt = pixel_to_world_angles((63.5 + f, 63.5), (0.0, 0.0), f, (63.5, 63.5))
    assert pan == pytest.approx(-45.0) and tilt == 0.0


def test_run_rrd_logs_every_decision_and_movement(run_dir: Path) -> None:
    """run.rrd read back with Rerun's reader: one saliency map and P per decision, one
    annotation per fixation and per saccade, a gaze value per step."""
    from experiments.runs.viewer import read_recording as read_rrd

    m = json.loads((run_dir / "metrics.json").read_text())
    data = read_rrd(run_dir / "run.rrd")
    assert len(data[("/events", "SegmentationImage:buffer")]) == m["steps"] == 150
    assert len(data[("/oms", "SegmentationImage:buffer")]) == 150
    assert len(data[("/gaze/pan", "Scalars:scalars")]) == 150
    assert len(data[("/saliency", "Image:buffer")]) == m["decisions"]
    texts = [v[0] for _, v in data[("/annotations", "TextLog:text")]]
    assert sum(t.startswith("fixation ") for t in texts) == m["decisions"]
    assert sum(t.startswith("saccade ") for t in texts) == m["saccades"]
    with open(run_dir / "fixations.csv") as fh:
        rows = [r for r in csv.DictReader(fh) if r["target_x_px"] != ""]
    centres = [v[0] for _, v in data[("/saliency/P", "Boxes2D:centers")]]
    assert centres == [[float(r["target_x_px"]), float(r["target_y_px"])] for r in rows]


def test_metrics_and_run_json_are_strict_json_with_versions(run_dir: Path) -> None:
    def refuse(name: str) -> None:
        raise ValueError(f"non-standard JSON constant {name}")

    for name in ("metrics.json", "run.json"):
        json.loads((run_dir / name).read_text(), parse_constant=refuse)
    versions = json.loads((run_dir / "run.json").read_text())["versions"]
    assert set(versions) == {
        "python",
        "numpy",
        "mujoco",
        "torch",
        "sinabs",
        "nengo",
        "gymnasium",
        "wander",
    }
    assert all(versions[k] for k in versions if k != "wander")


def test_quality_reaches_the_env_and_a_bad_one_is_one_line(tmp_path):
    from typer.testing import CliRunner

    from experiments.cli.main import app
    from experiments.jobs.run_agent import RunConfig

    assert RunConfig().env["quality"] == "fast"
    assert RunConfig(WanderConfig(quality="fine")).env["quality"] == "fine"
    result = CliRunner().invoke(app, ["run", "--quality", "best", "--out", str(tmp_path / "r")])
    assert result.exit_code == 2 and result.output.endswith(
        " run: Invalid value for '--quality': expected one of 'fast', 'fine', got 'best'\n"
    )
    assert result.output.count("\n") == 1 and not (tmp_path / "r").exists()
