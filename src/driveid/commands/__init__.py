"""Click commands, one module per subcommand family; :mod:`driveid.cli` assembles them.

Every command callback is wrapped in :func:`clean_errors`: errors the user can fix become
one ``error: ...`` line with exit status 2, and driveid's warnings (a repaired timestamp, a
resampled record, an implausible estimate) become one ``warning: ...`` line each on stderr,
never Python's warning format. :func:`driveid.commands._output.emit` adds the warnings
raised while reading to the estimate, so they also reach ``--json`` and ``--strict``.
"""

from __future__ import annotations

import contextvars
import functools
import warnings
from collections.abc import Callable
from typing import Any

import click

from driveid.errors import DriveIdError, DriveIdWarning

__all__ = ["clean_errors", "captured_warnings", "mark_printed"]

_CAPTURED: contextvars.ContextVar[list[list[Any]] | None] = contextvars.ContextVar(
    "driveid_captured_warnings", default=None)


def captured_warnings() -> list[str]:
    """Return the driveid warnings raised so far inside the running command.

    Returns
    -------
    list of str
        Messages in the order raised (empty outside a command).
    """
    captured = _CAPTURED.get()
    return [] if captured is None else [entry[0] for entry in captured]


def mark_printed(messages: list[str] | tuple[str, ...]) -> None:
    """Note that ``messages`` were printed already, so :func:`clean_errors` skips them.

    Parameters
    ----------
    messages : sequence of str
        Warning texts printed by the caller.
    """
    captured = _CAPTURED.get()
    if captured is not None:
        for entry in captured:
            if entry[0] in messages:
                entry[1] = True


def _echo_pending() -> None:
    for entry in _CAPTURED.get() or []:
        if not entry[1]:
            click.echo(f"warning: {_cli_text(entry[0])}", err=True)
            entry[1] = True


def _cli_text(text: str) -> str:
    from driveid.commands._output import cli_text  # CLI spellings, no reprs (issue 26)

    return cli_text(text)


def clean_errors(func: Callable[..., Any]) -> Callable[..., Any]:
    """Print errors as one ``error: ...`` line (exit 2) and warnings as ``warning: ...`` lines.

    Parameters
    ----------
    func : callable
        A click command callback.

    Returns
    -------
    callable
        The callback, turning :class:`~driveid.errors.DriveIdError`, file-system errors and
        click usage errors into one line without a traceback, and printing the
        :class:`~driveid.errors.DriveIdWarning` raised inside it once each on stderr.
    """

    @functools.wraps(func)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        captured: list[list[Any]] = []
        token = _CAPTURED.set(captured)
        previous = warnings.showwarning

        def show(message, category, filename, lineno, file=None, line=None):  # noqa: ANN001
            if issubclass(category, DriveIdWarning):
                if all(entry[0] != str(message) for entry in captured):
                    captured.append([str(message), False])
            else:
                previous(message, category, filename, lineno, file, line)

        try:
            with warnings.catch_warnings():
                warnings.simplefilter("always", DriveIdWarning)  # scoped to this command
                warnings.showwarning = show
                try:
                    return func(*args, **kwargs)
                finally:
                    _echo_pending()
        except (DriveIdError, FileNotFoundError, PermissionError, IsADirectoryError,
                NotADirectoryError) as exc:
            click.echo(f"error: {_cli_text(str(exc))}", err=True)
            raise SystemExit(2) from None
        except click.ClickException as exc:
            click.echo(f"error: {_cli_text(exc.format_message())}", err=True)
            raise SystemExit(2) from None
        finally:
            _CAPTURED.reset(token)

    return wrapper
