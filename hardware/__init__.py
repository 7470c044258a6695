"""The rig's devices: the FLIR PTU driver and emulator, the Speck and replay event sources.

Their warnings (a halt that was not acknowledged while closing a failed unit) go to the
``hardware`` loggers; what matters is also recorded in the run folder, so without a
logging configuration they stay quiet (the library convention: a ``NullHandler``).

Importing ``hardware`` registers the rig env ``wander/Rig-v0`` (the simulator below it
does not name the floor above): ``import hardware`` before ``gymnasium.make``, or
``gymnasium.make("hardware:wander/Rig-v0", ...)``, which imports it. The entry point is
a string, so registering imports neither pyserial nor samna.
"""

import logging

from gymnasium.envs.registration import register, registry

logging.getLogger(__name__).addHandler(logging.NullHandler())

if "wander/Rig-v0" not in registry:
    register(id="wander/Rig-v0", entry_point="hardware.rig_env:RigEnv", nondeterministic=True)
