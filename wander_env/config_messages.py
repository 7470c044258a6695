"""The messages of the config system (:mod:`wander_env.config`): a type's readable name,
a dataclass's keys, and one pydantic validation error as ``field.path: what is wrong,
got value``, the path walked through nested dataclasses, tuples, lists and tagged
unions (``Annotated[A | B, pydantic.Field(discriminator="kind")]``, whose tag pydantic
puts in the error's location).

Examples:
    >>> type_name(tuple[float, float]), type_name(int | None)
    ('list [float, float]', 'int or null')
"""

from __future__ import annotations

import dataclasses
import re
import types
import typing
from collections.abc import Iterable, Mapping
from typing import Any, Literal

__all__ = [
    "MAX_MESSAGES",
    "SHOWN_CHARS",
    "allowed_keys",
    "error_message",
    "error_messages",
    "field_types",
    "kept_errors",
    "shown",
    "type_name",
]


def type_name(tp: Any) -> str:
    """A readable name of a type for messages (``list [float, float]``, ``one of 'a'``)."""
    origin = typing.get_origin(tp)
    if origin is typing.Annotated:
        return type_name(typing.get_args(tp)[0])
    if origin is Literal:
        return "one of " + ", ".join(repr(a) for a in typing.get_args(tp))
    if origin in (typing.Union, types.UnionType):
        return " or ".join(type_name(a) for a in typing.get_args(tp))
    if origin is tuple:
        args = typing.get_args(tp)
        if len(args) == 2 and args[1] is Ellipsis:
            return f"list of {type_name(args[0])}"
        return "list [" + ", ".join(type_name(a) for a in args) + "]"
    if tp is type(None):
        return "null"
    return getattr(tp, "__name__", str(tp))


def field_types(cls: type) -> dict[str, Any]:
    """The init fields of dataclass ``cls`` and their (resolved) types."""
    hints = typing.get_type_hints(cls)
    return {f.name: hints[f.name] for f in dataclasses.fields(cls) if f.init}


def allowed_keys(cls: type) -> str:
    """``key (type), ...`` for error messages and ``--help``."""
    return ", ".join(f"{k} ({type_name(t)})" for k, t in field_types(cls).items())


def _field_locs(cls: type, loc: tuple[Any, ...]) -> tuple[Any, ...]:
    """``loc`` without pydantic's union-member tags (``("soms", "SOMSParams", "alpha")``
    → ``("soms", "alpha")``), so that it is a path of fields and indices."""
    out: list[Any] = []
    owner: Any = cls
    tp: Any = None
    for part in loc:
        if isinstance(part, int):
            out.append(part)
            continue
        types_ = field_types(owner) if dataclasses.is_dataclass(owner) else {}
        if part in types_:
            out.append(part)
            tp = types_[part]
            inner = [a for a in (typing.get_args(tp) or (tp,)) if dataclasses.is_dataclass(a)]
            owner = inner[0] if inner else None
        elif tp is not None and typing.get_origin(tp) in (typing.Union, types.UnionType):
            members = [a for a in typing.get_args(tp) if getattr(a, "__name__", None) == part]
            owner = members[0] if members else None  # the tag of the member tried
            tp = None
        else:
            out.append(part)
    return tuple(out)


#: pydantic's errors for a value of the right type that its field still refuses.
_SPECIFIC_KINDS = frozenset(
    (
        "value_error",
        "greater_than",
        "greater_than_equal",
        "less_than",
        "less_than_equal",
        "finite_number",
    )
)


def kept_errors(cls: type, errors: list[Any]) -> list[Any]:
    """Errors of a union field: the one from inside a member where there is one (a
    nested mapping with a bad key, a value of a member's type out of its range, or one a
    member's own check refused, says what is wrong there, not that the field is not one
    of the other members)."""
    locs = [_field_locs(cls, tuple(e["loc"])) for e in errors]
    specific = {loc for e, loc in zip(errors, locs, strict=True) if e["type"] in _SPECIFIC_KINDS}
    return [
        e
        for e, loc in zip(errors, locs, strict=True)
        if not any(len(o) > len(loc) and o[: len(loc)] == loc for o in locs)
        and (e["type"] in _SPECIFIC_KINDS or loc not in specific)
    ]


#: The most characters of a value (a file's contents, a device's reply) a message quotes.
SHOWN_CHARS = 200
#: The most problems one message lists (then "and N more").
MAX_MESSAGES = 10


def shown(value: Any) -> str:
    """``repr(value)``, cut to :data:`SHOWN_CHARS` characters (a message stays a short
    line however much a file or a device sent).

    >>> shown("x" * 1000) == repr("x" * 196)[:197] + "..."
    True
    >>> len(shown("x" * 1000))
    200
    """
    text = repr(value)
    return text if len(text) <= SHOWN_CHARS else text[: SHOWN_CHARS - 3] + "..."


def _lower(msg: str) -> str:
    return msg[:1].lower() + msg[1:]


# ----------------------------------------------------------------------------------------
# Path-first messages

_LEADING_FIELD = re.compile(r"^(?:[A-Z]\w*\.)?(\w+)((?:\[\d+\])*)(:?) ")  # after a class name


def _bare(tp: Any) -> Any:
    """``tp`` without ``| None``."""
    if typing.get_origin(tp) in (typing.Union, types.UnionType):
        args = [a for a in typing.get_args(tp) if a is not type(None)]
        if len(args) == 1:
            return args[0]
    return tp


def _members(tp: Any) -> list[Any]:
    """The dataclasses of a union of dataclasses (a tagged union), else []."""
    if typing.get_origin(tp) not in (typing.Union, types.UnionType):
        return []
    args = [a for a in typing.get_args(tp) if a is not type(None)]
    return args if len(args) > 1 and all(dataclasses.is_dataclass(a) for a in args) else []


def _tags(member: Any, key: str | None = None) -> set[Any]:
    """The values of ``member``'s Literal fields (field ``key`` only, when given): a
    tagged union's tag is one of them."""
    return {
        v
        for name, t in field_types(member).items()
        if typing.get_origin(t) is Literal and key in (None, name)
        for v in typing.get_args(t)
    }


def _walk(cls: Any, loc: Iterable[Any]) -> tuple[str, Any]:
    """(the path text, the type there) of a pydantic error location under ``cls``; a
    tagged union's tag (pydantic puts it in the location) leaves the path as it is."""
    path, tp = "", cls
    for part in loc:
        base = _bare(tp)
        members = _members(base)
        if members and isinstance(part, str):
            # the tag: a Literal field's value, or the class's name (a callable
            # discriminator's Tag, as agents.attention.AgentParams.soms)
            tp = next((m for m in members if part in _tags(m) or m.__name__ == part), None)
            continue
        if typing.get_origin(base) in (typing.Union, types.UnionType) and isinstance(part, str):
            # pydantic names the member it tried: a class's name, or e.g. "literal['a','b']"
            named = [a for a in typing.get_args(base) if getattr(a, "__name__", None) == part]
            tp = named[0] if named else None
            continue
        if isinstance(part, int):
            path += f"[{part}]"
            args = typing.get_args(base) if typing.get_origin(base) is tuple else ()
            if len(args) == 2 and args[1] is Ellipsis:
                tp = args[0]
            else:
                tp = args[part] if part < len(args) else None
            continue
        path = f"{path}.{part}" if path else str(part)
        tp = field_types(base).get(part) if dataclasses.is_dataclass(base) else None
    return path, tp


def _at(path: str, text: str) -> str:
    return f"{path}: {text}" if path else text


def error_message(cls: Any, err: Mapping[str, Any]) -> str:
    """One pydantic error as ``path: what is wrong, got value``."""
    loc = tuple(err["loc"])[1:]  # drop the list index of _run's box
    kind, ctx = err["type"], err.get("ctx") or {}
    if kind == "unexpected_keyword_argument":
        path, tp = _walk(cls, loc[:-1])
        owner = _bare(tp)
        name = getattr(owner, "__name__", "this block")
        allowed = allowed_keys(owner) if dataclasses.is_dataclass(owner) else "none"
        return _at(path, f"unknown key {shown(loc[-1])} for {name}; allowed keys: {allowed}")
    if kind == "missing" and loc and isinstance(loc[-1], int):  # a list too short
        path, tp = _walk(cls, loc[:-1])
        return _at(path, f"expected {type_name(_bare(tp))}, got {shown(err['input'])}")
    path, tp = _walk(cls, loc)
    whole = _walk(cls, loc[:-1])[1] if loc else None
    if (
        isinstance(loc[-1] if loc else None, str)
        and typing.get_origin(_bare(whole)) in (typing.Union, types.UnionType)
        and not _members(_bare(whole))
        and kind not in _SPECIFIC_KINDS
    ):  # a value that is none of a plain union's members: name the union
        return _at(path, f"expected {type_name(_bare(whole))}, got {shown(err['input'])}")
    if kind == "missing":
        return _at(path, "required")
    if kind in ("union_tag_invalid", "union_tag_not_found"):
        key = str(ctx.get("discriminator", "kind")).strip("'")
        tags = [t for m in _members(_bare(tp)) for t in sorted(_tags(m, key))]
        allowed = ", ".join(repr(t) for t in tags)
        if "tag" in ctx:
            text = f"expected one of {allowed}, got {ctx['tag']!r}"
        else:
            text = f"required (one of {allowed})"
        return _at(f"{path}.{key}" if path else key, text)
    if kind == "value_error":  # a dataclass's own check (__post_init__): name its field
        text = str(ctx["error"]) if "error" in ctx else err["msg"]
        owner = _bare(tp)
        m = _LEADING_FIELD.match(text)
        if m and dataclasses.is_dataclass(owner) and m.group(1) in field_types(owner):
            sub = f"{m.group(1)}{m.group(2)}"
            path = f"{path}.{sub}" if path else sub
            if m.group(3):  # "field: text" -> "path.field: text"
                text = text[m.end() :]
        return _at(path, text)
    if kind == "literal_error" or (kind.endswith("_type") and tp is not None):
        return _at(path, f"expected {type_name(_bare(tp))}, got {shown(err['input'])}")
    return _at(path, f"{_lower(err['msg'])}, got {shown(err['input'])}")


def error_messages(cls: Any, errors: Iterable[Mapping[str, Any]]) -> list[str]:
    """The messages of pydantic ``errors`` (:func:`error_message`), each once: the unknown
    keys of one block in one message (``unknown keys 'a', 'b' for X; allowed keys: ...``,
    the allowed keys said once), at most :data:`MAX_MESSAGES` of them, then ``and N more
    problems``."""
    unknown: dict[tuple[Any, ...], tuple[int, list[str]]] = {}  # block: (message, keys)
    msgs: list[str] = []
    for err in errors:
        loc = tuple(err["loc"])
        if err["type"] != "unexpected_keyword_argument":
            msgs.append(error_message(cls, err))
        elif loc[:-1] in unknown:
            unknown[loc[:-1]][1].append(shown(loc[-1]))
        else:
            unknown[loc[:-1]] = (len(msgs), [shown(loc[-1])])
            msgs.append(error_message(cls, err))
    for index, keys in unknown.values():
        if len(keys) > 1:
            named = ", ".join(keys[:MAX_MESSAGES])
            if len(keys) > MAX_MESSAGES:
                named += f" and {len(keys) - MAX_MESSAGES} more"
            old, new = f"unknown key {keys[0]} ", f"unknown keys {named} "
            msgs[index] = msgs[index].replace(old, new, 1)
    msgs = list(dict.fromkeys(msgs))
    if len(msgs) > MAX_MESSAGES:
        msgs = [*msgs[:MAX_MESSAGES], f"and {len(msgs) - MAX_MESSAGES} more problems"]
    return msgs
