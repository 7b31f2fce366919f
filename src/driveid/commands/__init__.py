"""Click commands, one module per subcommand family; :mod:`driveid.cli` assembles them."""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Any

import click

from driveid.errors import DriveIdError

__all__ = ["clean_errors"]


def clean_errors(func: Callable[..., Any]) -> Callable[..., Any]:
    """Print errors the user can fix as one ``error: ...`` line with exit status 2.

    Parameters
    ----------
    func : callable
        A click command callback.

    Returns
    -------
    callable
        The callback, turning :class:`~driveid.errors.DriveIdError` and file-system errors
        into a message without a traceback.
    """

    @functools.wraps(func)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        try:
            return func(*args, **kwargs)
        except (DriveIdError, FileNotFoundError, PermissionError, IsADirectoryError) as exc:
            click.echo(f"error: {exc}", err=True)
            raise SystemExit(2) from None

    return wrapper
