"""Module-level trial runners for the sweep fault tests (spawned workers import them)."""

from __future__ import annotations

import os
import time
from pathlib import Path


def sleepy(spec) -> dict:
    """Write this worker's pid into $SWEEP_PIDS, then outlast any test."""
    folder = Path(os.environ["SWEEP_PIDS"])
    (folder / f"{os.getpid()}.pid").write_text(str(os.getpid()))
    time.sleep(600)
    return {"trial": spec.index, "trial_id": spec.id, "repeat": spec.repeat, "seed": spec.seed}
