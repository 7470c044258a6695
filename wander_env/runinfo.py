"""What every result folder records: its config, seed, git revision and versions."""

from __future__ import annotations

import json
import platform
import subprocess
import sys
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

GIT_TIMEOUT_S = 30.0  # a git that hangs (a lock, a network file system) must not hang a run


def git_revision(path: Path | None = None) -> str:
    """The current commit (with ``-dirty`` if the tree has changes), or ``"unknown"``
    (no git, not a checkout, or git took longer than ``GIT_TIMEOUT_S``)."""
    cwd = path or Path(__file__).resolve().parent
    try:
        rev = subprocess.run(
            ["git", "rev-parse", "HEAD"],
            cwd=cwd, capture_output=True, text=True, check=True, timeout=GIT_TIMEOUT_S,
        ).stdout.strip()  # fmt: skip
        dirty = subprocess.run(
            ["git", "status", "--porcelain", "--untracked-files=no"],
            cwd=cwd, capture_output=True, text=True, check=True, timeout=GIT_TIMEOUT_S,
        ).stdout.strip()  # fmt: skip
    except (OSError, subprocess.CalledProcessError, subprocess.TimeoutExpired):
        return "unknown"
    return rev + ("-dirty" if dirty else "")


def run_record(command: str, config: dict[str, Any], seed: int | None) -> dict[str, Any]:
    """The provenance block written next to every result."""
    return {
        "command": command,
        "config": config,
        "seed": seed,
        "git_revision": git_revision(),
        "created": datetime.now(timezone.utc).isoformat(timespec="seconds"),
        "python": sys.version.split()[0],
        "platform": platform.platform(),
    }


def write_json(path: Path, data: dict[str, Any]) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(data, indent=2, default=str) + "\n")
