"""The events the sOMS keeps and the fraction it suppresses: one rule for the agent, the
studies and the benchmark (numpy only: no torch).

The sOMS output is one map per polarity (channel 0 OFF, 1 ON, as
:func:`wander_env.events.to_frame` counts events): an event is kept where the map of its
own polarity fired at its pixel, so an ON event at a pixel where only the OFF map fired is
suppressed. The fraction suppressed is ``1 − kept / in`` (the paper's 85.16 %), NaN when
no event came in.

Examples:
    >>> counts = np.zeros((2, 1, 2), np.float32); counts[1, 0, :] = (3, 2)
    >>> oms = np.zeros((2, 1, 2), np.float32); oms[0, 0, 0] = oms[1, 0, 1] = 1
    >>> kept_events(counts, oms).tolist()  # the ON map fired at pixel 1 only
    [[[0.0, 0.0]], [[0.0, 2.0]]]
    >>> suppressed_fraction(5, 2), suppressed_fraction(0, 0)
    (0.6, nan)
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["kept_events", "suppressed_fraction"]


def kept_events(counts: np.ndarray, oms: np.ndarray) -> np.ndarray:
    """The event counts ``(2, H, W)`` that pass the sOMS: each polarity's counts where
    that polarity's OMS map ``(2, H, W)`` (0/1, or bool) fired."""
    return np.asarray(counts) * (np.asarray(oms) > 0)


def suppressed_fraction(events_in: float, events_kept: float) -> float:
    """``1 − events_kept / events_in``: the fraction of the events the sOMS removed; NaN
    when none came in."""
    return 1.0 - events_kept / events_in if events_in else math.nan
