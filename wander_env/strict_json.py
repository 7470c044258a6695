"""Strict JSON: every file parses with a strict parser.

A missing or undefined figure (NaN, ±inf) is ``null``, NumPy scalars and arrays become
plain numbers and lists (``json.loads(text, parse_constant=...)`` raising never fires).

Examples:
    >>> import math, numpy as np
    >>> to_strict_json({"a": math.nan, "b": np.float32(0.5), "c": [np.inf, 1]})
    {'a': None, 'b': 0.5, 'c': [None, 1]}
    >>> dumps_strict({"x": float("nan")})
    '{"x": null}'
    >>> import pathlib, tempfile
    >>> with tempfile.TemporaryDirectory() as d:
    ...     path = write_strict(pathlib.Path(d) / "a.json", {"x": math.inf})
    ...     path.read_text(), sorted(p.name for p in path.parent.iterdir())
    ('{"x": null}\\n', ['a.json'])
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path
from typing import Any

import numpy as np


def to_strict_json(value: Any) -> Any:
    """``value`` with every non-finite float replaced by ``None`` and NumPy values made
    plain (recursively through dicts, lists and tuples); other objects are left as they
    are (``json.dumps(default=str)`` turns them into text)."""
    if isinstance(value, dict):
        return {str(k): to_strict_json(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [to_strict_json(v) for v in value]
    if isinstance(value, np.ndarray):
        return to_strict_json(value.tolist())
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def dumps_strict(data: Any, **kwargs: Any) -> str:
    """``json.dumps`` of :func:`to_strict_json` ``(data)``; never writes NaN/Infinity."""
    kwargs.setdefault("default", str)
    return json.dumps(to_strict_json(data), allow_nan=False, **kwargs)


def write_strict(path: Path, data: Any, **kwargs: Any) -> Path:
    """Write :func:`dumps_strict` ``(data, **kwargs)`` and a newline to ``path``, whole or
    not at all: written beside it (``.NAME.tmp``), then renamed over it, so a full disk or
    a signal leaves the earlier file, or none, never a damaged one (the partial file is
    removed). Returns ``path``."""
    tmp = path.with_name(f".{path.name}.tmp")
    try:
        tmp.write_text(dumps_strict(data, **kwargs) + "\n")
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    return path
