"""``wander run``: the attention agent closed-loop in a scene, and its run folder.

:func:`run_closed_loop` drives any env with the shared contract (the simulated
``wander/Wander-v0`` or the rig's ``wander/Rig-v0``) with an :class:`AttentionAgent` and
writes the run folder:

- ``run.json``: resolved config, seed, git revision, versions;
- ``metrics.json``: fixations, saccades, detection accuracy (the 8×8 box around each
  ``P`` touches a moving object's mask, the mask being the union over the fixation
  window — with ground truth only), sOMS event suppression, foveation error of the
  saccades (reached minus intended gaze, in pixels at the fovea), scanpath statistics
  (``scanpath``: the scanpath experiment's, of the windows merged into fixations,
  :func:`~experiments.analysis.scanpath_stats.scanpath_summary`), wall time and real-time
  factor;
- ``fixations.csv``: the fixation table (:mod:`experiments.analysis.scanpath_stats`: ``pan_deg``,
  ``tilt_deg`` (+ = left, up), ``t_start_s``, ``duration_s``) plus each window's ``P``,
  hit and the moving object hit (named as in the scene file);
- ``scanpath.png``: cumulative saliency on the pan-tilt sphere with fixations, saccade
  lines and the salient points; gaze over time (a camera whose view does not follow the
  gaze, a replayed recording, ``record["fixed_view"]``: saliency and ``P`` in the
  sensor's frame, and the note saying so);
- ``run.mp4``: events | OMS | saliency | camera, with the fovea (green) and ``P``
  (magenta 8×8 box) marked, at ``video_fps`` frames per simulated second
  (:data:`VIDEO_FPS` by default; a frame is composed only when one is due);
- ``events.h5``: every event of the run, written as the run goes
  (:class:`~wander_env.events.stream.EventStreamWriter`: memory does not grow with the
  run's length, and a killed run leaves the file readable up to its last flushed chunk).

A fault mid-run (a device that stops answering, a signal: :mod:`experiments.runs.signals`)
still leaves the folder with what was recorded, ``metrics.json`` naming the error (and
the signal); the exception is raised after it is written. A signal only sets a flag
(:class:`~experiments.runs.signals.DeferredSignals`): the loop takes it up between two steps,
so it never interrupts a render, a device read or a video frame's write; the video is
then finished by ffmpeg (``metrics.json`` ``video_complete`` says whether ``run.mp4``
is a whole MP4). A signal that comes while the folder is written waits until the
folder is finished. A run stopped by a signal is marked with an ``INCOMPLETE`` file
saying when it stopped.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Annotated, Any

import numpy as np
import pydantic

from agents.attention import AgentParams, AttentionAgent
from experiments.analysis import scanpath_stats
from experiments.analysis.stats import mean_std, real_time_factor
from experiments.jobs.scanpath_figure import plot_scanpath
from experiments.runs.episode import OneEpisode, Recorder, run_episode
from experiments.runs.folder import RunFolder
from experiments.runs.provenance import run_record
from experiments.runs.recorders import (
    DetectionRecorder,
    EventsRecorder,
    FolderRecorder,
    ReadoutRecorder,
    RerunRecorder,
    VideoRecorder,
    WriteParams,
    open_recorders,
)
from experiments.runs.signals import DeferredSignals, SignalExit
from experiments.runs.tables import write_csv
from experiments.studies.framework import MAX_SEED
from wander_env.camera import (
    degrees_to_pixels,
    focal_length_px,
    pixel_to_world_angles,
    principal_point,
)
from wander_env.env_config import WanderConfig
from wander_env.events.stream import EventStreamWriter
from wander_env.viz import event_image, labelled_frame, saliency_rgb

__all__ = [
    "VIDEO_FPS",
    "AgentMetrics",
    "AgentRunFolder",
    "OneEpisodeRun",
    "RunConfig",
    "RunResult",
    "closed_loop_metrics",
    "run",
    "run_closed_loop",
    "run_for_config",
    "scanpath_tables",
    "video_frame",
]


#: ``run.mp4``'s frames per simulated second by default: at the default 10 ms step, a
#: frame every 4th step, evenly spaced (30 took frames 30 and 40 ms apart), and 1/6 less of
#: the writer's CPU than 30 (a frame a step is 100).
VIDEO_FPS = 25


class OneEpisodeRun(OneEpisode):
    """What the configs of ``wander run`` and ``wander rig`` share beside
    :class:`~experiments.runs.episode.OneEpisode`: the agent of their ``agent`` block
    matched to the env."""

    def __post_init__(self) -> None:
        super().__post_init__()
        self.agent.check_env_fields()  # the env sets them: a change would be dropped

    def agent_params(self, env: Any) -> AgentParams:
        """The ``agent`` block with the env's sensor (``width_px``, ``height_px``), control
        period (``step_s``), lens (``hfov_deg``) and PTU resolution
        (:meth:`agents.attention.AgentParams.on_env`). run.json's ``agent`` records the
        values used."""
        return self.agent.on_env(env)


@dataclass(frozen=True)
class RunConfig(OneEpisodeRun):
    """What ``wander run`` runs: the env's block (scene, DVS preset, frames; its
    ``episode_seconds`` is the run's length), the seed, the video, and the agent's block
    ``agent`` (:class:`agents.attention.AgentParams`, the paper's defaults: ``window_s``,
    ``fixational``, ``soms`` (``alpha``, the sOMS threshold on the agent's quantile norm,
    :data:`agents.attention.AGENT_SOMS_ALPHA`; ``norm: minmax`` the paper-literal sOMS;
    ``soms: speck`` the front end shaped for Speck's cores,
    :class:`agents.speck_front.SpeckFrontParams`), ``proto`` (``polarity_split: false``:
    the streamlined model), ...). Its sensor geometry and step are the env's
    (:meth:`OneEpisodeRun.agent_params`)."""

    env: WanderConfig = field(default_factory=WanderConfig)
    seed: Annotated[int, pydantic.Field(ge=0, le=MAX_SEED)] = 0
    video: bool = True
    video_fps: Annotated[int, pydantic.Field(ge=1, le=1000)] = VIDEO_FPS
    agent: AgentParams = field(default_factory=AgentParams)


@dataclass
class RunResult:
    """What a run produced: the metrics and the files written."""

    metrics: dict[str, Any]
    files: list[str] = field(default_factory=list)
    error: str | None = None


# ----------------------------------------------------------------------------------------
# Pictures


def video_frame(
    events: np.ndarray,
    oms: np.ndarray,
    saliency: np.ndarray | None,
    camera: np.ndarray | None,
    target: tuple[int, int] | None,
    caption: str = "",
    scale: int = 2,
) -> np.ndarray:
    """One video frame (uint8 RGB): events | OMS | saliency | camera, each named, the
    fovea and P marked, and a footer with ``caption`` (the time stamp) and the colour
    keys (ON/OFF, the saliency scale, fovea, P)."""
    h, w = events.shape[1:]
    sal = saliency_rgb(saliency) if saliency is not None else np.zeros((h, w, 3), np.uint8)
    panels = [
        ("events (this step)", event_image(events)),
        ("OMS (fixation window)", event_image(oms)),
        ("saliency (last decision)", sal),
    ]
    if camera is not None:
        panels.append(("camera", np.asarray(camera, dtype=np.uint8)))
    keys = ("polarity", "saliency", "fovea", "P")
    return labelled_frame(panels, scale, caption, keys=keys, target=target)


# ----------------------------------------------------------------------------------------
# The loop


def run_closed_loop(
    env: Any,
    agent: AttentionAgent,
    seconds: float,
    out_dir: Path,
    record: dict[str, Any],
    video: bool = True,
    progress: Callable[[int, int], None] | None = None,
    seed: int | None = None,
    halt: Callable[[], None] | None = None,
    recorders: Sequence[Recorder] = (),
    video_fps: int = VIDEO_FPS,
    writing: WriteParams | None = None,
) -> RunResult:
    """Run ``agent`` on ``env`` for ``seconds`` and write the run folder (module doc):
    :func:`~experiments.runs.episode.run_episode` with the run's recorders (events,
    video at ``video_fps`` frames per simulated second, Rerun log, detection, readout
    counters, the folder) and ``recorders`` (a study's or the rig's own: what their
    ``metrics()`` return is added to ``metrics.json``). The files are written as
    ``writing`` says (:class:`~experiments.runs.recorders.WriteParams`; ``None``: its
    defaults, on a writer thread, events a chunk at a time, Rerun rows every 0.5 s of
    simulated time).

    ``halt`` (the rig: halt the PTU; it must not raise) is called as soon as the loop ends
    on an error or a signal, before the video is closed and the folder written.
    """
    out_dir = Path(out_dir)
    with DeferredSignals() as signals:  # a signal sets a flag; the loop takes it up
        RunFolder(out_dir).create()
        dt = _control_period(env, agent)
        n_steps = max(1, round(seconds / dt))
        p = agent.params
        record = record | {"agent": asdict(p)}
        title = str(record.get("command", "wander run"))
        writing = writing or WriteParams()
        writer, batch = writing.writer(), writing.batch_steps(dt)
        size = (p.width_px, p.height_px, 2)
        makers: list[Callable[[], Recorder]] = [
            lambda: EventsRecorder(
                out_dir / "events.h5", size, record, writer, batch, writing.batch_events
            ),
            lambda: RerunRecorder(out_dir, env, title, True, writer, batch),  # run.rrd
        ]
        if video:
            mp4 = out_dir / "run.mp4"
            makers.append(lambda: VideoRecorder(mp4, video_fps, dt, _capture, _compose, writer))
        events, rerun, *video_recorder = open_recorders(makers, writer)
        detection = DetectionRecorder()
        parts = [*video_recorder, ReadoutRecorder(), *recorders]  # their metrics() added
        run = AgentMetrics(agent, dt, detection)
        folder = AgentRunFolder(out_dir, record, n_steps, env, run, rerun, parts)
        # The writer closes after the recorders that write through it, before the run's
        # wall time ends and the folder is written.
        run_episode(
            env,
            agent,
            n_steps,
            [events, rerun, detection, *parts, *([writer] if writer else []), run, folder],
            signals,
            seed=seed,
            progress=progress,
            halt=halt,
        )
        if signals.pending:  # it came while the folder was written: the folder is finished
            folder.folder.record_late_signal(
                signals.signum,
                f"the run folder was written, after the run's {folder.steps} steps",
            )
    return folder.result  # unless the pending signal, raised on leaving the block


def _capture(env: Any, agent: AttentionAgent, obs: dict, info: dict) -> tuple:
    """What a video frame shows, copied out of the env and the agent (:func:`_compose`)."""
    camera = getattr(env.unwrapped, "camera_frame", None)
    t = info.get("t", math.nan)
    target = "none" if agent.target is None else f"({agent.target[0]}, {agent.target[1]})"
    caption = f"t = {t:5.2f} s   {agent.phase.value}   P = {target}"
    saliency = None if agent.saliency is None else np.array(agent.saliency)
    return (
        np.array(obs["events"]),
        np.array(agent.oms_map),
        saliency,
        None if camera is None else np.array(camera),
        agent.target,
        caption,
    )


def _compose(captured: tuple) -> np.ndarray:
    return video_frame(*captured)


def _saccade_metrics(agent: AttentionAgent, clipped: list[bool]) -> dict[str, Any]:
    p = agent.params
    f = focal_length_px(p.width_px, p.hfov_deg)
    errs = []
    for s, c in zip(agent.saccades, clipped, strict=False):
        if c:
            continue
        e = s.error_deg
        # Pixels at the fovea; x right is −pan, y down is −tilt.
        errs.append(
            (
                degrees_to_pixels(-e[0], p.width_px, p.hfov_deg),
                degrees_to_pixels(-e[1], p.width_px, p.hfov_deg),
            )
        )
    out: dict[str, Any] = {
        "saccades": len(agent.saccades),
        "saccades_clipped_by_ptu_limits": int(sum(clipped)),
        "saccade_duration_mean_s": mean_std(s.t_end - s.t_start for s in agent.saccades)[0],
        "focal_length_px": f,
    }
    if errs:
        e = np.abs(np.asarray(errs))
        out |= {
            "foveation_error_x_px_mean": float(e[:, 0].mean()),
            "foveation_error_x_px_std": float(e[:, 0].std()),
            "foveation_error_y_px_mean": float(e[:, 1].mean()),
            "foveation_error_y_px_std": float(e[:, 1].std()),
        }
    return out


def _object_paths(
    sightings: list[tuple], focal_px: float, centre: tuple[float, float]
) -> dict[str, np.ndarray]:
    """Each moving object's world (t, pan, tilt) from its pixel centres and the gaze."""
    paths: dict[str, list[tuple[float, float, float]]] = {}
    for name, t, pan, tilt, x, y in sightings:
        paths.setdefault(name, []).append(
            (t, *pixel_to_world_angles((x, y), (pan, tilt), focal_px, centre))
        )
    return {k: np.asarray(v) for k, v in paths.items()}


def _ptu_limits(env: Any) -> tuple[tuple[float, float], tuple[float, float]] | None:
    """The PTU's (pan, tilt) limits in degrees (simulated unit or the rig's driver)."""
    ptu = getattr(env.unwrapped, "ptu", None)
    for src in (ptu, getattr(ptu, "params", None)):  # the rig's driver, the simulated unit
        if hasattr(src, "pan_limits_deg") and hasattr(src, "tilt_limits_deg"):
            return tuple(src.pan_limits_deg), tuple(src.tilt_limits_deg)  # type: ignore[return-value]
    return None


def scanpath_tables(agent: AttentionAgent) -> tuple[np.ndarray, list[bool], np.ndarray]:
    """What :func:`experiments.analysis.scanpath_stats.scanpath_summary` takes, from the
    agent: its decision windows ``(n, 4)`` (pan, tilt, start, duration), whether each
    ended its fixation (its ``P`` started a saccade) and its saccades ``(m, 4)`` (the PTU
    target each started from, the gaze it reached)."""
    windows = np.array(
        [[*w.gaze_deg, w.t_start, w.t_end - w.t_start] for w in agent.fixations],
        dtype=np.float64,
    ).reshape(-1, 4)
    ends = [w.target_px is not None for w in agent.fixations]
    saccades = np.array(
        [[*s.from_target_deg, *s.to_gaze_deg] for s in agent.saccades], dtype=np.float64
    ).reshape(-1, 4)
    return windows, ends, saccades


class AgentMetrics(Recorder):
    """In memory, the figures of an agent's run (``metrics.json``'s, module doc):
    :meth:`figures` after the loop, from the agent, ``detection`` (a
    :class:`~experiments.runs.recorders.DetectionRecorder` in the same run) and what this
    recorder counted: steps, events, the gaze trace ``(t, pan, tilt)`` per step and the
    wall time from its creation (just before the loop) to its close (close it after the
    recorders whose closing belongs to the run: the video's, the files')."""

    def __init__(self, agent: AttentionAgent, dt: float, detection: DetectionRecorder) -> None:
        self.agent, self.dt, self.detection = agent, dt, detection
        self.steps = self.events = 0
        self.gaze: list[tuple[float, float, float]] = []
        self._t0 = time.perf_counter()
        self.wall_s: float | None = None

    def on_step(self, env: Any, agent: Any, obs: dict, info: dict) -> None:
        self.steps += 1
        self.events += len(info["events"].events)
        self.gaze.append((float(info.get("t", self.steps * self.dt)), *map(float, obs["gaze"])))

    def close(self, error: BaseException | None) -> BaseException | None:
        self.wall_s = time.perf_counter() - self._t0
        return error

    def table(self) -> np.ndarray:
        """The fixation table (:mod:`experiments.analysis.scanpath_stats`) of the agent's
        windows, one row each (``fixations.csv``)."""
        return scanpath_stats.normalise_fixations(scanpath_tables(self.agent)[0])

    def figures(self) -> dict[str, Any]:
        agent, hits = self.agent, self.detection.hits
        wall = self.wall_s if self.wall_s is not None else time.perf_counter() - self._t0
        scored = [h for h in hits if h is not None]
        sim_s = self.steps * self.dt
        return {
            "steps": self.steps,
            "simulated_s": sim_s,
            "wall_s": wall,
            "real_time_factor": real_time_factor(sim_s, wall),
            "decisions": len(agent.fixations),
            "decisions_with_target": sum(fx.target_px is not None for fx in agent.fixations),
            "decisions_scored": len(scored),
            "detection_accuracy": float(np.mean(scored)) if scored else math.nan,
            "events": self.events,
            "events_into_agent": agent.events_in,
            "events_kept_by_soms": agent.events_oms,
            "soms_suppression": agent.suppression,
            **_saccade_metrics(agent, self.detection.clipped),
            "scanpath": (
                scanpath_stats.scanpath_summary(*scanpath_tables(agent)) if agent.fixations else {}
            ),
        }


class AgentRunFolder(FolderRecorder):
    """The folder of an agent's run (module doc): ``metrics.json`` from ``run``
    (:class:`AgentMetrics`) and the ``parts``, ``fixations.csv``, ``scanpath.png`` (the
    objects' paths from ``rerun``'s sightings), ``run.json``; ``result`` after
    :meth:`close`."""

    def __init__(
        self,
        out_dir: Path,
        record: dict[str, Any],
        asked: int,
        env: Any,
        run: AgentMetrics,
        rerun: RerunRecorder,
        parts: Sequence[Recorder],
    ) -> None:
        super().__init__(out_dir, record, asked, parts)
        self.env, self.run, self.rerun = env, run, rerun
        self.result: RunResult | None = None

    def figures(self, error: BaseException | None) -> dict[str, Any]:
        return self.run.figures()

    def write_files(self, metrics: dict[str, Any], error: BaseException | None) -> None:
        out_dir = self.folder.path
        agent, detection = self.run.agent, self.run.detection
        p = agent.params
        f = focal_length_px(p.width_px, p.hfov_deg)
        centre = principal_point(p.width_px, p.height_px)
        targets_deg = [
            pixel_to_world_angles(fx.target_px, fx.gaze_deg, f, centre) if fx.target_px else None
            for fx in agent.fixations
        ]
        if agent.fixations:
            columns, rows = scanpath_stats.fixation_rows(
                self.run.table(), _fixation_columns(agent, detection, targets_deg)
            )
            write_csv(rows, out_dir / "fixations.csv", columns=columns)
        if agent.fixations and detection.maps:
            n = min(len(detection.maps), len(agent.fixations))
            moves = f"{len(agent.fixations)} fixations, {len(agent.saccades)} saccades"
            plot_scanpath(
                out_dir / "scanpath.png",
                detection.maps[:n],
                [
                    {
                        "gaze_deg": fx.gaze_deg,
                        "duration_s": fx.t_end - fx.t_start,
                        "target_deg": tg,
                        "target_px": fx.target_px,
                    }
                    for fx, tg in zip(agent.fixations[:n], targets_deg, strict=False)
                ],
                f,
                gaze_trace=np.asarray(self.run.gaze),
                title=f"scanpath ({moves})",
                object_paths=_object_paths(self.rerun.sightings, f, centre),
                limits_deg=_ptu_limits(self.env),
                fixed_view=self.record.get("fixed_view"),  # a replayed recording (wander rig)
            )

    def close(self, error: BaseException | None) -> BaseException | None:
        error = super().close(error)
        if error is None and self.written is not None:
            files = sorted(x.name for x in self.folder.path.iterdir())
            self.result = RunResult(metrics=dict(self.written), files=files)
        return error


def _fixation_columns(
    agent: AttentionAgent,
    detection: DetectionRecorder,
    targets_deg: list[tuple[float, float] | None],
) -> dict[str, list[object]]:
    """``fixations.csv``'s columns after the fixation table's four (module doc of
    :mod:`experiments.analysis.scanpath_stats`); ``None`` where a window has no ``P`` or no
    score."""
    fx, n = agent.fixations, len(agent.fixations)
    hits = [detection.hits[k] if k < len(detection.hits) else None for k in range(n)]
    objects = [detection.hit_objects[k] if k < len(detection.hit_objects) else "" for k in range(n)]
    return {
        "target_x_px": [f.target_px[0] if f.target_px else None for f in fx],
        "target_y_px": [f.target_px[1] if f.target_px else None for f in fx],
        "target_pan_deg": [round(t[0], 6) if t else None for t in targets_deg],
        "target_tilt_deg": [round(t[1], 6) if t else None for t in targets_deg],
        "hit": [None if h is None else int(h) for h in hits],
        "target_object": objects,
        "events": [f.events for f in fx],
        "oms_events": [f.oms_events for f in fx],
    }


def closed_loop_metrics(
    env: Any,
    agent: AttentionAgent,
    seconds: float,
    seed: int | None = None,
    recorders: Sequence[Recorder] = (),
) -> dict[str, Any]:
    """An experiment's trial: ``agent`` on ``env`` for ``seconds`` with ``recorders`` and
    no file written; returns the figures ``metrics.json`` would hold
    (:class:`AgentMetrics`)."""
    dt = _control_period(env, agent)
    detection = DetectionRecorder()
    run = AgentMetrics(agent, dt, detection)
    with DeferredSignals() as signals:
        run_episode(
            env,
            agent,
            max(1, round(seconds / dt)),
            [detection, *recorders, run],
            signals,
            seed=seed,
        )
    return run.figures()


def _control_period(env: Any, agent: AttentionAgent) -> float:
    """The env's step: its config's ``control_period_s`` (the agent's step without one)."""
    config = getattr(env.unwrapped, "config", None)
    return float(getattr(config, "control_period_s", agent.params.step_s))


def run_for_config(
    env: Any,
    agent: AttentionAgent,
    config: Any,
    out_dir: Path,
    record: dict[str, Any],
    progress: Callable[[int, int], None] | None = None,
    halt: Callable[[], None] | None = None,
    recorders: Sequence[Recorder] = (),
) -> RunResult:
    """:func:`run_closed_loop` for a run config's ``seconds``, ``video``, ``video_fps``
    and ``seed`` (``wander run``'s :class:`RunConfig` and ``wander rig``'s config);
    ``recorders``: the caller's own."""
    return run_closed_loop(
        env,
        agent,
        config.seconds,
        out_dir,
        record,
        video=config.video,
        progress=progress,
        seed=config.seed,
        halt=halt,
        recorders=recorders,
        video_fps=config.video_fps,
    )


def run(
    out_dir: Path, config: RunConfig, progress: Callable[[int, int], None] | None = None
) -> RunResult:
    """``wander run``: the agent in the simulated scene."""
    import gymnasium as gym

    import wander_env  # noqa: F401  (registers the environments)

    record = run_record("wander run", asdict(config), config.seed)
    env = None
    try:
        env = gym.make("wander/Wander-v0", **config.env)
        env.unwrapped.warm_up()  # its GL contexts and kernels while the agent is built
        agent = AttentionAgent(config.agent_params(env), seed=config.seed)
    except KeyboardInterrupt as stop:  # Ctrl-C or a signal while setting up
        _stopped_in_setup(Path(out_dir), config, record, stop)
        if env is not None:
            env.close()
        raise
    try:
        return run_for_config(env, agent, config, out_dir, record, progress)
    finally:
        agent.close()
        env.close()


def _stopped_in_setup(
    out_dir: Path, config: RunConfig, record: dict[str, Any], stop: KeyboardInterrupt
) -> None:
    """The run folder of a run stopped before its first step: no events, the signal named."""
    from wander_env.scenes import load_scene_config

    camera = load_scene_config(config.env.scene).camera
    folder = RunFolder(out_dir)
    folder.create()
    summary = {"steps": 0, "events": 0}
    rec = record | {"summary": summary}
    EventStreamWriter(out_dir / "events.h5", (camera.width, camera.height, 2)).close(rec)
    metrics: dict[str, Any] = {**summary, "stage": "set-up"}
    metrics["error"] = f"{type(stop).__name__}: {stop} (while setting up)"
    folder.mark_incomplete(f"{str(stop) or 'interrupted'} while setting up, before any step")
    if isinstance(stop, SignalExit):
        metrics["signal"] = stop.name
    folder.write_metrics(metrics)
    folder.write_run(rec)
