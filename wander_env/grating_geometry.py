"""The gratings screen's geometry and its state at a time (pure).

:func:`grating_layout` places the screen of a :class:`~wander_env.scene_config.GratingConfig`
ahead of the camera and sizes its background periods and the patch's strips
(:class:`GratingLayout`); :func:`grating_state` gives the background's slide and the
strips' grey levels at time t. :class:`wander_env.entities.GratingStimulus` builds the
screen from them and moves it.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from wander_env.scene_config import GratingConfig
from wander_env.textures import grating_profile

__all__ = ["GratingLayout", "grating_layout", "grating_state"]


@dataclass(frozen=True)
class GratingLayout:
    """Metric layout of the gratings screen for a :class:`GratingConfig` and camera."""

    center: tuple[float, float, float]
    background_period_m: float
    background_periods: int  # even: the plane's centre is at phase 0
    screen_half_height_m: float
    object_period_m: float
    object_side_m: float
    strip_offsets_m: tuple[float, ...]  # strip centres, image-right from the centre

    @property
    def screen_half_width_m(self) -> float:
        """Half the background plane's width (m)."""
        return self.background_periods * self.background_period_m / 2.0


def grating_layout(
    g: GratingConfig, camera_position: Sequence[float], hfov_deg: float, vfov_deg: float
) -> GratingLayout:
    """Place the screen ``distance_m`` ahead of the camera (at pan = tilt = 0)."""
    d = g.distance_m
    mpd = g.metres_per_deg
    p_b = 1.0 / g.background_cycles_per_deg * mpd
    p_o = 1.0 / g.object_cycles_per_deg * mpd
    half_w = d * math.tan(math.radians(min(hfov_deg / 2.0 + g.margin_deg, 85.0)))
    half_h = d * math.tan(math.radians(min(vfov_deg / 2.0 + g.margin_deg, 85.0)))
    periods = 2 * math.ceil((half_w + p_b) / p_b)
    side = g.object_size_deg * mpd
    n = g.object_strips
    offsets = tuple(-side / 2.0 + (i + 0.5) * side / n for i in range(n))
    cx, cy, cz = camera_position
    return GratingLayout(
        center=(cx + d, cy, cz),
        background_period_m=p_b,
        background_periods=periods,
        screen_half_height_m=half_h,
        object_period_m=p_o,
        object_side_m=side,
        strip_offsets_m=offsets,
    )


def grating_state(g: GratingConfig, layout: GratingLayout, t: float) -> tuple[float, np.ndarray]:
    """(background slide in m, image-right; strip intensities in [0, 1]) at time t.

    The background shows phase (x - v_b t) / P_b at image-right offset x; the strips
    show (x - v_o t) / P_o, or the background's phase in ``eye-only`` mode.
    """
    v_b, v_o = (v * g.metres_per_deg for v in g.effective_speeds_deg_s())
    p_b, p_o = layout.background_period_m, layout.object_period_m
    slide = math.fmod(v_b * t, p_b)
    x = np.asarray(layout.strip_offsets_m)
    if g.mode == "eye-only":
        phase = (x - slide) / p_b
    else:
        phase = (x - math.fmod(v_o * t, p_o)) / p_o
    return slide, grating_profile(phase, g.profile, g.contrast, g.mean)
