"""The settings of a simulated env (:class:`WanderConfig`): the one definition of every
``wander/Wander-v0`` keyword, its default, unit and range.

Every job and experiment config holds these as its ``env`` block (``env: {frames:
exact}`` in a YAML file, ``--set env.frames=exact`` or ``--frames exact`` on the command
line), and the env is made from that block alone: ``gymnasium.make("wander/Wander-v0",
**config.env)`` (a :class:`WanderConfig` unpacks as a mapping of its fields).

Fields are checked as the scene's are (:func:`wander_env.config.check_annotated`: the
constraints live on the ``Annotated`` type), plus the checks that tie fields together
(a control period of whole render ticks of whole µs, key intervals of whole ticks).
:func:`control_period_us` is the one rule and conversion of a control period, the
sim's and the rig's (:class:`hardware.rig_env.RigConfig`).

Examples:
    >>> cfg = WanderConfig(scene="shelf", frames="exact")
    >>> dict(cfg)["frames"], cfg.ticks_per_step
    ('exact', 10)
    >>> WanderConfig(frames="fast")
    Traceback (most recent call last):
    ...
    ValueError: frames: expected one of 'keyframes', 'exact', 'panorama', got 'fast'
"""

from __future__ import annotations

import typing
from dataclasses import dataclass, field
from typing import Annotated, Literal

import pydantic

from wander_env.config import FieldsMapping, check_annotated
from wander_env.dvs import DVSParams
from wander_env.field_doc import field_doc
from wander_env.frames.registry import MODE_NAMES, frame_modes_help
from wander_env.ptu.params import PTUParams
from wander_env.readout import ReadoutParams
from wander_env.scene_config import SceneConfig
from wander_env.scenes import available_scenes, load_scene_config

__all__ = [
    "FRAME_MODES",
    "MAX_CONTROL_PERIOD_S",
    "QUALITIES",
    "DvsPreset",
    "FrameMode",
    "PtuPreset",
    "Quality",
    "ReadoutPreset",
    "SceneName",
    "WanderConfig",
    "check_dvs_preset",
    "check_scene_name",
    "control_period_us",
]

#: The longest control period (one env step) the sim and the rig take, seconds.
MAX_CONTROL_PERIOD_S = 1.0


def control_period_us(control_period_s: float, name: str = "control_period_s") -> int:
    """A control period (one env step) in whole µs: ``control_period_s`` must be a number
    of seconds in (0, :data:`MAX_CONTROL_PERIOD_S`] that is a whole number of µs (within
    1e-6 µs); ValueError naming ``name`` and the value otherwise.

    >>> control_period_us(0.01), control_period_us(0.0125)
    (10000, 12500)
    >>> control_period_us(1.5e-7)
    Traceback (most recent call last):
    ...
    ValueError: control_period_s: must be a whole number of µs in (0, 1] s, got 1.5e-07
    """
    number = isinstance(control_period_s, (int, float)) and not isinstance(control_period_s, bool)
    valid = number and 0 < control_period_s <= MAX_CONTROL_PERIOD_S
    us = control_period_s * 1e6 if valid else 0.0
    if not valid or abs(us - round(us)) > 1e-6:
        raise ValueError(
            f"{name}: must be a whole number of µs in (0, {MAX_CONTROL_PERIOD_S:g}] s, "
            f"got {control_period_s!r}"
        )
    return round(us)


def check_scene_name(name: str) -> str:
    """``name`` when it is a scene name of ``assets/scenes`` or a scene file that loads;
    ValueError naming the scenes otherwise."""
    try:
        load_scene_config(name)
    except FileNotFoundError as err:
        raise ValueError(
            f"{err}; allowed: {', '.join(available_scenes())} or a scene .yaml file"
        ) from None
    return name


def check_dvs_preset(name: str) -> str:
    """``name`` when it is a DVS preset (ValueError naming the presets otherwise)."""
    DVSParams.preset(name)  # ValueError naming the presets
    return name


def _ptu_preset(name: str) -> str:
    PTUParams.preset(name)  # ValueError naming the presets
    return name


def _readout_preset(name: str) -> str:
    ReadoutParams.preset(name)  # ValueError naming the presets
    return name


#: A scene: a name of ``assets/scenes`` or a scene file that loads.
SceneName = Annotated[str, pydantic.AfterValidator(check_scene_name)]
#: A DVS preset (:meth:`wander_env.dvs.DVSParams.preset`).
DvsPreset = Annotated[str, pydantic.AfterValidator(check_dvs_preset)]


#: A readout preset (:meth:`wander_env.readout.ReadoutParams.preset`).
ReadoutPreset = Annotated[str, pydantic.AfterValidator(_readout_preset)]
#: A PTU preset (:meth:`wander_env.ptu.PTUParams.preset`).
PtuPreset = Annotated[str, pydantic.AfterValidator(_ptu_preset)]
#: How the env makes its frames: one name per mode of ``wander_env.frames.registry``.
FrameMode = Literal[MODE_NAMES]
#: Rendering quality: ``fast`` (the scene's antialiasing), ``fine`` (16 samples a pixel).
Quality = Literal["fast", "fine"]
FRAME_MODES: tuple[str, ...] = typing.get_args(FrameMode)
QUALITIES: tuple[str, ...] = typing.get_args(Quality)


@dataclass(frozen=True)
class WanderConfig(FieldsMapping):
    """Everything that defines a simulated env instance (pickled with it); a mapping of
    its fields (:class:`~wander_env.config.FieldsMapping`)."""

    scene: Annotated[
        SceneName | SceneConfig,
        field_doc("A scene name (assets/scenes), a scene YAML file, or a scene config"),
    ] = "office"
    control_period_s: Annotated[
        float,
        field_doc(
            "One env step (a control period): whole µs, at most 1 s (control_period_us)",
            unit="s",
        ),
    ] = 0.01
    render_rate_hz: Annotated[
        float,
        field_doc(
            "Frames a second handed to the DVS: whole render ticks a step, each of whole µs",
            unit="Hz",
            gt=0,
            le=1e6,
        ),
    ] = 1000.0
    dvs: Annotated[DvsPreset, field_doc("DVS preset: ideal, paper or speck")] = "ideal"
    adaptive_log_change: Annotated[
        float,
        field_doc(
            "A frame whose largest log-intensity change passes this is split by "
            "adaptive sub-frames",
            gt=0,
        ),
    ] = 1.0
    max_subframes: Annotated[
        int, field_doc("Most frames a render tick is split into", ge=1, le=1000)
    ] = 8
    ground_truth: Annotated[
        bool, field_doc("Object masks and positions in info (a segmentation pass)")
    ] = True
    episode_seconds: Annotated[
        float, field_doc("Length of an episode", unit="s", gt=0, le=86400)
    ] = 10.0
    start_gaze_deg: Annotated[
        tuple[float, float], field_doc("Pan and tilt at reset (+ = left, up)", unit="deg")
    ] = (0.0, 0.0)
    ptu: PTUParams = field(default_factory=PTUParams)
    dvs_params: Annotated[
        DVSParams | None, field_doc("DVS parameters; overrides the dvs preset when given")
    ] = None
    antialias_samples: Annotated[
        int | None,
        field_doc(
            "Overrides the scene's camera.antialias_samples (MSAA) when given; 0 renders "
            "about twice as fast on a CPU but edges jump from pixel to pixel: ~5 % more "
            "events and ~1.5x the adaptive sub-frames (office, still camera)",
            ge=0,
            le=64,
        ),
    ] = None
    frames: Annotated[
        FrameMode,
        field_doc("How frames are made (wander_env.frames.registry): " + frame_modes_help()),
    ] = "keyframes"
    keyframe_ms: Annotated[
        float,
        field_doc(
            "Keys this far apart (and at each step's end) where the image motion has no "
            "bound (a camera centre that moves, a sliding screen), or always with "
            "keyframe_px=None; a whole number of render ticks, or dividing one",
            unit="ms",
            gt=0,
        ),
    ] = 2.0
    keyframe_px: Annotated[
        float | None,
        field_doc(
            "Keys where the image motion predicted since the last key (the camera's "
            "rotation along the PTU's trajectory, the objects' known motion) would pass "
            "this; none while nothing moves (None: every keyframe_ms)",
            unit="px",
            gt=0,
        ),
    ] = 2.0
    keyframe_max_ms: Annotated[
        float | None,
        field_doc(
            "With keyframe_px: keys no further apart than this while anything moves "
            "(None: as few as one key a step); 5 (two keys a step) keeps the events "
            "within 2 points of exact rendering's against the fine reference",
            unit="ms",
            gt=0,
        ),
    ] = 5.0
    supersample: Annotated[
        int,
        field_doc(
            "Render at this many times the resolution and average blocks (2 = 16 "
            "samples a pixel with MSAA 4): the fidelity benchmark's reference",
            ge=1,
            le=8,
        ),
    ] = 1
    quality: Annotated[
        Quality,
        field_doc(
            "fast: the scene's antialiasing (MSAA 4); fine: every rendered frame with "
            "16 samples a pixel (supersample 2), about twice the cost of a render"
        ),
    ] = "fast"
    render_thread: Annotated[
        bool,
        field_doc(
            "Draw on a render thread of its own (GL beside the main thread's frame "
            "synthesis and DVS); the same events either way"
        ),
    ] = True

    readout: Annotated[
        ReadoutPreset | ReadoutParams | None,
        field_doc(
            "Speck's readout after the DVS (wander_env.readout): None (off), a preset "
            "(ideal, speck, speck_filtered) or a readout block"
        ),
    ] = None

    def __post_init__(self) -> None:
        check_annotated(self)
        period_us = self.control_period_us
        ticks = self.control_period_s * self.render_rate_hz
        if abs(ticks - round(ticks)) > 1e-9 or round(ticks) < 1:
            raise ValueError(
                f"control_period_s: {self.control_period_s} must be a whole number (>= 1) "
                f"of render periods (render_rate_hz={self.render_rate_hz})"
            )
        if period_us % self.ticks_per_step:  # the ticks must add up to the period exactly
            raise ValueError(
                f"render_rate_hz: {self.render_rate_hz} must give render periods of whole µs "
                f"({period_us} µs / {self.ticks_per_step} ticks = "
                f"{period_us / self.ticks_per_step:g} µs)"
            )
        if round(1e6 / self.render_rate_hz / self.max_subframes) < 1:
            raise ValueError(f"max_subframes: {self.max_subframes} splits a tick below 1 µs")
        for name in ("keyframe_ms", "keyframe_max_ms"):
            k = getattr(self, name)
            if k is None:
                continue
            # Keys are render ticks (and each step's end): an interval must be a whole
            # number of ticks, or divide a tick (every tick a key).
            key_us, tick_us = round(k * 1e3), self.tick_us
            whole = abs(k * 1e3 - key_us) <= 1e-6 and key_us >= 1
            if not whole or (key_us % tick_us and tick_us % key_us):
                raise ValueError(
                    f"{name}: {k} must be a whole number of render periods or divide one "
                    f"(render_rate_hz={self.render_rate_hz}: {tick_us} µs)"
                )
        if self.quality == "fine" and self.supersample != 1:
            raise ValueError("quality: give quality='fine' or a supersample, not both")

    @property
    def readout_params(self) -> ReadoutParams | None:
        """The readout's parameters (None: no readout stage)."""
        if isinstance(self.readout, str):
            return ReadoutParams.preset(self.readout)
        return self.readout

    @property
    def control_period_us(self) -> int:
        """One step in whole µs (:func:`control_period_us`): ``ticks_per_step`` ticks of
        ``tick_us``, exactly."""
        return control_period_us(self.control_period_s)

    @property
    def ticks_per_step(self) -> int:
        return round(self.control_period_s * self.render_rate_hz)

    @property
    def tick_us(self) -> int:
        return self.control_period_us // self.ticks_per_step

    @property
    def keyframe_us(self) -> int:
        return round(self.keyframe_ms * 1e3)

    @property
    def render_supersample(self) -> int:
        """The renderer's supersampling: ``supersample``, or 2 with ``quality="fine"``."""
        return 2 if self.quality == "fine" else self.supersample
