"""Fault injection, configuration: a bad setting gives the config's own error."""

from __future__ import annotations

import mujoco
import pytest

from wander_env.env_config import WanderConfig, control_period_us
from wander_env.renderer import CameraRenderer


def test_zero_subframes_is_the_configs_value_error():
    with pytest.raises(
        ValueError, match=r"^max_subframes: input should be greater than or equal to 1, got 0$"
    ):
        WanderConfig(max_subframes=0)


def test_a_camera_too_large_for_the_driver_does_not_blame_mujoco_gl(monkeypatch):
    monkeypatch.setenv("MUJOCO_GL", mujoco.GLContext.__module__.rpartition(".")[2])
    xml = (
        '<mujoco><visual><global offwidth="20000" offheight="20000"/></visual>'
        '<worldbody><camera name="event_camera"/></worldbody></mujoco>'
    )
    model = mujoco.MjModel.from_xml_string(xml)
    with pytest.raises(RuntimeError) as info:
        CameraRenderer(model, 20000, 20000)
    text = str(info.value)
    assert text.startswith("could not create a 20000x20000 OpenGL context")
    assert "set MUJOCO_GL" not in text and "may exceed what the GL driver" in text


@pytest.mark.parametrize(
    ("period_s", "rate_hz", "ticks", "tick_us"),
    [
        (0.01, 1000.0, 10, 1000),
        (0.01, 100.0, 1, 10000),
        (0.0125, 2000.0, 25, 500),
        (1.0, 1e5, 100000, 10),
    ],
)
def test_the_render_ticks_of_a_step_add_up_to_the_control_period(period_s, rate_hz, ticks, tick_us):
    cfg = WanderConfig(control_period_s=period_s, render_rate_hz=rate_hz)
    assert (cfg.ticks_per_step, cfg.tick_us) == (ticks, tick_us)
    assert cfg.ticks_per_step * cfg.tick_us == cfg.control_period_us == control_period_us(period_s)


def test_a_render_rate_whose_tick_is_no_whole_us_is_refused():
    with pytest.raises(ValueError) as info:
        WanderConfig(render_rate_hz=3000.0)
    assert str(info.value) == (
        "render_rate_hz: 3000.0 must give render periods of whole µs "
        "(10000 µs / 30 ticks = 333.333 µs)"
    )


@pytest.mark.parametrize("period_s", [1.5e-7, 0.0, -0.01, 1.5, 1e30])
def test_the_control_period_is_whole_us_in_0_1_s_in_the_sim_as_on_the_rig(period_s):
    message = f"control_period_s: must be a whole number of µs in (0, 1] s, got {period_s!r}"
    with pytest.raises(ValueError) as info:
        WanderConfig(control_period_s=period_s)
    assert str(info.value) == message
    with pytest.raises(ValueError) as info:
        control_period_us(period_s)
    assert str(info.value) == message
