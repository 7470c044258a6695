"""One line per bad command line: the ``wander`` app's group class.

Click's usage errors (a bad option value, a missing argument, an unknown option)
normally print the usage, a hint and a boxed message; :class:`OneLineErrors` prints one
line on stderr instead — ``wander run: Invalid value for '--scene': ...`` — and exits
with the error's code (2 for usage errors), never a traceback. Options are validated
by their callbacks (:mod:`experiments.cli.options`) while the command line is parsed, so
the error comes before any work (or progress bar) starts.
"""

from __future__ import annotations

import functools
import inspect
import sys
from collections.abc import Callable
from typing import Any, TypeVar

import typer
from typer.core import TyperGroup

from experiments.runs.failure import describe, write_failure
from experiments.runs.folder import CurrentRun
from experiments.runs.signals import Received, SignalExit, handle_signals

__all__ = ["OneLineErrors", "current_run", "fail", "long_command", "one_line"]

#: The key of a long command's :class:`CurrentRun` in its Click context's ``meta``.
CURRENT_RUN = "wander.current_run"


def one_line(err: typer.TyperException) -> str:
    """``<command path>: <message>`` on a single line."""
    ctx = getattr(err, "ctx", None)
    where = ctx.command_path if ctx is not None else "wander"
    text = " ".join(err.format_message().split())
    return f"{where}: {text}"


def fail(message: object, where: typer.Context | str = "wander") -> typer.Exit:
    """One line on stderr (``<command path>: error: <message>``, the message's white space
    folded) and the exit (code 2) for the command to raise; ``where`` is the command's
    context (its path names the command) or the command's name."""
    if not isinstance(where, str):  # the context Typer passes (a base of typer.Context's)
        where = where.command_path
    typer.echo(f"{where}: error: {' '.join(str(message).split())}", err=True)
    return typer.Exit(code=2)


_F = TypeVar("_F", bound=Callable[..., Any])


def current_run(ctx: typer.Context) -> CurrentRun | None:
    """The :class:`CurrentRun` of the long command of context ``ctx`` (``None`` for a
    command that is none): a run folder named with it registers itself there."""
    return ctx.meta.get(CURRENT_RUN)


def long_command(name: str) -> Callable[[_F], _F]:
    """Decorate a Typer command: signals handled (:func:`experiments.runs.signals.handle_signals`),
    failures as one line and an exit code (:mod:`experiments.runs.failure`), said in the
    run folder the command named (:func:`current_run`, whether ``--out`` gave it or not:
    :meth:`~experiments.runs.folder.RunFolder.record_failure`). A signal that came ends the
    command with its code even when foreign code turned it into another error or dropped it.
    The command's :class:`typer.Context` parameter (Typer passes it) holds the
    :class:`CurrentRun`; a command without one (called directly) names no folder there.
    """

    def deco(fn: _F) -> _F:
        sig = inspect.signature(fn, eval_str=True)
        contexts = [k for k, p in sig.parameters.items() if p.annotation is typer.Context]

        @functools.wraps(fn)
        def wrapper(*args: Any, **kwargs: Any) -> Any:
            current = CurrentRun()
            given = sig.bind_partial(*args, **kwargs).arguments
            for key in contexts:
                if given.get(key) is not None:
                    given[key].meta[CURRENT_RUN] = current
            received = Received()
            try:
                with handle_signals() as received:
                    result = fn(*args, **kwargs)
                    dropped = received.first()
                    if dropped is not None:  # raised where foreign code dropped it
                        raise dropped
                    return result
            except typer.Exit:  # the command said what happened (the rig: its signal line)
                raise
            except BaseException as err:
                stop = err if isinstance(err, SignalExit) else received.first()
                if stop is not None:
                    if stop is not err:  # foreign code turned the raised signal into `err`
                        stop.__cause__ = err
                    folder = current.folder
                    if folder is not None:
                        folder.record_failure(stop)
                    where = f"; {str(folder.final)!r} holds what was recorded" if folder else ""
                    typer.echo(f"{name}: {stop}{where}", err=True)
                    raise typer.Exit(stop.exit_code) from None
                if not isinstance(err, OSError) or write_failure(err) is None:
                    raise
                folder = current.folder
                if folder is not None:
                    folder.record_failure(err)
                marked = folder is not None and folder.incomplete()
                mark = f"; {str(folder.final)!r} is marked INCOMPLETE" if marked else ""
                typer.echo(f"{name}: {describe(err)}{mark}", err=True)
                raise typer.Exit(1) from None

        return wrapper  # type: ignore[return-value]

    return deco


class OneLineErrors(TyperGroup):
    """A :class:`typer.core.TyperGroup` whose usage errors are one line on stderr."""

    def main(self, *args: Any, standalone_mode: bool = True, **kwargs: Any) -> Any:
        if not standalone_mode:
            return super().main(*args, standalone_mode=False, **kwargs)
        try:
            rv = super().main(*args, standalone_mode=False, **kwargs)
        except typer.TyperException as err:  # Typer's Click errors derive from it
            if type(err).__name__ == "NoArgsIsHelpError":  # the help (no public class: told
                err.show()  # by its name, as Typer's own rich_utils does)
            else:
                typer.echo(one_line(err), err=True)
            sys.exit(err.exit_code)
        except typer.Abort:
            typer.echo("Aborted!", err=True)
            sys.exit(1)
        sys.exit(rv if isinstance(rv, int) else 0)
