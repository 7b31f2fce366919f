"""The one-time notice when a simulation kernel compiles (and none when numba loads its cache)."""

import os
import subprocess
import sys

from driveid.sim._compile_notice import MESSAGE

# The smallest kernel function (compiles in well under a second), INFO logging on.
_RUN = ("import logging; logging.basicConfig(level=logging.INFO, format='%(message)s');"
        "from driveid.sim._free_decay_kernel import _propagate;"
        "_propagate(0.1, 1.0, 0.0, 0.1, 4.0)")


def _stderr(cache_dir):
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache_dir))
    done = subprocess.run([sys.executable, "-c", _RUN], env=env, capture_output=True,
                          text=True, timeout=300, check=True)
    return done.stderr


def test_notice_once_when_compiling_and_never_when_loading_the_cache(tmp_path):
    assert _stderr(tmp_path).splitlines().count(MESSAGE) == 1  # empty cache: compiles
    assert MESSAGE not in _stderr(tmp_path)  # the same cache: loads, says nothing


def test_command_line_prints_it_on_a_terminal_only(monkeypatch, capsys):
    import logging

    from driveid import cli

    logger = logging.getLogger("driveid.compile")
    for name in ("handlers", "level", "propagate"):  # restored after the test
        monkeypatch.setattr(logger, name, [] if name == "handlers" else getattr(logger, name))
    cli.cli.main(["--version"], standalone_mode=False)  # pytest's stderr is not a terminal
    assert logger.handlers == []
    monkeypatch.setattr(sys.stderr, "isatty", lambda: True)
    cli.cli.main(["--version"], standalone_mode=False)
    logger.info(MESSAGE)
    assert capsys.readouterr().err == f"note: {MESSAGE}\n"


def test_warmup_loads_or_compiles_every_engine():
    from click.testing import CliRunner

    from driveid.cli import cli
    from driveid.sim import _free_decay_kernel, _kernels, _smooth_kernels, lugre

    result = CliRunner().invoke(cli, ["warmup"])
    assert result.exit_code == 0 and "simulation kernels ready" in result.output, result.output
    # each engine now has a compiled (or cache-loaded) entry point
    assert _kernels.drive_kernel.signatures
    assert _free_decay_kernel.free_decay_batch_kernel.signatures
    for module in (_smooth_kernels, lugre):
        assert any(getattr(f, "signatures", None) for f in vars(module).values()), module
