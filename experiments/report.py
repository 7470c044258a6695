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


def _load(folder: Path, name: str) -> tuple[Any, list[dict[str, Any]]]:
    exp = get_experiment(name)
    cfg_data = json.loads((folder / "config.json").read_text())
    cfg_data.pop("experiment", None)
    config = config_from_dict(exp.config_type, cfg_data, where=str(folder / "config.json"))
    return config, read_csv(folder / "results.csv")


def studies_section(root: Path, report_dir: Path) -> list[str]:
    """The scanpath and speed studies' tested statements beside the paper's: the
    fixational − saccades difference in object hit rate (paired test, effect size),
    the scanpaths' repeatability, the FLIR main-sequence fits, the command latency's
    effect on time to foveate, and the speed sweeps' response surfaces."""
    from experiments.paper import saccade_speed, scanpath
    from experiments.stats import paired_comparison

    lines = ["## Scanpath and speed studies: the statements tested", ""]
    rows_out = ["| statement | paper | ours | from |", "|---|---|---|---|"]
    folder = latest_result(root, "scanpath")
    if folder is not None:
        cfg, rows = _load(folder, "scanpath")
        src = _rel(folder / "results.csv", report_dir)
        for c in scanpath.compare(cfg, rows):
            if c.result.endswith(": object hit rate") or "repeatability" in c.result:
                ours = c.ours + (f"; {c.note}" if c.note.startswith("fixational") else "")
                rows_out.append(f"| {c.result} | {c.paper} | {ours} | [{src}]({src}) |")
    folder = latest_result(root, "saccade_speed")
    if folder is not None:
        cfg, rows = _load(folder, "saccade_speed")
        src = _rel(folder / "results.csv", report_dir)
        for c in saccade_speed.compare(cfg, rows):
            if c.result.startswith("main sequence, 2000 pos/s, 2000 pos/s²"):
                rows_out.append(f"| {c.result} | {c.paper} | {c.ours} | [{src}]({src}) |")
        base = [r for r in rows if r["factor"] == "baseline"]
        ideal = [r for r in rows if r["factor"] == "ptu_link" and r["ptu"] == "ideal"]
        if base and ideal and base[0]["ptu"] == "flir":
            by = {int(r["seed"]): float(r["time_to_foveate_s"]) for r in ideal}
            pairs = [(float(r["time_to_foveate_s"]), by[int(r["seed"])]) for r in base
                     if int(r["seed"]) in by]  # fmt: skip
            t = paired_comparison([a for a, _ in pairs], [b for _, b in pairs])
            rows_out.append(
                f"| time to foveate (s): FLIR link (9600 baud) − ideal PTU | — (the paper's "
                f"rig talks to the PTU at 9600 baud) | {t.text('.3g')} | [{src}]({src}) |"
            )
    if len(rows_out) > 2:
        lines += [*rows_out, ""]
    sweeps = root / "sweeps"
    for d in sorted(sweeps.glob("speed*")) if sweeps.is_dir() else []:
        if (d / "results.csv").is_file():
            from experiments.paper.speed_study import plot_surfaces

            fig = plot_surfaces(
                read_csv(d / "results.csv"),
                report_dir / "report_figures" / f"sweep_{d.name}_surfaces.png",
                title=f"sweep {d.name}: response surfaces",
            )
            lines += [f"![{fig.stem}]({_rel(fig, report_dir)})", ""]
    if len(lines) == 2:
        lines += [
            "Not run yet: `wander experiment scanpath`, `wander experiment saccade_speed`.",
            "",
        ]
    return lines


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
    lines += studies_section(root, report_dir)
    lines += _sweeps(root, report_dir)
    return "\n".join(lines).rstrip() + "\n"


def build_report(root: Path = Path("results"), out: Path = Path("REPORT.md")) -> Path:
    """Write ``out`` (and its figures next to it); returns its path."""
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(render_report(root, out.parent))
    return out
