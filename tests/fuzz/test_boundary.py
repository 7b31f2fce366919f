"""The CLI error boundary: outcome classes, --debug, warnings, Ctrl-C, real subprocesses."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
import warnings
from pathlib import Path

import click
import numpy as np
import pytest
from click.testing import CliRunner

from driveid.cli import EXIT_INTERNAL, EXIT_INTERRUPTED, cli
from driveid.errors import ParameterError, RecordWarning

DRIVEID = Path(sys.executable).with_name("driveid")


def _boom(kind: str) -> None:
    if kind == "bug":
        raise ZeroDivisionError("division by zero in a helper")
    if kind == "key":
        raise KeyError("missing")
    if kind == "ctrl-c":
        raise KeyboardInterrupt
    if kind == "driveid":
        raise ParameterError("x must be > 0; got -1; pass a positive x")
    if kind == "oserror":
        open("/nonexistent-folder/x.csv")  # noqa: SIM115
    if kind == "memory":
        raise MemoryError
    if kind == "usage":
        raise click.UsageError("give --a or --b, not both")
    if kind == "numpy":
        np.log(np.zeros(3))  # RuntimeWarning: divide by zero
        np.float64(1e308) * 10  # overflow
        click.echo("result 1.0")
    if kind == "record-warning":
        warnings.warn("two samples repaired", RecordWarning, stacklevel=1)
        warnings.warn("two samples repaired", RecordWarning, stacklevel=1)
        warnings.warn("old API", DeprecationWarning, stacklevel=1)
        click.echo("result 2.0")
    if kind == "eof":
        raise EOFError


@pytest.fixture
def boom_cli():
    @click.command("boom")
    @click.argument("kind")
    def boom(kind):
        """Fail in the requested way."""
        _boom(kind)

    cli.add_command(boom)
    yield cli
    cli.commands.pop("boom")


@pytest.mark.parametrize("kind, code, start", [
    ("bug", EXIT_INTERNAL, "error: internal error (ZeroDivisionError: division by zero"),
    ("key", EXIT_INTERNAL, "error: internal error (KeyError:"),
    ("ctrl-c", EXIT_INTERRUPTED, "error: interrupted (Ctrl-C)"),
    ("driveid", 2, "error: x must be > 0; got -1"),
    ("oserror", 2, "error: No such file or directory: /nonexistent-folder/x.csv"),
    ("memory", 2, "error: out of memory"),
    ("usage", 2, "error: give --a or --b, not both"),
    ("eof", 2, "error: a file could not be read"),
])
def test_every_exception_is_one_line_and_a_status(boom_cli, kind, code, start):
    res = CliRunner().invoke(boom_cli, ["boom", kind])
    assert res.exit_code == code, res.stderr
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(start), res.stderr
    assert "Traceback" not in res.stderr
    if code == EXIT_INTERNAL:
        assert "this is a bug" in lines[0] and "--debug" in lines[0]


def test_debug_shows_the_traceback(boom_cli):
    res = CliRunner().invoke(boom_cli, ["--debug", "boom", "bug"])
    assert res.exit_code == EXIT_INTERNAL
    assert "Traceback" in res.stderr and "ZeroDivisionError" in res.stderr
    assert res.stderr.strip().splitlines()[-1].startswith("error: internal error")


def test_numpy_warnings_become_one_plain_line_each(boom_cli):
    res = CliRunner().invoke(boom_cli, ["boom", "numpy"])
    assert res.exit_code == 0 and res.stdout == "result 1.0\n"
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 2 and all(line.startswith("warning: numerical trouble")
                                   for line in lines), res.stderr
    assert "np.log" not in res.stderr and ".py:" not in res.stderr  # no source lines


def test_record_warnings_are_plain_deduplicated_and_deprecations_dropped(boom_cli):
    res = CliRunner().invoke(boom_cli, ["boom", "record-warning"])
    assert res.exit_code == 0
    assert res.stderr == "warning: two samples repaired\n"


def test_warning_capture_is_scoped_to_the_command(boom_cli):
    before = list(warnings.filters)
    CliRunner().invoke(boom_cli, ["boom", "numpy"])
    assert warnings.filters == before


@pytest.mark.parametrize("args, code", [
    ([], 2), (["--help"], 0), (["--version"], 0), (["nope"], 2), (["identify", "nope"], 2),
    (["identify", "logdec"], 2), (["simulate", "free-decay"], 2),
    (["identify", "logdec", "--no-such-option", "x"], 2),
])
def test_usage_errors(args, code):
    res = CliRunner().invoke(cli, args)
    assert res.exit_code == code, res.stderr
    assert "Traceback" not in res.stderr
    if code == 2 and args:
        errors = [line for line in res.stderr.splitlines() if line.startswith("error:")]
        assert len(errors) == 1 and len(res.stderr.strip().splitlines()) == 1, res.stderr


# ---- real processes -----------------------------------------------------------------------

needs_script = pytest.mark.skipif(not DRIVEID.exists(), reason="driveid script not installed")


@needs_script
@pytest.mark.parametrize("args, code, start", [
    (["identify", "logdec", "/nonexistent/a.csv"], 2, "error:"),
    (["simulate", "free-decay", "--out", "x.csv", "--noise", "nan"], 2, "error:"),
    (["simulate", "free-decay", "--out", "x.csv", "--duration", "1e9"], 2, "error:"),
])
def test_real_process_errors(tmp_path, args, code, start):
    res = subprocess.run([str(DRIVEID), *args], cwd=tmp_path, capture_output=True, text=True,
                         timeout=120)
    assert res.returncode == code, res.stderr
    assert res.stderr.startswith(start) and len(res.stderr.strip().splitlines()) == 1
    assert list(tmp_path.iterdir()) == []


@needs_script
def test_real_process_internal_error_exit_70(tmp_path):
    code = ("import click, driveid.cli as c\n"
            "@click.command('boom')\n"
            "def boom():\n    raise ZeroDivisionError('x')\n"
            "c.cli.add_command(boom)\nc.main()\n")
    res = subprocess.run([sys.executable, "-c", code, "boom"], cwd=tmp_path,
                         capture_output=True, text=True, timeout=120)
    assert res.returncode == EXIT_INTERNAL
    assert res.stderr.startswith("error: internal error (ZeroDivisionError: x)")
    assert "Traceback" not in res.stderr


def _interrupt_after_import(args, module, tmp_path):
    """Send Ctrl-C as soon as the child has imported ``module`` (None: its first import).

    A fixed delay lands in a different phase when the machine is loaded (parallel test
    workers, a kernel compiling beside it); the child's ``-X importtime`` lines on stderr say
    where it is instead. They are dropped from the returned stderr.
    """
    env = {**os.environ, "PYTHONPROFILEIMPORTTIME": "1"}
    proc = subprocess.Popen([str(DRIVEID), *args], cwd=tmp_path, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=env)
    head = []
    for line in proc.stderr:  # EOF first if the child ends before the import
        head.append(line)
        if module is None or line.rsplit("|", 1)[-1].strip() == module:
            proc.send_signal(signal.SIGINT)
            break
    _, err = proc.communicate(timeout=120)
    lines = head + err.splitlines(keepends=True)
    return proc.returncode, "".join(x for x in lines if not x.startswith("import time:"))


@needs_script
@pytest.mark.parametrize("module, duration", [
    pytest.param(None, "1", marks=pytest.mark.xfail(strict=False, reason=(
        "at the interpreter's first import the signal arrives before driveid/__init__.py "
        "installs its handler: Python dies of it, or prints a traceback in its own start-up "
        "and carries on; nothing in the package can catch that"))),
    ("driveid", "600"), ("driveid.sim", "600")], ids=["interpreter-start", "imports", "early"])
def test_ctrl_c_during_start_up_is_one_line_exit_130(tmp_path, module, duration):
    # "driveid": the package's start-up handler is installed, driveid.cli still imports;
    # "driveid.sim": the command has begun its work. At the first import the signal is sent
    # before driveid loads whatever the duration: a short run if the interpreter swallows it.
    code, err = _interrupt_after_import(["simulate", "free-decay", "--out", "x.csv",
                                         "--duration", duration, "--rate", "20000"],
                                        module, tmp_path)
    if code == 0:  # pragma: no cover - the machine finished first
        pytest.skip("the command ended normally: the signal came after its end or was lost "
                    "in the interpreter's start-up")
    assert code == EXIT_INTERRUPTED, err
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1, err
    assert err.startswith("error: interrupted")
    assert not [p for p in tmp_path.iterdir() if p.name != "x.csv" or p.stat().st_size == 0]


@needs_script
def test_ctrl_c_inside_the_work_leaves_no_partial_file(tmp_path):
    # 15 million rows: the signal goes as soon as the writer's temporary file appears, so it
    # arrives while writing (a fixed delay landed anywhere on a loaded machine, and cost 6 s)
    proc = subprocess.Popen([str(DRIVEID), "simulate", "free-decay", "--out", "x.csv",
                             "--duration", "3000", "--rate", "5000"], cwd=tmp_path,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 120.0
    while not os.listdir(tmp_path) and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.01)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    code = proc.returncode
    if code == 0:  # pragma: no cover
        pytest.skip("the command finished before the signal")
    assert code == EXIT_INTERRUPTED, err
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1, err
    assert os.listdir(tmp_path) == []  # no partial x.csv, no temporary file
