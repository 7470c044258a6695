"""``wander bench agent``: per-step latency of the agent's stages and the closed loop's
real-time factor, measured on the observations of a real closed-loop run.

The agent runs closed-loop in a scene; every call of each stage is timed in place
(``time.perf_counter`` around the stage's ``step``): the sOMS and the sAC every env step,
the proto-object model once per fixation window (at the decision), the whole
:meth:`AttentionAgent.act` every step (split into ordinary and decision steps), and the
env's step. The streamlined proto-object model (no polarity split) is timed afterwards
on the same OMS maps.

Examples:
    >>> rows, loop = bench_agent(seconds=0.3, scene="shelf")  # doctest: +SKIP
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from agents.attention import AgentParams, AttentionAgent
from agents.proto_object import ProtoObjectSaliency
from experiments.bench.env import timed

# The columns of `wander bench agent`'s tables (row field -> format spec).
LATENCY_COLUMNS: dict[str, str] = {
    "stage": "",
    "calls": "d",
    "median_ms": ".2f",
    "p95_ms": ".2f",
    "max_ms": ".2f",
}
LOOP_COLUMNS: dict[str, str] = {
    "scene": "",
    "simulated_s": ".1f",
    "wall_s": ".1f",
    "env_ms_per_step": ".1f",
    "agent_ms_per_step": ".2f",
    "realtime_factor": ".2f",
}
MODES_COLUMNS: dict[str, str] = {
    "scene": "",
    "keyframe_ms": "g",
    "simulated_s": ".1f",
    "exact_rtf": ".2f",
    "keyframes_rtf": ".2f",
    "speedup": ".2f",
    "exact_env_ms": ".1f",
    "keyframes_env_ms": ".1f",
    "exact_agent_ms": ".2f",
    "keyframes_agent_ms": ".2f",
    "exact_decisions": "d",
    "keyframes_decisions": "d",
}


@dataclass(frozen=True)
class LatencyRow:
    """One stage: number of calls and the median / 95th percentile / max, in ms."""

    stage: str
    calls: int
    median_ms: float
    p95_ms: float
    max_ms: float


@dataclass(frozen=True)
class LoopRow:
    """The closed loop: simulated seconds per wall second of env + agent."""

    scene: str
    simulated_s: float
    wall_s: float
    env_ms_per_step: float
    agent_ms_per_step: float
    realtime_factor: float


def latency_row(stage: str, seconds: list[float]) -> LatencyRow:
    """Summarise call durations (s) as a row in milliseconds."""
    ms = np.asarray(seconds, dtype=np.float64) * 1e3
    if ms.size == 0:
        return LatencyRow(stage, 0, float("nan"), float("nan"), float("nan"))
    return LatencyRow(
        stage, int(ms.size), float(np.median(ms)), float(np.percentile(ms, 95)), float(ms.max())
    )


def bench_agent(
    seconds: float = 5.0,
    scene: str = "office",
    seed: int = 0,
    dvs: str = "ideal",
    **env_kwargs: Any,
) -> tuple[list[LatencyRow], LoopRow]:
    """Run the agent closed-loop for ``seconds`` and time every stage (module doc);
    ``env_kwargs`` (e.g. ``frames``) go to the env. Afterwards the parts the speed work
    replaced are timed old against new on the run's own inputs (:func:`compare_impls`)."""
    env, agent = _agent_in_env(scene, dvs, seconds, seed, **env_kwargs)
    acc: dict[str, list[float]] = {"soms": [], "proto": [], "control": []}
    record: dict[str, list] = {}
    _record_inputs(agent, record)
    agent.soms.step = timed(agent.soms.step, acc, "soms")
    agent.proto.step = timed(agent.proto.step, acc, "proto")
    agent.controller.step = timed(agent.controller.step, acc, "control")
    t_soms, t_proto, t_ctrl = acc["soms"], acc["proto"], acc["control"]
    t_act: list[float] = []
    t_decide: list[float] = []
    t_env: list[float] = []
    oms_maps: list[np.ndarray] = []
    obs, info = env.reset(seed=seed)
    steps = round(seconds / agent.params.step_s)
    wall0 = time.perf_counter()
    for _ in range(steps):
        t0 = time.perf_counter()
        action = agent.act(obs, info)
        t1 = time.perf_counter()
        (t_decide if agent.decided else t_act).append(t1 - t0)
        if agent.decided:
            oms_maps.append(agent.oms_map.copy())
        obs, _, terminated, truncated, info = env.step(action)
        t_env.append(time.perf_counter() - t1)
        if terminated or truncated:
            break
    wall = time.perf_counter() - wall0
    n = len(t_env)
    streamlined = ProtoObjectSaliency(
        replace(agent.params.proto, polarity_split=False),
        agent.params.height_px,
        agent.params.width_px,
    )
    t_stream: list[float] = []
    for m in oms_maps:
        t0 = time.perf_counter()
        streamlined.step(m)
        t_stream.append(time.perf_counter() - t0)
    agent.close()
    env.close()
    rows = [
        latency_row("sOMS (every step)", t_soms),
        latency_row("proto-object, split (per decision)", t_proto),
        latency_row("proto-object, streamlined (same maps)", t_stream),
        latency_row("sAC nengo (every step)", t_ctrl),
        *(
            latency_row(f"{r.part}, {which} (same inputs; max |diff| {r.max_abs_diff:.1e})", t)
            for r in compare_impls(record, seed=seed)
            for which, t in (("replaced", r.old_s), ("today", r.new_s))
        ),
        latency_row("agent act, all steps", t_act + t_decide),
        latency_row("agent act, decision steps", t_decide),
        latency_row("env step", t_env),
    ]
    loop = LoopRow(
        scene=scene,
        simulated_s=n * agent.params.step_s,
        wall_s=wall,
        env_ms_per_step=1e3 * float(np.mean(t_env)),
        agent_ms_per_step=1e3 * float(np.mean(t_act + t_decide)),
        realtime_factor=n * agent.params.step_s / wall,
    )
    return rows, loop


@dataclass(frozen=True)
class ModesRow:
    """The closed loop with both frame modes, run side by side in one process."""

    scene: str
    keyframe_ms: float
    simulated_s: float
    exact_rtf: float
    keyframes_rtf: float
    speedup: float  # exact loop ms per step / keyframes loop ms per step
    exact_env_ms: float
    keyframes_env_ms: float
    exact_agent_ms: float
    keyframes_agent_ms: float
    exact_decisions: int
    keyframes_decisions: int


def loop_modes(
    seconds: float = 5.0,
    scene: str = "office",
    seed: int = 0,
    dvs: str = "ideal",
    keyframe_ms: float | None = None,
) -> ModesRow:
    """Two closed loops (env + agent), ``frames="exact"`` and ``"keyframes"``, stepped
    alternately (one step of each in turn, each timed), so that machine noise hits both."""
    from wander_env.env_config import WanderConfig

    km = WanderConfig.keyframe_ms if keyframe_ms is None else keyframe_ms
    modes = {"exact": {"frames": "exact"}, "keyframes": {"frames": "keyframes", "keyframe_ms": km}}
    loops = {}
    try:
        for mode, kw in modes.items():
            env, agent = _agent_in_env(scene, dvs, seconds, seed, **kw)
            obs, info = env.reset(seed=seed)
            loops[mode] = {
                "env": env,
                "agent": agent,
                "obs": obs,
                "info": info,
                "t_env": 0.0,
                "t_agent": 0.0,
                "steps": 0,
                "decisions": 0,
            }
        step_s = loops["exact"]["agent"].params.step_s
        for _ in range(round(seconds / step_s)):
            for lp in loops.values():
                t0 = time.perf_counter()
                action = lp["agent"].act(lp["obs"], lp["info"])
                t1 = time.perf_counter()
                lp["obs"], _, _, _, lp["info"] = lp["env"].step(action)
                t2 = time.perf_counter()
                lp["t_agent"] += t1 - t0
                lp["t_env"] += t2 - t1
                lp["steps"] += 1
                lp["decisions"] += int(lp["agent"].decided)
    finally:
        for lp in loops.values():
            lp["agent"].close()
            lp["env"].close()
    ex, kf = loops["exact"], loops["keyframes"]

    def rtf(lp: dict) -> float:
        return lp["steps"] * step_s / (lp["t_env"] + lp["t_agent"])

    return ModesRow(
        scene=scene,
        keyframe_ms=km,
        simulated_s=ex["steps"] * step_s,
        exact_rtf=rtf(ex),
        keyframes_rtf=rtf(kf),
        speedup=rtf(kf) / rtf(ex),
        exact_env_ms=1e3 * ex["t_env"] / ex["steps"],
        keyframes_env_ms=1e3 * kf["t_env"] / kf["steps"],
        exact_agent_ms=1e3 * ex["t_agent"] / ex["steps"],
        keyframes_agent_ms=1e3 * kf["t_agent"] / kf["steps"],
        exact_decisions=ex["decisions"],
        keyframes_decisions=kf["decisions"],
    )


def _agent_in_env(
    scene: str, dvs: str, seconds: float, seed: int, **env_kwargs: Any
) -> tuple[Any, AttentionAgent]:
    """The env (no ground truth) and the default agent that the benches time."""
    import gymnasium as gym

    import wander_env  # noqa: F401  (registers the environments)

    env = gym.make(
        "wander/Wander-v0",
        scene=scene,
        dvs=dvs,
        ground_truth=False,
        episode_seconds=seconds,
        **env_kwargs,
    )
    return env, AttentionAgent(AgentParams.for_env(env), seed=seed)


@dataclass(frozen=True)
class ImplTimes:
    """One part of the agent, the implementation it replaced (``old``) and today's,
    called alternately on the same inputs of one run: each call's duration (s) and the
    largest absolute difference of their outputs."""

    part: str
    old_s: list[float]
    new_s: list[float]
    max_abs_diff: float


def _record_inputs(agent: AttentionAgent, record: dict[str, list], keep: int = 200) -> None:
    """Wrap the agent's sOMS and sAC so that their inputs land in ``record`` (the first
    ``keep`` sOMS event maps and ``diff`` maps, every sAC call)."""
    record.setdefault("events", [])
    record.setdefault("diff", [])
    record.setdefault("control", [])
    soms_step, ctrl_step = agent.soms.step, agent.controller.step

    def soms(x: Any) -> Any:
        out = soms_step(x)
        if len(record["diff"]) < keep:
            record["events"].append(np.array(x, dtype=np.float32))
            record["diff"].append(out.diff.clone())
        return out

    def ctrl(target: Any, duration_s: float = 0.01) -> Any:
        record["control"].append((None if target is None else tuple(target), duration_s))
        return ctrl_step(target, duration_s)

    agent.soms.step, agent.controller.step = soms, ctrl


def _alternate(
    part: str, inputs: list[Any], old: Callable[[Any], Any], new: Callable[[Any], Any]
) -> ImplTimes:
    """``old`` and ``new`` called alternately on each of ``inputs`` (tensors in, tensors
    out, no gradients): each call timed, and the largest difference of their outputs."""
    import torch

    t_old, t_new, worst = [], [], 0.0
    with torch.no_grad():
        for x in inputs:
            t0 = time.perf_counter()
            a = old(x)
            t1 = time.perf_counter()
            b = new(x)
            t2 = time.perf_counter()
            t_old.append(t1 - t0)
            t_new.append(t2 - t1)
            worst = max(worst, float((a - b).abs().max()))
    return ImplTimes(part, t_old, t_new, worst)


def compare_impls(record: dict[str, list], seed: int = 0) -> list[ImplTimes]:
    """Old against new implementation of the parts this speed work replaced, on the
    inputs recorded from a run (``record["events"]``, ``record["diff"]``: sOMS event
    and ``diff`` maps ``(2, H, W)``; ``record["control"]``: sAC calls ``(target,
    duration_s)``): the sOMS centre and surround filters (an FFT pair against two 1-D
    passes of each Gaussian's factor), the sOMS quantile norm's pooling + 90th
    percentile (FFT pair + ``np.quantile`` against the separable Gaussian + one
    ``np.partition``) and the sAC's 10 nengo steps per env step (``Simulator.run_steps``
    against :class:`agents.control.FusedSteps`)."""
    import torch

    from agents.control import AttentionController
    from agents.kernels import FFTConv2d
    from agents.soms import SOMS, peak_scale

    p = AgentParams().resolved()
    rows = []
    events = record.get("events", [])
    if events:
        h, w = events[0].shape[-2:]
        soms = SOMS(p.soms, h, w)
        old_filter = FFTConv2d(soms.weight, h, w)
        xs = [torch.from_numpy(ev) for ev in events]
        rows.append(
            _alternate(
                "sOMS centre + surround filters",
                xs,
                lambda x: old_filter(x.unsqueeze(1)),
                soms.filter,
            )
        )
    diffs = record.get("diff", [])
    if diffs and p.soms.norm == "quantile":
        h, w = diffs[0].shape[-2:]
        soms = SOMS(p.soms, h, w)
        old_pool = FFTConv2d(soms.pool_weight, h, w)
        sp = p.soms

        def old_score(d: torch.Tensor) -> torch.Tensor:
            pooled = old_pool(-d.unsqueeze(1))[:, 0]
            a = pooled.numpy().ravel()
            q = float(np.quantile(a, sp.quantile))
            scale = peak_scale(q, float(a.max()), sp.gain, sp.peak_ratio, sp.floor_spikes)
            return torch.clamp(pooled / scale, 0.0, 1.0)

        rows.append(_alternate("sOMS score: pooling + quantile", diffs, old_score, soms.score))
    calls = record.get("control", [])
    if calls:
        ctrl = {
            k: AttentionController(replace(p.control, seed=seed, stepper=k))
            for k in ("nengo", "fused")
        }
        t = {"nengo": [], "fused": []}
        worst = 0.0
        try:
            for target, duration in calls:
                u = {}
                for k, c in ctrl.items():
                    t0 = time.perf_counter()
                    u[k] = c.step(target, duration)
                    t[k].append(time.perf_counter() - t0)
                worst = max(worst, float(np.abs(u["nengo"] - u["fused"]).max()))
        finally:
            for c in ctrl.values():
                c.close()
        rows.append(ImplTimes("sAC: nengo steps", t["nengo"], t["fused"], worst))
    return rows
