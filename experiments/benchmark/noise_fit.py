"""Fit a sensor's background activity and hot pixels to a recording: the noise terms of
:class:`~wander_env.dvs.DVSParams` and the kill list of
:class:`~wander_env.readout.ReadoutParams`, measured instead of assumed.

:func:`fit_noise` reads an event recording (any scene; a still camera is best):

- **per-pixel rate**: events per second of each pixel;
- **hot pixels**: pixels firing at least ``hot_min_hz`` (50 Hz: the lower end of the
  Speck datasheet's 50–1000 Hz, §3.2.3.5.3) and at least ``hot_ratio`` (4) times the
  mean rate of their 8 neighbours (a hot pixel fires alone: an edge that crosses it
  crosses its neighbours too; two hot pixels side by side are both still found);
- **background activity**: events with no event at any of the 8 neighbouring pixels
  within the previous ``support_us`` (the support test of a background-activity
  filter), per pixel and second, over the pixels that are not hot, separately ON and
  OFF. Scene events without support (an edge's first pixel) count too, so on a busy
  scene this is an upper bound.

:meth:`NoiseFit.dvs_overrides` turns the fit into the emulator's terms: the emulator's
shot noise fires either polarity (``shot_rate_hz`` in total) and its leak fires ON only,
so ``shot_rate_hz = 2 · OFF rate`` and ``leak_rate_hz = ON rate − OFF rate`` (at least
0); ``hot_pixel_fraction`` and ``hot_pixel_rate_hz`` (the median hot rate) from the hot
pixels. :attr:`NoiseFit.hot_pixels` is a ready ``kill_pixels`` list.

:func:`rates_from_interval_histogram` reads the other kind of noise recording, IEBCS's
per-pixel histograms of noise-event intervals (``noise_{pos,neg}_<lux>.npy``), into
per-pixel rates; their means are the ``paper`` DVS preset's background rates.

docs/readout.md has the worked example.

Examples:
    >>> from wander_env.events import make_events
    >>> ev = make_events([3] * 100, [3] * 100, range(0, 1_000_000, 10_000), [1] * 100)
    >>> fit = fit_noise(ev, (8, 8), duration_s=1.0)
    >>> fit.hot_pixels, fit.hot_rates_hz  # one pixel at 100 Hz, alone
    (((3, 3),), (100.0,))
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

__all__ = ["IEBCS_FREQ_HZ", "NoiseFit", "fit_noise", "rates_from_interval_histogram"]

#: The frequency bins of IEBCS's noise histograms: 1..9 × 10^d Hz, d = -3..4
#: (neuromorphicsystems/IEBCS ``src/dvs_sensor.py``, ``init_bgn_hist``).
IEBCS_FREQ_HZ = np.array([m * 10.0**d for d in range(-3, 5) for m in range(1, 10)])


@dataclass(frozen=True)
class NoiseFit:
    """What :func:`fit_noise` measured. Rates in Hz per pixel."""

    sensor_size: tuple[int, int]
    duration_s: float
    rate_hz: np.ndarray  # (H, W): every event
    background_on_hz: float  # unsupported ON events, per non-hot pixel
    background_off_hz: float
    hot_pixels: tuple[tuple[int, int], ...]  # (x, y), the fastest first
    hot_rates_hz: tuple[float, ...]

    def dvs_overrides(self) -> dict[str, float]:
        """The fit as :class:`~wander_env.dvs.DVSParams` fields (see the module docstring):
        ``DVSParams.preset("speck", **fit.dvs_overrides())``."""
        w, h = self.sensor_size
        out = {
            "leak_rate_hz": max(self.background_on_hz - self.background_off_hz, 0.0),
            "shot_rate_hz": 2.0 * self.background_off_hz,
            "hot_pixel_fraction": len(self.hot_pixels) / (w * h),
        }
        if self.hot_pixels:
            out["hot_pixel_rate_hz"] = float(np.median(self.hot_rates_hz))
        return out


@numba.njit(cache=True, nogil=True)
def _unsupported(x, y, t, p, width, height, support_us, on, off):
    """Count, per pixel, the ON and OFF events with no event at the 8 neighbours within
    the previous ``support_us`` (events in time order)."""
    last = np.full(width * height, np.iinfo(np.int64).min // 2, np.int64)
    for i in range(x.size):
        xi, yi, ti = np.int64(x[i]), np.int64(y[i]), t[i]
        supported = False
        for yy in range(max(yi - 1, 0), min(yi + 1, height - 1) + 1):
            for xx in range(max(xi - 1, 0), min(xi + 1, width - 1) + 1):
                if (xx != xi or yy != yi) and ti - last[yy * width + xx] <= support_us:
                    supported = True
        own = yi * width + xi
        if not supported:
            if p[i] != 0:
                on[own] += 1
            else:
                off[own] += 1
        last[own] = ti


def _neighbour_mean(rate: np.ndarray) -> np.ndarray:
    """The mean of each pixel's 8 neighbours (edge pixels: of those that exist)."""
    h, w = rate.shape
    padded = np.pad(rate.astype(float), 1, constant_values=np.nan)
    shifts = [
        padded[1 + dy : 1 + dy + h, 1 + dx : 1 + dx + w]
        for dy in (-1, 0, 1)
        for dx in (-1, 0, 1)
        if dy or dx
    ]
    return np.nanmean(np.stack(shifts), axis=0)


def fit_noise(
    events: np.ndarray,
    sensor_size: tuple[int, int],
    duration_s: float | None = None,
    *,
    support_us: int = 10_000,
    hot_min_hz: float = 50.0,
    hot_ratio: float = 4.0,
) -> NoiseFit:
    """Per-pixel rates, hot pixels and background activity of ``events`` (sorted by
    ``t``) from a ``sensor_size`` = (W, H) sensor over ``duration_s`` (default: first
    to last event). See the module docstring."""
    w, h = int(sensor_size[0]), int(sensor_size[1])
    if len(events) == 0:
        raise ValueError("fit_noise: no events")
    t = events["t"].astype(np.int64)
    if np.any(np.diff(t) < 0):
        raise ValueError("fit_noise: events must be sorted by t")
    x, y = events["x"].astype(np.int64), events["y"].astype(np.int64)
    if x.min() < 0 or y.min() < 0 or x.max() >= w or y.max() >= h:
        raise ValueError(f"fit_noise: events outside the {w}x{h} sensor")
    if duration_s is None:
        duration_s = (int(t[-1]) - int(t[0])) * 1e-6
    if not duration_s > 0:
        raise ValueError(f"fit_noise: duration_s must be > 0, got {duration_s}")
    counts = np.bincount(y * w + x, minlength=w * h).reshape(h, w)
    rate = counts / duration_s
    hot = (rate >= hot_min_hz) & (rate >= hot_ratio * _neighbour_mean(rate))
    on, off = np.zeros(w * h, np.int64), np.zeros(w * h, np.int64)
    _unsupported(x, y, t, events["p"].astype(np.int8), w, h, int(support_us), on, off)
    cold = ~hot.reshape(-1)
    per_pixel_s = max(int(cold.sum()), 1) * duration_s
    hy, hx = np.nonzero(hot)
    order = np.argsort(-rate[hy, hx], kind="stable")
    return NoiseFit(
        sensor_size=(w, h),
        duration_s=float(duration_s),
        rate_hz=rate,
        background_on_hz=float(on[cold].sum() / per_pixel_s),
        background_off_hz=float(off[cold].sum() / per_pixel_s),
        hot_pixels=tuple((int(hx[i]), int(hy[i])) for i in order),
        hot_rates_hz=tuple(float(rate[hy[i], hx[i]]) for i in order),
    )


def rates_from_interval_histogram(cumulative: np.ndarray) -> np.ndarray:
    """Per-pixel noise rates (Hz; 0 where a pixel has no data) from IEBCS noise
    histograms: ``(..., 72)`` cumulative counts over :data:`IEBCS_FREQ_HZ` with the total
    in element ``[-2]`` (``[-1]`` unused). IEBCS draws a pixel's next noise event
    ``1 / f`` after the last, ``f`` from this distribution; the rate is the inverse of
    the mean interval.

    >>> h = np.zeros(72); h[27:] = 2; h[36:] = 4; h[-1] = 0  # 2 at 1 Hz, 2 at 10 Hz
    >>> float(rates_from_interval_histogram(h))  # intervals 1 s and 0.1 s: mean 0.55 s
    1.8181818181818181
    """
    c = np.asarray(cumulative, float)
    if c.shape[-1] != 72:
        raise ValueError(f"an IEBCS noise histogram has 72 bins, got {c.shape[-1]}")
    total = c[..., -2]
    cdf = c[..., :-1] / np.where(total > 0, total, 1.0)[..., None]
    pdf = np.diff(cdf, axis=-1, prepend=0.0)
    mean_interval = (pdf / IEBCS_FREQ_HZ[:71]).sum(axis=-1)
    return np.where(total > 0, 1.0 / np.where(mean_interval > 0, mean_interval, 1.0), 0.0)
