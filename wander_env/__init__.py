"""wander_env: the simulator side of wander (events, DVS emulator, scenes, PTU, env).

MuJoCo picks its OpenGL backend when it is first imported; headless EGL is the
default here unless the user chose another (``MUJOCO_GL=osmesa``/``glfw``).
"""

import os

os.environ.setdefault("MUJOCO_GL", "egl")
