"""wander report: its studies section, from a scanpath result folder made by hand; where it
writes; damaged result folders (one line naming the file, exit 2, nothing written)."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest
from test_scanpath_metrics import _rows
from typer.testing import CliRunner

from experiments.cli.main import app
from experiments.paper import scanpath
from experiments.paper.report import studies_section
from experiments.runs.tables import write_csv
from wander_env.config import to_plain


def test_studies_section_shows_the_tested_statements_beside_the_papers(tmp_path) -> None:
    _scanpath_folder(tmp_path / "results")
    lines = studies_section(tmp_path / "results", tmp_path)
    text = "\n".join(lines)
    assert lines[0] == "## Scanpath and speed studies: the statements tested"
    hit = next(line for line in lines if line.startswith("| shelf: object hit rate |"))
    assert "random jumps to non-informative locations" in hit
    assert "fixational − saccades: Δ = 0.645" in hit and "p = 0.00195" in hit
    assert "| shelf: repeatability (position similarity to the other seeds) |" in text
    assert "results/scanpath/x/results.csv" in hit


def test_studies_section_without_results_says_what_to_run(tmp_path) -> None:
    lines = studies_section(tmp_path, tmp_path)
    assert "Not run yet" in lines[2]


def test_studies_section_shows_the_flir_main_sequence_and_the_links_cost(tmp_path) -> None:
    import numpy as np

    from experiments.paper import ptu_main_sequence, saccade_speed
    from experiments.paper.main_sequence import fit_linear, fit_saturating
    from wander_env.ptu.params import PTUParams

    cfg = saccade_speed.SaccadeSpeedConfig()
    folder = tmp_path / "results" / "saccade_speed" / "x"
    base = saccade_speed.baseline()
    amps = np.array(cfg.main_sequence_amplitudes_deg)
    v, d = ptu_main_sequence.theory_main_sequence(amps, PTUParams())
    fits = fit_saturating(amps, v).as_dict("ms_v_") | fit_linear(amps, d).as_dict("ms_d_")
    fits["ms_amplitudes"] = len(amps)
    rows = []
    for factor, ptu, ttf in (("baseline", "flir", 0.75), ("ptu_link", "ideal", 0.5)):
        for seed in range(10):
            rows.append(
                {
                    "trial": len(rows),
                    "trial_id": f"t{len(rows)}",
                    "repeat": seed,
                    "seed": seed,
                    "factor": factor,
                    **base,
                    "ptu_preset": ptu,
                    "main_sequence": seed == 0,
                    "time_to_foveate_s": ttf + 0.125 * seed,
                    "detection_accuracy": 1.0,
                    "foveation_error_x_px": 0.3,
                    "foveation_error_y_px": 0.3,
                    "command_latency_mean_s": 0.024,
                    **(fits if seed == 0 else {}),
                }
            )
    write_csv(rows, folder / "results.csv")
    (folder / "config.json").write_text(
        json.dumps({"experiment": "saccade_speed", **to_plain(cfg)})
    )
    (folder / "run.json").write_text(json.dumps({"created": "2026-01-01T00:00:00"}))
    lines = studies_section(tmp_path / "results", tmp_path)
    ms = [line for line in lines if line.startswith("| main sequence, 2000 pos/s, 2000 pos/s²")]
    assert len(ms) == 2 and "flir PTU" in ms[0] and "— (future work)" in ms[0]
    assert "D = D0 + k·A: D0 " in ms[0] and "k 0.0255 [" in ms[0]
    link = next(line for line in lines if line.startswith("| time to foveate (s): FLIR link"))
    # FLIR − ideal: exactly 0.25 s on every seed: p = 2/1024, no spread (d_z undefined)
    assert "Δ = 0.25 [0.25, 0.25], p = 0.00195, d_z = — (no spread), r_rb = 1.00 (n = 10) |" in link


# ----------------------------------------------------------------------------------------
# Damaged result folders: one line naming the file, exit 2, nothing written


def _scanpath_folder(root: Path) -> Path:
    """A complete scanpath result folder under ``root/scanpath/x`` (made by hand)."""
    cfg = scanpath.ScanpathConfig(scenes=("shelf",))
    folder = root / "scanpath" / "x"
    rows = []
    for i, r in enumerate(_rows()):
        extra = {k: 1.0 for _, k, _ in scanpath._metrics(cfg) if k != "object_hit_rate"}
        rows.append({"trial": i, "trial_id": f"t{i}", "repeat": r["seed"], **r, **extra})
    write_csv(rows, folder / "results.csv")
    (folder / "config.json").write_text(json.dumps({"experiment": "scanpath", **to_plain(cfg)}))
    (folder / "run.json").write_text(json.dumps({"created": "2026-01-01T00:00:00"}))
    return folder


def _lines(path: Path) -> list[str]:
    return path.read_text().splitlines()


def _cut_row(csv_path: Path) -> None:
    lines = _lines(csv_path)
    lines[-1] = ",".join(lines[-1].split(",")[:-2])
    csv_path.write_text("\n".join(lines) + "\n")


def _cut_header(csv_path: Path) -> None:
    lines = _lines(csv_path)
    lines[0] = ",".join(lines[0].split(",")[:-1])
    csv_path.write_text("\n".join(lines) + "\n")


def _abc(csv_path: Path, rows: range) -> None:
    lines = _lines(csv_path)
    col = lines[0].split(",").index("object_hit_rate")
    for k in rows:
        cells = lines[k].split(",")
        cells[col] = "abc"
        lines[k] = ",".join(cells)
    csv_path.write_text("\n".join(lines) + "\n")


RANDOM = bytes(range(128, 256)) * 8  # not UTF-8 anywhere
DAMAGE = {
    "a row cut short": (
        "results.csv",
        _cut_row,
        "line 21 has 17 cells, the header 19 (cut or damaged)",
    ),
    "the header cut short": (
        "results.csv",
        _cut_header,
        "line 2 has 19 cells, the header 18 (cut or damaged)",
    ),
    "abc in a number column": (
        "results.csv",
        lambda p: _abc(p, range(3, 4)),
        "column 'object_hit_rate', line 4: 'abc' where the other rows hold numbers",
    ),
    "abc in every row of a number column": (
        "results.csv",
        lambda p: _abc(p, range(1, 21)),
        "scanpath's figures failed on its rows (ValueError: could not convert string to "
        "float: 'abc')",
    ),
    "random bytes for the table": (
        "results.csv",
        lambda p: p.write_bytes(RANDOM),
        "not UTF-8 text (invalid start byte at byte 0)",
    ),
    "an empty table": ("results.csv", lambda p: p.write_text(""), "empty: no header row"),
    "run.json cut short": (
        "run.json",
        lambda p: p.write_bytes(p.read_bytes()[:9]),
        "not valid JSON, cut short or damaged (Unterminated string starting at: line 1 "
        "column 2 (char 1))",
    ),
    "random bytes for run.json": (
        "run.json",
        lambda p: p.write_bytes(RANDOM),
        "not UTF-8 text (invalid start byte at byte 0)",
    ),
    "run.json not an object": (
        "run.json",
        lambda p: p.write_text("[1]"),
        "expected a JSON object, got list",
    ),
    "config.json cut short": (
        "config.json",
        lambda p: p.write_bytes(p.read_bytes()[:9]),
        "not valid JSON, cut short or damaged (Unterminated string starting at: line 1 "
        "column 2 (char 1))",
    ),
    "run.json missing": ("run.json", lambda p: p.unlink(), "missing"),
    "run.json a folder": (
        "run.json",
        lambda p: (p.unlink(), p.mkdir()),
        "not a regular file (a folder): refused",
    ),
    "results.csv a folder": (
        "results.csv",
        lambda p: (p.unlink(), p.mkdir()),
        "not a regular file (a folder): refused",
    ),
    "results.csv missing from a finished run": (
        "results.csv",
        lambda p: (p.unlink(), (p.parent / "run.json").write_text('{"timing": {"total_s": 1}}')),
        "missing, though run.json records a finished run (damaged)",
    ),
    "the table cut inside its header": (
        "results.csv",
        lambda p: p.write_text("trial,tri"),
        "no rows (a run writes one per trial): cut or damaged",
    ),
    "a header and no rows": (
        "results.csv",
        lambda p: p.write_text(_lines(p)[0] + "\n"),
        "no rows (a run writes one per trial): cut or damaged",
    ),
}


@pytest.mark.parametrize("case", list(DAMAGE))
def test_a_damaged_result_folder_is_one_line_and_nothing_is_written(tmp_path, case) -> None:
    name, damage, problem = DAMAGE[case]
    folder = _scanpath_folder(tmp_path / "results")
    damage(folder / name)
    out = tmp_path / "docs" / "REPORT.md"
    result = CliRunner().invoke(
        app,
        ["report", "--results", str(tmp_path / "results"), "--out", str(out)],
        prog_name="wander",
    )
    assert result.exit_code == 2, result.output
    assert result.stderr.splitlines() == [f"wander report: error: {folder / name}: {problem}"]
    assert not (tmp_path / "docs").exists()


def test_a_run_not_finished_is_passed_over_not_refused(tmp_path) -> None:
    """A folder without a results.csv whose run.json has no timings is a run still going
    or stopped (a rerun resumes it): the report leaves it out."""
    folder = _scanpath_folder(tmp_path / "results")
    (folder / "results.csv").unlink()
    out = tmp_path / "R.md"
    args = ["report", "--results", str(tmp_path / "results"), "--out", str(out)]
    result = CliRunner().invoke(app, args, prog_name="wander")
    assert result.exit_code == 0, result.output
    assert "Not run yet: `wander experiment scanpath`." in out.read_text()


@pytest.mark.parametrize("kind", ["fifo", "/dev/null"])
def test_an_out_that_is_not_a_regular_file_is_refused(tmp_path, monkeypatch, kind) -> None:
    """``--out /dev/null --force`` made /dev/report_figures: refused before anything."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "results").mkdir()
    out = kind
    if kind == "fifo":
        os.mkfifo(tmp_path / "fifo")
    before = Path("/dev/report_figures").exists()
    args = ["report", "--results", "results", "--out", out, "--force"]
    result = CliRunner().invoke(app, args, prog_name="wander")
    assert (result.exit_code, result.stderr.splitlines()) == (
        2,
        [f"wander report: Invalid value for '--out': '{out}' exists and is not a regular file"],
    )
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted({"results", out} - {"/dev/null"})
    assert Path("/dev/report_figures").exists() == before


def test_a_damaged_sweep_file_is_named(tmp_path) -> None:
    sweep = tmp_path / "results" / "sweeps" / "s1"
    sweep.mkdir(parents=True)
    (sweep / "sweep.json").write_text('{"trials": 3')
    args = ["report", "--results", str(tmp_path / "results"), "--out", str(tmp_path / "R.md")]
    result = CliRunner().invoke(app, args, prog_name="wander")
    assert result.exit_code == 2
    assert result.stderr.splitlines() == [
        f"wander report: error: {sweep / 'sweep.json'}: not valid JSON, cut short or damaged "
        "(Expecting ',' delimiter: line 1 column 13 (char 12))"
    ]
    assert not (tmp_path / "R.md").exists()


def test_a_finished_sweep_without_its_table_is_named(tmp_path) -> None:
    sweep = tmp_path / "results" / "sweeps" / "s1"
    sweep.mkdir(parents=True)
    (sweep / "sweep.json").write_text('{"trials": 3}')
    args = ["report", "--results", str(tmp_path / "results"), "--out", str(tmp_path / "R.md")]
    result = CliRunner().invoke(app, args, prog_name="wander")
    assert (result.exit_code, result.stderr.splitlines()) == (
        2,
        [f"wander report: error: {sweep / 'results.csv'}: missing"],
    )
    assert not (tmp_path / "R.md").exists()


@pytest.mark.slow
def test_report_figures_go_beside_the_report_not_the_cwd(tmp_path, monkeypatch) -> None:
    _scanpath_folder(tmp_path / "results")
    cwd = tmp_path / "cwd"
    (cwd / "reports").mkdir(parents=True)
    monkeypatch.chdir(cwd)
    runner = CliRunner()
    args = ["report", "--results", str(tmp_path / "results")]
    assert runner.invoke(app, [*args, "--out", "reports"]).exit_code == 0  # a folder
    assert runner.invoke(app, [*args, "--out", "../docs/R.md"]).exit_code == 0  # a file
    figures = ["scanpath/scanpath.png", "scanpath/scanpath_stats.png"]
    for report in (cwd / "reports" / "REPORT.md", tmp_path / "docs" / "R.md"):
        text = report.read_text()
        for fig in figures:
            assert (report.parent / "report_figures" / fig).is_file()
            assert f"(report_figures/{fig})" in text
    assert sorted(p.name for p in cwd.iterdir()) == ["reports"]


def test_report_help_shows_no_double_backticks() -> None:
    result = CliRunner().invoke(app, ["report", "--help"])
    assert result.exit_code == 0 and "``" not in result.output and "--force" in result.output


def test_what_the_report_copies_from_files_is_escaped(tmp_path) -> None:
    """run.json's command, revision and time reach REPORT.md as text: no tag, no handler,
    no remote image, in the file or in the page it renders to."""
    import markdown

    folder = _scanpath_folder(tmp_path / "results")
    hostile = {
        "created": "2026-01-01T00:00:00<script>alert(1)</script>",
        "command": "wander x `rm` | ![t](https://evil.example/t.png)",
        "git_revision": '<img src=x onerror="alert(2)">',
        "seed": "[a](javascript:alert(3))",
    }
    (folder / "run.json").write_text(json.dumps(hostile))
    out = tmp_path / "REPORT.md"
    result = CliRunner().invoke(
        app, ["report", "--results", str(tmp_path / "results"), "--out", str(out)]
    )
    assert result.exit_code == 0, result.output
    text = out.read_text()
    (command,) = [line for line in text.splitlines() if line.startswith("- command:")]
    assert command == (
        r"- command: <code>wander x \`rm\` | ![t]\(https://evil.example/t.png)</code>"
    )
    (seed,) = [line for line in text.splitlines() if line.startswith("- seed ")]
    assert seed == (
        r"- seed [a]\(javascript:alert(3)), git revision "
        r'<code>&lt;img src=x onerror="alert(2)"&gt;</code>, created '
        r"2026-01-01T00:00:00&lt;script&gt;alert(1)&lt;/script&gt;"
    )
    page = markdown.markdown(text, extensions=["tables"])
    for raw in ("<script", "<img src=x", '<img alt="t"', 'evil.example/t.png"', 'href="javascript'):
        assert raw not in page
    assert "<code>wander x `rm` | ![t](https://evil.example/t.png)</code>" in page


def test_a_trial_id_that_names_a_path_is_refused(tmp_path) -> None:
    folder = _scanpath_folder(tmp_path / "results")
    csv_path = folder / "results.csv"
    lines = _lines(csv_path)
    header = lines[0].split(",")
    cells = lines[1].split(",")
    cells[header.index("trial_id")] = "../../outside"
    lines[1] = ",".join(cells)
    csv_path.write_text("\n".join(lines) + "\n")
    result = CliRunner().invoke(
        app,
        ["report", "--results", str(tmp_path / "results"), "--out", str(tmp_path / "R.md")],
        prog_name="wander",
    )
    assert result.exit_code == 2
    assert result.stderr.splitlines() == [
        f"wander report: error: {csv_path}: line 2: trial_id '../../outside' is not a plain "
        "name (letters, digits, '_', '-', '.'): it would name a file outside the result folder"
    ]
    assert not (tmp_path / "R.md").exists()


def test_a_missing_results_folder_is_one_line(tmp_path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)
    result = CliRunner().invoke(app, ["report", "--results", "nodir"], prog_name="wander")
    assert result.exit_code == 2
    assert result.stderr.splitlines() == [
        "wander report: Invalid value for '--results': no results folder 'nodir': run "
        "`wander experiment NAME` first, or give the folder that holds its results"
    ]
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    ("out", "problem"),
    [
        ("file/REPORT.md", "cannot create 'file/REPORT.md': Not a directory"),
        ("/proc/wander/", "cannot create '/proc/wander': No such file or directory"),
    ],
)
def test_an_out_that_cannot_be_written_is_one_line(tmp_path, monkeypatch, out, problem) -> None:
    monkeypatch.chdir(tmp_path)
    (tmp_path / "results").mkdir()
    (tmp_path / "file").write_text("x")
    args = ["report", "--results", "results", "--out", out]
    result = CliRunner().invoke(app, args, prog_name="wander")
    assert result.exit_code == 2
    assert result.stderr.splitlines() == [f"wander report: Invalid value for '--out': {problem}"]


def test_an_out_ending_with_a_slash_is_a_folder(tmp_path, monkeypatch) -> None:
    """The issue's case: ``--out newdir/`` wrote a file named ``newdir``."""
    _scanpath_folder(tmp_path / "results")
    monkeypatch.chdir(tmp_path)
    result = CliRunner().invoke(app, ["report", "--results", "results", "--out", "newdir/"])
    assert result.exit_code == 0, result.output
    assert (tmp_path / "newdir").is_dir() and (tmp_path / "newdir" / "REPORT.md").is_file()
    assert (tmp_path / "newdir" / "report_figures" / "scanpath" / "scanpath.png").is_file()
