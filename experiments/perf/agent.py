"""``wander perf agent``: per-step latency of the agent's stages and the closed loop's
real-time factor, measured on the observations of a real closed-loop run.

The agent runs closed-loop in a scene; every call of each stage is timed in place
(``time.perf_counter`` around the stage's ``step``): the sOMS and the sAC every env step,
the proto-object model once per fixation window (at the decision), the whole
:meth:`AttentionAgent.act` every step (split into ordinary and decision steps), and the
env's step. The streamlined proto-object model (no polarity split) is timed afterwards
on the same OMS maps. Every table has the process's CPU time beside the wall time and
the load average around its measurement (:mod:`experiments.perf.clock`).

What runs is an :class:`AgentBenchConfig` (the env's block, the agent's block and the
seed), which ``wander perf agent`` builds through the command line's one layered path
(:func:`experiments.cli.options.command_config`: ``--set agent.soms.alpha=0.5`` too).

Examples:
    >>> from wander_env.config import validate
    >>> config = validate(AgentBenchConfig, {"env.scene": "shelf", "env.episode_seconds": 0.3})
    >>> config.env.episode_seconds, config.env.ground_truth, config.agent == AgentParams()
    (0.3, True, True)
    >>> rows, loop = bench_agent(config)  # doctest: +SKIP
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Annotated, Any

import numpy as np
import pydantic

from agents.attention import AgentParams, AttentionAgent
from agents.proto_object import ProtoObjectSaliency
from experiments.analysis.stats import real_time_factor
from experiments.jobs.run_agent import OneEpisodeRun
from experiments.perf.clock import LOAD_COLUMN, Clock, Measured, Timings, timed
from experiments.perf.dvs import CALIBRATION_COLUMN, calibration_fps
from experiments.studies.framework import MAX_SEED
from wander_env.env_config import WanderConfig

# The columns of `wander perf agent`'s tables (row field -> format spec).
LATENCY_COLUMNS: dict[str, str] = {
    "stage": "",
    "calls": "d",
    "median_ms": ".2f",
    "p95_ms": ".2f",
    "max_ms": ".2f",
    "cpu_median_ms": ".2f",
    **LOAD_COLUMN,
}
LOOP_COLUMNS: dict[str, str] = {
    "scene": "",
    "simulated_s": ".1f",
    "wall_s": ".1f",
    "cpu_s": ".1f",
    "env_ms_per_step": ".1f",
    "agent_ms_per_step": ".2f",
    "realtime_factor": ".2f",
    "keys_ahead_adopted": "",
    **CALIBRATION_COLUMN,
    **LOAD_COLUMN,
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
    "exact_cpu_ms": ".1f",
    "keyframes_cpu_ms": ".1f",
    "exact_decisions": "d",
    "keyframes_decisions": "d",
    **LOAD_COLUMN,
}


@dataclass(frozen=True)
class LatencyRow(Measured):
    """One stage: number of calls and the median / 95th percentile / max wall time, the
    median CPU time of this process, in ms; the load average around the run."""

    stage: str
    calls: int
    median_ms: float
    p95_ms: float
    max_ms: float
    cpu_median_ms: float = float("nan")


@dataclass(frozen=True)
class LoopRow(Measured):
    """The closed loop: simulated seconds per wall second of env + agent."""

    scene: str
    simulated_s: float
    wall_s: float
    env_ms_per_step: float
    agent_ms_per_step: float
    realtime_factor: float
    cpu_s: float = float("nan")  # this process's CPU time over the loop
    keys_ahead_adopted: str = "–"  # keys drawn ahead adopted, of those drawn ahead
    dvs_fps: float = float("nan")  # the machine's speed just before (calibration_fps)


def latency_row(
    stage: str, seconds: list[float], cpu_seconds: list[float] | None = None, load: str = "–"
) -> LatencyRow:
    """Summarise call durations (s: wall, and the process's CPU when given) as a row in
    milliseconds."""
    ms = np.asarray(seconds, dtype=np.float64) * 1e3
    if ms.size == 0:
        return LatencyRow(stage, 0, float("nan"), float("nan"), float("nan"), load=load)
    cpu = float("nan") if not cpu_seconds else 1e3 * float(np.median(cpu_seconds))
    return LatencyRow(
        stage,
        int(ms.size),
        float(np.median(ms)),
        float(np.percentile(ms, 95)),
        float(ms.max()),
        cpu,
        load=load,
    )


def _bench_env() -> WanderConfig:
    return WanderConfig(episode_seconds=5.0)


@dataclass(frozen=True)
class AgentBenchConfig(OneEpisodeRun):
    """What ``wander perf agent`` times: the env's block (ground truth on, as a run has
    it; its ``episode_seconds`` the closed loop's length, 5 s), the seed of the env and
    the agent, and the agent's block (:class:`agents.attention.AgentParams`)."""

    env: WanderConfig = field(default_factory=_bench_env)
    seed: Annotated[int, pydantic.Field(ge=0, le=MAX_SEED)] = 0
    agent: AgentParams = field(default_factory=AgentParams)


def bench_agent(config: AgentBenchConfig) -> tuple[list[LatencyRow], LoopRow]:
    """Run the agent of ``config`` closed-loop for its ``seconds`` and time every stage
    (module doc). Afterwards the parts the speed work replaced are timed old against new
    on the run's own inputs (:func:`compare_impls`)."""
    seconds, seed, scene = config.seconds, config.seed, _scene_name(config.env)
    dvs_fps = calibration_fps()
    env, agent = _agent_in_env(config, config.env)
    acc = Timings()
    record: dict[str, list] = {}
    _record_inputs(agent, record)
    agent.soms.step = timed(agent.soms.step, acc, "soms")
    agent.proto.step = timed(agent.proto.step, acc, "proto")
    agent.controller.step = timed(agent.controller.step, acc, "control")
    act, env_step = timed(agent.act, acc, "act"), timed(env.step, acc, "env")
    oms_maps: list[np.ndarray] = []
    decided: list[bool] = []
    obs, info = env.reset(seed=seed)
    steps = round(seconds / agent.params.step_s)
    clock = Clock()
    with clock.span():
        for _ in range(steps):
            action = act(obs, info)
            decided.append(agent.decided)
            if agent.decided:
                oms_maps.append(agent.oms_map.copy())
            obs, _, terminated, truncated, info = env_step(action)
            if terminated or truncated:
                break
    n = len(decided)
    streamlined = ProtoObjectSaliency(
        replace(agent.params.proto, polarity_split=False),
        agent.params.height_px,
        agent.params.width_px,
    )
    stream = timed(streamlined.step, acc, "stream")
    for m in oms_maps:
        stream(m)
    source = env.unwrapped.source
    drawn_ahead = source.keys_ahead_adopted + source.keys_ahead_dropped
    ahead = f"{source.keys_ahead_adopted} of {drawn_ahead}" if drawn_ahead else "–"
    agent.close()
    env.close()
    load = clock.load

    def row(stage: str, key: str, only: list[bool] | None = None) -> LatencyRow:
        wall, cpu = acc.wall.get(key, []), acc.cpu.get(key, [])
        if only is not None:
            wall = [w for w, keep in zip(wall, only, strict=True) if keep]
            cpu = [c for c, keep in zip(cpu, only, strict=True) if keep]
        return latency_row(stage, wall, cpu, load)

    rows = [
        row("sOMS (every step)", "soms"),
        row("proto-object, split (per decision)", "proto"),
        row("proto-object, streamlined (same maps)", "stream"),
        row("sAC nengo (every step)", "control"),
        *(
            latency_row(
                f"{r.part}, {which} (same inputs; max |diff| {r.max_abs_diff:.1e})", t, c, load
            )
            for r in compare_impls(record, seed=seed)
            for which, t, c in (("replaced", r.old_s, r.old_cpu_s), ("today", r.new_s, r.new_cpu_s))
        ),
        row("agent act, all steps", "act"),
        row("agent act, decision steps", "act", decided),
        row("env step", "env"),
    ]
    loop = LoopRow(
        scene=scene,
        simulated_s=n * agent.params.step_s,
        wall_s=clock.wall_s,
        env_ms_per_step=1e3 * float(np.mean(acc.wall["env"])),
        agent_ms_per_step=1e3 * float(np.mean(acc.wall["act"])),
        realtime_factor=real_time_factor(n * agent.params.step_s, clock.wall_s),
        cpu_s=clock.cpu_s,
        keys_ahead_adopted=ahead,
        dvs_fps=dvs_fps,
        load=load,
    )
    return rows, loop


@dataclass(frozen=True)
class ModesRow(Measured):
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
    exact_cpu_ms: float = float("nan")  # env + agent, this process's CPU time a step
    keyframes_cpu_ms: float = float("nan")


def loop_modes(config: AgentBenchConfig) -> ModesRow:
    """Two closed loops (env + agent) of ``config``, its env with ``frames="exact"`` and
    ``"keyframes"``, stepped alternately (one step of each in turn, each timed), so that
    machine noise hits both."""
    seconds, seed, scene = config.seconds, config.seed, _scene_name(config.env)
    km = config.env.keyframe_ms
    modes = {"exact": "exact", "keyframes": "keyframes"}
    loops = {}
    try:
        for mode, frames in modes.items():
            env, agent = _agent_in_env(config, replace(config.env, frames=frames))
            obs, info = env.reset(seed=seed)
            loops[mode] = {
                "env": env,
                "agent": agent,
                "obs": obs,
                "info": info,
                "t_env": 0.0,
                "t_agent": 0.0,
                "clock": Clock(),
                "steps": 0,
                "decisions": 0,
            }
        step_s = loops["exact"]["agent"].params.step_s
        for _ in range(round(seconds / step_s)):
            for lp in loops.values():
                with lp["clock"].span():
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
        return real_time_factor(lp["steps"] * step_s, lp["t_env"] + lp["t_agent"])

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
        exact_cpu_ms=ex["clock"].ms_per(ex["steps"])[1],
        keyframes_cpu_ms=kf["clock"].ms_per(kf["steps"])[1],
        load=f"{ex['clock'].load_start:.2f}-{kf['clock'].load_end:.2f}",
    )


def _scene_name(env: WanderConfig) -> str:
    """The scene's name for the tables (a scene config's file name)."""
    return env.scene if isinstance(env.scene, str) else env.scene.name


def _agent_in_env(config: AgentBenchConfig, env_config: WanderConfig) -> tuple[Any, AttentionAgent]:
    """The env of ``env_config`` and the agent of ``config`` that the benches time."""
    import gymnasium as gym

    import wander_env  # noqa: F401  (registers the environments)

    env = gym.make("wander/Wander-v0", **env_config)
    return env, AttentionAgent(config.agent_params(env), seed=config.seed)


@dataclass(frozen=True)
class ImplTimes:
    """One part of the agent, the implementation it replaced (``old``) and today's,
    called alternately on the same inputs of one run: each call's duration (s) and the
    largest absolute difference of their outputs."""

    part: str
    old_s: list[float]
    new_s: list[float]
    max_abs_diff: float
    old_cpu_s: list[float] = field(default_factory=list)  # the process's CPU time a call
    new_cpu_s: list[float] = field(default_factory=list)


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

    acc, worst = Timings(), 0.0
    old, new = timed(old, acc, "old"), timed(new, acc, "new")
    with torch.no_grad():
        for x in inputs:
            a, b = old(x), new(x)
            worst = max(worst, float((a - b).abs().max()))
    get = acc.wall.get
    return ImplTimes(
        part, get("old", []), get("new", []), worst, acc.cpu.get("old", []), acc.cpu.get("new", [])
    )


def compare_impls(record: dict[str, list], seed: int = 0) -> list[ImplTimes]:
    """Old against new implementation of the parts this speed work replaced, on the
    inputs recorded from a run (``record["events"]``, ``record["diff"]``: sOMS event
    and ``diff`` maps ``(2, H, W)``; ``record["control"]``: sAC calls ``(target,
    duration_s)``): the sOMS centre and surround filters (an FFT pair against two 1-D
    passes of each Gaussian's factor), the sOMS quantile norm's pooling + 90th
    percentile (FFT pair + ``np.quantile`` against the separable Gaussian + one
    ``np.partition``) and the sAC's 10 nengo steps per env step (``Simulator.run_steps``
    against :class:`agents.control_fused.FusedSteps`)."""
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
        acc, worst = Timings(), 0.0
        steps = {k: timed(c.step, acc, k) for k, c in ctrl.items()}
        try:
            for target, duration in calls:
                u = {k: step(target, duration) for k, step in steps.items()}
                worst = max(worst, float(np.abs(u["nengo"] - u["fused"]).max()))
        finally:
            for c in ctrl.values():
                c.close()
        w, c = acc.wall, acc.cpu
        rows.append(
            ImplTimes("sAC: nengo steps", w["nengo"], w["fused"], worst, c["nengo"], c["fused"])
        )
    return rows
