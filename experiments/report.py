"""``wander report``: REPORT.md from the latest result folders, the paper's numbers beside ours.

For every registered experiment the newest folder ``results/NAME/*`` holding a
``results.csv`` and a ``run.json`` is read (newest by the ``created`` time in ``run.json``,
then by folder name); its figures are drawn again into ``<report dir>/report_figures/NAME``
and a section gives the command, seed, git revision and run time that produced it and the
experiment's comparison table (``Experiment.compare``). Sweeps found under
``results/sweeps/*`` are listed with their tables.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

from experiments.framework import (
    EXPERIMENT_NAMES,
    config_from_dict,
    get_experiment,
    read_csv,
)

__all__ = ["PAPER_REFERENCE", "build_report", "latest_result", "render_report"]

#: The paper whose results the report sets ours beside (title and authors as published).
PAPER_REFERENCE = (
    "G. D'Angelo, V. Clerico, C. Bartolozzi, M. Hoffmann, P. M. Furlong and "
    'A. Hadjiivanov, "Wandering around: A bioinspired approach to visual attention '
    'through object motion sensitivity"'
)


def _created(folder: Path) -> tuple[str, str]:
    try:
        run = json.loads((folder / "run.json").read_text())
    except (OSError, ValueError):
        return ("", folder.name)
    return (str(run.get("created", "")), folder.name)


def latest_result(root: Path, name: str) -> Path | None:
    """The newest complete result folder of experiment ``name`` under ``root``."""
    base = root / name
    if not base.is_dir():
        return None
    done = [
        d for d in base.iterdir() if (d / "results.csv").is_file() and (d / "run.json").is_file()
    ]
    return max(done, key=_created) if done else None


def _rel(path: Path, start: Path) -> str:
    return Path(os.path.relpath(path.resolve(), start.resolve())).as_posix()


def _seconds(value: Any) -> str:
    """``"12 s"``, or ``"? s"`` for a missing figure (``null`` in strict JSON)."""
    return "? s" if value is None else f"{float(value):.0f} s"


def _section(name: str, folder: Path | None, report_dir: Path) -> list[str]:
    exp = get_experiment(name)
    lines = [f"## {name}", "", exp.description, ""]
    if folder is None:
        return [*lines, f"Not run yet: `wander experiment {name}`.", ""]
    run: dict[str, Any] = json.loads((folder / "run.json").read_text())
    cfg_data = json.loads((folder / "config.json").read_text())
    cfg_data.pop("experiment", None)
    config = config_from_dict(exp.config_type, cfg_data, where=str(folder / "config.json"))
    rows = read_csv(folder / "results.csv")
    timing = run.get("timing", {})
    lines += [
        f"- command: `{run.get('command', '')}`",
        f"- seed {run.get('seed')}, git revision `{run.get('git_revision', 'unknown')}`, "
        f"created {run.get('created', '?')}",
        f"- {len(rows)} trials in {_seconds(timing.get('total_s'))}; table: "
        f"[{_rel(folder / 'results.csv', report_dir)}]({_rel(folder / 'results.csv', report_dir)})",
        "",
    ]
    comps = exp.compare(config, rows) if exp.compare else []
    if comps:
        lines += ["| result | paper | ours | note |", "|---|---|---|---|"]
        lines += [f"| {c.result} | {c.paper} | {c.ours} | {c.note} |" for c in comps]
        lines.append("")
    if exp.plot is not None:
        figs = exp.plot(config, rows, folder, report_dir / "report_figures" / name)
        lines += [f"![{p.stem}]({_rel(p, report_dir)})" for p in figs]
        lines.append("")
    return lines


def _sweeps(root: Path, report_dir: Path) -> list[str]:
    base = root / "sweeps"
    found = (
        sorted(d for d in base.iterdir() if (d / "sweep.json").is_file()) if base.is_dir() else []
    )
    if not found:
        return []
    lines = [
        "## Sweeps",
        "",
        "| sweep | trials | backend | command | table |",
        "|---|---:|---|---|---|",
    ]
    for d in found:
        s = json.loads((d / "sweep.json").read_text())
        table = _rel(d / "results.csv", report_dir)
        lines.append(
            f"| {d.name} | {s.get('trials')} | {s.get('backend')} | `{s.get('command', '')}` "
            f"| [{table}]({table}) |"
        )
    return [*lines, ""]


def render_report(root: Path = Path("results"), report_dir: Path = Path(".")) -> str:
    """The Markdown text (figures are written under ``report_dir/report_figures``)."""
    lines = [
        "# wander: the paper's results and ours",
        "",
        "Each section comes from the newest result folder of one experiment "
        f"(`{root}/NAME/...`); rerun it with the command shown. The paper: {PAPER_REFERENCE}. "
        "Its numbers come from real recordings (Speck, EVIMO, LLE-VOS), ours from the "
        "simulator.",
        "",
    ]
    for name in EXPERIMENT_NAMES:
        lines += _section(name, latest_result(root, name), report_dir)
    lines += _sweeps(root, report_dir)
    return "\n".join(lines).rstrip() + "\n"


def build_report(root: Path = Path("results"), out: Path = Path("REPORT.md")) -> Path:
    """Write ``out`` (and its figures next to it); returns its path."""
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(render_report(root, out.parent))
    return out
