"""One step loop over an env in ``experiments/``: :func:`experiments.runs.episode.run_episode`.

Read from the source with ``ast``: a ``for`` or ``while`` whose body calls ``.step(`` on
an env (the receiver's source names an ``env``: ``env.step``, ``self.env.step``,
``lp["env"].step``) is a step loop. Every one outside ``run_episode`` must be listed in
:data:`EXCEPTIONS` with the reason it is not an episode under a policy with recorders;
a listed one that is gone fails too, so the list stays true.
"""

from __future__ import annotations

import ast

from locations import ROOT

#: (file, enclosing function) -> why its loop is not run_episode's.
EXCEPTIONS: dict[tuple[str, str], str] = {
    ("experiments/perf/agent.py", "bench_agent"): "a speed benchmark: times agent.act and "
    "env.step apart, each step; a recorder's hook would sit inside the timing",
    ("experiments/perf/agent.py", "loop_modes"): "a speed benchmark: several env + agent "
    "loops stepped in turns, one step each per round, to time them side by side",
    ("experiments/perf/env.py", "bench_env"): "a speed benchmark: several envs stepped in "
    "a rotated order, one step each, each env.step timed alone",
    ("experiments/perf/env.py", "step_breakdown"): "a speed benchmark: times the bare "
    "env.step of a still camera with the stage's parts instrumented",
    ("experiments/perf/fidelity.py", "run_row"): "steps the modes' envs and the reference "
    "in lockstep on the reference's actions: several envs, one policy",
    ("experiments/perf/floor.py", "render_floor"): "warm-up steps before timing GL calls; "
    "no episode is run",
    ("experiments/perf/panorama.py", "step_ms"): "a speed benchmark: frame-source variants "
    "stepped in turns, each env.step timed alone",
}
THE_LOOP = ("experiments/runs/episode.py", "run_episode")


def _names_env_step(node: ast.AST) -> bool:
    """Whether ``node`` is an ``env.step`` attribute (the receiver's source names an env)."""
    return (
        isinstance(node, ast.Attribute)
        and node.attr == "step"
        and "env" in ast.unparse(node.value).lower()
    )


def _step_aliases(fn: ast.AST) -> set[str]:
    """Names a function binds to something made of ``env.step`` (``step = timed(env.step,
    ...)``): calling them steps the env too."""
    return {
        target.id
        for node in ast.walk(fn)
        if isinstance(node, ast.Assign) and any(_names_env_step(n) for n in ast.walk(node.value))
        for t in node.targets
        for target in ast.walk(t)
        if isinstance(target, ast.Name)
    }


def _is_env_step(node: ast.AST, aliases: set[str] = frozenset()) -> bool:
    if not isinstance(node, ast.Call):
        return False
    return _names_env_step(node.func) or (
        isinstance(node.func, ast.Name) and node.func.id in aliases
    )


def _loops_in(fn: ast.AST) -> bool:
    aliases = _step_aliases(fn)
    return any(
        isinstance(loop, (ast.For, ast.While))
        and any(_is_env_step(n, aliases) for stmt in loop.body for n in ast.walk(stmt))
        for loop in ast.walk(fn)
    )


def step_loops() -> set[tuple[str, str]]:
    """(file, enclosing function) of every loop over ``env.step`` (or a name bound to it)
    in ``experiments/``."""
    found: set[tuple[str, str]] = set()
    for path in sorted((ROOT / "experiments").rglob("*.py")):
        tree = ast.parse(path.read_text(), str(path))
        rel = path.relative_to(ROOT).as_posix()
        for fn in ast.walk(tree):
            if isinstance(fn, (ast.FunctionDef, ast.AsyncFunctionDef)) and _loops_in(fn):
                found.add((rel, fn.name))
    return found


def test_one_step_loop_over_an_env_in_experiments() -> None:
    loops = step_loops()
    assert THE_LOOP in loops
    assert loops - {THE_LOOP} - set(EXCEPTIONS) == set(), "step the env with run_episode"
    assert set(EXCEPTIONS) - loops == set(), "an exception whose loop is gone"
    assert all(len(why) > 20 for why in EXCEPTIONS.values())


def test_the_finder_sees_env_loops_and_not_other_steps() -> None:
    source = """
def a(env):
    for _ in range(3):
        obs, _, _, _, info = env.step(0)
def b(self):
    while True:
        self.env.step(0)
def c(dvs, lp):
    for f in range(3):
        dvs.step(f)
    lp["env"].step(0)
def d(env, timed):
    env_step = timed(env.step)
    for _ in range(3):
        env_step(0)
def e(dvs, timed):
    step = timed(dvs.step)
    for _ in range(3):
        step(0)
"""
    tree = ast.parse(source)
    hits = [fn.name for fn in tree.body if isinstance(fn, ast.FunctionDef) and _loops_in(fn)]
    assert hits == ["a", "b", "d"]
