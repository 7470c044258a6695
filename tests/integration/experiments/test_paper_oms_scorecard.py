"""The stimulus family, its scoring and the sOMS scorecard experiment."""

from __future__ import annotations

import math
from collections import Counter

import numpy as np
import pytest
import torch

from agents.soms import SOMSParams
from experiments.paper.oms_family import family_claims, measure
from experiments.paper.oms_scorecard import OMSScorecardConfig, variants
from experiments.paper.oms_stimuli import (
    Stimulus,
    family,
    frames,
    object_mask,
    prediction,
    render,
    split,
)
from experiments.studies.framework import (
    ConfigError,
    get_experiment,
    resolve_config,
    run_experiment,
)


def test_family_size_labels_and_halves():
    fam = family()
    assert len(fam) == 672 >= 100
    labels = Counter(prediction(s) for s in fam)
    assert labels == {"respond": 288, "suppress": 96, "fail": 288}
    train, test = split(fam)
    assert len(train) == len(test) == 336
    assert {s.seed % 2 for s in train} == {0} and {s.seed % 2 for s in test} == {1}

    def cell(s: Stimulus) -> tuple:
        return (s.texture, s.object, s.period_px, s.motion, s.preset)

    assert {cell(s) for s in train} == {cell(s) for s in test}  # every cell in both halves
    assert len({cell(s) for s in fam}) == 336
    assert {s.period_px for s in fam} == {8, 16, 32}


def test_patch_object_is_invisible_at_rest_and_window_is_not():
    patch = Stimulus("noise", "patch", 16, "ratio-2", "ideal", seed=4, duration_s=0.01)
    window = Stimulus("noise", "window", 16, "ratio-2", "ideal", seed=4, duration_s=0.01)
    fp, fw = frames(patch), frames(window)
    assert fp.shape == (11, 128, 128)
    mask = object_mask(patch)
    assert mask.sum() == 1264  # disc of radius 20 px about the centre
    assert np.array_equal(fp[0][~mask], fw[0][~mask])  # same background
    assert not np.array_equal(fp[0][mask], fw[0][mask])  # own texture in the window
    # the patch at t = 0 is the background's own texture: the first frame is seamless
    ref = Stimulus("noise", "patch", 16, "eye-only", "ideal", seed=4, duration_s=0.01)
    assert np.array_equal(frames(ref)[0], fp[0])


@pytest.mark.parametrize("preset", ["ideal"])
def test_nothing_moving_emits_nothing(preset):
    s = Stimulus("discs", "window", 16, "still", preset, seed=2, duration_s=0.05)
    rec = render(s)
    assert rec.counts.shape == (5, 2, 128, 128) and rec.events == 0
    for m in measure(s, variants()).values():
        assert (m.events_in, m.kept, m.object_in, m.object_kept) == (0, 0, 0, 0)


def test_eye_only_grating_suppression_bounds():
    """A full-field sine grating (period 16 px) drifting at 30 px/s for 0.1 s, ideal DVS,
    10 ms bins: the agent's sOMS suppresses ≥ 99.5 % of ~55.5 k events; the
    paper-literal one (min-max, α 0.80) only 70–75 %."""
    torch.set_num_threads(1)
    s = Stimulus("sine", "patch", 16, "eye-only", "ideal", seed=1, speed_px_s=30.0, duration_s=0.1)
    m = measure(s, variants())
    assert m["paper"].events_in == m["agent"].events_in
    assert 54_000 <= m["agent"].events_in <= 57_000
    assert 0.995 <= m["agent"].suppressed <= 1.0
    assert 0.70 <= m["paper"].suppressed <= 0.75


def test_object_only_is_kept_by_the_agent_sOMS():
    s = Stimulus(
        "sine", "window", 16, "object-only", "ideal", seed=1, speed_px_s=30.0, duration_s=0.1
    )
    m = measure(s, variants())
    agent = m["agent"]
    assert agent.events_in == agent.object_in > 4000  # only the window moves
    # the peak-clipped norm keeps the window's events within α of its peak: 2685 of 4381
    # (the former divisor 2.5 × the 90th percentile kept ≥ 85 %)
    assert agent.precision == 1.0 and 0.60 <= agent.object_kept_share <= 0.63
    assert m["paper"].object_kept_share <= 0.3


def test_family_claims_arithmetic():
    from experiments.paper.oms_family import Measure

    eo = Stimulus("sine", "patch", 16, "eye-only", "ideal", seed=0)
    oo = Stimulus("sine", "patch", 16, "object-only", "ideal", seed=0)
    items = [
        (eo, Measure(100, 4, 10, 0)),
        (eo, Measure(100, 14, 10, 0)),
        (oo, Measure(50, 20, 50, 20)),
    ]
    c = family_claims(items)
    assert c["eye-only"]["suppressed"] == pytest.approx(0.91) and c["eye-only"]["pass"]
    assert c["eye-only"]["stimuli_passing"] == pytest.approx(0.5)
    assert c["object-only"]["precision"] == 1.0
    assert c["object-only"]["object_kept"] == pytest.approx(0.4) and c["object-only"]["pass"]
    assert c["eye+object"]["n"] == 0 and not c["eye+object"]["pass"]


def test_a_stimulus_that_keeps_nothing_has_no_precision():
    """Nothing kept: the precision is NaN (not 0), left out of the group's mean precision;
    the stimulus still fails (none of the object's events kept), and a group whose
    precision is undefined throughout fails its bar."""
    from experiments.paper.oms_family import Measure

    oo = Stimulus("sine", "patch", 16, "object-only", "ideal", seed=0)
    assert math.isnan(Measure(10, 0, 5, 0).precision)
    c = family_claims([(oo, Measure(50, 20, 50, 20)), (oo, Measure(50, 0, 50, 0))])
    assert c["object-only"]["precision"] == 1.0  # the mean of the stimuli with a precision
    assert c["object-only"]["object_kept"] == 0.2 and c["object-only"]["stimuli_passing"] == 0.5
    c = family_claims([(oo, Measure(50, 0, 50, 0))])
    assert math.isnan(c["object-only"]["precision"]) and not c["object-only"]["pass"]


def test_oms_maps_are_each_variants_own_soms_step_bit_for_bit():
    """The family steps the variants sharing a LIF stage once and pools once per pooling:
    every variant's kept events still equal its own ``SOMS.step``'s, exactly, on random
    maps (where a re-implemented quantile differs from the sOMS's in the last bits)."""
    from dataclasses import replace

    from agents.attention import AGENT_SOMS
    from agents.soms import SOMS
    from agents.suppression import kept_events
    from experiments.paper.oms_family import oms_maps

    torch.set_num_threads(1)
    rng = np.random.default_rng(7)
    rate = np.full((8, 2, 64, 64), 0.2)  # sparse noise and a dense patch moving 2 px a bin
    for t in range(8):
        rate[t, :, 20:36, 10 + 2 * t : 26 + 2 * t] = 3.0
    counts = rng.poisson(rate).astype(np.float32)
    vs = {
        "paper": SOMSParams(conv="separable"),
        "agent": AGENT_SOMS,
        "plain": replace(AGENT_SOMS, peak_ratio=None, gain=2.5),
        "q95": replace(AGENT_SOMS, quantile=0.95, alpha=0.6),
        "pool4": replace(AGENT_SOMS, pool_sigma=4.0),
        "direct": replace(AGENT_SOMS, conv="direct"),
        "direct-paper": SOMSParams(),
    }
    own = {k: SOMS(replace(p, dt=0.01)) for k, p in vs.items()}
    kept_total = dict.fromkeys(vs, 0.0)
    for c, maps in zip(counts, oms_maps(counts, 0.01, vs), strict=True):
        assert maps.keys() == vs.keys()
        for k, oms in maps.items():
            expected = kept_events(c, own[k].step(c).oms.numpy())
            assert np.array_equal(kept_events(c, oms), expected), k
            kept_total[k] += float(expected.sum())
    assert all(v > 0 for v in kept_total.values()), kept_total


def test_variants_are_paper_literal_and_agent_default():
    from agents.attention import AgentParams

    v = variants()
    assert v["paper"].norm == "minmax" and v["paper"].alpha == 0.80
    assert v["agent"] == AgentParams().resolved().soms
    assert SOMSParams().norm == "minmax"


SMALL = [
    "parts=[family-test, family-train]",
    "textures=[square]",
    "objects=[patch]",
    "periods=[16]",
    "motions=[eye-only, object-only]",
    "presets=[ideal]",
    "duration_s=0.05",
]


@pytest.mark.slow
def test_same_seed_gives_the_same_scorecard(tmp_path):
    exp = get_experiment("oms_scorecard")
    cfg = resolve_config(exp, sets=SMALL)
    rows_a, _ = run_experiment("oms_scorecard", cfg, 3, tmp_path / "a")
    run_experiment("oms_scorecard", cfg, 3, tmp_path / "b")
    a = (tmp_path / "a" / "results.csv").read_bytes()
    assert a == (tmp_path / "b" / "results.csv").read_bytes()
    assert [r["part"] for r in rows_a] == ["family-test", "family-train"]
    assert rows_a[0]["stimuli"] == 2
    summary = (tmp_path / "a" / "summary.md").read_text()
    assert "eye-only, family held-out (odd seeds), 2 stimuli" in summary
    rows_c, _ = run_experiment("oms_scorecard", cfg, 4, tmp_path / "c")
    # another seed draws other stimuli (directions, speeds, textures)
    assert rows_c[0]["paper:eye-only:suppressed"] != rows_a[0]["paper:eye-only:suppressed"]


def test_scorecard_config_is_validated():
    exp = get_experiment("oms_scorecard")
    with pytest.raises(ConfigError, match="parts"):
        resolve_config(exp, sets=["parts=[nonsense]"])
    with pytest.raises(ConfigError, match="replicates"):
        resolve_config(exp, sets=["replicates=3"])
    assert OMSScorecardConfig().replicates == 2


def test_hand_line_passes_only_when_every_hand_bar_holds():
    from experiments.paper.oms_scorecard import scorecard

    cfg = OMSScorecardConfig(parts=("hand",))
    row = {"part": "hand"}
    for k, hit in (("paper", 1.0), ("agent", 0.999)):
        row |= {
            f"{k}:hand:hit": hit,
            f"{k}:hand:suppressed": 0.823,
            f"{k}:hand:shake_suppressed": 0.995,
            f"{k}:hand:hand_kept": 0.62 if k == "agent" else 0.17,
            f"{k}:hand:hit_steps": 804,
        }
    ((claim, bar, cells),) = scorecard(cfg, [row])
    assert claim == "hand scene (suppression protocol, 4 phases)"
    assert bar.startswith("hand hit ≥ 90 % of the hand-moving steps, ≥ 75 % suppressed")
    assert cells["agent"] == (
        "**pass** hand hit in 99.9 % of 804 steps; 82.3 % suppressed (paper 85.16 %); "
        "shake-only 99.5 %; hand's events kept 62.0 %"
    )
    assert cells["paper"].startswith("FAIL hand hit in 100.0 %")  # keeps 17 % of the hand


def _quality(path, soms: dict | None, accuracy: float | None = 0.9) -> str:
    """A ``wander evaluate`` quality.json whose run had the agent sOMS ``soms``."""
    import json

    pooled = {"detection_accuracy": accuracy, "detection_ci_low": 0.8}
    pooled |= {"detection_ci_high": 0.95, "scored": 40}
    run = {} if soms is None else {"agent": {"soms": soms}}
    data = {"config": {"run": run}, "rows": [{"seed": 0}, {"seed": 1}], "pooled": pooled}
    path.write_text(json.dumps(data))
    return str(path)


def test_office_results_must_be_runs_of_the_agent_block(tmp_path):
    """The office part reads ``wander evaluate`` results of the config's ``agent.soms``
    (its step aside): another agent's, a file of another shape, or one that is not a
    regular file is refused, naming the key and the file."""
    from dataclasses import replace

    from agents.attention import AGENT_SOMS
    from experiments.jobs.evaluate_agent import read_quality
    from experiments.paper.oms_scorecard import run_trial, scorecard
    from experiments.studies.framework import TrialSpec
    from wander_env.config import to_plain

    plain = to_plain(replace(AGENT_SOMS, dt=0.02))  # the step may differ
    good = _quality(tmp_path / "good.json", plain, accuracy=0.925)
    cfg = resolve_config(get_experiment("oms_scorecard"), sets=["parts=[office]"])
    cfg = replace(cfg, office_results=(good,))
    row = run_trial(cfg, TrialSpec("oms_scorecard", {}, {"part": "office"}, 0))
    assert row["agent:office0:accuracy"] == 0.925 and row["agent:office0:seeds"] == "0,1"
    assert row["agent:office0:scored"] == 40

    other = resolve_config(get_experiment("oms_scorecard"), sets=["agent.soms.alpha=0.7"])
    with pytest.raises(ValueError) as e:
        read_quality(good, "office_results", other.agent.soms)
    assert str(e.value) == (
        f"office_results: {good}: its run's agent.soms is not this scorecard's (agent.soms)"
    )
    old = _quality(tmp_path / "old.json", None)
    with pytest.raises(ValueError, match=r"^office_results: .*old\.json: its run records no "):
        read_quality(old, "office_results", AGENT_SOMS)
    (tmp_path / "list.json").write_text("[1, 2]")
    with pytest.raises(ValueError) as e:
        read_quality(str(tmp_path / "list.json"), "office_results_paper")
    assert str(e.value).endswith("list.json: not the quality.json of a wander evaluate run")
    with pytest.raises(ValueError) as e:
        read_quality("/dev/zero", "office_results")
    assert str(e.value) == (
        "office_results: /dev/zero: not a regular file (a character device): refused"
    )
    # a run with no scored decision: its accuracy null, read as NaN, fails the bar
    none = _quality(tmp_path / "none.json", plain, accuracy=None)
    row = run_trial(
        replace(cfg, office_results=(none,)), TrialSpec("oms_scorecard", {}, {"part": "office"}, 0)
    )
    assert math.isnan(row["agent:office0:accuracy"])
    ((_, bar, cells),) = scorecard(cfg, [{"part": "office", **row}])
    assert bar == "≥ 90 %" and cells["agent"].startswith("FAIL seeds 0,1: — (")


@pytest.mark.parametrize(
    ("item", "message"),
    [
        ("periods=[0]", "periods: must be in [2, 256] px (the texture tile), got [0]"),
        (
            "duration_s=60",
            "duration_s: must be <= 10 s (a stimulus's frames are held in memory, about 65 MB a "
            "second), got 60.0",
        ),
        ("periods=[8, 1000]", "periods: must be in [2, 256] px (the texture tile), got [8, 1000]"),
        ("parts=[]", "parts: must list at least one value, got []"),
        ("textures=[]", "textures: must list at least one value, got []"),
        ("objects=[]", "objects: must list at least one value, got []"),
        ("motions=[]", "motions: must list at least one value, got []"),
        ("presets=[]", "presets: must list at least one value, got []"),
        ("real_bins_ms=[]", "real_bins_ms: must list at least one value, got []"),
        (
            "parts=[real, hand, real]",
            "parts: must list each value once ('real' twice), got ['real', 'hand', 'real']",
        ),
        ("periods=[8, 8]", "periods: must list each value once (8 twice), got [8, 8]"),
        (
            "office_results=[a.json, a.json]",
            "office_results: must list each value once ('a.json' twice), got ['a.json', 'a.json']",
        ),
    ],
)
def test_config_refuses_empty_repeated_or_impossible_lists(item, message):
    with pytest.raises(ConfigError) as err:
        resolve_config(get_experiment("oms_scorecard"), sets=[item])
    assert str(err.value) == f"--set: {message}"


def test_the_files_the_parts_read_are_checked_before_any_trial_runs(tmp_path):
    """The real clips (with ``real`` in parts) and every office_results file: one line
    naming the key and the file when the trials are made (make_trials, before the result
    folder), not in a trial; a config without them, as a stored one, still validates."""
    from experiments.paper.oms_scorecard import REAL_CLIPS
    from experiments.studies.framework import make_trials

    exp = get_experiment("oms_scorecard")
    cases = [
        (
            ["parts=[real]", f"real_dir={tmp_path}"],
            f"real_dir: {tmp_path}/poster_6dof_events_txyp.npy not found (the real part reads "
            f"it: set real_dir, or leave real out of parts), got '{tmp_path}'",
        ),
        (
            ["parts=[office]", f"office_results=[{tmp_path}/no.json]"],
            f"office_results[0]: {tmp_path}/no.json: no such file",
        ),
        (
            ["parts=[hand]", f"office_results_paper=[{tmp_path}]"],
            f"office_results_paper[0]: {tmp_path}: not a regular file (a folder): refused",
        ),
        (
            ["parts=[hand]", f"reuse=[{tmp_path}]"],
            f"reuse[0]: {tmp_path} holds no config.json: not an oms_scorecard result folder",
        ),
    ]
    for sets, message in cases:
        cfg = resolve_config(exp, sets=sets)  # the config itself is valid
        with pytest.raises(ConfigError) as err:
            make_trials(exp, cfg, 0)
        assert str(err.value) == message
    other = _quality(tmp_path / "other.json", {"alpha": 0.1})
    cfg = resolve_config(exp, sets=["parts=[office]", f"office_results=[{other}]"])
    with pytest.raises(ConfigError) as err:
        make_trials(exp, cfg, 0)
    assert str(err.value) == (
        f"office_results[0]: {other}: its run's agent.soms is not this scorecard's (agent.soms)"
    )
    for clip in REAL_CLIPS:
        (tmp_path / f"{clip}_events_txyp.npy").write_bytes(b"")
    cfg = resolve_config(exp, sets=["parts=[real]", f"real_dir={tmp_path}"])
    assert [s.params for s in make_trials(exp, cfg, 0)] == [{"part": "real"}]


def test_a_part_is_reused_only_from_a_run_of_the_same_config_and_seed(tmp_path):
    """``reuse`` copies a part's row from an earlier scorecard of the same family, bins,
    hand settings and agent block (``agent.soms`` is the second column), and refuses one
    run with another."""
    import json
    from dataclasses import replace

    from experiments.paper.oms_scorecard import reused_row
    from experiments.runs.tables import write_csv
    from wander_env.config import to_plain

    exp = get_experiment("oms_scorecard")
    cfg = resolve_config(exp, sets=SMALL)
    old = tmp_path / "old"
    old.mkdir()
    (old / "config.json").write_text(json.dumps({"experiment": exp.name, **to_plain(cfg)}))
    (old / "run.json").write_text(json.dumps({"seed": 3}))
    ids = {"trial": 0, "trial_id": "t0", "repeat": 0, "seed": 3}
    write_csv([{**ids, "part": "real", "agent:real:x": 0.25}], old / "results.csv")
    mine = replace(cfg, reuse=(str(old),))
    assert reused_row(mine, "real", 3) == {"agent:real:x": 0.25, "reused_from": str(old)}
    assert reused_row(mine, "hand", 3) is None
    with pytest.raises(ValueError, match=r"has seed 3, this run 4$"):
        reused_row(mine, "real", 4)
    other = resolve_config(exp, sets=[*SMALL, "agent.soms.alpha=0.7"])
    with pytest.raises(ValueError, match=r"was run with another config \(agent\)$"):
        reused_row(replace(other, reuse=(str(old),)), "real", 3)
