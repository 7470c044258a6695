"""Synthetic stimuli (experiments.jobs.synthetic): the demo's and the DVS benchmark's."""

from __future__ import annotations

import numpy as np

from experiments.jobs.synthetic import disc_over_texture, drifting_texture


def test_drifting_texture_moves_by_the_requested_speed():
    f = drifting_texture(64, 8, n_frames=5, speed_px=2.0, seed=1)
    # The texture drifts left by 2 px a frame: frame 2 column x is frame 0 column x + 4.
    assert np.abs(f[2][:, :-4].astype(int) - f[0][:, 4:].astype(int)).max() <= 1


def test_disc_stimulus_is_seeded():
    a = disc_over_texture(32, 32, 4, 0.1, 5, 8, 4, seed=2)
    b = disc_over_texture(32, 32, 4, 0.1, 5, 8, 4, seed=2)
    assert np.array_equal(a, b)
