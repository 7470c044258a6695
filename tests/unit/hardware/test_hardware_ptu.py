"""FLIR PTU driver (hardware.ptu_driver) against the pty emulator (hardware.ptu_emulator).

The driver talks to the emulator through a real pseudo-terminal serial port; the
emulator's motion comes from wander_env.ptu, so a move lasts at least its
``move_duration``. Nothing here asserts what the wall clock allows: a move that must be
caught mid-way runs at a slow speed (it lasts a minute), and the driver's timeouts are
checked on a fake clock put in place of the driver's ``time``.
"""

from __future__ import annotations

import doctest
import math
import threading
import time
from dataclasses import replace

import pytest
import serial
from fake_clock import FakeClock
from polling import wait_until

from hardware import ptu_driver, ptu_emulator
from hardware.ptu_driver import (
    FlirPTU,
    FlirPTUParams,
    PTUError,
    PTUPortError,
    PTUProtocol,
    PTUTimeout,
    open_port,
    parse_reply,
    reply_number,
)
from hardware.ptu_emulator import PTUEmulator, PTUEmulatorParams
from hardware.ptu_firmware import PTUFirmware
from wander_env.ptu.axis import AxisState, move_duration
from wander_env.ptu.link import PTULinkParams
from wander_env.ptu.params import PTUParams
from wander_env.ptu.unit import PanTiltUnit
from wander_env.ptu.units import degrees_to_positions, round_position

PAN_RES, TILT_RES = 46.2857, 92.5714  # a non-default pan resolution: must be queried
# Fast axes: a few hundred positions take 0.1-0.2 s.
MOTION = PTUParams(
    pan_resolution_arcsec=PAN_RES,
    tilt_resolution_arcsec=TILT_RES,
    pan_min_pos=-6000,
    pan_max_pos=6000,
    tilt_min_pos=-900,
    tilt_max_pos=600,
    pan_speed=4000.0,
    tilt_speed=4000.0,
    pan_accel=40000.0,
    tilt_accel=40000.0,
    pan_base_speed=500.0,
    tilt_base_speed=500.0,
    pan_upper_speed=8000.0,
    tilt_upper_speed=8000.0,
)
DRIVER = FlirPTUParams(timeout_s=0.5, await_timeout_s=5.0, halt_timeout_s=0.2, banner_quiet_s=0.05)
DP, DT = PAN_RES / 3600.0, TILT_RES / 3600.0  # degrees per position
SLOW = 100.0  # pos/s: a 5000-position move lasts 50 s, so it is always caught mid-way


@pytest.fixture
def emu():
    with PTUEmulator(PTUEmulatorParams(ptu=MOTION)) as e:
        yield e


@pytest.fixture
def ptu(emu):
    with FlirPTU(emu.port, DRIVER) as p:
        yield p


@pytest.fixture
def driver_clock(monkeypatch):
    """The driver's clock, faked: 10 ms pass at each reading, so a wait ends after the
    number of readings its timeout allows, however loaded the host."""
    clock = FakeClock(step=0.01)
    monkeypatch.setattr(ptu_driver, "time", clock.module())
    return clock


def start_slow_pan_move(ptu, emu):
    """A 5000-position pan move at :data:`SLOW` (50 s), once the pan has left 0."""
    ptu.set_speed(pan_deg_s=SLOW * DP)
    ptu.move_to(pan_deg=5000 * DP)
    assert wait_until(lambda: emu.positions[0] > 0)


# -- start-up ----------------------------------------------------------------------------


def test_init_sets_modes_and_queries_the_unit(emu, ptu):
    cmds = emu.commands
    assert cmds[:4] == ["FT", "ED", "CI", "I"]
    assert {"PR", "TR", "PN", "PX", "TN", "TX", "PL", "PU", "TL", "TU"} <= set(cmds[4:])
    assert emu.modes == {
        "echo": False,
        "verbose": False,
        "slaved": False,
        "velocity_mode": False,
        "limits_enabled": True,
    }
    assert ptu.resolution_arcsec == pytest.approx((PAN_RES, TILT_RES))
    assert ptu.deg_per_position == pytest.approx((DP, DT))
    assert ptu.pan_limits_deg == pytest.approx((-6000 * DP, 6000 * DP))
    assert ptu.tilt_limits_deg == pytest.approx((-900 * DT, 600 * DT))
    pan_bounds, tilt_bounds = ptu.speed_bounds_deg_s
    assert pan_bounds == pytest.approx((31 * DP, 8000 * DP))
    assert tilt_bounds == pytest.approx((31 * DT, 8000 * DT))
    assert ptu.is_open and "open" in repr(ptu)


def test_banner_arriving_after_open_is_drained():
    # The banner ends in a reset's "!T!T!P!P*", which must not be taken for FT's "*".
    banner = "Pan-Tilt Controller v2.14.0\r\nInitializing...\r\n!T!T!P!P*\r\n"
    params = PTUEmulatorParams(ptu=MOTION, banner=banner, banner_delay_s=0.02)
    # Drained until the line is quiet for 0.5 s: a loaded host may wake the emulator's
    # thread late, the banner must still come before the quiet spell ends.
    patient = FlirPTUParams(**{**DRIVER.__dict__, "banner_quiet_s": 0.5})
    with PTUEmulator(params) as emu, FlirPTU(emu.port, patient) as ptu:
        assert emu.banner_sent
        assert ptu.resolution_arcsec == pytest.approx((PAN_RES, TILT_RES))
        assert ptu.position() == (0.0, 0.0)


@pytest.mark.parametrize("eol", ["\n", "\r"])
def test_lf_or_cr_line_endings(eol):
    # The line end is the unit's link's (a fast line: its pacing costs the test little).
    link = PTULinkParams(baudrate=115200, eol=eol)
    params = PTUEmulatorParams(ptu=replace(MOTION, link=link))
    assert params.eol == eol
    with (
        PTUEmulator(params) as emu,
        FlirPTU(emu.port, DRIVER) as ptu,
    ):
        ptu.goto(pan_deg=40 * DP, tilt_deg=-20 * DT)
        assert emu.positions == (40, -20)
        assert ptu.position() == pytest.approx((40 * DP, -20 * DT))


# -- moves -------------------------------------------------------------------------------


def test_absolute_and_relative_moves_land_on_exact_positions(emu, ptu):
    assert ptu.move_to(pan_deg=123 * DP, tilt_deg=-45 * DT) == pytest.approx((123 * DP, -45 * DT))
    assert emu.commands[-2:] == ["PP123", "TP-45"]
    ptu.await_motion()
    assert emu.positions == (123, -45)
    assert ptu.position() == pytest.approx((123 * DP, -45 * DT))
    assert (ptu.pan_deg, ptu.tilt_deg) == pytest.approx((123 * DP, -45 * DT))

    # An angle between positions goes to the nearest one; None leaves the axis alone.
    pan, tilt = ptu.move_to(pan_deg=10.0)
    expected = round_position(degrees_to_positions(10.0, PAN_RES))
    assert tilt is None and pan == pytest.approx(expected * DP)
    ptu.await_motion()
    assert emu.positions == (expected, -45)

    assert ptu.move_by(pan_deg=-23 * DP, tilt_deg=5 * DT) == pytest.approx((-23 * DP, 5 * DT))
    assert emu.commands[-2:] == ["PO-23", "TO5"]
    ptu.await_motion()
    assert emu.positions == (expected - 23, -40)
    assert ptu.target() == pytest.approx(((expected - 23) * DP, -40 * DT))


def test_await_returns_when_the_motion_model_says_done(emu, ptu):
    ptu.set_speed(pan_deg_s=3000 * DP, tilt_deg_s=2500 * DT)
    assert emu.speeds == (3000.0, 2500.0)
    assert ptu.speed() == pytest.approx((3000 * DP, 2500 * DT))
    expected = max(
        move_duration(300, vmax=3000.0, amax=40000.0, vbase=500.0),  # pan, trapezoid
        move_duration(120, vmax=2500.0, amax=40000.0, vbase=500.0),  # tilt, triangle
    )
    emu.clear_commands()
    t0 = time.monotonic()
    ptu.move_to(pan_deg=300 * DP, tilt_deg=120 * DT)
    ptu.await_motion()
    elapsed = time.monotonic() - t0
    # The unit moves in real time, so the move cannot end sooner (a load only delays it);
    # ``A`` was answered by the unit, not ended by the driver's timeout (no ``H``).
    assert elapsed >= expected - 0.005, (elapsed, expected)
    assert emu.commands == ["PP300", "TP120", "A"]
    assert not emu.moving and not ptu.moving()
    assert emu.positions == (300, 120)


def test_acceleration_round_trip_and_timing(emu, ptu):
    ptu.set_acceleration(pan_deg_s2=10000 * DP, tilt_deg_s2=20000 * DT)
    assert emu.accelerations == (10000.0, 20000.0)
    assert ptu.acceleration() == pytest.approx((10000 * DP, 20000 * DT))
    assert ptu.base_speed() == pytest.approx((500 * DP, 500 * DT))
    emu.clear_commands()
    t0 = time.monotonic()
    ptu.goto(pan_deg=200 * DP)
    elapsed = time.monotonic() - t0
    expected = move_duration(200, vmax=4000.0, amax=10000.0, vbase=500.0)
    assert elapsed >= expected - 0.005, (elapsed, expected)  # never sooner than the model
    assert emu.commands == ["PP200", "A"] and emu.positions == (200, 0)


def test_halt_stops_mid_move(emu, ptu):
    ptu.set_speed(pan_deg_s=SLOW * DP)  # pan: 50 s to go
    ptu.move_to(pan_deg=5000 * DP, tilt_deg=500 * DT)
    assert ptu.moving() and emu.moving
    assert wait_until(lambda: emu.positions[0] > 0)
    ptu.halt(axis="pan")  # HP: pan brakes, tilt goes on
    ptu.await_motion()
    pan, tilt = emu.positions
    assert 0 < pan < 5000 and tilt == 500
    assert ptu.target()[0] == pytest.approx(pan * DP)
    ptu.move_to(pan_deg=0.0)
    time.sleep(0.05)
    ptu.halt()
    assert wait_until(lambda: not emu.moving)
    assert emu.commands[-1] == "H"
    with pytest.raises(ValueError, match="axis"):
        ptu.halt(axis="roll")


def test_await_timeout_halts_and_keeps_the_exchange_in_step(emu, ptu):
    start_slow_pan_move(ptu, emu)
    with pytest.raises(PTUTimeout) as info:
        ptu.await_motion(timeout_s=0.05)
    assert info.value.command == "A"
    assert emu.commands[-2:] == ["A", "H"]
    assert not emu.moving
    pan = emu.positions[0]
    assert 0 < pan < 5000
    assert ptu.pan_deg == pytest.approx(pan * DP)  # replies still match their commands
    ptu.set_speed(pan_deg_s=4000 * DP)
    ptu.goto(pan_deg=10 * DP)
    assert emu.positions[0] == 10


def test_slaved_mode_queues_positions_until_await(emu, ptu):
    ptu.send("S")
    ptu.move_to(pan_deg=50 * DP, tilt_deg=-10 * DT)
    time.sleep(0.05)
    assert emu.positions == (0, 0) and not emu.moving
    assert ptu.target() == pytest.approx((50 * DP, -10 * DT))  # desired, not yet executed
    ptu.await_motion()  # A executes the stored commands and waits for them
    assert emu.positions == (50, -10)
    ptu.send("I")
    assert not emu.modes["slaved"]


# -- refusals and errors ------------------------------------------------------------------


def test_out_of_limit_moves_are_refused_before_sending(emu, ptu):
    emu.clear_commands()
    with pytest.raises(ValueError, match="outside the unit's limits"):
        ptu.move_to(pan_deg=ptu.pan_limits_deg[1] + DP)
    with pytest.raises(ValueError, match="tilt"):
        ptu.move_to(pan_deg=1.0, tilt_deg=-90.0)  # pan valid, tilt not: neither is sent
    with pytest.raises(ValueError, match="finite"):
        ptu.move_to(pan_deg=float("nan"))
    with pytest.raises(ValueError, match="speed"):
        ptu.set_speed(pan_deg_s=9000 * DP)  # above PU
    assert emu.commands == []
    with pytest.raises(ValueError, match="outside"):
        ptu.move_by(tilt_deg=-901 * DT)
    assert emu.commands == ["PP", "TP"]  # the position queries only, no TO
    assert emu.positions == (0, 0)


# One speed rule (wander_env.ptu.units.whole_speed) in the simulator, the driver and the
# firmware: (pan °/s asked, the whole pos/s set, or the refusal of the simulator and the
# driver and the firmware's reply to the rounded PS), at the FLIR defaults (PL 31, PU 2902).
SPEED_CASES = [
    (10.0, 389, None, None),  # 388.889 pos/s
    (30.6 * 92.5714 / 3600, 31, None, None),
    (74.6, 2901, None, None),  # 2901.11 pos/s
    (
        0.5,  # 19.4445 pos/s
        None,
        "pan speed must round to 31…2902 positions/s, got 19.4445 positions/s",
        "! Pan speed cannot be less than 31 positions/sec",
    ),
    (
        0.01,  # 0.389 pos/s: rounds to 0
        None,
        "pan speed must round to 31…2902 positions/s, got 0.388889 positions/s",
        "! Pan speed cannot be less than 31 positions/sec",
    ),
    (
        74.7,  # 2905.0009 pos/s
        None,
        "pan speed must round to 31…2902 positions/s, got 2905 positions/s",
        "! Pan speed cannot exceed 2902 positions/sec",
    ),
]


def test_a_speed_request_is_the_same_in_the_sim_the_driver_and_the_firmware():
    with (
        PTUEmulator(PTUEmulatorParams(banner="")) as emu,
        FlirPTU(emu.port, DRIVER) as rig,
    ):
        for deg_s, whole, refusal, reply in SPEED_CASES:
            sim = PanTiltUnit(PTUParams())
            firmware = PTUFirmware(PTUParams(), now=0.0)
            ps = f"PS{round_position(degrees_to_positions(deg_s))}"
            emu.clear_commands()
            if refusal is None:
                sim.set_speed(pan_deg_s=deg_s)
                rig.set_speed(pan_deg_s=deg_s)
                assert firmware.execute(ps, now=0.0) == "*"
                assert (sim.speeds[0], emu.speeds[0], firmware.axes["P"].speed) == (whole,) * 3
                assert emu.commands == [f"PS{whole}"]
                continue
            with pytest.raises(ValueError) as sim_err:
                sim.set_speed(pan_deg_s=deg_s)
            with pytest.raises(ValueError) as rig_err:
                rig.set_speed(pan_deg_s=deg_s)
            assert (str(sim_err.value), str(rig_err.value)) == (refusal, refusal)
            assert emu.commands == []  # the driver refused before sending
            assert firmware.execute(ps, now=0.0) == reply
            assert (sim.speeds[0], firmware.axes["P"].speed) == (2000.0, 2000.0)


def test_firmware_rounds_speeds_as_the_link_rounds_positions():
    # round_position (halves away from zero), not Python's round (halves to even).
    firmware = PTUFirmware(PTUParams(pan_speed=100.5), now=0.0)
    firmware.axes["P"].state = AxisState(0.0, -2.5)
    assert firmware.execute("PD", now=0.0) == "* Current Pan speed is -3 positions/sec"
    assert firmware.execute("PD10", now=0.0) == "*"  # offsets the rounded speed, 101
    assert firmware.axes["P"].speed == 111.0


def test_error_replies_raise_with_the_units_message(emu, ptu):
    emu.inject_error("Illegal argument", command="PS")
    with pytest.raises(PTUError) as info:
        ptu.set_speed(pan_deg_s=1000 * DP)
    assert info.value.message == "Illegal argument"
    assert info.value.command == "PS1000"
    with pytest.raises(PTUError, match="Maximum allowable Pan position is 6000") as info:
        ptu.send("pp7000")  # raw commands bypass the driver's checks: the unit refuses
    assert info.value.command == "PP7000"
    with pytest.raises(PTUError, match="Pan speed cannot exceed 8000 positions/sec"):
        ptu.send("PS9000")
    with pytest.raises(PTUError, match="Illegal Command Entered"):
        ptu.send("XYZ")
    assert ptu.pan_deg == 0.0  # the exchange stays in step after errors
    # Measured on each reply (how long is the host's business: a reply read in time can
    # be parsed after the deadline on a loaded host).
    assert math.isfinite(ptu.last_latency_s) and ptu.last_latency_s > 0.0


def test_verbose_feedback_and_echo_are_parsed(emu, ptu):
    ptu.send("FV")
    ptu.send("EE")
    assert emu.modes["verbose"] and emu.modes["echo"]
    assert ptu.send("PR") == "46.2857 seconds arc per position"
    ptu.goto(pan_deg=-70 * DP, tilt_deg=30 * DT)
    assert ptu.position() == pytest.approx((-70 * DP, 30 * DT))
    assert ptu.target() == pytest.approx((-70 * DP, 30 * DT))
    assert not ptu.moving()
    assert ptu.speed() == pytest.approx((4000 * DP, 4000 * DT))
    assert ptu.acceleration() == pytest.approx((40000 * DP, 40000 * DT))
    ptu.reset()  # "R !T!T!P!P*", then every limit and resolution query again, verbose
    assert emu.positions == (0, 0)
    assert ptu.resolution_arcsec == pytest.approx((PAN_RES, TILT_RES))
    assert ptu.tilt_limits_deg == pytest.approx((-900 * DT, 600 * DT))


# -- safety: timeouts, exceptions, ports -------------------------------------------------


def test_timeout_raises_and_close_still_halts_without_hanging(emu, ptu, driver_clock):
    emu.stop_answering()
    step = driver_clock.step
    t0 = driver_clock.t
    with pytest.raises(PTUTimeout, match=r"no reply from the PTU within 0\.5 s") as info:
        _ = ptu.pan_deg
    assert info.value.command == "PP"
    # On the driver's clock: the send, the deadline, then readings until it has passed.
    waited = driver_clock.t - t0
    assert DRIVER.timeout_s <= waited <= DRIVER.timeout_s + 3 * step, waited
    t0 = driver_clock.t
    ptu.close()
    waited = driver_clock.t - t0
    assert DRIVER.halt_timeout_s <= waited <= DRIVER.halt_timeout_s + 3 * step, waited
    assert emu.commands[-1] == "H"  # the halt was sent
    assert not ptu.is_open
    ptu.close()  # idempotent
    with pytest.raises(PTUPortError, match="closed"):
        ptu.move_to(pan_deg=1.0)


@pytest.mark.parametrize("exc_type", [RuntimeError, KeyboardInterrupt])
def test_leaving_the_with_block_by_an_exception_halts(emu, exc_type):
    with pytest.raises(exc_type):
        with FlirPTU(emu.port, DRIVER) as ptu:
            start_slow_pan_move(ptu, emu)
            raise exc_type("stop")
    assert emu.commands[-1] == "H"
    assert wait_until(lambda: not emu.moving)
    assert 0 < emu.positions[0] < 5000


def test_home_on_close(emu):
    with FlirPTU(emu.port, FlirPTUParams(**{**DRIVER.__dict__, "home_on_close": True})) as ptu:
        ptu.goto(pan_deg=100 * DP, tilt_deg=50 * DT)
    assert emu.commands[-4:] == ["H", "PP0", "TP0", "A"]
    assert emu.positions == (0, 0)


def test_missing_port_names_it():
    with pytest.raises(PTUPortError, match=r"'/dev/no-such-ptu-port' does not exist"):
        FlirPTU("/dev/no-such-ptu-port", DRIVER)


def test_busy_port_names_it(emu):
    with serial.Serial(emu.port, exclusive=True):
        with pytest.raises(PTUPortError, match="busy") as info:
            FlirPTU(emu.port, DRIVER)
    assert emu.port in str(info.value)
    with FlirPTU(emu.port, DRIVER) as ptu:  # free again
        assert ptu.is_open


def test_no_threads_or_ports_left_behind():
    before = threading.active_count()
    emu = PTUEmulator(PTUEmulatorParams(ptu=MOTION))
    ptu = FlirPTU(emu.port, DRIVER)
    ptu.close()
    emu.close()
    emu.close()
    assert threading.active_count() == before


# -- the reply parser, over loop:// --------------------------------------------------------


def test_reply_parser_over_loop_url():
    port = open_port("loop://")
    proto = PTUProtocol(port)
    try:
        proto.send("PP")  # loop:// returns it, as an echoing unit would
        port.write(b"* Current Pan position is -500\r\n")
        assert reply_number(proto.read_reply("PP", 0.5)) == -500.0
        proto.send("TR")
        port.write(b"* 92.5714\n")
        assert proto.read_reply("TR", 0.5) == "92.5714"
        proto.send("PP3200")
        port.write(b"! Maximum allowable Pan position is 3090\r")
        with pytest.raises(PTUError) as info:
            proto.read_reply("PP3200", 0.5)
        assert (info.value.message, info.value.command) == (
            "Maximum allowable Pan position is 3090",
            "PP3200",
        )
        proto.send("R")
        port.write(b"Initializing...\r\n!T!T!P!P*\r\n")
        assert proto.read_reply("R", 0.5) == ""
        proto.send("PP")
        with pytest.raises(PTUTimeout):
            proto.read_reply("PP", 0.05)
        assert proto.last_latency_s >= 0.0
    finally:
        port.close()
    with pytest.raises(ValueError) as info:
        PTUProtocol(port, delimiter=";")
    assert str(info.value) == "PTUProtocol delimiter must be a space, CR or LF, got ';'"
    assert parse_reply("", "PP") is None
    with pytest.raises(PTUError, match="no number"):
        reply_number("ASCII terse mode")


def test_driver_on_a_silent_loop_url_times_out_and_closes(driver_clock):
    params = FlirPTUParams(timeout_s=0.05, banner_quiet_s=0.0, banner_timeout_s=0.05)
    with pytest.raises(PTUTimeout) as info:
        FlirPTU("loop://", params)
    assert info.value.command == "FT"
    # On the driver's clock: the banner's drain ends at once (quiet_s 0), FT's wait at
    # its timeout (the send, the deadline and the last reading past it).
    assert params.timeout_s <= driver_clock.t <= params.timeout_s + 5 * driver_clock.step


# -- the emulator's protocol, byte for byte -------------------------------------------------


def exchange(port, command: bytes) -> bytes:
    port.write(command)
    return port.readline()


def test_emulator_replies_byte_for_byte():
    params = PTUEmulatorParams(ptu=MOTION, banner="")
    # A reply is read as soon as its line ends: the long timeout only spares a loaded host.
    with PTUEmulator(params) as emu, serial.Serial(emu.port, timeout=10.0) as port:
        # Power-up: echo on, verbose.
        assert exchange(port, b"PP ") == b"PP * Current Pan position is 0\r\n"
        assert exchange(port, b"pr ") == b"pr * 46.2857 seconds arc per position\r\n"
        assert exchange(port, b"PX ") == b"PX * Maximum Pan position is 6000\r\n"
        assert exchange(port, b"TN ") == b"TN * Minimum Tilt position is -900\r\n"
        assert exchange(port, b"PU ") == b"PU * Maximum Pan speed is 8000 positions/sec\r\n"
        assert exchange(port, b"TA ") == b"TA * Tilt acceleration is 40000 positions/sec^2\r\n"
        assert exchange(port, b"E ") == b"E * Echoing ON\r\n"
        assert exchange(port, b"F ") == b"F * ASCII verbose mode\r\n"
        assert exchange(port, b"L ") == b"L * Limit bounds are ENABLED (soft limits enabled)\r\n"
        assert exchange(port, b"C ") == b"C * Independent speed control mode\r\n"
        assert exchange(port, b"V ").startswith(b"V * Pan-Tilt Controller v2.14.0")
        assert exchange(port, b"ED ") == b"ED *\r\n"
        assert exchange(port, b"FT\r") == b"*\r\n"
        assert exchange(port, b"F ") == b"* ASCII terse mode\r\n"
        assert exchange(port, b"PR\n") == b"* 46.2857\r\n"
        assert exchange(port, b"PP7000 ") == b"! Maximum allowable Pan position is 6000\r\n"
        assert exchange(port, b"TP-901 ") == b"! Minimum allowable Tilt position is -900\r\n"
        assert exchange(port, b"PS9000 ") == b"! Pan speed cannot exceed 8000 positions/sec\r\n"
        assert exchange(port, b"PP1.5 ") == b"! Illegal argument\r\n"
        assert exchange(port, b"QQ ") == b"! Illegal Command Entered\r\n"
        # A answers only when stopped; a halt sent during A goes through and ends it.
        port.write(b"PP5000 A H ")
        assert [port.readline() for _ in range(3)] == [b"*\r\n"] * 3
        assert not emu.moving and 0 < emu.positions[0] < 5000  # H ended A mid-move
        # Pure velocity mode: a signed speed drives the axis, 0 stops it.
        assert exchange(port, b"PP0 A ") == b"*\r\n" and port.readline() == b"*\r\n"
        assert exchange(port, b"CV ") == b"*\r\n"
        assert exchange(port, b"PS-2000 ") == b"*\r\n"
        assert wait_until(lambda: emu.positions[0] < -50)
        assert exchange(port, b"PS0 ") == b"*\r\n"
        assert wait_until(lambda: not emu.moving)
        assert exchange(port, b"CI ") == b"*\r\n"
        # PD queries the current speed; a reset answers with its limit hits.
        assert exchange(port, b"PD ") == b"* 0\r\n"
        assert exchange(port, b"R ") == b"!T!T!P!P*\r\n"
        assert emu.positions == (0, 0)
        assert exchange(port, b"DF ") == b"*\r\n"


def test_emulator_goes_silent_after_n_commands():
    params = PTUEmulatorParams(ptu=MOTION, banner="", silent_after=1)
    with PTUEmulator(params) as emu, serial.Serial(emu.port, timeout=10.0) as port:
        assert exchange(port, b"ED ") == b"ED *\r\n"
        port.timeout = 0.1  # silence: nothing comes, however long one waits
        assert exchange(port, b"PP ") == b""
        assert wait_until(lambda: emu.commands == ["ED", "PP"])
        emu.resume_answering()
        port.timeout = 10.0
        assert exchange(port, b"PP ") == b"* Current Pan position is 0\r\n"


def test_emulator_and_driver_params_are_checked():
    bad = [
        (
            lambda: PTUEmulatorParams(reset_s=-1.0),
            "PTUEmulatorParams.reset_s must be a finite number >= 0, got -1.0",
        ),
        (
            lambda: PTUEmulatorParams(poll_s=0.0),
            "PTUEmulatorParams.poll_s must be a finite number > 0, got 0.0",
        ),
        (
            lambda: PTUEmulatorParams(silent_after=-1),
            "PTUEmulatorParams.silent_after must be an int >= 0, got -1",
        ),
        (
            lambda: FlirPTUParams(timeout_s=0.0),
            "FlirPTUParams.timeout_s must be a finite number > 0, got 0.0",
        ),
        (
            lambda: FlirPTUParams(delimiter=";"),
            "FlirPTUParams.delimiter must be a space, CR or LF, got ';'",
        ),
    ]
    for make, message in bad:
        with pytest.raises(ValueError) as info:
            make()
        assert str(info.value) == message
    # The line's settings have one home, the unit's link: none here but the defaults.
    assert PTUEmulatorParams().eol == PTULinkParams().eol == "\r\n"
    assert (FlirPTUParams().baudrate, FlirPTUParams().delimiter) == (9600, " ")


def test_doctests():
    flags = doctest.ELLIPSIS
    result = doctest.testmod(ptu_driver, optionflags=flags)
    assert (result.failed, result.attempted) == (0, 15)  # all ran, none failed
    result = doctest.testmod(ptu_emulator, optionflags=flags)
    assert (result.failed, result.attempted) == (0, 5)
