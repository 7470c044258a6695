"""Ray's own messages on the driver go to a log file, not the terminal.

While the Ray backend runs, Ray speaks on the driver in two ways: its ``ray`` logger
(``Started a local Ray instance``, warnings) and the thread that listens for the
cluster's errors, which prints them on ``sys.stdout`` (a dead raylet's message with the
last 20 lines of its log, before the sweep's own one-line error). Ray has no switch for
the second (``log_to_driver=False`` covers the workers' output only), so
:func:`ray_output_to` routes both to a file for the duration: the ``ray`` logger gets a
handler on it (and stops propagating), and ``sys.stdout`` writes made by Ray's threads
(named ``ray_…``) go to it; every other thread's output is untouched.
"""

from __future__ import annotations

import logging
import sys
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any, TextIO

RAY_THREAD_PREFIX = "ray_"


class _ByThread:
    """A text stream that sends what Ray's threads write to ``log``, the rest to ``out``."""

    def __init__(self, out: TextIO, log: TextIO) -> None:
        self._out, self._log = out, log

    def _target(self) -> TextIO:
        name = threading.current_thread().name
        return self._log if name.startswith(RAY_THREAD_PREFIX) else self._out

    def write(self, text: str) -> int:
        return self._target().write(text)

    def flush(self) -> None:
        self._target().flush()

    def __getattr__(self, name: str) -> Any:  # isatty, fileno, encoding, ...
        return getattr(self._out, name)


@contextmanager
def ray_output_to(path: Path) -> Iterator[None]:
    """Within the block, Ray's logger records and its threads' prints are appended to
    ``path`` (created if missing); both are restored on the way out."""
    with open(path, "a", encoding="utf-8") as log:
        handler = logging.StreamHandler(log)
        handler.setFormatter(logging.Formatter("%(asctime)s %(levelname)s %(name)s: %(message)s"))
        ray_logger = logging.getLogger("ray")
        saved = ray_logger.handlers[:], ray_logger.propagate
        ray_logger.handlers, ray_logger.propagate = [handler], False
        out = sys.stdout
        routed = _ByThread(out, log)
        sys.stdout = routed
        try:
            yield
        finally:
            if sys.stdout is routed:
                sys.stdout = out
            ray_logger.handlers, ray_logger.propagate = saved
            handler.flush()
