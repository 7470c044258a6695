"""Benchmark datasets: event recordings with ground-truth object masks per time window.

- :mod:`~experiments.datasets.base` — :class:`SequenceData`, :class:`MaskWindow`,
  :class:`DatasetLayoutError`;
- :mod:`~experiments.datasets.masks` — PNG mask folders (``NNNNNN_T.png``) and fitting
  masks to the sensor grid;
- :mod:`~experiments.datasets.evimo` — EVIMO / EVIMO2 NPZ releases;
- :mod:`~experiments.datasets.llevos` — LLE-VOS;
- :mod:`~experiments.datasets.generic` — any event file + a mask folder.
"""

from experiments.datasets.base import (
    DatasetLayoutError,
    MaskWindow,
    SequenceData,
    check_windows_ordered,
)
from experiments.datasets.evimo import find_evimo_sequences, load_evimo
from experiments.datasets.generic import load_generic
from experiments.datasets.llevos import LLEVOSConfig, load_llevos
from experiments.datasets.masks import MaskFit, fit_mask, mask_fit, read_mask_folder

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
