"""Main-sequence fits: saccade peak velocity and duration against amplitude (pure).

The two standard forms of the oculomotor literature (Bahill, Clark & Stark 1975; Baloh
et al. 1975):

- peak velocity, saturating: ``V(A) = Vmax · (1 − exp(−A / C))`` (``Vmax`` °/s, ``C`` °);
- duration, linear: ``D(A) = D0 + k · A`` (``D0`` s, ``k`` s/°).

:func:`fit_saturating` and :func:`fit_linear` fit them by least squares
(:func:`scipy.optimize.curve_fit`) and give each parameter's 95 % interval from the
fit's covariance (Student's t with ``n − 2`` degrees of freedom), the RMS residual and
R². A PTU's trapezoid is not an exponential: the residuals say how far it is from the
eye's shape.

Examples:
    >>> import numpy as np
    >>> a = np.array([1.0, 2, 5, 10, 20, 40])
    >>> fit = fit_saturating(a, 50 * (1 - np.exp(-a / 8)))
    >>> round(fit.params["vmax"], 3), round(fit.params["c"], 3), round(fit.r2, 6)
    (50.0, 8.0, 1.0)
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import numpy as np
from scipy import optimize
from scipy import stats as _st

__all__ = ["MainSequenceFit", "fit_linear", "fit_saturating", "linear", "saturating"]


def saturating(a: np.ndarray, vmax: float, c: float) -> np.ndarray:
    """``vmax · (1 − exp(−a / c))``."""
    return vmax * (1.0 - np.exp(-np.asarray(a, float) / c))


def linear(a: np.ndarray, d0: float, k: float) -> np.ndarray:
    """``d0 + k · a``."""
    return d0 + k * np.asarray(a, float)


@dataclass(frozen=True)
class MainSequenceFit:
    """Parameters by name, their 95 % intervals ``(low, high)``, n points, RMS residual
    and R² (NaN where the fit is undefined, e.g. fewer than 3 points)."""

    form: str
    params: dict[str, float]
    intervals: dict[str, tuple[float, float]]
    n: int
    rmse: float
    r2: float

    def text(self, units: dict[str, str] | None = None) -> str:
        """``name = value [low, high] unit, ...``"""
        units = units or {}
        parts = []
        for k, v in self.params.items():
            lo, hi = self.intervals[k]
            u = f" {units[k]}" if k in units else ""
            parts.append(f"{k} = {v:.4g} [{lo:.4g}, {hi:.4g}]{u}")
        return ", ".join(parts) + f" (n = {self.n}, R² = {self.r2:.3f})"

    def as_dict(self, prefix: str) -> dict[str, float]:
        """Flat columns ``<prefix><name>``, ``..._low``, ``..._high``, ``<prefix>r2``."""
        out: dict[str, float] = {}
        for k, v in self.params.items():
            out |= {
                f"{prefix}{k}": v,
                f"{prefix}{k}_low": self.intervals[k][0],
                f"{prefix}{k}_high": self.intervals[k][1],
            }
        return out | {f"{prefix}r2": self.r2, f"{prefix}rmse": self.rmse}


def _fit(form, names, f, x, y, p0, bounds) -> MainSequenceFit:
    x, y = np.asarray(x, float).ravel(), np.asarray(y, float).ravel()
    ok = np.isfinite(x) & np.isfinite(y)
    x, y = x[ok], y[ok]
    nan = dict.fromkeys(names, math.nan)
    if len(x) < 3:
        return MainSequenceFit(
            form, nan, dict.fromkeys(names, (math.nan, math.nan)), len(x), *[math.nan] * 2
        )
    with warnings.catch_warnings():  # an exact fit has no covariance: NaN intervals
        warnings.simplefilter("ignore", optimize.OptimizeWarning)
        popt, pcov = optimize.curve_fit(f, x, y, p0=p0, bounds=bounds, maxfev=20000)
    resid = y - f(x, *popt)
    dof = len(x) - len(popt)
    t = float(_st.t.ppf(0.975, dof)) if dof > 0 else math.nan
    se = np.sqrt(np.clip(np.diag(pcov), 0, None)) if np.all(np.isfinite(pcov)) else [math.nan] * 2
    ss_tot = float(np.sum((y - y.mean()) ** 2))
    r2 = 1.0 - float(np.sum(resid**2)) / ss_tot if ss_tot > 0 else math.nan
    params = {k: float(v) for k, v in zip(names, popt, strict=True)}
    intervals = {
        k: (float(v - t * s), float(v + t * s)) for k, v, s in zip(names, popt, se, strict=True)
    }
    return MainSequenceFit(form, params, intervals, len(x), float(np.sqrt(np.mean(resid**2))), r2)


def fit_saturating(amplitude_deg: np.ndarray, peak_velocity_deg_s: np.ndarray) -> MainSequenceFit:
    """Fit ``V = Vmax (1 − e^(−A/C))`` (parameters ``vmax`` °/s and ``c`` °); with the
    same peak at every amplitude ``c`` is NaN (not identifiable).

    >>> fit = fit_saturating([1.0, 5.0, 20.0], [25.7, 25.7, 25.7])
    >>> fit.params["vmax"], math.isnan(fit.params["c"]), math.isnan(fit.r2)
    (25.7, True, True)
    """
    v = np.asarray(peak_velocity_deg_s, float)
    a = np.asarray(amplitude_deg, float)
    ok = np.isfinite(a) & np.isfinite(v)
    if ok.sum() >= 3 and np.all(v[ok] == v[ok][0]):
        # The same peak at every amplitude (a unit that never leaves its base speed): Vmax
        # is that speed, C is not identifiable (any C far below the smallest amplitude
        # fits), R² undefined.
        vm = float(v[ok][0])
        return MainSequenceFit(
            "saturating",
            {"vmax": vm, "c": math.nan},
            {"vmax": (vm, vm), "c": (math.nan, math.nan)},
            int(ok.sum()),
            0.0,
            math.nan,
        )
    vmax0 = float(np.nanmax(v)) if np.isfinite(v).any() else 1.0
    c0 = float(np.nanmedian(a)) if np.isfinite(a).any() else 1.0
    return _fit(
        "saturating",
        ("vmax", "c"),
        saturating,
        a,
        v,
        (vmax0, max(c0, 1e-3)),
        ([0.0, 1e-6], [np.inf, np.inf]),
    )


def fit_linear(amplitude_deg: np.ndarray, duration_s: np.ndarray) -> MainSequenceFit:
    """Fit ``D = D0 + k·A`` (parameters ``d0`` s and ``k`` s/°).

    >>> round(fit_linear([1, 2, 3, 4], [0.1, 0.2, 0.3, 0.4]).params["k"], 6)
    0.1
    """
    return _fit(
        "linear", ("d0", "k"), linear, amplitude_deg, duration_s, (0.0, 0.01), (-np.inf, np.inf)
    )
