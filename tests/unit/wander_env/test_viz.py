"""Pictures: event images, tiling, upscaling."""

from __future__ import annotations

import numpy as np
import pytest

from wander_env.viz import OFF_RGB, ON_RGB, event_image, polarity_codes, tile, upscale


def test_event_image_colours():
    counts = np.zeros((2, 2, 3))
    counts[1, 0, 0] = 2
    counts[0, 0, 0] = 1  # more ON than OFF -> red
    counts[0, 1, 2] = 1
    img = event_image(counts)
    assert tuple(img[0, 0]) == ON_RGB
    assert tuple(img[1, 2]) == OFF_RGB
    assert tuple(img[1, 1]) == (255, 255, 255)
    with pytest.raises(ValueError, match=r"\(2, H, W\)"):
        event_image(np.zeros((3, 2, 2)))


def test_polarity_codes_follow_the_event_image_rule_on_a_batch():
    counts = np.zeros((2, 2, 4, 1))  # two steps
    counts[0, 1, 0, 0] = 2  # ON only
    counts[0, 0, 1, 0], counts[0, 1, 1, 0] = 3, 1  # more OFF
    counts[0, 0, 2, 0], counts[0, 1, 2, 0] = 2, 2  # a tie: ON
    counts[1, 0, 3, 0] = 1  # the second step: OFF only
    codes = polarity_codes(counts)
    assert codes.dtype == np.uint8 and codes[..., 0].tolist() == [[2, 1, 2, 0], [0, 0, 0, 1]]
    rgb = [tuple(event_image(counts[0])[k, 0]) for k in range(4)]
    assert rgb == [ON_RGB, OFF_RGB, ON_RGB, (255, 255, 255)]
    with pytest.raises(ValueError, match=r"shape \(2, H, W\), got \(3, 3\)"):
        polarity_codes(np.zeros((3, 3)))


def test_tile_and_upscale_shapes():
    ims = [np.zeros((4, 5, 3), np.uint8)] * 5
    assert tile(ims, columns=3, gap=1).shape == (2 * 4 + 1, 3 * 5 + 2, 3)
    assert upscale(np.ones((2, 3, 3), np.uint8), 4).shape == (8, 12, 3)
    # every pixel a factor x factor block, as np.repeat along both axes makes it
    im = np.random.default_rng(0).integers(0, 256, (9, 7, 3)).astype(np.uint8)
    for f in (1, 2, 3, 5):
        assert np.array_equal(upscale(im, f), np.repeat(np.repeat(im, f, 0), f, 1))
    assert upscale(im[..., :1], 2).shape == (18, 14, 1)
