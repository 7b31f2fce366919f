"""``driveid simulate contour`` and ``driveid identify contour`` end to end (issue 27)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from click.testing import CliRunner

from driveid.cli import cli

EXAMPLE = Path("examples/drive_configs/contour_xy.toml")


@pytest.fixture(scope="module")
def workdir(tmp_path_factory):
    """A small circle (R = 25 mm at 0.1 m/s: 1.7 s) and its identification."""
    tmp = tmp_path_factory.mktemp("contour")
    text = EXAMPLE.read_text().replace("radius = 0.05 ", "radius = 0.025 ")
    config = tmp / "axes.toml"
    config.write_text(text)
    runner = CliRunner()
    res = runner.invoke(cli, ["simulate", "contour", str(config), "--out",
                              str(tmp / "circle.csv"), "--json"])
    assert res.exit_code == 0, res.output
    (tmp / "sim.json").write_text(res.stdout)
    res = runner.invoke(cli, ["identify", "contour", str(tmp / "circle.csv"), "--config",
                              str(config), "--json", "--report", str(tmp / "report.html")])
    assert res.exit_code == 0, res.output
    (tmp / "est.json").write_text(res.stdout)
    return tmp


def test_simulate_json_has_radial_error_glitches_and_spikes(workdir):
    data = json.loads((workdir / "sim.json").read_text())
    assert data["radial_error"]["peak"] > data["radial_error"]["rms"] > 0
    assert len(data["glitches"]) == 4 and len(data["reversal_spikes"]) == 4
    header = [ln for ln in (workdir / "circle.csv").read_text().splitlines()
              if not ln.startswith("#")][0]
    assert header.startswith("t [s],x_ref [m],y_ref [m],x [m],y [m]")
    assert "u_x [N]" in header


def test_identify_json_and_report(workdir):
    est = json.loads((workdir / "est.json").read_text())
    assert est["method"] == "contour-idim"
    p = est["parameters"]
    # truth: x 59 N, gap 12 µm (examples/drive_configs/contour_xy.toml); 2 % is ~10 s.e.
    assert abs(p["x.fk_mean"]["value"] / 59.0 - 1) < 0.02
    assert abs(p["x.gap"]["value"] / 12e-6 - 1) < 0.05
    assert p["y.c_mean"]["stderr"] > 0
    assert est["diagnostics"]["compensation"]["peak_ratio"] >= 3
    html = (workdir / "report.html").read_text()
    assert "data:image/png;base64" in html  # the ball-bar figure is embedded


def test_compensate_reports_with_without_and_wrong_friction(workdir):
    res = CliRunner().invoke(cli, ["simulate", "contour", str(workdir / "axes.toml"),
                                   "--out", str(workdir / "comp.csv"), "--compensate",
                                   str(workdir / "est.json"), "--json"])
    assert res.exit_code == 0, res.output
    table = json.loads(res.stdout)["compensation"]["radial_error"]
    assert set(table) >= {"with", "without", "friction_low", "friction_high", "peak_ratio"}
    assert table["peak_ratio"] >= 3  # the acceptance, in the true plant


def test_refuses_overwrite_and_bad_inputs(workdir):
    runner = CliRunner()
    res = runner.invoke(cli, ["simulate", "contour", str(workdir / "axes.toml"), "--out",
                              str(workdir / "circle.csv")])
    assert res.exit_code == 2 and "error:" in res.output and "overwrite" in res.output
    bad = workdir / "bad.toml"
    bad.write_text("[path]\nradius = 0.1\nfeed = 0.1\n")
    res = runner.invoke(cli, ["simulate", "contour", str(bad), "--out",
                              str(workdir / "x.csv")])
    assert res.exit_code == 2 and "plane 'xy' needs the axes" in res.output
    res = runner.invoke(cli, ["simulate", "contour", str(workdir / "axes.toml"), "--out",
                              str(workdir / "y.csv"), "--compensate", str(bad)])
    assert res.exit_code == 2 and "--compensate" in res.output
    res = runner.invoke(cli, ["identify", "contour", str(workdir / "circle.csv"), "--config",
                              str(workdir / "axes.toml"), "--position", "x"])
    assert res.exit_code == 2 and "reads its columns by name" in res.output


@pytest.mark.parametrize("change, words", [
    # issue 28: a 10 MHz controller is 3.2e7 Python calls (~19 min): refused before work
    (("rate = 2000.0 ", "rate = 1e7 "), "--max-periods"),
    # a circle of 1e6 revolutions would need ~1 TB: refused before allocation
    (("revolutions = 1.0", "revolutions = 1e6"), "memory"),
])
def test_simulate_contour_refuses_a_run_beyond_budget_or_memory(tmp_path, change, words):
    config = tmp_path / "axes.toml"
    text = EXAMPLE.read_text()
    assert change[0] in text
    config.write_text(text.replace(*change))
    res = CliRunner().invoke(cli, ["simulate", "contour", str(config), "--out",
                                   str(tmp_path / "c.csv")])
    assert res.exit_code == 2, res.output
    line = res.output.strip()
    assert line.startswith("error: simulate contour") and words in line
    assert "[path] revolutions" in line and len(line.splitlines()) == 1
    assert not (tmp_path / "c.csv").exists()


def test_a_cut_circle_is_refused_in_contour_words_not_idim_s(workdir, tmp_path):
    # the circle's decimation is chosen by `identify contour`, not by the user, so IDIM's
    # "--decimate 1" advice would name an option this command does not have
    lines = (workdir / "circle.csv").read_text().splitlines()
    head = [ln for ln in lines if ln.startswith("#")]
    body = [ln for ln in lines if not ln.startswith("#")]
    (tmp_path / "cut.csv").write_text("\n".join(head + body[:100]) + "\n")
    res = CliRunner().invoke(cli, ["identify", "contour", str(tmp_path / "cut.csv"),
                                   "--config", str(workdir / "axes.toml"), "--no-preview"])
    assert res.exit_code == 2, res.output
    assert "record the whole circle" in res.output and "--decimate" not in res.output
    assert "Traceback" not in res.output
