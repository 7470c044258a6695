"""The house uses only the public names of the packages it depends on, read from the
source with ``ast``: no import of a private module or name of a third-party package
(``from typer import _click``, ``import typer._click.globals``, ``from x import _y``) and
no reach through a third-party module for a private attribute (``typer._click``). A
private name is one that starts with ``_`` and is not a dunder (``__version__``); the
standard library (``os._exit`` is documented) and our own packages are not third-party.
"""

from __future__ import annotations

import ast
import sys
from pathlib import Path

from locations import ROOT

PACKAGES = ("wander_env", "agents", "hardware", "experiments")


def _private(part: str) -> bool:
    return part.startswith("_") and not (part.startswith("__") and part.endswith("__"))


def _third_party(module: str) -> bool:
    top = module.split(".")[0]
    return top not in PACKAGES and top not in sys.stdlib_module_names and top != "__future__"


def private_uses(source: str) -> list[tuple[int, str]]:
    """Each private name of a third-party package ``source`` imports or reaches, with its
    line: ``(line, "typer._click")``.

    >>> private_uses("import typer\\nfrom typer import _click\\nx = typer._click")
    [(2, 'typer._click'), (3, 'typer._click')]
    """
    tree = ast.parse(source)
    found, modules = [], {}
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                if _third_party(alias.name):
                    modules[alias.asname or alias.name.split(".")[0]] = alias.name
                    if any(_private(p) for p in alias.name.split(".")):
                        found.append((node.lineno, alias.name))
        elif isinstance(node, ast.ImportFrom) and not node.level and node.module:
            if _third_party(node.module):
                if any(_private(p) for p in node.module.split(".")):
                    found.append((node.lineno, node.module))
                found += [
                    (node.lineno, f"{node.module}.{a.name}") for a in node.names if _private(a.name)
                ]
    for node in ast.walk(tree):
        if (
            isinstance(node, ast.Attribute)
            and isinstance(node.value, ast.Name)
            and node.value.id in modules
            and _private(node.attr)
        ):
            found.append((node.lineno, f"{modules[node.value.id]}.{node.attr}"))
    return sorted(found)


def _sources() -> list[Path]:
    return [
        path
        for top in PACKAGES
        for path in sorted((ROOT / top).rglob("*.py"))
        if "__pycache__" not in path.parts
    ]


def test_the_check_finds_each_kind_of_private_use():
    source = (
        "import typer._click.globals\n"
        "from typer._click.globals import get_current_context\n"
        "from typer import _click, Context\n"
        "import numpy as np\n"
        "y = np._core\n"
        "import os\n"
        "os._exit(0)\n"
        "from __future__ import annotations\n"
        "from .x import _own\n"
        "from experiments.cli import _own\n"
        "z = typer.__version__\n"
    )
    assert private_uses(source) == [
        (1, "typer._click.globals"),
        (2, "typer._click.globals"),
        (3, "typer._click"),
        (5, "numpy._core"),
    ]


def test_no_module_uses_a_private_name_of_a_third_party_package():
    found = {
        str(path.relative_to(ROOT)): uses
        for path in _sources()
        if (uses := private_uses(path.read_text(encoding="utf-8")))
    }
    assert found == {}
