"""One config system: parameter dataclasses validated from YAML, dicts and ``--set`` items.

pydantic (strict, unknown keys refused, nested dataclasses and tuples) does the
validation; this module only turns its errors into the project's messages, each led by
where the value came from (a file, ``--set``) and the field's path, then what is wrong
and the value given, e.g.
``--set: soms: unknown key 'alph' for SOMSParams; allowed keys: ...``,
``c.yaml: env.frames: expected one of 'keyframes', 'exact', 'panorama', got 'fast'`` or
``scene.yaml: moving_objects[1].trajectory.kind: expected one of ...``.

- :func:`validate` — a dataclass instance from a mapping (nested mappings become nested
  dataclasses; dotted keys are nested keys), optionally on top of a ``base`` instance (a
  nested mapping updates only the keys it names); tagged unions
  (``Annotated[A | B, pydantic.Field(discriminator="kind")]``) included;
- :func:`coerce` — one value as a type (``TypeError`` naming the type);
- :func:`parse_sets` — ``["a.b=value", ...]`` → nested ``{"a": {"b": value}}``;
- :func:`check_fields` — the shared ``__post_init__`` check of numeric fields;
- :func:`check_annotated` — a ``__post_init__`` check of a dataclass's ``Annotated``
  and ``Literal`` fields by pydantic (for instances built in code, e.g. by
  ``dataclasses.replace``);
- :func:`load_yaml` / :func:`parse_yaml` — the one YAML reader of every config, scene
  and sweep file (and ``--set`` value): bounded (:data:`MAX_YAML_BYTES`,
  :data:`MAX_YAML_DEPTH`), plain data only (no anchors or aliases, no tags), UTF-8 text;
  every refusal and syntax error one :class:`ConfigError` line naming the file, the line
  and the column.

Numbers: ints are accepted for floats; bools are not numbers; a string such as ``1e-3``
(YAML 1.1 reads it as a string) is read as the float it spells; infinities and NaN are
refused (``1e400`` is one). A field's range (``Annotated[float, pydantic.Field(le=...)]``)
is checked with its type: ``duration_s: input should be less than or equal to 3600, got
7200``.

Examples:
    >>> from wander_env.scene_config import RoomConfig
    >>> room = validate(RoomConfig, parse_sets(["wall_texture.tile_m=2"], RoomConfig))
    >>> room.wall_texture.tile_m, room.floor_texture.kind  # the other blocks keep defaults
    (2.0, 'checker')
"""

from __future__ import annotations

import dataclasses
import json
import math
import typing
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any, Literal

import numpy as np
import pydantic
import yaml

from wander_env.config_messages import (
    allowed_keys,
    error_messages,
    field_types,
    kept_errors,
    shown,
    type_name,
)
from wander_env.untrusted import UntrustedFileError, open_regular

__all__ = [
    "MAX_KEY_PARTS",
    "MAX_NUMBER_CHARS",
    "MAX_YAML_BYTES",
    "MAX_YAML_DEPTH",
    "ConfigError",
    "FieldsMapping",
    "check_annotated",
    "check_fields",
    "coerce",
    "load_yaml",
    "parse_sets",
    "parse_yaml",
    "to_plain",
    "validate",
]


class ConfigError(ValueError):
    """A bad config key or value; the message names where, the key and the value."""


_STRICT = pydantic.ConfigDict(strict=True, extra="forbid")
_FINITE = pydantic.ConfigDict(strict=True, extra="forbid", allow_inf_nan=False)


#: The largest YAML file read (bytes): configs, scenes and sweeps are a few kB.
MAX_YAML_BYTES = 1 << 20
#: The deepest nesting of lists and mappings in a YAML document (or a ``--set`` value).
MAX_YAML_DEPTH = 64
#: The longest plain scalar read as a number (characters): no setting needs more digits.
MAX_NUMBER_CHARS = 100
#: The most parts of a dotted ``--set`` key.
MAX_KEY_PARTS = MAX_YAML_DEPTH


class _Refused(yaml.MarkedYAMLError):
    """A YAML document refused by :class:`_PlainLoader` (not a syntax error)."""


class _PlainLoader(yaml.SafeLoader):
    """PyYAML's safe loader, bounded: nesting depth, no anchors, aliases or tags, no
    over-long numbers; each refusal a ``yaml.MarkedYAMLError`` at the node."""

    def __init__(self, stream: str) -> None:
        super().__init__(stream)
        self.depth = 0

    def _refuse(self, event: Any, problem: str) -> _Refused:
        return _Refused(problem=problem, problem_mark=event.start_mark)

    def compose_node(self, parent: Any, index: Any) -> Any:
        event = self.peek_event()
        if isinstance(event, yaml.AliasEvent) or getattr(event, "anchor", None) is not None:
            raise self._refuse(event, "anchors and aliases (&name, *name) are not allowed")
        tag = getattr(event, "tag", None)
        if tag not in (None, "!"):
            raise self._refuse(event, f"tags are not allowed, got {tag!r}")
        if isinstance(event, yaml.ScalarEvent) and len(event.value) > MAX_NUMBER_CHARS:
            resolved = self.resolve(yaml.ScalarNode, event.value, event.implicit)
            if resolved.endswith((":int", ":float")):
                raise self._refuse(
                    event,
                    f"a number of {len(event.value)} characters; at most {MAX_NUMBER_CHARS}",
                )
        if not isinstance(event, (yaml.MappingStartEvent, yaml.SequenceStartEvent)):
            return super().compose_node(parent, index)
        self.depth += 1
        if self.depth > MAX_YAML_DEPTH:
            raise self._refuse(event, f"nested deeper than {MAX_YAML_DEPTH} levels")
        try:
            return super().compose_node(parent, index)
        finally:
            self.depth -= 1

    def construct_mapping(self, node: Any, deep: bool = False) -> Any:
        """A mapping, a key given twice refused (PyYAML keeps the last one silently)."""
        seen: set[Any] = set()
        for key_node, _ in node.value:
            key = self.construct_object(key_node, deep=True)
            if not isinstance(key, str | int | float | bool):
                continue  # unhashable: refused later as a key that is not a string
            if key in seen:
                raise _Refused(problem=f"duplicate key {key!r}", problem_mark=key_node.start_mark)
            seen.add(key)
        return super().construct_mapping(node, deep=deep)

    def _decimal(self, node: Any, integer: bool) -> None:
        """Refuse YAML 1.1's other ways of writing a number (``017`` octal, ``0x10``,
        ``0b1``, ``1:20`` base 60, ``1_000``): each reads as another value than it seems."""
        text = node.value.lstrip("+-")
        other = text[:2].lower() in ("0x", "0b", "0o") or ":" in text or "_" in text
        octal = integer and len(text) > 1 and text[0] == "0"
        if other or octal:
            raise _Refused(
                problem=f"{node.value!r}: write numbers in plain decimal (YAML 1.1 reads this "
                "form as octal, hexadecimal, binary or base 60)",
                problem_mark=node.start_mark,
            )

    def construct_yaml_int(self, node: Any) -> int:
        self._decimal(node, integer=True)
        return super().construct_yaml_int(node)

    def construct_yaml_float(self, node: Any) -> float:
        self._decimal(node, integer=False)
        return super().construct_yaml_float(node)


_PlainLoader.add_constructor("tag:yaml.org,2002:int", _PlainLoader.construct_yaml_int)
_PlainLoader.add_constructor("tag:yaml.org,2002:float", _PlainLoader.construct_yaml_float)


def _yaml_value(text: str) -> Any:
    """``text`` parsed by :class:`_PlainLoader` (yaml.YAMLError on any problem)."""
    loader = _PlainLoader(text)
    try:
        return loader.get_single_data()
    finally:
        loader.dispose()


def _yaml_problem(err: yaml.YAMLError) -> str:
    """A PyYAML error as ``line L, column C: what`` on one line."""
    if isinstance(err, yaml.reader.ReaderError):
        code = err.character if isinstance(err.character, int) else ord(err.character)
        return f"a control character (U+{code:04X}) at offset {err.position}"
    if isinstance(err, yaml.MarkedYAMLError):
        mark = err.problem_mark or err.context_mark
        what = " ".join(p for p in (err.context, err.problem) if p) or "invalid YAML"
        at = f"line {mark.line + 1}, column {mark.column + 1}: " if mark is not None else ""
        return at + " ".join(what.split())
    return " ".join(str(err).split())


def parse_yaml(text: str | bytes, where: str) -> Any:
    """The data of YAML ``text`` (bytes must be UTF-8), bounded as :func:`load_yaml`;
    ConfigError ``where: ...`` on one line.

    >>> parse_yaml("size: [0.2, 1]", "a.yaml")
    {'size': [0.2, 1]}
    >>> parse_yaml("size: [0.2", "a.yaml")
    Traceback (most recent call last):
    ...
    wander_env.config.ConfigError: a.yaml: line 1, column 11: while parsing a flow sequence expected ',' or ']', but got '<stream end>'
    >>> parse_yaml("a: &x [1]\\nb: *x", "a.yaml")
    Traceback (most recent call last):
    ...
    wander_env.config.ConfigError: a.yaml: line 1, column 4: anchors and aliases (&name, *name) are not allowed
    """  # noqa: E501
    if isinstance(text, bytes):
        if len(text) > MAX_YAML_BYTES:
            raise ConfigError(f"{where}: larger than {MAX_YAML_BYTES} bytes (the limit)")
        if text.startswith((b"\xff\xfe", b"\xfe\xff")):
            raise ConfigError(f"{where}: UTF-16 text; save it as UTF-8")
        try:
            text = text.decode("utf-8-sig")
        except UnicodeDecodeError as err:
            raise ConfigError(
                f"{where}: not UTF-8 text (byte 0x{err.object[err.start]:02x} at offset "
                f"{err.start})"
            ) from None
    nul = text.find("\x00")
    if nul >= 0:
        raise ConfigError(f"{where}: a NUL character at offset {nul} (not a text file)")
    if len(text) > MAX_YAML_BYTES:
        raise ConfigError(f"{where}: larger than {MAX_YAML_BYTES} bytes (the limit)")
    try:
        return _yaml_value(text)
    except yaml.YAMLError as err:
        raise ConfigError(f"{where}: {_yaml_problem(err)}") from None
    except (ValueError, RecursionError) as err:  # a constructor's own refusal
        raise ConfigError(f"{where}: {' '.join(str(err).split())}") from None


def load_yaml(path: str | Path, what: str = "config file") -> Any:
    """The data of the YAML file ``path`` (``what`` names it in messages): at most
    :data:`MAX_YAML_BYTES` of UTF-8 text, lists and mappings nested at most
    :data:`MAX_YAML_DEPTH` deep, numbers of at most :data:`MAX_NUMBER_CHARS` characters,
    no anchors or aliases (``&a``/``*a``), no tags (``!!python/...``), no NUL; an empty
    file is None. ConfigError on one line naming the file (and the line and column).
    """
    path = Path(path)
    try:
        with open_regular(path) as f:  # a FIFO or a device is refused, never waited on
            data = f.read(MAX_YAML_BYTES + 1)
    except UntrustedFileError as err:
        if err.missing:
            raise ConfigError(f"{what} not found: {path}") from None
        if err.kind == "a folder":
            raise ConfigError(f"{path}: a folder, not a {what}") from None
        raise ConfigError(f"{path}: the {what}: {err.problem}") from None
    except OSError as err:
        raise ConfigError(f"{path}: cannot read the {what}: {err.strerror or err}") from None
    return parse_yaml(data, str(path))


def to_plain(obj: Any) -> Any:
    """Dataclasses (their init fields) as dicts and tuples as lists, recursively."""
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return {f.name: to_plain(getattr(obj, f.name)) for f in dataclasses.fields(obj) if f.init}
    if isinstance(obj, (list, tuple)):
        return [to_plain(v) for v in obj]
    if isinstance(obj, Mapping):
        return {k: to_plain(v) for k, v in obj.items()}
    return obj


def _merge(base: Any, values: Mapping[str, Any]) -> dict[str, Any]:
    """``base`` (a plain dict) updated by ``values``; nested mappings update nested dicts,
    except one with a key its dict lacks: another block (of a union field: the Speck front
    end where the base holds an sOMS), or a mistyped key's, which replaces the dict (the
    validator then names the key)."""
    out = dict(base) if isinstance(base, Mapping) else {}
    for k, v in values.items():
        old = out.get(k)
        if isinstance(v, Mapping) and isinstance(old, Mapping) and set(v) <= set(old):
            out[k] = _merge(out[k], v)
        else:
            out[k] = v
    return out


def _expand(values: Mapping[str, Any]) -> dict[str, Any]:
    """Dotted keys (``"soms.alpha": 0.6``, as in a sweep's grid) as nested mappings."""
    out: dict[str, Any] = {}
    for key, v in values.items():
        *head, last = key.split(".")
        node = out
        for name in head:
            node = node.setdefault(name, {})
            if not isinstance(node, dict):
                raise ConfigError(f"key {key!r}: {name} is set to a value already")
        if isinstance(v, Mapping) and isinstance(node.get(last), dict):
            node[last] = _merge(node[last], v)
        else:
            node[last] = v
    return out


def _on_defaults(cls: Any, values: Mapping[str, Any]) -> dict[str, Any]:
    """``values`` with each nested block laid over its field's default (so a nested
    mapping changes only the keys it names, also where the default is not the block
    class's own defaults)."""
    if not dataclasses.is_dataclass(cls):
        return dict(values)
    by_name = {f.name: f for f in dataclasses.fields(cls) if f.init}
    out = dict(values)
    for k, v in values.items():
        f = by_name.get(k)
        if f is None or not isinstance(v, Mapping):
            continue
        if f.default is not dataclasses.MISSING:
            default = f.default
        elif f.default_factory is not dataclasses.MISSING:
            default = f.default_factory()
        else:
            default = None
        plain = to_plain(default) if dataclasses.is_dataclass(default) else None
        if plain is not None and set(v) <= set(plain):  # else another block, as in _merge
            # The default's own nested values (not its class's) under the keys v names.
            out[k] = _merge(plain, v)
    return out


def _float_text(v: Any) -> float | None:
    if not isinstance(v, str):
        return None
    try:
        return float(v)
    except ValueError:
        return None


def _set_at(data: Any, loc: tuple[Any, ...], value: Any) -> None:
    """Put ``value`` at pydantic's error location ``loc`` in ``data``; a tagged union's
    member (``agent.soms``'s ``"SOMSParams"``) stands in ``loc`` but names no key."""
    for part in loc[:-1]:
        if isinstance(data, dict) and part not in data:
            continue
        data = data[part]
    data[loc[-1]] = value


def _run(tp: Any, data: Any, config: pydantic.ConfigDict = _STRICT) -> Any:
    """Validate ``data`` as ``tp`` (strict, JSON semantics); numeric strings taken as floats."""
    adapter = pydantic.TypeAdapter(list[tp], config=config)  # type: ignore[valid-type]
    box = [json.loads(json.dumps(data, allow_nan=True))]
    for _ in range(64):  # at most one retry per numeric string
        try:
            return adapter.validate_json(json.dumps(box, allow_nan=True))[0]
        except pydantic.ValidationError as e:
            fixable = [
                err
                for err in e.errors()
                if err["type"] == "float_type" and _float_text(err["input"]) is not None
            ]
            if not fixable:
                raise
            for err in fixable:
                _set_at(box, err["loc"], _float_text(err["input"]))
    return adapter.validate_json(json.dumps(box, allow_nan=True))[0]


def coerce(value: Any, tp: Any) -> Any:
    """``value`` as type ``tp`` (int, float, str, bool, Literal, tuples, unions,
    dataclasses); raises TypeError when it is not one.

    >>> coerce([1, 2.5], tuple[float, ...]), coerce(3, float), coerce("a", Literal["a", "b"])
    ((1.0, 2.5), 3.0, 'a')
    """
    if tp is Any:
        return value
    try:
        return _run(tp, value)
    except (pydantic.ValidationError, TypeError, ValueError):
        raise TypeError(f"expected {type_name(tp)}") from None


def _type_at(cls: type, path: list[str]) -> Any:
    tp: Any = cls
    for name in path:
        types_ = field_types(tp) if dataclasses.is_dataclass(tp) else {}
        if name not in types_:
            return None
        tp = types_[name]
        inner = [a for a in typing.get_args(tp) if dataclasses.is_dataclass(a)]
        if inner and not dataclasses.is_dataclass(tp):
            tp = inner[0]
    return tp


def _set_value(key: str, text: str) -> Any:
    """A ``--set`` value read as YAML (bounded as :func:`parse_yaml`); text that is no
    YAML stays text (pydantic then names the type it should be)."""
    if not text.strip():
        return text
    if len(text) > MAX_YAML_BYTES:
        raise ConfigError(f"--set {key}: larger than {MAX_YAML_BYTES} bytes (the limit)")
    try:
        return _yaml_value(text)
    except _Refused as err:
        raise ConfigError(f"--set {key}: {_yaml_problem(err)}") from None
    except yaml.YAMLError:
        return text


def parse_sets(sets: Iterable[str], cls: type) -> dict[str, Any]:
    """``["key=value", "block.key=value", ...]`` -> ``{key: value, block: {key: value}}``;
    values read as YAML (``[1, 2]``, ``true``, ``0.5``) except for plain string fields,
    which take the text as it is.

    >>> from wander_env.scene_config import SceneConfig
    >>> parse_sets(["name=on", "camera.width=64"], SceneConfig)
    {'name': 'on', 'camera': {'width': 64}}
    """
    out: dict[str, Any] = {}
    for item in sets:
        key, sep, text = item.partition("=")
        path = [p.strip() for p in key.strip().split(".")]
        if not sep or not all(path):
            raise ConfigError(
                f"--set {item!r}: expected key=value or block.key=value; allowed keys: "
                f"{allowed_keys(cls)}"
            )
        if len(path) > MAX_KEY_PARTS:
            raise ConfigError(f"--set: a key of {len(path)} parts; at most {MAX_KEY_PARTS}")
        if _type_at(cls, path) is str:
            value: Any = text
        else:
            value = _set_value(key.strip(), text)
        node = out
        for i, name in enumerate(path[:-1]):
            nxt = node.setdefault(name, {})
            if not isinstance(nxt, dict):
                raise ConfigError(
                    f"--set {item!r}: {'.'.join(path[: i + 1])} is set to a value already"
                )
            node = nxt
        node[path[-1]] = value
    return out


class FieldsMapping:
    """A mixin for a dataclass of an env's settings: it unpacks as a mapping of its
    init fields, so the env is made from the block alone:
    ``gymnasium.make("wander/Wander-v0", **config.env)``.

    >>> from dataclasses import dataclass
    >>> @dataclass
    ... class Settings(FieldsMapping):
    ...     a: int = 1
    ...     b: str = "x"
    >>> dict(**Settings())
    {'a': 1, 'b': 'x'}
    """

    def keys(self) -> list[str]:
        return [f.name for f in dataclasses.fields(self) if f.init]  # type: ignore[arg-type]

    def __getitem__(self, name: str) -> Any:
        if name not in self.keys():
            raise KeyError(name)
        return getattr(self, name)


def check_fields(
    obj: Any,
    names: Iterable[str],
    *,
    positive: bool = False,
    minimum: float | None = None,
    integer: bool = False,
    allow_none: bool = False,
) -> None:
    """The shared ``__post_init__`` check: each field in ``names`` of dataclass ``obj`` is
    a finite number (an int when ``integer``; bools refused), > 0 when ``positive``,
    >= ``minimum`` when given (None passes when ``allow_none``). ValueError
    ``Class.field must be ..., got value``.

    >>> from dataclasses import dataclass
    >>> @dataclass
    ... class P:
    ...     n: int = 0
    ...     def __post_init__(self):
    ...         check_fields(self, ("n",), integer=True, minimum=1)
    >>> P(n=0)
    Traceback (most recent call last):
    ...
    ValueError: P.n must be an int >= 1, got 0
    """
    cls = type(obj).__name__
    for name in names:
        v = getattr(obj, name)
        if v is None and allow_none:
            continue
        kind = "an int" if integer else "a finite number"
        bound = " > 0" if positive else (f" >= {minimum:g}" if minimum is not None else "")
        if isinstance(v, bool):
            ok = False
        elif integer:
            ok = isinstance(v, (int, np.integer))
        else:
            ok = isinstance(v, (int, float)) and math.isfinite(v)
        if ok and positive:
            ok = v > 0
        if ok and minimum is not None:
            ok = v >= minimum
        if not ok:
            raise ValueError(f"{cls}.{name} must be {kind}{bound}, got {v!r}")


def _as_given(data: Any, err: dict[str, Any]) -> dict[str, Any]:
    """``err`` showing the value as it was given: a number spelt as text (``'1e-6'``),
    which :func:`_run` read as the float, is shown as that text."""
    given: Any = data
    for part in tuple(err["loc"])[1:]:  # after the list index of _run's box
        try:
            given = given[part]
        except (KeyError, IndexError, TypeError):
            return err
    if isinstance(given, str) and not isinstance(err.get("input"), str):
        return {**err, "input": given}
    return err


def validate(
    cls: type, values: Mapping[str, Any], base: Any = None, where: str | None = None
) -> Any:
    """A ``cls`` instance: ``base`` (or the defaults) with ``values`` applied; nested
    mappings set nested dataclass fields, changing only the keys they name (strict,
    unknown keys refused, numbers finite). ConfigError: each problem as ``field.path:
    what is wrong, got value`` (``; ``-separated), after ``where: `` when given.

    >>> from wander_env.scene_config import SceneConfig
    >>> try:
    ...     validate(SceneConfig, {"name": "a", "camera": {"width": 0}}, where="a.yaml")
    ... except ConfigError as e:
    ...     print(e)
    a.yaml: camera.width: input should be greater than or equal to 1, got 0
    """
    head = f"{where}: " if where else ""
    if not isinstance(values, Mapping):
        raise ConfigError(f"{head}expected a mapping of key: value, got {shown(values)}")
    bad = [k for k in values if not isinstance(k, str)]
    if bad:
        raise ConfigError(f"{head}keys must be strings, got {shown(bad)}")
    try:
        values = _expand(values)
    except ConfigError as e:
        raise ConfigError(f"{head}{e}") from None
    data = _merge(to_plain(base), values) if base is not None else _on_defaults(cls, values)
    try:
        return _run(cls, data, _FINITE)
    except pydantic.ValidationError as e:
        errors = [_as_given(data, err) for err in kept_errors(cls, e.errors())]
        raise ConfigError(head + "; ".join(error_messages(cls, errors))) from None
    except (ValueError, TypeError) as e:
        raise ConfigError(f"{head}{e}") from None


def check_annotated(obj: Any) -> None:
    """The ``__post_init__`` check of dataclass ``obj``'s constrained fields: each field
    annotated ``Annotated[..., pydantic.Field(...)]`` or ``Literal[...]`` is validated by
    pydantic (strict, finite numbers). ValueError ``field: what is wrong, got value``.

    >>> from wander_env.scene_config import GratingConfig  # its __post_init__ calls this
    >>> GratingConfig(distance_m=0)
    Traceback (most recent call last):
    ...
    ValueError: distance_m: input should be greater than 0, got 0
    """
    hints = typing.get_type_hints(type(obj), include_extras=True)
    for f in dataclasses.fields(obj):
        tp = hints.get(f.name)
        if not f.init or typing.get_origin(tp) not in (typing.Annotated, Literal):
            continue
        try:
            pydantic.TypeAdapter(tp, config=_FINITE).validate_python(getattr(obj, f.name))
        except pydantic.ValidationError as e:
            err = e.errors()[0]
            if err["type"] == "literal_error":
                text = f"expected {type_name(tp)}"
            elif err["type"] == "value_error" and "error" in (err.get("ctx") or {}):
                raise ValueError(f"{f.name}: {err['ctx']['error']}") from None
            else:
                text = err["msg"][:1].lower() + err["msg"][1:]
            raise ValueError(f"{f.name}: {text}, got {getattr(obj, f.name)!r}") from None
