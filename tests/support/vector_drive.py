"""Drives a 2-env vector env through the same 20 steps and fingerprints what came back.

Imported by tests/test_vector_env.py; run as a script (``python tests/vector_drive.py``)
it is the issue's snippet in a fresh process: ``AsyncVectorEnv`` and ``make_vec(...,
"async")`` with the default start method, printing one JSON line.
"""

from __future__ import annotations

import hashlib
import json
import multiprocessing
import time
from typing import Any

import gymnasium as gym
import numpy as np

import wander_env  # noqa: F401  (registers the environments)

NUM_ENVS, STEPS, SEED = 2, 20, 1
WAIT_S = 240.0  # bound on each reset/step of an async vector env


def make_env() -> gym.Env:
    """The default env, as a new user makes it (importable: picklable for "spawn")."""
    return gym.make("wander/Wander-v0")


def actions() -> np.ndarray:
    """(STEPS, NUM_ENVS, 2): env 0 saccades right-down, env 1 left-up, then small steps."""
    a = np.random.default_rng(7).uniform(-0.05, 0.05, (STEPS, NUM_ENVS, 2)).astype(np.float32)
    a[0] = [[0.4, 0.2], [-0.3, -0.15]]
    return a


def drive(venv: gym.vector.VectorEnv) -> dict[str, Any]:
    """Reset with SEED and take :func:`actions`; per step and env, the events' digest,
    count and the observation's sum; async waits are bounded by ``WAIT_S``."""
    bounded = hasattr(venv, "step_wait")
    if bounded:
        venv.reset_async(seed=SEED)
        obs, _ = venv.reset_wait(timeout=WAIT_S)
    else:
        obs, _ = venv.reset(seed=SEED)
    rows = []
    for a in actions():
        if bounded:
            venv.step_async(a)
            obs, _, _, _, infos = venv.step_wait(timeout=WAIT_S)
        else:
            obs, _, _, _, infos = venv.step(a)
        packets = infos["events"]
        rows.append(
            {
                "types": sorted({type(p).__name__ for p in packets}),
                "digests": [hashlib.sha256(np.asarray(p).tobytes()).hexdigest() for p in packets],
                "counts": [len(p) for p in packets],
                "obs_sums": [int(s) for s in obs["events"].reshape(NUM_ENVS, -1).sum(axis=1)],
                "masks": bool(np.all(infos["_events"])),
            }
        )
    return {"rows": rows, "gaze": obs["gaze"].tolist()}


def drive_and_close(venv: gym.vector.VectorEnv) -> dict[str, Any]:
    """:func:`drive`, then close; after a failure (a timeout) the workers are terminated,
    since a plain ``close`` would wait for an answer from a stuck worker."""
    try:
        out = drive(venv)
    except BaseException:
        venv.close(terminate=True)
        raise
    venv.close()
    return out


def main() -> None:
    out: dict[str, Any] = {"start_method": multiprocessing.get_start_method()}
    t0 = time.perf_counter()
    venv = gym.vector.AsyncVectorEnv([lambda: gym.make("wander/Wander-v0") for _ in range(2)])
    out["async_default"] = drive_and_close(venv)
    out["async_default_s"] = time.perf_counter() - t0
    venv = gym.make_vec("wander/Wander-v0", num_envs=NUM_ENVS, vectorization_mode="async")
    out["make_vec_async"] = drive_and_close(venv)
    print(json.dumps(out))


if __name__ == "__main__":
    main()
