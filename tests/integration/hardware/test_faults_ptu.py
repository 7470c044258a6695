"""Fault injection, PTU: an emulated unit that fails on cue (error replies, silence,
garbage, a closed pty), at the driver and through ``wander rig``."""

from __future__ import annotations

import numpy as np
import pytest
from test_cli_rig import (  # noqa: F401  (fixtures: app, patient_driver, square)
    QUICK,
    app,
    assert_events_of_steps,
    assert_one_line_failure,
    on_first_move,
    patient_driver,
    read_folder,
    run_emulated,
    run_stepped,
    square,
)
from test_rig_env import make_rig, recording  # noqa: F401  (fixture: recording)

from hardware.ptu_driver import (
    MAX_LINE_BYTES,
    FlirPTU,
    FlirPTUParams,
    PTUFlood,
    PTUPortError,
    PTUProtocol,
    PTUTimeout,
)
from hardware.ptu_emulator import PTUEmulator

DRIVER = FlirPTUParams(timeout_s=0.5, halt_timeout_s=0.2, banner_quiet_s=0.02)


@pytest.fixture
def emu():
    with PTUEmulator(QUICK) as e:
        yield e


def test_closed_pty_is_a_port_error_and_close_does_not_raise(emu):
    ptu = FlirPTU(emu.port, DRIVER)
    assert ptu.pan_deg == 0.0
    emu.hang_up()
    with pytest.raises(PTUPortError) as info:
        _ = ptu.pan_deg
    assert info.value.command == "PP"
    assert "Input/output error" in str(info.value)  # termios.error(EIO) underneath
    ptu.close()  # halt attempted, fails, logged; the port is closed
    assert not ptu.is_open
    ptu.close()


def test_garbage_reply_is_a_timeout_that_shows_it(emu):
    with FlirPTU(emu.port, DRIVER) as ptu:
        emu.inject_garbage("#$%&noise")
        with pytest.raises(PTUTimeout, match=r"lines that are no reply: \['#\$%&noise'\]"):
            _ = ptu.pan_deg
        assert ptu.pan_deg == 0.0  # the exchange is back in step


FLOOD = "x" * 488_000 + "<end of the flood>"  # 488 KB with no line end, as a unit sent


class FakePort:
    """A serial port whose input is what the test puts in (``loop://`` blocks past 4 KB)."""

    def __init__(self) -> None:
        self.input = bytearray()

    @property
    def in_waiting(self) -> int:
        return len(self.input)

    def read(self, n: int) -> bytes:
        got = bytes(self.input[:n])
        del self.input[:n]
        return got

    def write(self, data: bytes) -> None:  # what the host sends is not echoed
        pass

    def flush(self) -> None:
        pass

    def reset_input_buffer(self) -> None:
        self.input.clear()


@pytest.mark.parametrize("tail", ["", "\r\n* 5\r\n"])
def test_a_flood_with_no_line_end_is_one_short_line_and_the_input_is_dropped(tail):
    port = FakePort()
    proto = PTUProtocol(port)
    port.input += (FLOOD + tail).encode("ascii")  # the line end, if any, comes too late
    with pytest.raises(PTUFlood) as info:
        proto.read_reply("PP", timeout_s=5.0)
    text = str(info.value)
    assert "\n" not in text and len(text) <= 320
    assert text.startswith(f"the PTU sent more than {MAX_LINE_BYTES} bytes without a line end")
    assert text.endswith("(command 'PP')")
    # the quote is the flood's last characters, 200 at most, quotes included
    quoted = text[text.index("ending ") + len("ending ") : text.index(" (command")]
    assert len(quoted) == 200 and quoted.startswith("'x") and quoted.endswith("'")
    assert info.value.command == "PP"
    port.input += b"* 7\r\n"  # the flood (and what came with it) was dropped: back in step
    assert proto.read_reply("PP", timeout_s=5.0) == "7"


def test_a_line_of_exactly_the_cap_is_read():
    port = FakePort()
    proto = PTUProtocol(port)
    port.input += b"* " + b"9" * (MAX_LINE_BYTES - 2) + b"\n"
    assert proto.read_reply("PP", timeout_s=5.0) == "9" * (MAX_LINE_BYTES - 2)


def test_a_flood_mid_run_is_a_short_error_and_a_short_ptu_error_in_the_stats(
    recording,  # noqa: F811
    emu,
):
    camera, _ = recording
    env = make_rig(emu.port, camera, ptu_poll_s=10.0)  # no poll ("PP") before the move
    try:
        env.reset()
        emu.inject_garbage("x" * (MAX_LINE_BYTES + 1000))  # then the unit's line end
        with pytest.raises(PTUFlood) as info:  # from the step, or once the PTU thread sees it
            env.step(np.float32((0.2, 0.0)))
            env.settle()
        text = str(info.value)
        assert "\n" not in text and len(text) < 600
        assert f"the PTU sent more than {MAX_LINE_BYTES} bytes without a line end" in text
        stored = env.stats["ptu_error"]
        assert stored.startswith("PTUFlood(") and len(stored) == 200  # cut to 200 characters
    finally:
        env.close()


@pytest.mark.slow
@pytest.mark.parametrize("fault", ["hang_up", "garbage", "silence"])
def test_rig_mid_run_fault_is_one_line_exit_1_with_the_halt_recorded(
    app,  # noqa: F811
    square,  # noqa: F811
    emu,
    tmp_path,
    monkeypatch,
    fault,
):
    camera, expected = square
    action = {
        "hang_up": emu.hang_up,
        "garbage": lambda: emu.inject_garbage("#$%&noise", count=1000),
        "silence": emu.stop_answering,
    }[fault]
    on_first_move(monkeypatch, emu, action)
    out = tmp_path / "run"
    result = run_stepped(app, emu, camera, out, "2", "--no-fixational")
    metrics, _, _ = read_folder(out)
    steps = metrics["steps"]
    line = assert_one_line_failure(
        result,
        f"wander rig: PTU '{emu.port}'",
        f"The run folder '{out}' holds what was recorded ({steps} steps completed).",
    )
    # the 13th step (window 0.12 s) sends the first move; the poll after it meets the fault
    assert steps == 12 and metrics["error"].startswith("PTU")
    halt = metrics["rig"]["ptu_halt"]
    if fault == "hang_up":
        assert "Input/output error" in line
        assert halt.startswith("halt (H) sent, not acknowledged")
        assert "PTUPortError" in metrics["rig"]["ptu_error"]
    else:
        assert halt.startswith("halt (H) sent, not acknowledged")
        assert "PTUTimeout" in metrics["rig"]["ptu_error"]
    assert_events_of_steps(out, expected, metrics)


def test_speck_unplugged_mid_run_is_one_line_exit_1_with_the_halt_recorded(
    app,  # noqa: F811
    tmp_path,
    monkeypatch,
    patient_driver,  # noqa: F811
):
    import numpy as np
    from fake_samna import FakeSamna, FakeSpeck, install

    from agents.attention import AttentionAgent
    from wander_env.events import make_events

    rng = np.random.default_rng(1)
    n = 30_000
    ev = make_events(
        rng.integers(0, 128, n),
        rng.integers(0, 128, n),
        np.sort(rng.integers(0, 3_000_000, n)),
        rng.integers(0, 2, n),
    )
    fake = install(monkeypatch, FakeSamna([("Speck2fDevKit", "sf", FakeSpeck(ev))]))
    act, calls = AttentionAgent.act, []

    def unplug_at_step_6(self, observation, info):
        calls.append(1)
        if len(calls) == 6:

            def gone(timeout):
                raise OSError(5, "USB device gone")

            fake.handles[-1]._sinks[0].get_events_blocking = gone
        return act(self, observation, info)

    monkeypatch.setattr(AttentionAgent, "act", unplug_at_step_6)
    out = tmp_path / "run"
    result = run_emulated(app, "speck", out, "2", "--no-video")
    metrics, _, _ = read_folder(out)
    assert_one_line_failure(
        result,
        "wander rig: camera 'speck' failed mid-run: Speck reader thread failed",
        "USB device gone",
        f"The run folder '{out}' holds what was recorded ({metrics['steps']} steps completed).",
    )
    assert 5 <= metrics["steps"] < 200  # unplugged during the 6th step
    # attempted and recorded (acknowledged unless a loaded machine starved the emulator)
    assert metrics["rig"]["ptu_halt"].startswith("halt (H) ")
    assert fake.handles[-1].closed


def test_stuck_link_write_times_out_into_the_port_fault_path(emu, caplog):
    """A wedged line (nothing drains the pty): the write is bounded by write_timeout_s
    and fails as a PTUPortError naming the command; close's halt is bounded too."""
    import logging

    params = FlirPTUParams(
        timeout_s=0.5, halt_timeout_s=0.2, banner_quiet_s=0.02, write_timeout_s=0.3
    )
    ptu = FlirPTU(emu.port, params)
    assert ptu._port.write_timeout == 0.3
    assert ptu.pan_deg == 0.0
    emu.stall()
    with pytest.raises(PTUPortError, match=r"writing 'PP' timed out after 0\.3 s") as info:
        _ = ptu.pan_deg
    assert info.value.command == "PP"
    with caplog.at_level(logging.WARNING, logger="hardware.ptu_driver"):
        ptu.close()  # its halt's write times out too: logged, the port closed
    assert not ptu.is_open
    assert any(
        "halt on close failed" in r.getMessage()
        and "writing 'H' timed out after 0.3 s" in r.getMessage()
        for r in caplog.records
    ), caplog.text
