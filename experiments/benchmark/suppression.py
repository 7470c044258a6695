"""Event suppression: the fraction of events the OMS stage removes.

:func:`event_suppression` measures it on a recording with no independently moving object
(e.g. ``uzh_poster_egomotion``), streamed window by window through the same
:class:`~experiments.benchmark.protocol.BenchmarkModel` as the detection benchmark, and
:func:`render_suppression_markdown` puts it beside the paper's Table
(:data:`PAPER_SUPPRESSION`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType

import numpy as np

from agents.suppression import kept_events, suppressed_fraction
from experiments.analysis.stats import mean_std
from experiments.benchmark.protocol import BenchmarkModel, ProgressEvent, ProgressFn, check_maps
from wander_env.events import SensorSize, check_sorted, time_window, to_frame

# Event suppression, the paper's Table: 10 trials, counts per 2 ms window.
PAPER_SUPPRESSION: Mapping[str, float] = MappingProxyType(
    {
        "events_in_mean": 14747.03,
        "events_in_std": 2029.17,
        "events_out_mean": 2189.15,
        "events_out_std": 385.57,
        "suppressed_pct": 85.16,
    }
)


@dataclass(frozen=True, eq=False)
class SuppressionResult:
    """Events into the OMS stage and the events it kept, per window."""

    window_us: int
    events_in: np.ndarray
    events_out: np.ndarray

    @property
    def n_windows(self) -> int:
        return len(self.events_in)

    @property
    def total_in(self) -> int:
        return int(np.sum(self.events_in))

    @property
    def total_out(self) -> int:
        return int(np.sum(self.events_out))

    @property
    def fraction_suppressed(self) -> float:
        """``1 − out / in`` over the whole recording (the paper's 85.16 %)."""
        return suppressed_fraction(self.total_in, self.total_out)

    def per_window(self, ddof: int = 0) -> dict[str, float]:
        """Mean ± std of events in / out per window (the paper's Table layout)."""
        mi, si = mean_std(self.events_in.astype(float), ddof)
        mo, so = mean_std(self.events_out.astype(float), ddof)
        return {
            "events_in_mean": mi,
            "events_in_std": si,
            "events_out_mean": mo,
            "events_out_std": so,
        }


def event_suppression(
    events: np.ndarray,
    sensor_size: SensorSize,
    model: BenchmarkModel,
    window_us: int = 2000,
    progress: ProgressFn | None = None,
    name: str = "recording",
) -> SuppressionResult:
    """Stream a recording in ``window_us`` steps; count events in and kept out.

    Meant for a recording with no independently moving object, where every event the
    OMS stage keeps is a false positive. Windows tile ``[t_first, t_last]``; each
    window's events are counted as *out* when the OMS map of their polarity, which the
    model returns for that window, fired at their pixel (:func:`agents.suppression.
    kept_events`, the agent's and the studies' rule).
    """
    if window_us <= 0:
        raise ValueError(f"window_us must be > 0, got {window_us}")
    check_sorted(events, name)
    hw = (int(sensor_size[1]), int(sensor_size[0]))
    model.reset()
    if len(events) == 0:
        return SuppressionResult(window_us, np.zeros(0, np.int64), np.zeros(0, np.int64))
    t0, t_last = int(events["t"][0]), int(events["t"][-1])
    n = (t_last - t0) // window_us + 1
    ins = np.zeros(n, np.int64)
    outs = np.zeros(n, np.int64)
    for k in range(n):
        a = t0 + k * window_us
        wev = time_window(events, a, a + window_us)
        counts = to_frame(wev, sensor_size)
        maps = check_maps(model.process(counts, window_us / 1e6), hw, f"{name} window {k}")
        ins[k] = len(wev)
        outs[k] = int(kept_events(counts, maps.oms_polarity).sum())
        if progress is not None:
            progress(ProgressEvent(name, "", 0, 1, k, n))
    return SuppressionResult(window_us, ins, outs)


def render_suppression_markdown(result: SuppressionResult, name: str, ddof: int = 0) -> str:
    """A Markdown table of :func:`event_suppression` beside the paper's Table."""
    pw = result.per_window(ddof)
    ref = PAPER_SUPPRESSION
    return "\n".join(
        [
            f"# Event suppression: {name}",
            "",
            f"Counts per {result.window_us / 1000:g} ms window, mean ± std over "
            f"{result.n_windows} windows (ddof={ddof}); suppressed = 1 − out/in over the "
            "recording.",
            "",
            "| | events in | OMS events out | suppressed |",
            "|---|---:|---:|---:|",
            f"| ours | {pw['events_in_mean']:.2f} ± {pw['events_in_std']:.2f} "
            f"| {pw['events_out_mean']:.2f} ± {pw['events_out_std']:.2f} "
            f"| {100 * result.fraction_suppressed:.2f} % |",
            f"| paper (10 trials, 2 ms) | {ref['events_in_mean']} ± {ref['events_in_std']} "
            f"| {ref['events_out_mean']} ± {ref['events_out_std']} | {ref['suppressed_pct']} % |",
            "",
        ]
    )
