"""The bio-inspired attention agent: sOMS → proto-object saliency → sAC → saccade, then
fixational eye movements (the paper's closed loop, §"Real-world demonstrator").

The agent is a two-phase state machine, stepped once per env step (``step_s``)::

    FIXATE (window_s = St_w) ──P found──► SACCADE (sAC drives the PTU) ──settled──► FIXATE
       ▲  │ no salient point: keep fixating (walk goes on)
       └──┘

* **FIXATE.** Every step the step's event counts go through the sOMS (its LIF state
  carried from step to step, τ converted with the real step length); the event map and
  the OMS map of the window are the sums over the window's steps. Fixational eye
  movements (a new random walk of N = 8 relative PTU steps per fixation,
  :mod:`agents.fixation`) are sent on their schedule, so a static scene still produces
  events. When the window ``window_s`` (the paper's ``t_w = St_w = 124 ms``) has passed,
  the proto-object model runs on the window's OMS map (its LIF time step is the window)
  and ``P(x, y)`` = argmax of the saliency decides the saccade.
* **SACCADE.** ``P`` is held as the sAC's target (nengo, stepped in lockstep with the
  env: ``step_s`` of controller time per env step, also while fixating). The decoded
  ``u`` (action units, ``u ≈ (P − c)/(W/2, H/2)`` once settled) is the *total* gaze shift
  wanted, turned into the exact pan-tilt rotation that centres that pixel offset
  (:func:`wander_env.camera.pixel_to_rotation`, at the tilt the saccade starts from);
  because the env integrates relative actions, the agent sends each step the change of
  that rotation, so the PTU target ends on ``P``'s ray whatever the controller's
  transient. The phase
  ends when ``saccade_settle_s`` has passed and the PTU reports it is no longer moving
  (``info["moving"]``); the sOMS and proto-object states are then reset (the saccade's
  event burst is not integrated, like saccadic suppression) and a new fixation starts.

The saccade condition of the paper's scanpath study (``t_w = 10 ms``, no fixational
movements) is ``AgentParams(window_s=0.01, fixational=False)``.

What it exposes for plots and metrics: ``event_map``, ``oms_map`` (window sums),
``saliency`` (the last decision's map), ``target`` (the last ``P``), ``phase``,
``decided`` (whether the last :meth:`AttentionAgent.act` made a decision), the
``scanpath`` (:class:`Fixation` and :class:`Saccade` records) and event counters for the
suppression figure.

Examples:
    >>> import numpy as np
    >>> agent = AttentionAgent(AgentParams(window_s=0.02), seed=0)
    >>> obs = {"events": np.zeros((2, 128, 128), np.float32), "gaze": np.zeros(2)}
    >>> a = agent.act(obs, {"moving": False})
    >>> a.shape, agent.phase.value
    ((2,), 'fixate')
"""

from __future__ import annotations

import enum
import math
from collections.abc import Mapping
from dataclasses import dataclass, field, fields, replace
from typing import Annotated, Any

import numpy as np
import pydantic

from agents.control import AttentionController, ControlParams, steps_for
from agents.fixation import (
    FIXATION_WINDOW_S,
    FixationalMovements,
    FixationParams,
    check_resolution_arcsec,
)
from agents.pipeline import PipelineBase, SaliencyPipeline
from agents.proto_object import ProtoObjectParams
from agents.soms import SOMSParams
from agents.speck_front import SpeckFrontParams, SpeckPipeline
from agents.suppression import kept_events, suppressed_fraction
from agents.torch_fork import set_torch_threads
from wander_env.actions import gaze_degrees_to_action
from wander_env.camera import SPECK_HFOV_DEG, check_hfov_deg, pixel_to_rotation, principal_point
from wander_env.config import check_fields, to_plain
from wander_env.ptu.units import FLIR_RESOLUTION_ARCSEC

__all__ = [
    "AGENT_SOMS",
    "AGENT_SOMS_ALPHA",
    "ENV_FIELDS",
    "AgentParams",
    "AttentionAgent",
    "Fixation",
    "Phase",
    "Saccade",
    "same_but_step",
    "soms_block",
]

_EPS = 1e-9

#: The agent's sOMS threshold α: the paper's table value, applied to the input-dependent
#: ``"quantile"`` norm of :data:`AGENT_SOMS` (see AgentParams).
AGENT_SOMS_ALPHA = 0.80

#: The agent's sOMS: the paper's kernels, τ and α with the ``"quantile"`` norm (divisor:
#: the map's peak clipped to [2, 3.5] × its 90th percentile) whose parameters were chosen
#: on the whole even-seed half of the stimulus family
#: (``wander experiment oms_scorecard``; README "The sOMS threshold").
AGENT_SOMS = SOMSParams(
    conv="separable",
    alpha=AGENT_SOMS_ALPHA,
    norm="quantile",
    pool_sigma=6.0,
    quantile=0.9,
    gain=3.5,
    peak_ratio=2.0,
)


def soms_block(name: str) -> SOMSParams | SpeckFrontParams:
    """The agent's front end by name: ``"agent"`` :data:`AGENT_SOMS` (the default),
    ``"paper"`` the paper-literal sOMS (``SOMSParams(conv="separable")``), ``"speck"``
    the front end on Speck's cores (``SpeckFrontParams()``).

    >>> type(soms_block("speck")).__name__, soms_block("paper").norm
    ('SpeckFrontParams', 'minmax')
    """
    blocks: dict[str, SOMSParams | SpeckFrontParams] = {
        "agent": AGENT_SOMS,
        "paper": SOMSParams(conv="separable"),
        "speck": SpeckFrontParams(),
    }
    if name not in blocks:
        raise ValueError(f"soms must be one of {sorted(blocks)} or a parameter block, got {name!r}")
    return blocks[name]


def same_but_step(a: SOMSParams | SpeckFrontParams, b: SOMSParams | SpeckFrontParams) -> bool:
    """Whether front ends ``a`` and ``b`` are the same block but for their step ``dt``.

    >>> same_but_step(replace(AGENT_SOMS, dt=0.02), AGENT_SOMS)
    True
    >>> same_but_step(SOMSParams(), AGENT_SOMS)
    False
    """
    return replace(a, dt=b.dt) == b


def _front_end_data(value: Any) -> Any:
    """A front end named by a string (:func:`soms_block`) as its block's plain data, for
    pydantic (a config file's or ``--set``'s ``agent.soms: speck``); anything else as it
    is."""
    return to_plain(soms_block(value)) if isinstance(value, str) else value


def _front_end_tag(value: Any) -> str:
    """Which block of :class:`AgentParams`'s ``soms`` a value is (pydantic validates it as
    that block alone, so a bad value is one message): a mapping with a key only
    :class:`agents.speck_front.SpeckFrontParams` has is one, anything else a
    :class:`agents.soms.SOMSParams`."""
    if isinstance(value, SpeckFrontParams):
        return "SpeckFrontParams"
    if isinstance(value, Mapping):
        speck_only = {f.name for f in fields(SpeckFrontParams)} - {
            f.name for f in fields(SOMSParams)
        }
        if speck_only & set(value):
            return "SpeckFrontParams"
    return "SOMSParams"


#: The type of :class:`AgentParams`'s ``soms``: either block, or a name (as data).
FrontEnd = Annotated[
    Annotated[SOMSParams, pydantic.Tag("SOMSParams")]
    | Annotated[SpeckFrontParams, pydantic.Tag("SpeckFrontParams")],
    pydantic.Discriminator(_front_end_tag),
    pydantic.BeforeValidator(_front_end_data),
]


#: The agent's fields an env sets (:meth:`AgentParams.for_env`): its sensor, control
#: period, lens and PTU resolution.
ENV_FIELDS = ("width_px", "height_px", "step_s", "hfov_deg", "ptu_resolution_arcsec")


@dataclass(frozen=True)
class AgentParams:
    """Parameters of the composed agent; the paper's values as defaults.

    - ``window_s`` St_w = t_w = 0.124 s: the fixation window over which the event and
      OMS maps are integrated before a decision (the demonstrator's latency);
    - ``step_s`` 0.01 s: the env's control period (sOMS time step, controller lockstep);
    - ``fixational`` True: fixational eye movements during each fixation;
    - ``saccade_settle_s`` 0.1 s: time the sAC is given to converge on ``P`` (its decoded
      value is within 0.1 of the target from 50 ms on, within ≈0.01 from 100 ms);
    - ``max_saccade_s`` 3 s: a saccade that has not settled by then ends anyway
      (a PTU that keeps reporting motion must not freeze the agent);
    - ``min_saliency`` 0: a decision needs a saliency peak above this (else the fixation
      goes on, its walk continuing around the same point);
    - ``reset_after_saccade`` True: clear the sOMS and proto-object state when a new
      fixation starts;
    - ``torch_threads`` 1: torch intra-op threads set by the agent (``None`` leaves
      torch's setting). At 128×128 one thread is fastest, and with two threads on a
      busy 2-core machine the sOMS and proto-object steps were measured 20–40× slower;
    - ``soms`` :data:`AGENT_SOMS`: the paper's kernels, τ and α = 0.80 with the
      ``"quantile"`` norm instead of the min-max one. The paper calls α "a threshold
      that depends on the visual input"; with min-max normalisation the threshold is
      relative to the map's own range, so a scene where nothing moves relative to the
      background still lets a fixed share through, and no single α shows all the
      paper's sOMS findings. The quantile norm pools ``surround − centre`` (Gaussian,
      σ 6 px) and divides it by the map's peak clipped to [2, 3.5] × its 90th
      percentile: global ego-motion (no peak 2× above the bulk) is suppressed whatever
      its texture, and an object whose events are denser than the background's stands
      out. Its parameters (``quantile`` 0.9, ``gain`` 3.5, ``peak_ratio`` 2) passed the
      three family claims with the largest margin on the whole even-seed half of the
      stimulus family (``experiments.paper.oms_family.tune``); ``wander experiment
      oms_scorecard`` prints its scorecard beside the paper-literal one (docs/experiments.md,
      "The sOMS threshold"). ``SOMSParams()`` alone is the paper-literal sOMS.
      A :class:`agents.speck_front.SpeckFrontParams` block instead runs the front end
      shaped for Speck's cores (the quantised DoG → border-ownership → grouping network,
      :class:`agents.speck_front.SpeckPipeline`; ``proto`` is then unused): the names
      ``"agent"``, ``"paper"`` and ``"speck"`` give the three blocks
      (:func:`soms_block`);
    - the env's geometry (128×128 Speck, HFOV 112.83° in (0, 180),
      :func:`wander_env.camera.check_hfov_deg`; the PTU's ``ptu_resolution_arcsec``
      (pan, tilt), the FLIR's 92.5714″ on both axes), which :meth:`for_env` reads from
      the env, and one parameter block per component. The components' ``dt``, sizes,
      field of view, PTU resolution and fixation interval are set from these fields by
      :meth:`resolved` (so they cannot disagree); ``step_s`` must be a whole number of
      the controller's steps (``control.dt``).
    """

    window_s: float = FIXATION_WINDOW_S
    step_s: float = 0.01
    fixational: bool = True
    saccade_settle_s: float = 0.1
    max_saccade_s: float = 3.0
    min_saliency: float = 0.0
    reset_after_saccade: bool = True
    torch_threads: int | None = 1
    width_px: int = 128
    height_px: int = 128
    hfov_deg: float = SPECK_HFOV_DEG
    ptu_resolution_arcsec: tuple[float, float] = (FLIR_RESOLUTION_ARCSEC, FLIR_RESOLUTION_ARCSEC)
    soms: FrontEnd = field(default_factory=lambda: AGENT_SOMS)
    proto: ProtoObjectParams = field(default_factory=ProtoObjectParams)
    control: ControlParams = field(default_factory=ControlParams)
    fixation: FixationParams = field(default_factory=FixationParams)

    def __post_init__(self) -> None:
        if isinstance(self.soms, str):  # a name: its block
            object.__setattr__(self, "soms", soms_block(self.soms))
        names = ("window_s", "step_s", "saccade_settle_s", "max_saccade_s")
        check_fields(self, names, positive=True)
        if self.window_s + _EPS < self.step_s:
            raise ValueError(
                f"AgentParams.window_s={self.window_s} is shorter than step_s={self.step_s}"
            )
        steps_for(self.step_s, self.control.dt, "AgentParams.step_s")  # the sAC's lockstep
        check_fields(self, ("width_px", "height_px"), integer=True, minimum=1)
        check_hfov_deg(self.hfov_deg, "AgentParams.hfov_deg")
        check_resolution_arcsec(self.ptu_resolution_arcsec, "AgentParams.ptu_resolution_arcsec")

    @property
    def window_steps(self) -> int:
        """Env steps per fixation window, ``ceil(window_s / step_s)`` (13 for 124/10 ms)."""
        return max(1, math.ceil(self.window_s / self.step_s - _EPS))

    def resolved(self) -> AgentParams:
        """These parameters with every component's time step and geometry made consistent."""
        n = max(self.fixation.n_steps, 1)
        soms = replace(self.soms, dt=self.step_s)
        if isinstance(soms, SpeckFrontParams):
            soms = replace(soms, width_px=self.width_px, height_px=self.height_px)
        return replace(
            self,
            soms=soms,
            proto=replace(self.proto, dt=self.window_steps * self.step_s),
            control=replace(self.control, width_px=self.width_px, height_px=self.height_px),
            fixation=replace(
                self.fixation,
                width_px=self.width_px,
                height_px=self.height_px,
                hfov_deg=self.hfov_deg,
                resolution_arcsec=self.ptu_resolution_arcsec,
                interval_s=self.window_s / n,
            ),
        )

    def on_env(self, env: Any, **overrides: Any) -> AgentParams:
        """These parameters with ``env``'s sensor, lens, PTU resolution and step
        (:meth:`for_env`: a config's ``agent`` block on the env it runs in), then
        ``overrides`` (a study's condition)."""
        own = {f.name: getattr(self, f.name) for f in fields(self) if f.init}
        kept = {k: v for k, v in own.items() if k not in ENV_FIELDS}
        return type(self).for_env(env, **{**kept, **overrides})

    def check_env_fields(self) -> None:
        """Refuse a change to a field the env sets (:data:`ENV_FIELDS`): a config whose
        agent runs on an env (:meth:`on_env`) would drop it. ValueError ``agent.FIELD: ...``.

        >>> AgentParams(width_px=64).check_env_fields()
        Traceback (most recent call last):
        ...
        ValueError: agent.width_px: 64 is the env's to set (its camera, PTU and control \
period), not the agent block's; leave it at its default, 128
        """
        default = AgentParams()
        for name in ENV_FIELDS:
            value, default_value = getattr(self, name), getattr(default, name)
            if value != default_value:
                raise ValueError(
                    f"agent.{name}: {value!r} is the env's to set (its camera, PTU and control "
                    f"period), not the agent block's; leave it at its default, {default_value!r}"
                )

    @classmethod
    def for_env(cls, env: Any, **overrides: Any) -> AgentParams:
        """Parameters matched to an env (``WanderEnv`` and ``RigEnv`` alike): sensor size
        from its observation space, step length from its ``config.control_period_s``, the
        lens's ``hfov_deg`` and the PTU's ``ptu_resolution_arcsec`` (pan, tilt) from the
        env's attributes of those names."""
        h, w = env.observation_space["events"].shape[1:]
        base = env.unwrapped
        cfg = getattr(base, "config", None)
        step = getattr(cfg, "control_period_s", cls.step_s)
        matched = {
            "width_px": int(w),
            "height_px": int(h),
            "step_s": step,
            "hfov_deg": base.hfov_deg,
            "ptu_resolution_arcsec": base.ptu_resolution_arcsec,
        }
        return cls(**{**matched, **overrides})

    def check_reads(self, *blocks: str, speck: bool = True) -> None:
        """Refuse a setting that a study of the agent's components would ignore: a config
        that runs only the ``blocks`` named (``"soms"``, ``"proto"``) at a step of its own
        (the benchmark, the sOMS and detection experiments) holds the agent's whole block;
        every other field must keep its default. With ``speck`` false, ``soms`` must be an
        sOMS (:class:`agents.soms.SOMSParams`), not the front end on Speck's cores.
        ValueError ``agent.FIELD: ...``.

        >>> AgentParams(window_s=0.05).check_reads("soms", "proto")
        Traceback (most recent call last):
        ...
        ValueError: agent.window_s: 0.05 plays no part here (only agent.soms, agent.proto \
do); leave it at its default, 0.124
        """
        if not speck and not isinstance(self.soms, SOMSParams):
            raise ValueError(
                "agent.soms: the sOMS pipeline runs here; the front end on Speck's cores "
                f"({type(self.soms).__name__}) is not one"
            )
        default = AgentParams()
        for f in fields(self):
            value, default_value = getattr(self, f.name), getattr(default, f.name)
            if f.name not in blocks and value != default_value:
                used = ", ".join(f"agent.{b}" for b in blocks)
                raise ValueError(
                    f"agent.{f.name}: {value!r} plays no part here (only {used} do); leave "
                    f"it at its default, {default_value!r}"
                )


class Phase(enum.Enum):
    """The agent's state."""

    FIXATE = "fixate"
    SACCADE = "saccade"


@dataclass(frozen=True)
class Fixation:
    """One fixation window: when, where the PTU pointed, and what it decided.

    ``gaze_deg`` is the (pan, tilt) at the window's start, ``target_px`` the ``P`` found
    at its end (None when nothing was salient), ``peak`` the saliency there; times are
    the env's (``info["t"]``, s) when given, else the agent's own clock.
    """

    index: int
    t_start: float
    t_end: float
    gaze_deg: tuple[float, float]
    target_px: tuple[int, int] | None
    peak: float
    events: int
    oms_events: int


@dataclass(frozen=True)
class Saccade:
    """One saccade: ``target_px`` P in the image at the decision; ``ideal_deg`` the
    rotation (pan, tilt; PTU signs) that brings P to the fovea (pinhole model);
    ``command_deg`` the rotation the sAC actually commanded, from the PTU target
    ``from_target_deg``; the gaze reached ``to_gaze_deg`` when it settled (at ``t_end``)."""

    index: int
    t_start: float
    t_end: float
    target_px: tuple[int, int]
    from_target_deg: tuple[float, float]
    ideal_deg: tuple[float, float]
    command_deg: tuple[float, float]
    to_gaze_deg: tuple[float, float]

    @property
    def error_deg(self) -> tuple[float, float]:
        """Reached minus ideal gaze (pan, tilt), degrees: the sAC's decoding error plus
        the PTU's (quantisation, backlash, limits)."""
        return (
            self.to_gaze_deg[0] - (self.from_target_deg[0] + self.ideal_deg[0]),
            self.to_gaze_deg[1] - (self.from_target_deg[1] + self.ideal_deg[1]),
        )


class AttentionAgent:
    """The policy: ``act(observation, info) -> action`` (see the module docstring).

    ``observation`` is the env's ``{"events": (2, H, W), "gaze": (pan, tilt)}``; from
    ``info`` the agent reads ``moving`` (whether the PTU is still moving), and ``t`` and
    ``ptu_target_deg`` (where the PTU is heading) when present. The same code drives the
    simulated env and the rig. ``pipeline`` replaces the one the parameters choose (the
    front end running on a real Speck: :class:`hardware.speck_network.ChipPipeline`).
    """

    def __init__(
        self,
        params: AgentParams | None = None,
        seed: int | None = None,
        pipeline: PipelineBase | None = None,
    ) -> None:
        self.params = (params if params is not None else AgentParams()).resolved()
        p = self.params
        if p.torch_threads is not None:
            set_torch_threads(p.torch_threads)  # one only in a forked child
        self.seed = seed
        # One pipeline (agents.pipeline): the sOMS every step, the saliency once a window;
        # ``pipeline`` replaces it (the front end on a real Speck,
        # hardware.speck_network.ChipPipeline).
        self.pipeline: PipelineBase
        if pipeline is not None:
            self.pipeline = pipeline
        elif isinstance(p.soms, SpeckFrontParams):
            self.pipeline = SpeckPipeline(p.soms)
        else:
            self.pipeline = SaliencyPipeline(
                p.soms, p.proto, p.height_px, p.width_px, lockstep=False
            )
        self.soms, self.proto = self.pipeline.soms, self.pipeline.proto
        self.controller = AttentionController(replace(p.control, seed=seed))
        self.fixation = FixationalMovements(p.fixation, np.random.default_rng(seed))
        self._shape = (2, p.height_px, p.width_px)
        self.reset(seed)

    # -- state -------------------------------------------------------------------------

    def reset(self, seed: int | None = None) -> None:
        """Back to the start of a first fixation; ``seed`` re-seeds the fixational walk
        and the controller (default: the constructor's seed)."""
        if seed is not None:
            self.seed = seed
        self.pipeline.reset()
        self.controller.reset(seed=self.seed)
        self.fixation = FixationalMovements(self.params.fixation, np.random.default_rng(self.seed))
        self.phase = Phase.FIXATE
        self.event_map = np.zeros(self._shape, np.float32)
        self.oms_map = np.zeros(self._shape, np.float32)
        self.saliency: np.ndarray | None = None
        self.target: tuple[int, int] | None = None
        self.decided = False
        self.fixations: list[Fixation] = []
        self.saccades: list[Saccade] = []
        self.events_in = 0
        self.events_oms = 0
        self.steps = 0
        self._t = 0.0
        self._started = False
        self._begin_fixation(after_saccade=True, t=0.0, gaze=(0.0, 0.0))

    def _begin_fixation(self, after_saccade: bool, t: float, gaze: tuple[float, float]) -> None:
        if after_saccade and self.params.reset_after_saccade:
            self.pipeline.reset()
        self.event_map[:] = 0.0
        self.oms_map[:] = 0.0
        self._window_steps = 0
        self._window_start = t
        self._window_gaze = gaze
        self._elapsed = 0.0
        if self.params.fixational:
            self.fixation.start(after_saccade=after_saccade)

    # -- the policy ----------------------------------------------------------------------

    def act(self, observation: dict[str, np.ndarray], info: dict[str, Any]) -> np.ndarray:
        """One env step: the next action (2,) float32 in [-1, 1]."""
        counts = np.asarray(observation["events"], dtype=np.float32)
        if counts.shape != self._shape:
            raise ValueError(
                f"observation['events'] has shape {counts.shape}, the agent was built for "
                f"{self._shape} (use AgentParams.for_env(env))"
            )
        gaze = tuple(float(g) for g in np.asarray(observation["gaze"]).reshape(2))
        t = float(info["t"]) if "t" in info else self._t + self.params.step_s
        if not self._started:  # the first window starts where the env put the camera
            self._started = True
            self._window_gaze = gaze
            # It counts the reset's observation, one step before t, but no earlier than
            # the run: no event arrives before t = 0.
            self._window_start = max(t - self.params.step_s, 0.0)
        self._t = t
        self.steps += 1
        self.decided = False

        oms_counts = kept_events(counts, self.pipeline.oms_step(counts).numpy())
        self.events_in += int(counts.sum())
        self.events_oms += int(oms_counts.sum())

        if self.phase is Phase.FIXATE:
            return self._fixate(counts, oms_counts, gaze, t, info)
        return self._saccade(gaze, t, info)

    def _fixate(
        self,
        counts: np.ndarray,
        oms_counts: np.ndarray,
        gaze: tuple[float, float],
        t: float,
        info: dict[str, Any],
    ) -> np.ndarray:
        p = self.params
        self.event_map += counts
        self.oms_map += oms_counts
        self._window_steps += 1
        action = np.zeros(2)
        if p.fixational and self.fixation.due(self._elapsed):
            action += self.fixation.next_offset().action
        self._elapsed += p.step_s
        if self._window_steps < p.window_steps:
            self.controller.step(None, p.step_s)
            return _clip(action)
        # End of the window: saliency of its OMS map, then decide.
        self.saliency = self.pipeline.saliency_of(self.oms_map).numpy()
        target = self.pipeline.argmax()
        peak = float(self.saliency[target[1], target[0]]) if target is not None else 0.0
        if target is not None and peak <= p.min_saliency:
            target = None
        self.decided = True
        self.target = target
        self.fixations.append(
            Fixation(
                index=len(self.fixations),
                t_start=self._window_start,
                t_end=t,
                gaze_deg=self._window_gaze,
                target_px=target,
                peak=peak,
                events=int(self.event_map.sum()),
                oms_events=int(self.oms_map.sum()),
            )
        )
        if target is None:
            self.controller.step(None, p.step_s)
            self._begin_fixation(after_saccade=False, t=t, gaze=gaze)
            return _clip(action)
        self._start_saccade(target, gaze, t, info)
        return self._saccade(gaze, t, info, first=True)

    def _start_saccade(
        self, target: tuple[int, int], gaze: tuple[float, float], t: float, info: dict[str, Any]
    ) -> None:
        self.target = target
        self.phase = Phase.SACCADE
        self._saccade_start = t
        self._saccade_elapsed = 0.0
        self._sent_deg = np.zeros(2)
        self._from_target = _target_deg(info, gaze)

    def saccade_to(
        self,
        target_px: tuple[int, int],
        gaze_deg: tuple[float, float] = (0.0, 0.0),
        info: dict[str, Any] | None = None,
    ) -> None:
        """Start a saccade to pixel ``target_px`` now, as if a window had chosen it (for
        saccade-accuracy experiments); the following :meth:`act` calls carry it out.
        ``gaze_deg`` and ``info`` (its ``ptu_target_deg``) give the starting direction for
        the saccade's record."""
        x, y = (int(v) for v in target_px)
        if not (0 <= x < self.params.width_px and 0 <= y < self.params.height_px):
            raise ValueError(
                f"target_px {target_px} is outside the {self.params.width_px}x"
                f"{self.params.height_px} sensor"
            )
        gaze = (float(gaze_deg[0]), float(gaze_deg[1]))
        self._start_saccade((x, y), gaze, self._t, info or {})

    def _saccade(
        self, gaze: tuple[float, float], t: float, info: dict[str, Any], first: bool = False
    ) -> np.ndarray:
        p = self.params
        settled = self._saccade_elapsed + _EPS >= p.saccade_settle_s and not info.get(
            "moving", False
        )
        if not first and (settled or self._saccade_elapsed + _EPS >= p.max_saccade_s):
            self.saccades.append(
                Saccade(
                    index=len(self.saccades),
                    t_start=self._saccade_start,
                    t_end=t,
                    target_px=self.target,
                    from_target_deg=self._from_target,
                    ideal_deg=self._ideal_deg(),
                    command_deg=(float(self._sent_deg[0]), float(self._sent_deg[1])),
                    to_gaze_deg=gaze,
                )
            )
            self.phase = Phase.FIXATE
            self.controller.step(None, p.step_s)
            self._begin_fixation(after_saccade=True, t=t, gaze=gaze)
            return self._fixate_first_step()
        u = self.controller.step(self.target, p.step_s)
        self._saccade_elapsed += p.step_s
        if self._saccade_elapsed > p.saccade_settle_s + _EPS:
            return np.zeros(2, np.float32)  # the command is complete; wait for the PTU
        u = np.clip(u, -1.0, 1.0)
        want = np.array(
            pixel_to_rotation(
                u[0] * p.width_px / 2,
                u[1] * p.height_px / 2,
                self._from_target[1],
                p.width_px,
                p.hfov_deg,
            )
        )
        delta = want - self._sent_deg
        self._sent_deg = want
        return _clip(gaze_degrees_to_action(*delta, p.width_px, p.height_px, p.hfov_deg))

    def _ideal_deg(self) -> tuple[float, float]:
        p = self.params
        x, y = self.target
        cx, cy = principal_point(p.width_px, p.height_px)
        dx, dy = x - cx, y - cy
        return pixel_to_rotation(dx, dy, self._from_target[1], p.width_px, p.hfov_deg)

    def _fixate_first_step(self) -> np.ndarray:
        """The action of the step that starts a fixation (its first walk step)."""
        if self.params.fixational and self.fixation.due(self._elapsed):
            return _clip(self.fixation.next_offset().action)
        return np.zeros(2, np.float32)

    # -- summaries -----------------------------------------------------------------------

    @property
    def suppression(self) -> float:
        """Fraction of the events seen so far that the sOMS suppressed (nan before any)."""
        return suppressed_fraction(self.events_in, self.events_oms)

    def close(self) -> None:
        """Release the nengo simulator."""
        self.controller.close()


def _clip(action: np.ndarray) -> np.ndarray:
    return np.clip(np.asarray(action, dtype=np.float64), -1.0, 1.0).astype(np.float32)


def _target_deg(info: dict[str, Any], gaze: tuple[float, float]) -> tuple[float, float]:
    """Where the PTU is heading (its target, degrees) when the env says so, else the gaze."""
    target = info.get("ptu_target_deg")
    if target is None:
        return gaze
    return float(target[0]), float(target[1])
