"""Shared helpers of the fuzz suite: run the CLI, classify the outcome, watch the folder.

Outcome classes (issue 12): ``ok`` (exit 0) or ``clean error`` (exit 2, exactly one stderr
line starting ``error:``, no traceback). Everything else fails the case: a traceback, exit 1
or 70, several error lines, a file written or changed outside the case's own folder.

The rule that no input reaches an internal error (issue 28) is checked on every run: an
:class:`Outcome` with exit 70 fails its test at once, whatever the test goes on to assert.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from driveid.cli import EXIT_INTERNAL, cli


def snapshot(folder: Path) -> dict[str, tuple]:
    """Map every entry under ``folder`` (links not followed) to (kind, size, mtime, target)."""
    out = {}
    for root, dirs, files in os.walk(folder):
        for name in dirs + files:
            p = Path(root) / name
            st = p.lstat()
            target = os.readlink(p) if p.is_symlink() else None
            out[str(p.relative_to(folder))] = (st.st_mode, st.st_size, st.st_mtime_ns, target)
    return out


class Outcome:
    """The result of one CLI run, with the checks every case makes."""

    def __init__(self, result):
        self.result = result
        self.code = result.exit_code
        self.stdout = result.stdout
        self.stderr = result.stderr
        self.lines = [line for line in self.stderr.splitlines() if line.strip()]
        # exit 70 is "internal error, this is a bug": no fuzz input may ever reach it
        assert self.code != EXIT_INTERNAL, "internal error (exit 70): " + self.describe()

    def describe(self) -> str:
        exc = self.result.exception
        return (f"exit {self.code}; exception {type(exc).__name__ if exc else None}: {exc}\n"
                f"stderr:\n{self.stderr}\nstdout:\n{self.stdout[:2000]}")

    def assert_no_traceback(self) -> None:
        assert "Traceback" not in self.stderr + self.stdout, self.describe()
        exc = self.result.exception
        assert exc is None or isinstance(exc, SystemExit), self.describe()

    def assert_clean_error(self, match: str | None = None, *,
                           progress_label: str | None = None) -> None:
        """Exit 2, one ``error:`` line (``warning:`` lines allowed), no traceback.

        ``progress_label``: a progress bar's label line printed before the error (by
        ``pho run``, whose bar starts before the campaign checks its plan) is tolerated.
        """
        self.assert_no_traceback()
        assert self.code == 2, self.describe()
        errors = [line for line in self.lines if line.startswith("error:")]
        others = [line for line in self.lines
                  if not line.startswith(("error:", "warning:"))
                  and line.strip() != progress_label]
        assert len(errors) == 1 and not others, self.describe()
        if match is not None:
            assert match.lower() in errors[0].lower(), self.describe()

    def assert_ok(self) -> None:
        self.assert_no_traceback()
        assert self.code == 0, self.describe()
        bad = [line for line in self.lines
               if not line.startswith(("warning:", "PHO runs", "wrote"))
               and "%" not in line]
        assert not [b for b in bad if "Warning" in b or "warn(" in b], self.describe()

    def assert_ok_or_clean_error(self) -> None:
        self.assert_no_traceback()
        if self.code == 0:
            self.assert_ok()
        else:
            self.assert_clean_error()


@pytest.fixture(scope="session")
def runner() -> CliRunner:
    return CliRunner()


@pytest.fixture
def run(runner, tmp_path, monkeypatch):
    """Run ``driveid ARGS`` in ``tmp_path``; return an :class:`Outcome`."""
    monkeypatch.chdir(tmp_path)

    def _run(*args: str, input: str | None = None) -> Outcome:
        return Outcome(runner.invoke(cli, [str(a) for a in args], input=input))

    return _run


@pytest.fixture(scope="session")
def good_record(tmp_path_factory) -> Path:
    """A small, valid free-decay CSV (2 s at 1 kHz, 4 rad/s, encoder quantised)."""
    from driveid.io import write_record
    from driveid.sim import OscillatorParams, simulate_free_decay

    folder = tmp_path_factory.mktemp("good")
    params = OscillatorParams(J=1.0, K=16.0, c_mean=0.3, c_delta=0.1, fk_mean=0.07,
                              fk_delta=0.03)
    rec = simulate_free_decay(params, x0=10.0, duration=6.0, fs=1000.0).record
    path = folder / "decay.csv"
    write_record(rec, path)
    return path


@pytest.fixture(scope="session")
def good_arrays(good_record):
    from driveid.io import read_record

    rec = read_record(good_record)
    return {"t": np.asarray(rec.t), "x": np.asarray(rec.x), "u": np.asarray(rec.u)}


@pytest.fixture(scope="session")
def result_json(tmp_path_factory, good_record) -> Path:
    """The ``--json`` result of ``identify logdec`` on :func:`good_record` (hostile edits
    start from it)."""
    out = CliRunner().invoke(cli, ["identify", "logdec", str(good_record), "--mass", "1",
                                   "--json"])
    assert out.exit_code == 0, out.output
    path = tmp_path_factory.mktemp("res") / "result.json"
    path.write_text(out.stdout)
    return path
