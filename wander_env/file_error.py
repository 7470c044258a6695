"""The base of the errors that refuse a file: :class:`FileError` names the file, the field
and what is wrong. Dependency-free: the event library's :class:`EventFileError
<wander_env.events.checks.EventFileError>` and the reader of untrusted files'
:class:`UntrustedFileError <wander_env.untrusted.UntrustedFileError>` are its subclasses.

Examples:
    >>> from dataclasses import dataclass
    >>> @dataclass(eq=False, repr=False)
    ... class TableError(FileError):
    ...     def message(self) -> str:
    ...         return f"{self.path}: {self.problem}"
    >>> err = TableError("a.csv", "no header", "row 0")
    >>> str(err), err.field
    ('a.csv: no header', 'row 0')
"""

from __future__ import annotations

import os
from dataclasses import dataclass

__all__ = ["FileError"]


@dataclass(eq=False, repr=False)
class FileError(ValueError):
    """A file refused: ``path`` (kept as a ``str``), ``problem``, what is wrong, and
    ``field``, where in the file (None: the file as a whole). Its message is the
    subclass's :meth:`message`. A subclass, a dataclass too, adds its own fields."""

    path: str | os.PathLike
    problem: str
    field: str | None = None

    def __post_init__(self) -> None:
        self.path = str(self.path)
        super().__init__(self.message())

    def message(self) -> str:
        """The one line the error says."""
        raise NotImplementedError
