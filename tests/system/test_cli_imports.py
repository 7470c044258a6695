"""``wander --help``, ``wander report --help`` and ``wander view --help`` start fast: the
command line loads none of the heavy libraries (the simulator's, the agent's, the
plotting and storage ones). Each is asserted on the modules a fresh interpreter holds
after the import or the help, never on a clock.
"""

from __future__ import annotations

import json
import subprocess
import sys

import pytest
from locations import ROOT

HEAVY = ("torch", "mujoco", "nengo", "numba", "sinabs", "cv2", "ray", "h5py", "matplotlib")

# The help of the commands named (none: only the import), then the modules loaded, as JSON
# on the last line of stdout.
SCRIPT = """
import json, sys
import experiments.cli.main
args = sys.argv[1:]
if args:
    try:
        experiments.cli.main.app([*args, "--help"], prog_name="wander")
    except SystemExit as stop:
        assert stop.code == 0, stop.code
print()
print(json.dumps(sorted(sys.modules)))
"""


def modules_loaded(*command: str) -> set[str]:
    """The top-level packages a fresh interpreter holds after importing the CLI and
    printing the help of ``command`` (nothing more for no command)."""
    proc = subprocess.run(
        [sys.executable, "-c", SCRIPT, *command],
        capture_output=True,
        text=True,
        cwd=ROOT,
        check=True,
    )
    return {name.split(".")[0] for name in json.loads(proc.stdout.splitlines()[-1])}


@pytest.mark.parametrize("command", [(), ("report",), ("view",)], ids=["import", "report", "view"])
def test_the_command_line_and_its_help_load_no_heavy_library(command):
    loaded = modules_loaded(*command)
    assert "experiments" in loaded and "typer" in loaded  # the CLI did load
    assert sorted(loaded.intersection(HEAVY)) == []
