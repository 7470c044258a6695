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


def test_studies_section_shows_the_flir_main_sequence_and_the_links_cost(tmp_path) -> None:
    import numpy as np

    from experiments.paper import saccade_speed
    from experiments.paper.main_sequence import fit_linear, fit_saturating
    from wander_env.ptu import PTUParams

    cfg = saccade_speed.SaccadeSpeedConfig()
    folder = tmp_path / "results" / "saccade_speed" / "x"
    base = saccade_speed.baseline()
    amps = np.array(cfg.main_sequence_amplitudes_deg)
    v, d = saccade_speed.theory_main_sequence(amps, PTUParams())
    fits = fit_saturating(amps, v).as_dict("ms_v_") | fit_linear(amps, d).as_dict("ms_d_")
    fits["ms_amplitudes"] = len(amps)
    rows = []
    for factor, ptu, ttf in (("baseline", "flir", 0.75), ("ptu_link", "ideal", 0.5)):
        for seed in range(10):
            rows.append({"trial": len(rows), "trial_id": f"t{len(rows)}", "repeat": seed,
                         "seed": seed, "factor": factor, **base, "ptu": ptu,
                         "main_sequence": seed == 0, "time_to_foveate_s": ttf + 0.125 * seed,
                         "detection_accuracy": 1.0, "foveation_error_x_px": 0.3,
                         "foveation_error_y_px": 0.3, "command_latency_mean_s": 0.024,
                         **(fits if seed == 0 else {})})  # fmt: skip
    write_csv(rows, folder / "results.csv")
    (folder / "config.json").write_text(
        json.dumps({"experiment": "saccade_speed", **config_to_dict(cfg)})
    )
    (folder / "run.json").write_text(json.dumps({"created": "2026-01-01T00:00:00"}))
    lines = studies_section(tmp_path / "results", tmp_path)
    ms = [line for line in lines if line.startswith("| main sequence, 2000 pos/s, 2000 pos/s²")]
    assert len(ms) == 2 and "flir PTU" in ms[0] and "— (future work)" in ms[0]
    assert "D = D0 + k·A: D0 " in ms[0] and "k 0.0255 [" in ms[0]
    link = next(line for line in lines if line.startswith("| time to foveate (s): FLIR link"))
    # FLIR − ideal: exactly 0.25 s on every seed: p = 2/1024, no spread (d_z undefined)
    assert "Δ = 0.25 [0.25, 0.25], p = 0.00195, d_z = — (no spread), r_rb = 1.00 (n = 10) |" in link
