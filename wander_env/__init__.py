"""wander_env: the simulator side of wander (events, DVS emulator, scenes, PTU, env).

MuJoCo picks its OpenGL backend when it is first imported; headless EGL is the
default here unless the user chose another (``MUJOCO_GL=osmesa``/``glfw``).
"""

import os

os.environ.setdefault("MUJOCO_GL", "egl")

from gymnasium.envs.registration import register as _register
from gymnasium.envs.registration import registry as _registry

# Entry points are strings: registering imports neither MuJoCo nor the env module. The rig
# env wander/Rig-v0 is registered by the package that holds it (``import hardware``).
if "wander/Wander-v0" not in _registry:
    _register(id="wander/Wander-v0", entry_point="wander_env.env:WanderEnv")
