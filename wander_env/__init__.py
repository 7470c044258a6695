"""wander_env: the simulator side of wander (events, DVS emulator, scenes, PTU, env).

MuJoCo picks its OpenGL backend when it is first imported; headless EGL is the
default here unless the user chose another (``MUJOCO_GL=osmesa``/``glfw``). On Mesa's
software rasteriser (llvmpipe) the drawing stays on the thread that draws
(``LP_NUM_THREADS=0``, read when MuJoCo opens its display) unless the user set it: the
env's render thread is the drawing's parallelism, and llvmpipe's own rasteriser threads
only competed with the main thread for the cores (closed loop on 2 cores: 1.03x real
time against 0.89-0.93x with 1 or 2 rasteriser threads; docs/benchmarks.md). For the
same reason OpenCV runs its work on the calling thread (``OPENCV_FOR_THREADS_NUM=1``,
read when cv2 is first imported) unless the user set it: its pool's second thread spun
(``sched_yield``) between the in-between frames' warps, 0.5 ms of CPU a closed-loop step
taken from the render thread's core.
"""

import os

os.environ.setdefault("MUJOCO_GL", "egl")
os.environ.setdefault("LP_NUM_THREADS", "0")
os.environ.setdefault("OPENCV_FOR_THREADS_NUM", "1")

from gymnasium.envs.registration import register as _register
from gymnasium.envs.registration import registry as _registry

# Entry points are strings: registering imports neither MuJoCo nor the env module. The rig
# env wander/Rig-v0 is registered by the package that holds it (``import hardware``).
if "wander/Wander-v0" not in _registry:
    _register(id="wander/Wander-v0", entry_point="wander_env.env:WanderEnv")
