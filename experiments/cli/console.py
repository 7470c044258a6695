"""The CLI's one console, its progress bars and its tables (rich).

Library code never imports this module: a job takes a ``progress`` callback (or
nothing), and the command that runs it turns the calls into a bar here
(:func:`step_progress`). A table's column headers come from its rows' field names
(:func:`header`: ``peak_mib`` -> ``peak MiB``, ``mev_per_s`` -> ``Mev/s``); Markdown
(an experiment's ``summary.md``) is printed by :func:`print_markdown`, its tables as
tables that fit the terminal.

Examples:
    >>> from dataclasses import dataclass
    >>> @dataclass
    ... class Row:
    ...     name: str
    ...     ms: float | None
    >>> table_of("Speed", [Row("a", 1.234), Row("b", None)], {"name": "", "ms": ".2f"}).row_count
    2
"""

from __future__ import annotations

import sys
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from typing import Any

from rich.console import Console
from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn
from rich.table import Table

__all__ = [
    "console",
    "header",
    "print_markdown",
    "print_table",
    "progress_bars",
    "step_progress",
    "table_of",
]

# Tables keep their full column names when the output is a file or a pipe.
console = Console(width=None if sys.stdout.isatty() else 160)


def progress_bars() -> Progress:
    """Rich progress bars on :data:`console` (description, bar, done/total, time left)."""
    return Progress(
        TextColumn("[bold]{task.description}"),
        BarColumn(),
        TextColumn("{task.completed}/{task.total}"),
        TimeRemainingColumn(),
        console=console,
        transient=False,
    )


@contextmanager
def step_progress(description: str, total: float | None) -> Iterator[Callable[[int, int], None]]:
    """One bar; yields the ``progress(i, n)`` callback a job calls (``i`` of ``n`` done)."""
    with progress_bars() as bar:
        task = bar.add_task(description, total=total)
        yield lambda i, n: bar.update(task, completed=i, total=n)


# Words of field names written otherwise in a header (units keep their capitals).
HEADER_WORDS = {
    "per": "/",
    "pct": "%",
    "mev": "Mev",
    "mib": "MiB",
    "us": "µs",
    "rtf": "RTF",
    "aa16": "AA16",
    "l1": "L1",
}


def header(field: str) -> str:
    """A column header from a row's field name: words apart, units as written.

    >>> [header(f) for f in ("mev_per_s", "peak_mib", "events_diff_pct", "max_abs_dt_us")]
    ['Mev/s', 'peak MiB', 'events diff %', 'max abs dt µs']
    """
    return " ".join(HEADER_WORDS.get(w, w) for w in field.split("_")).replace(" / ", "/")


def table_of(title: str, rows: Sequence[Any], columns: dict[str, str]) -> Table:
    """A table of dataclass rows; ``columns`` maps field name -> format spec (None: –)."""
    table = Table(title=title)
    for name in columns:
        table.add_column(header(name), justify="right")
    for row in rows:
        table.add_row(
            *(
                "–" if (v := getattr(row, k)) is None else format(v, fmt)
                for k, fmt in columns.items()
            )
        )
    return table


def print_table(title: str, rows: Sequence[Any], columns: dict[str, str]) -> None:
    """Print dataclass rows on :data:`console` (:func:`table_of`)."""
    console.print(table_of(title, rows, columns))


def print_markdown(text: str) -> None:
    """Print Markdown on :data:`console`: headings, paragraphs and tables drawn by rich
    (a table's cells wrap inside their columns instead of its lines wrapping across the
    terminal)."""
    from rich.markdown import Markdown

    console.print(Markdown(text))
