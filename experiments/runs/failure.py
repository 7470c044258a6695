"""How a long command ends badly: the write failure in an error, one line, an exit code.

A signal ends a command with ``128 + signal`` (130 SIGINT, 143 SIGTERM, 129 SIGHUP), a
result file that cannot be written (disk full, read-only or unwritable folder) with 1;
:meth:`experiments.runs.folder.RunFolder.record_failure` says it in the folder first.

Examples:
    >>> import errno
    >>> err = OSError(errno.ENOSPC, "No space left on device", "runs/x/metrics.json")
    >>> describe(RuntimeError("writing failed")), exit_code(err)
    ('RuntimeError: writing failed', 1)
    >>> describe(err)
    'cannot write runs/x/metrics.json: No space left on device'
"""

from __future__ import annotations

import errno
import os

from experiments.runs.signals import SignalExit

#: errno values that mean "the result cannot be written here".
WRITE_ERRNOS = frozenset(
    getattr(errno, n) for n in ("ENOSPC", "EDQUOT", "EACCES", "EPERM", "EROFS") if hasattr(errno, n)
)


def write_failure(err: BaseException) -> OSError | None:
    """The write failure (disk full, not writable) in ``err`` or its causes, if any."""
    seen: set[int] = set()
    e: BaseException | None = err
    while e is not None and id(e) not in seen:
        seen.add(id(e))
        if isinstance(e, OSError) and (
            e.errno in WRITE_ERRNOS
            or type(e).__name__ == "OutputError"
            or "No space left on device" in str(e)
        ):
            return e
        e = e.__cause__ or e.__context__
    return None


def describe(err: BaseException) -> str:
    """One line for a failure of a long command."""
    if isinstance(err, SignalExit):
        return str(err)
    failed = write_failure(err)
    if failed is not None:
        where = failed.filename or getattr(err, "filename", None) or "the output folder"
        what = failed.strerror or os.strerror(failed.errno or errno.EIO)
        return f"cannot write {where}: {what}"
    return " ".join(f"{type(err).__name__}: {err}".split())


def exit_code(err: BaseException) -> int:
    """128 + signal for a :class:`SignalExit`, 130 for a plain ``KeyboardInterrupt``, else 1."""
    if isinstance(err, SignalExit):
        return err.exit_code
    return 130 if isinstance(err, KeyboardInterrupt) else 1


__all__ = ["WRITE_ERRNOS", "describe", "exit_code", "write_failure"]
