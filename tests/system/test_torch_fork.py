"""torch in a forked child: one thread (no libgomp hang), or an error naming the fix."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest
import torch
from locations import ROOT

from agents import torch_fork
from agents.torch_fork import set_torch_threads

# The parent runs a 2-thread convolution, then forks; the child convolves again. Without
# agents.torch_fork the child waits forever in GOMP_parallel (measured: py-spy).
CHILD = """
import os, sys, time, torch
import agents.torch_fork
torch.set_num_threads(2)
x, w = torch.randn(1, 4, 256, 256), torch.randn(8, 4, 9, 9)
torch.nn.functional.conv2d(x, w)
pid = os.fork()
if pid == 0:
    torch.nn.functional.conv2d(x, w)
    os._exit(10 + torch.get_num_threads())
deadline = time.monotonic() + 120
while time.monotonic() < deadline:
    done, status = os.waitpid(pid, os.WNOHANG)
    if done:
        print(os.waitstatus_to_exitcode(status), torch.get_num_threads())
        sys.exit(0)
    time.sleep(0.05)
os.kill(pid, 9)
print("hung")
"""


@pytest.mark.slow
def test_a_forked_child_convolves_on_one_thread_and_the_parent_keeps_two():
    path = os.pathsep.join(p for p in (str(ROOT), os.environ.get("PYTHONPATH")) if p)
    proc = subprocess.run(
        [sys.executable, "-c", CHILD],
        cwd=ROOT,
        env={**os.environ, "PYTHONPATH": path},
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert proc.stdout.split() == ["11", "2"]  # child: exit 10 + 1 thread; parent: 2


def test_more_than_one_thread_in_a_forked_child_is_refused(monkeypatch):
    before = torch.get_num_threads()
    monkeypatch.setitem(torch_fork._FORKED_FROM, "pid", 4242)  # as in a forked child
    with pytest.raises(RuntimeError, match=r"forked from process 4242.*'spawn'"):
        set_torch_threads(2)
    assert torch.get_num_threads() == before
    set_torch_threads(1)
    assert torch.get_num_threads() == 1
    torch.set_num_threads(before)
    with pytest.raises(ValueError, match="int >= 1, got 0"):
        set_torch_threads(0)
