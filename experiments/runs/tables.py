"""Tidy CSV tables: a row per trial (or per seed), a column per figure, as a study or a
job writes them and reads them back.

Floats are written with ``repr`` (exact), NaN as an empty cell, bools as ``true``/``false``;
read back, every cell takes its type again (int, float, bool, str), except the
:data:`TEXT_COLUMNS`, which hold names. Artifact keys (``_*``) are never columns.
"""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

__all__ = ["TEXT_COLUMNS", "Row", "Scalar", "columns_of", "parse_csv", "read_csv", "write_csv"]

Scalar = int | float | str | bool
Row = dict[str, Scalar]


def _cell(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):  # NumPy's float64 too, written as the float it is
        return "" if math.isnan(v) else repr(float(v))
    return str(v)


def _parse_cell(text: str) -> Scalar:
    if text == "":
        return math.nan
    if text in ("true", "false"):
        return text == "true"
    for conv in (int, float):
        try:
            return conv(text)
        except ValueError:
            continue
    return text


def columns_of(rows: Sequence[Mapping[str, Any]]) -> list[str]:
    """Union of the rows' keys (artifact keys ``_*`` left out), in order of first appearance."""
    return list(dict.fromkeys(k for r in rows for k in r if not k.startswith("_")))


def write_csv(
    rows: Sequence[Mapping[str, Any]], path: Path, columns: Sequence[str] | None = None
) -> Path:
    """Tidy CSV; floats as ``repr`` (exact), NaN as an empty cell, bools as true/false.

    The columns are ``columns`` in that order (the header even without rows; a row's
    missing key is an empty cell, a key outside them a ValueError), else
    :func:`columns_of` the rows.
    """
    cols = columns_of(rows) if columns is None else list(columns)
    extra = [k for k in columns_of(rows) if k not in cols]
    if extra:
        raise ValueError(f"row keys {extra} are not among the columns {cols}")
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(cols)
    for r in rows:
        w.writerow([_cell(r.get(c, math.nan)) for c in cols])
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(buf.getvalue())
    return path


#: Columns that hold names, never numbers: a trial id is 16 hex digits, which can read as
#: an int (``8462951001639847``) or a float (``12e4567890123456``).
TEXT_COLUMNS = ("trial_id",)


def read_csv(path: Path) -> list[Row]:
    """Rows of :func:`write_csv` with their types back (:func:`parse_csv`)."""
    with Path(path).open(newline="") as f:
        return parse_csv(f)


def parse_csv(lines: Iterable[str]) -> list[Row]:
    """Rows of :func:`write_csv`'s text ``lines`` (a file opened with ``newline=""``, or
    ``io.StringIO(text, newline="")``) with their types back (int, float, bool, str; the
    :data:`TEXT_COLUMNS` as written).

    >>> parse_csv(["trial_id,x,ok", "12e4,2.5,true"])
    [{'trial_id': '12e4', 'x': 2.5, 'ok': True}]
    """
    return [
        {k: v if k in TEXT_COLUMNS else _parse_cell(v) for k, v in rec.items()}
        for rec in csv.DictReader(lines)
    ]
