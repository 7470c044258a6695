"""The ``env`` block of a paper experiment's config: its check, and a trial's env made from it.

An experiment's config holds the env's parameters as ``env`` (a
:class:`~wander_env.env_config.WanderConfig`, ``--set env.frames=exact``); the fields
each trial sets itself (its scene, step, length, PTU: the module's
``ENV_SET_PER_TRIAL``, name: what sets it) the block leaves at their defaults
(:func:`check_env_block`, in the config's ``__post_init__``), and each trial makes its env
from the block with those fields replaced (:func:`trial_env`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import replace
from typing import Any

import gymnasium as gym

from wander_env.env_config import WanderConfig

__all__ = ["check_env_block", "trial_env"]


def check_env_block(env: WanderConfig, fixed: Mapping[str, str]) -> None:
    """An experiment config's check of its ``env`` block: each field of ``fixed`` (name:
    what sets it) the experiment sets itself per trial, so the block must leave it at
    :class:`~wander_env.env_config.WanderConfig`'s default (nothing given is dropped).

    >>> check_env_block(WanderConfig(scene="shelf"), {"scene": "the grid's scenes"})
    Traceback (most recent call last):
    ...
    ValueError: env.scene: set by the experiment (the grid's scenes); leave it out
    """
    default = WanderConfig()
    for name, by in fixed.items():
        if env[name] != default[name]:
            raise ValueError(f"env.{name}: set by the experiment ({by}); leave it out")


def trial_env(env: WanderConfig, **per_trial: Any) -> gym.Env:
    """A trial's ``wander/Wander-v0``: the config's ``env`` block with the fields the trial
    sets (``per_trial``, e.g. ``scene=``, ``episode_seconds=``) replaced."""
    return gym.make("wander/Wander-v0", **replace(env, **per_trial))
