"""RigEnv against the PTU emulator, replayed event files and the fake samna."""

from __future__ import annotations

import doctest
import logging
import math
import sys
import threading
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import serial
from fake_samna import FakeSamna, FakeSpeck, install
from locations import REALDATA, ROOT
from polling import wait_until

import hardware.rig_env as rig_env
import wander_env  # noqa: F401  (registers the environments)
from agents.attention import AgentParams
from hardware.ptu_driver import FlirPTU, FlirPTUParams, PTUError, PTUPortError, PTUTimeout
from hardware.ptu_emulator import PTUEmulator, PTUEmulatorParams
from hardware.rig_env import RigConfig, RigEnv
from hardware.samna_import import SamnaUnavailableError
from hardware.speck import SpeckParams
from wander_env.camera import SPECK_HFOV_DEG
from wander_env.events import EVENT_DTYPE, make_events
from wander_env.events.io import EventRecording, write_events
from wander_env.ptu.link import PTULinkParams
from wander_env.ptu.params import PTUParams

WALK = REALDATA / "dvs128_people" / "alex_walking_for_10secs_txyp.npy"
# Generous reply timeouts: a loaded CI machine can starve the emulator thread for a while.
DRIVER = FlirPTUParams(timeout_s=2.0, await_timeout_s=10.0, halt_timeout_s=0.5, banner_quiet_s=0.02)
# The default unit (so the spaces match the simulated env's), with quick axes.
FAST = PTUEmulatorParams(
    ptu=PTUParams(pan_speed=2900.0, tilt_speed=2900.0, pan_accel=50000.0, tilt_accel=50000.0)
)
RES = PTUParams().pan_resolution_arcsec  # 92.5714″ on both axes
T_OFFSET = 7_000_000  # the synthetic file's first timestamp (µs); replay rebases it to 0


def write_recording(path: Path, size=(128, 128, 2), n=4000, span_us=45_000) -> np.ndarray:
    """A synthetic recording in ``path``; returns its events rebased to start at 0."""
    rng = np.random.default_rng(7)
    t = np.sort(rng.integers(0, span_us, n))
    t[0] = 0
    ev = make_events(
        rng.integers(0, size[0], n),
        rng.integers(0, size[1], n),
        t + T_OFFSET,
        rng.integers(0, 2, n),
    )
    write_events(path, EventRecording(ev, size))
    out = ev.copy()
    out["t"] -= T_OFFSET
    return out


@pytest.fixture
def recording(tmp_path) -> tuple[str, np.ndarray]:
    path = tmp_path / "synthetic.npz"
    return f"replay:{path}", write_recording(path)


@pytest.fixture
def emu():
    with PTUEmulator(FAST) as e:
        yield e


def moves(emu: PTUEmulator) -> list[str]:
    """The commands the emulator received, less the position polls."""
    return [c for c in emu.commands if c not in ("PP", "TP")]


def make_rig(ptu: str, camera: str, **kw) -> RigEnv:
    kw = {"replay": "fast", "driver": DRIVER, "emulator": FAST, **kw}
    return RigEnv(ptu_port=ptu, camera=camera, **kw)


def expected_offset_pos(action) -> tuple[int, int]:
    """The pinhole model by hand: pixels -> degrees -> whole PTU positions (PTU signs)."""
    f = 64.0 / math.tan(math.radians(SPECK_HFOV_DEG) / 2)
    deg = [-math.degrees(math.atan(a * 64.0 / f)) for a in action]
    return tuple(int(math.floor(abs(d) * 3600 / RES + 0.5) * math.copysign(1, d)) for d in deg)


# -- registration, spaces, settings from the devices ----------------------------------------


def test_registered_nondeterministic_with_the_sim_envs_spaces(recording):
    spec = gym.spec("wander/Rig-v0")
    assert spec.nondeterministic is True
    assert spec.entry_point == "hardware.rig_env:RigEnv"
    camera, _ = recording
    rig = gym.make("wander/Rig-v0", ptu_port="emulate", camera=camera, replay="fast", driver=DRIVER)
    sim = gym.make("wander/Wander-v0", scene="shelf", ground_truth=False)
    try:
        assert rig.observation_space == sim.observation_space
        assert rig.action_space == sim.action_space
        obs, info = rig.reset(seed=0)
        assert rig.observation_space.contains(obs)
        contract = {
            "events",
            "t",
            "ptu_positions",
            "ptu_target_positions",
            "ptu_target_deg",
            "moving",
            "target_clipped",
        }
        rig_only = {"command_latency_s", "dropped_events", "lag_s"}
        assert set(info) == contract | rig_only  # no ground truth on the rig
        assert (info["t"], info["ptu_positions"], info["moving"]) == (0.0, (0, 0), False)
        assert len(info["events"]) == 0 and math.isnan(info["command_latency_s"])
    finally:
        rig.close()
        sim.close()


def test_sensor_size_and_ptu_limits_come_from_the_devices(tmp_path):
    path = tmp_path / "small.npz"
    write_recording(path, size=(64, 48, 2), n=100)
    motion = PTUParams(
        pan_resolution_arcsec=46.2857,
        pan_min_pos=-5000,
        pan_max_pos=4000,
        tilt_min_pos=-700,
        tilt_max_pos=500,
    )
    env = make_rig("emulate", f"replay:{path}", emulator=PTUEmulatorParams(ptu=motion))
    try:
        assert env.sensor_size == (64, 48, 2)
        assert env.observation_space["events"].shape == (2, 48, 64)
        gaze = env.observation_space["gaze"]
        np.testing.assert_array_equal(
            gaze.low, np.float32([-5000 * 46.2857 / 3600, -700 * RES / 3600])
        )
        np.testing.assert_array_equal(
            gaze.high, np.float32([4000 * 46.2857 / 3600, 500 * RES / 3600])
        )
        assert env.emulator.commands[:4] == ["FT", "ED", "CI", "I"]
        assert {"PR", "TR", "PN", "PX", "TN", "TX"} <= set(env.emulator.commands)
        # The agent reads the unit's resolution and the lens from the env, as in the sim.
        assert env.ptu_resolution_arcsec == (46.2857, RES) and env.hfov_deg == SPECK_HFOV_DEG
        params = AgentParams.for_env(env)
        assert (params.width_px, params.height_px, params.step_s) == (64, 48, 0.01)
        assert (params.hfov_deg, params.ptu_resolution_arcsec) == (SPECK_HFOV_DEG, (46.2857, RES))
    finally:
        env.close()


def test_config_is_checked():
    # The rig polls at the sim link's default period: one value, PTULinkParams.poll_s.
    assert RigConfig(ptu_port="emulate", camera="speck").ptu_poll_s == PTULinkParams().poll_s
    assert PTULinkParams().poll_s == 0.01
    with pytest.raises(ValueError, match="ptu_port is required"):
        RigConfig(camera="speck")
    with pytest.raises(ValueError, match="'speck', 'speck:<serial number>' or 'replay:"):
        RigConfig(ptu_port="emulate", camera="davis")
    with pytest.raises(ValueError, match="replay must be one of"):
        RigConfig(ptu_port="emulate", camera="speck", replay="slow")
    for period in (1.5e-7, 0.0, -0.01, 1.5, math.nan, True):
        with pytest.raises(ValueError) as info:
            RigConfig(ptu_port="emulate", camera="speck", control_period_s=period)
        assert str(info.value) == (
            f"RigConfig.control_period_s: must be a whole number of µs in (0, 1] s, got {period!r}"
        )
    assert RigConfig(
        ptu_port="emulate", camera="speck", control_period_s=1.0
    ).control_period_us == (1_000_000)
    assert RigConfig(
        ptu_port="emulate", camera="speck", control_period_s=0.0125
    ).control_period_us == (12_500)
    for hfov in (0.0, 180.0, math.inf):
        with pytest.raises(ValueError) as info:
            RigConfig(ptu_port="emulate", camera="speck", hfov_deg=hfov)
        assert str(info.value) == f"RigConfig.hfov_deg: must be in (0, 180) degrees, got {hfov!r}"
    with pytest.raises(ValueError, match="start_gaze_deg"):
        RigConfig(ptu_port="emulate", camera="speck", start_gaze_deg=(math.nan, 0.0))
    assert RigConfig(ptu_port="emulate", camera="speck:sf-2").camera_kind() == ("speck", "sf-2")


# -- events --------------------------------------------------------------------------------


def check_windows(env: RigEnv, expected: np.ndarray, period_us: int) -> None:
    env.reset()
    n_steps = math.ceil((int(expected["t"][-1]) + 1) / period_us)
    truncated, total = False, 0
    for k in range(n_steps):
        assert not truncated
        obs, reward, terminated, truncated, info = env.step(np.zeros(2, np.float32))
        lo, hi = np.searchsorted(expected["t"], [k * period_us, (k + 1) * period_us])
        want = expected[lo:hi]
        got = info["events"].events
        assert got.dtype == EVENT_DTYPE
        assert len(got) == hi - lo
        for f in ("x", "y", "t", "p"):
            np.testing.assert_array_equal(got[f], want[f])
        assert obs["events"].dtype == np.float32
        assert obs["events"][1].sum() == np.count_nonzero(want["p"] == 1)  # channel 1 = ON
        assert obs["events"][0].sum() == np.count_nonzero(want["p"] == 0)
        assert info["t"] == (k + 1) * period_us / 1e6
        assert (reward, terminated) == (0.0, False)
        total += len(got)
    assert truncated  # the file is exhausted
    assert total == len(expected)


def test_each_step_returns_exactly_the_replay_window(recording):
    camera, expected = recording
    env = make_rig("emulate", camera)
    try:
        check_windows(env, expected, 10_000)
        assert env.stats["discarded_at_reset"] == 0
    finally:
        env.close()


@pytest.mark.skipif(not WALK.is_file(), reason="../shared/realdata absent")
def test_real_recording_windows(tmp_path):
    raw = np.load(WALK)
    raw = raw[raw["t"] < raw["t"][0] + 80_000]
    ev = make_events(raw["x"], raw["y"], raw["t"], raw["p"])
    write_events(tmp_path / "walk.npz", EventRecording(ev, (128, 128, 2)))
    expected = ev.copy()
    expected["t"] -= expected["t"][0]
    env = make_rig("emulate", f"replay:{tmp_path / 'walk.npz'}", control_period_s=0.02)
    try:
        check_windows(env, expected, 20_000)
    finally:
        env.close()


# -- actions -------------------------------------------------------------------------------


def test_actions_move_the_ptu_by_the_expected_positions(recording, emu):
    camera, _ = recording
    env = make_rig(emu.port, camera, replay_loop=True)
    try:
        env.reset()
        emu.clear_commands()
        a1 = (0.25, -0.1)
        d1 = expected_offset_pos(a1)
        obs, _, _, _, info = env.step(np.float32(a1))
        assert info["ptu_target_positions"] == d1
        assert info["moving"] is True  # the step did not wait for the motion
        assert not info["target_clipped"]
        env.settle()
        assert emu.positions == d1
        obs, _, _, _, info = env.step(np.zeros(2, np.float32))  # a zero action sends nothing
        assert (info["ptu_positions"], info["moving"]) == (d1, False)
        np.testing.assert_array_equal(obs["gaze"], np.float32([d * RES / 3600 for d in d1]))
        assert 0.0 < info["command_latency_s"] < 5.0
        assert moves(emu) == [f"PP{d1[0]}", f"TP{d1[1]}"]
        a2 = (-0.5, 0.0)  # relative: added to the current target, pan only
        d2 = expected_offset_pos(a2)
        _, _, _, _, info = env.step(np.float32(a2))
        want = (d1[0] + d2[0], d1[1])
        assert info["ptu_target_positions"] == want
        env.settle()
        assert emu.positions == want
        assert moves(emu) == [f"PP{d1[0]}", f"TP{d1[1]}", f"PP{want[0]}"]
        for _ in range(3):  # far up: the tilt target stops at the unit's limit
            _, _, _, _, info = env.step(np.float32((0.0, -1.0)))
        assert info["target_clipped"] is True
        assert info["ptu_target_positions"][1] == PTUParams().tilt_max_pos
        env.settle()
        assert emu.positions[1] == PTUParams().tilt_max_pos
    finally:
        env.close()


def test_a_stepped_replay_runs_the_link_in_stream_time(recording, emu):
    """replay="stepped": each 10 ms window's exchanges are on the wire when the step
    returns, the same however slowly the host runs: one poll per window, and a step that
    moves sends its command and polls right after it at the window's start."""
    camera, events = recording
    env = make_rig(emu.port, camera, replay="stepped", ptu_poll_s=0.01)
    try:
        env.reset()
        emu.clear_commands()
        for k in range(2):
            _, _, _, _, info = env.step(np.zeros(2, np.float32))
            assert emu.commands == ["PP", "TP"] * (k + 1)  # the window's poll, before return
            want = events[(events["t"] >= k * 10_000) & (events["t"] < (k + 1) * 10_000)]
            np.testing.assert_array_equal(info["events"].events["t"], want["t"])  # since reset
        a = (0.25, -0.1)
        d = expected_offset_pos(a)
        _, _, _, _, info = env.step(np.float32(a))
        assert emu.commands[4:] == [f"PP{d[0]}", f"TP{d[1]}", "PP", "TP", "PP", "TP"]
        assert info["ptu_target_positions"] == d and info["t"] == pytest.approx(0.03)
        env.settle()  # polls until the unit rests there (it moves on the wall clock)
        assert emu.positions == d
        _, _, _, _, info = env.step(np.zeros(2, np.float32))
        assert (info["ptu_positions"], info["moving"]) == (d, False)
        assert env.stats["commands_sent"] == 1 and env.stats["commands_replaced"] == 0
        assert env._link._thread.is_alive() is False  # no PTU thread in this mode
    finally:
        env.close()


@pytest.mark.parametrize(
    "action", [(math.nan, 0.0), (0.0, math.inf), (1.5, 0.0), (0.0, -1.01), (0.1, 0.1, 0.1)]
)
def test_bad_actions_raise_and_send_nothing(recording, emu, action):
    camera, _ = recording
    env = make_rig(emu.port, camera)
    try:
        with pytest.raises(RuntimeError, match="reset"):
            env.step(np.zeros(2, np.float32))
        env.reset()
        emu.clear_commands()
        with pytest.raises(ValueError, match="action"):
            env.step(np.array(action))
        assert moves(emu) == []
        assert env.camera.cursor_us == 0  # no window was consumed
    finally:
        env.close()


# -- opening faults ----------------------------------------------------------------------------


def test_missing_port_is_named(recording):
    camera, _ = recording
    with pytest.raises(PTUPortError, match=r"'/dev/no-such-ptu-port' does not exist"):
        make_rig("/dev/no-such-ptu-port", camera)


def test_busy_port_is_named(recording, emu):
    camera, _ = recording
    with serial.Serial(emu.port, exclusive=True):
        with pytest.raises(PTUPortError, match="busy") as info:
            make_rig(emu.port, camera)
    assert emu.port in str(info.value)


def test_error_reply_at_start_carries_the_units_message(recording, emu):
    camera, _ = recording
    emu.inject_error("Illegal Command Entered", command="PR")
    with pytest.raises(PTUError) as info:
        make_rig(emu.port, camera)
    assert (info.value.message, info.value.command) == ("Illegal Command Entered", "PR")
    with FlirPTU(emu.port, DRIVER) as ptu:  # the port was released
        assert ptu.is_open


def test_samna_missing_is_clear_and_the_ptu_is_left_halted(monkeypatch, emu):
    monkeypatch.setitem(sys.modules, "samna", None)
    with pytest.raises(SamnaUnavailableError, match="samna is not installed") as info:
        make_rig(emu.port, "speck")
    assert isinstance(info.value, RuntimeError) and "pip install" in str(info.value)
    assert emu.commands[-1] == "H"
    with FlirPTU(emu.port, DRIVER) as ptu:  # the port was released
        assert ptu.is_open


def test_no_speck_found_lists_what_was_found(monkeypatch, emu):
    install(monkeypatch, FakeSamna([("DVXplorer", "dvx-1", None), ("Davis 346", "d-7", None)]))
    with pytest.raises(RuntimeError, match="Speck2f or Speck2e") as info:
        make_rig(emu.port, "speck")
    message = str(info.value)
    assert "DVXplorer" in message and "Davis 346" in message and "'d-7'" in message
    assert emu.commands[-1] == "H"


# -- faults mid-run ---------------------------------------------------------------------------


def test_error_reply_mid_run_halts_and_raises_with_the_units_message(recording, emu):
    camera, _ = recording
    env = make_rig(emu.port, camera, ptu_poll_s=10.0)  # no poll ("PP") before the move
    try:
        env.reset()
        emu.inject_error("Illegal argument", command="PP")
        with pytest.raises(PTUError) as info:  # from the step, or once the PTU thread sees it
            env.step(np.float32((0.2, 0.0)))
            env.settle()
        err = info.value
        pan = expected_offset_pos((0.2, 0.0))[0]
        assert (err.message, err.command) == ("Illegal argument", f"PP{pan}")
        assert "halt (H) acknowledged" in str(err) and isinstance(err.__cause__, PTUError)
        assert emu.commands[-1] == "H"
        with pytest.raises(PTUError, match="Illegal argument"):
            env.step(np.zeros(2, np.float32))
        assert env.stats["ptu_halt"] == "halt (H) acknowledged"
    finally:
        env.close()


def test_ptu_going_silent_mid_run_times_out_after_a_halt_attempt(recording, emu, caplog):
    camera, _ = recording
    env = make_rig(emu.port, camera, replay_loop=True)
    try:
        env.reset()
        env.step(np.float32((0.3, 0.0)))
        env.settle()
        emu.stop_answering()
        n_before = len(emu.commands)
        with pytest.raises(PTUTimeout, match="stopped answering mid-run") as info:
            env.step(np.float32((-0.3, 0.0)))  # returns at once: the PTU thread sends it
            env.settle()
        assert "halt (H) sent, not acknowledged" in str(info.value)
        assert isinstance(info.value.__cause__, PTUTimeout)
        assert "PP0" in emu.commands[n_before:] and emu.commands[-1] == "H"
        with pytest.raises(PTUTimeout, match="stopped answering mid-run"):  # every later step too
            env.step(np.zeros(2, np.float32))
        with caplog.at_level(logging.WARNING, logger="hardware.ptu_driver"):
            env.close()  # halts once more; the halt's wait ends at the driver's halt timeout
        assert emu.commands[-1] == "H"
        assert any(
            "halt on close failed" in r.getMessage()
            and "no reply from the PTU within 0.5 s" in r.getMessage()
            for r in caplog.records
        ), caplog.text
    finally:
        env.close()


def test_camera_failure_halts_the_ptu_first(recording, emu, monkeypatch):
    camera, _ = recording
    env = make_rig(emu.port, camera)
    try:
        env.reset()

        def broken(*args, **kwargs):
            raise RuntimeError("Speck reader thread failed: USB gone")

        monkeypatch.setattr(env.camera, "read", broken)
        with pytest.raises(RuntimeError, match="USB gone"):
            env.step(np.float32((0.5, 0.0)))
        assert emu.commands[-1] == "H"
    finally:
        env.close()


def test_queue_overflow_is_counted_in_info(monkeypatch, emu):
    rng = np.random.default_rng(2)
    n, capacity = 3000, 500
    ev = np.empty(n, EVENT_DTYPE)
    for f, hi in (("x", 128), ("y", 128), ("p", 2)):
        ev[f] = rng.integers(0, hi, n)
    ev["t"] = np.sort(rng.integers(150_000, 250_000, n))  # well after reset
    install(monkeypatch, FakeSamna([("Speck2fDevKit", "sf", FakeSpeck(ev))]))
    env = make_rig(
        emu.port, "speck", speck=SpeckParams(queue_events=capacity), control_period_s=0.4
    )
    try:
        env.reset()
        assert wait_until(lambda: env.camera.stats["received"] >= n)  # nobody reads: overflow
        _, _, _, _, info = env.step(np.zeros(2, np.float32))
        stats = env.stats
        cam = stats["camera"]
        assert cam["received"] == n
        assert info["dropped_events"] == env.camera.dropped - stats["dropped_at_reset"]
        assert stats["discarded_at_reset"] == stats["dropped_at_reset"] == 0
        assert info["dropped_events"] == n - capacity  # the oldest went
        got, kept = info["events"].events, ev[-capacity:]  # the newest are delivered, exactly
        np.testing.assert_array_equal(got["t"] + stats["t0_us"], kept["t"])
        np.testing.assert_array_equal(got["x"], kept["x"])
        assert cam["buffered"] == 0 and cam["dropped_overflow"] == n - capacity
    finally:
        env.close()


# -- life cycle ----------------------------------------------------------------------------------


def test_close_halts_releases_everything_and_is_idempotent(recording):
    camera, _ = recording
    before = threading.active_count()
    env = make_rig("emulate", camera, emulator=PTUEmulatorParams())  # slow default axes
    emu = env.emulator
    env.reset()
    env.step(np.float32((0.9, 0.0)))
    env.close()
    assert emu.commands[-1] == "H"
    assert env.camera.closed and not env.ptu.is_open
    env.close()
    with pytest.raises(RuntimeError, match="closed"):
        env.reset()
    assert wait_until(lambda: threading.active_count() <= before)
    assert threading.active_count() == before


def test_importing_the_rig_env_does_not_import_samna():
    import subprocess

    code = "import sys, hardware.rig_env; assert 'samna' not in sys.modules"
    subprocess.run([sys.executable, "-c", code], cwd=ROOT, check=True)


def test_doctests():
    assert doctest.testmod(rig_env, optionflags=doctest.ELLIPSIS).failed == 0
