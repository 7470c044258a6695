"""``wander perf fidelity``: every frame mode against the world, on the same seeds.

The yardstick is a fine **reference**: exact rendering with 64 samples a pixel
(``supersample=4`` × the scenes' MSAA 4) at 4 kHz render ticks (``render_rate_hz=4000``),
what a photodiode that integrates its whole area, sampled finely in time, would see. Against
it, on the same seeds and actions, run:

- ``exact``: every 1 ms tick rendered with the scenes' 4 samples a pixel (MSAA 4);
- ``aa16``: the same with 16 samples a pixel (``supersample=2``);
- ``default``: the env's default frames (``WanderConfig``'s defaults);
- ``fine``: the default frames with ``quality="fine"`` (keys with 16 samples a pixel);
- ``one_key``: ``frames="keyframes"`` with one key a step (``keyframe_ms`` = the control
  period, ``keyframe_px=None``);
- ``panorama``: ``frames="panorama"`` (the static world warped from a cube map rendered
  once per reset, see :class:`wander_env.frames.panorama.PanoramaFrames`).

The motions: ``still`` (zero actions), ``walk`` (the fixational random walk of ``wander
record --policy fixational``) and ``saccade`` (one 20° pan at the first step, then still).

Per row (scene × motion, seeds pooled) and mode (:class:`ModeStats`): the events'
deviation from the reference (%), the per-step count-map L1 (the sum over steps, pixels
and polarities of ``|counts − reference counts|``) over the reference's events, *matched*
(the share of the reference's events with an event of the mode at the same pixel and
polarity no more than ``tol_us`` away), the longest event gap while the camera moves in a
saccade row (ms) and the RGB renders per step. The old comparison against 4-sample exact
(the share of exact's events the default matches within ``tol_us``) is one more column.

The bar (:func:`bar_check`), per row: the default's ``|events deviation|`` no more than
exact's + 2 points, its L1 no more than 1.1 × exact's, its matched share at least exact's
− 3 points, and no event gap above 2 ms during a saccade; and ``fine``'s L1 no more than
0.75 × exact's (its own column, not the default's verdict).

Examples:
    >>> rows = bench_fidelity(scenes=("shelf",), motions=("still",), seeds=(0,),
    ...                       seconds=0.02)  # doctest: +SKIP
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from agents.scripted import GazePolicy
from experiments.analysis.stats import number_text
from wander_env.actions import gaze_degrees_to_action

SCENES = ("office", "hand", "shelf", "gratings")
MOTIONS = ("still", "walk", "saccade")
SACCADE_DEG = 20.0
REFERENCE_HZ = 4000.0
REFERENCE_SUPERSAMPLE = 4
#: The modes compared against the reference, in the tables' order.
MODES = ("exact", "aa16", "default", "fine", "one_key", "panorama")
# The bar's margins: events (points), L1 (factor), matched (points), gap (ms).
BAR_EVENTS_PTS = 2.0
BAR_L1_FACTOR = 1.1
BAR_MATCHED_PTS = 3.0
BAR_GAP_MS = 2.0
# `fine`'s bar: its L1 no more than this times exact's.
BAR_FINE_L1_FACTOR = 0.75

# The columns of `wander perf fidelity`'s tables (field -> format spec).
MODE_COLUMNS: dict[str, str] = {
    "scene": "",
    "motion": "",
    "reference_events": ",d",
    "reference_renders": ".1f",
    **dict.fromkeys(MODES, ""),
}
BAR_COLUMNS: dict[str, str] = {
    "scene": "",
    "motion": "",
    "events": "",
    "l1": "",
    "matched": "",
    "gap": "",
    "default_vs_exact_pct": ".1f",
    "verdict": "",
    "fine_l1": "",
}


@dataclass(frozen=True)
class ModeStats:
    """One mode on one row, seeds pooled, against the reference (module docstring)."""

    events: int
    events_dev_pct: float
    l1_per_event: float
    matched_pct: float
    max_gap_ms: float | None  # saccade rows only
    renders_per_step: float


@dataclass(frozen=True)
class BarCheck:
    """The default against exact on one row: each condition and whether it holds."""

    events: bool
    l1: bool
    matched: bool
    gap: bool

    @property
    def ok(self) -> bool:
        return self.events and self.l1 and self.matched and self.gap


@dataclass(frozen=True)
class FidelityRow:
    """One scene and motion, seeds pooled: the reference's events and renders a step,
    every mode's :class:`ModeStats`, the old comparison (the share of exact's events the
    default matches, %) and the bar."""

    scene: str
    motion: str
    seeds: int
    steps: int
    reference_events: int
    reference_renders: float
    modes: dict[str, ModeStats]
    default_vs_exact_pct: float
    bar: BarCheck


def bar_check(default: ModeStats, exact: ModeStats) -> BarCheck:
    """The bar of the default against exact on one row (module docstring); a row whose
    reference has no events (``matched_pct`` nan) passes the matched condition.

    >>> ex = ModeStats(100, -8.0, 0.5, 40.0, 1.0, 14.0)
    >>> bar_check(ModeStats(99, -9.5, 0.55, 37.0, 2.0, 3.0), ex)
    BarCheck(events=True, l1=True, matched=True, gap=True)
    >>> bar_check(ModeStats(97, -10.5, 0.56, 36.5, 2.5, 3.0), ex)
    BarCheck(events=False, l1=False, matched=False, gap=False)
    """
    return BarCheck(
        events=abs(default.events_dev_pct) <= abs(exact.events_dev_pct) + BAR_EVENTS_PTS,
        l1=default.l1_per_event <= BAR_L1_FACTOR * exact.l1_per_event,
        # no reference events (nothing moved): nothing to match
        matched=math.isnan(exact.matched_pct)
        or default.matched_pct >= exact.matched_pct - BAR_MATCHED_PTS,
        gap=default.max_gap_ms is None or default.max_gap_ms <= BAR_GAP_MS,
    )


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


def max_gap_ms(events: np.ndarray, windows: list[tuple[int, int]]) -> float | None:
    """Longest interval (ms) without an event inside the ``(t0, t1]`` windows (µs; their
    edges count as events); None without windows.

    >>> from wander_env.events import EVENT_DTYPE
    >>> ev = np.array([(0, 0, 1500, 1), (0, 0, 2000, 0)], EVENT_DTYPE)
    >>> max_gap_ms(ev, [(1000, 5000)]), max_gap_ms(ev, [])
    (3.0, None)
    """
    if not windows:
        return None
    t = np.sort(events["t"].astype(np.int64))
    gap = 0
    for t0, t1 in windows:
        inside = t[(t > t0) & (t <= t1)]
        pts = np.concatenate([[t0], inside, [t1]])
        gap = max(gap, int(np.diff(pts).max()))
    return gap / 1e3


def moving_windows(flags: list[bool], period_us: int) -> list[tuple[int, int]]:
    """``(t0, t1]`` spans (µs) of the runs of steps in which the camera moved.

    >>> moving_windows([False, True, True, False, True], 10_000)
    [(10000, 30000), (40000, 50000)]
    """
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


def mode_kwargs(
    period_s: float, reference_hz: float, reference_supersample: int
) -> dict[str, dict[str, object]]:
    """The env keyword arguments of the reference and of every mode of :data:`MODES`.

    >>> mode_kwargs(0.01, 4000.0, 4)["one_key"]
    {'frames': 'keyframes', 'keyframe_ms': 10.0, 'keyframe_px': None}
    """
    return {
        "reference": {
            "frames": "exact",
            "render_rate_hz": reference_hz,
            "supersample": reference_supersample,
        },
        "exact": {"frames": "exact"},
        "aa16": {"frames": "exact", "supersample": 2},
        "default": {},
        "fine": {"quality": "fine"},
        "one_key": {"frames": "keyframes", "keyframe_ms": period_s * 1e3, "keyframe_px": None},
        "panorama": {"frames": "panorama"},
    }


@dataclass
class Run:
    """One seed of one row: each env's events per step, count-map L1 against the
    reference, RGB renders, and whether the camera moved in each step."""

    events: dict[str, list[np.ndarray]]
    l1: dict[str, float]
    renders: dict[str, int]
    moving: list[bool]
    steps: int
    period_us: int


def run_row(
    scene: str,
    motion: str,
    seed: int,
    seconds: float,
    reference_hz: float = REFERENCE_HZ,
    reference_supersample: int = REFERENCE_SUPERSAMPLE,
) -> Run:
    """The reference and every mode stepped in lockstep on the same actions (the
    reference's ``info`` drives the walk) for ``seconds``."""
    import gymnasium as gym

    import wander_env  # noqa: F401  (registers the environments)
    from wander_env.env_config import WanderConfig

    period = WanderConfig.control_period_s
    kwargs = mode_kwargs(period, reference_hz, reference_supersample)
    envs = {
        m: gym.make("wander/Wander-v0", scene=scene, episode_seconds=seconds + 1.0, **kw)
        for m, kw in kwargs.items()
    }
    try:
        ref = envs["reference"].unwrapped
        infos = {m: env.reset(seed=seed)[1] for m, env in envs.items()}
        policy = GazePolicy("fixational", seed + 1, period, 0.5)
        run = Run(
            {m: [] for m in envs},
            dict.fromkeys(MODES, 0.0),
            dict.fromkeys(envs, 0),
            [],
            round(seconds / period),
            round(period * 1e6),
        )
        for k in range(run.steps):
            if motion == "walk":
                action = policy.act(None, infos["reference"])
            elif motion == "saccade" and k == 0:
                cam = ref.scene.camera
                action = gaze_degrees_to_action(
                    SACCADE_DEG, 0.0, cam.width, cam.height, cam.hfov_deg
                ).astype(np.float32)
            else:
                action = np.zeros(2, np.float32)
            counts = {}
            for m, env in envs.items():
                obs, _, _, _, infos[m] = env.step(action)
                counts[m] = obs["events"].astype(np.int64)
                run.events[m].append(infos[m]["events"])
                run.renders[m] += env.unwrapped.renders_in_step
            run.moving.append(bool(infos["reference"]["moving"]))
            for m in MODES:
                run.l1[m] += float(np.abs(counts[m] - counts["reference"]).sum())
        return run
    finally:
        for env in envs.values():
            env.close()


def _pooled_share(a: list[np.ndarray], b: list[np.ndarray], tol_us: int) -> float:
    """:func:`matched_share` of the events of several seeds, pooled (``nan`` if none)."""
    n = sum(len(x) for x in a)
    if n == 0:
        return float("nan")
    got = sum(
        matched_share(x, y, tol_us, 128, 128) * len(x) for x, y in zip(a, b, strict=True) if len(x)
    )
    return 100.0 * got / n


def _deviation_pct(n: int, n_ref: int) -> float:
    """``n`` events against the reference's ``n_ref`` (%): 0 when neither has any, inf
    when only the mode has some.

    >>> _deviation_pct(75, 100), _deviation_pct(0, 0), _deviation_pct(3, 0)
    (-25.0, 0.0, inf)
    """
    if n_ref == 0:
        return 0.0 if n == 0 else math.inf
    return 100.0 * (n / n_ref - 1.0)


def row_of(scene: str, motion: str, runs: list[Run], tol_us: int = 1000) -> FidelityRow:
    """Pool the seeds' runs of one row into its :class:`FidelityRow`."""
    ev = {m: [np.concatenate(r.events[m]) for r in runs] for m in ("reference", *MODES)}
    n_ref = sum(len(e) for e in ev["reference"])
    steps = sum(r.steps for r in runs)
    modes = {}
    for m in MODES:
        n = sum(len(e) for e in ev[m])
        gaps = [
            max_gap_ms(e, moving_windows(r.moving, r.period_us))
            for e, r in zip(ev[m], runs, strict=True)
        ]
        gaps = [g for g in gaps if g is not None]
        modes[m] = ModeStats(
            events=n,
            events_dev_pct=_deviation_pct(n, n_ref),
            l1_per_event=sum(r.l1[m] for r in runs) / max(n_ref, 1),
            matched_pct=_pooled_share(ev["reference"], ev[m], tol_us),
            max_gap_ms=max(gaps) if motion == "saccade" and gaps else None,
            renders_per_step=sum(r.renders[m] for r in runs) / steps,
        )
    return FidelityRow(
        scene=scene,
        motion=motion,
        seeds=len(runs),
        steps=steps,
        reference_events=n_ref,
        reference_renders=sum(r.renders["reference"] for r in runs) / steps,
        modes=modes,
        default_vs_exact_pct=_pooled_share(ev["exact"], ev["default"], tol_us),
        bar=bar_check(modes["default"], modes["exact"]),
    )


def bench_fidelity(
    scenes: tuple[str, ...] = SCENES,
    motions: tuple[str, ...] = MOTIONS,
    seeds: tuple[int, ...] = (0, 1, 2),
    seconds: float = 0.1,
    reference_hz: float = REFERENCE_HZ,
    reference_supersample: int = REFERENCE_SUPERSAMPLE,
    tol_us: int = 1000,
    progress: Callable[[str], None] | None = None,
) -> list[FidelityRow]:
    """One row per scene and motion (seeds pooled); see the module docstring."""
    rows = []
    for scene in scenes:
        for motion in motions:
            runs = []
            for seed in seeds:
                if progress is not None:
                    progress(f"{scene} {motion} seed {seed}")
                runs.append(
                    run_row(scene, motion, seed, seconds, reference_hz, reference_supersample)
                )
            rows.append(row_of(scene, motion, runs, tol_us))
    return rows


@dataclass(frozen=True)
class ModeCells:
    """A :class:`FidelityRow` as the cells of the modes table: per mode
    ``events dev % / L1 / matched % / gap ms / renders a step``."""

    scene: str
    motion: str
    reference_events: int
    reference_renders: float
    exact: str
    aa16: str
    default: str
    fine: str
    one_key: str
    panorama: str


@dataclass(frozen=True)
class BarCells:
    """A :class:`FidelityRow` as the cells of the bar table: the default's value against
    its limit from exact's, a mark when it fails."""

    scene: str
    motion: str
    events: str
    l1: str
    matched: str
    gap: str
    default_vs_exact_pct: float
    verdict: str
    fine_l1: str


def mode_cells(row: FidelityRow) -> ModeCells:
    """The modes table's cells of one row."""

    def cell(s: ModeStats) -> str:
        return (
            f"{number_text(s.events_dev_pct, '+.1f')} % / {number_text(s.l1_per_event, '.3f')} / "
            f"{number_text(s.matched_pct, '.0f')} % / {number_text(s.max_gap_ms, '.1f')} / "
            f"{s.renders_per_step:.1f}"
        )

    return ModeCells(
        row.scene,
        row.motion,
        row.reference_events,
        row.reference_renders,
        *(cell(row.modes[m]) for m in MODES),
    )


def bar_cells(row: FidelityRow) -> BarCells:
    """The bar table's cells of one row: ``value ≤ limit`` (``✗`` where it fails)."""
    d, e, f, b = row.modes["default"], row.modes["exact"], row.modes["fine"], row.bar

    def mark(ok: bool) -> str:
        return "" if ok else " ✗"

    return BarCells(
        row.scene,
        row.motion,
        f"|{number_text(d.events_dev_pct, '+.1f')}| ≤ {abs(e.events_dev_pct) + BAR_EVENTS_PTS:.1f}"
        + mark(b.events),
        f"{d.l1_per_event:.3f} ≤ {BAR_L1_FACTOR * e.l1_per_event:.3f}" + mark(b.l1),
        f"{number_text(d.matched_pct, '.1f')} ≥ "
        f"{number_text(e.matched_pct - BAR_MATCHED_PTS, '.1f')}" + mark(b.matched),
        f"{number_text(d.max_gap_ms, '.1f')} ≤ {BAR_GAP_MS:g}" + mark(b.gap)
        if d.max_gap_ms is not None
        else "—",
        row.default_vs_exact_pct,
        "pass" if b.ok else "FAIL",
        f"{f.l1_per_event:.3f} ≤ {BAR_FINE_L1_FACTOR * e.l1_per_event:.3f}"
        + mark(f.l1_per_event <= BAR_FINE_L1_FACTOR * e.l1_per_event),
    )
