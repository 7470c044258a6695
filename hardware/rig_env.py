"""The rig environment: a real (or replayed) event camera on a real (or emulated) FLIR PTU.

:class:`RigEnv` has the observation and action spaces of the simulated
:class:`~wander_env.env.WanderEnv`, so one agent runs on both unchanged:

* action ``Box(-1, 1, (2,))``: a gaze offset in half-sensor units, turned into
  angles with the pinhole model (:func:`wander_env.actions.action_to_gaze_degrees`,
  focal length from the sensor width and ``hfov_deg``) and *added* to the PTU's
  current target (clipped to the unit's limits; ``info["target_clipped"]`` says
  so). A NaN, infinite or out-of-range action raises ``ValueError``;
* observation ``{"events": (2, H, W) float32 per-polarity counts of the step
  (channel 1 = ON), "gaze": (pan, tilt) degrees}`` (the last polled PTU position);
* ``info``: ``events`` (the step's raw events, ``t`` in µs since ``reset``, as a
  :class:`~wander_env.events.packet.EventPacket` like the sim's: ``.events`` is the array),
  ``t`` (s since ``reset``, the end of the step window), ``ptu_positions``,
  ``ptu_target_positions``, ``moving``, ``target_clipped``, and, rig only,
  ``command_latency_s`` (seconds from handing the latest acknowledged command to
  the PTU thread until the unit's ``*``; NaN before the first), ``dropped_events``
  (events the camera lost since ``reset``) and ``lag_s`` (how far the end of the
  step window trails the camera's clock; 0 for a fast replay).

Nothing about the devices is a constant here: the sensor size comes from the
source, the PTU's resolution (``ptu_resolution_arcsec``, pan and tilt, as the sim's) and
limits from the driver's queries; ``hfov_deg`` (the lens) from the config.

One step is one window of ``control_period_s`` of the camera's clock. The PTU command is
handed to a background thread that owns the serial line
(:class:`~hardware.ptu_link_thread.PTULinkThread`), so the event stream is never held up
by the (slow: 9600 baud) PTU exchange; a command not yet sent when the next one comes is
replaced by it (the targets are integrated, so nothing is lost). The same thread polls
the position (``PP``/``TP``) every ``ptu_poll_s``. With ``camera="speck"`` or a
real-time replay a step returns when the camera's clock has passed the window's end;
with ``replay="fast"`` at once, the windows advancing in stream time, so the events of
every step are fixed by the file (the PTU side stays real-time, hence
``nondeterministic=True``). With ``replay="stepped"`` the link runs in stream time too,
without its thread: a step sends its command and answers the polls due by the window's
end before it returns (one poll per ``ptu_poll_s`` of the recording), so what the agent
sees depends on the file and the unit's motion, not on how fast the host runs the steps.

Faults: a PTU that stops answering, answers ``!`` or garbage, or loses its port
mid-run (any error of the serial layer, ``termios.error`` included) makes the PTU
thread try a halt (``H``) and stop; the next :meth:`RigEnv.step`
(or :meth:`RigEnv.settle`, :meth:`RigEnv.reset`) raises the driver's error type
(:class:`~hardware.ptu_driver.PTUTimeout`, :class:`~hardware.ptu_driver.PTUError`
keeping the unit's ``message`` and ``command``) saying what happened and whether
the halt was acknowledged. A camera failure halts the PTU before it propagates.
:meth:`RigEnv.close` (idempotent) halts the PTU, closes its port and the camera;
opening failures (port missing or busy, samna missing, no Speck) close what was
already open before raising.

The PTU emulator and a replayed recording:

Examples:
    >>> import tempfile, gymnasium, hardware
    >>> from wander_env.events.io import EventRecording, write_events
    >>> from wander_env.events import make_events
    >>> tmp = tempfile.TemporaryDirectory()
    >>> path = f"{tmp.name}/two.npz"
    >>> ev = make_events(x=[1, 2], y=[3, 4], t=[0, 15_000], p=[1, 0])
    >>> write_events(path, EventRecording(ev, (128, 128, 2)))
    >>> env = gymnasium.make("wander/Rig-v0", ptu_port="emulate", camera=f"replay:{path}",
    ...                      replay="fast", driver=FlirPTUParams(banner_quiet_s=0.02))
    >>> obs, info = env.reset()
    >>> obs, reward, terminated, truncated, info = env.step(np.zeros(2, np.float32))
    >>> obs["events"].shape, int(obs["events"][1].sum()), info["t"], obs["gaze"].tolist()
    ((2, 128, 128), 1, 0.01, [0.0, 0.0])
    >>> env.close(); tmp.cleanup()
"""

from __future__ import annotations

import atexit
import math
import time
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from hardware.event_source import EventSource
from hardware.ptu_driver import FlirPTU, FlirPTUParams, PTUError, PTUTimeout
from hardware.ptu_emulator import PTUEmulator, PTUEmulatorParams
from hardware.ptu_link_thread import PTULinkThread
from hardware.replay import ReplaySource
from hardware.speck import SpeckParams, SpeckSource
from wander_env.camera import SPECK_HFOV_DEG, check_hfov_deg
from wander_env.config import FieldsMapping, check_fields
from wander_env.config_messages import shown
from wander_env.env_base import CameraEnv, StepInfo
from wander_env.env_config import control_period_us
from wander_env.events import empty_events
from wander_env.events.packet import EventPacket
from wander_env.ptu.link import PTULinkParams
from wander_env.ptu.units import clip_to_limits
from wander_env.viz import event_image, labelled_frame

_REPLAY_MODES = ("realtime", "fast", "stepped")


@dataclass(frozen=True)
class RigConfig(FieldsMapping):
    """What a :class:`RigEnv` opens and how it runs.

    ``ptu_port``: a pyserial URL of the FLIR PTU (``"/dev/ttyUSB0"``,
    ``"socket://host:4000"``) or ``"emulate"`` (a :class:`~hardware.ptu_emulator.PTUEmulator`
    with ``emulator`` parameters, its unit's ``emulator.ptu``: ``ptu`` is a
    :class:`~wander_env.ptu.params.PTUParams` block in every config); ``camera``:
    ``"speck"`` (``"speck:<serial>"`` for one board) or ``"replay:<event file>"``;
    ``replay``: ``"realtime"`` (paced by the wall clock), ``"fast"`` (windows advance
    in stream time) or ``"stepped"`` (windows and the PTU link's polls in stream time:
    see the module docstring); ``replay_loop`` repeats the file.
    ``control_period_s``: the step window (whole µs, at most 1 s: the sim's rule,
    :func:`wander_env.env_config.control_period_us`); ``episode_seconds``: truncation;
    ``start_gaze_deg``: where :meth:`RigEnv.reset` points the PTU (``None``: leave it);
    ``hfov_deg``: the lens's horizontal field of view (not queryable; Speck's by
    default; in (0, 180), :func:`wander_env.camera.check_hfov_deg`); ``ptu_poll_s``:
    position polling period (by default the sim link's, ``PTULinkParams.poll_s``);
    ``driver``, ``emulator``, ``speck``: the parameters of those parts
    (``emulator.ptu.link`` paces the emulator's line).

    >>> RigConfig(ptu_port="emulate", camera="replay:walk.npz").control_period_us
    10000
    """

    ptu_port: str = ""
    camera: str = ""
    replay: str = "realtime"
    replay_loop: bool = False
    control_period_s: float = 0.01
    episode_seconds: float = 10.0
    start_gaze_deg: tuple[float, float] | None = (0.0, 0.0)
    hfov_deg: float = SPECK_HFOV_DEG
    ptu_poll_s: float = PTULinkParams.poll_s
    driver: FlirPTUParams = field(default_factory=FlirPTUParams)
    emulator: PTUEmulatorParams = field(default_factory=PTUEmulatorParams)
    speck: SpeckParams = field(default_factory=SpeckParams)

    def __post_init__(self) -> None:
        if not isinstance(self.ptu_port, str) or not self.ptu_port.strip():
            raise ValueError(
                "RigConfig.ptu_port is required: the PTU's serial URL ('/dev/ttyUSB0', "
                f"'socket://host:4000') or 'emulate'; got {self.ptu_port!r}"
            )
        self.camera_kind()  # raises for a malformed camera
        if self.replay not in _REPLAY_MODES:
            raise ValueError(
                f"RigConfig.replay must be one of {_REPLAY_MODES}, got {self.replay!r}"
            )
        check_fields(self, ("episode_seconds", "ptu_poll_s"), positive=True)
        check_hfov_deg(self.hfov_deg, "RigConfig.hfov_deg")
        control_period_us(self.control_period_s, "RigConfig.control_period_s")
        if self.start_gaze_deg is not None:
            gaze = tuple(float(v) for v in self.start_gaze_deg)
            if len(gaze) != 2 or not all(math.isfinite(v) for v in gaze):
                raise ValueError(
                    f"RigConfig.start_gaze_deg must be (pan, tilt) finite degrees or None, "
                    f"got {self.start_gaze_deg!r}"
                )
            object.__setattr__(self, "start_gaze_deg", gaze)

    @property
    def control_period_us(self) -> int:
        """The step window in whole µs (:func:`wander_env.env_config.control_period_us`,
        the sim's rule)."""
        return control_period_us(self.control_period_s)

    def camera_kind(self) -> tuple[str, str]:
        """``("speck", serial or "")`` or ``("replay", path)``, from ``camera``.

        >>> RigConfig(ptu_port="emulate", camera="speck:sf-1").camera_kind()
        ('speck', 'sf-1')
        """
        kind, _, arg = str(self.camera).partition(":")
        if kind == "speck":
            return "speck", arg
        if kind == "replay" and arg:
            return "replay", arg
        raise ValueError(
            "RigConfig.camera must be 'speck', 'speck:<serial number>' or "
            f"'replay:<event file>', got {self.camera!r}"
        )


def _fault(err: PTUError, text: str) -> PTUError:
    """A copy of ``err`` (same type, ``message`` and ``command``) that reads ``text``."""
    out = type(err)(err.message, err.command)
    out.args = (text,)
    return out


class RigEnv(CameraEnv):
    """See the module docstring. Build with ``gymnasium.make("wander/Rig-v0", ...)``;
    ``speck_config``: a prepared samna configuration for the Speck (the attention front
    end's cores, :func:`hardware.speck_network.deploy`; camera ``"speck"`` only), which
    the :class:`~hardware.speck.SpeckSource` applies with the DVS layer's monitor on."""

    def __init__(
        self, render_mode: str | None = None, speck_config: Any = None, **config: Any
    ) -> None:
        self.config = RigConfig(**config)
        if speck_config is not None and self.config.camera_kind()[0] != "speck":
            raise ValueError(
                f"speck_config (a prepared Speck configuration) needs camera 'speck', "
                f"got {self.config.camera!r}"
            )
        self._speck_config = speck_config
        c = self.config
        self.init_render(render_mode, c.control_period_s)
        self.emulator: PTUEmulator | None = None
        self.ptu: FlirPTU | None = None
        self.camera: EventSource | None = None
        self._link: PTULinkThread | None = None
        self._stepped = False
        self._link_offset_s = 0.0
        self._closed = False
        try:
            self._open()
        except BaseException:
            self.close()
            raise
        atexit.register(self.close)  # an env left open still halts the PTU at exit
        self.hfov_deg = c.hfov_deg
        self.ptu_resolution_arcsec: tuple[float, float] = self.ptu.resolution_arcsec
        self.init_spaces(
            self.sensor_size[0],
            self.sensor_size[1],
            self.ptu.pan_limits_deg,
            self.ptu.tilt_limits_deg,
        )
        self._target: tuple[int, int] = self._link.snapshot()["acked"]
        self._positions: tuple[int, int] = self._link.snapshot()["positions"]
        self._t0_us = 0
        self._dropped_at_reset = 0
        self._discarded_at_reset = 0
        self._steps = 0
        self._ready = False

    # -- opening and closing --------------------------------------------------------------

    def _open(self) -> None:
        """PTU first (a camera stream should not run while the PTU is found faulty)."""
        c = self.config
        url = c.ptu_port
        if url == "emulate":
            self.emulator = PTUEmulator(c.emulator)
            url = self.emulator.port
        self.ptu = FlirPTU(url, c.driver)
        kind, arg = c.camera_kind()
        self._stepped = kind == "replay" and c.replay == "stepped"
        clock = self._link_clock if self._stepped else time.monotonic
        self._link = PTULinkThread(self.ptu, c.ptu_poll_s, clock)
        if not self._stepped:
            self._link.start()
        if kind == "speck":
            params = replace(c.speck, serial_number=arg) if arg else c.speck
            self.camera = SpeckSource(params, config=self._speck_config)
        else:
            self.camera = ReplaySource(arg, realtime=c.replay == "realtime", loop=c.replay_loop)
        self.camera.start()

    def _link_clock(self) -> float:
        """The stepped replay's link time: the camera's clock, plus the time the link
        has run alone while :meth:`settle` waited."""
        cursor_us = self.camera.cursor_us if self.camera is not None else 0
        return self._link_offset_s + cursor_us / 1e6

    def _serve_link(self) -> None:
        """The stepped replay's link: run every exchange due by now (a queued command,
        the poll right after it, the polls of ``ptu_poll_s``) in this thread."""
        while self._link.serve():
            pass

    def _settle_stepped(self, limit_s: float) -> bool:
        """:meth:`settle` of the stepped replay: poll until the unit rests on the target,
        False after ``limit_s`` (wall clock). The camera's clock stands still; the link's
        runs on to each next poll, one ``ptu_poll_s`` of wall clock apart (the unit moves
        in real time)."""
        link = self._link
        deadline = time.monotonic() + limit_s
        while True:
            self._serve_link()
            if link.error is not None or not link.snapshot(self._target)["moving"]:
                return True
            if time.monotonic() >= deadline:
                return False
            time.sleep(self.config.ptu_poll_s)
            self._link_offset_s += max(0.0, link.schedule.due_s() - self._link_clock())

    def close(self) -> None:
        """Halt the PTU and close its port, close the camera and the emulator; idempotent.

        Never raises for a device that no longer answers (the driver logs it).
        """
        if getattr(self, "_closed", True):
            return
        self._closed = True
        atexit.unregister(self.close)
        try:
            if self._link is not None:
                self._link.close()
        finally:
            try:
                if self.ptu is not None:
                    self.ptu.close()  # halts (H), homes with driver.home_on_close
            finally:
                try:
                    if self.camera is not None:
                        self.camera.close()
                finally:
                    if self.emulator is not None:
                        self.emulator.close()
        super().close()

    # -- devices ----------------------------------------------------------------------------

    @property
    def sensor_size(self) -> tuple[int, int, int]:
        """``(W, H, 2)`` as the camera reports it."""
        return tuple(int(v) for v in self.camera.sensor_size)  # type: ignore[return-value]

    @property
    def stats(self) -> dict[str, Any]:
        """Counters: steps, PTU commands sent/replaced and polls, the episode's start in the
        camera's clock (``t0_us``), events discarded by ``reset`` and lost before it.
        """
        link = self._link
        return {
            "steps": self._steps,
            **(link.counts if link is not None else {}),
            "t0_us": self._t0_us,
            "discarded_at_reset": self._discarded_at_reset,
            "dropped_at_reset": self._dropped_at_reset,
            "ptu_halt": link.halt_result if link is not None else None,
            "ptu_error": shown(link.error) if link is not None and link.error else None,
            "camera": self.camera.stats if self.camera is not None else None,
        }

    def settle(self, timeout_s: float | None = None) -> None:
        """Block until the PTU rests on the commanded target.

        Raises the PTU fault if one happened, ``TimeoutError`` after ``timeout_s``
        (default: the driver's ``await_timeout_s``).
        """
        self._check_open()
        limit = self.config.driver.await_timeout_s if timeout_s is None else timeout_s
        try:
            if self._stepped:
                ok = self._settle_stepped(limit)
            else:
                ok = self._link.wait(self._target, limit)
        except BaseException:  # KeyboardInterrupt while waiting: stop the unit too
            self.halt_after_failure()
            raise
        self._raise_if_faulted()
        if not ok:
            halt = self._link.halt_now()
            raise TimeoutError(
                f"the PTU did not reach its target {self._target} (positions) within {limit} s; "
                f"last polled at {self._link.snapshot()['positions']}; {halt}"
            )

    def _check_open(self) -> None:
        if self._closed:
            raise RuntimeError("RigEnv is closed; create a new one")

    def _raise_if_faulted(self) -> None:
        link = self._link
        if link is not None and link.error is not None:
            err = link.error
            what = "stopped answering" if isinstance(err, PTUTimeout) else "failed"
            raise _fault(
                err,
                f"PTU {self.ptu.url!r} {what} mid-run (after {self._steps} steps): {err}. "
                f"Then {link.halt_result}. The env can only be closed now (if the halt was not "
                "acknowledged the unit may still be moving: switch it off).",
            ) from err

    def halt_after_failure(self) -> None:
        """Leave the PTU halted when something else fails (camera, interrupt)."""
        if self._link is not None and self._link.error is None:
            self._link.halt_now()

    # -- gymnasium API ----------------------------------------------------------------------

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        """Point the PTU at the start gaze and wait for it, then drop the events until now.

        ``options={"gaze_deg": (pan, tilt)}`` overrides ``start_gaze_deg``.
        """
        super().reset(seed=seed)
        self._check_open()
        self._raise_if_faulted()
        gaze = (options or {}).get("gaze_deg", self.config.start_gaze_deg)
        clipped = False
        if gaze is not None:
            clipped = self.aim(*(float(v) for v in gaze))
            self.settle()
        cam = self.camera
        try:
            now = max(cam.cursor_us, cam.now_us())
            self._discarded_at_reset = len(cam.read(until_t_us=now))
        except BaseException:
            self.halt_after_failure()
            raise
        self._t0_us = cam.cursor_us
        self._dropped_at_reset = cam.dropped
        self._steps = 0
        self._ready = True
        info = self._info(empty_events(), clipped, lag_s=0.0)
        return self.observe(None), info

    def check_ready(self) -> None:
        self._check_open()
        if not self._ready:
            raise RuntimeError("call reset() before step()")
        self._raise_if_faulted()

    def collect(self, clipped: bool) -> tuple[np.ndarray, StepInfo]:
        """Collect the step window's events (the new target is with the PTU thread)."""
        cam = self.camera
        try:
            if self._stepped:
                self._serve_link()  # the command, at the window's start
            events = cam.read(duration_us=self.config.control_period_us)
            if self._stepped:
                self._serve_link()  # the polls due by the window's end
        except BaseException:
            self.halt_after_failure()
            raise
        self._steps += 1
        self._raise_if_faulted()
        lag_s = max(0.0, (cam.now_us() - cam.cursor_us) * 1e-6)
        return events, self._info(events, clipped, lag_s)  # one snapshot: gaze and `moving`

    def truncated(self, info: StepInfo) -> bool:
        return self.episode_over(info["t"]) or bool(getattr(self.camera, "finished", False))

    # -- the target -------------------------------------------------------------------------

    @property
    def target_deg(self) -> tuple[float, float]:
        """The commanded (pan, tilt) target in degrees."""
        return self._link.to_degrees(self._target)

    def clip_target(self, pan_deg: float, tilt_deg: float) -> tuple[float, float]:
        return clip_to_limits(pan_deg, tilt_deg, self.ptu.pan_limits_deg, self.ptu.tilt_limits_deg)

    def set_target(self, pan_deg: float, tilt_deg: float) -> None:
        """Hand the target (as whole positions) to the PTU thread when it changed."""
        target = self._link.to_positions((pan_deg, tilt_deg))
        if target != self._target:
            self._target = target
            self._link.command(target)

    def gaze(self) -> np.ndarray:
        """The PTU position of the latest ``info`` (the last poll) in degrees."""
        pan, tilt = self._link.to_degrees(self._positions)
        return np.array([pan, tilt], np.float32)

    def _info(self, events: np.ndarray, clipped: bool, lag_s: float) -> StepInfo:
        events["t"] -= self._t0_us
        snap = self._link.snapshot(self._target)
        self._positions = snap["positions"]
        return StepInfo(
            events=EventPacket(events),
            t=(self.camera.cursor_us - self._t0_us) / 1e6,
            ptu_positions=snap["positions"],
            ptu_target_positions=self._target,
            ptu_target_deg=self._link.to_degrees(self._target),
            moving=snap["moving"],
            target_clipped=clipped,
            command_latency_s=snap["latency_s"],
            dropped_events=self.camera.dropped - self._dropped_at_reset,
            lag_s=lag_s,
        )

    def render(self) -> np.ndarray | None:
        """The event frame of the last step (3x), named, with the time stamp and the
        ON/OFF key, for ``render_mode="rgb_array"``."""
        if self.render_mode != "rgb_array":
            return None
        t = (self.camera.cursor_us - self._t0_us) / 1e6
        panel = [("events (last step)", event_image(self.last_counts))]
        return labelled_frame(panel, 3, f"t = {t:5.2f} s", keys=("polarity", "fovea"))


__all__ = ["RigConfig", "RigEnv"]
