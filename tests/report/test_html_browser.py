"""The HTML report rendered by a real browser: headless Chromium (Debian package).

The report is made the way a user makes it (simulate a free decay, ``identify logdec
--report``, and ``driveid report`` over two ``--json`` results), opened from a ``file://``
URL, and checked: a non-blank screenshot of the requested size, no console message, and the
parameter table in the rendered DOM with the values of the JSON result. Chromium logs every
console message (error or not) as a ``CONSOLE`` line with ``--enable-logging=stderr``; the
report has no script, so any such line is a failure. A control page proves this build of
Chromium does log them. CI installs chromium with ``.ci/system-packages``.
"""

import json
import os
import re
import shutil
import struct
import subprocess
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from driveid.commands.logdec import free_decay_command, logdec_command
from driveid.commands.report import report_command

WIDTH, HEIGHT = 1200, 1600  # window size requested = screenshot size [px]
_FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
          "--disable-background-networking", "--disable-component-update", "--disable-sync",
          "--enable-logging=stderr", "--v=0"]


def _browser():
    path = shutil.which("chromium") or ("/usr/bin/chromium" if os.path.exists(
        "/usr/bin/chromium") else None)
    if path is None:
        pytest.skip("headless Chromium is not installed (Debian package 'chromium'; "
                    ".ci/system-packages installs it): the report cannot be rendered")
    return path


def _run(tmp: Path, page: Path, *action: str) -> subprocess.CompletedProcess:
    profile = tmp / f"profile-{len(list(tmp.glob('profile-*')))}"
    cmd = [_browser(), *_FLAGS, f"--user-data-dir={profile}",
           f"--window-size={WIDTH},{HEIGHT}", *action, page.resolve().as_uri()]
    env = {**os.environ, "HOME": str(tmp)}  # nothing written to the user's home
    return subprocess.run(cmd, capture_output=True, text=True, timeout=120, env=env,
                          check=False)


def _console_lines(stderr: str) -> list[str]:
    return [line for line in stderr.splitlines() if ":CONSOLE" in line]


@pytest.fixture(scope="module")
def reports(tmp_path_factory):
    """Two pages made through the command line: one estimate, and a ± comparison."""
    tmp = tmp_path_factory.mktemp("browser")
    runner = CliRunner()
    results = []
    for sign in (1, -1):
        csv = tmp / f"run{'+' if sign > 0 else '-'}.csv"
        made = runner.invoke(free_decay_command, ["--out", str(csv), "--duration", "12",
                                                  "--x0", str(10 * sign),
                                                  "--counts-per-rev", "8000"])
        assert made.exit_code == 0, made.output
        out = runner.invoke(logdec_command, [str(csv), "--mass", "1", "--json"])
        assert out.exit_code == 0, out.output
        results.append(tmp / f"result{sign:+d}.json")
        results[-1].write_text(out.stdout)
    single = tmp / "single.html"
    made = runner.invoke(logdec_command, [str(tmp / "run+.csv"), "--mass", "1",
                                          "--report", str(single)])
    assert made.exit_code == 0, made.output
    both = tmp / "both.html"
    made = runner.invoke(report_command, [*map(str, results), "-o", str(both)])
    assert made.exit_code == 0, made.output
    return {"tmp": tmp, "single": single, "both": both,
            "result": json.loads(results[0].read_text())}


def _png_size(data: bytes) -> tuple[int, int]:
    assert data[:8] == b"\x89PNG\r\n\x1a\n", "not a PNG file"
    return struct.unpack(">II", data[16:24])


@pytest.mark.parametrize("page", ["single", "both"])
def test_screenshot_is_a_nonblank_png_of_the_window_size(reports, page):
    import matplotlib.image

    shot = reports["tmp"] / f"{page}.png"
    done = _run(reports["tmp"], reports[page], f"--screenshot={shot}")
    assert done.returncode == 0, done.stderr[-2000:]
    assert _png_size(shot.read_bytes()) == (WIDTH, HEIGHT)
    pixels = matplotlib.image.imread(shot)[..., :3]
    ink = np.any(pixels < 0.9, axis=-1).mean()
    # text, table rules and (single page) the figure cover a few % of a white page; a blank
    # or error page covers < 0.5 %, a page that failed to style (black) ~100 %
    assert 0.01 < ink < 0.6, f"fraction of non-white pixels {ink:.3f}"
    blue = np.abs(pixels - np.array([0x2B, 0x5D, 0x8A]) / 255).max(axis=-1) < 0.08
    assert blue.sum() > 200, "the headings' colour is missing: the inline style was not applied"
    if page == "single":
        # the record's line in matplotlib's first colour (#1f77b4) is on screen: the inline
        # PNG was decoded and painted (a broken image shows only its alt text)
        line = np.abs(pixels - np.array([0x1F, 0x77, 0xB4]) / 255).max(axis=-1) < 0.1
        assert line.sum() > 500, f"{line.sum()} pixels of the figure's line colour"


class _Table(HTMLParser):
    def __init__(self, table_id):
        super().__init__()
        self.table_id, self.inside, self.rows, self.cell = table_id, False, [], None

    def handle_starttag(self, tag, attrs):
        if tag == "table" and dict(attrs).get("id") == self.table_id:
            self.inside = True
        elif self.inside and tag == "tr":
            self.rows.append([])
        elif self.inside and tag in ("td", "th"):
            self.cell = ""

    def handle_endtag(self, tag):
        if tag == "table":
            self.inside = False
        elif self.inside and tag in ("td", "th") and self.cell is not None:
            self.rows[-1].append(" ".join(self.cell.split()))
            self.cell = None

    def handle_data(self, data):
        if self.cell is not None:
            self.cell += data


def test_rendered_dom_shows_the_parameter_table_without_console_messages(reports):
    done = _run(reports["tmp"], reports["both"], "--dump-dom")
    assert done.returncode == 0, done.stderr[-2000:]
    assert _console_lines(done.stderr) == []
    parser = _Table("parameters-1")
    parser.feed(done.stdout)
    rows = {row[0]: row[1:] for row in parser.rows[1:]}
    expected = reports["result"]["parameters"]
    assert list(rows) == list(expected)
    for name, par in expected.items():
        shown = float(rows[name][0])
        # 6 significant digits are shown: relative difference < 5e-6
        assert shown == pytest.approx(par["value"], rel=5e-6, abs=1e-300)
        if par["fixed"]:
            assert rows[name][1] == "fixed (given)"
        else:
            half = float(re.sub("^± ", "", rows[name][1]))
            assert half == pytest.approx(1.959964 * par["stderr"], rel=5e-2)  # 2 digits shown
    comparison = _Table("comparison-table")
    comparison.feed(done.stdout)
    assert len(comparison.rows[0]) == 4  # parameter, unit, run +, run -


def test_single_page_renders_its_figure_without_console_messages(reports):
    done = _run(reports["tmp"], reports["single"], "--dump-dom")
    assert done.returncode == 0, done.stderr[-2000:]
    assert _console_lines(done.stderr) == []
    assert done.stdout.count('src="data:image/png;base64,') == 1
    assert "Parameters (method <code>output-error</code>)" in done.stdout  # the default


def test_console_messages_are_detected_on_a_page_that_has_them(tmp_path):
    # control: without it, "no CONSOLE line" could mean this Chromium logs nothing at all
    page = tmp_path / "bad.html"
    page.write_text("<p>x</p><script>console.error('driveid-control'); missing();</script>")
    done = _run(tmp_path, page, "--dump-dom")
    lines = _console_lines(done.stderr)
    assert any("driveid-control" in line for line in lines), done.stderr[-2000:]
    assert any("ReferenceError" in line for line in lines)
