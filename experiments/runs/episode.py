"""One episode of an env under a policy, watched by recorders: the one step loop of
``wander run``, ``record``, ``rig`` and the experiments' closed-loop trials.

:func:`run_episode` resets ``env`` (and the policy, where it has ``reset()``), then for
each step asks ``policy.act(obs, info)`` for the action and steps the env. Everything
that watches the run is a :class:`Recorder` (events file, ground truth, video, Rerun,
detection, a study's own statistics, the rig's counters, the run folder:
:mod:`experiments.runs.recorders`), called in the order given:

- :meth:`Recorder.on_reset` after ``env.reset`` and ``policy.reset``;
- :meth:`Recorder.on_act` after ``policy.act`` (the env still in the pose the policy
  decided in; ``obs``/``info`` the ones it saw);
- :meth:`Recorder.on_step` after ``env.step`` (``obs``/``info`` the step's);
- ``until()`` (where given) after the step's recorders: true ends the episode there (a
  stop condition: a forced saccade that ended);
- :meth:`Recorder.close` once when the loop ended, with the loop's error (``None``:
  none), returning the error to raise (a recorder whose file failed to close hands back
  its own when the run had none).

The error path is the loop's, once for every caller: a signal deferred by ``signals``
(:class:`~experiments.runs.signals.DeferredSignals`) is taken up between two steps, never
inside a render, a device read or a file write; an error or a signal calls ``halt`` (the
rig: halt the PTU) at once, then closes every recorder with it (the run-folder recorder
writes ``metrics.json`` with ``error`` and ``signal`` and the ``INCOMPLETE`` marker), then
raises it.

Examples:
    >>> class Counter(Recorder):
    ...     steps = 0
    ...     def on_step(self, env, policy, obs, info):
    ...         self.steps += 1
    >>> class Env:  # the Gymnasium contract, ending after 3 steps
    ...     t = 0
    ...     def reset(self, seed=None, options=None):
    ...         self.t = 0
    ...         return {}, {}
    ...     def step(self, action):
    ...         self.t += 1
    ...         return {}, 0.0, self.t == 3, False, {}
    >>> class Still:
    ...     def act(self, obs, info):
    ...         return 0
    >>> counter = Counter()
    >>> run_episode(Env(), Still(), 10, (counter,)), counter.steps
    (3, 3)
    >>> early = Counter()  # a stop condition ends it sooner
    >>> run_episode(Env(), Still(), 10, (early,), until=lambda: early.steps == 2)
    2
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any, Protocol

from experiments.runs.signals import DeferredSignals

__all__ = ["OneEpisode", "Policy", "Recorder", "run_episode"]


class OneEpisode:
    """The base of a job's config whose run is one episode of its ``env`` block (``wander
    run``, ``record``, ``rig``): the dataclass's fields checked against their annotations
    when it is made (:func:`wander_env.config.check_annotated`)."""

    def __post_init__(self) -> None:
        from wander_env.config import check_annotated  # pydantic: only where a config is made

        check_annotated(self)

    @property
    def seconds(self) -> float:
        """The run's length: one episode of ``env``."""
        return self.env.episode_seconds  # type: ignore[attr-defined]


class Policy(Protocol):
    """What :func:`run_episode` drives: ``act(obs, info) -> action`` (and an optional
    ``reset()``, called after ``env.reset``): the attention agent, the scripted gaze
    policies."""

    def act(self, obs: Any, info: dict[str, Any]) -> Any: ...


class Recorder:
    """A recorder that watches nothing (override the hooks it needs; module doc)."""

    def on_reset(self, env: Any, policy: Any, obs: Any, info: dict[str, Any]) -> None:
        """After ``env.reset`` and ``policy.reset``."""

    def on_act(self, env: Any, policy: Any, obs: Any, info: dict[str, Any]) -> None:
        """After ``policy.act(obs, info)``, before the env steps."""

    def on_step(self, env: Any, policy: Any, obs: Any, info: dict[str, Any]) -> None:
        """After ``env.step``: ``obs`` and ``info`` of the step."""

    def close(self, error: BaseException | None) -> BaseException | None:
        """The loop ended (with ``error``); returns the error to raise."""
        return error

    def metrics(self) -> dict[str, Any]:
        """What it adds to the run's ``metrics.json`` (after :meth:`close`; {}: nothing)."""
        return {}


def run_episode(
    env: Any,
    policy: Policy,
    steps: int,
    recorders: Sequence[Recorder] = (),
    signals: DeferredSignals | None = None,
    *,
    seed: int | None = None,
    options: dict[str, Any] | None = None,
    until: Callable[[], bool] | None = None,
    progress: Callable[[int, int], None] | None = None,
    halt: Callable[[], None] | None = None,
) -> int:
    """Reset ``env`` with ``seed`` (and the reset ``options``, e.g. a start gaze, where
    given) and step it ``steps`` times (fewer when it terminates or truncates, or when
    ``until``, asked after each step's recorders, says the episode is over) under
    ``policy``, calling ``recorders``' hooks (module doc).

    ``signals``: the caller's deferred-signal block, checked between steps; ``progress``:
    called with (steps done, ``steps``) after each step; ``halt``: called at once when the
    loop ends on an error or a signal (it must not raise). Returns the steps taken;
    raises the loop's error (or one a recorder's close handed back) after every
    recorder was closed.
    """
    error: BaseException | None = None
    done = 0
    try:
        if options is None:
            obs, info = env.reset(seed=seed)
        else:
            obs, info = env.reset(seed=seed, options=options)
        reset = getattr(policy, "reset", None)
        if reset is not None:
            reset()
        for r in recorders:
            r.on_reset(env, policy, obs, info)
        for _ in range(steps):
            if signals is not None:
                signals.check()  # a signal that came during the last step stops here
            action = policy.act(obs, info)
            for r in recorders:
                r.on_act(env, policy, obs, info)
            obs, _, terminated, truncated, info = env.step(action)
            done += 1
            for r in recorders:
                r.on_step(env, policy, obs, info)
            if progress is not None:
                progress(done, steps)
            if terminated or truncated or (until is not None and until()):
                break
    except BaseException as exc:
        # the signal raised, also where foreign code turned it into another error
        stop = signals.raised if signals is not None else None
        error = stop if stop is not None else exc
        if halt is not None:
            halt()
    for r in recorders:
        try:
            error = r.close(error)
        except BaseException as exc:  # a close that raised: the others still close
            if error is None:
                error = exc
            else:
                error.add_note(f"closing the {type(r).__name__} also failed: {exc!r}")
    if error is not None:
        raise error
    return done
