"""The paper's experiments by name, each the module ``experiments/paper/<name>.py`` holding
its ``EXPERIMENT`` (:func:`experiments.studies.framework.get_experiment` loads it). A
module of its own, with no imports, so that the command line lists the names without
loading the experiments' configs (and the simulator behind them).
"""

from __future__ import annotations

__all__ = ["EXPERIMENT_NAMES"]

EXPERIMENT_NAMES: tuple[str, ...] = (
    "oms_characterisation",
    "event_suppression",
    "detection",
    "sac_accuracy",
    "scanpath",
    "saccade_speed",
    "oms_scorecard",
)
