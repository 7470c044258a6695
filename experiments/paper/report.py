"""``wander report``: REPORT.md from the latest result folders, the paper's numbers beside ours.

For every registered experiment the newest finished folder ``results/NAME/*`` (one
holding a ``results.csv``, the table a run writes last, and a ``run.json``) is read (newest
by the ``created`` time in ``run.json``, then by folder name); its figures are drawn again
into ``<report dir>/report_figures/NAME`` and a section gives the command, seed, git
revision and run time that produced it and the experiment's comparison table
(``Experiment.compare``). A folder without a ``results.csv`` whose ``run.json`` does not
record a finished run is a run still going or stopped (``wander experiment NAME``
resumes it) and is passed over. Sweeps found under ``results/sweeps/*`` are listed with
their tables.

Result folders are read as untrusted input: every file the report uses (``run.json``,
``config.json``, ``results.csv``, ``sweep.json``) is read and checked, and every comparison
computed, before anything is written; a damaged one (cut short, random bytes, a row with
too few or too many cells, a table without rows, ``abc`` in a number column, rows the
experiment cannot use, a ``trial_id`` that is not a plain name such as ``../../outside``,
which would name a file outside the folder; a finished folder missing its ``run.json`` or
``results.csv``, or holding a folder in their place) is a :class:`ReportInputError` naming
the file, and nothing is written.
Every text the report copies from those files (commands, revisions, folder names, the
comparisons' cells) is escaped (:func:`md_text`): HTML is shown as text and Markdown's link,
image and table syntax is neutralised, so a result folder cannot put a script, an
``onerror`` handler or a remote image into REPORT.md.
"""

from __future__ import annotations

import csv
import errno
import html
import io
import math
import os
import re
import shutil
import tempfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TypeVar
from urllib.parse import quote

from experiments.runs.folder import RESULTS, SWEEPS
from experiments.runs.tables import parse_csv
from experiments.studies.framework import EXPERIMENT_NAMES, config_from_dict, get_experiment
from wander_env import untrusted
from wander_env.config_messages import shown

__all__ = [
    "PAPER_REFERENCE",
    "LoadedResult",
    "ReportInputError",
    "build_report",
    "latest_result",
    "load_result",
    "md_link",
    "md_text",
    "read_json",
    "read_rows",
    "render_report",
    "report_path",
]
_T = TypeVar("_T")

#: The paper whose results the report sets ours beside (title and authors as published).
PAPER_REFERENCE = (
    "G. D'Angelo, V. Clerico, C. Bartolozzi, M. Hoffmann, P. M. Furlong and "
    'A. Hadjiivanov, "Wandering around: A bioinspired approach to visual attention '
    'through object motion sensitivity"'
)


class ReportInputError(ValueError):
    """A result file the report cannot use: names the file and what is wrong with it."""

    def __init__(self, path: Path, problem: str) -> None:
        self.path = str(path)
        super().__init__(f"{path}: {problem}")


#: The largest ``results.csv`` read (bytes): 100,000 trials of a few hundred bytes each
#: fit; parsed, a table takes several times its size in memory.
MAX_TABLE_BYTES = 64 << 20

#: A trial id: a plain file name (``artifacts/<trial_id>.npz``), never a path.
_TRIAL_ID = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.-]*")


def md_text(value: object, cell: bool = False) -> str:
    """``value`` as Markdown text that shows exactly it on one line: white space folded,
    ``&``, ``<`` and ``>`` as HTML entities (no tag, script, ``onerror`` handler or
    autolink reaches the page), ``\\`` and ````` escaped (no code span), the ``](`` of an
    inline link or image broken (``]\\(``: no link, no remote image), and in a table
    ``cell`` ``|`` escaped (no cell break).

    >>> print(md_text('<img src=x onerror="alert(1)"> ![t](http://a.b/c.png) `a|b` [1, 2]'))
    &lt;img src=x onerror="alert(1)"&gt; ![t]\\(http://a.b/c.png) \\`a|b\\` [1, 2]
    >>> print(md_text("a|b", cell=True))
    a\\|b
    """
    text = " ".join(str(value).split()).replace("\\", "\\\\").replace("`", "\\`")
    text = html.escape(text, quote=False).replace("](", "]\\(")
    return text.replace("|", "\\|") if cell else text


def md_link(path: str, cell: bool = False) -> str:
    """A Markdown link to the relative ``path``, its text escaped (:func:`md_text`, in a
    table ``cell`` or not) and its target percent-encoded (a folder name cannot end the
    link or start another).

    >>> print(md_link("x)![i](http:/e)/results.csv"))
    [x)![i]\\(http:/e)/results.csv](x%29%21%5Bi%5D%28http%3A/e%29/results.csv)
    """
    return f"[{md_text(path, cell)}]({quote(path)})"


def read_json(path: Path) -> dict[str, Any]:
    """A JSON object from ``path``, or :class:`ReportInputError`."""
    try:
        data = untrusted.read_json(path)  # a regular file, bounded in size and nesting
    except untrusted.UntrustedFileError as err:
        raise ReportInputError(path, "missing" if err.missing else err.problem) from None
    if not isinstance(data, dict):
        raise ReportInputError(path, f"expected a JSON object, got {type(data).__name__}")
    return data


def read_rows(path: Path) -> list[dict[str, Any]]:
    """The rows of a ``results.csv`` (:func:`experiments.runs.tables.parse_csv`), checked
    first: a regular file of at most :data:`MAX_TABLE_BYTES` of UTF-8 text, every row as many
    cells as the header, at least one row (a run has at least one trial: a table cut inside
    its header has none), and no column that mixes numbers with text (``abc`` where the
    other rows hold numbers); :class:`ReportInputError` otherwise."""
    try:
        text = untrusted.read_bytes(path, MAX_TABLE_BYTES).decode("utf-8")
        table = list(csv.reader(io.StringIO(text, newline="")))
    except untrusted.UntrustedFileError as err:
        raise ReportInputError(path, "missing" if err.missing else err.problem) from None
    except UnicodeDecodeError as err:
        raise ReportInputError(path, f"not UTF-8 text ({err.reason} at byte {err.start})") from None
    except csv.Error as err:
        raise ReportInputError(path, f"not a CSV table ({err})") from None
    if not table or not table[0]:
        raise ReportInputError(path, "empty: no header row")
    header = table[0]
    for i, cells in enumerate(table[1:], start=2):
        if len(cells) != len(header):
            raise ReportInputError(
                path, f"line {i} has {len(cells)} cells, the header {len(header)} (cut or damaged)"
            )
    if len(table) < 2:
        raise ReportInputError(path, "no rows (a run writes one per trial): cut or damaged")
    rows = parse_csv(io.StringIO(text, newline=""))
    for col in header:
        kinds = {
            "text" if isinstance(r[col], str) else "number"
            for r in rows
            if not (isinstance(r[col], float) and math.isnan(r[col]))
        }
        if len(kinds) > 1:
            i, bad = next((i, r[col]) for i, r in enumerate(rows) if isinstance(r[col], str))
            raise ReportInputError(
                path,
                f"column {shown(col)}, line {i + 2}: {shown(bad)} where the other rows hold "
                "numbers",
            )
    for i, row in enumerate(rows):
        tid = row.get("trial_id")
        if tid is not None and not _TRIAL_ID.fullmatch(str(tid)):
            raise ReportInputError(
                path,
                f"line {i + 2}: trial_id {shown(tid)} is not a plain name (letters, digits, "
                "'_', '-', '.'): it would name a file outside the result folder",
            )
    return rows


def _checked(path: Path, what: str, fn: Callable[..., _T], *args: Any, **kwargs: Any) -> _T:
    """``fn(*args, **kwargs)`` on the rows of ``path``: a failure that their values cause is
    a :class:`ReportInputError` naming the file (the experiment's own code reads them)."""
    try:
        return fn(*args, **kwargs)
    except (ValueError, TypeError, KeyError, IndexError, ZeroDivisionError) as err:
        problem = f"{what} failed on its rows ({type(err).__name__}: {err})"
        raise ReportInputError(path, " ".join(problem.split())) from None


def _finished(folder: Path) -> tuple[str, str] | None:
    """The sort key (``run.json``'s ``created``, the name) of the folder ``folder`` when it
    holds a finished run, else None (module docstring). One holding a ``results.csv`` must
    hold a ``run.json`` (a regular file, a JSON object), and one without a ``results.csv``
    whose ``run.json`` records the run's timings (written once all its trials ran) lost
    its table: :class:`ReportInputError` naming the file."""
    if os.path.lexists(folder / "results.csv"):
        return (str(read_json(folder / "run.json").get("created", "")), folder.name)
    try:
        run = untrusted.read_json(folder / "run.json")
    except (ValueError, RecursionError):  # none yet, or being written: a run starting
        return None
    if isinstance(run, dict) and "timing" in run:
        raise ReportInputError(
            folder / "results.csv", "missing, though run.json records a finished run (damaged)"
        )
    return None


def latest_result(root: Path, name: str) -> Path | None:
    """The newest finished result folder of experiment ``name`` under ``root``
    (:func:`_finished`: a damaged one is a :class:`ReportInputError`)."""
    base = root / name
    if not base.is_dir():
        return None
    keys = {d: _finished(d) for d in sorted(base.iterdir()) if d.is_dir()}
    done = {d: k for d, k in keys.items() if k is not None}
    return max(done, key=done.__getitem__) if done else None


@dataclass(frozen=True)
class LoadedResult:
    """A result folder read and checked: ``run.json``, the config, the rows and the
    experiment's comparisons with the paper."""

    folder: Path
    run: dict[str, Any]
    config: Any
    rows: list[dict[str, Any]]
    comparisons: list[Any]


def load_result(folder: Path, name: str) -> LoadedResult:
    """Read and check the result folder ``folder`` of experiment ``name``
    (:class:`ReportInputError` naming the damaged file)."""
    exp = get_experiment(name)
    run = read_json(folder / "run.json")
    cfg_path = folder / "config.json"
    cfg_data = read_json(cfg_path)
    cfg_data.pop("experiment", None)
    config = config_from_dict(exp.config_type, cfg_data, where=str(cfg_path))  # ConfigError
    csv_path = folder / "results.csv"
    rows = read_rows(csv_path)
    compare = exp.compare
    comps = _checked(csv_path, f"{name}'s comparison", compare, config, rows) if compare else []
    return LoadedResult(folder, run, config, rows, comps)


def _rel(path: Path, start: Path) -> str:
    return Path(os.path.relpath(path.resolve(), start.resolve())).as_posix()


def _seconds(value: Any) -> str:
    """``"12 s"``, or ``"? s"`` for a missing figure (``null`` in strict JSON)."""
    return "? s" if value is None else f"{float(value):.0f} s"


def _figure_link(path: Path, figures: Path) -> str:
    """The report's link to a figure written under ``figures`` (``report_figures/`` there)."""
    return f"![{path.stem}](report_figures/{path.relative_to(figures).as_posix()})"


def _section(name: str, result: LoadedResult | None, report_dir: Path, figures: Path) -> list[str]:
    exp = get_experiment(name)
    lines = [f"## {name}", "", exp.description, ""]
    if result is None:
        return [*lines, f"Not run yet: `wander experiment {name}`.", ""]
    run, folder, rows = result.run, result.folder, result.rows
    timing = run.get("timing")
    total = timing.get("total_s") if isinstance(timing, dict) else None
    lines += [
        f"- command: <code>{md_text(run.get('command', ''))}</code>",
        f"- seed {md_text(run.get('seed'))}, git revision "
        f"<code>{md_text(run.get('git_revision', 'unknown'))}</code>, "
        f"created {md_text(run.get('created', '?'))}",
        f"- {len(rows)} trials in {_seconds(total)}; table: "
        f"{md_link(_rel(folder / 'results.csv', report_dir))}",
        "",
    ]
    if result.comparisons:
        lines += ["| result | paper | ours | note |", "|---|---|---|---|"]
        lines += [_row(c.result, c.paper, c.ours, c.note) for c in result.comparisons]
        lines.append("")
    if exp.plot is not None:
        plot = exp.plot
        csv_path = folder / "results.csv"
        figs = _checked(
            csv_path, f"{name}'s figures", plot, result.config, rows, folder, figures / name
        )
        lines += [_figure_link(p, figures) for p in figs]
        lines.append("")
    return lines


#: The keys of ``sweep.json`` the report's sweep table shows (after the sweep's name).
SWEEP_KEYS = ("trials", "backend", "command")


def _row(*cells: object) -> str:
    """A Markdown table row of ``cells``, each escaped (:func:`md_text`)."""
    return "| " + " | ".join(md_text(c, cell=True) for c in cells) + " |"


def _sweep_folders(root: Path) -> list[tuple[Path, dict[str, Any]]]:
    """The sweeps under ``root/sweeps`` with their ``sweep.json`` (checked)."""
    base = root / SWEEPS
    found = (
        sorted(d for d in base.iterdir() if os.path.lexists(d / "sweep.json"))
        if base.is_dir()
        else []
    )
    return [(d, read_json(d / "sweep.json")) for d in found]


def _sweep_tables(root: Path) -> list[tuple[Path, list[dict[str, Any]]]]:
    """The finished sweeps under ``root/sweeps`` (a ``results.csv`` or the ``sweep.json``
    written after it) with their rows (checked: a missing table is a
    :class:`ReportInputError`)."""
    sweeps = root / SWEEPS
    found = sorted(sweeps.iterdir()) if sweeps.is_dir() else []
    done = [
        d for d in found if os.path.lexists(d / "results.csv") or os.path.lexists(d / "sweep.json")
    ]
    return [(d, read_rows(d / "results.csv")) for d in done]


def _speed_sweeps(root: Path) -> list[tuple[Path, list[dict[str, Any]]]]:
    """The saccade-speed sweeps (``speed*``) with their rows."""
    return [
        (d, rows)
        for d, rows in _sweep_tables(root)
        if d.name.startswith("speed") and rows and "time_to_foveate_s" in rows[0]
    ]


def _ratio_sweeps(root: Path) -> list[tuple[Path, list[dict[str, Any]]]]:
    """The hand-against-shake sweeps (rows with ``cfg.hand_ratio``), their ``both`` rows."""
    from experiments.paper.speed_ratio import RATIO

    found = []
    for d, rows in _sweep_tables(root):
        if rows and RATIO in rows[0] and "phase" in rows[0]:
            found.append((d, [r for r in rows if r["phase"] == "both"]))
    return found


def ratio_section(root: Path, figures: Path) -> list[str]:
    """Each speed-ratio sweep's table (hit, suppression, background kept; the crossing
    ratios) and its figure, drawn into ``figures``."""
    from experiments.paper.event_suppression import image_speeds
    from experiments.paper.event_suppression_protocol import Shake
    from experiments.paper.speed_ratio import plot, table
    from wander_env.scenes import load_scene_config

    lines: list[str] = []
    for d, rows in _ratio_sweeps(root):
        _, shake = image_speeds(load_scene_config("hand"), Shake())
        text = _checked(d / "results.csv", "the speed-ratio table", table, rows)
        path = figures / f"sweep_{d.name}_ratio.png"
        fig = _checked(d / "results.csv", "the speed-ratio figure", plot, rows, path, shake)
        lines += [
            f"## The hand against the shake: sweep {md_text(d.name)}",
            "",
            text,
            _figure_link(fig, figures),
            "",
        ]
    return lines


def _sweeps(root: Path, report_dir: Path) -> list[str]:
    found = _sweep_folders(root)
    if not found:
        return []
    lines = [
        "## Sweeps",
        "",
        "| sweep | trials | backend | command | table |",
        "|---|---:|---|---|---|",
    ]
    for d, s in found:
        table = md_link(_rel(d / "results.csv", report_dir), cell=True)
        name, trials, backend, command = (
            md_text(v, cell=True) for v in (d.name, *(s.get(k, "") for k in SWEEP_KEYS))
        )
        lines.append(f"| {name} | {trials} | {backend} | <code>{command}</code> | {table} |")
    return [*lines, ""]


def _studies_table(root: Path, report_dir: Path) -> list[str]:
    """The rows of the studies' table (computed, nothing written)."""
    from experiments.analysis.stats import paired_comparison

    rows_out = ["| statement | paper | ours | from |", "|---|---|---|---|"]
    folder = latest_result(root, "scanpath")
    if folder is not None:
        loaded = load_result(folder, "scanpath")
        src = md_link(_rel(folder / "results.csv", report_dir), cell=True)
        for c in loaded.comparisons:
            if c.result.endswith(": object hit rate") or "repeatability" in c.result:
                ours = c.ours + (f"; {c.note}" if c.note.startswith("fixational") else "")
                rows_out.append(f"{_row(c.result, c.paper, ours)} {src} |")
    folder = latest_result(root, "saccade_speed")
    if folder is not None:
        loaded = load_result(folder, "saccade_speed")
        src = md_link(_rel(folder / "results.csv", report_dir), cell=True)
        for c in loaded.comparisons:
            if c.result.startswith("main sequence, 2000 pos/s, 2000 pos/s²"):
                rows_out.append(f"{_row(c.result, c.paper, c.ours)} {src} |")

        def link_cost() -> str | None:
            rows = loaded.rows
            base = [r for r in rows if r["factor"] == "baseline"]
            link = [r for r in rows if r["factor"] == "ptu_link"]
            ideal = [r for r in link if r.get("ptu_preset") == "ideal"]  # (no column: older)
            if not (base and ideal and base[0].get("ptu_preset") == "flir"):
                return None
            by = {int(r["seed"]): float(r["time_to_foveate_s"]) for r in ideal}
            pairs = [
                (float(r["time_to_foveate_s"]), by[int(r["seed"])])
                for r in base
                if int(r["seed"]) in by
            ]
            return paired_comparison([a for a, _ in pairs], [b for _, b in pairs]).text(".3g")

        cost = _checked(folder / "results.csv", "the PTU link's comparison", link_cost)
        if cost is not None:
            rows_out.append(
                f"| time to foveate (s): FLIR link (9600 baud) − ideal PTU | — (the paper's "
                f"rig talks to the PTU at 9600 baud) | {md_text(cost, cell=True)} | {src} |"
            )
    return rows_out if len(rows_out) > 2 else []


def studies_section(root: Path, report_dir: Path, figures: Path | None = None) -> list[str]:
    """The scanpath and speed studies' tested statements beside the paper's: the
    fixational − saccades difference in object hit rate (paired test, effect size),
    the scanpaths' repeatability, the FLIR main-sequence fits, the command latency's
    effect on time to foveate, and the speed sweeps' response surfaces (drawn into
    ``figures``, default ``report_dir/report_figures``)."""
    figures = report_dir / "report_figures" if figures is None else figures
    lines = ["## Scanpath and speed studies: the statements tested", ""]
    table = _studies_table(root, report_dir)
    speed = _speed_sweeps(root)
    if table:
        lines += [*table, ""]
    for d, rows in speed:
        from experiments.paper.speed_study import plot_surfaces

        fig = _checked(
            d / "results.csv",
            "the response surfaces",
            plot_surfaces,
            rows,
            figures / f"sweep_{d.name}_surfaces.png",
            title=f"sweep {d.name}: response surfaces",
        )
        lines += [_figure_link(fig, figures), ""]
    if len(lines) == 2:
        lines += [
            "Not run yet: `wander experiment scanpath`, `wander experiment saccade_speed`.",
            "",
        ]
    return lines


def render_report(
    root: Path = RESULTS, report_dir: Path = Path("."), figures: Path | None = None
) -> str:
    """The Markdown text of a report in ``report_dir``; its figures are written under
    ``figures`` (default ``report_dir/report_figures``) and linked as ``report_figures/``.

    Every result file is read and checked, and every comparison computed, before the first
    figure is drawn: a damaged file is a :class:`ReportInputError` naming it.
    """
    figures = report_dir / "report_figures" if figures is None else figures
    results = {}
    for name in EXPERIMENT_NAMES:
        folder = latest_result(root, name)
        results[name] = None if folder is None else load_result(folder, name)
    _studies_table(root, report_dir)
    sweeps = _sweeps(root, report_dir)  # (each sweep.json checked before its table)
    _speed_sweeps(root)
    _ratio_sweeps(root)
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
        lines += _section(name, results[name], report_dir, figures)
    lines += studies_section(root, report_dir, figures)
    lines += ratio_section(root, report_dir / "report_figures" if figures is None else figures)
    lines += sweeps
    return "\n".join(lines).rstrip() + "\n"


def report_path(out: str | os.PathLike) -> Path:
    """The report file of ``--out``: ``out`` itself, or ``out/REPORT.md`` when ``out`` is an
    existing folder or ends with a slash (a folder, made when missing).

    >>> report_path("docs/results.md").as_posix(), report_path("/").as_posix()
    ('docs/results.md', '/REPORT.md')
    >>> report_path("newdir/").as_posix()
    'newdir/REPORT.md'
    """
    text = os.fspath(out)
    folder = text.endswith(("/", os.sep)) or Path(text).is_dir()
    return Path(text) / "REPORT.md" if folder else Path(text)


def build_report(root: Path = RESULTS, out: str | os.PathLike = "REPORT.md") -> Path:
    """Write ``out`` (a file, or a folder: :func:`report_path`) and its figures in
    ``report_figures/`` beside it; returns the report's path.

    The figures are drawn in a temporary folder and moved beside the report once all of
    them are: a damaged result file (:class:`ReportInputError`) leaves nothing written.
    An ``out`` that exists and is not a regular file (``/dev/null``, a FIFO) is a
    FileExistsError naming it, before anything is read or written: the report and its
    figures' folder beside it belong in a folder of files.
    """
    out = report_path(out)
    if out.exists() and not out.is_file():
        raise FileExistsError(f"{str(out)!r} exists and is not a regular file")
    with tempfile.TemporaryDirectory(prefix="wander-report-") as tmp:
        text = render_report(root, out.parent, Path(tmp))
        try:
            out.parent.mkdir(parents=True, exist_ok=True)
        except FileExistsError:  # a file where a folder of the path should be
            raise NotADirectoryError(errno.ENOTDIR, os.strerror(errno.ENOTDIR), str(out)) from None
        figures = out.parent / "report_figures"
        for f in sorted(Path(tmp).rglob("*")):
            if f.is_file():
                dest = figures / f.relative_to(tmp)
                dest.parent.mkdir(parents=True, exist_ok=True)
                shutil.move(f, dest)
    out.write_text(text)
    return out
