"""A run as a Rerun recording (``run.rrd``), and the viewer that opens it (``wander view``).

:class:`RunLog` writes one `Rerun <https://rerun.io>`_ recording per run folder, every
entity on the simulated-time timeline ``sim_time`` (seconds of the env's clock,
``info["t"]``), so a run can be scrubbed through in the Rerun viewer:

==========================  ==============================================================
entity                      what (logged at each step where it exists)
==========================  ==============================================================
``camera``                  the camera image, RGB as JPEG (simulated env only)
``events``                  the step's events: labels 0 none, 1 OFF, 2 ON (more events wins)
``oms``                     the sOMS output summed over the fixation window, same labels
``object_mask``             ground-truth object ids (0 background, k moving object k)
``saliency``                the proto-object saliency map (float), at each decision
``saliency/P``              the salient point P(x, y) chosen there (8×8 box)
``gaze/pan``, ``gaze/tilt`` the PTU's gaze, degrees (PTU signs: + pan left, + tilt up)
``ptu_target/pan``, …tilt   the PTU's commanded target, degrees
``annotations``             one text line per fixation and per saccade
==========================  ==============================================================

The polarity and object labels carry their names and colours (an ``AnnotationContext``,
red ON, blue OFF as in :mod:`wander_env.viz`), so the viewer shows its own key.

:class:`StepLogger` knows where things are in an env step (``obs``, ``info``, the env's
camera frame) and in the :class:`~agents.attention.AttentionAgent` (OMS window map,
saliency, P, fixations, saccades): the Rerun recorder of ``wander run``, ``record`` and
``rig`` (:class:`experiments.runs.recorders.RerunRecorder`) calls :func:`open_run_log` once,
:meth:`StepLogger.row` after each env step and :meth:`StepLogger.write` with the rows (in
batches, on the run's writer thread).

The events and OMS maps are segmentation images of
:func:`wander_env.viz.polarity_codes` (0 none, 1 OFF, 2 ON).
"""

from __future__ import annotations

import math
import os
import shutil
import stat
import subprocess
import sys
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from wander_env.viz import NO_EVENT, OFF_CODE, OFF_RGB, ON_CODE, ON_RGB, polarity_codes

__all__ = [
    "RRD_MAGIC",
    "RRD_NAME",
    "TIMELINE",
    "RunLog",
    "StepLogger",
    "StepRow",
    "check_recording",
    "command_text",
    "open_command",
    "open_run_log",
    "read_recording",
    "view",
]

RRD_NAME = "run.rrd"
#: How a Rerun recording file starts: ``RRF`` (then its encoding's version, ``RRF2``).
RRD_MAGIC = b"RRF"
TIMELINE = "sim_time"
#: Distinct colours for the object ids of ``object_mask`` (cycled).
OBJECT_RGB = ((255, 160, 0), (0, 190, 90), (200, 0, 200), (0, 170, 220), (140, 90, 40))


def _ns(t_s: Any) -> np.ndarray:
    """Simulated seconds -> integer nanoseconds of the timeline (rounded)."""
    return np.round(np.asarray(t_s, dtype=np.float64) * 1e9).astype(np.int64)


def _present(t_ns: np.ndarray, items: Sequence[Any]) -> list[tuple[np.ndarray, list]]:
    """The items that are there, with their times, in groups of one array shape."""
    groups: dict[tuple[int, ...], tuple[list[int], list]] = {}
    for k, item in enumerate(items):
        if item is not None:
            item = np.asarray(item)
            at, arrays = groups.setdefault(item.shape, ([], []))
            at.append(k)
            arrays.append(item)
    return [(t_ns[at], arrays) for at, arrays in groups.values()]


def _flat(images: Any) -> np.ndarray:
    """``(N, H, W[, C])`` images -> ``(N, H·W·C)`` uint8 rows, one buffer per image."""
    stack = np.ascontiguousarray(np.stack(images), dtype=np.uint8)
    return stack.reshape(len(stack), -1)


def _format(rr: Any, image: np.ndarray, color_model: str | None = None) -> Any:
    """Rerun's description of a uint8 ``image``'s layout."""
    h, w = image.shape[:2]
    return rr.components.ImageFormat(
        width=w, height=h, color_model=color_model, channel_datatype="U8"
    )


def _jpeg(image: np.ndarray, quality: int) -> bytes:
    """An RGB ``image`` as JPEG bytes (OpenCV's encoder)."""
    import cv2

    bgr = cv2.cvtColor(np.ascontiguousarray(image, dtype=np.uint8), cv2.COLOR_RGB2BGR)
    ok, data = cv2.imencode(".jpg", bgr, [cv2.IMWRITE_JPEG_QUALITY, int(quality)])
    if not ok:
        raise ValueError(f"OpenCV could not encode a {image.shape} image as JPEG")
    return data.tobytes()


class RunLog:
    """Write a run to ``path`` (``run.rrd``) as it goes; :meth:`close` finishes the file.

    ``object_names``: the moving objects, in the order of the mask ids 1, 2, …;
    ``camera_jpeg_quality``: the camera images are stored as JPEG of this quality (a
    128×128 frame ≈ 5 kB instead of 29 kB; ``None`` keeps the exact pixels).
    """

    def __init__(
        self,
        path: Path,
        title: str = "wander run",
        object_names: Sequence[str] = (),
        camera_jpeg_quality: int | None = 90,
    ) -> None:
        import rerun as rr

        self._rr = rr
        self.path = Path(path)
        self.rec = rr.RecordingStream("wander", send_properties=True)
        self.rec.save(self.path)
        self.rec.send_recording_name(title)
        polarity = rr.AnnotationContext(
            [
                rr.AnnotationInfo(id=NO_EVENT, label="no event", color=(255, 255, 255, 0)),
                rr.AnnotationInfo(id=OFF_CODE, label="OFF", color=OFF_RGB),
                rr.AnnotationInfo(id=ON_CODE, label="ON", color=ON_RGB),
            ]
        )
        self.rec.log("events", polarity, static=True)
        self.rec.log("oms", polarity, static=True)
        objects = [rr.AnnotationInfo(id=0, label="background", color=(0, 0, 0, 0))]
        objects += [
            rr.AnnotationInfo(id=k, label=name, color=OBJECT_RGB[(k - 1) % len(OBJECT_RGB)])
            for k, name in enumerate(object_names, 1)
        ]
        self.rec.log("object_mask", rr.AnnotationContext(objects), static=True)
        for name in ("gaze", "ptu_target"):
            for axis in ("pan", "tilt"):
                label = f"{name.replace('_', ' ')} {axis} (°)"
                self.rec.log(f"{name}/{axis}", rr.SeriesLines(names=label), static=True)
        self.camera_jpeg_quality = camera_jpeg_quality
        # Time series are kept and sent as one column each at close (a row per scalar
        # costs ≈ 250 bytes in the file; a column ≈ 16 bytes per value).
        self._series: dict[str, tuple[list[float], list[float]]] = {}
        self.closed = False

    def _at(self, t_s: float) -> None:
        self.rec.set_time(TIMELINE, duration=np.timedelta64(int(_ns(t_s)), "ns"))

    def steps(
        self,
        t_s: Sequence[float],
        *,
        camera: Sequence[np.ndarray | None] | None = None,
        events: Sequence[np.ndarray | None] | None = None,
        oms: Sequence[np.ndarray | None] | None = None,
        gaze_deg: Sequence[Sequence[float] | None] | None = None,
        ptu_target_deg: Sequence[Sequence[float] | None] | None = None,
        object_mask: Sequence[np.ndarray | None] | None = None,
    ) -> None:
        """Log steps at times ``t_s``: each other argument, when given, holds one item per
        step (``None``: nothing at that step): the camera image ``(H, W, 3)`` uint8,
        per-polarity ``events`` and ``oms`` counts ``(2, H, W)``, the gaze and PTU target
        (pan, tilt) in degrees, the object-id mask ``(H, W)``. Each entity's images go
        in one column send (a log call per image costs 4× the CPU)."""
        rr = self._rr
        t = _ns(t_s)
        if camera is not None:
            for at, images in _present(t, camera):
                if self.camera_jpeg_quality is None:
                    fmt = _format(rr, images[0], "RGB")
                    columns = rr.Image.columns(buffer=_flat(images), format=[fmt] * len(at))
                else:
                    blobs = [_jpeg(image, self.camera_jpeg_quality) for image in images]
                    columns = rr.EncodedImage.columns(
                        blob=blobs, media_type=["image/jpeg"] * len(at)
                    )
                self._send("camera", at, columns)
        labelled = (("events", events, polarity_codes), ("oms", oms, polarity_codes))
        for entity, items, label in (*labelled, ("object_mask", object_mask, None)):
            for at, arrays in _present(t, items or ()):
                stack = np.stack(arrays)
                stack = label(stack) if label is not None else stack.astype(np.uint8)
                fmt = _format(rr, stack[0])
                columns = rr.SegmentationImage.columns(buffer=_flat(stack), format=[fmt] * len(at))
                self._send(entity, at, columns)
        for name, values in (("gaze", gaze_deg), ("ptu_target", ptu_target_deg)):
            for k, value in enumerate(values or ()):
                if value is not None:
                    self._scalar(f"{name}/pan", t[k], float(value[0]))
                    self._scalar(f"{name}/tilt", t[k], float(value[1]))

    def _send(self, entity: str, t_ns: np.ndarray, columns: Any) -> None:
        times = self._rr.TimeColumn(TIMELINE, duration=t_ns.astype("timedelta64[ns]"))
        self.rec.send_columns(entity, indexes=[times], columns=columns)

    def _scalar(self, entity: str, t_ns: int, value: float) -> None:
        times, values = self._series.setdefault(entity, ([], []))
        times.append(int(t_ns))
        values.append(value)

    def decision(
        self, t_s: float, saliency: np.ndarray, target_px: tuple[int, int] | None, box: int = 8
    ) -> None:
        """Log a decision: the saliency map and the salient point P (with its box)."""
        rr = self._rr
        self._at(t_s)
        self.rec.log("saliency", rr.Image(np.asarray(saliency, dtype=np.float32)))
        if target_px is None:
            self.rec.log("saliency/P", rr.Clear(recursive=False))
            return
        x, y = float(target_px[0]), float(target_px[1])
        self.rec.log(
            "saliency/P",
            rr.Boxes2D(centers=[[x, y]], sizes=[[box, box]], labels=["P"], colors=[(0, 255, 0)]),
        )

    def annotate(self, t_s: float, text: str, level: str = "INFO") -> None:
        """One line of the run's story (a fixation, a saccade) at time ``t_s``."""
        self._at(t_s)
        self.rec.log("annotations", self._rr.TextLog(text, level=level))

    def close(self) -> None:
        """Flush and finish ``run.rrd`` (idempotent)."""
        if self.closed:
            return
        self.closed = True
        rr = self._rr
        for entity, (times, values) in self._series.items():
            self._send(entity, np.asarray(times, np.int64), rr.Scalars.columns(scalars=values))
        self.rec.flush()
        self.rec.disconnect()


@dataclass
class StepRow:
    """What one step logs (:meth:`StepLogger.row`), copied out of the env and the agent so
    that it can be written later, on another thread (:meth:`StepLogger.write`)."""

    t: float
    camera: np.ndarray | None
    events: np.ndarray | None
    oms: np.ndarray | None
    gaze_deg: np.ndarray | None
    ptu_target_deg: np.ndarray | None
    object_mask: np.ndarray | None
    #: The agent's decision at this step: (saliency, P); ``None``: none.
    decision: tuple[np.ndarray, tuple[int, int] | None] | None = None
    #: One line per fixation and saccade that ended at this step.
    notes: list[str] = field(default_factory=list)


def _copy(a: Any) -> np.ndarray | None:
    return None if a is None else np.array(a)


class StepLogger:
    """Logs each step of a run (and, with an agent, its decisions and movements):
    :meth:`row` takes what a step shows (in the loop), :meth:`write` logs rows (then or
    later, on a writer thread); :meth:`step` does both."""

    def __init__(self, log: RunLog, env: Any) -> None:
        self.log = log
        self.base = env.unwrapped
        self._fixations = 0
        self._saccades = 0
        #: Ground truth seen at each step: (object name, t, gaze pan, gaze tilt, centre x,
        #: centre y), the object's pixel centre where it is in front of the camera.
        self.sightings: list[tuple[str, float, float, float, float, float]] = []

    def row(self, obs: dict, info: dict, agent: Any = None) -> StepRow:
        """What the step just taken (``obs``, ``info`` from ``env.step``) and the agent's
        decision in it log; notes the step's sightings."""
        t = float(info.get("t", 0.0))
        gaze = obs.get("gaze")
        row = StepRow(
            t,
            camera=_copy(getattr(self.base, "camera_frame", None)),
            events=_copy(obs.get("events")),
            oms=None if agent is None else _copy(agent.oms_map),
            gaze_deg=_copy(gaze),
            ptu_target_deg=_copy(info.get("ptu_target_deg")),
            object_mask=_copy(info.get("object_mask")),
        )
        for o in info.get("objects", ()) if gaze is not None else ():
            cx, cy = o["centre_px"]
            if math.isfinite(cx) and math.isfinite(cy):
                self.sightings.append((o["name"], t, float(gaze[0]), float(gaze[1]), cx, cy))
        if agent is None:
            return row
        if agent.decided and agent.saliency is not None:
            row.decision = (np.array(agent.saliency), agent.target)
        for fx in agent.fixations[self._fixations :]:
            where = "nothing salient" if fx.target_px is None else f"P = {tuple(fx.target_px)}"
            row.notes.append(
                f"fixation {fx.index}: {fx.t_start:.3f}–{fx.t_end:.3f} s at pan "
                f"{fx.gaze_deg[0]:.2f}°, tilt {fx.gaze_deg[1]:.2f}°; {where}"
            )
        for sc in agent.saccades[self._saccades :]:
            row.notes.append(
                f"saccade {sc.index}: {sc.t_start:.3f}–{sc.t_end:.3f} s to P = "
                f"{tuple(sc.target_px)}, reached pan {sc.to_gaze_deg[0]:.2f}°, tilt "
                f"{sc.to_gaze_deg[1]:.2f}°"
            )
        self._fixations, self._saccades = len(agent.fixations), len(agent.saccades)
        return row

    def write(self, rows: Sequence[StepRow]) -> None:
        """Log ``rows`` (the images of each entity in one send)."""
        self.log.steps(
            [r.t for r in rows],
            camera=[r.camera for r in rows],
            events=[r.events for r in rows],
            oms=[r.oms for r in rows],
            gaze_deg=[r.gaze_deg for r in rows],
            ptu_target_deg=[r.ptu_target_deg for r in rows],
            object_mask=[r.object_mask for r in rows],
        )
        for r in rows:
            if r.decision is not None:
                self.log.decision(r.t, *r.decision)
            for text in r.notes:
                self.log.annotate(r.t, text)

    def close(self) -> None:
        self.log.close()


def open_run_log(out_dir: Path, env: Any, title: str) -> StepLogger:
    """Start ``out_dir/run.rrd`` for a run of ``env`` (object names from its scene)."""
    base = env.unwrapped
    scene = getattr(base, "scene", None)
    names = [o.name for o in getattr(scene, "moving_objects", ())]
    return StepLogger(RunLog(Path(out_dir) / RRD_NAME, title=title, object_names=names), env)


def read_recording(path: Path) -> dict[tuple[str, str], list[tuple[int, list]]]:
    """A ``run.rrd`` read back with Rerun's own chunk reader: ``(entity, component)`` ->
    ``[(sim_time in ns, value)]`` of the rows on the ``sim_time`` timeline, in time order
    (entities as Rerun names them, ``"/gaze/pan"``; components ``"Scalars:scalars"``…)."""
    import pyarrow as pa
    from rerun.chunk import RrdReader

    out: dict[tuple[str, str], list[tuple[int, list]]] = {}
    for chunk in RrdReader(path).stream():
        if chunk.is_static or TIMELINE not in chunk.timeline_names:
            continue
        batch = chunk.to_record_batch()
        times = batch.column(TIMELINE).cast(pa.int64()).to_pylist()
        for name in batch.schema.names:
            if ":" not in name:
                continue
            rows = out.setdefault((chunk.entity_path, name), [])
            rows += [
                (t, v)
                for t, v in zip(times, batch.column(name).to_pylist(), strict=True)
                if v is not None
            ]
    return {k: sorted(v, key=lambda tv: tv[0]) for k, v in out.items()}


# ----------------------------------------------------------------------------------------
# Opening a recording


def open_command(rrd: Path) -> list[str]:
    """The command that opens ``rrd`` in the Rerun viewer (the ``rerun`` executable that
    rerun-sdk installs, or ``python -m rerun``)."""
    exe = shutil.which("rerun") or str(Path(sys.executable).with_name("rerun"))
    if Path(exe).is_file():
        return [exe, str(rrd)]
    return [sys.executable, "-m", "rerun", str(rrd)]


def check_recording(rrd: Path) -> None:
    """``rrd`` is a regular, readable file that starts as a Rerun recording does
    (:data:`RRD_MAGIC`; the rest is the viewer's to read). ValueError, one line naming the
    file, otherwise.

    >>> check_recording(Path("/dev/null"))
    Traceback (most recent call last):
    ...
    ValueError: '/dev/null' is not a regular file
    """
    try:
        if not stat.S_ISREG(rrd.stat().st_mode):  # a FIFO would block the read below
            raise ValueError(f"{str(rrd)!r} is not a regular file")
        with open(rrd, "rb") as f:
            head = f.read(len(RRD_MAGIC))
    except OSError as err:
        raise ValueError(f"cannot read {str(rrd)!r}: {err.strerror}") from None
    if not head:
        raise ValueError(f"{str(rrd)!r} is empty: the run wrote no recording")
    if head != RRD_MAGIC:
        raise ValueError(
            f"{str(rrd)!r} is not a Rerun recording: it starts with {head!r}, not {RRD_MAGIC!r}"
        )


def view(run_dir: Path, env: dict[str, str] | None = None) -> tuple[str, list[str]]:
    """Open ``run_dir/run.rrd`` in the viewer when there is a display; headless, only say
    how. Returns ``("spawned" | "headless", command)``; raises FileNotFoundError when the
    folder has no recording, ValueError when it is no recording (:func:`check_recording`)."""
    env = dict(os.environ if env is None else env)
    rrd = Path(run_dir) / RRD_NAME
    if not rrd.exists():
        raise FileNotFoundError(
            f"no {RRD_NAME} in {str(run_dir)!r} (a run folder of wander run, record or rig)"
        )
    check_recording(rrd)
    command = open_command(rrd.resolve())
    if not (env.get("DISPLAY") or env.get("WAYLAND_DISPLAY")):
        return "headless", command
    subprocess.Popen(command, start_new_session=True, env=env)  # the viewer outlives us
    return "spawned", command


def command_text(command: list[str]) -> str:
    """``command`` as one shell line."""
    import shlex

    return " ".join(shlex.quote(c) for c in command)
