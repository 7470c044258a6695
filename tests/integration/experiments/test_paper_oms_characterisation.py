"""oms_characterisation: firing statistics, the trial grid, and the paper's three findings."""

from __future__ import annotations

import math

import numpy as np
import pytest

from experiments.paper.oms_characterisation import (
    EXPERIMENT,
    OMSCharacterisationConfig,
    compare,
    grating_scene,
    grid,
    isi_stats,
    mfr_stats,
)
from experiments.studies.framework import ConfigError, make_trials, resolve_config, run_spec


def test_mfr_is_spikes_per_second_over_all_neurons():
    assert mfr_stats(np.array([0, 2, 4]), 2.0) == (1.0, pytest.approx(math.sqrt(2 / 3)))
    assert all(math.isnan(v) for v in mfr_stats(np.array([]), 1.0))


def test_isi_is_the_mean_gap_of_neurons_with_two_or_more_spikes():
    s = np.zeros((10, 4), np.int8)
    s[[0, 2, 4, 6], 0] = 1  # gaps 2, 2, 2 steps
    s[[1, 9], 1] = 2  # one gap of 8 steps (two polarities in one step count as one step)
    s[5, 2] = 1  # a single spike: no ISI
    assert isi_stats(s, 0.01) == (pytest.approx(0.05), pytest.approx(0.03), 2)
    assert isi_stats(np.zeros((3, 2)), 0.01)[2] == 0


def test_grid_has_the_papers_groups_in_order():
    rows = grid(OMSCharacterisationConfig())
    groups = [r["group"] for r in rows]
    assert groups == ["mode"] * 3 + ["frequency"] * 6 + ["speed"] * 7 + ["kernel"] * 8
    assert [r["condition"] for r in rows[:3]] == ["eye+object", "eye-only", "object-only"]
    speed = [r for r in rows if r["group"] == "speed"]
    assert all(r["background_deg_s"] >= r["object_deg_s"] for r in speed)
    assert all(r["mode"] == "eye+object" for r in rows[3:])
    kern = [(r["sigma_c"], r["sigma_s"], r["kernel_size"]) for r in rows if r["group"] == "kernel"]
    assert kern[0] == (1.0, 4.0, 8) and kern[-1] == (8.0, 16.0, 32)
    assert rows[0]["sigma_c"] == 1.0 and rows[0]["kernel_size"] == 8


def test_grating_scene_sets_the_stimulus_and_keeps_the_rest():
    data = grating_scene("eye-only", 0.1, 0.2, 5.0, 7.0)
    g = data["gratings"]
    assert (g["mode"], g["background_cycles_per_deg"], g["object_cycles_per_deg"]) == (
        "eye-only",
        0.1,
        0.2,
    )
    assert (g["background_speed_deg_s"], g["object_speed_deg_s"], g["object_size_deg"]) == (
        5.0,
        7.0,
        40.0,
    )
    assert data["camera"] == {"width": 128, "height": 128}


def test_compare_states_each_modes_finding_in_the_papers_order():
    """One comparison per mode present, eye+object, eye-only, object-only (whatever the
    rows' order), with that mode's numbers; an absent mode gives none."""
    base = {
        "group": "mode",
        "object_kept_pct": 80.1,
        "background_kept_pct": 1.5,
        "oms_precision": 0.912,
        "suppressed_pct": 91.25,
        "mfr_mean_hz": 3.3,
        "isi_mean_ms": 120.4,
    }
    rows = [{**base, "condition": c} for c in ("object-only", "eye-only", "eye+object")]
    got = [(c.result, c.paper, c.ours) for c in compare(OMSCharacterisationConfig(), rows)]
    assert got == [
        (
            "eye+object: object response",
            "robust response to the object moving against the background",
            "object events kept 80.1 %, background kept 1.5 %; OMS precision 0.91",
        ),
        (
            "eye-only: background suppressed",
            "most background activity suppressed; higher MFR and ISI than the others",
            "91.2 % of events suppressed; MFR 3.3 Hz, ISI 120 ms",
        ),
        (
            "object-only: object response",
            "robust response",
            "object events kept 80.1 %; OMS precision 0.91",
        ),
    ]
    assert [c.result for c in compare(OMSCharacterisationConfig(), rows[1:2])] == [
        "eye-only: background suppressed"
    ]


def test_config_refuses_a_bad_mode_group_or_kernel():
    with pytest.raises(ValueError, match="modes must be among"):
        OMSCharacterisationConfig(modes=("eye",))
    with pytest.raises(ValueError, match="groups must be among"):
        OMSCharacterisationConfig(groups=("sizes",))
    with pytest.raises(ValueError, match=r"kernel_size must be in \[1, 128\], got 0"):
        OMSCharacterisationConfig(kernels=((1.0, 4.0, 0),))


@pytest.mark.parametrize(
    ("item", "message"),
    [
        ("groups=[]", "groups: must list at least one value, got []"),
        ("modes=[]", "modes: must list at least one value, got []"),
        ("speed_pairs=[]", "speed_pairs: must list at least one value, got []"),
        (
            "groups=[mode, kernel, mode]",
            "groups: must list each value once ('mode' twice), got ['mode', 'kernel', 'mode']",
        ),
        (
            "frequency_pairs=[[0.1, 0.2], [0.1, 0.2]]",
            "frequency_pairs: must list each value once ((0.1, 0.2) twice), got "
            "[(0.1, 0.2), (0.1, 0.2)]",
        ),
        (
            "frequency_pairs=[[0.1, 0.2], [0, 1]]",
            "frequency_pairs[1]: (background, object) cycles/deg must be > 0, got [0.0, 1.0]",
        ),
        (
            "frequency_pairs=[[0.1, -0.2]]",
            "frequency_pairs[0]: (background, object) cycles/deg must be > 0, got [0.1, -0.2]",
        ),
        ("object_cycles_per_deg=0", "object_cycles_per_deg: must be > 0 (cycles/deg), got 0.0"),
    ],
)
def test_config_refuses_empty_or_repeated_lists_and_frequencies_that_are_not_positive(
    item, message
):
    """Each is one line when the config is validated, before a trial writes its scene."""
    with pytest.raises(ConfigError) as err:
        resolve_config(EXPERIMENT, sets=[item])
    assert str(err.value) == f"--set: {message}"


@pytest.mark.slow
def test_the_papers_findings_at_alpha_one_half():
    """0.3 s of each mode and one background-faster case (alpha 0.5: at the paper's 0.8
    the relative threshold keeps almost nothing, see the README)."""
    cfg = resolve_config(
        EXPERIMENT,
        sets=[
            "duration_s=0.3",
            "agent.soms.alpha=0.5",
            "groups=[mode, speed]",
            "speed_pairs=[[60, 30]]",
        ],
    )
    rows = {r["condition"]: r for r in map(run_spec, make_trials(EXPERIMENT, cfg, 0))}
    both, eye, obj, fast = (
        rows["eye+object"],
        rows["eye-only"],
        rows["object-only"],
        rows["v 60/30"],
    )
    # eye+object: strong response to the object, the background suppressed
    assert both["object_kept_pct"] >= 20 and both["background_kept_pct"] <= 2
    assert both["oms_precision"] >= 0.9
    # eye-only: most (background) events suppressed
    assert eye["suppressed_pct"] >= 70
    # object-only: strong response, on the object
    assert obj["object_kept_pct"] >= 20 and obj["oms_precision"] >= 0.9
    # background faster than the object: the OMS map is on the background instead
    assert fast["object_kept_pct"] < fast["background_kept_pct"] and fast["oms_precision"] < 0.1
    assert all(r["active_neurons"] > 0 and r["mfr_mean_hz"] > 0 for r in rows.values())
