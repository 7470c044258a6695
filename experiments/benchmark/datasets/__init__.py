"""Benchmark datasets: event recordings with ground-truth object masks per time window.

- :mod:`~experiments.benchmark.datasets.base` — :class:`SequenceData`, :class:`MaskWindow`,
  :class:`DatasetLayoutError`;
- :mod:`~experiments.benchmark.datasets.masks` — PNG mask folders (``NNNNNN_T.png``) and fitting
  masks to the sensor grid;
- :mod:`~experiments.benchmark.datasets.evimo` — EVIMO / EVIMO2 NPZ releases;
- :mod:`~experiments.benchmark.datasets.llevos` — LLE-VOS;
- :mod:`~experiments.benchmark.datasets.generic` — any event file + a mask folder.
"""

from experiments.benchmark.datasets.base import (
    DatasetLayoutError,
    MaskWindow,
    SequenceData,
    check_windows_ordered,
)
from experiments.benchmark.datasets.evimo import find_evimo_sequences, load_evimo
from experiments.benchmark.datasets.generic import load_generic
from experiments.benchmark.datasets.llevos import LLEVOSConfig, load_llevos
from experiments.benchmark.datasets.masks import MaskFit, fit_mask, mask_fit, read_mask_folder

__all__ = [
    "DatasetLayoutError",
    "LLEVOSConfig",
    "MaskFit",
    "MaskWindow",
    "SequenceData",
    "check_windows_ordered",
    "find_evimo_sequences",
    "fit_mask",
    "load_evimo",
    "load_generic",
    "load_llevos",
    "mask_fit",
    "read_mask_folder",
]
