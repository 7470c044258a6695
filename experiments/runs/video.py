"""Video to disk as it is made: :class:`VideoSink` writes RGB frames to an MP4 through
imageio-ffmpeg (libx264), its failures named; :func:`mp4_complete` says whether an MP4
is whole. The run's video recorder
(:class:`experiments.runs.recorders.VideoRecorder`) writes through it.
"""

from __future__ import annotations

import os
import struct
import time
from pathlib import Path
from typing import Any

import numpy as np

from wander_env.events.io import OutputError, check_space

__all__ = ["VideoSink", "mp4_complete"]


def mp4_complete(path: str | os.PathLike) -> bool:
    """Whether ``path`` is a whole MP4 file: its top-level boxes fill it exactly and one of
    them is ``moov``, the index a player needs (ffmpeg writes it when it finishes; a
    killed ffmpeg leaves the frames without it).

    Examples:
        >>> import tempfile
        >>> path = Path(tempfile.mkdtemp()) / "v.mp4"
        >>> box = lambda kind, body: struct.pack(">I4s", 8 + len(body), kind) + body
        >>> _ = path.write_bytes(box(b"ftyp", b"isom") + box(b"mdat", b"frames"))
        >>> mp4_complete(path)  # the frames, no index
        False
        >>> _ = path.write_bytes(box(b"ftyp", b"isom") + box(b"moov", b"") + box(b"mdat", b"x"))
        >>> mp4_complete(path), mp4_complete(path.with_name("none.mp4"))
        (True, False)
    """
    kinds: set[bytes] = set()
    try:
        size = os.path.getsize(path)
        with open(path, "rb") as fh:
            pos = 0
            while pos < size:
                fh.seek(pos)
                head = fh.read(16)
                if len(head) < 8:
                    return False
                n, kind = struct.unpack(">I4s", head[:8])
                if n == 1:  # a 64-bit size follows the type
                    if len(head) < 16:
                        return False
                    (n,) = struct.unpack(">Q", head[8:16])
                elif n == 0:  # the box runs to the end of the file
                    n = size - pos
                if n < 8:
                    return False
                kinds.add(kind)
                pos += n
    except OSError:
        return False
    return pos == size and b"moov" in kinds


class VideoSink:
    """An MP4 written frame by frame through imageio-ffmpeg, its failures named.

    :meth:`append` turns a failed write into :class:`OutputError` naming the file (ENOSPC
    with the free bytes when the disk is full: ffmpeg's pipe shows a full disk as a broken
    pipe); :meth:`finish` closes it and hands back the run's error, or the close's own
    when the run had none. The close is bounded: ffmpeg gets ``close_timeout_s`` to finish
    the file and is then ended (an :class:`OutputError` says the video is incomplete), so
    a hung encoder cannot keep the run folder from being written; a signal that arrives
    while ffmpeg finishes is handed back the same way, not raised past the folder (a run
    loop defers signals to its step boundaries, so that none
    interrupts a frame's write or the close: ffmpeg would be killed). After
    :meth:`finish`, ``complete`` says whether the file is a whole MP4
    (:func:`mp4_complete`: playable to its last frame; ``None``: no frame, no file).

    Examples:
        >>> import tempfile
        >>> path = Path(tempfile.mkdtemp()) / "v.mp4"
        >>> sink = VideoSink(path, fps=10)
        >>> for _ in range(3):
        ...     sink.append(np.zeros((16, 16, 3), np.uint8))
        >>> sink.finish(None) is None, path.stat().st_size > 0, sink.complete
        (True, True, True)
    """

    def __init__(self, path: str | os.PathLike, fps: int, close_timeout_s: float = 60.0) -> None:
        if not close_timeout_s > 0:
            raise ValueError(f"VideoSink.close_timeout_s must be > 0, got {close_timeout_s!r}")
        self.path = Path(path)
        self.fps = fps
        self.close_timeout_s = float(close_timeout_s)
        self._size: tuple[int, int] | None = None  # (width, height) of the first frame
        self._frames: Any = None  # imageio-ffmpeg's frame generator, from the first frame
        self.complete: bool | None = None  # set by finish

    def append(self, frame: np.ndarray) -> None:
        """Write one RGB frame ``(H, W, 3)`` uint8 of an even width and height (H.264's
        4:2:0 colour; every frame the first one's size)."""
        import cv2

        frame = np.asarray(frame)
        if frame.ndim != 3 or frame.shape[2] != 3 or frame.dtype != np.uint8:
            raise ValueError(
                f"{self.path}: a video frame must be (H, W, 3) uint8, got {frame.shape} "
                f"{frame.dtype}"
            )
        size = (frame.shape[1], frame.shape[0])
        if size[0] % 2 or size[1] % 2:
            raise ValueError(
                f"{self.path}: a video frame's width and height must be even (4:2:0 "
                f"colour), got {size[0]}x{size[1]} px"
            )
        if self._size is not None and size != self._size:
            raise ValueError(
                f"{self.path}: frame of {size[0]}x{size[1]} px after frames of "
                f"{self._size[0]}x{self._size[1]} px"
            )
        try:
            if self._frames is None:
                import imageio_ffmpeg

                self._size = size
                self._frames = imageio_ffmpeg.write_frames(
                    str(self.path),
                    size,
                    # OpenCV makes the 4:2:0 planes: ffmpeg's own conversion from RGB
                    # took 0.2 of its 0.59 s of CPU on 300 frames, OpenCV's 0.06 s
                    pix_fmt_in="yuv420p",
                    fps=self.fps,
                    quality=None,  # the rate is set by -crf below
                    # libx264's "ultrafast" preset at CRF 28 on one thread: on 300
                    # labelled frames of a run (1036x304) 0.54 s of CPU against 1.10 s
                    # for "superfast" at CRF 26 and 1.6-1.9 s for "veryfast" at CRF 23,
                    # PSNR 29.4 against 29.0 and 29.8 dB, the file 4.8 against 3.4 and
                    # 3.3 MB; the encoder shares the cores with the loop
                    output_params=["-preset", "ultrafast", "-crf", "28", "-threads", "1"],
                    macro_block_size=1,
                    ffmpeg_log_level="warning",
                    ffmpeg_timeout=self.close_timeout_s,
                )
                self._frames.send(None)  # starts ffmpeg
            self._frames.send(cv2.cvtColor(np.ascontiguousarray(frame), cv2.COLOR_RGB2YUV_I420))
        except Exception as err:
            check_space(self.path, frame.nbytes)
            raise OutputError(self.path, err) from err

    def finish(self, error: BaseException | None) -> BaseException | None:
        """Close the file; return ``error``, or the close's error if none: an
        :class:`OutputError` (a failed or timed-out close) or the signal that came."""
        frames, self._frames = self._frames, None
        if frames is None:
            return error
        start = time.monotonic()
        try:
            frames.close()
        except Exception as err:
            return error or OutputError(self.path, err)
        except BaseException as stop:  # a signal while ffmpeg finishes: write the folder first
            return error or stop
        finally:
            self.complete = mp4_complete(self.path)
        if time.monotonic() - start >= self.close_timeout_s:
            late = TimeoutError(
                f"ffmpeg did not finish the video within {self.close_timeout_s:g} s and was "
                "ended; the file is incomplete"
            )
            return error or OutputError(self.path, late)
        return error
