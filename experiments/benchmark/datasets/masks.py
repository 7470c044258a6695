"""Ground-truth mask images: reading PNG masks and fitting them to the sensor grid.

Mask folder convention (as in ``../shared/realdata/eed_ball_net/ref_masks_tt_adapt``):
one PNG per time window, named ``NNNNNN_T.png`` (frame index, then the window's END
time ``T`` in µs; the index is optional, ``T.png`` also works). The mask covers the
events with ``T − window ≤ t < T``. The window is given, or inferred as the smallest
difference between consecutive end times (a missing frame is then a gap, never a
longer window).

Pixel values: palette (``P``) / grey (``L``, ``I``) / 1-bit PNGs give the stored value
(0/1, 0/255 or object ids) as the label; RGB(A) PNGs give the long id
``R + 256·G + 65536·B`` (the DAVIS/Cutie convention). Any label > 0 is object.

Resolution: the masks are read at their own size, at most :data:`MAX_MASK_PIXELS` (checked
from the PNG header, before the image is decompressed). :func:`mask_fit` says how a mask
relates to the sensor grid and :func:`fit_mask` puts it there — by nearest-neighbour
resizing (the default; the maps are never stretched, the *mask* is) or, given the
crop offset of the mask inside the sensor, by padding/cropping without any scaling.
The :class:`MaskFit` descriptor is what callers record.

Examples:
    >>> import numpy as np
    >>> m = np.zeros((2, 3), bool); m[1, 2] = True
    >>> out, fit = fit_mask(m, (6, 4, 2))
    >>> fit.describe()
    'mask 2x3 (HxW) resized nearest-neighbour to sensor 4x6: scale x 2, y 2'
    >>> np.argwhere(out).tolist()
    [[2, 4], [2, 5], [3, 4], [3, 5]]
"""

from __future__ import annotations

import itertools
import os
import re
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from experiments.benchmark.datasets.base import DatasetLayoutError, MaskWindow
from wander_env.events import SensorSize

MASK_NAME = re.compile(r"^(?:(\d+)_)?(\d+)\.png$", re.IGNORECASE)
MASK_NAME_HELP = "NNNNNN_T.png or T.png (T = window end time in µs)"
#: The largest mask image read (4096×4096): its labels take up to 8 bytes a pixel.
MAX_MASK_PIXELS = 4096 * 4096


def read_mask_png(path: str | os.PathLike) -> np.ndarray:
    """Labels ``(H, W)`` of a mask PNG (see the module docstring); errors name the file."""
    from PIL import Image, UnidentifiedImageError

    path = Path(path)
    try:
        with warnings.catch_warnings():  # PIL's bomb warning as an error: one line, not two
            warnings.simplefilter("error", Image.DecompressionBombWarning)
            im = Image.open(path)
    except (Image.DecompressionBombError, Image.DecompressionBombWarning) as err:
        raise DatasetLayoutError(path, f"mask image too large ({err})") from None
    except (OSError, UnidentifiedImageError, ValueError) as err:
        raise DatasetLayoutError(path, f"unreadable mask image ({err})") from None
    with im:
        w, h = im.size
        if w * h > MAX_MASK_PIXELS:
            raise DatasetLayoutError(
                path, f"mask image of {w}x{h} pixels; at most {MAX_MASK_PIXELS:,} are read"
            )
        try:
            im.load()
            mode = im.mode
            arr = np.asarray(im)
        except (OSError, ValueError) as err:
            raise DatasetLayoutError(path, f"unreadable mask image ({err})") from None
    if arr.ndim == 2:
        return arr.astype(np.uint8) if mode == "1" else arr
    if arr.ndim == 3 and arr.shape[2] in (3, 4):
        rgb = arr[..., :3].astype(np.int64)
        labels = rgb[..., 0] + 256 * rgb[..., 1] + 65536 * rgb[..., 2]
        return labels.astype(np.min_scalar_type(int(labels.max(initial=0))))
    raise DatasetLayoutError(path, f"mask image of mode {mode!r}, shape {arr.shape} is not 2-D")


def parse_mask_name(name: str) -> tuple[int | None, int]:
    """``(frame index or None, end time µs)`` from a mask file name.

    >>> parse_mask_name("000003_15000.png")
    (3, 15000)
    """
    m = MASK_NAME.match(name)
    if m is None:
        raise ValueError(f"{name!r} is not a mask name ({MASK_NAME_HELP})")
    index = int(m.group(1)) if m.group(1) is not None else None
    return index, int(m.group(2))


def infer_window_us(end_times_us: list[int] | np.ndarray) -> int:
    """The smallest positive step between sorted window end times.

    >>> infer_window_us([5000, 10000, 20000])
    5000
    """
    t = np.sort(np.asarray(end_times_us, dtype=np.int64))
    steps = np.diff(t)
    steps = steps[steps > 0]
    if steps.size == 0:
        raise ValueError("cannot infer the window from fewer than two distinct end times")
    return int(steps.min())


def read_mask_folder(folder: str | os.PathLike, window_us: int | None = None) -> list[MaskWindow]:
    """Mask windows ``[T − window, T)`` from a folder of ``NNNNNN_T.png`` files.

    Sorted by end time. Raises :class:`DatasetLayoutError` naming the file for an
    unreadable mask, a mask whose size differs from the first one, two files with the
    same end time, or a folder without mask files.
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise DatasetLayoutError(folder, "no such folder", f"a folder of {MASK_NAME_HELP}")
    named: list[tuple[int, Path]] = []
    for p in folder.iterdir():
        if p.is_file() and MASK_NAME.match(p.name):
            named.append((parse_mask_name(p.name)[1], p))
    if not named:
        found = sorted(p.name for p in folder.iterdir())[:5]
        raise DatasetLayoutError(
            folder, f"no mask files (found {found or 'nothing'})", f"files named {MASK_NAME_HELP}"
        )
    named.sort(key=lambda tp: (tp[0], tp[1].name))
    for (t0, p0), (t1, p1) in itertools.pairwise(named):
        if t0 == t1:
            raise DatasetLayoutError(p1, f"same end time T={t1} µs as {p0.name}")
    if window_us is None:
        if len(named) < 2:
            raise DatasetLayoutError(
                folder, "one mask file: cannot infer the window", "pass window_us"
            )
        window_us = infer_window_us([t for t, _ in named])
    if window_us <= 0:
        raise ValueError(f"window_us must be > 0, got {window_us}")
    windows: list[MaskWindow] = []
    shape: tuple[int, int] | None = None
    for t_end, path in named:
        labels = read_mask_png(path)
        if shape is None:
            shape = labels.shape
        elif labels.shape != shape:
            raise DatasetLayoutError(
                path,
                f"mask is {labels.shape[0]}x{labels.shape[1]} (HxW), the first mask "
                f"{named[0][1].name} is {shape[0]}x{shape[1]}",
                "all masks of a folder the same size",
            )
        windows.append(MaskWindow(t_end - window_us, t_end, labels, source=str(path)))
    return windows


@dataclass(frozen=True)
class MaskFit:
    """How a mask of ``mask_hw`` is put on a sensor grid of ``sensor_hw``.

    ``mode`` is ``"identity"`` (same size), ``"resize_nearest"`` (scaled by
    ``scale_x``, ``scale_y`` with nearest-neighbour sampling) or ``"pad"`` (placed
    unscaled at ``offset_xy``, the rest padded with background, overflow cropped).
    """

    mask_hw: tuple[int, int]
    sensor_hw: tuple[int, int]
    mode: str
    scale_x: float = 1.0
    scale_y: float = 1.0
    offset_xy: tuple[int, int] = (0, 0)

    @property
    def changed(self) -> bool:
        return self.mode != "identity"

    @property
    def aspect_changed(self) -> bool:
        return self.mode == "resize_nearest" and not np.isclose(self.scale_x, self.scale_y)

    def describe(self) -> str:
        """One line for logs and table notes."""
        (mh, mw), (sh, sw) = self.mask_hw, self.sensor_hw
        if self.mode == "identity":
            return f"mask {mh}x{mw} (HxW) = sensor grid"
        if self.mode == "pad":
            return (
                f"mask {mh}x{mw} (HxW) placed unscaled at x={self.offset_xy[0]}, "
                f"y={self.offset_xy[1]} on sensor {sh}x{sw} (padded/cropped)"
            )
        text = (
            f"mask {mh}x{mw} (HxW) resized nearest-neighbour to sensor {sh}x{sw}: "
            f"scale x {self.scale_x:.4g}, y {self.scale_y:.4g}"
        )
        return text + (" (aspect ratio changed)" if self.aspect_changed else "")


def _sensor_hw(sensor_size: SensorSize | tuple[int, ...]) -> tuple[int, int]:
    if len(sensor_size) < 2 or min(int(sensor_size[0]), int(sensor_size[1])) < 1:
        raise ValueError(f"sensor_size must be (W, H[, 2]) with W, H >= 1, got {sensor_size!r}")
    return int(sensor_size[1]), int(sensor_size[0])


def mask_fit(
    mask_hw: tuple[int, int],
    sensor_size: SensorSize | tuple[int, ...],
    offset_xy: tuple[int, int] | None = None,
) -> MaskFit:
    """The :class:`MaskFit` for a mask of ``(H, W)`` on ``sensor_size = (W, H[, 2])``."""
    sensor_hw = _sensor_hw(sensor_size)
    mask_hw = (int(mask_hw[0]), int(mask_hw[1]))
    if offset_xy is not None:
        return MaskFit(mask_hw, sensor_hw, "pad", offset_xy=(int(offset_xy[0]), int(offset_xy[1])))
    if mask_hw == sensor_hw:
        return MaskFit(mask_hw, sensor_hw, "identity")
    return MaskFit(
        mask_hw,
        sensor_hw,
        "resize_nearest",
        scale_x=sensor_hw[1] / mask_hw[1],
        scale_y=sensor_hw[0] / mask_hw[0],
    )


def _resize_nearest(labels: np.ndarray, hw: tuple[int, int]) -> np.ndarray:
    """Nearest-neighbour resize of integer labels to ``(H, W)`` (pixel-centre sampling)."""
    h, w = hw
    src_h, src_w = labels.shape
    ys = np.minimum(((np.arange(h) + 0.5) * src_h / h).astype(np.int64), src_h - 1)
    xs = np.minimum(((np.arange(w) + 0.5) * src_w / w).astype(np.int64), src_w - 1)
    return labels[np.ix_(ys, xs)]


def fit_mask(
    mask: np.ndarray,
    sensor_size: SensorSize | tuple[int, ...],
    offset_xy: tuple[int, int] | None = None,
) -> tuple[np.ndarray, MaskFit]:
    """Put a mask (boolean or labels) on the sensor grid; returns it and its :class:`MaskFit`.

    The dtype is kept (labels stay labels). Never interpolates values: nearest
    neighbour (pixel-centre sampling) or unscaled placement only.
    """
    arr = np.asarray(mask)
    if arr.ndim != 2:
        raise ValueError(f"mask must be 2-D (H, W), got shape {arr.shape}")
    fit = mask_fit(arr.shape, sensor_size, offset_xy)
    if fit.mode == "identity":
        return arr, fit
    if fit.mode == "resize_nearest":
        return _resize_nearest(arr, fit.sensor_hw), fit
    sh, sw = fit.sensor_hw
    out = np.zeros((sh, sw), dtype=arr.dtype)
    ox, oy = fit.offset_xy
    y0, x0 = max(oy, 0), max(ox, 0)
    y1, x1 = min(oy + arr.shape[0], sh), min(ox + arr.shape[1], sw)
    if y0 < y1 and x0 < x1:
        out[y0:y1, x0:x1] = arr[y0 - oy : y1 - oy, x0 - ox : x1 - ox]
    return out, fit
