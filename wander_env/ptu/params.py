"""The pan-tilt unit's parameters (:class:`PTUParams`): resolution, limits, speeds and
accelerations per axis, the mechanics between motor and camera, and the serial link.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, fields, replace

from wander_env.config import check_fields
from wander_env.ptu.link import PTULinkParams
from wander_env.ptu.units import FLIR_RESOLUTION_ARCSEC, clip_to_limits, positions_to_degrees


@dataclass(frozen=True)
class PTUParams:
    """Pan-tilt unit parameters; positions, positions/s and positions/s² per axis.

    Defaults are those of a FLIR PTU-D46/E46 at the paper's resolution:

    - resolution 92.5714″/position on both axes (the paper's ``PR``/``TR``);
    - limits ``PN``/``PX`` = ∓3090, ``TN``/``TX`` = −907/+604 (FLIR factory limits);
    - ``accel`` 2000 pos/s² (what the FLIR manuals' ``PA`` query examples report) and
      ``base_speed`` 1000 pos/s (the ``PB``/``TB`` default in the PTU-D46 manual);
    - ``speed`` 2000 pos/s ≈ 51.4°/s, a typical configured ``PS``/``TS`` (an
      assumption: the paper does not give its speed), below ``upper_speed`` 2902 pos/s
      (the ``PU`` in the manual's example) and above ``lower_speed`` 31 pos/s (the
      ``PL`` in the FLIR manual's §4.4.6 example, PTU-D300 v2.18: "Minimum Pan speed is
      31 positions/sec"); these bound the configured speed and
      :meth:`~wander_env.ptu.unit.PanTiltUnit.set_speed`, as they bound ``PS`` on the
      unit (:func:`~wander_env.ptu.units.whole_speed`).
      With these, a 1000-position (25.7°) saccade takes 0.73 s and a 60-position
      fixational step 0.058 s (see :func:`~wander_env.ptu.axis.move_duration`).

    ``*_backlash_pos`` (play between motor and camera, 0 = ideal) and the camera's
    offset from the tilt hinge (``camera_forward_m`` along the optical axis,
    ``camera_up_m`` perpendicular to it, up at tilt 0; its one home: the scene says only
    where the hinge stands, and the model is built with these) default to an ideal unit.
    ``quantise`` keeps targets and reported angles on whole positions, as the
    stepper does.
    """

    pan_resolution_arcsec: float = FLIR_RESOLUTION_ARCSEC
    tilt_resolution_arcsec: float = FLIR_RESOLUTION_ARCSEC
    pan_min_pos: int = -3090
    pan_max_pos: int = 3090
    tilt_min_pos: int = -907
    tilt_max_pos: int = 604
    pan_speed: float = 2000.0
    tilt_speed: float = 2000.0
    pan_accel: float = 2000.0
    tilt_accel: float = 2000.0
    pan_base_speed: float = 1000.0
    tilt_base_speed: float = 1000.0
    pan_upper_speed: float = 2902.0
    tilt_upper_speed: float = 2902.0
    pan_lower_speed: float = 31.0
    tilt_lower_speed: float = 31.0
    pan_backlash_pos: float = 0.0
    tilt_backlash_pos: float = 0.0
    camera_forward_m: float = 0.0
    camera_up_m: float = 0.0
    quantise: bool = True
    link: PTULinkParams | None = None

    @classmethod
    def preset(cls, name: str) -> PTUParams:
        """``"ideal"`` (the defaults: commands act at once) or ``"flir"`` (the same unit
        behind its 9600-baud serial link, :class:`~wander_env.ptu.link.PTULinkParams`).

        >>> PTUParams.preset("flir").link.baudrate, PTUParams.preset("ideal").link
        (9600, None)
        """
        if name == "ideal":
            return cls()
        if name == "flir":
            return cls(link=PTULinkParams())
        raise ValueError(f"unknown PTU preset {name!r}; expected 'ideal' or 'flir'")

    def __post_init__(self) -> None:
        if isinstance(self.link, Mapping):  # from asdict() (pickling, JSON configs)
            object.__setattr__(self, "link", PTULinkParams(**self.link))
        if self.link is not None and not isinstance(self.link, PTULinkParams):
            raise ValueError(f"PTUParams.link must be PTULinkParams or None, got {self.link!r}")
        ints = ("pan_min_pos", "pan_max_pos", "tilt_min_pos", "tilt_max_pos")
        positive = (
            "pan_resolution_arcsec",
            "tilt_resolution_arcsec",
            "pan_speed",
            "tilt_speed",
            "pan_accel",
            "tilt_accel",
            "pan_upper_speed",
            "tilt_upper_speed",
        )
        signed = ("camera_forward_m", "camera_up_m")
        if not isinstance(self.quantise, bool):
            raise ValueError(f"PTUParams.quantise must be a bool, got {self.quantise!r}")
        check_fields(self, ints, integer=True)
        check_fields(self, positive, positive=True)
        check_fields(self, signed)
        named = {*ints, *positive, *signed, "quantise", "link"}
        check_fields(self, [f.name for f in fields(self) if f.name not in named], minimum=0)
        for axis in ("pan", "tilt"):
            lo, hi = getattr(self, f"{axis}_min_pos"), getattr(self, f"{axis}_max_pos")
            if lo >= hi:
                raise ValueError(f"PTUParams.{axis}_min_pos ({lo}) must be < {axis}_max_pos ({hi})")
            upper = getattr(self, f"{axis}_upper_speed")
            for name in (f"{axis}_speed", f"{axis}_base_speed", f"{axis}_lower_speed"):
                if getattr(self, name) > upper:
                    raise ValueError(
                        f"PTUParams.{name} must be <= {axis}_upper_speed ({upper}), "
                        f"got {getattr(self, name)!r}"
                    )
            lower, speed = getattr(self, f"{axis}_lower_speed"), getattr(self, f"{axis}_speed")
            if speed < lower:
                raise ValueError(
                    f"PTUParams.{axis}_speed must be >= {axis}_lower_speed ({lower}), got {speed!r}"
                )

    @property
    def pan_deg_per_pos(self) -> float:
        """Degrees per pan position (0.025714 by default)."""
        return positions_to_degrees(1.0, self.pan_resolution_arcsec)

    @property
    def tilt_deg_per_pos(self) -> float:
        """Degrees per tilt position."""
        return positions_to_degrees(1.0, self.tilt_resolution_arcsec)

    @property
    def pan_limits_deg(self) -> tuple[float, float]:
        """(min, max) pan angle in degrees (≈ ±79.46° by default)."""
        r = self.pan_resolution_arcsec
        return positions_to_degrees(self.pan_min_pos, r), positions_to_degrees(self.pan_max_pos, r)

    @property
    def tilt_limits_deg(self) -> tuple[float, float]:
        """(min, max) tilt angle in degrees (≈ −23.32°…+15.53° by default)."""
        r = self.tilt_resolution_arcsec
        return (
            positions_to_degrees(self.tilt_min_pos, r),
            positions_to_degrees(self.tilt_max_pos, r),
        )

    def clip_deg(self, pan_deg: float, tilt_deg: float) -> tuple[float, float]:
        """Clip a (pan, tilt) target in degrees into the limits.

        >>> PTUParams().clip_deg(100.0, -5.0)[0] == PTUParams().pan_limits_deg[1]
        True
        """
        return clip_to_limits(pan_deg, tilt_deg, self.pan_limits_deg, self.tilt_limits_deg)

    def with_slew(self, speed_pos_s: float, accel_pos_s2: float) -> PTUParams:
        """These parameters with both axes' slew speed and acceleration set (positions/s,
        positions/s²) and the start speed capped to the slew speed.

        >>> p = PTUParams().with_slew(500.0, 4000.0)
        >>> p.tilt_speed, p.pan_base_speed, p.tilt_accel
        (500.0, 500.0, 4000.0)
        """
        return replace(
            self,
            pan_speed=speed_pos_s,
            tilt_speed=speed_pos_s,
            pan_base_speed=min(self.pan_base_speed, speed_pos_s),
            tilt_base_speed=min(self.tilt_base_speed, speed_pos_s),
            pan_accel=accel_pos_s2,
            tilt_accel=accel_pos_s2,
        )
