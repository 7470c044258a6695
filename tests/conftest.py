"""Test session setup: headless EGL rendering before any module imports MuJoCo.

MuJoCo picks its OpenGL backend when ``mujoco`` is first imported; a test module that
imports ``mujoco`` before ``wander_env`` would otherwise get GLFW, which needs a display.
"""

import os

os.environ.setdefault("MUJOCO_GL", "egl")
