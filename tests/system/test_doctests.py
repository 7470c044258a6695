"""Every docstring example in the packages runs and gives what it shows."""

from __future__ import annotations

import doctest
import importlib
import pkgutil
from pathlib import Path

import pytest

import wander_env  # noqa: F401  (headless rendering before anything imports MuJoCo)

PACKAGES = ("wander_env", "agents", "hardware", "experiments")


def _modules() -> list[str]:
    names = []
    for pkg in PACKAGES:
        names.append(pkg)
        path = importlib.import_module(pkg).__path__
        names += [m.name for m in pkgutil.walk_packages(path, f"{pkg}.")]
    return names


@pytest.mark.parametrize("name", _modules())
def test_docstring_examples(name: str) -> None:
    module = importlib.import_module(name)
    result = doctest.testmod(module, optionflags=doctest.ELLIPSIS)
    assert result.failed == 0, f"{result.failed} of {result.attempted} examples failed in {name}"
    # a module whose source shows examples has them collected (none lost in a docstring
    # doctest does not read); a skipped one counts as collected, not as attempted
    source = Path(module.__file__).read_text().splitlines()
    shows = any(line.lstrip().startswith(">>> ") for line in source)
    found = sum(len(t.examples) for t in doctest.DocTestFinder().find(module))
    assert found > 0 or not shows, f"{name} shows examples but none was collected"
