"""The stateful pan-tilt unit (:class:`PanTiltUnit`) the env steps, and the camera's
:class:`Trajectory` over one step.

Targets are in degrees; each axis moves by :mod:`wander_env.ptu.axis`, the camera
follows through :mod:`wander_env.ptu.mechanics`, and with a serial link
(:mod:`wander_env.ptu.link`) commands reach the axes late, as on the rig.

Examples:
    >>> from wander_env.ptu.params import PTUParams
    >>> from wander_env.ptu.unit import PanTiltUnit
    >>> ptu = PanTiltUnit(PTUParams(pan_base_speed=0.0, pan_speed=1000.0))
    >>> ptu.set_target(pan_deg=1000 * ptu.params.pan_deg_per_pos, tilt_deg=0.0)
    >>> for _ in range(1500):
    ...     ptu.step(0.001)
    >>> ptu.positions, ptu.moving
    ((1000, 0), False)
"""

from __future__ import annotations

import bisect
import copy
import math
from dataclasses import dataclass

from wander_env.ptu.axis import REL_TOL, AxisState, axis_path
from wander_env.ptu.link import CommandLink
from wander_env.ptu.mechanics import backlash, camera_position
from wander_env.ptu.params import PTUParams
from wander_env.ptu.units import (
    degrees_to_positions,
    positions_to_degrees,
    round_position,
    step_counter,
    whole_speed,
)


@dataclass(frozen=True)
class Trajectory:
    """The camera's angles over one span of ticks, from :meth:`PanTiltUnit.trajectory`.

    ``t_us[i]`` is the end of tick ``i`` (tick 0 starts at ``t0_us``) and ``pan_deg[i]``,
    ``tilt_deg[i]`` the camera's angles there (after backlash); ``starts[i]`` is the unit
    as it was at the start of tick ``i`` (a copy, never stepped), from which
    :meth:`at` evaluates angles at times inside the span (adaptive sub-frames).
    """

    t0_us: int
    t_us: tuple[int, ...]
    pan_deg: tuple[float, ...]
    tilt_deg: tuple[float, ...]
    starts: tuple[PanTiltUnit, ...]

    def angles(self, i: int) -> tuple[float, float]:
        """Camera (pan, tilt) in degrees at the end of tick ``i``."""
        return self.pan_deg[i], self.tilt_deg[i]

    def at(self, times_us: list[int]) -> list[tuple[float, float]]:
        """Camera (pan, tilt) at increasing ``times_us`` inside the span (adaptive
        sub-frames): per tick, a copy of the unit at its start stepped from one time to
        the next (the unit that made the trajectory is not touched); a tick's end
        reached in one step from its start is the trajectory's own angles there (the
        same step)."""
        out = []
        tick, unit, t_prev = -1, None, self.t0_us
        for t in times_us:
            i = bisect.bisect_left(self.t_us, t)
            if not (i < len(self.t_us) and (self.t_us[i - 1] if i else self.t0_us) < t):
                raise ValueError(f"t={t} µs is not inside ({self.t0_us}, {self.t_us[-1]}]")
            if i != tick:
                tick, unit = i, None
                t_prev = self.t_us[i - 1] if i else self.t0_us
            if unit is None and t == self.t_us[i]:  # the tick's end, as the trajectory has it
                out.append(self.angles(i))
                continue
            if unit is None:
                unit = self.starts[i].copy()
            unit.step((t - t_prev) * 1e-6)
            t_prev = t
            out.append((unit.camera_pan_deg, unit.camera_tilt_deg))
        return out


class PanTiltUnit:
    """A two-axis PTU: targets in degrees, :meth:`step` advances the motion model.

    Targets outside the limits raise ``ValueError`` (as the FLIR unit answers
    ``!`` and does not move); :meth:`clip_target` clips one into range first.

    >>> ptu = PanTiltUnit(PTUParams(tilt_backlash_pos=10.0))
    >>> ptu.set_target(tilt_deg=5.0)
    >>> ptu.step(1.0)
    >>> round(ptu.tilt_deg, 3), round(ptu.tilt_deg - ptu.camera_tilt_deg, 4)
    (4.989, 0.1286)
    """

    def __init__(self, params: PTUParams | None = None) -> None:
        self.params = params if params is not None else PTUParams()
        self.reset()

    # -- commands ---------------------------------------------------------------------

    def reset(self, pan_deg: float = 0.0, tilt_deg: float = 0.0) -> None:
        """Place the unit at rest at (pan, tilt), camera on the motor (play centred)."""
        pan = self._to_pos("pan", pan_deg)
        tilt = self._to_pos("tilt", tilt_deg)
        self._pan = AxisState(pan, 0.0)
        self._tilt = AxisState(tilt, 0.0)
        self._target = [pan, tilt]  # commanded (what target_deg reports)
        self._drive = [pan, tilt]  # what the axes move to (the unit's target)
        self._speed = [self.params.pan_speed, self.params.tilt_speed]
        self._camera = [self._motor(pan), self._motor(tilt)]
        self._time_s = 0.0
        link = self.params.link
        self.link = (
            CommandLink(link, (round_position(pan), round_position(tilt)))
            if link is not None
            else None
        )

    def copy(self) -> PanTiltUnit:
        """An independent unit in the same state."""
        twin = copy.copy(self)
        twin._target, twin._drive, twin._speed, twin._camera = (
            list(self._target),
            list(self._drive),
            list(self._speed),
            list(self._camera),
        )
        twin.link = self.link.copy() if self.link is not None else None
        return twin

    def set_target(self, pan_deg: float | None = None, tilt_deg: float | None = None) -> None:
        """Command an absolute target in degrees; ``None`` keeps that axis's target.

        Raises ``ValueError`` naming the limit when a target is out of range. With a
        :attr:`link` a changed target is handed to it (it reaches the axes later).
        """
        pan = self._to_pos("pan", pan_deg) if pan_deg is not None else None
        tilt = self._to_pos("tilt", tilt_deg) if tilt_deg is not None else None
        self._command(pan, tilt)

    def _command(self, pan: float | None, tilt: float | None) -> None:
        old = tuple(self._target)
        if pan is not None:
            self._target[0] = pan
        if tilt is not None:
            self._target[1] = tilt
        if self.link is None:
            self._drive = list(self._target)
        elif tuple(self._target) != old:
            whole = (round_position(self._target[0]), round_position(self._target[1]))
            self.link.submit(whole, self._time_s)

    def set_target_positions(
        self, pan_pos: float | None = None, tilt_pos: float | None = None
    ) -> None:
        """As :meth:`set_target`, in PTU positions (for a FLIR protocol front end)."""
        pan = self._check_pos("pan", pan_pos) if pan_pos is not None else None
        tilt = self._check_pos("tilt", tilt_pos) if tilt_pos is not None else None
        self._command(pan, tilt)

    def drive_axis(self, axis: int, pos: float) -> None:
        """Give axis 0 (pan) or 1 (tilt) its new target now (the link's command has
        arrived at the unit)."""
        self._drive[axis] = float(pos)

    def step_counter(self, axis: int) -> int:
        """What a ``PP``/``TP`` query of axis 0/1 answers now
        (:func:`~wander_env.ptu.units.step_counter`)."""
        state = self._pan if axis == 0 else self._tilt
        return step_counter(state.position, state.velocity)

    def clip_target(self, pan_deg: float, tilt_deg: float) -> tuple[float, float]:
        """(pan, tilt) in degrees clipped into the limits; see
        :meth:`~wander_env.ptu.params.PTUParams.clip_deg`."""
        return self.params.clip_deg(pan_deg, tilt_deg)

    def set_speed(self, pan_deg_s: float | None = None, tilt_deg_s: float | None = None) -> None:
        """Change the slew speed on the fly (FLIR ``PS``/``TS``), in degrees per second;
        ``None`` keeps it.

        The unit takes whole positions/s within the axis's ``lower_speed`` and
        ``upper_speed`` (:func:`~wander_env.ptu.units.whole_speed`, the rig driver's
        rule); a speed outside raises ``ValueError`` and changes neither axis.

        >>> ptu = PanTiltUnit()
        >>> ptu.set_speed(pan_deg_s=10.0)
        >>> ptu.speeds
        (389.0, 2000.0)
        """
        p = self.params
        speeds = list(self._speed)
        for i, (axis, value) in enumerate((("pan", pan_deg_s), ("tilt", tilt_deg_s))):
            if value is None:
                continue
            pos_s = degrees_to_positions(value, getattr(p, f"{axis}_resolution_arcsec"))
            lower, upper = getattr(p, f"{axis}_lower_speed"), getattr(p, f"{axis}_upper_speed")
            speeds[i] = float(whole_speed(axis, pos_s, lower, upper))
        self._speed = speeds

    def step(self, dt_s: float) -> None:
        """Advance the motion model by ``dt_s`` seconds (with a :attr:`link`, stopping at
        each of its events: the split does not change the exact motion)."""
        if not (math.isfinite(dt_s) and dt_s >= 0):
            raise ValueError(f"dt_s must be a finite number >= 0, got {dt_s!r}")
        if self.link is None:
            self._advance(dt_s)
            return
        t_end = self._time_s + dt_s
        while self.link.next_time() <= t_end:
            self._advance(max(self.link.next_time() - self._time_s, 0.0))
            self.link.fire(self)
        self._advance(max(t_end - self._time_s, 0.0))
        self._time_s = t_end

    def trajectory(self, t0_us: int, t1_us: int, tick_us: int) -> Trajectory:
        """Step the unit from ``t0_us`` to ``t1_us`` once per tick of ``tick_us`` (the last
        tick ends at ``t1_us``) and return the camera's angles at every tick's end: the
        one motion of a control step, which every frame source reads.

        >>> ptu = PanTiltUnit()
        >>> ptu.set_target(pan_deg=1.0)
        >>> tr = ptu.trajectory(0, 3000, 1000)
        >>> tr.t_us, round(tr.pan_deg[-1], 6) == round(ptu.camera_pan_deg, 6)
        ((1000, 2000, 3000), True)
        """
        if tick_us <= 0 or t1_us <= t0_us:
            raise ValueError(f"need tick_us > 0 and t1_us > t0_us, got {tick_us}, {t0_us}, {t1_us}")
        times, pans, tilts, starts = [], [], [], []
        t = t0_us
        while t < t1_us:
            t_next = min(t + tick_us, t1_us)
            starts.append(self.copy())
            self.step((t_next - t) * 1e-6)
            t = t_next
            times.append(t)
            pans.append(self.camera_pan_deg)
            tilts.append(self.camera_tilt_deg)
        return Trajectory(t0_us, tuple(times), tuple(pans), tuple(tilts), tuple(starts))

    def _advance(self, dt_s: float) -> None:
        p = self.params
        axes = (
            (self._pan, p.pan_accel, p.pan_base_speed, p.pan_backlash_pos),
            (self._tilt, p.tilt_accel, p.tilt_base_speed, p.tilt_backlash_pos),
        )
        new = []
        for i, (state, accel, base, play) in enumerate(axes):
            vb = min(base, self._speed[i])
            nxt, path = axis_path(state, self._drive[i], dt_s, self._speed[i], accel, vb)
            for q in [*path, nxt.position]:
                self._camera[i] = backlash(self._camera[i], self._motor(q), play)
            new.append(nxt)
        self._pan, self._tilt = new
        self._time_s += dt_s

    # -- state ------------------------------------------------------------------------

    @property
    def time_s(self) -> float:
        """Seconds of motion simulated since :meth:`reset`."""
        return self._time_s

    @property
    def pan_deg(self) -> float:
        """Pan joint angle reached (degrees; on whole positions when ``quantise``)."""
        return positions_to_degrees(
            self._motor(self._pan.position), self.params.pan_resolution_arcsec
        )

    @property
    def tilt_deg(self) -> float:
        """Tilt joint angle reached (degrees; on whole positions when ``quantise``)."""
        return positions_to_degrees(
            self._motor(self._tilt.position), self.params.tilt_resolution_arcsec
        )

    @property
    def camera_pan_deg(self) -> float:
        """Pan of the optical axis after backlash (degrees)."""
        return positions_to_degrees(self._camera[0], self.params.pan_resolution_arcsec)

    @property
    def camera_tilt_deg(self) -> float:
        """Tilt of the optical axis after backlash (degrees)."""
        return positions_to_degrees(self._camera[1], self.params.tilt_resolution_arcsec)

    @property
    def camera_position_m(self) -> tuple[float, float, float]:
        """Camera centre in the PTU frame (m), from the camera angles and hinge offset."""
        return camera_position(
            self.camera_tilt_deg,
            self.params.camera_forward_m,
            self.params.camera_up_m,
            self.camera_pan_deg,
        )

    @property
    def positions(self) -> tuple[int, int]:
        """(pan, tilt) motor positions as the unit reports them (``PP``/``TP``)."""
        return round_position(self._pan.position), round_position(self._tilt.position)

    @property
    def speeds(self) -> tuple[float, float]:
        """(pan, tilt) slew speeds (positions/s): the configured ones until
        :meth:`set_speed` sets whole ones."""
        return self._speed[0], self._speed[1]

    @property
    def target_positions(self) -> tuple[float, float]:
        """(pan, tilt) targets in positions (whole numbers when ``quantise``)."""
        return self._target[0], self._target[1]

    @property
    def target_deg(self) -> tuple[float, float]:
        """(pan, tilt) targets in degrees."""
        return (
            positions_to_degrees(self._target[0], self.params.pan_resolution_arcsec),
            positions_to_degrees(self._target[1], self.params.tilt_resolution_arcsec),
        )

    @property
    def pan_velocity_deg_s(self) -> float:
        """Signed pan velocity (degrees/s)."""
        return positions_to_degrees(self._pan.velocity, self.params.pan_resolution_arcsec)

    @property
    def tilt_velocity_deg_s(self) -> float:
        """Signed tilt velocity (degrees/s)."""
        return positions_to_degrees(self._tilt.velocity, self.params.tilt_resolution_arcsec)

    @property
    def velocities_deg_s(self) -> tuple[float, float]:
        """(pan, tilt) signed velocities (degrees/s)."""
        return self.pan_velocity_deg_s, self.tilt_velocity_deg_s

    @property
    def moving(self) -> bool:
        """True until both axes are at rest on their targets; with a :attr:`link`, as
        the rig sees it (:meth:`~wander_env.ptu.link.CommandLink.moving`)."""
        if self.link is not None:
            return self.link.moving(
                (round_position(self._target[0]), round_position(self._target[1]))
            )
        return any(
            s.velocity != 0.0 or s.position != t
            for s, t in ((self._pan, self._drive[0]), (self._tilt, self._drive[1]))
        )

    @property
    def command_latency_s(self) -> float:
        """The latest command's latency on the :attr:`link` (NaN without one or before
        the first acknowledged command)."""
        return self.link.schedule.latency_s if self.link is not None else math.nan

    # -- helpers ----------------------------------------------------------------------

    def _motor(self, pos: float) -> float:
        """The motor's position as it stands: on a whole step when ``quantise``."""
        return float(round_position(pos)) if self.params.quantise else pos

    def _to_pos(self, axis: str, deg: float) -> float:
        if not math.isfinite(deg):
            raise ValueError(f"{axis} target must be a finite angle in degrees, got {deg!r}")
        pos = degrees_to_positions(deg, getattr(self.params, f"{axis}_resolution_arcsec"))
        return self._check_pos(axis, pos, deg)

    def _check_pos(self, axis: str, pos: float, deg: float | None = None) -> float:
        if not math.isfinite(pos):
            raise ValueError(f"{axis} target must be finite, got {pos!r}")
        if self.params.quantise:
            pos = float(round_position(pos))
        lo = getattr(self.params, f"{axis}_min_pos")
        hi = getattr(self.params, f"{axis}_max_pos")
        tol = REL_TOL * max(abs(pos), 1.0)
        if pos < lo - tol or pos > hi + tol:
            lo_d, hi_d = getattr(self.params, f"{axis}_limits_deg")
            shown = f"{deg!r}° = {pos:g} positions" if deg is not None else f"{pos:g} positions"
            bound = f"{axis}_min_pos = {lo}" if pos < lo else f"{axis}_max_pos = {hi}"
            raise ValueError(
                f"{axis} target {shown} is outside the limit {bound} "
                f"(range {lo_d:.4f}°…{hi_d:.4f}°); use clip_target to clip it"
            )
        return min(max(pos, float(lo)), float(hi))
