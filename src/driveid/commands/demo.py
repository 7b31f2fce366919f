"""``driveid demo``."""

from __future__ import annotations

from pathlib import Path

import click

from driveid.commands import clean_errors
from driveid.demo import run_demo

__all__ = ["demo_command"]


@click.command("demo")
@click.option("--out", "out", type=click.Path(file_okay=False, path_type=Path),
              default=Path("driveid-demo"), show_default=True,
              help="Parent folder; each run writes a new numbered run-NNN folder in it.")
@clean_errors
def demo_command(out):
    """Simulate a measured free decay, identify it, print truth vs estimate, save a figure."""
    run_demo(out, echo=click.echo)
