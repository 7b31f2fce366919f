"""The documentation: the Sphinx site builds without warnings, and the tutorial is true.

The tutorial (docs/tutorial.md) is run as written: its Python block writes the CSV, and its
``driveid inspect`` and ``driveid identify logdec`` lines print what the page shows.
"""

import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest
from click.testing import CliRunner

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"


def _blocks(text):
    """Fenced code blocks of a Markdown page as (info string, body) pairs."""
    return re.findall(r"^```([^\n`]*)\n(.*?)^```\s*$", text, flags=re.S | re.M)


def _lines(text):
    return [" ".join(line.split()) for line in text.strip().splitlines()]


def _command(argv):
    from driveid.commands.inspect import inspect_command
    from driveid.commands.logdec import logdec_command
    from driveid.commands.report import report_command

    table = {("inspect",): inspect_command, ("identify", "logdec"): logdec_command,
             ("report",): report_command}
    for prefix, command in table.items():
        if tuple(argv[1:1 + len(prefix)]) == prefix:
            return command, argv[1 + len(prefix):]
    raise AssertionError(f"the tutorial runs a command this test does not know: {argv}")


def test_tutorial_runs_as_written(tmp_path, monkeypatch):
    blocks = _blocks((DOCS / "tutorial.md").read_text(encoding="utf-8"))
    (script,) = [body for info, body in blocks if info.strip() == "python"]
    monkeypatch.chdir(tmp_path)
    exec(compile(script, "tutorial.md", "exec"), {})  # noqa: S102 - the page's own code
    shown = dict(zip([b for _, b in blocks], [b for _, b in blocks[1:]] + [""], strict=True))
    checked = 0
    for _, body in blocks:
        line = body.strip()
        if not line.startswith(("driveid inspect", "driveid identify")) or "\n" in line:
            continue
        command, args = _command(shlex.split(line))
        result = CliRunner().invoke(command, args)
        assert result.exit_code == 0, result.output
        # the block after each command is its output: every line of it (values, units,
        # columns) except the file-format summary, whose wording may change
        missing = [x for x in _lines(shown[body])
                   if not x.startswith("file:") and x not in _lines(result.output)]
        assert not missing, f"{line}: the page shows lines the command no longer prints"
        checked += 1
    assert checked == 2  # inspect and identify logdec
    assert Path("axis3.html").stat().st_size > 10_000  # the report with its figure


def test_index_includes_the_other_pages_by_glob():
    index = (DOCS / "index.md").read_text(encoding="utf-8")
    assert ":glob:" in index and "\n*\n" in index  # colleagues' pages appear without edits
    assert "api/index" in index


@pytest.mark.slow
def test_sphinx_build_has_no_warnings(tmp_path):
    done = subprocess.run(
        [sys.executable, "-m", "sphinx", "-W", "--keep-going", "-q", "-b", "html",
         "-d", str(tmp_path / "doctrees"), str(DOCS), str(tmp_path / "html")],
        capture_output=True, text=True, timeout=900, cwd=ROOT, check=False,
        env={**os.environ, "MPLBACKEND": "Agg"})
    report = done.stdout[-4000:] + done.stderr[-8000:]
    assert done.returncode == 0, report
    assert "WARNING" not in done.stderr and "ERROR" not in done.stderr, report
    assert (tmp_path / "html" / "tutorial.html").is_file()
    api = tmp_path / "html" / "api" / "generated" / "driveid.identify.free_decay.logdec.html"
    assert "estimate_log_decrement" in api.read_text(encoding="utf-8")


def test_plain_text_docstrings_are_made_valid_restructuredtext(monkeypatch):
    monkeypatch.syspath_prepend(str(DOCS))
    import conf

    lines = ["speed |v| and ``|x|/2`` and :math:`|v|`", ".. math::", "", "   |x| = 1",
             "after |y|", "Errata of §2", "-----", "References", "----------", ".. [1] A."]
    conf._plain_text_docstring(None, "module", "m", None, {}, lines)
    assert lines[0] == r"speed \|v\| and ``|x|/2`` and :math:`|v|`"  # literals untouched
    assert lines[3] == "   |x| = 1" and lines[4] == r"after \|y\|"  # math block untouched
    assert lines[6] == "-" * len("Errata of §2")
    assert lines[7:9] == [".. rubric:: References", ""]
