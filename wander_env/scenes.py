"""The scenes: where the shipped ones are, and loading one into a :class:`SceneConfig`.

:func:`load_scene_config` takes a name (``assets/scenes/NAME.yaml``), a YAML file, a
parsed mapping or a :class:`~wander_env.scene_config.SceneConfig` (as it is);
:func:`scene_config_from_dict` validates a parsed document (:mod:`wander_env.scene_config`
says how). Files are read through :mod:`wander_env.untrusted` and the one YAML reader
(:func:`wander_env.config.parse_yaml`); relative mesh and MJCF paths in a YAML file are
relative to its folder. The lists of parts and lights are checked against their limits
before the rest is validated (a million objects cost no more than the file). A scene's
``ptu`` block says where the unit stands, not where the camera sits on it: the hinge
offset (``camera_forward_m`` / ``camera_up_m``) is refused there, naming its home
(:class:`wander_env.ptu.params.PTUParams`, the env's ``ptu`` block).

Examples:
    >>> cfg = load_scene_config("office")
    >>> cfg.name, len(cfg.moving_objects)
    ('office', 2)
"""

from __future__ import annotations

import importlib.resources
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from wander_env.config import MAX_YAML_BYTES, ConfigError, parse_yaml, validate
from wander_env.config_messages import shown
from wander_env.scene_config import MAX_LIGHTS, MAX_MATERIALS, MAX_PARTS, SceneConfig
from wander_env.untrusted import ReadLog, UntrustedFileError, read_bytes

DEFAULT_SCENE = "office"
_PART_LISTS = ("tables", "shelves", "static_objects", "moving_objects", "mjcf_includes")


# ----------------------------------------------------------------------------------------
# Locating and loading


def assets_dir() -> Path:
    """The scene assets: ``wander_env/assets`` of an installed wheel (package data), else
    the checkout's top-level ``assets/`` (a source tree or an editable install)."""
    installed = Path(str(importlib.resources.files("wander_env").joinpath("assets")))
    source = Path(__file__).resolve().parents[1] / "assets"
    for path in (installed, source):
        if (path / "scenes").is_dir():
            return path
    raise FileNotFoundError(
        f"scene assets not found at {installed} (installed package) or {source} (checkout)"
    )


def available_scenes() -> tuple[str, ...]:
    """Names of the scenes in ``assets/scenes``."""
    return tuple(sorted(p.stem for p in (assets_dir() / "scenes").glob("*.yaml")))


def load_scene_config(
    scene: str | Path | Mapping[str, Any] | SceneConfig = DEFAULT_SCENE,
    log: ReadLog | None = None,
) -> SceneConfig:
    """The scene ``scene`` names: a :class:`SceneConfig` as it is, a mapping (a parsed
    scene document) validated, a name (``assets/scenes/NAME.yaml``) or a YAML file path.

    Relative mesh and MJCF file paths in a YAML file are relative to its folder. ``log``
    records every file the scene read (the YAML file, meshes, MJCF includes and the files
    they name) with its SHA-256.
    """
    if isinstance(scene, (SceneConfig, Mapping)):
        config = scene if isinstance(scene, SceneConfig) else scene_config_from_dict(scene)
        if log is not None:
            for record in config.files_read():
                log.add_record(record)
        return config
    text = str(scene)
    is_path = isinstance(scene, Path) or text.endswith((".yaml", ".yml")) or "/" in text
    if is_path:
        path = Path(scene)
        try:
            found = path.is_file()
        except OSError as e:  # a name too long for the file system, say
            raise FileNotFoundError(
                f"scene file not readable: {text[:200]!r}: {e.strerror}"
            ) from None
        if not found:
            raise FileNotFoundError(f"scene file not found: {path}")
    else:
        path = assets_dir() / "scenes" / f"{text}.yaml"
        if len(text) > 255 or not path.is_file():
            raise ValueError(
                f"unknown scene {text[:200]!r}; available: {', '.join(available_scenes())}"
            )
    try:
        text = read_bytes(path, MAX_YAML_BYTES, log=log)
    except UntrustedFileError as e:
        raise ConfigError(str(e)) from None
    data = _files_relative_to(parse_yaml(text, str(path)), path.parent)
    config = scene_config_from_dict(data, default_name=path.stem, where=str(path))
    if log is not None:
        for record in config.files_read():
            log.add_record(record)
    return config


def _files_relative_to(data: Any, folder: Path) -> Any:
    """``data`` (a parsed scene document, not yet validated) with the relative ``file``
    paths of its meshes and MJCF includes made relative to ``folder``."""
    if not isinstance(data, Mapping):
        return data

    def rebase(block: Any) -> Any:
        file = block.get("file") if isinstance(block, Mapping) else None
        if not isinstance(file, str) or Path(file).expanduser().is_absolute():
            return block
        return {**block, "file": str(folder / file)}

    def with_mesh(item: Any) -> Any:
        return (
            {**item, "mesh": rebase(item["mesh"])}
            if isinstance(item, Mapping) and "mesh" in item
            else item
        )

    out = dict(data)
    for key in ("static_objects", "moving_objects"):
        if isinstance(out.get(key), list):
            out[key] = [with_mesh(item) for item in out[key]]
    if isinstance(out.get("mjcf_includes"), list):
        out["mjcf_includes"] = [rebase(item) for item in out["mjcf_includes"]]
    return out


# ----------------------------------------------------------------------------------------
# Parsing


def scene_config_from_dict(
    data: Any, default_name: str = "scene", where: str | None = None
) -> SceneConfig:
    """Validate a parsed YAML mapping into a :class:`SceneConfig` (``name`` defaults to
    ``default_name``); ConfigError (a ValueError) starting with ``where: `` (the file)
    when given, then the field's path.

    >>> scene_config_from_dict({"camera": {"width": 64}}).camera.width
    64
    >>> bad = {"moving_objects": [{"shape": "box", "size": [1, 1, 1], "trajectory": {}}]}
    >>> try:
    ...     scene_config_from_dict(bad, where="my.yaml")
    ... except ValueError as e:
    ...     print(e)  # doctest: +NORMALIZE_WHITESPACE
    my.yaml: moving_objects[0].trajectory.kind: required
    (one of 'linear_bounce', 'circular', 'random_walk', 'waypoints',
    'scripted')
    """
    if isinstance(data, Mapping) and "name" not in data:
        data = {"name": default_name, **data}
    _refuse_hinge_offset(data, where)
    _check_lengths(data, where)
    return validate(SceneConfig, data, where=where)


def _check_lengths(data: Any, where: str | None) -> None:
    """The lists of parts and lights within their limits, checked on the parsed document
    before it is validated (so that a million objects cost no more than the file).
    ConfigError ``where: key: ...``."""
    if not isinstance(data, Mapping):
        return
    lighting = data.get("lighting")
    why = f"MuJoCo renders at most {MAX_MATERIALS} materials, one a part"
    lists = {key: (data.get(key), MAX_PARTS, why) for key in _PART_LISTS}
    if isinstance(lighting, Mapping):
        lights = lighting.get("lights")
        lists["lighting.lights"] = (lights, MAX_LIGHTS, f"MuJoCo's limit is {MAX_LIGHTS}")
    head = f"{where}: " if where else ""
    for key, (items, limit, reason) in lists.items():
        if isinstance(items, (list, tuple)) and len(items) > limit:
            raise ConfigError(f"{head}{key}: at most {limit} items ({reason}), got {len(items)}")


#: The camera's offset from the tilt hinge: a scene's ``ptu`` block held it once; it is
#: :class:`wander_env.ptu.params.PTUParams`' alone.
_HINGE_OFFSET_KEYS = ("camera_forward_m", "camera_up_m")


def _refuse_hinge_offset(data: Any, where: str | None) -> None:
    """ConfigError ``where: ptu.KEY: ...`` naming where the hinge offset is given now, when
    the parsed document gives it in its ``ptu`` block (nested or as a dotted key)."""
    if not isinstance(data, Mapping):
        return
    ptu = data.get("ptu")
    block = ptu if isinstance(ptu, Mapping) else {}
    for key in _HINGE_OFFSET_KEYS:
        if key in block:
            value = block[key]
        elif f"ptu.{key}" in data:
            value = data[f"ptu.{key}"]
        else:
            continue
        head = f"{where}: " if where else ""
        raise ConfigError(
            f"{head}ptu.{key}: the camera's offset from the hinge is the PTU's, not the "
            f"scene's: give it in the env's ptu block (env.ptu.{key}, or --set "
            f"env.ptu.{key}=...), got {shown(value)}"
        )
