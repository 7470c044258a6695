"""Pictures of events and maps (pure functions returning uint8 RGB arrays).

Example:
    >>> import numpy as np
    >>> from wander_env.viz import event_image
    >>> counts = np.zeros((2, 2, 2)); counts[1, 0, 0] = 1; counts[0, 1, 1] = 3
    >>> event_image(counts)[0, 0].tolist(), event_image(counts)[1, 1].tolist()
    ([220, 30, 30], [30, 60, 220])
"""

from __future__ import annotations

import numpy as np

ON_RGB = (220, 30, 30)
OFF_RGB = (30, 60, 220)
BACKGROUND_RGB = (255, 255, 255)


def event_image(counts: np.ndarray) -> np.ndarray:
    """``(2, H, W)`` per-polarity counts -> ``(H, W, 3)``: red ON, blue OFF, white none.

    A pixel with both polarities shows the one with more events.
    """
    if counts.ndim != 3 or counts.shape[0] != 2:
        raise ValueError(f"expected per-polarity counts of shape (2, H, W), got {counts.shape}")
    off, on = counts[0], counts[1]
    img = np.empty((*on.shape, 3), np.uint8)
    img[:] = BACKGROUND_RGB
    img[(on > 0) & (on >= off)] = ON_RGB
    img[(off > 0) & (off > on)] = OFF_RGB
    return img


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
    """Nearest-neighbour enlargement, so single pixels stay visible."""
    return np.repeat(np.repeat(image, factor, axis=0), factor, axis=1)
