"""``wander rig`` end to end (PTU emulator + replayed events) and its device faults."""

from __future__ import annotations

import csv
import doctest
import json
import math
import re
import sys
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import serial
import typer
from fake_samna import FakeSamna, FakeSpeck, forget_dynapcnn, install
from typer.testing import CliRunner

import experiments.jobs.rig as rig_module
import hardware.rig_env as rig_env
from agents.attention import AgentParams, AttentionAgent
from agents.control import normalised_error
from agents.speck_limits import SpeckLimitError
from experiments.cli.rig import dropped_warning, register, summary_line
from experiments.jobs.rig import RigRunConfig, RigRunError, run_rig
from hardware.ptu_driver import FlirPTU, FlirPTUParams, PTUTimeout
from hardware.ptu_emulator import PTUEmulator, PTUEmulatorParams
from hardware.rig_env import RigConfig
from hardware.speck import SpeckParams
from hardware.speck_network import ChipPipeline
from wander_env.actions import action_to_gaze_degrees
from wander_env.camera import SPECK_HFOV_DEG, focal_length_px
from wander_env.events import EVENT_DTYPE, make_events
from wander_env.events.io import EventRecording, read_events, write_events
from wander_env.ptu.params import PTUParams
from wander_env.readout import DvsLayerParams, ReadoutParams

RES = PTUParams().pan_resolution_arcsec  # 92.5714″ on both axes of the emulated unit
T_OFFSET = 5_000_000  # the synthetic file's first timestamp (µs); the replay rebases it to 0
# A unit quick enough that a saccade has settled well inside a short run (the emulated unit
# moves on the wall clock; the stepped replay's steps take at least its serial exchanges).
QUICK = PTUEmulatorParams(
    ptu=PTUParams(
        pan_speed=100_000.0,
        tilt_speed=100_000.0,
        pan_upper_speed=100_000.0,
        tilt_upper_speed=100_000.0,
        pan_accel=1e7,
        tilt_accel=1e7,
    )
)
MOVE = re.compile(r"([PT])P(-?\d+)")  # an absolute move (a bare "PP"/"TP" is a poll)
FILES = {"events.h5", "fixations.csv", "metrics.json", "run.json", "run.rrd", "scanpath.png"}


def write_square(path: Path, seconds: float, every_us: int = 2000) -> np.ndarray:
    """A dense 10×10 square of events (x 70-79, y 66-75 at first) moving right at 10 px/s,
    right of and below the centre, every pixel firing every ``every_us``; returns the
    events rebased to 0."""
    rng = np.random.default_rng(0)
    gx, gy = (g.ravel() for g in np.meshgrid(np.arange(10), np.arange(10)))
    parts = []
    for t in range(0, round(seconds * 1e6), every_us):
        x0 = 70 + int(10.0 * t / 1e6)
        parts.append((x0 + gx, 66 + gy, np.full(100, t + T_OFFSET), rng.integers(0, 2, 100)))
    x, y, t, p = (np.concatenate(c) for c in zip(*parts, strict=True))
    ev = make_events(x, y, t, p)
    write_events(path, EventRecording(ev, (128, 128, 2)))
    out = ev.copy()
    out["t"] -= T_OFFSET
    return out


@pytest.fixture(scope="module")
def square(tmp_path_factory) -> tuple[str, np.ndarray]:
    """``replay:<file>`` of a 3 s moving square, and its rebased events."""
    path = tmp_path_factory.mktemp("replay") / "square.npz"
    return f"replay:{path}", write_square(path, 3.0)


@pytest.fixture(scope="module")
def app() -> typer.Typer:
    app = typer.Typer(add_completion=False, pretty_exceptions_enable=False)

    @app.callback()
    def main() -> None:
        """The test's root app (as ``wander``)."""

    register(app)
    return app


@pytest.fixture
def emu():
    with PTUEmulator(QUICK) as e:
        yield e


def invoke(app: typer.Typer, *args: str):
    return CliRunner().invoke(app, ["rig", *args])


def run_emulated(app: typer.Typer, camera: str, out: Path, seconds: str, *extra: str):
    """``wander rig`` on an emulated PTU (``--ptu emulate``) with ``camera`` for
    ``seconds``, into ``out``; ``extra``: more options."""
    args = ("--ptu", "emulate", "--camera", camera, "--seconds", seconds)
    return invoke(app, *args, *extra, "--out", str(out))


def run_stepped(
    app: typer.Typer, emu: PTUEmulator, camera: str, out: Path, seconds: str, *extra: str
):
    """``wander rig`` on the emulator with the stepped replay of ``camera`` for ``seconds``,
    no video, into ``out``; ``extra``: more options."""
    args = ("--ptu", emu.port, "--camera", camera, "--replay", "stepped", "--seconds", seconds)
    return invoke(app, *args, *extra, "--no-video", "--out", str(out))


def read_folder(out: Path) -> tuple[dict, dict, list[dict]]:
    metrics = json.loads((out / "metrics.json").read_text())
    run = json.loads((out / "run.json").read_text())
    rows = []
    if (out / "fixations.csv").is_file():
        with open(out / "fixations.csv") as fh:
            rows = list(csv.DictReader(fh))
    return metrics, run, rows


def assert_events_of_steps(out: Path, expected: np.ndarray, metrics: dict) -> None:
    """``events.h5`` holds exactly the replay's events of the run's 10 ms windows, from the
    episode's start ``t0_us`` (a real-time replay runs while the agent is built, and
    ``reset`` drops what came before it) for ``steps`` windows, times relative to it."""
    rec = read_events(out / "events.h5")
    t0, steps = metrics["rig"]["t0_us"], metrics["steps"]
    want = expected[(expected["t"] >= t0) & (expected["t"] < t0 + steps * 10_000)].copy()
    want["t"] -= t0
    assert rec.sensor_size == (128, 128, 2)
    assert len(rec.events) == len(want) == metrics["events"]
    for f in ("x", "y", "t", "p"):
        np.testing.assert_array_equal(rec.events[f], want[f])


def moves(emu: PTUEmulator) -> list[tuple[str, int]]:
    """The absolute moves the emulator received, in order."""
    return [(m[1], int(m[2])) for c in emu.commands if (m := MOVE.fullmatch(c))]


def on_first_move(monkeypatch, emu: PTUEmulator, action: Callable[[], None]) -> None:
    """Run ``action`` right after the host's first move to ``emu`` has been answered, in
    the host's thread: the exchange after it (with a stepped replay, the poll that follows
    the command) meets the fault, however loaded the machine is."""
    move_to = FlirPTU.move_to
    fired: list[bool] = []

    def moved_then_act(self: FlirPTU, *args, **kwargs):
        out = move_to(self, *args, **kwargs)
        if self.url == emu.port and not fired:
            fired.append(True)
            action()
        return out

    monkeypatch.setattr(FlirPTU, "move_to", moved_then_act)


# -- end to end ------------------------------------------------------------------------------


@pytest.fixture
def patient_driver(monkeypatch):
    """`wander rig` with PTU reply timeouts a loaded machine cannot starve (5 s, not 1 s),
    for tests whose fault (if any) is not the PTU's."""
    from experiments.jobs.rig import RigRunConfig

    checked = RigRunConfig.__post_init__
    patient = FlirPTUParams(timeout_s=5.0, halt_timeout_s=2.0, banner_quiet_s=0.02)

    def with_patient_driver(self):
        checked(self)
        object.__setattr__(self, "env", replace(self.env, driver=patient))

    monkeypatch.setattr(RigRunConfig, "__post_init__", with_patient_driver)


def test_emulated_ptu_and_replay_end_to_end(app, square, tmp_path, monkeypatch, patient_driver):
    """The issue's dry run: ``wander rig --ptu emulate --camera replay:<file>``."""
    camera, expected = square
    emulators: list[PTUEmulator] = []

    class Recorded(PTUEmulator):
        def __init__(self, params: PTUEmulatorParams | None = None) -> None:
            super().__init__(params)
            emulators.append(self)

    monkeypatch.setattr(rig_env, "PTUEmulator", Recorded)
    out = tmp_path / "run"
    extra = ("--seed", "3", "--streamlined", "--set", "agent.soms.alpha=0.6")
    result = run_emulated(app, camera, out, "0.5", *extra)
    assert result.exit_code == 0, result.output
    assert {p.name for p in out.iterdir()} == FILES | {"run.mp4"}
    metrics, run, rows = read_folder(out)
    assert (metrics["steps"], metrics["simulated_s"]) == (50, 0.5)
    assert "error" not in metrics
    assert (metrics["rig"]["t0_us"], metrics["rig"]["discarded_at_reset"]) == (0, 0)  # fast
    assert_events_of_steps(out, expected, metrics)
    assert metrics["events"] == np.count_nonzero(expected["t"] < 500_000) == 25_000
    assert run["summary"] == {"steps": 50, "events": 25_000}
    # run.json: the config, and what the devices reported.
    assert run["command"] == "wander rig" and run["seed"] == 3
    cfg, env = run["config"], run["config"]["env"]
    assert (env["ptu_port"], env["camera"], env["replay"], env["episode_seconds"]) == (
        "emulate",
        camera,
        "fast",
        0.5,
    )
    agent = cfg["agent"]
    assert (agent["window_s"], agent["fixational"], cfg["video"]) == (0.124, True, True)
    # --set agent.soms.alpha and --streamlined (agent.proto.polarity_split), read back
    assert agent["soms"]["alpha"] == run["agent"]["soms"]["alpha"] == 0.6
    assert agent["proto"]["polarity_split"] is run["agent"]["proto"]["polarity_split"] is False
    ptu = run["rig"]["ptu"]
    assert ptu["emulated"] is True and ptu["url"] == emulators[0].port
    assert ptu["resolution_arcsec"] == [RES, RES]
    assert ptu["pan_limits_deg"] == [-3090 * RES / 3600, 3090 * RES / 3600]
    assert ptu["tilt_limits_deg"] == [-907 * RES / 3600, 604 * RES / 3600]
    assert run["rig"]["camera"] == {
        "kind": "replay",
        "sensor_size": [128, 128, 2],
        "file": camera[7:],
        "n_events": len(expected),
        "duration_us": int(expected["t"][-1]) + 1,
        "t_offset_us": T_OFFSET,
    }
    assert run["agent"]["width_px"] == 128 and run["agent"]["step_s"] == 0.01
    # The field of view assumed (the Speck's by default) and the replay's fixed view,
    # which the scanpath figure draws in the sensor's frame.
    assert run["rig"]["hfov_deg"] == run["agent"]["hfov_deg"] == SPECK_HFOV_DEG
    assert run["rig"]["hfov_from"] == "the Speck's lens, the default"
    assert run["fixed_view"] == (
        "replayed recording 'square.npz': its view is fixed (the recorded camera did not\n"
        "turn with the PTU), so saliency and P are drawn in the sensor's frame;\n"
        "field of view 112.8° (the Speck's lens, the default)"
    )
    # The agent decided on the square and drove the PTU.
    rig = metrics["rig"]
    assert rig["dropped_events"] == 0 and rig["ptu_error"] is None
    assert rig["camera"]["delivered"] == 25_000
    assert rig["ptu_commands_sent"] >= 1 and rig["command_latencies_seen"] >= 1
    # measured on the host's clock: how long is the host's business, their order is not
    assert 0 < rig["command_latency_mean_s"] <= rig["command_latency_max_s"]
    assert metrics["decisions"] >= 1 and rows[0]["target_x_px"] != ""
    (emulator,) = emulators
    assert len(moves(emulator)) >= 1 and emulator.positions != (0, 0)
    assert result.output.count("\n") >= 1
    assert summary_line(metrics, out) in result.output.replace("\n", "")


def test_hfov_option_reaches_the_env_the_agent_and_run_json(app, square, tmp_path, patient_driver):
    camera, _ = square
    out = tmp_path / "run"
    result = run_emulated(app, camera, out, "0.2", "--hfov", "64", "--no-video")
    assert result.exit_code == 0, result.output
    _, run, _ = read_folder(out)
    assert (
        run["config"]["env"]["hfov_deg"] == run["rig"]["hfov_deg"] == run["agent"]["hfov_deg"] == 64
    )
    assert run["rig"]["hfov_from"] == "--hfov" and run["fixed_view"].endswith("64.0° (--hfov)")
    bad = invoke(app, "--ptu", "emulate", "--camera", camera, "--hfov", "200")
    assert bad.exit_code == 2 and "'--hfov'" in bad.output and "must be in (0, 180)" in bad.output


def test_a_real_time_replay_records_the_files_windows(app, square, emu, tmp_path, patient_driver):
    """Paced by the wall clock: how many windows fit depends on the host, what each holds
    does not (the file's events from the episode's start)."""
    camera, expected = square
    out = tmp_path / "run"
    args = ("--ptu", emu.port, "--camera", camera, "--replay", "realtime", "--seconds", "0.05")
    result = invoke(app, *args, "--no-video", "--out", str(out))
    assert result.exit_code == 0, result.output
    metrics, run, _ = read_folder(out)
    assert 1 <= metrics["steps"] <= 5
    assert run["config"]["env"]["replay"] == "realtime"
    assert_events_of_steps(out, expected, metrics)


def test_a_saccade_moves_the_ptu_to_the_chosen_point(app, square, emu, tmp_path, patient_driver):
    """No fixational movements: every move is the saccade's; the unit ends on P's angle.
    The stepped replay: the link's exchanges are in the recording's time, so the run is the
    same on a busy host."""
    camera, expected = square
    out = tmp_path / "run"
    result = run_stepped(app, emu, camera, out, "0.35", "--no-fixational")
    assert result.exit_code == 0, result.output
    assert {p.name for p in out.iterdir()} == FILES
    metrics, run, rows = read_folder(out)
    assert metrics["steps"] == 35
    assert_events_of_steps(out, expected, metrics)
    assert run["config"]["env"]["replay"] == "stepped" and run["rig"]["ptu"]["emulated"] is False
    # One decision (at 0.13 s), one completed saccade; the next window has not ended.
    assert (metrics["decisions"], metrics["saccades"], len(rows)) == (1, 1, 1)
    target = (int(rows[0]["target_x_px"]), int(rows[0]["target_y_px"]))
    assert 66 <= target[0] < 86 and 62 <= target[1] < 80  # on the square or its border
    sent = moves(emu)
    assert sent, emu.commands
    final = tuple(next(v for axis, v in reversed(sent) if axis == a) for a in "PT")
    assert emu.positions == final  # the unit went where it was told, and rests there
    # The command is the pinhole angle of P (PTU signs: right = −pan, down = −tilt), up
    # to the sAC's decoding noise when its command completes (measured: < 1 px) and
    # the per-step rounding to whole positions: within 2 px at the fovea.
    ideal = action_to_gaze_degrees(normalised_error(target))
    assert ideal[0] < -2.0 and ideal[1] < -2.0
    px_deg = math.degrees(1 / focal_length_px(128, SPECK_HFOV_DEG))  # 1 px at the fovea
    for got, want in zip(final, ideal, strict=True):
        assert abs(got * RES / 3600 - want) < 2 * px_deg
    assert metrics["foveation_error_x_px_mean"] < 2.0
    assert metrics["foveation_error_y_px_mean"] < 2.0
    assert metrics["rig"]["ptu_commands_sent"] >= 1


# -- bad input -------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--camera", "speck"], "Missing option '--ptu'"),
        (["--ptu", "emulate"], "Missing option '--camera'"),
        (["--ptu", "emulate", "--camera", "davis"], "'replay:<event file>', got 'davis'"),
        (["--ptu", "emulate", "--camera", "speck", "--replay", "slow"], "replay must be one of"),
        (["--ptu", " ", "--camera", "speck"], "ptu_port is required"),
        (["--ptu", "/dev/no-such-ptu", "--camera", "speck"], "no such serial port: '/dev/no-such"),
        (
            ["--ptu", "emulate", "--camera", "speck", "--seconds", "0"],
            "seconds in (0, 86400], got 0.0",
        ),
    ],
)
def test_bad_options_exit_2_before_opening_anything(app, tmp_path, args, message):
    result = invoke(app, *args, "--out", str(tmp_path / "run"))
    assert result.exit_code == 2
    assert message in " ".join(result.output.replace("│", " ").split())
    assert not (tmp_path / "run").exists()


# -- faults at opening -------------------------------------------------------------------------


def assert_one_line_failure(result, *parts: str) -> str:
    assert result.exit_code == 1, result.output
    lines = [ln for ln in result.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1, result.stderr
    for part in parts:
        assert part in lines[0]
    return lines[0]


def test_busy_port(app, square, emu, tmp_path):
    camera, _ = square
    with serial.Serial(emu.port, exclusive=True):
        result = invoke(app, "--ptu", emu.port, "--camera", camera, "--out", str(tmp_path / "r"))
    assert_one_line_failure(
        result,
        f"opening the PTU '{emu.port}' failed: PTU port '{emu.port}' is busy: another process "
        "holds it open exclusively",
    )
    assert not (tmp_path / "r").exists()


def test_error_reply_at_opening(app, square, emu, tmp_path):
    camera, _ = square
    emu.inject_error("Illegal Command Entered", command="PR")
    result = invoke(app, "--ptu", emu.port, "--camera", camera, "--out", str(tmp_path / "r"))
    assert_one_line_failure(
        result,
        f"wander rig: opening the PTU '{emu.port}' failed: the unit answered "
        "'! Illegal Command Entered' to 'PR'",
    )
    assert not (tmp_path / "r").exists()


def test_samna_missing(app, monkeypatch, tmp_path):
    monkeypatch.setitem(sys.modules, "samna", None)
    result = invoke(app, "--ptu", "emulate", "--camera", "speck", "--out", str(tmp_path / "r"))
    line = assert_one_line_failure(
        result, "wander rig: opening the camera 'speck' failed: samna is not installed"
    )
    assert "pip install" in line
    assert not (tmp_path / "r").exists()


def test_no_speck_found_lists_what_was_found(app, monkeypatch, tmp_path):
    install(monkeypatch, FakeSamna([("DVXplorer", "dvx-1", None), ("Davis 346", "d-7", None)]))
    result = invoke(app, "--ptu", "emulate", "--camera", "speck:sf-9", "--out", str(tmp_path / "r"))
    assert_one_line_failure(
        result,
        "opening the camera 'speck:sf-9' failed: no unopened Speck",
        "with serial 'sf-9'",
        "samna found: DVXplorer (serial 'dvx-1'), Davis 346 (serial 'd-7')",
    )


def test_open_failure_through_run_rig_keeps_the_cause(square, tmp_path):
    camera, _ = square
    config = RigRunConfig(RigConfig(ptu_port="/dev/no-such-ptu-port", camera=camera))
    with pytest.raises(RigRunError) as info:
        run_rig(tmp_path / "r", config)
    err = info.value
    assert (err.device, err.stage, err.folder) == ("PTU '/dev/no-such-ptu-port'", "open", None)
    assert type(err.__cause__).__name__ == "PTUPortError"


# -- faults mid-run ----------------------------------------------------------------------------


def test_ptu_going_silent_mid_run(app, square, emu, tmp_path, monkeypatch):
    """Timeout -> halt attempt -> one clear line; the folder holds what was recorded."""
    camera, expected = square
    on_first_move(monkeypatch, emu, emu.stop_answering)
    out = tmp_path / "run"
    result = run_stepped(app, emu, camera, out, "3")
    metrics, run, _ = read_folder(out)
    steps = metrics["steps"]
    assert steps == 0  # step 1 sends a fixational move; the poll after it meets the silence
    line = assert_one_line_failure(
        result,
        f"wander rig: PTU '{emu.port}' stopped answering mid-run",
        "Then halt (H) sent, not acknowledged",
        f"The run folder '{out}' holds what was recorded ({steps} steps completed).",
    )
    assert "no reply from the PTU within 1 s" in line  # the driver's default timeout
    assert metrics["error"].startswith(f"PTUTimeout: PTU '{emu.port}' stopped answering mid-run")
    assert "halt (H) sent, not acknowledged" in metrics["rig"]["ptu_halt"]
    assert metrics["rig"]["ptu_error"].startswith("PTUTimeout(")
    assert run["summary"]["steps"] == steps
    assert_events_of_steps(out, expected, metrics)
    assert emu.commands[-1] == "H"  # the halt attempts were sent


def test_error_reply_mid_run(app, square, emu, tmp_path, monkeypatch):
    """The unit answers ``!`` to the first position poll after the first saccade command."""
    camera, expected = square
    on_first_move(monkeypatch, emu, lambda: emu.inject_error("Illegal argument", command="PP"))
    out = tmp_path / "run"
    result = run_stepped(app, emu, camera, out, "1", "--no-fixational")
    metrics, _, _ = read_folder(out)
    steps = metrics["steps"]
    assert steps == 12  # the 13th step (window 0.12 s) sends the first move, then polls
    assert metrics["decisions"] == 1
    assert_one_line_failure(
        result,
        f"wander rig: PTU '{emu.port}' failed mid-run",
        "Illegal argument (command 'PP",
        "Then halt (H) acknowledged",
        f"The run folder '{out}' holds what was recorded ({steps} steps completed).",
    )
    assert metrics["error"].startswith("PTUError: ")
    assert metrics["rig"]["ptu_halt"] == "halt (H) acknowledged"
    assert_events_of_steps(out, expected, metrics)


def test_mid_run_fault_through_run_rig_keeps_the_cause(square, emu, tmp_path, monkeypatch):
    camera, _ = square
    on_first_move(monkeypatch, emu, emu.stop_answering)
    config = RigRunConfig(
        RigConfig(ptu_port=emu.port, camera=camera, replay="stepped", episode_seconds=3.0),
        video=False,
    )
    with pytest.raises(RigRunError) as info:
        run_rig(tmp_path / "r", config)
    err = info.value
    assert (err.device, err.stage, err.folder) == (f"PTU '{emu.port}'", "run", tmp_path / "r")
    assert isinstance(err.__cause__, PTUTimeout)
    assert "\n" not in str(err)


def test_ctrl_c_mid_run_halts_and_keeps_the_folder(
    app, square, tmp_path, monkeypatch, patient_driver
):
    camera, expected = square
    act = AttentionAgent.act
    calls = []

    def interrupted(self, observation, info):
        calls.append(1)
        if len(calls) == 6:
            raise KeyboardInterrupt
        return act(self, observation, info)

    monkeypatch.setattr(AttentionAgent, "act", interrupted)
    out = tmp_path / "run"
    result = invoke(app, "--ptu", "emulate", "--camera", camera, "--no-video", "--out", str(out))
    assert result.exit_code == 130
    assert result.stderr.strip() == (
        f"wander rig: interrupted; the PTU was halted; if the run had started, '{out}' holds "
        "what was recorded"
    )
    metrics, _, _ = read_folder(out)
    assert (metrics["steps"], metrics["error"]) == (5, "KeyboardInterrupt: ")
    assert_events_of_steps(out, expected, metrics)


# -- event queue overflow ----------------------------------------------------------------------


def test_queue_overflow_is_counted_and_reported(monkeypatch, tmp_path, patient_driver):
    """A burst of 3000 events into a 500-event queue: 2500 dropped (the oldest)."""
    n, capacity = 3000, 500
    rng = np.random.default_rng(5)
    ev = np.empty(n, EVENT_DTYPE)
    for f, hi in (("x", 128), ("y", 128), ("p", 2)):
        ev[f] = rng.integers(0, hi, n)
    ev["t"] = 10**12  # not before the episode starts, however long a loaded machine takes
    reset = rig_env.RigEnv.reset

    def burst_after_reset(self, **kwargs):
        out = reset(self, **kwargs)
        ev["t"] = self.camera.cursor_us + 100_000  # the burst: 0.1 s into the episode
        return out

    monkeypatch.setattr(rig_env.RigEnv, "reset", burst_after_reset)
    install(monkeypatch, FakeSamna([("Speck2fDevKit", "sf", FakeSpeck(ev))]))
    config = RigRunConfig(
        RigConfig(
            ptu_port="emulate",
            camera="speck",
            episode_seconds=0.5,
            # The burst's window waits up to 2 s (host clock) for it, so a loaded host's
            # late reader thread still delivers it in its window; the later windows'
            # deadlines follow 10 ms apart: the margin is paid once.
            speck=SpeckParams(queue_events=capacity, latency_margin_us=2_000_000),
        ),
        video=False,
    )
    out = tmp_path / "run"
    result = run_rig(out, config)
    metrics, run, _ = read_folder(out)
    assert metrics == json.loads(json.dumps(result.metrics))
    rig = metrics["rig"]
    assert rig["dropped_events"] == n - capacity
    assert rig["camera"]["dropped_overflow"] == n - capacity
    assert rig["camera"]["received"] == n and rig["camera"]["delivered"] == capacity
    assert metrics["events"] == capacity  # the newest were delivered, exactly
    rec = read_events(out / "events.h5")
    kept = ev[-capacity:]
    np.testing.assert_array_equal(rec.events["t"] + rig["t0_us"], kept["t"])
    for f in ("x", "y", "p"):
        np.testing.assert_array_equal(rec.events[f], kept[f])
    assert run["rig"]["camera"]["kind"] == "speck"
    assert run["rig"]["camera"]["device_type_name"] == "Speck2fDevKit"
    assert run["rig"]["camera"]["sensor_size"] == [128, 128, 2]
    assert dropped_warning(metrics) == (
        "warning: the camera dropped 2,500 events (dropped overflow 2,500); the agent did not "
        "see them (see metrics.json 'rig')"
    )
    assert "(2,500 dropped)" in summary_line(metrics, out)
    assert dropped_warning({"rig": {"dropped_events": 0}}) is None


def test_the_front_end_runs_on_the_speck_and_the_camera_still_records(
    monkeypatch, tmp_path, patient_driver
):
    """soms=speck with a live Speck: one configuration (cores + DVS monitor); the agent
    reads the monitored cores' spikes (core 1's are not monitored, so not streamed) and
    the camera's events are recorded as without the front end."""
    n = 300
    rng = np.random.default_rng(7)
    ev = np.empty(n, EVENT_DTYPE)
    for f, hi in (("x", 128), ("y", 128), ("p", 2)):
        ev[f] = rng.integers(0, hi, n)
    ev["t"] = 10**12
    # (t, core, feature, x, y): 2 DoG (core 0), 1 unmonitored (core 1), 3 grouping (core 2)
    cores = [(0, 0, 1, 10, 5), (0, 0, 0, 11, 5), (0, 1, 3, 2, 2)] + [(0, 2, 0, 40, 20)] * 3
    speck = FakeSpeck(ev)
    reset = rig_env.RigEnv.reset

    def stream_after_reset(self, **kwargs):
        out = reset(self, **kwargs)
        t0 = self.camera.cursor_us + 50_000
        ev["t"] = t0 + np.arange(n) * 100
        speck.core_spikes[:] = [(t0 + 10 * i, *c[1:]) for i, c in enumerate(cores)]
        return out

    read: list[tuple[float, float]] = []
    spikes = ChipPipeline.spikes

    def spy(self, counts):
        dog, group = spikes(self, counts)
        read.append((float(dog.sum()), float(group.sum())))
        assert self.params.dt == 0.02  # deployed for the rig's step (the leak per step)
        return dog, group

    monkeypatch.setattr(rig_env.RigEnv, "reset", stream_after_reset)
    monkeypatch.setattr(ChipPipeline, "spikes", spy)
    forget_dynapcnn(monkeypatch)
    fake = install(monkeypatch, FakeSamna([("Speck2fModuleDevKit", "sf", speck)]))
    config = RigRunConfig(
        RigConfig(ptu_port="emulate", camera="speck", episode_seconds=0.3, control_period_s=0.02),
        video=False,
        agent=AgentParams(soms="speck"),
    )
    out = tmp_path / "run"
    run_rig(out, config)
    metrics, run, _ = read_folder(out)
    assert run["rig"]["front_end"] == metrics["rig"]["front_end"] == "chip"
    [handle] = fake.handles
    [applied] = handle.applied  # once: the camera's, with the network's cores in it
    assert applied.dvs_layer.raw_monitor_enable is True
    assert [c.monitor_enable for c in applied.cnn_layers[:3]] == [True, False, True]
    assert sum(d for d, _ in read) == 2 and sum(g for _, g in read) == 3  # into the agent
    assert metrics["rig"]["front_end_spikes"] == 5
    assert speck.emitted_other == {"Spike": 5}  # core 1's spike was not streamed
    assert metrics["rig"]["camera"]["other_events"] == {"Spike": 5}  # counted, not recorded
    assert metrics["events"] == n and metrics["rig"]["dropped_events"] == 0
    rec = read_events(out / "events.h5")
    np.testing.assert_array_equal(rec.events["t"] + metrics["rig"]["t0_us"], ev["t"])


def test_a_front_end_that_does_not_fit_is_refused_before_the_device_is_opened(
    app, monkeypatch, tmp_path
):
    forget_dynapcnn(monkeypatch)
    speck = FakeSpeck(np.zeros(0, EVENT_DTYPE))
    fake = install(monkeypatch, FakeSamna([("Speck2fModuleDevKit", "sf", speck)]))
    args = ("--ptu", "emulate", "--camera", "speck", "--out", str(tmp_path / "r"))
    result = invoke(app, *args, "--set", "agent.soms.bo_kernel_px=31")  # a Speck front end
    assert result.exit_code == 2, result.output
    assert result.stderr.strip() == (
        "wander rig: agent.soms: layer 1 (conv 31x31): kernel 31 px > Speck's 16 px limit"
    )
    assert fake.handles == [] and not (tmp_path / "r").exists()


def test_a_readout_region_the_deployed_network_does_not_take_is_refused(monkeypatch, tmp_path):
    forget_dynapcnn(monkeypatch)
    speck = FakeSpeck(np.zeros(0, EVENT_DTYPE))
    fake = install(monkeypatch, FakeSamna([("Speck2fModuleDevKit", "sf", speck)]))
    readout = ReadoutParams(dvs_layer=DvsLayerParams(cut=(63, 63)))
    config = RigRunConfig(
        RigConfig(ptu_port="emulate", camera="speck", speck=SpeckParams(readout=readout)),
        agent=AgentParams(soms="speck"),
    )
    with pytest.raises(SpeckLimitError) as info:
        run_rig(tmp_path / "r", config)
    assert str(info.value) == (
        "the front end was built for the chip's 128x128 pixel array, but the camera gives "
        "64x64 (env.speck.readout's region)"
    )
    [handle] = fake.handles
    assert handle.closed and not (tmp_path / "r").exists()


def test_a_replayed_camera_runs_the_front_end_in_simulation(square, tmp_path, patient_driver):
    camera, _ = square
    config = RigRunConfig(
        RigConfig(ptu_port="emulate", camera=camera, replay="stepped", episode_seconds=0.1),
        video=False,
        agent=AgentParams(soms="speck"),
    )
    run_rig(tmp_path / "r", config)
    metrics, run, _ = read_folder(tmp_path / "r")
    assert run["rig"]["front_end"] == metrics["rig"]["front_end"] == "simulated"
    assert metrics["rig"]["front_end_spikes"] is None
    assert "samna" not in sys.modules


def test_doctests():
    assert doctest.testmod(rig_module).failed == 0
