"""Fault injection, configuration: a bad setting gives the config's own error."""

from __future__ import annotations

import mujoco
import pytest

from wander_env.env_config import WanderConfig
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
