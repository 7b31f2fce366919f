"""The command line loads subcommands lazily: --help is fast and every entry resolves."""

import subprocess
import sys

import click
import pytest

from driveid import cli as cli_module


def _entries():
    for table in (cli_module._TOP, cli_module._SIMULATE, cli_module._IDENTIFY):
        yield from table.items()


@pytest.mark.parametrize(("name", "entry"), list(_entries()), ids=lambda v: str(v)[:30])
def test_every_lazy_entry_is_a_click_command_with_that_name(name, entry):
    import importlib

    module, _, attribute = entry[0].partition(":")
    command = getattr(importlib.import_module(module), attribute)
    assert isinstance(command, click.Command)
    assert command.name == name
    short = entry[1]
    assert short.endswith(".") and len(short) <= 70  # shown in one --help row


@pytest.mark.parametrize("argv", [["--help"], ["identify", "logdec", "--help"],
                                  ["pho", "run", "--help"], ["simulate", "free-decay", "--help"]])
def test_help_imports_no_heavy_module(argv):
    code = ("import sys; from driveid.cli import cli; "
            f"cli.main({argv!r}, standalone_mode=False); "
            "heavy = [m for m in ('numba', 'scipy.signal', 'scipy.optimize', 'matplotlib', "
            "'pandas') if m in sys.modules]; print('HEAVY', heavy)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout
    assert "HEAVY []" in out


def test_lazy_commands_get_the_option_policy():
    from click.testing import CliRunner

    # --noise nan must be refused on a lazily loaded command (issue 12's policy)
    result = CliRunner().invoke(cli_module.cli, ["simulate", "free-decay", "--noise", "nan",
                                                 "--out", "x.csv"])
    assert result.exit_code == 2
