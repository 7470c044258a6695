"""Module-level trial runners for the sweep fault tests (spawned workers import them)."""

from __future__ import annotations

import os
import signal
import time
from pathlib import Path


def sleepy(spec) -> dict:
    """Write this worker's pid into $SWEEP_PIDS, then outlast any test."""
    folder = Path(os.environ["SWEEP_PIDS"])
    (folder / f"{os.getpid()}.pid").write_text(str(os.getpid()))
    time.sleep(600)
    return {"trial": spec.index, "trial_id": spec.id, "repeat": spec.repeat, "seed": spec.seed}


def _row(spec) -> dict:
    return {"trial": spec.index, "trial_id": spec.id, "repeat": spec.repeat, "seed": spec.seed}


def _attempt(spec) -> int:
    """Count this attempt at the trial in $SWEEP_PIDS (``<trial id>.<n>`` files); returns n."""
    folder = Path(os.environ["SWEEP_PIDS"])
    n = len(list(folder.glob(f"{spec.id}.*"))) + 1
    (folder / f"{spec.id}.{n}").write_text(str(os.getpid()))
    return n


def killed_first_time(spec) -> dict:
    """The trial with index 1 is killed with SIGKILL (as the OOM killer would) in its first
    attempt; every attempt is counted."""
    if _attempt(spec) == 1 and spec.index == 1:
        os.kill(os.getpid(), signal.SIGKILL)
    return _row(spec)


def killed_always(spec) -> dict:
    """The trial with index 1 is killed with SIGKILL in every attempt."""
    _attempt(spec)
    if spec.index == 1:
        os.kill(os.getpid(), signal.SIGKILL)
    return _row(spec)
