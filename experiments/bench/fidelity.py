"""``wander bench fidelity``: keyframe frames against exact rendering, on the same seeds.

For each scene, gaze motion and seed, four envs run in lockstep on the same actions:
``frames="exact"`` (every frame rendered, the reference), ``frames="keyframes"`` with
keys every ``keyframe_ms``, ``frames="keyframes"`` with adaptive keys (``keyframe_px``:
see :func:`wander_env.keyframes.adaptive_key_ticks`) and, for
scale, ``frames="exact"`` with 16 samples a pixel instead of the scenes' 4 (2 × 2
supersampling of the 4 MSAA samples: Mesa's llvmpipe caps MSAA at 4, so asking it for 16
renders the same pixels as 4). The motions:
``still`` (zero actions), ``walk`` (the fixational random walk of ``wander record
--policy fixational``) and ``saccade`` (one 20° pan at the first step, then still).

Per row (seeds pooled): total events of each mode; the per-step count-map L1 (the sum
over steps and pixels of |counts - exact counts|, both polarities) divided by the exact
events, for keyframes and for 16 samples; the timestamp agreement (the share of one
mode's events with an event of the other at the same pixel and polarity within
``tol_us``, both ways, and of the 16-sample events in the exact ones); and the longest
gap between consecutive events while the camera moves.

Examples:
    >>> rows = bench_fidelity(scenes=("shelf",), motions=("still",), seeds=(0,),
    ...                       seconds=0.02)  # doctest: +SKIP
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from experiments.jobs.record import GazePolicy
from wander_env.actions import gaze_degrees_to_action

SCENES = ("office", "shelf", "hand", "gratings")
MOTIONS = ("still", "walk", "saccade")
SACCADE_DEG = 20.0
_MODES = ("exact", "keyframes", "adaptive", "aa16")
# The adaptive keys' motion bound (px) the benchmark uses when not told.
ADAPTIVE_PX = 2.0


# The columns of `wander bench fidelity`'s tables (row field -> format spec).
KEYFRAME_COLUMNS: dict[str, str] = {
    "scene": "",
    "motion": "",
    "exact_events": ",d",
    "keyframes_events": ",d",
    "events_diff_pct": "+.2f",
    "l1_per_event": ".3f",
    "aa16_l1_per_event": ".3f",
    "matched_pct": ".1f",
    "exact_matched_pct": ".1f",
    "aa16_matched_pct": ".1f",
    "max_gap_exact_ms": "",
    "max_gap_keyframes_ms": "",
    "renders_per_step_exact": ".1f",
    "renders_per_step_keyframes": ".1f",
}
ADAPTIVE_COLUMNS: dict[str, str] = {
    "scene": "",
    "motion": "",
    "exact_events": ",d",
    "adaptive_events": ",d",
    "adaptive_events_diff_pct": "+.2f",
    "adaptive_l1_per_event": ".3f",
    "aa16_l1_per_event": ".3f",
    "adaptive_matched_pct": ".1f",
    "adaptive_exact_matched_pct": ".1f",
    "max_gap_exact_ms": "",
    "max_gap_adaptive_ms": "",
    "renders_per_step_exact": ".1f",
    "renders_per_step_adaptive": ".1f",
}


@dataclass(frozen=True)
class FidelityRow:
    """One scene and motion, seeds pooled (see the module docstring)."""

    scene: str
    motion: str
    keyframe_ms: float
    seeds: int
    steps: int
    exact_events: int
    keyframes_events: int
    events_diff_pct: float  # keyframes vs exact
    l1_per_event: float  # keyframes vs exact
    aa16_l1_per_event: float  # exact with 16 samples a pixel vs exact (4): the scale
    matched_pct: float  # keyframes events with an exact event within tol_us
    exact_matched_pct: float  # exact events with a keyframes event within tol_us
    aa16_matched_pct: float  # 16-sample events with an exact event within tol_us: the scale
    max_gap_exact_ms: float | None  # while the camera moves; None when it never does
    max_gap_keyframes_ms: float | None
    renders_per_step_exact: float
    renders_per_step_keyframes: float
    # Adaptive keys (keyframe_px): the same measures against exact.
    keyframe_px: float = ADAPTIVE_PX
    adaptive_ms: float = float("nan")  # the adaptive keys' longest interval while moving
    adaptive_events: int = 0
    adaptive_events_diff_pct: float = float("nan")
    adaptive_l1_per_event: float = float("nan")
    adaptive_matched_pct: float = float("nan")
    adaptive_exact_matched_pct: float = float("nan")
    max_gap_adaptive_ms: float | None = None
    renders_per_step_adaptive: float = float("nan")


def matched_share(a: np.ndarray, b: np.ndarray, tol_us: int, width: int, height: int) -> float:
    """Share of events in ``a`` with an event of ``b`` at the same pixel and polarity no
    more than ``tol_us`` apart (``nan`` when ``a`` is empty).

    >>> from wander_env.events import EVENT_DTYPE
    >>> a = np.array([(1, 2, 100, 1), (1, 2, 5000, 1), (3, 3, 10, 0)], EVENT_DTYPE)
    >>> b = np.array([(1, 2, 900, 1), (3, 3, 10, 1)], EVENT_DTYPE)
    >>> matched_share(a, b, 1000, 4, 4)
    0.3333333333333333
    """
    if len(a) == 0:
        return float("nan")
    if len(b) == 0:
        return 0.0

    def codes(ev: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        key = (ev["p"].astype(np.int64) * height + ev["y"]) * width + ev["x"]
        return key, ev["t"].astype(np.int64)

    ka, ta = codes(a)
    kb, tb = codes(b)
    shift = np.int64(1) << np.int64(42)  # times below 2^41 µs (25 days)
    cb = np.sort(kb * shift + tb)
    ca = ka * shift + ta
    i = np.searchsorted(cb, ca)
    ok = np.zeros(len(a), bool)
    for j in (i - 1, i):
        valid = (j >= 0) & (j < len(cb))
        jj = np.clip(j, 0, len(cb) - 1)
        near = cb[jj]
        ok |= valid & (near // shift == ka) & (np.abs(near % shift - ta) <= tol_us)
    return float(ok.mean())


def _max_gap_ms(events: np.ndarray, windows: list[tuple[int, int]]) -> float | None:
    """Longest interval (ms) without an event inside the windows (edges included)."""
    if not windows:
        return None
    t = np.sort(events["t"].astype(np.int64))
    gap = 0
    for t0, t1 in windows:
        inside = t[(t > t0) & (t <= t1)]
        pts = np.concatenate([[t0], inside, [t1]])
        gap = max(gap, int(np.diff(pts).max()))
    return gap / 1e3


def _moving_windows(flags: list[bool], period_us: int) -> list[tuple[int, int]]:
    """(t0, t1] spans (µs) of the runs of steps in which the camera moved."""
    out: list[tuple[int, int]] = []
    for k, moving in enumerate(flags):
        t0, t1 = k * period_us, (k + 1) * period_us
        if not moving:
            continue
        if out and out[-1][1] == t0:
            out[-1] = (out[-1][0], t1)
        else:
            out.append((t0, t1))
    return out


@dataclass
class _Run:
    events: dict[str, list[np.ndarray]]
    l1: dict[str, float]
    renders: dict[str, int]
    moving: list[bool]
    steps: int
    period_us: int


def _run(
    scene: str,
    motion: str,
    seed: int,
    seconds: float,
    keyframe_ms: float,
    keyframe_px: float,
    adaptive_ms: float,
) -> _Run:
    import gymnasium as gym

    import wander_env  # noqa: F401  (registers the environments)

    kwargs = {
        "exact": {"frames": "exact"},
        "keyframes": {"frames": "keyframes", "keyframe_ms": keyframe_ms, "keyframe_px": None},
        "adaptive": {"frames": "keyframes", "keyframe_ms": adaptive_ms, "keyframe_px": keyframe_px},
        "aa16": {"frames": "exact", "supersample": 2},
    }
    envs = {
        m: gym.make("wander/Wander-v0", scene=scene, episode_seconds=seconds + 1.0, **kw)
        for m, kw in kwargs.items()
    }
    try:
        base = envs["exact"].unwrapped
        period = base.config.control_period_s
        infos = {m: env.reset(seed=seed)[1] for m, env in envs.items()}
        policy = GazePolicy("fixational", seed + 1, period, 0.5)
        run = _Run(
            {m: [] for m in envs},
            dict.fromkeys(envs, 0.0),
            dict.fromkeys(envs, 0),
            [],
            round(seconds / period),
            round(period * 1e6),
        )
        for k in range(run.steps):
            if motion == "walk":
                action = policy.act(infos["exact"])
            elif motion == "saccade" and k == 0:
                cam = base.scene.camera
                action = gaze_degrees_to_action(
                    SACCADE_DEG, 0.0, cam.width, cam.height, cam.hfov_deg
                )
                action = action.astype(np.float32)
            else:
                action = np.zeros(2, np.float32)
            counts = {}
            for m, env in envs.items():
                obs, _, _, _, info = env.step(action)
                infos[m] = info
                counts[m] = obs["events"]
                run.events[m].append(info["events"])
                run.renders[m] += env.unwrapped.renders_in_step
            run.moving.append(bool(infos["exact"]["moving"]))
            for m in ("keyframes", "adaptive", "aa16"):
                run.l1[m] += float(np.abs(counts[m] - counts["exact"]).sum())
        return run
    finally:
        for env in envs.values():
            env.close()


def _pct(x: float) -> float:
    return 100.0 * x if math.isfinite(x) else float("nan")


def bench_fidelity(
    scenes: tuple[str, ...] = SCENES,
    motions: tuple[str, ...] = MOTIONS,
    seeds: tuple[int, ...] = (0, 1, 2),
    seconds: float = 0.25,
    keyframe_ms: float | None = None,
    keyframe_px: float = ADAPTIVE_PX,
    adaptive_ms: float | None = None,
    tol_us: int = 1000,
    progress: Callable[[str], None] | None = None,
) -> list[FidelityRow]:
    """One row per scene and motion (seeds pooled); see the module docstring.
    ``keyframe_ms`` defaults to the env's; the adaptive columns use keys bounded by
    ``keyframe_px`` and no more than ``adaptive_ms`` apart (default ``keyframe_ms``)
    while anything moves (``WanderConfig.keyframe_px``)."""
    from wander_env.env import WanderConfig

    keyframe_ms = WanderConfig.keyframe_ms if keyframe_ms is None else keyframe_ms
    adaptive_ms = keyframe_ms if adaptive_ms is None else adaptive_ms
    rows = []
    for scene in scenes:
        for motion in motions:
            runs = []
            for seed in seeds:
                if progress is not None:
                    progress(f"{scene} {motion} seed {seed}")
                runs.append(
                    _run(scene, motion, seed, seconds, keyframe_ms, keyframe_px, adaptive_ms)
                )
            ev = {m: [np.concatenate(r.events[m]) for r in runs] for m in _MODES}
            n = {m: sum(len(e) for e in ev[m]) for m in _MODES}
            steps = sum(r.steps for r in runs)

            def share(x: str, y: str, ev=ev, n=n) -> float:
                if n[x] == 0:
                    return float("nan")
                got = sum(
                    matched_share(a, b, tol_us, 128, 128) * len(a)
                    for a, b in zip(ev[x], ev[y], strict=True)
                    if len(a)
                )
                return got / n[x]

            gaps = {}
            for m in ("exact", "keyframes", "adaptive"):
                per = [
                    _max_gap_ms(e, _moving_windows(r.moving, r.period_us))
                    for e, r in zip(ev[m], runs, strict=True)
                ]
                per = [g for g in per if g is not None]
                gaps[m] = max(per) if per else None
            den = max(n["exact"], 1)
            rows.append(
                FidelityRow(
                    scene=scene,
                    motion=motion,
                    keyframe_ms=keyframe_ms,
                    seeds=len(seeds),
                    steps=steps,
                    exact_events=n["exact"],
                    keyframes_events=n["keyframes"],
                    events_diff_pct=_pct(n["keyframes"] / n["exact"] - 1.0)
                    if n["exact"]
                    else float("nan"),
                    l1_per_event=sum(r.l1["keyframes"] for r in runs) / den,
                    aa16_l1_per_event=sum(r.l1["aa16"] for r in runs) / den,
                    matched_pct=_pct(share("keyframes", "exact")),
                    exact_matched_pct=_pct(share("exact", "keyframes")),
                    aa16_matched_pct=_pct(share("aa16", "exact")),
                    max_gap_exact_ms=gaps["exact"],
                    max_gap_keyframes_ms=gaps["keyframes"],
                    renders_per_step_exact=sum(r.renders["exact"] for r in runs) / steps,
                    renders_per_step_keyframes=sum(r.renders["keyframes"] for r in runs) / steps,
                    keyframe_px=keyframe_px,
                    adaptive_ms=adaptive_ms,
                    adaptive_events=n["adaptive"],
                    adaptive_events_diff_pct=_pct(n["adaptive"] / n["exact"] - 1.0)
                    if n["exact"]
                    else float("nan"),
                    adaptive_l1_per_event=sum(r.l1["adaptive"] for r in runs) / den,
                    adaptive_matched_pct=_pct(share("adaptive", "exact")),
                    adaptive_exact_matched_pct=_pct(share("exact", "adaptive")),
                    max_gap_adaptive_ms=gaps["adaptive"],
                    renders_per_step_adaptive=sum(r.renders["adaptive"] for r in runs) / steps,
                )
            )
    return rows
