"""torch's CPU threads across ``fork``: one thread in a forked child, or a clear error.

torch's CPU kernels (oneDNN convolutions, ATen's ``parallel_for``) run on GNU OpenMP
(libgomp), whose thread team does not survive ``fork``: once the parent has run a
parallel region, a child's next parallel region waits forever for threads that were not
copied (``py-spy dump --native`` of such a child: ``GOMP_parallel`` under
``dnnl::...::execute``). A region run on one thread needs no team, so the child is safe
with ``torch.set_num_threads(1)``.

Importing this module registers an ``os.register_at_fork`` hook that sets one thread in
every forked child, and :func:`set_torch_threads` (what the agent calls) refuses more
than one there, naming the fix. Processes started with ``"spawn"`` are fresh: any number.

Examples:
    >>> set_torch_threads(1)
    >>> torch.get_num_threads()
    1
"""

from __future__ import annotations

import os

import torch

# The parent's pid in a process forked after this module was imported; None otherwise.
_FORKED_FROM: dict[str, int | None] = {"pid": None}


def _one_thread_in_child() -> None:
    _FORKED_FROM["pid"] = os.getppid()
    torch.set_num_threads(1)


os.register_at_fork(after_in_child=_one_thread_in_child)


def set_torch_threads(n: int) -> None:
    """``torch.set_num_threads(n)``; in a forked child only ``n = 1`` (see the module doc)."""
    if isinstance(n, bool) or not isinstance(n, int) or n < 1:
        raise ValueError(f"torch threads must be an int >= 1, got {n!r}")
    parent = _FORKED_FROM["pid"]
    if n > 1 and parent is not None:
        raise RuntimeError(
            f"this process was forked from process {parent}: torch's OpenMP threads do not "
            f"survive fork, and {n} threads would hang in the first convolution. Use one "
            "thread (AgentParams(torch_threads=1), the default) or start the process with "
            "the 'spawn' method (multiprocessing.get_context('spawn'), "
            "AsyncVectorEnv(..., context='spawn'))"
        )
    torch.set_num_threads(n)


__all__ = ["set_torch_threads"]
