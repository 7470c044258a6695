"""``wander rig``: the attention agent on the rig, writing the same run folder as ``wander run``.

The rig is an event camera (a Speck, or a recorded event file replayed as one) on a FLIR
pan-tilt unit (a real one on a serial port, or the protocol emulator): the
``wander/Rig-v0`` env of :mod:`hardware.rig_env`. :func:`run_rig` builds it, runs the
same :class:`~agents.attention.AttentionAgent` as ``wander run`` through
:func:`experiments.jobs.run_agent.run_closed_loop`, and adds what only the rig has:

- ``run.json`` (and the ``events.h5`` metadata): the config, plus ``rig``: the PTU's
  resolution and limits and the sensor size, as the devices reported them, and the
  lens's field of view the run assumed (``hfov_deg``, ``hfov_from``: the ``--hfov``
  given or the Speck's lens by default — a recording from another camera, e.g. a
  DVS128, is scored with the field of view given here);
- with the Speck front end as the agent's sOMS (``agent.soms: speck``), ``rig.front_end``
  in ``run.json``: ``"chip"`` with a live Speck (:func:`run_rig` checks and builds the
  network's configuration with :func:`hardware.speck_network.deploy` before the device
  is opened, so a network that does not fit is refused with one line and nothing is
  touched; the camera applies that one configuration with its DVS monitor on, and the
  agent reads the monitored cores' spikes through
  :class:`~hardware.speck_network.ChipPipeline` on the same device), ``"simulated"``
  with a replayed recording (the same quantised model on the host);
- with a replayed recording, ``fixed_view`` in ``run.json``: the recorded camera did not
  turn with the PTU, so ``scanpath.png`` draws saliency and ``P`` in the sensor's frame
  (not on the pan-tilt sphere) and says so;
- ``metrics.json``: ``rig``: events the camera dropped (queue overflow, late, off the
  sensor), the PTU command latency (mean and max over the acknowledged commands seen at
  step boundaries), commands sent and replaced, polls, the largest lag behind the
  camera's clock, the episode's start in the camera's clock (``t0_us``: ``events.h5``
  times are relative to it), the halt result and the PTU error if any, and the camera's
  counters; ``front_end`` (as in ``run.json``) and ``front_end_spikes``, the spikes read
  from the chip's monitored cores (``None`` unless the front end runs on the chip).

A device that fails raises :class:`RigRunError` naming the device and saying what went
wrong; when the run had started the run folder is written first with what was recorded
(``metrics.json`` then has ``error`` and the ``steps`` done). A fault or a signal in the
loop halts the PTU (``H``) as soon as the loop stops, before the video and the folder are
written; a signal is taken up between two steps (every wait in a step is bounded by a
control period or a device timeout), not inside a device read (a second signal before
that is raised at once, to wake a wait: :class:`~experiments.runs.signals.DeferredSignals`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Annotated, Any

import gymnasium as gym
import numpy as np
import pydantic

from agents.attention import AgentParams, AttentionAgent
from agents.speck_front import SpeckFrontParams
from agents.speck_limits import SpeckLimitError
from experiments.jobs.run_agent import (
    VIDEO_FPS,
    OneEpisodeRun,
    RunResult,
    run_for_config,
)
from experiments.runs.episode import Recorder
from experiments.runs.folder import METRICS_JSON, RunFolder
from experiments.runs.provenance import run_record
from experiments.studies.framework import MAX_SEED
from hardware.ptu_driver import PTUError, PTUFlood, PTUPortError, PTUTimeout
from hardware.rig_env import RigConfig
from wander_env.camera import SPECK_HFOV_DEG
from wander_env.readout import SPECK_DVS_SIZE
from wander_env.strict_json import to_strict_json
from wander_env.untrusted import UntrustedFileError

__all__ = [
    "RigCounters",
    "RigRunConfig",
    "RigRunError",
    "chip_front",
    "fixed_view_note",
    "front_end",
    "run_rig",
]


@dataclass(frozen=True)
class RigRunConfig(OneEpisodeRun):
    """What ``wander rig`` runs: the rig env's block ``env``
    (:class:`~hardware.rig_env.RigConfig`: the PTU's pyserial URL or ``"emulate"``, the
    camera ``"speck"``, ``"speck:<serial>"`` or ``"replay:<event file>"``, the replay's
    pacing, ``episode_seconds`` as the run's length (a replay that ends earlier ends the
    run), ``hfov_deg`` as the lens's field of view, the device parameter blocks);
    ``seed``, ``video``, ``video_fps`` and the agent's block ``agent``: as ``wander run``
    (the agent's sensor, step and lens are the rig's).

    >>> RigRunConfig(RigConfig(ptu_port="emulate", camera="replay:walk.npz")).seconds
    10.0
    """

    env: RigConfig
    seed: Annotated[int, pydantic.Field(ge=0, le=MAX_SEED)] = 0
    video: bool = True
    video_fps: Annotated[int, pydantic.Field(ge=1, le=1000)] = VIDEO_FPS
    agent: AgentParams = field(default_factory=AgentParams)


class RigRunError(RuntimeError):
    """A device failed: one line naming the device and the failure.

    ``device`` (``"PTU '/dev/ttyUSB0'"``, ``"camera 'speck'"``), ``stage`` (``"open"``
    or ``"run"``), ``folder`` (the run folder written with what was recorded, ``None``
    when the run had not started); the original error is ``__cause__``.
    """

    def __init__(self, text: str, device: str, stage: str, folder: Path | None) -> None:
        super().__init__(" ".join(text.split()))
        self.device = device
        self.stage = stage
        self.folder = folder


class RigCounters(Recorder):
    """Sees every step's ``info`` and keeps the rig's counters; ``metrics()``:
    ``{"rig": ...}`` (module doc; valid also after a fault)."""

    def __init__(self, env: gym.Env, front_end: str | None = None, chip: Any = None) -> None:
        self.base = env.unwrapped
        self.front_end = front_end
        self.chip = chip  # the ChipPipeline of a front end on the chip, or None
        self.latencies: list[float] = []
        self.lag_max_s = 0.0
        self._sent = 0

    def on_reset(self, env: Any, policy: Any, obs: Any, info: dict[str, Any]) -> None:
        self.latencies, self.lag_max_s = [], 0.0
        self._sent = self.base.stats["commands_sent"]

    def on_step(self, env: Any, policy: Any, obs: Any, info: dict[str, Any]) -> None:
        sent = self.base.stats["commands_sent"]
        latency = float(info.get("command_latency_s", math.nan))
        if sent != self._sent and math.isfinite(latency):
            self.latencies.append(latency)
        self._sent = sent
        self.lag_max_s = max(self.lag_max_s, float(info.get("lag_s", 0.0)))

    def metrics(self) -> dict[str, Any]:
        return {"rig": self.summary()}

    def summary(self) -> dict[str, Any]:
        """The counters (valid also after a fault)."""
        base = self.base
        stats = base.stats
        camera = base.camera
        lat = np.asarray(self.latencies, dtype=np.float64)
        return {
            "dropped_events": int(camera.dropped) - int(stats["dropped_at_reset"]),
            "command_latency_mean_s": float(lat.mean()) if len(lat) else math.nan,
            "command_latency_max_s": float(lat.max()) if len(lat) else math.nan,
            "command_latencies_seen": len(lat),
            "ptu_commands_sent": stats.get("commands_sent", 0),
            "ptu_commands_replaced": stats.get("commands_replaced", 0),
            "ptu_polls": stats.get("polls", 0),
            "lag_max_s": self.lag_max_s,
            "t0_us": stats["t0_us"],
            "discarded_at_reset": stats["discarded_at_reset"],
            "ptu_halt": stats["ptu_halt"],
            "ptu_error": stats["ptu_error"],
            "camera": stats["camera"],
            "front_end": self.front_end,
            "front_end_spikes": None if self.chip is None else self.chip.spikes_read,
        }


def device_record(base: Any) -> dict[str, Any]:
    """What the devices reported: the PTU's resolution and limits, the sensor size."""
    ptu = base.ptu
    camera = base.camera
    kind, arg = base.config.camera_kind()
    cam: dict[str, Any] = {"kind": kind, "sensor_size": list(base.sensor_size)}
    if kind == "replay":
        cam |= {"file": arg, "n_events": camera.n_events, "duration_us": camera.duration_us}
        cam["t_offset_us"] = camera.metadata.get("t_offset_us")
    else:
        cam |= {"device_type_name": camera.device_type_name, "serial_number": arg or None}
        cam["sensor_size_from"] = camera.stats.get("sensor_size_from")
    hfov = base.config.hfov_deg
    return {
        "ptu": {
            "url": ptu.url,
            "emulated": base.emulator is not None,
            "resolution_arcsec": list(ptu.resolution_arcsec),
            "pan_limits_deg": list(ptu.pan_limits_deg),
            "tilt_limits_deg": list(ptu.tilt_limits_deg),
        },
        "camera": cam,
        "control_period_s": base.config.control_period_s,
        "hfov_deg": hfov,
        "hfov_from": "the Speck's lens, the default" if hfov == SPECK_HFOV_DEG else "--hfov",
    }


def fixed_view_note(rig: dict[str, Any]) -> str | None:
    """What ``scanpath.png`` says of a replayed recording (None for a live camera): its
    view is fixed, so the figure is in the sensor's frame; and the field of view assumed.

    >>> rig = {"camera": {"kind": "replay", "file": "/d/walk.h5"}, "hfov_deg": 112.83,
    ...        "hfov_from": "--hfov"}
    >>> fixed_view_note(rig).splitlines()[0]
    "replayed recording 'walk.h5': its view is fixed (the recorded camera did not"
    """
    camera = rig["camera"]
    if camera["kind"] != "replay":
        return None
    return (
        f"replayed recording {Path(camera['file']).name!r}: its view is fixed (the recorded "
        "camera did not\nturn with the PTU), so saliency and P are drawn in the sensor's "
        f"frame;\nfield of view {rig['hfov_deg']:.1f}° ({rig['hfov_from']})"
    )


def front_end(config: RigRunConfig) -> str | None:
    """Where the agent's Speck front end (``agent.soms`` a
    :class:`~agents.speck_front.SpeckFrontParams`) runs: ``"chip"`` on a live Speck (the
    configuration of :func:`hardware.speck_network.deploy`), ``"simulated"`` with a
    replayed camera (the same quantised sinabs model on the host); ``None`` for another
    sOMS. ``run.json`` says so as ``rig.front_end``.

    >>> env = RigConfig(ptu_port="emulate", camera="replay:walk.npz")
    >>> front_end(RigRunConfig(env, agent=AgentParams(soms="speck")))
    'simulated'
    """
    if not isinstance(config.agent.soms, SpeckFrontParams):
        return None
    return "chip" if config.env.camera_kind()[0] == "speck" else "simulated"


def chip_front(config: RigRunConfig) -> SpeckFrontParams:
    """The front end deployed on the chip: the agent's block made consistent with the
    rig's step (its leak per step) on the chip's pixel array, as the agent will resolve it
    once the camera is open (:func:`run_rig` checks that it does)."""
    agent = replace(
        config.agent,
        step_s=config.env.control_period_s,
        width_px=SPECK_DVS_SIZE[0],
        height_px=SPECK_DVS_SIZE[1],
    )
    return agent.resolved().soms


def _device(err: BaseException, config: RigRunConfig) -> str | None:
    """Which device ``err`` comes from (``None``: not a device failure)."""
    if isinstance(err, (PTUError, TimeoutError)):
        return f"PTU {config.env.ptu_port!r}"
    return None


def _open_failure(err: Exception, config: RigRunConfig) -> RigRunError:
    device = _device(err, config) or f"camera {config.env.camera!r}"
    if isinstance(err, PTUError) and not isinstance(err, (PTUPortError, PTUTimeout, PTUFlood)):
        if err.command is not None:
            why = f"the unit answered '! {err.message}' to {err.command!r}"
        else:
            why = str(err)
    else:
        why = str(err) or type(err).__name__
    return RigRunError(f"opening the {device} failed: {why}", device, "open", None)


def _run_failure(err: BaseException, config: RigRunConfig, out: Path, steps: int) -> RigRunError:
    device = _device(err, config) or f"camera {config.env.camera!r}"
    text = str(err)
    if not text.startswith(("PTU ", "camera ")):
        text = f"{device} failed mid-run: {text}"
    return RigRunError(
        f"{text} The run folder {str(out)!r} holds what was recorded ({steps} steps completed).",
        device,
        "run",
        out,
    )


def _camera_failed(base: Any) -> bool:
    stats = getattr(base.camera, "stats", None) or {}
    return bool(stats.get("reader_error"))


def run_rig(
    out_dir: Path, config: RigRunConfig, progress: Callable[[int, int], None] | None = None
) -> RunResult:
    """``wander rig``: the agent on the rig; the run folder as ``wander run`` writes it.

    Raises :class:`RigRunError` when a device fails (after writing the folder when the
    run had started); other errors propagate (also after writing the folder).
    """
    import wander_env  # noqa: F401  (registers the environments)

    out_dir = Path(out_dir)
    front = front_end(config)
    deployment = None
    if front == "chip":
        from hardware.samna_import import SamnaUnavailableError
        from hardware.speck_network import deploy

        try:  # before the device is opened: a network that does not fit is refused here
            deployment = deploy(chip_front(config))
        except SamnaUnavailableError as err:
            raise _open_failure(err, config) from err
    try:
        speck_config = None if deployment is None else deployment.config
        env = gym.make("wander/Rig-v0", speck_config=speck_config, **config.env)
    except Exception as err:
        raise _open_failure(err, config) from err
    agent: AttentionAgent | None = None
    try:
        base = env.unwrapped
        pipeline = None
        if deployment is not None:
            from hardware.speck_network import ChipPipeline

            resolved = config.agent_params(env).resolved().soms  # on the camera's sensor
            if resolved != deployment.params:
                raise SpeckLimitError(
                    f"the front end was built for the chip's {SPECK_DVS_SIZE[0]}x"
                    f"{SPECK_DVS_SIZE[1]} pixel array, but the camera gives "
                    f"{resolved.width_px}x{resolved.height_px} (env.speck.readout's region)"
                )
            # SpeckSource applied the one configuration (cores and DVS monitor)
            pipeline = ChipPipeline(base.camera.device, deployment, configured=True)
            pipeline.start()
        counters = RigCounters(env, front, pipeline)
        agent = AttentionAgent(config.agent_params(env), seed=config.seed, pipeline=pipeline)
        record = run_record("wander rig", asdict(config), config.seed)
        record["rig"] = device_record(base)
        record["rig"]["front_end"] = front
        record["fixed_view"] = fixed_view_note(record["rig"])
        try:
            # A fault or a signal in the loop halts the PTU at once (halt), before the
            # folder is written; a failure outside the loop halts it here (after the
            # loop's halt this sends a second H, harmless).
            result = run_for_config(
                env,
                agent,
                config,
                out_dir,
                record,
                progress,
                halt=base.halt_after_failure,
                recorders=(counters,),
            )
        except BaseException as err:
            base.halt_after_failure()
            try:  # the steps the folder recorded: the failure's, not a damaged file's
                steps = RunFolder(out_dir).read_json(METRICS_JSON).get("steps", 0)
            except UntrustedFileError:
                steps = 0
            is_device = _device(err, config) is not None or (
                isinstance(err, (RuntimeError, OSError)) and _camera_failed(base)
            )
            if isinstance(err, Exception) and is_device:
                raise _run_failure(err, config, out_dir, steps) from err
            raise
        result.metrics = to_strict_json(result.metrics)  # as written: a missing figure is None
        return result
    finally:
        if agent is not None:
            agent.close()
        env.close()
