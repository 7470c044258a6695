"""What every run folder records in ``run.json``: the command, its config and seed, the
git revision, the time, the platform and the versions of the packages that made it
(:func:`run_record`).

Examples:
    >>> r = run_record("wander demo", {"seconds": 1.0}, seed=0)
    >>> sorted(r)
    ['command', 'config', 'created', 'git_revision', 'platform', 'python', 'seed', 'versions']
"""

from __future__ import annotations

import platform
import subprocess
import sys
from datetime import datetime, timezone
from importlib import metadata
from pathlib import Path
from typing import Any

GIT_TIMEOUT_S = 30.0  # a git that hangs (a lock, a network file system) must not hang a run

#: The packages whose versions ``run.json`` records (distribution names).
VERSIONED_PACKAGES = ("numpy", "mujoco", "torch", "sinabs", "nengo", "gymnasium", "wander")


def git_revision(path: Path | None = None) -> str:
    """The current commit (with ``-dirty`` if the tree has changes), or ``"unknown"``
    (no git, not a checkout, or git took longer than ``GIT_TIMEOUT_S``)."""
    cwd = path or Path(__file__).resolve().parent

    def git(*args: str) -> str:
        done = subprocess.run(
            ["git", *args],
            cwd=cwd,
            capture_output=True,
            text=True,
            check=True,
            timeout=GIT_TIMEOUT_S,
        )
        return done.stdout.strip()

    try:
        rev = git("rev-parse", "HEAD")
        dirty = git("status", "--porcelain", "--untracked-files=no")
    except (OSError, subprocess.CalledProcessError, subprocess.TimeoutExpired):
        return "unknown"
    return rev + ("-dirty" if dirty else "")


def package_versions(names: tuple[str, ...] = VERSIONED_PACKAGES) -> dict[str, str | None]:
    """Python's version and each installed package's (``None`` when not installed).

    >>> v = package_versions(("numpy", "no-such-package-here"))
    >>> sorted(v), v["no-such-package-here"]
    (['no-such-package-here', 'numpy', 'python'], None)
    """
    out: dict[str, str | None] = {"python": platform.python_version()}
    for name in names:
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = None
    return out


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
        "versions": package_versions(),
    }


__all__ = ["VERSIONED_PACKAGES", "git_revision", "package_versions", "run_record"]
