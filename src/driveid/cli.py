"""The ``driveid`` command line: a thin layer over the public API.

Every subcommand calls one public function. Errors the user can fix (bad input, missing
files, refused overwrites) are printed as ``error: ...`` with exit status 2, never a traceback
(:func:`driveid.commands.clean_errors` on every command).
"""

from __future__ import annotations

import sys

import click

from driveid import __version__
from driveid.commands.demo import demo_command
from driveid.commands.drive import drive_command
from driveid.commands.friction import friction_map_command, idim_command
from driveid.commands.instantaneous import hilbert_command, wavelet_command
from driveid.commands.logdec import free_decay_command, logdec_command
from driveid.commands.pho import pho_group

__all__ = ["main", "cli"]


@click.group
@click.version_option(__version__, prog_name="driveid")
def cli() -> None:
    """driveid: model and identify friction, backlash and compliance in machine drives."""


@cli.group
def simulate() -> None:
    """Simulate systems and write record files."""


@cli.group
def identify() -> None:
    """Identify parameters from record files."""


simulate.add_command(free_decay_command)
simulate.add_command(drive_command)
for command in (logdec_command, hilbert_command, wavelet_command, friction_map_command,
                idim_command):
    identify.add_command(command)
cli.add_command(pho_group)
cli.add_command(demo_command)


def main() -> None:
    """Entry point of the ``driveid`` script."""
    cli(prog_name="driveid")


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
