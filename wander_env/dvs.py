"""A streaming DVS (event camera) emulator: frames with timestamps in, events out.

The pixel model, one named parameter per term (see :class:`DVSParams`):

1. **Luminance.** ``uint8`` sRGB frames are linearised (the sRGB curve undone)
   and weighted to luminance (Rec. 709); float frames are taken as linear
   intensity (1.0 = full scale).
2. **Log with a linear segment near black.** ``L = ln(I)`` above
   ``linlog_intensity`` and the tangent line below it, so black is finite.
3. **Photoreceptor low-pass** (optional, ``cutoff_hz``): first order, with a
   cutoff that rises with intensity, ``fc(I) = cutoff_hz · (I + dark) / (1 + dark)``.
4. **Change detector.** Each pixel remembers the level of its last event; the
   filtered log signal is taken as moving linearly between two frames, and every
   crossing of the per-pixel ON or OFF threshold (Gaussian mismatch
   ``threshold_sigma``) is an event, timestamped where the line crosses the level:
   a change spanning k thresholds gives k events spread across the interval.
5. **Refractory period.** A crossing less than ``refractory_us`` after the
   pixel's previous event is lost (the level still moves on, as in a pixel
   whose reset switch is held).
6. **Latency and jitter.** Each event is delayed by ``latency_us`` plus Gaussian
   jitter ``jitter_us``; the delay is clipped at zero, so no event comes before
   its cause. Events delayed past the frame time are held back and delivered by
   the call whose window contains them (or by :meth:`DVSEmulator.flush`).
7. **Background activity.** Leak events (the memorised level drifts so that a
   static pixel fires ON at ``leak_rate_hz``), shot noise (Poisson, either
   polarity, ``shot_rate_hz`` per pixel) and hot pixels (a fraction
   ``hot_pixel_fraction`` firing ON at ``hot_pixel_rate_hz``).

Every noise term is off unless asked for; ``DVSParams.preset("paper")`` gives
the IEBCS settings the paper used and ``"speck"`` plausible Speck-like ones.

Examples:
    >>> import numpy as np
    >>> from wander_env.dvs import DVSEmulator, DVSParams
    >>> emu = DVSEmulator(4, 1, DVSParams(threshold_on=0.1, threshold_off=0.1))
    >>> emu.reset(np.full((1, 4), 0.5), t_us=0)
    >>> ev = emu.step(np.full((1, 4), 0.5 * np.exp(0.25)), t_us=1000)
    >>> len(ev), sorted(set(ev["t"].tolist()))  # 2 ON events per pixel, at 40 % and 80 %
    (8, [400, 800])
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields, replace

import numba
import numpy as np

from wander_env.config import check_fields
from wander_env.events import EVENT_DTYPE

#: Rec. 709 luminance weights for linear RGB.
LUMA = np.array([0.2126, 0.7152, 0.0722])
# Per-pixel state is float32 (half the memory traffic of float64, and twice the SIMD
# width for the log). A change meant to be exactly k thresholds may round to a hair
# under; this relative tolerance counts it as k.
_EPS = 1e-5


def srgb_to_linear(v: np.ndarray) -> np.ndarray:
    """Undo the sRGB transfer curve; ``v`` in [0, 1]."""
    v = np.asarray(v, dtype=np.float64)
    return np.where(v <= 0.04045, v / 12.92, ((v + 0.055) / 1.055) ** 2.4)


def luminance_tables() -> tuple[np.ndarray, np.ndarray]:
    """Per 8-bit sRGB code: its linear light (256,) and each channel's Rec. 709 weighted
    share of the linear luminance (3, 256), both float32 and weighted in float32 (the
    one table the DVS emulator and the panorama's cube map sum).

    >>> lut, wlut = luminance_tables()
    >>> lut.dtype, wlut.shape, float(lut[255]), float(wlut[:, 255].sum())
    (dtype('float32'), (3, 256), 1.0, 1.0)
    """
    lut = srgb_to_linear(np.arange(256) / 255.0).astype(np.float32)
    return lut, LUMA.astype(np.float32)[:, None] * lut[None, :]


def linlog(intensity: np.ndarray, linlog_intensity: float) -> np.ndarray:
    """``ln(I)`` above ``linlog_intensity``; below it the tangent line (finite at 0)."""
    i = np.asarray(intensity, dtype=np.float64)
    lin = math.log(linlog_intensity) + (i - linlog_intensity) / linlog_intensity
    return np.where(i >= linlog_intensity, np.log(np.maximum(i, linlog_intensity)), lin)


@dataclass(frozen=True)
class DVSParams:
    """Pixel model parameters. Log units are natural log; times in µs; rates in Hz."""

    threshold_on: float = 0.2
    threshold_off: float = 0.2
    threshold_sigma: float = 0.0
    threshold_min: float = 0.01
    linlog_intensity: float = 0.01
    cutoff_hz: float = 0.0
    cutoff_dark: float = 0.01
    refractory_us: float = 0.0
    latency_us: float = 0.0
    jitter_us: float = 0.0
    leak_rate_hz: float = 0.0
    shot_rate_hz: float = 0.0
    hot_pixel_fraction: float = 0.0
    hot_pixel_rate_hz: float = 200.0

    def __post_init__(self) -> None:
        positive = ("threshold_on", "threshold_off", "threshold_min", "linlog_intensity")
        check_fields(self, positive, positive=True)
        check_fields(self, [f.name for f in fields(self) if f.name not in positive], minimum=0)
        if self.hot_pixel_fraction > 1:
            raise ValueError(
                f"DVSParams.hot_pixel_fraction must be <= 1, got {self.hot_pixel_fraction}"
            )
        # Floats, as the config path (pydantic) gives them: an int or a NumPy scalar from
        # Python would compile a second copy of each kernel that takes the field.
        for f in fields(self):
            object.__setattr__(self, f.name, float(getattr(self, f.name)))

    @classmethod
    def preset(cls, name: str, **overrides: float) -> DVSParams:
        """``"ideal"``, ``"paper"`` or ``"speck"``, with optional field overrides."""
        presets = {
            "ideal": {},
            # The IEBCS settings of the paper (§ sOMS characterisation): th = 0.1,
            # th_noise = 0.01, lat = 100 µs, jit = 10 µs, ref = 100 µs, tau = 300 µs
            # (cutoff = 1 / (2π·300 µs) at full scale). Background rates are the means
            # of the IEBCS noise distributions measured at 161 lux (shared/realdata/
            # iebcs_noise): ON 0.104 Hz, OFF 0.0012 Hz per pixel.
            "paper": dict(
                threshold_on=0.1,
                threshold_off=0.1,
                threshold_sigma=0.01,
                latency_us=100.0,
                jitter_us=10.0,
                refractory_us=100.0,
                cutoff_hz=1.0 / (2 * math.pi * 300e-6),
                leak_rate_hz=0.104,
                shot_rate_hz=0.0023,
            ),
            # Plausible values for the Speck's 128×128 DVS (not a characterisation):
            # coarser, more mismatched thresholds than a DAVIS, slower pixels.
            "speck": dict(
                threshold_on=0.25,
                threshold_off=0.25,
                threshold_sigma=0.03,
                latency_us=200.0,
                jitter_us=50.0,
                refractory_us=250.0,
                cutoff_hz=300.0,
                leak_rate_hz=0.1,
                shot_rate_hz=0.5,
                hot_pixel_fraction=0.0005,
                hot_pixel_rate_hz=200.0,
            ),
        }
        if name not in presets:
            raise ValueError(f"unknown DVS preset {name!r}; choose one of {sorted(presets)}")
        return replace(cls(**presets[name]), **overrides)

    def to_dict(self) -> dict[str, float]:
        return asdict(self)


# ----------------------------------------------------------------------------------------
# Kernels. One pass plans (filtered level, count upper bound), one pass emits and commits,
# so the output buffer is sized exactly once and state is touched only when it succeeds.


@numba.njit(cache=True, nogil=True)
def _luminance_rgb(
    rgb: np.ndarray, wlut: np.ndarray, i_lin: float, lum: np.ndarray, arg: np.ndarray
):
    """Flat uint8 sRGB ``(H·W·3,)`` -> flat linear luminance ``lum``.

    ``wlut`` ``(3, 256)`` holds each channel's Rec. 709 weight times the linear light of
    each code (float32), so a pixel costs three look-ups and two additions, summed in
    the order ``R + G + B``. Also writes ``max(lum, i_lin)`` to ``arg``, ready for an
    in-place ``np.log``.
    """
    floor = np.float32(i_lin)
    lr, lg, lb = wlut[0], wlut[1], wlut[2]
    for i in range(lum.size):
        v = lr[rgb[3 * i]] + lg[rgb[3 * i + 1]] + lb[rgb[3 * i + 2]]
        lum[i] = v
        arg[i] = max(v, floor)


@numba.njit(cache=True, nogil=True)
def _luminance_grey(grey: np.ndarray, lut: np.ndarray, log_lut: np.ndarray, lum, log_in):
    """Flat uint8 grey ``(H·W,)`` -> ``lum`` (linear light) and ``log_in``
    (``ln(max(lum, i_lin))``), both straight from per-code tables: no log per pixel."""
    for i in range(lum.size):
        c = grey[i]
        lum[i] = lut[c]
        log_in[i] = log_lut[c]


@numba.njit(cache=True, nogil=True, fastmath=True)
def _levels(
    lum: np.ndarray,
    log_in_prev: np.ndarray,
    level: np.ndarray,
    diff: np.ndarray,
    th_on: np.ndarray,
    i_lin: float,
    lowpass: np.ndarray,
    leak_step: float,
    log_in: np.ndarray,
    level_new: np.ndarray,
    diff_new: np.ndarray,
) -> float:
    """Filtered log level at the new frame and the level-minus-reference it reaches.

    ``log_in`` holds ``ln(max(lum, i_lin))`` on entry (NumPy's vectorised log is
    ~10× faster than a scalar one); the linear segment below ``i_lin`` is patched in
    here. ``lowpass`` is the per-pixel fraction of the way the photoreceptor moves
    toward its input in this step (empty: no low-pass). Returns the largest change
    of the input log intensity.
    """
    il = np.float32(i_lin)
    log_il = np.float32(math.log(i_lin))
    leak = np.float32(leak_step)
    filtered = lowpass.size > 0
    max_change = np.float32(0.0)
    for i in range(lum.size):
        x = log_in[i] if lum[i] >= il else log_il + (lum[i] - il) / il
        log_in[i] = x
        max_change = max(max_change, abs(x - log_in_prev[i]))
        lv = level[i] + lowpass[i] * (x - level[i]) if filtered else x
        level_new[i] = lv
        # Leak: the memorised reference drifts down by leak_step thresholds per step.
        diff_new[i] = diff[i] + (lv - level[i]) + leak * th_on[i]
    return max_change


@numba.njit(cache=True, nogil=True, fastmath=True)
def _patch_linlog(lum: np.ndarray, log_in: np.ndarray, i_lin: float) -> None:
    """Patch the linear segment below ``i_lin`` into ``log_in`` (``ln(max(lum, i_lin))``
    on entry), exactly as :func:`_levels` does."""
    il = np.float32(i_lin)
    log_il = np.float32(math.log(i_lin))
    for i in range(lum.size):
        if lum[i] < il:
            log_in[i] = log_il + (lum[i] - il) / il


@numba.njit(cache=True, nogil=True)
def _max_change(a: np.ndarray, b: np.ndarray) -> float:
    """``max |a - b|`` of two float32 arrays."""
    m = np.float32(0.0)
    for i in range(a.size):
        m = max(m, abs(a[i] - b[i]))
    return m


@numba.njit(cache=True, nogil=True, inline="always")
def _crossings(d: float, th_on: float, th_off: float) -> tuple[int, int]:
    """Whole thresholds spanned by the difference ``d`` and their polarity (-1: none)."""
    if d >= th_on * (1.0 - _EPS):
        return int(d / th_on + _EPS), 1
    if d <= -th_off * (1.0 - _EPS):
        return int(-d / th_off + _EPS), 0
    return 0, -1


@numba.njit(cache=True, nogil=True)
def _crossing_pixels(
    diff: np.ndarray,
    diff_new: np.ndarray,
    th_on: np.ndarray,
    th_off: np.ndarray,
    active: np.ndarray,
) -> tuple[int, int]:
    """Commit pixels that cross no threshold; list the others in ``active``.

    Returns the number of active pixels and an upper bound on their events.
    """
    total = 0
    n_active = 0
    for i in range(diff.size):
        k, pol = _crossings(diff_new[i], th_on[i], th_off[i])
        if pol < 0:
            diff[i] = diff_new[i]
            continue
        total += k
        active[n_active] = i
        n_active += 1
    return n_active, total


@numba.njit(cache=True, nogil=True)
def _order_by_time(t: np.ndarray) -> np.ndarray:
    """Stable ordering of integer timestamps: a counting sort when their span is
    small (the usual case: one frame interval), else a merge sort."""
    n = t.size
    if n == 0:
        return np.empty(0, np.int64)
    lo, hi = t.min(), t.max()
    span = hi - lo + 1
    if span > 4 * n + 65536:
        return np.argsort(t, kind="mergesort")
    start = np.zeros(span + 1, np.int64)
    for v in t:
        start[v - lo + 1] += 1
    for k in range(1, span + 1):
        start[k] += start[k - 1]
    order = np.empty(n, np.int64)
    for i in range(n):
        k = t[i] - lo
        order[start[k]] = i
        start[k] += 1
    return order


@numba.njit(cache=True, nogil=True)
def _emit(
    active: np.ndarray,
    diff: np.ndarray,
    diff_new: np.ndarray,
    th_on: np.ndarray,
    th_off: np.ndarray,
    last_event: np.ndarray,
    refractory_us: float,
    t0: float,
    t1: float,
    width: int,
    out_x: np.ndarray,
    out_y: np.ndarray,
    out_t: np.ndarray,
    out_p: np.ndarray,
) -> int:
    """Write the crossings of the ``active`` pixels; update ``diff`` and ``last_event``."""
    n = 0
    span = t1 - t0
    for i in active:
        d0 = diff[i]
        d1 = diff_new[i]
        k, pol = _crossings(d1, th_on[i], th_off[i])
        th = th_on[i] if pol == 1 else th_off[i]
        # Crossing j happens where the line from d0 to d1 reaches j thresholds.
        slope = abs(d1 - d0)
        start = d0 if pol == 1 else -d0
        for j in range(1, k + 1):
            frac = (j * th - start) / slope if slope > 0 else 1.0
            if frac > 1.0:
                frac = 1.0
            t = t0 + frac * span
            if t - last_event[i] < refractory_us:
                continue
            last_event[i] = t
            out_x[n] = i % width
            out_y[n] = i // width
            out_t[n] = t
            out_p[n] = pol
            n += 1
        diff[i] = d1 - k * th if pol == 1 else d1 + k * th
    return n


# Events inside the emulator: columns (x, y, t, p), cheaper to sort than records.
_Columns = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]
_NO_EVENTS: _Columns = (
    np.empty(0, np.int16),
    np.empty(0, np.int16),
    np.empty(0, np.int64),
    np.empty(0, np.int8),
)


@dataclass(frozen=True, eq=False)
class LogFrame:
    """A frame's input to the pixels, computed once (:meth:`DVSEmulator.prepare`).

    ``lum`` is the flat linear luminance and ``log_in`` its log with the linear segment
    near black, both float32: what :meth:`DVSEmulator.step` derives from a frame. Pass it
    to :meth:`~DVSEmulator.log_change` and then :meth:`~DVSEmulator.step` to convert the
    frame once; the arrays are read, never written.
    """

    lum: np.ndarray
    log_in: np.ndarray


class DVSEmulator:
    """Streaming emulator for a ``width`` × ``height`` sensor.

    ``reset(frame, t_us)`` sets the pixels' memory; each ``step(frame, t_us)``
    returns the events in ``(t_prev, t_us]`` as a sorted :data:`EVENT_DTYPE` array.
    Same seed and same frames give the same events.
    """

    def __init__(
        self, width: int, height: int, params: DVSParams | None = None, seed: int | None = None
    ):
        if int(width) <= 0 or int(height) <= 0:
            raise ValueError(f"sensor size must be positive, got width={width}, height={height}")
        self.width, self.height = int(width), int(height)
        self.params = params if params is not None else DVSParams()
        self.seed = seed
        # Per 8-bit code: linear light, each channel's weighted share of the luminance
        # and (for grey frames) ln(max(light, linlog_intensity)), all float32 and
        # computed by the same operations the per-pixel path used, so events are
        # bit-for-bit those of converting every pixel.
        self._lut, self._wlut = luminance_tables()
        self._log_lut = np.log(np.maximum(self._lut, np.float32(self.params.linlog_intensity)))
        n = self.width * self.height
        self._lum = np.empty(n, np.float32)
        self._log_in = np.empty(n, np.float32)
        self._level_new = np.empty(n, np.float32)
        self._diff_new = np.empty(n, np.float32)
        self._active = np.empty(n, np.int64)
        self._alpha = np.empty(n, np.float32)
        self._no_lowpass = np.empty(0, np.float32)
        self._t_prev: int | None = None
        self.max_log_change = 0.0
        self._init_pixels(seed)

    @property
    def channel_luminance(self) -> np.ndarray:
        """(3, 256) float32: each sRGB channel code's weighted share of the linear
        luminance, as this emulator sums it (read, never write)."""
        return self._wlut

    # -- set-up -------------------------------------------------------------------------
    def _init_pixels(self, seed: int | None) -> None:
        p, n = self.params, self.width * self.height
        self._rng = np.random.default_rng(seed)
        if p.threshold_sigma > 0:
            on = self._rng.normal(p.threshold_on, p.threshold_sigma, n)
            off = self._rng.normal(p.threshold_off, p.threshold_sigma, n)
        else:
            on, off = np.full(n, p.threshold_on), np.full(n, p.threshold_off)
        self.th_on = np.maximum(on, p.threshold_min).astype(np.float32)
        self.th_off = np.maximum(off, p.threshold_min).astype(np.float32)
        hot = np.zeros(n, dtype=bool)
        if p.hot_pixel_fraction > 0:
            k = round(p.hot_pixel_fraction * n)
            hot[self._rng.choice(n, size=k, replace=False)] = True
        self.hot_pixels = np.flatnonzero(hot)

    def reset(self, frame: np.ndarray | LogFrame, t_us: int, seed: int | None = None) -> None:
        """Start a new stream at ``t_us`` with ``frame`` (or its :class:`LogFrame`);
        optionally re-seed."""
        if seed is not None:
            self.seed = seed
            self._init_pixels(seed)
        lum = self._prepared(frame).lum
        log_in = linlog(lum, self.params.linlog_intensity).astype(np.float32)
        self._log_in_prev = log_in
        self._level = log_in.copy()
        self._diff = np.zeros(lum.size, np.float32)
        if self.params.leak_rate_hz > 0:
            # Random leak phases, so that pixels do not all leak in the same instant.
            self._diff = (self._rng.uniform(0, 1, lum.size) * self.th_on).astype(np.float32)
        self._last_event = np.full(lum.size, -np.inf)
        self._pending = _NO_EVENTS
        self._t_prev = int(t_us)
        self.max_log_change = 0.0

    # -- checks ---------------------------------------------------------------------------
    def _luminance(
        self, frame: np.ndarray, lum: np.ndarray | None = None, log_in: np.ndarray | None = None
    ) -> np.ndarray:
        """Validate ``frame``; fill ``lum`` (linear luminance) and ``log_in`` =
        ``ln(max(lum, floor))`` (by default ``self._lum`` and ``self._log_in``); returns
        ``lum``. The linear segment below the floor is patched in later."""
        lum = self._lum if lum is None else lum
        log_in = self._log_in if log_in is None else log_in
        if not isinstance(frame, np.ndarray):
            raise ValueError(f"frame must be a numpy array, got {type(frame).__name__}")
        h, w = self.height, self.width
        floor = self.params.linlog_intensity
        if frame.dtype == np.uint8:
            if frame.shape == (h, w):
                _luminance_grey(frame.reshape(-1), self._lut, self._log_lut, lum, log_in)
                return lum
            if frame.shape != (h, w, 3):
                raise ValueError(
                    f"uint8 frame must have shape ({h}, {w}, 3) or ({h}, {w}), got {frame.shape}"
                )
            _luminance_rgb(frame.reshape(-1), self._wlut, floor, lum, log_in)
        elif frame.dtype.kind == "f":
            if frame.shape != (h, w):
                raise ValueError(f"float frame must have shape ({h}, {w}), got {frame.shape}")
            if not np.isfinite(frame).all():
                raise ValueError("frame contains NaN or infinite values")
            if frame.min() < 0:
                raise ValueError(f"frame intensity must be >= 0, got min {frame.min()}")
            lum[:] = frame.reshape(-1)
            np.maximum(lum, floor, out=log_in)
        else:
            raise ValueError(
                f"frame dtype must be uint8 (sRGB) or float (linear), got {frame.dtype}"
            )
        np.log(log_in, out=log_in)
        return lum

    def _check_time(self, t_us: int) -> int:
        if self._t_prev is None:
            raise RuntimeError("call reset(frame, t_us) before step()")
        t_us = int(t_us)
        if t_us <= self._t_prev:
            raise ValueError(f"time must increase: t_us={t_us} <= previous {self._t_prev}")
        return t_us

    def prepare(self, frame: np.ndarray) -> LogFrame:
        """Validate ``frame`` and convert it to the pixels' input (see :class:`LogFrame`)."""
        n = self.width * self.height
        lum, log_in = np.empty(n, np.float32), np.empty(n, np.float32)
        self._luminance(frame, lum, log_in)
        _patch_linlog(lum, log_in, self.params.linlog_intensity)
        return LogFrame(lum, log_in)

    def log_change(self, frame: np.ndarray | LogFrame) -> float:
        """Largest input log-intensity change ``frame`` would bring; changes no state.

        The value :attr:`max_log_change` takes when ``frame`` is the next :meth:`step`.
        """
        if self._t_prev is None:
            raise RuntimeError("call reset(frame, t_us) before log_change()")
        return float(_max_change(self._prepared(frame).log_in, self._log_in_prev))

    def _prepared(self, frame: np.ndarray | LogFrame) -> LogFrame:
        if not isinstance(frame, LogFrame):
            return self.prepare(frame)
        n = self.width * self.height
        if frame.lum.shape != (n,) or frame.log_in.shape != (n,):
            raise ValueError(f"LogFrame is for another sensor size: {frame.lum.shape} != ({n},)")
        return frame

    # -- the step -----------------------------------------------------------------------
    def step(self, frame: np.ndarray | LogFrame, t_us: int) -> np.ndarray:
        """Events in ``(t_prev, t_us]`` caused by moving to ``frame`` at ``t_us``.

        ``frame`` may be a :class:`LogFrame` from :meth:`prepare` (same events, one
        conversion fewer).
        """
        t_us = self._check_time(t_us)
        if isinstance(frame, LogFrame):
            lum = self._prepared(frame).lum
            np.copyto(self._log_in, frame.log_in)
        else:
            lum = self._luminance(frame)
        p, t0 = self.params, self._t_prev
        dt_s = (t_us - t0) * 1e-6
        self.max_log_change = float(
            _levels(
                lum,
                self._log_in_prev,
                self._level,
                self._diff,
                self.th_on,
                p.linlog_intensity,
                self._lowpass(lum, dt_s),
                p.leak_rate_hz * dt_s,
                self._log_in,
                self._level_new,
                self._diff_new,
            )
        )
        n_active, bound = _crossing_pixels(
            self._diff, self._diff_new, self.th_on, self.th_off, self._active
        )
        xs, ys = np.empty(bound, np.int16), np.empty(bound, np.int16)
        ts, ps = np.empty(bound, np.float64), np.empty(bound, np.int8)
        n = _emit(
            self._active[:n_active],
            self._diff,
            self._diff_new,
            self.th_on,
            self.th_off,
            self._last_event,
            p.refractory_us,
            float(t0),
            float(t_us),
            self.width,
            xs,
            ys,
            ts,
            ps,
        )
        self._level, self._level_new = self._level_new, self._level
        self._log_in_prev, self._log_in = self._log_in, self._log_in_prev
        ts = ts[:n]
        if p.latency_us > 0 or p.jitter_us > 0:
            jitter = self._rng.normal(0.0, p.jitter_us, n) if p.jitter_us > 0 else 0.0
            ts = ts + np.maximum(p.latency_us + jitter, 0.0)
        # To the nearest µs, but never onto t0: a crossing in (t0, t1] stays in it.
        t_int = np.maximum(np.rint(ts), t0 + 1).astype(np.int64)
        crossings = (xs[:n], ys[:n], t_int, ps[:n])
        self._t_prev = t_us
        return self._deliver([self._pending, crossings, *self._noise(t0, t_us)], t_us)

    def _lowpass(self, lum: np.ndarray, dt_s: float) -> np.ndarray:
        """Per pixel ``1 - exp(-2π·fc(I)·dt)``, fc rising with intensity; empty if off."""
        p = self.params
        if p.cutoff_hz <= 0:
            return self._no_lowpass
        k = np.float32(-2 * math.pi * dt_s * p.cutoff_hz / (1 + p.cutoff_dark))
        a = np.add(lum, np.float32(p.cutoff_dark), out=self._alpha)
        a *= k
        np.expm1(a, out=a)
        return np.negative(a, out=a)

    def _noise(self, t0: int, t1: int) -> list[_Columns]:
        """Shot noise and hot-pixel events, uniform in (t0, t1]."""
        p, out = self.params, []
        dt_s = (t1 - t0) * 1e-6
        n_pix = self.width * self.height
        if p.shot_rate_hz > 0:
            k = self._rng.poisson(p.shot_rate_hz * dt_s * n_pix)
            idx = self._rng.integers(0, n_pix, k)
            out.append(self._columns_at(idx, t0, t1, self._rng.integers(0, 2, k)))
        if len(self.hot_pixels):
            k = self._rng.poisson(p.hot_pixel_rate_hz * dt_s, len(self.hot_pixels))
            idx = np.repeat(self.hot_pixels, k)
            out.append(self._columns_at(idx, t0, t1, np.ones(len(idx))))
        return out

    def _columns_at(self, idx: np.ndarray, t0: int, t1: int, pol: np.ndarray) -> _Columns:
        t = self._rng.integers(t0 + 1, t1 + 1, len(idx))
        return (
            (idx % self.width).astype(np.int16),
            (idx // self.width).astype(np.int16),
            t.astype(np.int64),
            pol.astype(np.int8),
        )

    def _deliver(self, parts: list[_Columns], t_us: int) -> np.ndarray:
        """Sort all candidate events; return those up to ``t_us``, keep the rest pending."""
        parts = [c for c in parts if len(c[2])] or [_NO_EVENTS]
        cols = parts[0]
        if len(parts) > 1:
            cols = tuple(np.concatenate([c[k] for c in parts]) for k in range(4))
        order = _order_by_time(cols[2])
        cols = tuple(c[order] for c in cols)
        cut = int(np.searchsorted(cols[2], t_us, side="right"))
        self._pending = tuple(c[cut:] for c in cols)
        ev = np.empty(cut, EVENT_DTYPE)
        for name, c in zip("xytp", cols, strict=True):
            ev[name] = c[:cut]
        return ev

    def flush(self) -> np.ndarray:
        """Events still held back by latency (timestamps after the last frame)."""
        return self._deliver([self._pending], np.iinfo(np.int64).max)

    @property
    def pending(self) -> int:
        """How many delayed events are waiting for a later call."""
        return len(self._pending[2])
