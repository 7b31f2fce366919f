"""Messages on the command line speak CLI, never Python (issue 26, item 3).

Two checks: (1) every Python spelling ``NAME=True/False/None`` or ``NAME must`` found in the
message texts of ``src/driveid`` (raise statements and warnings) whose NAME is an option of
some command comes out in CLI spelling when raised under that command; (2) a walk of the
error messages that bad command lines trigger (one per kind of mistake) finds no Python
keyword spelling and no numpy repr.
"""

import re
from pathlib import Path

import click
import numpy as np
import pytest
from click.testing import CliRunner

import driveid
from driveid.cli import cli
from driveid.commands._output import cli_text
from tests.fixtures.formats import (
    write_cassy,
    write_clean_csv,
    write_ni_force_log,
    write_servo_telemetry,
)
from tests.test_cli_reading import _commands, _hint_texts

# a Python keyword argument or a numpy repr in a message (what must never reach the CLI)
_PYTHON = re.compile(r"(?<![\w\-.])[a-z][a-z0-9_]*=(True|False|None)\b|\bnp\.\w+\(|"
                     r"\bpass [a-z_]+=|\(Python:|\b[A-Z]\w*\(\w+=")  # ... and object reprs


def _long_options(command):
    names = {}
    for param in command.params:
        if isinstance(param, click.Option):
            for flag in param.opts:
                if flag.startswith("--"):
                    names[flag[2:].replace("-", "_")] = flag
    return names


def test_python_spellings_in_the_sources_become_cli_options():
    commands = [c for c in _commands() if not isinstance(c, click.Group)]
    root = Path(driveid.__file__).parent
    checked = 0
    for path in sorted(root.rglob("*.py")):
        texts = list(_hint_texts(__import__("ast").parse(path.read_text(encoding="utf-8"))))
        for text in texts:
            for match in re.finditer(r"(?<![\w\-.])([a-z][a-z0-9_]*)=(True|False|None)\b|"
                                     r"(?<![\w\-.])([a-z][a-z0-9]*_[a-z0-9_]+) must|"
                                     r"\b(?:pass|try|give|use|set) ([a-z][a-z0-9_]*)=", text):
                name = match.group(1) or match.group(3) or match.group(4)
                for command in commands:
                    if name not in _long_options(command):
                        continue
                    with click.Context(command):
                        shown = cli_text(text)
                    # the CLI form names the option; the Python spelling is gone
                    assert _long_options(command)[name] in shown, (path.name, text, shown)
                    assert not re.search(rf"(?<![\w\-]){name}(=|\s+must)", shown), (
                        path.name, shown)
                    checked += 1
    assert checked >= 5  # max_jitter=None, drift=True, cutoff_hz must, pass delay= ...


def test_cli_text_translates_and_drops_reprs():
    from driveid.commands.friction import idim_command
    from driveid.commands.logdec import logdec_command

    with click.Context(logdec_command):
        assert cli_text("not a free decay; try drift=True") == "not a free decay; try --drift"
        assert cli_text("pass max_jitter=None to accept it") == "give --max-jitter none to " \
                                                                "accept it"
    with click.Context(idim_command):
        assert cli_text("cutoff_hz must be below fs/2 = 32.2 Hz; got 100.0").startswith(
            "--cutoff-hz must be below fs/2")
    assert "Record.crop" not in cli_text("burst at 3 s: crop the record around them "
                                         "(Record.crop) or repeat the experiment")
    message = f"got {np.float64(0.035)!r} and {np.int64(3)!r}"
    assert "np." in message  # numpy 2 reprs: what the CLI must not show
    assert cli_text(message) == "got 0.035 and 3"
    # outside a command the API's own words stay (only reading options are known)
    assert cli_text("set feedback=None to use the callback") == ("set feedback=None to use "
                                                                 "the callback")


def _bad_command_lines(tmp: Path):
    clean = write_clean_csv(tmp)
    jittery = write_cassy(tmp)
    telemetry = write_servo_telemetry(tmp)
    force_only = write_ni_force_log(tmp)
    not_json = tmp / "result.json"
    not_json.write_text("{")
    return [
        ["identify", "logdec", str(jittery), "--mass", "1"],            # jitter
        ["identify", "logdec", str(clean), "--max-jitter", "-1"],
        ["identify", "logdec", str(clean), "--fs", "-3"],
        ["identify", "logdec", str(clean), "--unit", "x=furlong"],
        ["identify", "logdec", str(clean), "--scale", "u=abc"],
        ["identify", "logdec", str(clean), "--sign-magnitude", "x:99"],
        ["identify", "logdec", str(clean), "--position", "nothing"],
        ["identify", "logdec", str(telemetry)],                          # ambiguous servos
        ["identify", "logdec", str(telemetry), "--position", "pos"],
        ["identify", "logdec", str(force_only)],                         # no position
        ["identify", "idim", str(clean), "--cutoff-hz", "900"],
        ["identify", "idim", str(clean), "--position-noise-std", "-1e-6"],
        ["identify", "logdec", str(tmp / "missing.csv")],
        ["inspect", str(clean), "--unit", "q=mm"],
        ["validate", str(not_json), str(clean)],
        ["simulate", "drive", "--preset", "testbed-a", "--out", str(clean)],  # exists
        ["identify", "breakaway", str(clean), "--v-break", "-1"],
        ["identify", "friction-map", str(clean), "--cutoff-hz", "-5"],
        ["identify", "hilbert", str(force_only)],
        ["identify", "wavelet", str(telemetry), "--position", "pos (9)"],
        ["identify", "step", str(force_only)],
        ["identify", "static-stiffness", str(clean), "--unit", "u=V"],
        ["identify", "forced", str(clean), "--scale", "u=1/0"],
        ["report", str(not_json), "-o", str(tmp / "r.html")],
    ]


def test_every_triggered_cli_error_is_one_line_in_cli_spelling(tmp_path):
    runner = CliRunner()
    for args in _bad_command_lines(tmp_path):
        res = runner.invoke(cli, args)
        assert res.exit_code == 2, (args, res.output)
        errors = [ln for ln in res.stderr.splitlines() if ln.startswith("error: ")]
        assert len(errors) == 1, (args, res.stderr)
        assert not _PYTHON.search(res.stderr), (args, res.stderr)
        assert "Traceback" not in res.output


@pytest.mark.parametrize("fs", [64.5])
def test_idim_default_cutoff_follows_the_sample_rate(tmp_path, fs):
    """100 Hz refused a 64.5 Hz robot log; the default is now fs/10 below 1 kHz."""
    from driveid.io import Record, write_record

    t = np.arange(int(40 * fs)) / fs
    w = 2 * np.pi * 0.4
    x = 0.05 * np.sin(w * t)
    v = 0.05 * w * np.cos(w * t)
    a = -0.05 * w**2 * np.sin(w * t)
    u = 10.0 * a + 50.0 * v + 3.0 * np.tanh(v / 1e-3) - 0.5
    path = write_record(Record(t=t, x=x, u=u, meta={"units": {"x": "m", "u": "N"}}),
                        tmp_path / "slow.csv")
    res = CliRunner().invoke(cli, ["identify", "idim", str(path), "--no-sensitivity"])
    assert res.exit_code == 0, res.output
    assert f"--cutoff-hz {fs / 10:.4g} Hz" in res.stderr
