"""The PTU's serial-link command latency (wander_env.ptu.link.CommandLink), against the rig."""

from __future__ import annotations

import math
import pickle
import time
from dataclasses import asdict, replace

import gymnasium as gym
import numpy as np
import pytest
import serial
from fake_clock import FakeClock

import wander_env  # noqa: F401  (registers the environments)
from hardware.ptu_driver import FlirPTUParams
from hardware.ptu_emulator import PTUEmulator, PTUEmulatorParams
from wander_env.events import make_events
from wander_env.events.io import EventRecording, write_events
from wander_env.ptu.link import CommandLink, PTULinkParams, command_bytes, reply_bytes
from wander_env.ptu.params import PTUParams
from wander_env.ptu.unit import PanTiltUnit

BYTE = 10 / 9600  # s per byte at 9600 8N1


def test_byte_counts_are_the_drivers_and_emulators_strings() -> None:
    link = PTULinkParams()
    assert command_bytes(0, 1234, link) == len("PP1234 ")
    assert command_bytes(1, -907, link) == len("TP-907 ")
    assert command_bytes(0, None, link) == len("PP ")
    assert reply_bytes(None, link) == len("*\r\n")
    assert reply_bytes(-3090, link) == len("* -3090\r\n")


def test_a_command_on_an_idle_line_costs_its_bytes() -> None:
    link = CommandLink(PTULinkParams(), (0, 0))
    ptu = PanTiltUnit(PTUParams.preset("flir"))
    ptu.link = link
    link.submit((100, -50), 0.0)
    ptu.step(0.05)
    # PP100 + *, then TP-50 + *: (6 + 3) + (6 + 3) bytes
    assert link.schedule.latencies_s == [pytest.approx(18 * BYTE, abs=1e-12)]
    assert link.schedule.counts["commands_sent"] == 1


def test_a_command_waits_for_the_poll_in_progress() -> None:
    ptu = PanTiltUnit(PTUParams.preset("flir"))
    ptu.step(0.0105)  # the first poll began at poll_s = 10 ms: PP is on the line
    ptu.set_target(pan_deg=100 * ptu.params.pan_deg_per_pos)
    ptu.step(0.1)
    # The poll: PP (3) + "* 0\r\n" (5), TP (3) + "* 0\r\n" (5) = 16 bytes from 10 ms;
    # then PP100 (6) + * (3).
    expected = 0.010 + 16 * BYTE + 9 * BYTE - 0.0105
    assert ptu.link.schedule.latencies_s == [pytest.approx(expected, abs=1e-9)]


def test_the_axis_moves_only_once_the_command_has_arrived() -> None:
    ptu = PanTiltUnit(PTUParams.preset("flir"))
    ptu.set_target(pan_deg=200 * ptu.params.pan_deg_per_pos)
    ptu.step(6 * BYTE - 1e-6)  # "PP200 " is 6 bytes
    assert ptu.positions == (0, 0) and ptu.moving
    ptu.step(0.002)
    # From the base speed (1000 positions/s) at 2000 positions/s^2 from the arrival on:
    # 2 ms less the 1 us before it.
    deg = ptu.params.pan_deg_per_pos
    assert ptu.pan_velocity_deg_s == pytest.approx((1000 + 2000 * (0.002 - 1e-6)) * deg)
    ideal = PanTiltUnit(PTUParams.preset("ideal"))
    ideal.set_target(pan_deg=200 * ideal.params.pan_deg_per_pos)
    ideal.step(6 * BYTE - 1e-6)
    # No link: it accelerates from the step's start.
    assert ideal.pan_velocity_deg_s == pytest.approx((1000 + 2000 * (6 * BYTE - 1e-6)) * deg)
    assert math.isnan(ideal.command_latency_s)


def test_moving_is_the_rigs_until_a_poll_sees_the_target() -> None:
    ptu = PanTiltUnit(PTUParams.preset("flir"))
    ideal = PanTiltUnit(PTUParams.preset("ideal"))
    for unit in (ptu, ideal):
        unit.set_target(pan_deg=20 * unit.params.pan_deg_per_pos)
    t_ideal = t_flir = None
    for k in range(1, 400):
        for unit in (ptu, ideal):
            unit.step(0.001)
        if t_ideal is None and not ideal.moving:
            t_ideal = k
        if t_flir is None and not ptu.moving:
            t_flir = k
    # The link adds the command's 9 bytes before the move and up to a poll after it.
    assert t_flir - t_ideal >= 9 * BYTE * 1e3
    assert t_flir - t_ideal <= (9 + 16) * BYTE * 1e3 + 10 + 16 * BYTE * 1e3 + 1
    # 20 positions at the base speed: 20 ms; on the link, the step that ends the move
    # after the command's bytes and the poll that sees the target.
    assert (t_ideal, t_flir) == (20, 53)
    assert ptu.link.schedule.positions == (20, 0) and ptu.link.schedule.poll_target == (20, 0)


def test_the_split_of_the_steps_does_not_change_the_result() -> None:
    a, b = PanTiltUnit(PTUParams.preset("flir")), PanTiltUnit(PTUParams.preset("flir"))
    for k in range(30):
        for unit, substeps in ((a, 1), (b, 7)):
            if k % 4 == 0:
                unit.set_target(pan_deg=(k % 8) * 0.5, tilt_deg=-(k % 3) * 0.3)
            for _ in range(substeps):
                unit.step(0.01 / substeps)
    assert a.link.schedule.latencies_s == pytest.approx(b.link.schedule.latencies_s, abs=1e-12)
    assert a.positions == b.positions and a.moving == b.moving
    assert a.link.schedule.counts == b.link.schedule.counts


def test_presets_round_trip_through_asdict_and_pickle() -> None:
    flir = PTUParams.preset("flir")
    assert PTUParams(**asdict(flir)) == flir
    assert pickle.loads(pickle.dumps(flir)) == flir
    assert PTUParams.preset("ideal") == PTUParams()
    with pytest.raises(ValueError, match="unknown PTU preset 'fast'"):
        PTUParams.preset("fast")
    with pytest.raises(ValueError, match="baudrate must be an int > 0"):
        PTULinkParams(baudrate=0)


def test_link_params_check_their_line_ends() -> None:
    for kwargs, message in [
        ({"delimiter": ";"}, "PTULinkParams.delimiter must be a space, CR or LF, got ';'"),
        ({"eol": ";"}, "PTULinkParams.eol must be CR LF, LF or CR, got ';'"),
    ]:
        with pytest.raises(ValueError) as info:
            PTULinkParams(**kwargs)
        assert str(info.value) == message


@pytest.mark.parametrize("turnaround_s", [0.0, 0.05])
def test_emulator_paces_its_replies_at_the_units_link(turnaround_s: float) -> None:
    """The emulated unit's line is its ``ptu.link``, the simulated unit's settings."""
    flir = PTUParams.preset("flir")
    ptu = replace(flir, link=replace(flir.link, turnaround_s=turnaround_s))
    params = PTUEmulatorParams(ptu=ptu, banner="", echo=False, verbose=False)
    with PTUEmulator(params) as emu, serial.Serial(emu.port, timeout=10) as port:
        t0 = time.monotonic()
        port.write(b"PP ")
        line = port.readline()
        dt = time.monotonic() - t0
    assert line == b"* 0\r\n"
    # 3 bytes in, the turnaround, 5 out: 8.3 ms on the line (+ 50 ms) before the reply can
    # be read (a lower bound the pacing guarantees; how much later a loaded host delivers
    # it is not the emulator's).
    assert dt >= 8 * BYTE + turnaround_s - 1e-4


@pytest.mark.slow
def test_simulated_latency_matches_the_rig_env_on_the_emulator_at_9600_baud(tmp_path) -> None:
    """The rig env's measured ``command_latency_s`` (PTU emulator paced at 9600 baud,
    real-time replay) against :class:`CommandLink` driven by the same targets at the same
    step times: never below the line's pace, which the sim's quickest exchange is. How
    far above it the rig lands is the host's scheduling (printed, not asserted: the same
    traffic on the same line is asserted on the line's own clock in
    ``test_the_sim_link_and_the_rig_link_put_the_same_bytes_on_the_wire``)."""
    n_steps, span_us = 240, 3_000_000
    t = np.arange(0, span_us, 2000)
    ev = make_events(t % 128, (t // 128) % 128, t, t % 2)
    path = tmp_path / "tick.npz"
    write_events(path, EventRecording(ev, (128, 128, 2)))
    flir = PTUParams.preset("flir")  # the sim's unit and the emulator's: one link
    emulator = PTUEmulatorParams(ptu=flir, banner="")
    env = gym.make(
        "wander/Rig-v0",
        ptu_port="emulate",
        camera=f"replay:{path}",
        replay="realtime",
        emulator=emulator,
        driver=FlirPTUParams(banner_quiet_s=0.02),
        episode_seconds=10.0,
    )
    rig_latencies, targets = [], []
    try:
        env.reset()
        last = math.nan
        for k in range(n_steps):
            a = np.zeros(2, np.float32)
            if k % 6 == 0:  # a command every 60 ms, both axes, alternating
                s = 1.0 if (k // 6) % 2 == 0 else -1.0
                a[:] = (0.05 * s, -0.03 * s)
            _, _, _, _, info = env.step(a)
            targets.append(tuple(info["ptu_target_positions"]))
            lat = info["command_latency_s"]
            if not math.isnan(lat) and lat != last:
                rig_latencies.append(lat)
                last = lat
    finally:
        env.close()
    sim = PanTiltUnit(flir)
    for target in targets:  # the sim env commands at each step's start, as the rig env
        sim.set_target_positions(*target)
        sim.step(0.01)
    sim.step(0.2)
    sim_latencies = sim.link.schedule.latencies_s
    assert len(sim_latencies) == len(range(0, n_steps, 6))
    assert len(rig_latencies) >= 10  # a loaded host lags the real-time steps: commands merge
    rig_med, sim_med = float(np.median(rig_latencies)), float(np.median(sim_latencies))
    print(
        f"command latency: rig median {rig_med * 1e3:.2f} ms (mean "
        f"{np.mean(rig_latencies) * 1e3:.2f}), sim median {sim_med * 1e3:.2f} ms (mean "
        f"{np.mean(sim_latencies) * 1e3:.2f}), {len(rig_latencies)} / {len(sim_latencies)} commands"
    )
    # Every command moves both axes: each exchange carries at least the quickest one's
    # bytes (a position may print one digit shorter: 10 %), paced by the emulator.
    assert min(rig_latencies) >= 0.9 * min(sim_latencies)


class _Line:
    """The rig's serial port as a 9600-baud line: every byte written or read advances the
    clock by its time on the line (so the rig's exchanges last what the sim's do); keeps
    the bytes written."""

    def __init__(self, port: serial.SerialBase, clock: FakeClock, byte_s: float) -> None:
        self.port, self.clock, self.byte_s = port, clock, byte_s
        self.sent = bytearray()

    def write(self, data: bytes) -> int:
        self.sent += data
        self.clock.t += len(data) * self.byte_s
        return self.port.write(data)

    def read(self, size: int = 1) -> bytes:
        data = self.port.read(size)
        self.clock.t += len(data) * self.byte_s
        return data

    def __getattr__(self, name: str):  # in_waiting, flush, reset_input_buffer, ...
        return getattr(self.port, name)


class _Unit:
    """The sim link's unit: answers a poll with its latest target; keeps the words received."""

    def __init__(self, start: tuple[int, int]) -> None:
        self.pos = list(start)
        self.words: list[str] = []

    def step_counter(self, axis: int) -> int:
        self.words.append("PT"[axis] + "P")
        return self.pos[axis]

    def drive_axis(self, axis: int, pos: float) -> None:
        self.words.append(f"{'PT'[axis]}P{int(pos)}")
        self.pos[axis] = int(pos)


def test_the_sim_link_and_the_rig_link_put_the_same_bytes_on_the_wire() -> None:
    """One command sequence through :class:`CommandLink` (simulated time) and through the
    rig's :class:`~hardware.ptu_link_thread.PTULinkThread` against the emulator on a pty (its clock
    injected and moved by the bytes on the line): the same bytes sent, in the same order
    (queue-replace, pan before tilt, changed axes only, polls every ``poll_s``)."""
    from hardware.ptu_driver import FlirPTU
    from hardware.ptu_link_thread import PTULinkThread
    from wander_env.ptu.units import positions_to_degrees

    start = (200, 150)  # every position on the way is 3 digits: the replies' lengths agree
    script = [
        (0.005, (300, 150)),  # pan only
        (0.050, (300, 250)),  # tilt only
        (0.080, (300, 250)),  # the acknowledged target: a poll, no command
        (0.120, (400, 350)),  # both axes
        (0.200, (500, 300)),  # goes at once...
        (0.201, (600, 200)),  # ...this waits...
        (0.202, (700, 400)),  # ...and is replaced by this one
        (0.300, None),
    ]
    params = PTULinkParams()
    sim = CommandLink(params, start)
    unit = _Unit(start)
    for t, target in script:
        while sim.next_time() <= t:
            sim.fire(unit)
        if target is not None:
            sim.submit(target, t)
    while sim.schedule.current is not None:  # the exchange begun by the end, to its end
        sim.fire(unit)
    sim_wire = "".join(w + params.delimiter for w in unit.words).encode()

    quiet = PTUEmulatorParams(banner="")
    with PTUEmulator(quiet) as emu, FlirPTU(emu.port, FlirPTUParams(banner_quiet_s=0.02)) as ptu:
        res = ptu.resolution_arcsec
        ptu.goto(*(positions_to_degrees(p, r) for p, r in zip(start, res, strict=True)))
        clock = FakeClock()
        rig = PTULinkThread(ptu, params.poll_s, clock)  # not started: the test serves it
        line = _Line(ptu._proto.port, clock, params.byte_s)
        ptu._proto.port = line
        emu.clear_commands()
        for t, target in script:
            while (due := rig.schedule.due_s()) <= t:
                clock.t = max(clock.t, due)
                assert rig.serve()
            clock.t = max(clock.t, t)
            if target is not None:
                rig.command(target)
        received, sent = emu.commands, bytes(line.sent)
        rig.close()  # (the driver's halt on leaving the block is not part of the sequence)

    assert sent == sim_wire
    assert received == unit.words
    poll = ["PP", "TP"]
    assert unit.words == [
        *["PP300", *poll, *poll],  # a poll at once after a command, the next poll_s later
        *["TP250", *poll, *poll],
        *["PP400", "TP350", *poll, *poll],
        *["PP500", "TP300", "PP700", "TP400"],  # (600, 200) replaced while PP500 was out
        *poll,
        *poll,
        *poll,
    ]
    assert (
        sim.schedule.counts
        == rig.counts
        == {"commands_sent": 5, "commands_replaced": 1, "polls": 9}
    )
