"""An EVIMO2v2 NPZ sequence: events and per-frame object masks, laid out as the release.

:func:`write_evimo2_sequence` writes what ``wander record --evimo`` saves and
``wander benchmark evimo`` reads: the events as ``dataset_events_{t,xy,p}.npy``, the
object masks in ``dataset_mask.npz`` and the frames and pinhole intrinsics in
``dataset_info.npz``.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from wander_env.events.checks import EventRecording

__all__ = ["EVIMO2_MASK_SCALE", "write_evimo2_sequence"]

EVIMO2_MASK_SCALE = 1000  # EVIMO stores object id × 1000 per pixel


def write_evimo2_sequence(
    folder: str | os.PathLike,
    recording: EventRecording,
    mask_times_s: np.ndarray,
    masks: np.ndarray,
    focal_px: float,
    discretization_s: float = 0.01,
) -> Path:
    """Write ``folder`` as one EVIMO2v2 NPZ sequence (what ``wander benchmark evimo`` reads).

    Files: ``dataset_events_t.npy`` (float64 s), ``dataset_events_xy.npy`` (uint16
    ``(N, 2)``), ``dataset_events_p.npy`` (uint8), ``dataset_mask.npz``
    (``mask_<10-digit frame index>``: object id × 1000, uint16) and ``dataset_info.npz``
    (``meta`` — a pickled dict, as in the release: ``frames[i]`` with ``id``, ``ts``,
    ``gt_frame``; ``meta`` with the pinhole intrinsics and ``res_x``/``res_y`` — and
    ``K``, ``D``, ``index``, ``discretization``). ``masks`` is ``(F, H, W)`` with object
    ids 1..K (0 = background) at ``mask_times_s``.

    NB ``wander record`` gives one mask per step, at the step's end; the emulator's events
    of a step lie in ``(t_prev, t]``, so under EVIMO's half-open windows ``[ts − w, ts)``
    an event exactly at a mask time counts in the next window, as it would in the release.
    """
    folder = Path(folder)
    ev = recording.events
    w, h = int(recording.sensor_size[0]), int(recording.sensor_size[1])
    masks = np.asarray(masks)
    times = np.asarray(mask_times_s, dtype=np.float64)
    if masks.ndim != 3 or masks.shape[1:] != (h, w) or len(times) != masks.shape[0]:
        raise ValueError(
            f"masks must be (F, {h}, {w}) with one time each; got {masks.shape} and "
            f"{len(times)} times"
        )
    if masks.size and int(masks.max()) * EVIMO2_MASK_SCALE > np.iinfo(np.uint16).max:
        raise ValueError(f"object id {int(masks.max())} does not fit EVIMO's uint16 id × 1000")
    folder.mkdir(parents=True, exist_ok=True)
    np.save(folder / "dataset_events_t.npy", ev["t"].astype(np.float64) * 1e-6)
    np.save(folder / "dataset_events_xy.npy", np.stack([ev["x"], ev["y"]], 1).astype(np.uint16))
    np.save(folder / "dataset_events_p.npy", ev["p"].astype(np.uint8))
    np.savez_compressed(
        folder / "dataset_mask.npz",
        **{
            f"mask_{i:010d}": (m.astype(np.uint16) * EVIMO2_MASK_SCALE) for i, m in enumerate(masks)
        },
    )
    cx, cy = (w - 1) / 2, (h - 1) / 2
    frames = [{"id": i, "ts": float(t), "gt_frame": f"mask_{i:010d}"} for i, t in enumerate(times)]
    intrinsics = {"fx": focal_px, "fy": focal_px, "cx": cx, "cy": cy, "res_x": w, "res_y": h}
    intrinsics |= {"k1": 0.0, "k2": 0.0, "k3": 0.0, "k4": 0.0, "p1": 0.0, "p2": 0.0}
    meta = {"frames": frames, "meta": intrinsics, "full_trajectory": []}
    t_end = float(ev["t"][-1]) * 1e-6 if len(ev) else 0.0
    edges = np.arange(0.0, t_end + discretization_s, discretization_s)
    np.savez(
        folder / "dataset_info.npz",
        meta=np.array(meta, dtype=object),
        K=np.array([[focal_px, 0.0, cx], [0.0, focal_px, cy], [0.0, 0.0, 1.0]]),
        D=np.zeros(4),
        index=np.searchsorted(ev["t"], np.rint(edges * 1e6).astype(np.int64)).astype(np.uint32),
        discretization=np.float64(discretization_s),
    )
    return folder
