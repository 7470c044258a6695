"""What every run folder records in ``run.json``: the command, its config and seed, the
git revision, the time, the platform and the versions of the packages that made it
(:func:`run_record`), and what it read (:func:`input_record`): the resolved scene (the
validated :class:`~wander_env.scene_config.SceneConfig` as data) and the SHA-256 of every
file (the scene file, its meshes, MJCF includes and the files they name, a replayed
recording). :func:`check_inputs` refuses a rerun whose files changed since.

Examples:
    >>> r = run_record("wander demo", {"seconds": 1.0}, seed=0)
    >>> sorted(r)
    ['command', 'config', 'created', 'git_revision', 'platform', 'seed', 'versions']
    >>> r = run_record("wander run", {"env": {"scene": "shelf"}}, seed=0)
    >>> r["inputs"]["scenes"]["shelf"]["name"], [Path(f).name for f in r["inputs"]["files"]]
    ('shelf', ['shelf.yaml'])
"""

from __future__ import annotations

import os
import platform
import subprocess
from collections.abc import Callable, Iterator, Mapping
from datetime import datetime, timezone
from importlib import metadata
from pathlib import Path
from typing import Any, TypeVar

T = TypeVar("T")
GIT_TIMEOUT_S = 30.0  # a git that hangs (a lock, a network file system) must not hang a run

#: The packages whose versions ``run.json`` records (distribution names).
VERSIONED_PACKAGES = ("numpy", "mujoco", "torch", "sinabs", "nengo", "gymnasium", "wander")


def git_revision(path: Path | None = None) -> str:
    """The current commit (with ``-dirty`` if the tree has changes), or ``"unknown"``
    (no git, not a checkout, or git took longer than ``GIT_TIMEOUT_S``)."""
    cwd = path or Path(__file__).resolve().parent

    def git(*args: str) -> str:
        done = subprocess.run(
            ["git", *args],
            cwd=cwd,
            capture_output=True,
            text=True,
            check=True,
            timeout=GIT_TIMEOUT_S,
        )
        return done.stdout.strip()

    try:
        rev = git("rev-parse", "HEAD")
        dirty = git("status", "--porcelain", "--untracked-files=no")
    except (OSError, subprocess.CalledProcessError, subprocess.TimeoutExpired):
        return "unknown"
    return rev + ("-dirty" if dirty else "")


def package_versions(names: tuple[str, ...] = VERSIONED_PACKAGES) -> dict[str, str | None]:
    """Python's version and each installed package's (``None`` when not installed).

    >>> v = package_versions(("numpy", "no-such-package-here"))
    >>> sorted(v), v["no-such-package-here"]
    (['no-such-package-here', 'numpy', 'python'], None)
    """
    out: dict[str, str | None] = {"python": platform.python_version()}
    for name in names:
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = None
    return out


def run_record(command: str, config: dict[str, Any], seed: int | None) -> dict[str, Any]:
    """The provenance block written next to every result (with ``inputs``,
    :func:`input_record`, when the config names a scene or a file)."""
    rec = {
        "command": command,
        "config": config,
        "seed": seed,
        "git_revision": git_revision(),
        "created": datetime.now(timezone.utc).isoformat(timespec="seconds"),
        "platform": platform.platform(),
        "versions": package_versions(),
    }
    inputs = input_record(config)
    if inputs["files"] or inputs["scenes"]:
        rec["inputs"] = inputs
    return rec


def _walk(value: Any, key: str = "") -> Iterator[tuple[str, Any]]:
    """Every (key, value) pair nested in ``value`` (a list's items under its key)."""
    if isinstance(value, Mapping):
        for k, v in value.items():
            yield str(k), v
            yield from _walk(v, str(k))
    elif isinstance(value, (list, tuple)):
        for v in value:
            yield key, v
            yield from _walk(v, key)


def _names_scene(value: Any) -> bool:
    """Whether ``value`` is a scene: a mapping, a scene name or a scene YAML file."""
    if isinstance(value, Mapping):
        return True
    if not isinstance(value, str):
        return False
    from wander_env.scenes import available_scenes

    return value.endswith((".yaml", ".yml")) or value in available_scenes()


def input_record(config: Mapping[str, Any]) -> dict[str, Any]:
    """What a run of ``config`` reads: ``scenes`` (each ``scene``/``scenes`` value, the
    scene it resolves to as data) and ``files`` (``{absolute path: SHA-256}`` of every
    file they read, and of each string value of the config that names a regular file,
    ``replay:FILE`` included), read through :mod:`wander_env.untrusted`."""
    from wander_env.untrusted import ReadLog, UntrustedFileError, hash_file

    log = ReadLog()
    scenes: dict[str, Any] = {}
    files: list[str] = []
    for key, value in _walk(config):
        if key in ("scene", "scenes") and _names_scene(value):
            from wander_env.config import to_plain
            from wander_env.scenes import load_scene_config

            label = value if isinstance(value, str) else str(value.get("name", "scene"))
            scenes[label] = to_plain(load_scene_config(value, log=log))
        elif isinstance(value, str) and len(value) < 4096:
            files += [f for f in (value, value.partition(":")[2]) if f and os.path.isfile(f)]
    for f in files:
        try:
            log.add_record(hash_file(f))
        except UntrustedFileError:  # a FIFO, a device: not an input (the run refuses it)
            continue
    return {"scenes": scenes, "files": log.digests()}


def check_inputs(record: Mapping[str, Any], where: str) -> None:
    """``record`` (a ``run.json``) holds ``inputs``, a mapping whose ``scenes`` and
    ``files`` are mappings, and every file hashed in ``inputs.files`` still has its
    SHA-256; ValueError ``WHERE: inputs...: what is wrong`` (one line) otherwise (``inputs.
    files: FILE changed since the run ...``)."""
    from wander_env.config_messages import shown
    from wander_env.untrusted import UntrustedFileError, hash_file

    if "inputs" not in record:
        raise ValueError(f"{where}: inputs: missing (the scene and the files the run read)")
    inputs = record["inputs"]
    if not isinstance(inputs, Mapping):
        raise ValueError(
            f"{where}: inputs: must be a mapping of scenes and files, got {shown(inputs)}"
        )
    for key in ("scenes", "files"):
        if not isinstance(inputs.get(key), Mapping):
            raise ValueError(
                f"{where}: inputs.{key}: must be a mapping, got {shown(inputs.get(key))}"
            )
    for path, digest in inputs["files"].items():
        try:
            now = hash_file(path).sha256
        except UntrustedFileError as err:
            raise ValueError(f"{where}: inputs.files: {err}; the run read it") from None
        if now != digest:
            raise ValueError(
                f"{where}: inputs.files: {path} changed since the run (SHA-256 "
                f"{str(digest)[:12]}..., now {now[:12]}...): the rerun would differ"
            )


def rerun_config(path: Path, cls: Callable[..., T], command: str) -> T:
    """The config of the run whose ``run.json`` is ``path`` (a run of ``command``), as a
    ``cls``, its scene the resolved scene the run recorded and its seed the run's
    ``seed``; ValueError (one line naming the file, the key and the value) when it is not
    such a run or a file it read changed since (:func:`check_inputs`)."""
    from wander_env.config import validate
    from wander_env.config_messages import shown
    from wander_env.untrusted import UntrustedFileError, read_json

    try:
        record = read_json(path)
    except UntrustedFileError as err:
        raise ValueError(str(err)) from None
    if not isinstance(record, dict):
        raise ValueError(f"{path}: must be a run folder's JSON object, got {shown(record)}")
    if "config" not in record:
        raise ValueError(f"{path}: config: missing (not a run folder's run.json)")
    config = record["config"]
    if not isinstance(config, dict):
        raise ValueError(f"{path}: config: must be a mapping of settings, got {shown(config)}")
    if record.get("command") != command:
        found = str(record.get("command"))[:80]
        raise ValueError(f"{path}: command: {found!r} is not a {command!r} run")
    if "seed" not in record:
        raise ValueError(f"{path}: seed: missing (the run's seed)")
    seed = validate(cls, {"seed": record["seed"]}, where=str(path)).seed  # as cls takes it
    if config.get("seed", seed) != seed:
        raise ValueError(
            f"{path}: config.seed: must be the run's seed {seed}, got {shown(config['seed'])}"
        )
    env = config.get("env")
    if not isinstance(env, dict) or "scene" not in env:
        raise ValueError(
            f"{path}: config.env: must be a mapping naming the run's scene, got {shown(env)}"
        )
    check_inputs(record, str(path))
    scenes = record["inputs"]["scenes"]
    if isinstance(env["scene"], str):
        if env["scene"] not in scenes:
            raise ValueError(
                f"{path}: inputs.scenes: no entry for the run's scene, got config.env.scene "
                f"{shown(env['scene'])}"
            )
        env = {**env, "scene": scenes[env["scene"]]}  # the scene as it resolved
    return validate(cls, {**config, "env": env, "seed": seed}, where=f"{path}: config")


__all__ = [
    "VERSIONED_PACKAGES",
    "check_inputs",
    "git_revision",
    "input_record",
    "package_versions",
    "rerun_config",
    "run_record",
]
