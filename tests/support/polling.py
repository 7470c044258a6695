"""Waiting for another thread or process without asserting on the wall clock."""

from __future__ import annotations

import time
from collections.abc import Callable

# A guard against a hang, not a timing bound: long enough that only a broken condition
# reaches it on a loaded host (pytest-timeout ends the test later still).
LIMIT_S = 60.0


def wait_until(
    predicate: Callable[[], object], limit_s: float = LIMIT_S, every_s: float = 0.005
) -> bool:
    """Poll ``predicate`` every ``every_s`` until it is true (True) or ``limit_s`` has
    passed (False)."""
    deadline = time.monotonic() + limit_s
    while not predicate():
        if time.monotonic() > deadline:
            return False
        time.sleep(every_s)
    return True
