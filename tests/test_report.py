"""wander report's studies section, from a scanpath result folder made by hand."""

from __future__ import annotations

import json

from test_scanpath_metrics import _rows

from experiments.framework import config_to_dict, write_csv
from experiments.paper import scanpath
from experiments.report import studies_section


def test_studies_section_shows_the_tested_statements_beside_the_papers(tmp_path) -> None:
    cfg = scanpath.ScanpathConfig(scenes=("shelf",))
    folder = tmp_path / "results" / "scanpath" / "x"
    rows = []
    for i, r in enumerate(_rows()):
        extra = {k: 1.0 for _, k, _ in scanpath._metrics(cfg) if k != "object_hit_rate"}
        rows.append({"trial": i, "trial_id": f"t{i}", "repeat": r["seed"], **r, **extra})
    write_csv(rows, folder / "results.csv")
    (folder / "config.json").write_text(
        json.dumps({"experiment": "scanpath", **config_to_dict(cfg)})
    )
    (folder / "run.json").write_text(json.dumps({"created": "2026-01-01T00:00:00"}))
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
