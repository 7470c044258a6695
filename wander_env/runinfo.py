"""What every result folder records: its config, seed, git revision and versions.

JSON is written strictly (:func:`to_strict_json`): a missing or undefined figure (NaN,
±inf) is ``null``, NumPy scalars and arrays become plain numbers and lists, so every
file parses with a strict parser (``json.loads(text, parse_constant=...)`` raising).

Examples:
    >>> import math, numpy as np
    >>> to_strict_json({"a": math.nan, "b": np.float32(0.5), "c": [np.inf, 1]})
    {'a': None, 'b': 0.5, 'c': [None, 1]}
    >>> dumps_strict({"x": float("nan")})
    '{"x": null}'
"""

from __future__ import annotations

import json
import math
import platform
import subprocess
import sys
from datetime import datetime, timezone
from importlib import metadata
from pathlib import Path
from typing import Any

import numpy as np

GIT_TIMEOUT_S = 30.0  # a git that hangs (a lock, a network file system) must not hang a run

#: The packages whose versions ``run.json`` records (distribution names).
VERSIONED_PACKAGES = ("numpy", "mujoco", "torch", "sinabs", "nengo", "gymnasium", "wander")


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


def to_strict_json(value: Any) -> Any:
    """``value`` with every non-finite float replaced by ``None`` and NumPy values made
    plain (recursively through dicts, lists and tuples); other objects are left as they
    are (``json.dumps(default=str)`` turns them into text)."""
    if isinstance(value, dict):
        return {str(k): to_strict_json(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [to_strict_json(v) for v in value]
    if isinstance(value, np.ndarray):
        return to_strict_json(value.tolist())
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def dumps_strict(data: Any, **kwargs: Any) -> str:
    """``json.dumps`` of :func:`to_strict_json` ``(data)``; never writes NaN/Infinity."""
    kwargs.setdefault("default", str)
    return json.dumps(to_strict_json(data), allow_nan=False, **kwargs)


def write_json(path: Path, data: dict[str, Any]) -> None:
    """Write ``data`` as strict, indented JSON (NaN and ±inf as ``null``)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(dumps_strict(data, indent=2) + "\n")


def new_run_dir(
    out: Path | None, command: str, force: bool = False, root: Path = Path("runs")
) -> Path:
    """The folder a run writes to (not created here: a run that fails before it starts
    leaves nothing behind); the run folders of ``wander run``, ``record``, ``rig``,
    ``demo`` and ``evaluate`` are new per run.

    ``out`` None: a new time-stamped folder ``root/COMMAND-YYYYmmdd-HHMMSS`` (``-2``,
    ``-3``… when that exists). An explicit ``out`` that exists and is not empty is
    refused (:class:`FileExistsError`) unless ``force``.

    >>> import tempfile
    >>> root = Path(tempfile.mkdtemp())
    >>> a = new_run_dir(None, "run", root=root)
    >>> a.name[:4], len(a.name) == len("run-20260101-120000"), a.parent == root, a.exists()
    ('run-', True, True, False)
    >>> a.mkdir(); new_run_dir(None, "run", root=root) != a
    True
    >>> (a / "metrics.json").write_text("{}")
    2
    >>> new_run_dir(a, "run")
    Traceback (most recent call last):
    ...
    FileExistsError: ... is not empty: pass --force to write into it, ...for a new folder
    """
    if out is not None:
        out = Path(out)
        if out.exists() and not out.is_dir():
            raise FileExistsError(f"{str(out)!r} exists and is not a folder")
        if out.is_dir() and any(out.iterdir()) and not force:
            raise FileExistsError(
                f"{str(out)!r} is not empty: pass --force to write into it, "
                "or leave --out out for a new folder"
            )
        return out
    stamp = datetime.now().strftime("%Y%m%d-%H%M%S")
    for k in range(1, 1000):
        path = root / (f"{command}-{stamp}" if k == 1 else f"{command}-{stamp}-{k}")
        if not path.exists():
            return path
    raise FileExistsError(f"no free run folder for {command}-{stamp} under {root}")
