"""Test session setup, for every tier (``unit/``, ``integration/``, ``system/``).

Headless EGL rendering before any module imports MuJoCo: MuJoCo picks its OpenGL backend
when ``mujoco`` is first imported; a test module that imports ``mujoco`` before
``wander_env`` would otherwise get GLFW, which needs a display.

``tests/support/`` goes on ``sys.path``: the helpers (``fake_samna``, ``scene_files``,
``sweep_workers``, ``vector_drive``, ``locations``, ``fake_clock``, ``polling``,
``limited``) are imported by name from any tier.
So does every folder of test modules: tests import fixtures and builders from other test
modules by name (``from test_sweep import TOY_SWEEP``) wherever they sit; pytest imports a
test module under its file name, so file names are unique across the tiers.

The tiers: the default run (``pytest``, ``testpaths`` in ``pyproject.toml``) is
``unit/`` and ``integration/`` without the ``slow`` tests; ``pytest tests -m ""`` runs
every tier and every test (``.ci/run``). Each test gets its tier's marker (``unit``,
``integration``, ``system``) from its folder, so ``-m system`` selects a tier too.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import pytest

os.environ.setdefault("MUJOCO_GL", "egl")
# A native crash prints every thread's Python stack (pytest's faulthandler) and nothing
# else. Ray's own crash handler, installed when Ray starts, would run first: it writes to
# the stderr pytest captures (lost with the process) before handing the signal on, and a
# crash in the system tier after Ray had started printed no stack at all.
os.environ.setdefault("RAY_DISABLE_FAILURE_SIGNAL_HANDLER", "1")

TESTS = Path(__file__).resolve().parent
SUPPORT = TESTS / "support"
for folder in [SUPPORT, *sorted({p.parent for p in TESTS.glob("*/**/test_*.py")})]:
    if str(folder) not in sys.path:
        sys.path.insert(0, str(folder))

TIERS = ("unit", "integration", "system")


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Mark each test with the tier of its folder."""
    for item in items:
        parts = item.path.resolve().relative_to(TESTS).parts
        if parts and parts[0] in TIERS:
            item.add_marker(parts[0])


@pytest.fixture(scope="session")
def _ray_session():
    """Ray imported once a session; whatever instance is running at the session's end is
    shut down."""
    ray = pytest.importorskip("ray")
    yield ray
    if ray.is_initialized():
        ray.shutdown()


@pytest.fixture
def ray_instance(_ray_session):
    """One local Ray instance shared by the session's tests (2 CPUs, the repository on the
    workers' ``PYTHONPATH``): started by the first test that asks for it, and again after a
    test that needs a Ray of its own shut it down; the sweep's Ray backend reuses an
    initialised Ray instead of starting its own."""
    ray = _ray_session
    if not ray.is_initialized():
        root = str(TESTS.parent)
        path = os.pathsep.join(p for p in (root, os.environ.get("PYTHONPATH")) if p)
        ray.init(
            num_cpus=2,
            include_dashboard=False,
            log_to_driver=False,
            runtime_env={"env_vars": {"PYTHONPATH": path}},
        )
    return ray
