"""Config, scene and sweep files and the values in them: every bad one is one line on
stderr naming the file (line and column), the field and the value, exit 2, no traceback,
nothing written, before anything runs; alias bombs stay within 1 GB."""

from __future__ import annotations

import importlib
import itertools
import json
import os
import signal
import subprocess
import sys
from dataclasses import replace

import pytest
from limited import GIB, run_limited
from locations import ROOT
from test_sweep import TOY_SWEEP, CountingRunner
from typer.testing import CliRunner

from experiments.cli.main import app
from experiments.runs.folder import RunFolder
from experiments.runs.signals import SignalExit
from experiments.studies.framework import TrialSpec
from experiments.studies.sweep import run_sweep, sweep_from_dict
from wander_env.scenes import available_scenes

runner = CliRunner()
SCENES = ", ".join(available_scenes())
CONFIG = ["experiment", "event_suppression", "--config", "c.yaml"]
SYNTAX = (
    "line 2, column 1: while parsing a flow sequence expected ',' or ']', but got '<stream end>'"
)
ALIAS = "line 1, column 4: anchors and aliases (&name, *name) are not allowed"


def billion_laughs() -> str:
    """The 9-level alias bomb: 9**9 strings once its aliases are expanded."""
    lines = ['a: &a ["lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol"]']
    names = "abcdefghi"
    for prev, name in itertools.pairwise(names):
        lines.append(f"{name}: &{name} [" + ", ".join([f"*{prev}"] * 9) + "]")
    return "\n".join(lines) + "\n"


SWEEP = "name: t\nexperiments: [{experiment: event_suppression, set: {repeats: 1}}]\n"
#: A run.json of `wander run` but for its inputs.
RUN = {"command": "wander run", "config": {"env": {"scene": "office"}, "seed": 0}, "seed": 0}
NO_INPUTS = {"scenes": {}, "files": {}}
# (run.json, the line after "wander rerun: error: ")
RERUN_CASES = [
    (RUN, "r/run.json: inputs: missing (the scene and the files the run read)"),
    (
        {**RUN, "inputs": "x"},
        "r/run.json: inputs: must be a mapping of scenes and files, got 'x'",
    ),
    (
        {**RUN, "inputs": {"scenes": [], "files": {}}},
        "r/run.json: inputs.scenes: must be a mapping, got []",
    ),
    (
        {**RUN, "inputs": NO_INPUTS},
        "r/run.json: inputs.scenes: no entry for the run's scene, got config.env.scene 'office'",
    ),
    ({**RUN, "config": 5}, "r/run.json: config: must be a mapping of settings, got 5"),
    ({**RUN, "seed": "x"}, "r/run.json: seed: expected int, got 'x'"),
    ({**RUN, "seed": -1}, "r/run.json: seed: input should be greater than or equal to 0, got -1"),
    ({k: v for k, v in RUN.items() if k != "seed"}, "r/run.json: seed: missing (the run's seed)"),
    (
        {**RUN, "seed": 1, "inputs": NO_INPUTS},
        "r/run.json: config.seed: must be the run's seed 1, got 0",
    ),
    (
        {**RUN, "config": {"seed": 0}},
        "r/run.json: config.env: must be a mapping naming the run's scene, got None",
    ),
    ([1], "r/run.json: must be a run folder's JSON object, got [1]"),
]

# (command line, {file: content}, the one line on stderr)
CASES = [
    # --config: the one YAML reader's refusals
    (CONFIG, {"c.yaml": "size: [0.2\n"}, f"wander experiment: error: c.yaml: {SYNTAX}"),
    (CONFIG, {"c.yaml": "a: &a [1]\nb: *a\n"}, f"wander experiment: error: c.yaml: {ALIAS}"),
    (
        CONFIG,
        {"c.yaml": "a: !!python/object/apply:os.system ['true']\n"},
        "wander experiment: error: c.yaml: line 1, column 4: tags are not allowed, "
        "got 'tag:yaml.org,2002:python/object/apply:os.system'",
    ),
    (
        CONFIG,
        {"c.yaml": b"repeats: 1\x00\n"},
        "wander experiment: error: c.yaml: a NUL character at offset 10 (not a text file)",
    ),
    (
        CONFIG,
        {"c.yaml": b"repeats: 1\x01\n"},
        "wander experiment: error: c.yaml: a control character (U+0001) at offset 10",
    ),
    (
        CONFIG,
        {"c.yaml": "repeats: 1\n".encode("utf-16")},
        "wander experiment: error: c.yaml: UTF-16 text; save it as UTF-8",
    ),
    (
        CONFIG,
        {"c.yaml": b"scene: caf\xe9\n"},
        "wander experiment: error: c.yaml: not UTF-8 text (byte 0xe9 at offset 10)",
    ),
    (
        CONFIG,
        {"c.yaml": "a: " + "[" * 3000 + "]" * 3000 + "\n"},
        "wander experiment: error: c.yaml: line 1, column 67: nested deeper than 64 levels",
    ),
    (
        CONFIG,
        {"c.yaml": "repeats: " + "9" * 5000 + "\n"},
        "wander experiment: error: c.yaml: line 1, column 10: a number of 5000 characters; "
        "at most 100",
    ),
    (
        CONFIG,
        {"c.yaml": "# " + "x" * (1 << 20) + "\n"},
        "wander experiment: error: c.yaml: larger than 1048576 bytes (the limit)",
    ),
    (CONFIG, {}, "wander experiment: error: config file not found: c.yaml"),
    (CONFIG, {"c.yaml/": ""}, "wander experiment: error: c.yaml: a folder, not a config file"),
    (
        CONFIG,
        {"c.yaml": "window_s: 1e400\n"},
        "wander experiment: error: c.yaml: window_s: input should be a finite number, got '1e400'",
    ),
    # sweep files
    (["sweep", "s.yaml"], {}, "wander sweep: error: sweep file not found: s.yaml"),
    (["sweep", "s.yaml"], {"s.yaml": "size: [0.2\n"}, f"wander sweep: error: s.yaml: {SYNTAX}"),
    (["sweep", "s.yaml"], {"s.yaml": billion_laughs()}, f"wander sweep: error: s.yaml: {ALIAS}"),
    (
        ["sweep", "s.yaml"],
        {"s.yaml": "name: x\nseeds: [-1]\nexperiments: [{experiment: detection}]\n"},
        "wander sweep: error: s.yaml.seeds: must be a non-empty list of integers in "
        "[0, 4294967295], got [-1]",
    ),
    (
        ["sweep", "s.yaml"],
        {
            "s.yaml": "name: x\nseeds: [" + ", ".join(map(str, range(1000))) + "]\n"
            "experiments: [{experiment: detection, grid: {alpha: ["
            + ", ".join(["0.5"] * 200)
            + "]}}]\n"
        },
        "wander sweep: error: s.yaml.experiments[0].grid: 200 grid points x 1000 seeds; "
        "at most 100000 trials in a sweep",
    ),
    (
        ["sweep", "s.yaml"],
        {
            "s.yaml": "name: x\nexperiments:\n- experiment: scanpath\n"
            "  grid: {scenes: [[office], [offce]]}\n"
        },
        "wander sweep: error: s.yaml.experiments[0].grid.scenes[1]: scenes[0]: unknown "
        f"scene 'offce'; available: {SCENES}",
    ),
    # scene files, given as an option and inside a config
    (
        ["run", "--scene", "sc.yaml"],
        {"sc.yaml": "size: [0.2\n"},
        f"wander run: Invalid value for '--scene': sc.yaml: {SYNTAX}",
    ),
    (
        ["run", "--scene", "sc.yaml"],
        {"sc.yaml": billion_laughs()},
        f"wander run: Invalid value for '--scene': sc.yaml: {ALIAS}",
    ),
    (
        ["experiment", "scanpath", "--set", "scenes=[office, sc.yaml]"],
        {"sc.yaml": "size: [0.2\n"},
        f"wander experiment: error: --set: scenes[1]: sc.yaml: {SYNTAX}",
    ),
    # the camera's hinge offset is the PTU's (env.ptu), no longer a scene's
    (
        ["run", "--scene", "sc.yaml"],
        {"sc.yaml": "ptu: {position: [0, 0, 1], camera_forward_m: 0.03}\n"},
        "wander run: Invalid value for '--scene': sc.yaml: ptu.camera_forward_m: the camera's "
        "offset from the hinge is the PTU's, not the scene's: give it in the env's ptu block "
        "(env.ptu.camera_forward_m, or --set env.ptu.camera_forward_m=...), got 0.03",
    ),
    # names, checked when the config is validated
    (
        ["experiment", "scanpath", "--set", "scenes=[offce]"],
        {},
        f"wander experiment: error: --set: scenes[0]: unknown scene 'offce'; available: {SCENES}",
    ),
    (
        ["experiment", "scanpath", "--set", "scenes=[shelf, offce]"],
        {},
        f"wander experiment: error: --set: scenes[1]: unknown scene 'offce'; available: {SCENES}",
    ),
    (
        ["experiment", "event_suppression", "--set", "env.scene=no/such.yaml"],
        {},
        "wander experiment: error: --set: env.scene: scene file not found: no/such.yaml; "
        f"allowed: {SCENES} or a scene .yaml file",
    ),
    (
        ["experiment", "scanpath", "--set", "env.dvs=nosuch"],
        {},
        "wander experiment: error: --set: env.dvs: unknown DVS preset 'nosuch'; "
        "choose one of ['ideal', 'paper', 'speck']",
    ),
    (
        ["experiment", "detection", "--set", "env.frames=fast"],
        {},
        "wander experiment: error: --set: env.frames: expected one of 'keyframes', 'exact', "
        "'panorama', got 'fast'",
    ),
    (
        ["experiment", "saccade_speed", "--set", "ptu_presets=[flir, nosuch]"],
        {},
        "wander experiment: error: --set: ptu_presets[1]: unknown PTU preset 'nosuch'; "
        "expected 'ideal' or 'flir'",
    ),
    (
        ["experiment", "saccade_speed", "--set", "ptu_preset=nosuch"],
        {},
        "wander experiment: error: --set: ptu_preset: expected one of 'ideal', 'flir', got "
        "'nosuch'",
    ),
    (
        ["experiment", "event_suppression", "--set", "agent.soms=nosuch"],
        {},
        "wander experiment: error: --set: agent.soms: soms must be one of ['agent', 'paper', "
        "'speck'] or a parameter block, got 'nosuch'",
    ),
    # ranges
    (
        ["experiment", "detection", "--set", "duration_s=1e400"],
        {},
        "wander experiment: error: --set: duration_s: input should be a finite number, got '1e400'",
    ),
    (
        ["experiment", "scanpath", "--set", "duration_s=7200"],
        {},
        "wander experiment: error: --set: duration_s: "
        "input should be less than or equal to 3600, got 7200",
    ),
    (
        ["experiment", "event_suppression", "--set", f"repeats={10**26}"],
        {},
        "wander experiment: error: --set: repeats: "
        f"input should be less than or equal to 1000, got {10**26}",
    ),
    (
        ["experiment", "scanpath", "--set", "mosaic_step_deg=1e-6"],
        {},
        "wander experiment: error: --set: mosaic_step_deg: "
        "input should be greater than or equal to 0.05, got '1e-6'",
    ),
    (
        ["experiment", "scanpath", "--set", "radius_deg=1e6"],
        {},
        "wander experiment: error: --set: radius_deg: "
        "input should be less than or equal to 180, got '1e6'",
    ),
    (
        ["experiment", "event_suppression", "--set", "agent.soms.kernel_size=100000"],
        {},
        "wander experiment: error: --set: agent.soms.kernel_size: kernel_size must be in "
        "[1, 128], got 100000",
    ),
    (
        ["experiment", "detection", "--set", "agent.soms.kernel_size=100000"],
        {},
        "wander experiment: error: --set: agent.soms.kernel_size: kernel_size must be in "
        "[1, 128], got 100000",
    ),
    (
        ["experiment", "event_suppression", "--set", "repeats=" + "9" * 5000],
        {},
        "wander experiment: error: --set repeats: line 1, column 1: a number of 5000 "
        "characters; at most 100",
    ),
    (
        ["experiment", "event_suppression", "--set", "agent.soms=" + "[" * 3000 + "]" * 3000],
        {},
        "wander experiment: error: --set agent.soms: line 1, column 65: nested deeper than 64 "
        "levels",
    ),
    (
        ["experiment", "event_suppression", "--set", ".".join(["soms"] * 3000) + "=1"],
        {},
        "wander experiment: error: --set: a key of 3000 parts; at most 64",
    ),
    (
        ["experiment", "event_suppression", "--seed", "-1"],
        {},
        "wander experiment: Invalid value for '--seed': must be an integer in "
        "[0, 4294967295], got -1",
    ),
    (
        ["sweep", "s.yaml", "--workers", "100000"],
        {},
        "wander sweep: Invalid value for '--workers': must be an integer in [1, 256], got 100000",
    ),
    (
        ["sweep", "s.yaml", "--timeout", "nan"],
        {},
        "wander sweep: Invalid value for '--timeout': must be a finite number of seconds > 0, "
        "got nan",
    ),
    (
        ["run", "--seconds", "1e308"],
        {},
        "wander run: Invalid value for '--seconds': must be a finite number of seconds in "
        "(0, 86400], got 1e+308",
    ),
    # run folders: an empty --out, --force on the current folder, a sweep's --out on a file
    *(
        (
            [*command, "--out", ""],
            {},
            f"wander {command[0]}: Invalid value for '--out': must name a folder, got ''",
        )
        for command in (
            ["run"],
            ["record"],
            ["demo"],
            ["evaluate"],
            ["rerun", "r"],
            ["experiment", "detection"],
            ["sweep", "s.yaml"],
        )
    ),
    (
        ["benchmark", "suppression", "x.npy", "--out", ""],
        {},
        "wander benchmark suppression: Invalid value for '--out': must name a folder, got ''",
    ),
    *(
        (
            [command, "--out", out, "--force"],
            {"old.txt": "an earlier run"},
            f"wander {command}: Invalid value for '--out': {out!r} is the current folder or "
            "holds it: --force cannot replace it, give another --out",
        )
        for command, out in (("demo", "."), ("run", "."), ("evaluate", ".."), ("record", "."))
    ),
    (
        ["sweep", "s.yaml", "--out", "afile"],
        {"s.yaml": SWEEP, "afile": "x"},
        "wander sweep: Invalid value for '--out': 'afile' exists and is not a folder",
    ),
    (
        ["sweep", "s.yaml", "--out", "afile/x"],
        {"s.yaml": SWEEP, "afile": "x"},
        "wander sweep: Invalid value for '--out': cannot create 'afile/x': Not a directory",
    ),
    (
        ["sweep", "s.yaml", "--backend", "ray", "--address", "bogus"],
        {"s.yaml": SWEEP},
        "wander sweep: Invalid value for '--address': must be auto, HOST:PORT or "
        "ray://HOST:PORT (a port 1 to 65535), got 'bogus'",
    ),
    (
        ["sweep", "s.yaml", "--address", "head:6379"],
        {"s.yaml": SWEEP},
        "wander sweep: Invalid value for '--address': a Ray cluster's address, only with "
        "--backend ray, got --backend local",
    ),
    # seeds, checked while the command line is parsed
    *(
        (
            args,
            {},
            f"wander {name}: Invalid value for '{flag}': must be an integer in "
            f"[0, 4294967295], got {value}",
        )
        for args, name, flag, value in (
            (["evaluate", "--seeds", "-1"], "evaluate", "--seeds", -1),
            (["evaluate", "--seeds", "0," + "9" * 20], "evaluate", "--seeds", "9" * 20),
            (["demo", "--seed", "-1"], "demo", "--seed", -1),
            (["record", "--seed", "-1"], "record", "--seed", -1),
            (["perf", "agent", "--seed", "-1"], "perf agent", "--seed", -1),
            (["perf", "fidelity", "--seeds", "-1"], "perf fidelity", "--seeds", -1),
        )
    ),
    (
        ["demo", "--set", "seed=-1"],
        {},
        "wander demo: error: --set: seed: input should be greater than or equal to 0, got -1",
    ),
    (
        ["perf", "env", "--set", "seed=-1"],
        {},
        "wander perf env: error: --set: seed: input should be greater than or equal to 0, got -1",
    ),
    # comma-separated lists: no empty item, none twice, each checked
    (
        ["evaluate", "--seeds", "9" * 5000],
        {},
        "wander evaluate: Invalid value for '--seeds': a number of 5000 characters; at most 100",
    ),
    (
        ["evaluate", "--seeds", "1,,2"],
        {},
        "wander evaluate: Invalid value for '--seeds': has an empty seed, got '1,,2'",
    ),
    (
        ["evaluate", "--seeds", "1,2,"],
        {},
        "wander evaluate: Invalid value for '--seeds': has an empty seed, got '1,2,'",
    ),
    (
        ["evaluate", "--seeds", "1, 1"],
        {},
        "wander evaluate: Invalid value for '--seeds': seed 1 is given twice, got '1, 1'",
    ),
    (
        ["perf", "env", "--envs", "1,,2"],
        {},
        "wander perf env: Invalid value for '--envs': has an empty env count, got '1,,2'",
    ),
    (
        ["perf", "env", "--envs", "2,2"],
        {},
        "wander perf env: Invalid value for '--envs': env count 2 is given twice, got '2,2'",
    ),
    (
        ["perf", "fidelity", "--scenes", ""],
        {},
        "wander perf fidelity: Invalid value for '--scenes': needs at least one scene, e.g. "
        "office,hand",
    ),
    (
        ["perf", "fidelity", "--scenes", "office,,hand"],
        {},
        "wander perf fidelity: Invalid value for '--scenes': has an empty scene, got "
        "'office,,hand'",
    ),
    (
        ["perf", "fidelity", "--scenes", "office,office"],
        {},
        "wander perf fidelity: Invalid value for '--scenes': scene office is given twice, got "
        "'office,office'",
    ),
    (
        ["perf", "fidelity", "--scenes", "office,nope"],
        {},
        f"wander perf fidelity: Invalid value for '--scenes': unknown scene 'nope'; allowed: "
        f"{SCENES} or a scene .yaml file",
    ),
    (
        ["perf", "fidelity", "--motions", "walk,walk"],
        {},
        "wander perf fidelity: Invalid value for '--motions': motion walk is given twice, got "
        "'walk,walk'",
    ),
    # sizes and counts, bounded before anything is allocated
    (
        ["benchmark", "suppression", "x.npy", "--threads", "100000"],
        {},
        "wander benchmark suppression: Invalid value for '--threads': must be an integer in "
        "[1, 256], got 100000",
    ),
    (
        ["perf", "dvs", "--frames", "1000000000000"],
        {},
        "wander perf dvs: Invalid value for '--frames': must be an integer in [1, 5000], got "
        "1000000000000",
    ),
    (
        ["perf", "dvs", "--repeats", "1000000000"],
        {},
        "wander perf dvs: Invalid value for '--repeats': must be an integer in [1, 100], got "
        "1000000000",
    ),
    (
        ["perf", "env", "--envs", "100000"],
        {},
        "wander perf env: Invalid value for '--envs': must be an integer in [1, 256], got 100000",
    ),
    *(
        (
            ["perf", "fidelity", "--seconds", value],
            {},
            "wander perf fidelity: Invalid value for '--seconds': must be a whole number of "
            f"0.01 s control periods in [0.01, 60] seconds, got {shown}",
        )
        for value, shown in (("1e30", "1e+30"), ("nan", "nan"), ("0.015", "0.015"))
    ),
    (
        ["perf", "fidelity", "--reference-hz", "1e12"],
        {},
        "wander perf fidelity: Invalid value for '--reference-hz': must be a finite number of "
        "Hz in (0, 100000], got 1000000000000.0",
    ),
    (
        ["perf", "fidelity", "--reference-hz", "150"],
        {},
        "wander perf fidelity: Invalid value for '--reference-hz': control_period_s: 0.01 must "
        "be a whole number (>= 1) of render periods (render_rate_hz=150.0)",
    ),
    (
        ["perf", "fidelity", "--reference-supersample", "1000"],
        {},
        "wander perf fidelity: Invalid value for '--reference-supersample': must be an integer "
        "in [1, 8], got 1000",
    ),
    # the DVS demo's config
    *(
        (
            ["demo", *(a for item in sets for a in ("--set", item))],
            {},
            f"wander demo: error: {line}",
        )
        for sets, line in (
            (["width=0"], "--set: width: input should be greater than or equal to 16, got 0"),
            (["width=-5"], "--set: width: input should be greater than or equal to 16, got -5"),
            (
                ["width=100000", "height=100000"],
                "--set: width: input should be less than or equal to 2048, got 100000; height: "
                "input should be less than or equal to 2048, got 100000",
            ),
            (
                ["width=2048", "height=2048"],
                "--set: seconds: 1 s at 1000 Hz of 2048x2048 frames take 12,012 MiB; at most "
                "1,024 MiB",
            ),
            (
                ["frame_rate_hz=1e9"],
                "--set: frame_rate_hz: input should be less than or equal to 1000000, got '1e9'",
            ),
            (
                ["seconds=86400"],
                "--set: seconds: 86400 s at 1000 Hz of 128x128 frames take 4,050,000 MiB; at "
                "most 1,024 MiB",
            ),
            (
                ["frame_rate_hz=1", "panels=1", "panel_ms=1"],
                "--set: seconds: 1 s at 1 Hz is 1 frame(s); the demo needs at least 2",
            ),
            (["panels=0"], "--set: panels: input should be greater than or equal to 1, got 0"),
        )
    ),
    (
        ["demo", "--seconds", "86400"],
        {},
        "wander demo: Invalid value for '--seconds': 86400 s at 1000 Hz of 128x128 frames take "
        "4,050,000 MiB; at most 1,024 MiB",
    ),
    # wander rerun: run.json's keys
    *(
        (
            ["rerun", "r"],
            {"r/": "", "r/run.json": json.dumps(record)},
            f"wander rerun: error: {line}",
        )
        for record, line in RERUN_CASES
    ),
    # wander view: run.rrd must be a recording
    (
        ["view", "v"],
        {"v/": "", "v/run.rrd": ""},
        "wander view: Invalid value for 'RUN_DIR': 'v/run.rrd' is empty: the run wrote no "
        "recording",
    ),
    (
        ["view", "v"],
        {"v/": "", "v/run.rrd": "garbage"},
        "wander view: Invalid value for 'RUN_DIR': 'v/run.rrd' is not a Rerun recording: it "
        "starts with b'gar', not b'RRF'",
    ),
    (
        ["view", "v"],
        {"v/": "", "v/run.rrd/": ""},
        "wander view: Invalid value for 'RUN_DIR': 'v/run.rrd' is not a regular file",
    ),
]


@pytest.mark.parametrize(("args", "files", "line"), CASES)
def test_each_bad_file_or_value_is_one_line_exit_2_and_nothing_written(
    args, files, line, tmp_path, monkeypatch
):
    monkeypatch.chdir(tmp_path)
    for name, content in files.items():
        if name.endswith("/"):
            (tmp_path / name).mkdir()
        elif isinstance(content, bytes):
            (tmp_path / name).write_bytes(content)
        else:
            (tmp_path / name).write_text(content)
    before = sorted(tmp_path.iterdir())
    result = runner.invoke(app, args, prog_name="wander")
    assert (result.exit_code, result.stderr.splitlines(), result.stdout) == (2, [line], "")
    assert sorted(tmp_path.iterdir()) == before  # refused before anything was written


@pytest.mark.parametrize(
    ("args", "limit", "line"),
    [
        (["sweep", "bomb.yaml"], GIB, f"wander sweep: error: bomb.yaml: {ALIAS}"),
        (
            ["run", "--scene", "bomb.yaml"],
            GIB,
            f"wander run: Invalid value for '--scene': bomb.yaml: {ALIAS}",
        ),
        # The experiment's modules (torch, MuJoCo) reserve ~1.3 GB of address space on
        # import, before the file is read: 2 GB of it, and the 1 GB bound on the resident
        # peak (VmHWM).
        (
            ["experiment", "event_suppression", "--config", "bomb.yaml"],
            2 * GIB,
            f"wander experiment: error: bomb.yaml: {ALIAS}",
        ),
    ],
)
def test_the_billion_laughs_is_one_line_within_1_gb(args, limit, line, tmp_path):
    (tmp_path / "bomb.yaml").write_text(billion_laughs())
    rc, err, peak = run_limited(args, tmp_path, limit, timeout_s=600)
    assert (rc, err) == (2, [line])
    assert 0 < peak < GIB
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bomb.yaml"]


def test_a_syntax_error_through_a_real_process_has_no_traceback(tmp_path):
    (tmp_path / "s.yaml").write_text("size: [0.2\n")
    proc = subprocess.run(
        [sys.executable, "-c", "from experiments.cli.main import main; main()", "sweep", "s.yaml"],
        capture_output=True,
        text=True,
        timeout=300,
        cwd=tmp_path,
        env={**os.environ, "PYTHONPATH": str(ROOT)},
    )
    assert "Traceback" not in proc.stderr
    assert (proc.returncode, proc.stderr.splitlines()) == (
        2,
        [f"wander sweep: error: s.yaml: {SYNTAX}"],
    )


class StoppingRunner(CountingRunner):
    """A trial runner that is stopped by SIGINT at its ``stop_at``-th trial."""

    def __init__(self, stop_at: int | None) -> None:
        super().__init__()
        self.stop_at = stop_at

    def __call__(self, spec: TrialSpec) -> dict:
        if len(self.calls) == self.stop_at:
            raise SignalExit(signal.SIGINT)
        return {**super().__call__(spec), "simulated_s": 0.5}


def test_a_resumed_sweep_keeps_no_stale_error_and_records_the_stops(tmp_path):
    sweep = sweep_from_dict(TOY_SWEEP)
    for stop_at in (3, 2):  # stopped twice, as `wander sweep` records a stop
        with pytest.raises(SignalExit) as stop:
            run_sweep(sweep, tmp_path, backend="serial", runner=StoppingRunner(stop_at))
        RunFolder(tmp_path).record_failure(stop.value)
        assert json.loads((tmp_path / "metrics.json").read_text())["signal"] == "SIGINT"
    res = run_sweep(sweep, tmp_path, backend="serial", runner=StoppingRunner(None))
    assert (res.ran, res.skipped) == (len(res.rows) - 5, 5)
    assert not (tmp_path / "metrics.json").exists()  # the finished folder: no stale error
    stop = {"error": "SignalExit: stopped by SIGINT (signal 2)", "signal": "SIGINT"}
    assert json.loads((tmp_path / "run.json").read_text()) == {"stops": [stop, stop]}
    record = json.loads((tmp_path / "sweep.json").read_text())
    assert res.real_time_factor is not None and res.real_time_factor > 0
    assert record["real_time_factor"] == res.real_time_factor
    assert (record["ran"], record["skipped"]) == (res.ran, res.skipped)


def test_a_sweep_whose_trials_simulate_no_time_has_no_real_time_factor(tmp_path):
    res = run_sweep(sweep_from_dict(TOY_SWEEP), tmp_path, backend="serial", runner=CountingRunner())
    assert res.real_time_factor is None
    assert json.loads((tmp_path / "sweep.json").read_text())["real_time_factor"] is None


def test_experiment_and_sweep_print_the_real_time_factor(tmp_path, monkeypatch):
    """Trials that report ``simulated_s`` (here 0.5 s each, faked): both commands end
    with the factor, the one run.json / sweep.json records."""
    module = importlib.import_module("experiments.paper.event_suppression")

    def fake(config, spec):
        return {"simulated_s": 0.5}

    monkeypatch.setattr(
        module, "EXPERIMENT", replace(module.EXPERIMENT, run_trial=fake, plot=None, compare=None)
    )
    monkeypatch.chdir(tmp_path)
    args = ["experiment", "event_suppression", "--set", "repeats=2", "--out", "e"]
    res = runner.invoke(app, args, prog_name="wander")
    assert res.exit_code == 0, res.output
    rtf = json.loads((tmp_path / "e" / "run.json").read_text())["timing"]["real_time_factor"]
    assert rtf > 0
    line = f"real-time factor: {rtf:.3g} (simulated seconds per wall second)"
    assert res.stdout.splitlines()[-1] == line
    (tmp_path / "s.yaml").write_text(
        "name: s\nexperiments: [{experiment: event_suppression, set: {repeats: 2}}]\n"
    )
    res = runner.invoke(app, ["sweep", "s.yaml", "--backend", "serial", "--out", "s"])
    assert res.exit_code == 0, res.output
    rtf = json.loads((tmp_path / "s" / "sweep.json").read_text())["real_time_factor"]
    line = f"real-time factor: {rtf:.3g} (simulated seconds per wall second)"
    assert rtf > 0 and res.stdout.splitlines()[-1] == line
