"""The CLI in a child process under an address-space limit, with its resident peak.

For the tests that feed ``wander`` a bomb (a billion laughs, a PNG or zip bomb, nested
``<replicate>``): the process must end with one line within the limit, and its own
resident peak (VmHWM, printed at exit) tells how much it held.
"""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

from locations import ROOT, SUPPORT

GIB = 1 << 30

# The CLI under an address-space limit, printing its own resident peak (VmHWM) at exit.
LIMITED = textwrap.dedent(
    """
    import resource, sys
    limit = int(sys.argv[1])
    resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
    sys.argv = ["wander", *sys.argv[2:]]
    from experiments.cli.main import main
    try:
        main()
    finally:
        # This process's own resident peak (VmHWM): ru_maxrss would also count the pytest
        # process it was forked from, which Linux carries across exec.
        with open("/proc/self/status") as f:
            peak_kib = next(int(w.split()[1]) for w in f if w.startswith("VmHWM:"))
        print(f"peak {peak_kib}", file=sys.stdout, flush=True)
    """
)


def run_limited(
    args: list[str], cwd: Path, limit: int = 2 * GIB, timeout_s: float = 120.0
) -> tuple[int, list[str], int]:
    """(exit status, stderr lines, resident peak in bytes, -1 if it printed none) of
    ``wander ARGS`` in ``cwd`` under an address-space limit of ``limit`` bytes; a hang
    fails the test (``timeout_s``)."""
    path = os.pathsep.join([str(ROOT), str(SUPPORT)])
    env = {**os.environ, "PYTHONPATH": path, "MUJOCO_GL": "egl"}
    proc = subprocess.run(
        [sys.executable, "-c", LIMITED, str(limit), *args],
        capture_output=True,
        text=True,
        timeout=timeout_s,
        cwd=cwd,
        env=env,
    )
    peaks = [int(w.split()[1]) for w in proc.stdout.splitlines() if w.startswith("peak ")]
    return proc.returncode, proc.stderr.splitlines(), peaks[0] * 1024 if peaks else -1
