"""The house rules, read from the source with ``ast``: imports run only downward
(``experiments`` → ``agents`` / ``hardware`` → ``wander_env``), library code never
imports the CLI (``experiments.cli``), and no import circle exists between modules or
between packages (``experiments``' wings and root modules counted one by one).

Every import counts, also one inside a function or under ``TYPE_CHECKING``: a lazy import
still ties the two modules together.
"""

from __future__ import annotations

import ast
import graphlib
import json
import subprocess
import sys
from pathlib import Path

import pytest
from locations import ROOT

PACKAGES = ("wander_env", "agents", "hardware", "experiments")
WINGS = ("cli", "jobs", "perf", "benchmark", "paper", "runs", "studies", "analysis")


def _module_name(path: Path) -> str:
    parts = path.relative_to(ROOT).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _sources() -> dict[str, Path]:
    found = {}
    for top in PACKAGES:
        for path in sorted((ROOT / top).rglob("*.py")):
            if "__pycache__" not in path.parts:
                found[_module_name(path)] = path
    return found


SOURCES = _sources()


def _resolve(name: str) -> str | None:
    """The longest of our own modules that ``name`` (a dotted import) names or lies in."""
    parts = name.split(".")
    for n in range(len(parts), 0, -1):
        cand = ".".join(parts[:n])
        if cand in SOURCES:
            return cand
    return None


def imports_of(module: str) -> list[tuple[str, int]]:
    """Our own modules that ``module`` imports, with the line of each import."""
    path = SOURCES[module]
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    found = []
    for node in ast.walk(tree):
        names: list[str] = []
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join([*anchor, base] if base else anchor)
            # ``from pkg import mod`` imports the module pkg.mod; ``from mod import f`` mod.
            names = [
                f"{base}.{a.name}" if f"{base}.{a.name}" in SOURCES else base for a in node.names
            ]
        for name in names:
            target = _resolve(name)
            if target is not None and target != module:
                found.append((target, node.lineno))
    return found


GRAPH = {m: imports_of(m) for m in SOURCES}


def _top(module: str) -> str:
    return module.split(".")[0]


def _unit(module: str) -> str:
    """A package for the package-level graph: a top-level package, or one of
    ``experiments``' wings, or one root module of ``experiments``."""
    parts = module.split(".")
    if parts[0] != "experiments" or len(parts) == 1:
        return parts[0]
    return ".".join(parts[:2])


def _where(module: str, line: int) -> str:
    return f"{SOURCES[module].relative_to(ROOT)}:{line}"


def test_the_parser_sees_the_imports_it_must_see():
    # Guards the rules below: a parser that found nothing would pass every one of them.
    assert len(SOURCES) > 90
    main = {t for t, _ in GRAPH["experiments.cli.main"]}
    groups = ("run", "evaluate", "perf", "benchmark", "experiment", "rig", "errors")
    assert {f"experiments.cli.{g}" for g in groups} <= main
    assert "experiments.jobs.run_agent" in {t for t, _ in GRAPH["experiments.cli.run"]}
    assert "wander_env.camera" in {t for t, _ in GRAPH["agents.attention"]}
    # ``from experiments.analysis import scanpath_stats`` names the module, not the package.
    assert "experiments.analysis.scanpath_stats" in {
        t for t, _ in GRAPH["experiments.paper.scanpath"]
    }
    # A lazy import inside a function counts (events.stream's index_offset_us), and so does
    # ``from package import module`` (events.io's ``from wander_env.events import formats``).
    assert "wander_env.events.hdf5_index" in {t for t, _ in GRAPH["wander_env.events.stream"]}
    assert "wander_env.events.formats" in {t for t, _ in GRAPH["wander_env.events.io"]}
    rel = imports_of("experiments.benchmark.datasets")
    assert {"experiments.benchmark.datasets.base", "experiments.benchmark.datasets.evimo"} <= {
        t for t, _ in rel
    }


@pytest.mark.parametrize(
    ("lower", "higher"),
    [
        ("wander_env", "experiments"),
        ("agents", "experiments"),
        ("hardware", "experiments"),
        ("wander_env", "agents"),
        ("wander_env", "hardware"),
    ],
)
def test_imports_run_only_downward(lower, higher):
    upward = [
        f"{_where(m, line)} imports {t}"
        for m, edges in GRAPH.items()
        if _top(m) == lower
        for t, line in edges
        if _top(t) == higher
    ]
    assert upward == []


def test_library_code_never_imports_the_cli():
    found = [
        f"{_where(m, line)} imports {t}"
        for m, edges in GRAPH.items()
        if not m.startswith("experiments.cli")
        for t, line in edges
        if t.startswith("experiments.cli")
    ]
    assert found == []


def _third_party_of(module: str) -> set[str]:
    tree = ast.parse(SOURCES[module].read_text(encoding="utf-8"))
    names = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names |= {a.name.split(".")[0] for a in node.names}
        elif isinstance(node, ast.ImportFrom) and not node.level and node.module:
            names.add(node.module.split(".")[0])
    return names


def _top_level_third_party(module: str) -> set[str]:
    """The libraries ``module`` imports when it is imported: its top-level statements,
    not a function's body nor an ``if TYPE_CHECKING:`` block."""
    names = set()
    for node in ast.parse(SOURCES[module].read_text(encoding="utf-8")).body:
        if isinstance(node, ast.Import):
            names |= {a.name.split(".")[0] for a in node.names}
        elif isinstance(node, ast.ImportFrom) and not node.level and node.module:
            names.add(node.module.split(".")[0])
    return names


def test_only_the_cli_imports_the_command_line_libraries():
    found = sorted(
        f"{m} imports {lib}"
        for m in SOURCES
        if not m.startswith("experiments.cli")
        for lib in _third_party_of(m) & {"typer", "rich", "click"}
    )
    assert found == []
    assert "typer" in _third_party_of("experiments.cli.errors")


def test_the_cli_lives_in_one_package():
    elsewhere = [
        m for m in SOURCES if "cli" in m.rpartition(".")[2] and not m.startswith("experiments.cli")
    ]
    assert elsewhere == []
    assert {f"experiments.cli.{n}" for n in ("main", "console", "options", "errors")} <= set(
        SOURCES
    )


def test_experiments_is_in_wings():
    wings = {f"experiments.{w}" for w in WINGS}
    assert wings <= set(SOURCES), "a wing's __init__.py is missing"
    root = sorted(m for m in SOURCES if m.count(".") == 1 and m.startswith("experiments."))
    assert [m for m in root if m not in wings] == []


def _cycle(graph: dict[str, set[str]]) -> list[str]:
    try:
        tuple(graphlib.TopologicalSorter(graph).static_order())
    except graphlib.CycleError as err:
        return list(err.args[1])
    return []


def test_no_import_circle_between_modules():
    assert _cycle({m: {t for t, _ in edges} for m, edges in GRAPH.items()}) == []


def test_no_import_circle_between_packages():
    units: dict[str, set[str]] = {}
    for m, edges in GRAPH.items():
        units.setdefault(_unit(m), set()).update(_unit(t) for t, _ in edges if _unit(t) != _unit(m))
    # The top-level ``experiments`` package itself (its __init__) holds nothing.
    assert _cycle(units) == []
    assert {"experiments.cli", "experiments.paper", "agents", "wander_env"} <= set(units)


def test_the_cycle_finder_finds_a_circle():
    assert sorted(set(_cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}))) == ["a", "b", "c"]
    assert _cycle({"a": {"b"}, "b": set()}) == []


def test_the_frame_sources_sit_between_the_renderer_and_the_env():
    """wander_env.frames (the stage and the frame sources) draws through the renderer and
    reads the PTU's trajectory; the env picks a source from the registry and never the
    other way round; the rig shares only the CameraEnv base with the sim."""
    frames = {m: {t for t, _ in GRAPH[m]} for m in GRAPH if m.startswith("wander_env.frames.")}
    assert "wander_env.renderer" in frames["wander_env.frames.stage"]
    assert "wander_env.ptu.unit" in frames["wander_env.frames.source"]
    assert "wander_env.frames.keyframe_maths" in frames["wander_env.frames.keyframes"]
    assert "wander_env.frames.keyframes" in frames["wander_env.frames.panorama"]  # has one
    for targets in frames.values():
        assert "wander_env.env" not in targets and "wander_env.env_base" not in targets
    # The registry is light: no source, renderer or kernel at import.
    assert frames["wander_env.frames.registry"] <= {
        "wander_env.frames.source",
        "wander_env.frames.stage",
        "wander_env.dvs",
    }
    env = {t for t, _ in GRAPH["wander_env.env"]}
    assert {"wander_env.frames.registry", "wander_env.frames.stage"} <= env
    rig = {t for t, _ in GRAPH["hardware.rig_env"]}
    assert "wander_env.env_base" in rig and "wander_env.env" not in rig
    assert {t for t, _ in GRAPH["wander_env.env_base"]} <= {
        "wander_env.actions",
        "wander_env.events.packet",
        "wander_env.events",
    }


def test_the_simulator_names_no_floor_above_it_even_as_a_string():
    """Registering the rig env is hardware's own business: no module of wander_env names
    ``hardware``, ``agents`` or ``experiments`` in an entry point string."""
    named = [
        f"{m}: {floor}"
        for m, path in SOURCES.items()
        if _top(m) == "wander_env"
        for floor in ("hardware.", "agents.", "experiments.")
        if f'"{floor}' in path.read_text(encoding="utf-8")
    ]
    assert named == []


#: The only modules of ``wander_env`` outside ``wander_env.events`` that the event library
#: may import: small helpers that import nothing of ours but each other (checked below) and
#: no simulator (the untrusted-file reader: event metadata is untrusted JSON).
EVENTS_MAY_IMPORT = (
    "wander_env.strict_json",
    "wander_env.closing",
    "wander_env.file_error",
    "wander_env.untrusted",
)


def test_the_event_library_stands_on_its_own():
    """``wander_env.events`` (arrays, packets, files, checks, streaming) imports no module of
    wander_env outside itself but the named dependency-free helpers, and nothing heavier
    than the format libraries: a user who only reads and writes event files gets no
    simulator."""
    events = sorted(
        m for m in SOURCES if m == "wander_env.events" or m.startswith("wander_env.events.")
    )
    assert events == [
        "wander_env.events",
        "wander_env.events.checks",
        "wander_env.events.evimo2",
        "wander_env.events.formats",
        "wander_env.events.hdf5_index",
        "wander_env.events.io",
        "wander_env.events.packet",
        "wander_env.events.stream",
    ]
    outside = [
        f"{_where(m, line)} imports {t}"
        for m in events
        for t, line in GRAPH[m]
        if not (t == "wander_env.events" or t.startswith("wander_env.events."))
        and t not in EVENTS_MAY_IMPORT
    ]
    assert outside == []
    # The helpers are what the allowlist says they are: they import nothing of ours but
    # each other (the untrusted reader raises the one FileError).
    beyond = {m: [t for t, _ in GRAPH[m] if t not in EVENTS_MAY_IMPORT] for m in EVENTS_MAY_IMPORT}
    assert beyond == {m: [] for m in EVENTS_MAY_IMPORT}
    assert [t for t, _ in GRAPH["wander_env.untrusted"]] == ["wander_env.file_error"]
    heavy = {"mujoco", "torch", "gymnasium", "sinabs", "nengo", "numba", "cv2", "OpenGL"}
    found = sorted(f"{m} imports {lib}" for m in events for lib in _third_party_of(m) & heavy)
    # the helpers may reach one inside a function they do not call for events (the
    # untrusted reader's MJCF checks import MuJoCo there): none at their top level
    found += sorted(
        f"{m} imports {lib} at its top level"
        for m in EVENTS_MAY_IMPORT
        for lib in _top_level_third_party(m) & heavy
    )
    assert found == []


def test_reading_and_writing_events_loads_no_simulator():
    """Importing the readers, writers and the streaming writer in a fresh interpreter loads
    exactly these modules of ours, and none of MuJoCo, torch, Gymnasium's MuJoCo envs,
    numba, sinabs, nengo or OpenCV. (``wander_env/__init__.py`` runs first: it sets
    ``MUJOCO_GL`` and registers the sim env with Gymnasium by its entry-point string, which
    imports Gymnasium's registry but not the env module.)"""
    code = (
        "import sys, json\n"
        "import wander_env.events.io, wander_env.events.formats, wander_env.events.stream\n"
        "print(json.dumps(sorted(sys.modules)))\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, check=True
    ).stdout
    loaded = set(json.loads(out))
    ours = sorted(m for m in loaded if _top(m) in PACKAGES)
    assert ours == [
        "wander_env",
        "wander_env.closing",
        "wander_env.events",
        "wander_env.events.checks",
        "wander_env.events.formats",
        "wander_env.events.hdf5_index",
        "wander_env.events.io",
        "wander_env.events.stream",
        "wander_env.file_error",
        "wander_env.strict_json",
        "wander_env.untrusted",
    ]
    heavy = ("mujoco", "torch", "gymnasium.envs.mujoco", "numba", "sinabs", "nengo", "cv2")
    assert sorted(m for m in loaded if any(m == h or m.startswith(f"{h}.") for h in heavy)) == []


def test_wander_env_holds_no_lab_code():
    """Every module of wander_env serves the simulator: wander_env itself, the agents or the
    hardware import it. What only experiments use (the metrics, the Rerun recording, the
    demo's stimulus) lives in experiments. Exempt: the env (Gymnasium reaches it by its
    entry-point string), the frame sources (the frame registry names them by string), the
    event library, whose users are anyone with event files, and a subpackage's
    ``__init__`` (its modules are what is imported)."""
    from wander_env.frames.registry import REGISTRY

    by_name = {f"wander_env.frames.{m.source.partition(':')[0]}" for m in REGISTRY.values()}
    lab_only = sorted(
        m
        for m in SOURCES
        if _top(m) == "wander_env"
        and m not in ("wander_env", "wander_env.env", *by_name)
        and not (
            SOURCES[m].name == "__init__.py" and m.count(".") == 1 and m != "wander_env.events"
        )
        and not (m == "wander_env.events" or m.startswith("wander_env.events."))
        and not any(
            _top(user) in ("wander_env", "agents", "hardware") and m in {t for t, _ in edges}
            for user, edges in GRAPH.items()
        )
    )
    assert lab_only == []


def _private(name: str) -> bool:
    return name.startswith("_") and not (name.startswith("__") and name.endswith("__"))


def _own_names(cls: ast.ClassDef) -> set[str]:
    """The names a class defines: its body's functions and assignments, and every
    ``self.<name>`` (or ``cls.<name>``) its methods assign."""
    names = set()
    for node in ast.walk(cls):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            names.add(node.name)
        elif isinstance(node, ast.Name) and isinstance(node.ctx, ast.Store):
            names.add(node.id)
        elif (
            isinstance(node, ast.Attribute)
            and isinstance(node.ctx, ast.Store)
            and isinstance(node.value, ast.Name)
            and node.value.id in ("self", "cls")
        ):
            names.add(node.attr)
    return names


def private_reaches(module: str) -> list[str]:
    """Where ``module`` reads another's private name: ``x._name`` where ``x`` is not
    ``self``/``cls`` and ``_name`` is not one the enclosing class defines itself (its
    own instances' state: a copy method sets its twin's), and ``from m import _name``
    from another of our modules (dunders are public)."""
    path = SOURCES[module]
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    found = []

    def visit(node: ast.AST, own: set[str]) -> None:
        if isinstance(node, ast.ClassDef):
            own = own | _own_names(node)
        if isinstance(node, ast.Attribute) and _private(node.attr):
            mine = isinstance(node.value, ast.Name) and node.value.id in ("self", "cls")
            if not mine and node.attr not in own:
                found.append(f"{module}:{node.lineno} {ast.unparse(node)}")
        if isinstance(node, ast.ImportFrom) and node.module and _resolve(node.module):
            if _resolve(node.module) != module:
                for alias in node.names:
                    if _private(alias.name):
                        found.append(
                            f"{module}:{node.lineno} from {node.module} import {alias.name}"
                        )
        for child in ast.iter_child_nodes(node):
            visit(child, own)

    visit(tree, set())
    return found


def test_no_simulator_module_reaches_into_another_ones_private_names():
    """Across wander_env a module uses another's public seams, never its ``_private``
    names (attributes of other objects, or imports)."""
    reaches = [r for m in SOURCES if m.split(".")[0] == "wander_env" for r in private_reaches(m)]
    assert reaches == []


def test_the_private_name_check_finds_a_reach(tmp_path, monkeypatch):
    code = (
        "from wander_env.dvs import _LUT\n"
        "class A:\n"
        "    def __init__(self):\n"
        "        self._x = 1\n"
        "    def copy(self, other):\n"
        "        other._x = self._x\n"
        "        return other._y, other.__class__\n"
        "def f(dvs):\n"
        "    return dvs._wlut\n"
    )
    path = tmp_path / "probe.py"
    path.write_text(code)
    monkeypatch.setitem(SOURCES, "probe", path)
    assert private_reaches("probe") == [
        "probe:1 from wander_env.dvs import _LUT",
        "probe:7 other._y",
        "probe:9 dvs._wlut",
    ]
