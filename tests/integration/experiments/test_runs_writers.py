"""One writer of the run folder's records: read from the source with ``ast``, nothing outside
``experiments/runs/`` writes ``run.json``, ``metrics.json`` or the ``INCOMPLETE`` marker
(an ``open(..., "w")``, a ``write_text``, a ``json.dump``, a ``touch``, a ``write_json``
whose path names one of them, directly or through a variable of the same function).
"""

from __future__ import annotations

import ast

from locations import ROOT

PACKAGES = ("wander_env", "agents", "hardware", "experiments")
RECORDS = {"run.json", "metrics.json", "INCOMPLETE", "RUN_JSON", "METRICS_JSON"}
WRITES = {"write_text", "write_bytes", "touch", "dump", "write_json", "open", "replace"}


def _names(node: ast.AST) -> set[str]:
    """The string constants and the names in ``node``."""
    out = set()
    for n in ast.walk(node):
        if isinstance(n, ast.Constant) and isinstance(n.value, str):
            out.add(n.value)
        elif isinstance(n, ast.Name):
            out.add(n.id)
        elif isinstance(n, ast.Attribute):
            out.add(n.attr)
    return out


def _called(call: ast.Call) -> str | None:
    f = call.func
    return f.attr if isinstance(f, ast.Attribute) else f.id if isinstance(f, ast.Name) else None


def _writes_to_read_only(call: ast.Call) -> bool:
    """``open(path)`` / ``path.open()`` without a writing mode reads."""
    if _called(call) != "open":
        return False
    modes = [a.value for a in call.args if isinstance(a, ast.Constant) and isinstance(a.value, str)]
    modes += [
        k.value.value
        for k in call.keywords
        if k.arg == "mode" and isinstance(k.value, ast.Constant)
    ]
    return not any(set(m) & set("wax+") for m in modes)


def record_writers(source: str, where: str) -> list[str]:
    """``where:line`` of every write of a run record in ``source``."""
    found = []
    scopes = [n for n in ast.walk(ast.parse(source)) if isinstance(n, ast.FunctionDef)]
    for scope in scopes:
        tainted = set(RECORDS)
        for node in ast.walk(scope):
            if isinstance(node, ast.Assign) and _names(node.value) & tainted:
                tainted |= {
                    n.id for t in node.targets for n in ast.walk(t) if isinstance(n, ast.Name)
                }
            if isinstance(node, ast.withitem) and _names(node.context_expr) & tainted:
                if isinstance(node.optional_vars, ast.Name):
                    tainted.add(node.optional_vars.id)
        for node in ast.walk(scope):
            if not isinstance(node, ast.Call) or _called(node) not in WRITES:
                continue
            if _writes_to_read_only(node):
                continue
            if _names(node) & tainted:
                found.append(f"{where}:{node.lineno}")
    return sorted(set(found), key=lambda w: (w.rpartition(":")[0], int(w.rpartition(":")[2])))


def _sources() -> dict[str, str]:
    out = {}
    for top in PACKAGES:
        for path in sorted((ROOT / top).rglob("*.py")):
            if "__pycache__" not in path.parts:
                out[str(path.relative_to(ROOT))] = path.read_text(encoding="utf-8")
    return out


def test_the_finder_sees_a_hand_made_writer():
    # Guards the rule below: each of the old writers' shapes is found.
    code = (
        "def a(out):\n    write_json(out / 'run.json', {})\n"
        "def b(out):\n    path = out / 'metrics.json'\n    path.write_text('{}')\n"
        "def c(out):\n    (out / 'INCOMPLETE').touch()\n"
        "def d(out):\n    with open(out / 'run.json', 'w') as f:\n        json.dump({}, f)\n"
        "def e(out):\n    return json.loads((out / 'run.json').read_text())\n"
        "def f(out):\n    with open(out / 'run.json') as f:\n        return f.read()\n"
    )
    assert record_writers(code, "x.py") == ["x.py:2", "x.py:5", "x.py:7", "x.py:9", "x.py:10"]


def test_only_the_run_folder_writes_run_records():
    sources = _sources()
    outside = [
        w
        for path, text in sources.items()
        if not path.startswith("experiments/runs/")
        for w in record_writers(text, path)
    ]
    assert outside == []
    inside = [
        w
        for p, t in sources.items()
        if p.startswith("experiments/runs/")
        for w in record_writers(t, p)
    ]
    assert any(w.startswith("experiments/runs/folder.py:") for w in inside)
