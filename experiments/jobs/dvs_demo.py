"""The DVS demo's stimulus and picture: a synthetic moving pattern through the emulator.

No renderer is involved: a textured background drifts (as if the camera moved)
while a textured disc circles the centre. The events go to an HDF5 file and a
PNG of titled, time-stamped event frames (red ON, blue OFF, axes in pixels): the
events are :func:`demo_events`', the picture :func:`plot_event_panels`'; the run folder
(``events.h5``, ``events.png``, ``run.json``) is written by ``wander demo``
(:mod:`experiments.jobs.demo`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated

import numpy as np
import pydantic

from experiments.jobs.synthetic import disc_over_texture
from experiments.studies.framework import MAX_SEED
from wander_env.config import check_annotated
from wander_env.dvs import DVSEmulator, DVSParams
from wander_env.env_config import DvsPreset
from wander_env.events import concatenate, time_window, to_frame
from wander_env.viz import event_image, legend_below, polarity_patches, pyplot, save_figure

#: The most bytes the demo's frames may take (they are held in memory: ``(seconds x
#: frame_rate_hz + 1)`` frames of ``width x height`` RGB pixels).
MAX_FRAME_BYTES = 2**30


@dataclass(frozen=True)
class DemoConfig:
    """The DVS demo: ``seconds`` of the stimulus at ``frame_rate_hz`` frames a second (a
    frame at least 1 µs), ``width x height`` pixels, the DVS ``preset``, the ``seed``, and
    the picture's ``panels`` event frames of ``panel_ms`` each. Its frames are held in
    memory: at most :data:`MAX_FRAME_BYTES` of them."""

    seconds: Annotated[float, pydantic.Field(gt=0, le=86400)] = 1.0  # at most a day
    frame_rate_hz: Annotated[float, pydantic.Field(gt=0, le=1e6)] = 1000.0
    width: Annotated[int, pydantic.Field(ge=16, le=2048)] = 128
    height: Annotated[int, pydantic.Field(ge=16, le=2048)] = 128
    preset: DvsPreset = "paper"
    seed: Annotated[int, pydantic.Field(ge=0, le=MAX_SEED)] = 0
    panels: Annotated[int, pydantic.Field(ge=1, le=64)] = 8  # event frames in the picture
    panel_ms: Annotated[float, pydantic.Field(gt=0)] = 20.0  # each shows this much time

    def __post_init__(self) -> None:
        check_annotated(self)  # "field: what is wrong, got value" (wander_env.config)
        frames = round(self.seconds * self.frame_rate_hz)
        if frames < 2:
            raise ValueError(
                f"seconds: {self.seconds:g} s at {self.frame_rate_hz:g} Hz is {frames} "
                "frame(s); the demo needs at least 2"
            )
        size = (frames + 1) * self.width * self.height * 3
        if size > MAX_FRAME_BYTES:
            raise ValueError(
                f"seconds: {self.seconds:g} s at {self.frame_rate_hz:g} Hz of "
                f"{self.width}x{self.height} frames take {size / 2**20:,.0f} MiB; at most "
                f"{MAX_FRAME_BYTES / 2**20:,.0f} MiB"
            )
        if self.panel_ms * self.panels > self.seconds * 1000:
            raise ValueError(
                f"seconds: {self.panels} panels of {self.panel_ms} ms do not fit in "
                f"{self.seconds} s"
            )


def plot_event_panels(
    path: Path, events: np.ndarray, size: tuple[int, int, int], config: DemoConfig, step_us: int
) -> Path:
    """``events.png``: ``config.panels`` event frames of ``config.panel_ms`` each (red ON,
    blue OFF), every panel titled with its time span, axes in pixels, an ON/OFF legend."""
    plt = pyplot()
    from matplotlib.patches import Patch

    w, h = size[0], size[1]
    columns = min(4, config.panels)
    rows = -(-config.panels // columns)
    fig, axes = plt.subplots(rows, columns, figsize=(3.0 * columns, 3.1 * rows + 0.6))
    axes = np.atleast_1d(axes).ravel()
    span_us = round(config.panel_ms * 1000)
    for k, ax in enumerate(axes):
        if k >= config.panels:
            ax.axis("off")
            continue
        t0 = k * step_us
        window = time_window(events, t0, t0 + span_us)
        ax.imshow(
            event_image(to_frame(window, size)),
            interpolation="nearest",
            extent=(-0.5, w - 0.5, h - 0.5, -0.5),
        )
        ax.set_title(
            f"t = {t0 / 1e3:.0f}–{(t0 + span_us) / 1e3:.0f} ms ({len(window):,} ev)", fontsize=9
        )
        ax.tick_params(labelsize=7)
        if k % columns == 0:
            ax.set_ylabel("y (px)", fontsize=8)
        if k // columns == rows - 1:
            ax.set_xlabel("x (px)", fontsize=8)
    fig.suptitle(
        f"DVS emulator demo: a textured disc orbiting over a drifting texture, "
        f"{w}×{h} px, preset '{config.preset}', seed {config.seed}\n"
        f"events of {config.panel_ms:g} ms windows every {step_us / 1e3:g} ms",
        fontsize=10,
    )
    no_event = Patch(facecolor="white", edgecolor="0.5", label="no event")
    legend_below(fig, [*polarity_patches("ON (brighter)", "OFF (darker)"), no_event], fontsize=8)
    return save_figure(fig, path, rect=(0, 0.04, 1, 1))


def demo_events(
    config: DemoConfig, progress: Callable[[int, int], None] | None = None
) -> tuple[np.ndarray, DVSParams]:
    """The demo's events (and the DVS parameters that made them)."""
    n = round(config.seconds * config.frame_rate_hz)
    dt_us = round(1e6 / config.frame_rate_hz)
    frames = disc_over_texture(
        config.width,
        config.height,
        n + 1,
        background_speed_px=0.05,
        disc_radius_px=config.width / 8,
        orbit_px=config.width / 4,
        orbit_frames=n // 2,
        seed=config.seed,
    )
    params = DVSParams.preset(config.preset)
    emu = DVSEmulator(config.width, config.height, params, seed=config.seed)
    emu.reset(frames[0], 0)
    chunks = []
    for i in range(1, n + 1):
        chunks.append(emu.step(frames[i], i * dt_us))
        if progress is not None:
            progress(i, n)
    chunks.append(emu.flush())
    return concatenate(chunks), params
