"""Pictures of events and maps (pure functions returning uint8 RGB arrays).

Examples:
    >>> import numpy as np
    >>> from wander_env.viz import event_image
    >>> counts = np.zeros((2, 2, 2)); counts[1, 0, 0] = 1; counts[0, 1, 1] = 3
    >>> event_image(counts)[0, 0].tolist(), event_image(counts)[1, 1].tolist()
    ([220, 30, 30], [30, 60, 220])
"""

from __future__ import annotations

import functools
from pathlib import Path
from typing import Any

import numpy as np

ON_RGB = (220, 30, 30)
OFF_RGB = (30, 60, 220)
BACKGROUND_RGB = (255, 255, 255)


def pyplot() -> Any:
    """matplotlib's ``pyplot`` on its Agg backend: every plot of wander is drawn off
    screen and written to a file (:func:`save_figure`). Imported here, when a plot is
    made, so that a command that draws none does not pay for it."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def save_figure(
    fig: Any, path: Path, dpi: int = 110, rect: tuple[float, float, float, float] | None = None
) -> Path:
    """Lay out a matplotlib figure (``rect``: the area the axes fill, leaving room for a
    figure legend), write it to ``path`` (its folder made if missing) and close it;
    returns ``path``. Every plot of wander goes through here."""
    import matplotlib.pyplot as plt

    fig.tight_layout(rect=rect)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=dpi)
    plt.close(fig)
    return path


def legend_below(fig: Any, handles: list[Any], fontsize: float) -> None:
    """A figure legend of ``handles`` in one row along the bottom, without a frame (leave
    it room with :func:`save_figure`'s ``rect``)."""
    fig.legend(
        handles=handles, loc="lower center", ncol=len(handles), fontsize=fontsize, frameon=False
    )


def polarity_patches(on: str, off: str) -> list[Any]:
    """Legend handles of :func:`event_image`'s ON and OFF colours, labelled ``on`` and
    ``off``."""
    from matplotlib.patches import Patch

    return [
        Patch(color=np.asarray(ON_RGB) / 255, label=on),
        Patch(color=np.asarray(OFF_RGB) / 255, label=off),
    ]


#: The codes of :func:`polarity_codes`.
NO_EVENT, OFF_CODE, ON_CODE = 0, 1, 2
_CODE_RGB = np.array([BACKGROUND_RGB, OFF_RGB, ON_RGB], np.uint8)


def polarity_codes(counts: np.ndarray) -> np.ndarray:
    """``(..., 2, H, W)`` per-polarity counts (OFF, ON) -> ``(..., H, W)`` uint8 codes:
    ``NO_EVENT`` 0, ``OFF_CODE`` 1, ``ON_CODE`` 2, a pixel with both polarities coded by
    the one with more events (ON on a tie).

    >>> polarity_codes(np.array([[[0, 2, 1, 0]], [[0, 1, 1, 3]]])).tolist()
    [[0, 1, 2, 2]]
    """
    counts = np.asarray(counts)
    if counts.ndim < 3 or counts.shape[-3] != 2:
        raise ValueError(f"expected per-polarity counts of shape (2, H, W), got {counts.shape}")
    off, on = counts[..., 0, :, :], counts[..., 1, :, :]
    return np.where(on >= off, np.uint8(ON_CODE) * (on > 0), off > 0).astype(np.uint8, copy=False)


def event_image(counts: np.ndarray) -> np.ndarray:
    """``(2, H, W)`` per-polarity counts -> ``(H, W, 3)``: red ON, blue OFF, white none,
    by :func:`polarity_codes`."""
    counts = np.asarray(counts)
    if counts.ndim != 3:
        raise ValueError(f"expected per-polarity counts of shape (2, H, W), got {counts.shape}")
    return np.take(_CODE_RGB, polarity_codes(counts), axis=0)  # 4x indexing's speed


def tile(images: list[np.ndarray], columns: int, gap: int = 2) -> np.ndarray:
    """Lay same-sized RGB images out in a grid with a grey gap."""
    if not images:
        raise ValueError("no images to tile")
    h, w = images[0].shape[:2]
    rows = -(-len(images) // columns)
    out = np.full((rows * (h + gap) - gap, columns * (w + gap) - gap, 3), 128, np.uint8)
    for k, im in enumerate(images):
        r, c = divmod(k, columns)
        out[r * (h + gap) : r * (h + gap) + h, c * (w + gap) : c * (w + gap) + w] = im
    return out


def upscale(image: np.ndarray, factor: int) -> np.ndarray:
    """Nearest-neighbour enlargement by an integer ``factor``, so single pixels stay
    visible: every pixel becomes a ``factor × factor`` block (OpenCV's nearest resize,
    which for an integer factor is exactly that; an image ``(H, W)`` or ``(H, W, C)``
    of a dtype OpenCV resizes, e.g. uint8 or float32).

    >>> upscale(np.array([[1, 2]], np.uint8), 2).tolist()
    [[1, 1, 2, 2], [1, 1, 2, 2]]
    """
    import cv2

    if not (isinstance(factor, int) and factor >= 1):
        raise ValueError(f"factor must be an integer >= 1, got {factor!r}")
    h, w = image.shape[:2]
    big = cv2.resize(image, None, fx=factor, fy=factor, interpolation=cv2.INTER_NEAREST)
    return big.reshape(h * factor, w * factor, *image.shape[2:])  # cv2 drops a last axis of 1


# ----------------------------------------------------------------------------------------
# Labelled video frames: panel names, colour keys and a time stamp, drawn on the
# upscaled image (text on a 128-pixel panel is unreadable) with OpenCV.

TEXT_RGB = (20, 20, 20)
FOVEA_RGB = (0, 200, 0)
TARGET_RGB = (255, 0, 255)
BAR_PX = 24  # height of the header and footer strips


def saliency_rgb(values: np.ndarray) -> np.ndarray:
    """``(H, W)`` non-negative values -> RGB with the magma colour map, 0 black and the
    map's peak the brightest (the scale of the key :func:`labelled_frame` draws).

    >>> saliency_rgb(np.array([[0.0, 2.0]])).tolist()
    [[[0, 0, 4], [252, 253, 191]]]
    """
    v = np.asarray(values, dtype=np.float64)
    v = np.clip(np.where(np.isnan(v), 0.0, v), 0.0, np.finfo(np.float64).max)  # +inf: max
    peak = v.max() if v.size else 0.0
    grey = np.rint(255 * (v / peak if peak > 0 else v)).astype(np.uint8)
    return np.take(_magma(), grey, axis=0)


@functools.cache
def _magma() -> np.ndarray:
    """OpenCV's magma colour map as a ``(256, 3)`` RGB table (``applyColorMap`` builds
    its table anew at every call: 0.4 ms for a 128×128 map, against 0.03 ms to index)."""
    import cv2

    bgr = cv2.applyColorMap(np.arange(256, dtype=np.uint8)[:, None], cv2.COLORMAP_MAGMA)
    return np.ascontiguousarray(bgr[:, 0, ::-1])


def _text(img: np.ndarray, text: str, x: int, y: int, scale: float = 0.5) -> int:
    """Draw ``text`` with its baseline at ``y``; returns the x after it."""
    import cv2

    cv2.putText(img, text, (x, y), cv2.FONT_HERSHEY_SIMPLEX, scale, TEXT_RGB, 1, cv2.LINE_AA)
    (w, _), _ = cv2.getTextSize(text, cv2.FONT_HERSHEY_SIMPLEX, scale, 1)
    return x + w


def _swatch(img: np.ndarray, x: int, rgb: tuple[int, int, int], label: str) -> int:
    import cv2

    cv2.rectangle(img, (x, 6), (x + 11, 17), rgb, -1)
    cv2.rectangle(img, (x, 6), (x + 11, 17), TEXT_RGB, 1)
    return _text(img, label, x + 15, 17) + 12


def draw_keys(strip: np.ndarray, x: int, keys: tuple[str, ...]) -> int:
    """Draw the colour keys named in ``keys`` on a footer strip from ``x``:
    ``"polarity"`` (ON red, OFF blue), ``"saliency"`` (the magma bar from 0 to the
    map's peak), ``"fovea"`` (green cross), ``"P"`` (magenta 8×8 box)."""
    import cv2

    for key in keys:
        if key == "polarity":
            x = _swatch(strip, x, ON_RGB, "ON")
            x = _swatch(strip, x, OFF_RGB, "OFF")
        elif key == "saliency":
            x = _text(strip, "saliency 0", x, 17) + 4
            ramp = saliency_rgb(np.tile(np.linspace(0.0, 1.0, 80), (11, 1)))
            strip[6:17, x : x + 80] = ramp
            cv2.rectangle(strip, (x, 6), (x + 79, 16), TEXT_RGB, 1)
            x = _text(strip, "peak", x + 84, 17) + 12
        elif key == "fovea":
            cv2.drawMarker(strip, (x + 6, 12), FOVEA_RGB, cv2.MARKER_CROSS, 12, 2)
            x = _text(strip, "fovea", x + 15, 17) + 12
        elif key == "P":
            cv2.rectangle(strip, (x, 6), (x + 11, 17), TARGET_RGB, 1)
            x = _text(strip, "P (8x8 box)", x + 15, 17) + 12
        else:
            raise ValueError(f"unknown key {key!r}; known: polarity, saliency, fovea, P")
    return x


def labelled_frame(
    panels: list[tuple[str, np.ndarray]],
    scale: int,
    caption: str,
    keys: tuple[str, ...] = ("polarity",),
    target: tuple[int, int] | None = None,
    gap: int = 4,
) -> np.ndarray:
    """Panels side by side, each upscaled ``scale``× and named in a header strip, the
    fovea (and ``target`` P, a pixel of the sensor) marked on every panel, and a footer
    strip with ``caption`` (the time stamp first) and the colour ``keys``.

    >>> img = labelled_frame([("events", np.zeros((8, 8, 3), np.uint8))], 4, "t = 0.01 s")
    >>> img.shape
    (80, 32, 3)
    """
    import cv2

    if not panels:
        raise ValueError("no panels")
    h, w = panels[0][1].shape[:2]
    big = []
    for _, p in panels:
        if p.shape[:2] != (h, w):
            raise ValueError(f"panels differ in size: {p.shape[:2]} and {(h, w)}")
        img = np.ascontiguousarray(upscale(np.asarray(p, np.uint8), scale))
        centre = (round((w - 1) / 2 * scale + scale / 2), round((h - 1) / 2 * scale + scale / 2))
        cv2.drawMarker(img, centre, FOVEA_RGB, cv2.MARKER_CROSS, 4 * scale, 1)
        if target is not None:
            x0, y0 = (target[0] - 4) * scale, (target[1] - 4) * scale
            cv2.rectangle(img, (x0, y0), (x0 + 8 * scale - 1, y0 + 8 * scale - 1), TARGET_RGB, 1)
        big.append(img)
    pw = w * scale
    header = _header(tuple(name for name, _ in panels), pw, gap)
    sep = np.full((h * scale, gap, 3), 128, np.uint8)
    row = np.concatenate([x for p in big for x in (p, sep)][:-1], axis=1)
    footer = np.full((BAR_PX, header.shape[1], 3), 255, np.uint8)
    x = _text(footer, caption, 4, 17) + 16 - _KEYS_MARGIN
    strip = _keys_strip(tuple(keys))[:, : max(0, footer.shape[1] - x)]
    footer[:, x : x + strip.shape[1]] = np.minimum(footer[:, x : x + strip.shape[1]], strip)
    return np.concatenate([header, row, footer], axis=0)


# The strips that stay the same from frame to frame, drawn once (text is most of a frame's
# drawing: in a run's writer profile, 11 strings a frame took 1.3 ms of its 2 ms); read-only.
_KEYS_MARGIN = 2  # white pixels left of the keys, where anti-aliased text may reach


@functools.lru_cache(maxsize=8)
def _header(names: tuple[str, ...], pw: int, gap: int) -> np.ndarray:
    """The header strip: each panel's name over its ``pw`` pixels, ``gap`` between."""
    width = len(names) * pw + (len(names) - 1) * gap
    header = np.full((BAR_PX, width, 3), 255, np.uint8)
    for k, name in enumerate(names):
        _text(header, name, k * (pw + gap) + 4, 17)
    header.setflags(write=False)
    return header


@functools.lru_cache(maxsize=8)
def _keys_strip(keys: tuple[str, ...]) -> np.ndarray:
    """The colour ``keys`` (:func:`draw_keys`) on a white strip of their width."""
    strip = np.full((BAR_PX, 2048, 3), 255, np.uint8)
    end = draw_keys(strip, _KEYS_MARGIN, keys)
    strip = strip[:, :end].copy()
    strip.setflags(write=False)
    return strip
