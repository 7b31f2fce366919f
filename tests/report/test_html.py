"""The HTML report's content, without a browser (see test_html_browser.py for the browser)."""

import base64
import json
import math
import re
from html.parser import HTMLParser

import numpy as np
import pytest
from click.testing import CliRunner
from scipy.stats import norm

from driveid.commands.report import report_command
from driveid.errors import OverwriteError
from driveid.identify.core.estimate import Estimate, Parameter
from driveid.report.figures import pyplot
from driveid.report.html import Z95, render_report, write_report

SHA = "0123456789abcdef" * 4


def _estimate(**changes):
    fields = dict(
        method="logdec-lsq",
        params={"K": Parameter(16.0, 0.01, "N·m/rad"),
                "J": Parameter(1.0, unit="kg·m²", fixed=True),
                "c_mean": Parameter(0.3, 0.002, "N·m·s/rad"),
                "zeta": Parameter(0.05, math.nan, "-")},
        diagnostics={"n_peaks": 12, "rms_peak_value": 1.5e-7},
        warnings=("only 12 peaks; the stiffness is less certain",),
        covariance={"names": ["K", "c_mean"], "matrix": np.array([[1e-4, 1e-6], [1e-6, 4e-6]])},
        inputs=({"path": "data/run+.csv", "sha256": SHA, "rows": 12001,
                 "columns": {"t": "Zeit", "x": "Weg"}, "window": [0.5, 11.0],
                 "units": {"t": "s", "x": "rad"}, "units_in_file": {"Weg": "deg"}},),
    )
    fields.update(changes)
    return Estimate(**fields)


class _Cells(HTMLParser):
    """Rows of the tables with a given class, as lists of cell texts."""

    def __init__(self, table_class):
        super().__init__()
        self.table_class, self.depth, self.rows, self.cell = table_class, 0, [], None

    def handle_starttag(self, tag, attrs):
        attrs = dict(attrs)
        if tag == "table" and self.table_class in (attrs.get("class") or "").split():
            self.depth = 1
        elif self.depth and tag == "tr":
            self.rows.append([])
        elif self.depth and tag in ("td", "th"):
            self.cell = ""

    def handle_endtag(self, tag):
        if tag == "table":
            self.depth = 0
        elif self.depth and tag in ("td", "th") and self.cell is not None:
            self.rows[-1].append(" ".join(self.cell.split()))
            self.cell = None

    def handle_data(self, data):
        if self.cell is not None:
            self.cell += data


def _rows(html, table_class="parameters"):
    parser = _Cells(table_class)
    parser.feed(html)
    return {row[0]: row[1:] for row in parser.rows[1:]}


def test_z95_is_the_normal_quantile():
    assert Z95 == pytest.approx(norm.ppf(0.975), rel=1e-12)  # exact to double precision


def test_parameter_table_95_percent_intervals_and_fixed_values():
    rows = _rows(render_report(_estimate()))
    # K = 16 ± 1.96 * 0.01 = 16 ± 0.0196: bounds to the 2nd significant digit of the
    # half-width (truth: the closed form)
    assert rows["K"] == ["16", "± 0.02", "[15.98, 16.02]", "N·m/rad"]
    half = norm.ppf(0.975) * 0.002
    low, high = (float(v) for v in re.findall(r"[\d.]+", rows["c_mean"][2]))
    # rounding at the 2nd significant digit of the half-width: error <= 5 % of it
    assert low == pytest.approx(0.3 - half, abs=0.05 * half)
    assert high == pytest.approx(0.3 + half, abs=0.05 * half)
    assert rows["J"] == ["1", "fixed (given)", "kg·m²"]  # never "± 0"
    assert rows["zeta"][1:3] == ["not available", "not available"]


def test_interval_bounds_keep_the_digits_that_differ():
    rows = _rows(render_report(_estimate(params={"K": Parameter(16.0001, 8.1633e-5, "N")})))
    assert rows["K"][2] == "[15.99994, 16.00026]"  # 16.0001 ± 0.00016; 6 digits gave "16"


def test_page_is_self_contained_and_has_no_script():
    fig, ax = pyplot().subplots()
    ax.plot([0, 1], [0, 1])
    html = render_report(_estimate(), figures=[("the decay", fig)])
    assert "<script" not in html.lower()
    assert not re.search(r"""(src|href)\s*=\s*["'](?!data:)""", html)  # only data: URIs
    assert not re.search(r"url\(|@import|https?://", html)
    (src,) = re.findall(r'src="data:image/png;base64,([^"]+)"', html)
    assert base64.b64decode(src).startswith(b"\x89PNG\r\n\x1a\n")
    assert "the decay" in html


def test_inputs_warnings_diagnostics_and_reproduction():
    html = render_report(_estimate().to_dict(command=["/home/u/.venv/bin/driveid", "identify",
                                                      "logdec",
                                                      "run +.csv", "--mass", "1"]))
    assert SHA in html and "12001" in html and "0.5 … 11 s" in html
    assert "x ← Weg [rad, file: deg]" in html
    assert "only 12 peaks; the stiffness is less certain" in html
    assert "driveid identify logdec &#39;run +.csv&#39; --mass 1" in html  # shell-quoted
    assert "/home/u/.venv" not in html  # the script's name, not its path in one venv
    assert "rms_peak_value" in html and "1.5e-07" in html
    assert _rows(html, "correlation")["K"] == ["1", "0.05"]  # 1e-6 / (0.01 * 0.002)


def test_markup_in_names_and_warnings_is_escaped():
    est = _estimate(warnings=("<script>alert(1)</script>",),
                    inputs=({"path": "<b>x</b>.csv", "sha256": SHA},))
    html = render_report(est)
    assert "<script>" not in html and "&lt;script&gt;" in html
    assert "<b>x</b>" not in html


def test_several_estimates_compared_side_by_side():
    second = _estimate(params={"K": Parameter(15.0, 0.2, "N·m/rad"),
                               "gap_plus": Parameter(1e-3, 1e-5, "rad")},
                       inputs=({"path": "run-.csv"},))
    html = render_report([_estimate(), second.to_dict()])
    rows = _rows(html, "comparison")
    assert rows["K"] == ["N·m/rad", "16 ± 0.02", "15 ± 0.39"]  # 1.96 * 0.2 = 0.392
    assert rows["J"][2] == "—" and rows["gap_plus"][1] == "—"
    assert "1. logdec-lsq — run+.csv" in html and "2. logdec-lsq — run-.csv" in html
    assert _rows(render_report(_estimate()), "comparison") == {}  # one estimate: no table


class _FakeComparison:
    fit = {"x": 93.456}

    def plot(self):
        fig, ax = pyplot().subplots(2)
        ax[0].plot([0, 1])
        return fig


def test_validation_comparisons_are_duck_typed():
    html = render_report(_estimate(), comparisons=[_FakeComparison()])
    assert "x: 93.46 %" in html
    assert html.count("data:image/png;base64,") == 1


def test_write_report_refuses_to_overwrite(tmp_path):
    path = tmp_path / "report.html"
    path.write_text("keep me")
    with pytest.raises(OverwriteError, match="--overwrite"):
        write_report([_estimate()], path)
    assert path.read_text() == "keep me"
    write_report([_estimate()], path, overwrite=True, title="Axis 3")
    assert "<title>Axis 3</title>" in path.read_text(encoding="utf-8")


def test_empty_and_wrong_inputs_are_refused():
    with pytest.raises(ValueError, match="at least one estimate"):
        render_report([])
    with pytest.raises(ValueError, match="driveid-result/1"):
        render_report({"schema": "other"})
    with pytest.raises(TypeError, match="figure 1 must be"):
        render_report(_estimate(), figures=[42])


def test_report_command_compares_json_results(tmp_path):
    files = []
    for sign in "+-":
        path = tmp_path / f"result{sign}.json"
        path.write_text(json.dumps(_estimate().to_dict(command=["driveid", sign])))
        files.append(str(path))
    out = tmp_path / "report.html"
    runner = CliRunner()
    result = runner.invoke(report_command, [*files, "-o", str(out), "--title", "Axis X"])
    assert result.exit_code == 0, result.output
    assert "wrote" in result.output and "2 results" in result.output
    html = out.read_text(encoding="utf-8")
    assert "<title>Axis X</title>" in html and "Side-by-side comparison" in html
    again = runner.invoke(report_command, [files[0], "-o", str(out)])
    assert again.exit_code == 2 and "error:" in again.output and "--overwrite" in again.output
    assert out.read_text(encoding="utf-8") == html  # nothing overwritten


def test_report_command_rejects_a_file_that_is_not_a_result(tmp_path):
    bad = tmp_path / "bad.json"
    bad.write_text('{"schema": "something-else"}')
    notjson = tmp_path / "notjson.json"
    notjson.write_text("x,y\n1,2\n")
    for path in (bad, notjson):
        result = CliRunner().invoke(report_command, [str(path), "-o", str(tmp_path / "r.html")])
        assert result.exit_code == 2
        assert result.output.startswith("error:") and "--json" in result.output
        assert "Traceback" not in result.output
    assert not (tmp_path / "r.html").exists()


def test_figures_given_as_png_file_as_the_demo_does(tmp_path):
    fig, ax = pyplot().subplots()
    ax.plot([0, 1], [1, 0])
    png = tmp_path / "decay.png"
    fig.savefig(png)
    path = write_report([_estimate()], tmp_path / "report.html",
                        figures=[("Log decrement of both runs", png)], command=["driveid", "demo"])
    html = path.read_text(encoding="utf-8")
    (src,) = re.findall(r'src="data:image/png;base64,([^"]+)"', html)
    assert base64.b64decode(src) == png.read_bytes()  # embedded unchanged
    assert "<pre>driveid demo</pre>" in html
