"""A click group whose subcommands are imported only when they are run or their help shown.

``driveid --help`` then lists the commands without importing scipy, numba or matplotlib; the
short help of each entry is stated here, next to where the command lives, and a test checks
it against the command's own docstring.
"""

from __future__ import annotations

import importlib
from typing import Any

import click

__all__ = ["LazyGroup"]


class LazyGroup(click.Group):
    """Group with subcommands given as ``name -> ("module:attribute", "short help")``.

    Parameters
    ----------
    *args, **kwargs
        As for :class:`click.Group`, plus ``lazy_commands`` (mapping of command name to
        ``(import path, one-line help)``).
    """

    def __init__(self, *args: Any, lazy_commands: dict[str, tuple[str, str]] | None = None,
                 **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.lazy_commands = dict(lazy_commands or {})
        #: Called with each command when it is imported (the CLI's option policy).
        self.on_load: Any = None

    def list_commands(self, ctx: click.Context) -> list[str]:
        """Names of eager and lazy subcommands, sorted."""
        return sorted(set(super().list_commands(ctx)) | set(self.lazy_commands))

    def get_command(self, ctx: click.Context, cmd_name: str) -> click.Command | None:
        """Import a lazy subcommand on first use."""
        if cmd_name in self.lazy_commands:
            target = self.lazy_commands[cmd_name][0]
            module, _, attribute = target.partition(":")
            command = getattr(importlib.import_module(module), attribute)
            self.add_command(command, cmd_name)
            del self.lazy_commands[cmd_name]
            if self.on_load is not None:
                self.on_load(command)
            return command
        return super().get_command(ctx, cmd_name)

    def format_commands(self, ctx: click.Context, formatter: click.HelpFormatter) -> None:
        """List commands with their short help without importing the lazy ones."""
        names = self.list_commands(ctx)
        limit = formatter.width - 6 - max((len(n) for n in names), default=0)
        rows = []
        for name in names:
            if name in self.lazy_commands:
                rows.append((name, self.lazy_commands[name][1]))
                continue
            command = super().get_command(ctx, name)
            if command is not None and not command.hidden:
                rows.append((name, command.get_short_help_str(limit=limit)))
        if rows:
            with formatter.section("Commands"):
                formatter.write_dl(rows)
