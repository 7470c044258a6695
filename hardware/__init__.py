"""The rig's devices: the FLIR PTU driver and emulator, the Speck and replay event sources.

Their warnings (a halt that was not acknowledged while closing a failed unit) go to the
``hardware`` loggers; what matters is also recorded in the run folder, so without a
logging configuration they stay quiet (the library convention: a ``NullHandler``).
"""

import logging

logging.getLogger(__name__).addHandler(logging.NullHandler())
