"""``driveid identify drive`` and ``identify subsystems`` on simulated records."""

from __future__ import annotations

import json

import pytest
from click.testing import CliRunner

from driveid.cli import cli

TOML = """
[[body]]
J = 0.0115355
c_mean = 0.0007457
fk_mean = 0.109456

[feedback]
P = 5.0
D = 0.1
delay = 0.01377

[run]
duration = 2.0
fs = 1000.0
x0 = [1.0]
v0 = [0.0]
"""


def _record(tmp_path, text=TOML, name="a"):
    config = tmp_path / f"{name}.toml"
    config.write_text(text)
    out = tmp_path / f"{name}.csv"
    result = CliRunner().invoke(cli, ["simulate", "drive", str(config), "--out", str(out)])
    assert result.exit_code == 0, result.output
    return config, out


def test_identify_drive_json_and_model_out(tmp_path):
    config, rec = _record(tmp_path)
    start = tmp_path / "start.toml"
    start.write_text(TOML.replace("J = 0.0115355", "J = 0.015"))
    model = tmp_path / "fitted.toml"
    result = CliRunner().invoke(cli, ["identify", "drive", str(start), str(rec), "--estimate",
                                      "body1.J,body1.fk_mean", "--json", "--model-out",
                                      str(model)])
    assert result.exit_code == 0, result.output
    data = json.loads(result.output[result.output.index("{"):])
    # a noise-free record of the same simulator: the fit recovers the truth to 1e-4
    assert data["parameters"]["body1.J"]["value"] == pytest.approx(0.0115355, rel=1e-4)
    assert data["parameters"]["body1.c_mean"]["fixed"] is True
    assert "J = " in model.read_text()
    again = CliRunner().invoke(cli, ["simulate", "drive", str(model), "--out",
                                     str(tmp_path / "b.csv")])
    assert again.exit_code == 0, again.output


def test_identify_drive_bad_name_is_one_error_line(tmp_path):
    config, rec = _record(tmp_path)
    result = CliRunner().invoke(cli, ["identify", "drive", str(config), str(rec), "--estimate",
                                      "body1.X"])
    assert result.exit_code == 2
    assert result.output.strip().startswith("error:") and "body1" in result.output


def test_identify_subsystems_table(tmp_path):
    parts = {"A": 0.0115355, "AB": 0.0150626}
    for name, j in parts.items():
        _record(tmp_path, TOML.replace("J = 0.0115355", f"J = {j}"), name)
    (tmp_path / "m.toml").write_text(
        '[[section]]\nname = "A"\nconfig = "A.toml"\nfiles = ["A.csv"]\n'
        'estimate = ["body1.J"]\n[section.published]\nJ = 0.0115355\n'
        '[[section]]\nname = "B"\nconfig = "AB.toml"\nfiles = ["AB.csv"]\n'
        'estimate = ["body1.J"]\n')
    result = CliRunner().invoke(cli, ["identify", "subsystems", str(tmp_path / "m.toml"),
                                      "--json"])
    assert result.exit_code == 0, result.output
    data = json.loads(result.output[result.output.index("{"):])
    # each section's J within 2 % (Table 5.2 procedure; here exact records: 1e-4)
    assert data["parameters"]["B.J"]["value"] == pytest.approx(0.0150626 - 0.0115355,
                                                               rel=1e-3)
    assert data["parameters"]["A+B.J"]["value"] == pytest.approx(0.0150626, rel=1e-4)


def test_identify_drive_bad_pieces_is_one_error_line(tmp_path):
    config, rec = _record(tmp_path)
    result = CliRunner().invoke(cli, ["identify", "drive", str(config), str(rec), "--estimate",
                                      "body1.J", "--pieces", "-0.5"])
    assert result.exit_code == 2
    lines = result.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error:") and "--pieces" in lines[0]


def test_identify_drive_says_in_words_whether_it_fitted_pieces():
    from driveid.commands.identify_drive import _pieces_line

    done = _pieces_line({"done": True, "length": 0.5, "n_pieces": 12,
                         "whole_record_white": True})
    assert "then 12 pieces of 0.5 s" in done and "error bars are the pieces'" in done
    halved = _pieces_line({"done": True, "length": 0.25, "n_pieces": 24, "halved_from": {
        "length": 0.5, "not_white": 6, "channels": 24}})
    assert "0.5 s pieces left 6 of 24 channels not white" in halved
    assert _pieces_line({"done": False, "whole_record_white": True}) == \
        "fit: the whole record"
