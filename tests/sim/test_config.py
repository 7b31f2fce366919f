"""TOML drive configs: round trip against the presets, every error path, the CLI command."""

import dataclasses
import math
import tomllib
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from driveid.commands.drive import drive_command
from driveid.errors import ConfigError, ParameterError
from driveid.io import read_record
from driveid.sim.config import (
    RunOptions,
    load_drive_config,
    parse_drive_config,
    simulate_config,
)
from driveid.sim.drive import BacklashLink, ShaftLink, estimate_drive_cost
from driveid.sim.presets import preset

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "drive_configs" / "testbed_a.toml"

TESTBED_TOML = """
[[body]]
J = 0.0115355
c_mean = 0.0007457
fk_mean = 0.109456
[[body]]
J = 0.0035271
c_mean = 0.00112
fk_mean = 0.0321609
[[body]]
J = 0.0188773
c_mean = 0.00112
fk_mean = 0.029551
[[link]]
type = "backlash"
gap_plus = 0.02
gap_minus = 0.02
k = 100.0
c = 0.05
[[link]]
type = "shaft"
k = 20.0
c = 0.01
[feedback]
P = 10.0
D = 0.2
delay = 0.01377
[run]
duration = 1.0
fs = 500.0
x0 = 1.0
"""


def _write(tmp_path, text, name="drive.toml"):
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def test_example_file_equals_preset_testbed_a():
    params, run = load_drive_config(EXAMPLE)
    assert params == preset("testbed-a")  # frozen dataclasses: field-by-field equality
    assert run == RunOptions(duration=5.0, fs=1000.0, x0=(1.0,), v0=(0.0,), torque=(0.0,))
    by_file = simulate_config(params, run)
    by_preset = simulate_config(preset("testbed-a"), run)
    np.testing.assert_array_equal(by_file.x, by_preset.x)  # same inputs: identical bits


def test_explicit_three_bodies_equal_preset_testbed(tmp_path):
    params, run = load_drive_config(_write(tmp_path, TESTBED_TOML))
    reference = preset("testbed")
    assert [b.J for b in params.bodies] == pytest.approx(
        [b.J for b in reference.bodies], rel=1e-12)  # the preset differences the table
    assert params.links == reference.links and params.feedback == reference.feedback
    assert run.x0 == (1.0, 1.0, 1.0)
    a = simulate_config(params, run)
    b = simulate_config(reference, run)
    # masses equal to 1e-16 relative: the responses agree to rounding
    np.testing.assert_allclose(a.x, b.x, rtol=0, atol=1e-9)
    assert a.n_impacts == b.n_impacts > 0


def test_preset_with_feedback_override_and_units():
    params, run = parse_drive_config({"preset": "pendulum-cart", "feedback": {"P": 150.0},
                                      "run": {"duration": 1.0}})
    assert params.feedback.P == 150.0
    assert params.feedback.delay == preset("pendulum-cart").feedback.delay
    assert run.units == "m"


def test_links_none_and_locked_and_feedback_body():
    params, _ = parse_drive_config({
        "body": [{"J": 1.0}, {"J": 2.0, "locked": True}],
        "link": [{"type": "none"}],
        "feedback": {"P": 1.0, "D": 0.5, "body": 1, "saturation": math.inf},
    })
    assert params.links == (None,) and params.bodies[1].locked
    assert params.feedback.body == 0  # TOML counts from 1, the API from 0


def test_backlash_link_keys():
    params, _ = parse_drive_config({
        "body": [{"J": 1.0}, {"J": 1.0}],
        "link": [{"type": "backlash", "gap_plus": 0.1, "gap_minus": 0.2, "k": 1e3,
                  "allow_tension": True}],
    })
    assert params.links[0] == BacklashLink(gap_plus=0.1, gap_minus=0.2, k=1e3,
                                           allow_tension=True)
    assert not isinstance(params.links[0], ShaftLink)


@pytest.mark.parametrize("config, match", [
    ({"bodies": []}, r"top level: unknown key\(s\) \['bodies'\]; allowed keys are "
                     r"\['preset', 'body'"),
    ({}, r"body: missing: give \[\[body\]\] tables or a preset"),
    ({"body": []}, r"body: must be one or more"),
    ({"body": [{"K": 1.0}]}, r"body\[1\]: missing value\(s\) for \['J'\]"),
    ({"body": [{"J": 1.0, "mass": 2.0}]}, r"body\[1\]: unknown key\(s\) \['mass'\]; "
                                          r"allowed keys are \['J', 'K'"),
    ({"body": [{"J": 1.0}, {"J": -1.0}], "link": [{"type": "none"}]},
     r"body\[2\]\.J: BodyParams\.J must be positive.*got -1\.0"),
    ({"body": [{"J": "heavy"}]}, r"body\[1\]\.J: must be a number; got 'heavy'"),
    ({"body": [{"J": 1.0, "fs_mean": 0.1, "fk_mean": 0.2}]},
     r"body\[1\]: static friction must hold"),
    ({"body": [{"J": 1.0, "locked": 1}]}, r"body\[1\]\.locked: must be true or false"),
    ({"body": [{"J": 1.0}, {"J": 1.0}]}, r"link: needs len\(body\) - 1 = 1 \[\[link\]\]"),
    ({"body": [{"J": 1.0}, {"J": 1.0}], "link": [{"type": "gear"}]},
     r"link\[1\]\.type: must be one of \['shaft', 'backlash', 'none'\]; got 'gear'"),
    ({"body": [{"J": 1.0}, {"J": 1.0}], "link": [{"type": "shaft", "gap_plus": 1.0}]},
     r"link\[1\]: unknown key\(s\) \['gap_plus'\]; allowed keys are \['type', 'k', 'c'\]"),
    ({"body": [{"J": 1.0}, {"J": 1.0}], "link": [{"type": "backlash", "k": 1.0}]},
     r"link\[1\]: missing value\(s\) for \['gap_plus', 'gap_minus'\]"),
    ({"body": [{"J": 1.0}, {"J": 1.0}], "link": [{"type": "shaft", "k": -5.0}]},
     r"link\[1\]\.k: ShaftLink\.k must be >= 0"),
    ({"body": [{"J": 1.0}], "feedback": {"P": 1.0}}, r"feedback: missing value\(s\) for \['D'\]"),
    ({"body": [{"J": 1.0}], "feedback": {"P": 1.0, "D": 0.0, "delay": -0.1}},
     r"feedback\.delay: PDFeedback\.delay must be >= 0"),
    ({"body": [{"J": 1.0}], "feedback": {"P": 1.0, "D": 0.0, "gain": 1.0}},
     r"feedback: unknown key\(s\) \['gain'\]"),
    ({"body": [{"J": 1.0}], "feedback": {"P": 1.0, "D": 0.0, "body": 0}},
     r"feedback\.body: must be a body number >= 1"),
    ({"body": [{"J": 1.0}], "feedback": {"P": 1.0, "D": 0.0, "body": 2}},
     r"feedback\.body: names body 2, but the drive has 1 body \(counted from 1\)"),
    ({"preset": "bed"}, r"preset: unknown preset; use one of \['pendulum-cart'"),
    ({"preset": "testbed-a", "body": [{"J": 1.0}]}, r"body: a preset fixes the bodies"),
    ({"preset": "testbed-a", "feedback": {"delay": -1.0}}, r"feedback\.delay: PDFeedback"),
    ({"body": [{"J": 1.0}], "run": {"dt": 0.1}}, r"run: unknown key\(s\) \['dt'\]"),
    ({"body": [{"J": 1.0}], "run": {"duration": 0.0}}, r"run\.duration: RunOptions\.duration "
                                                      r"must be positive.*got 0\.0"),
    ({"body": [{"J": 1.0}], "run": {"x0": [1.0, 2.0]}},
     r"run\.x0: needs one value per body \(1\); got 2 values"),
    ({"body": [{"J": 1.0}], "run": {"torque": ["a"]}}, r"run\.torque\[1\]: must be a number"),
    ({"body": [{"J": 1.0}], "run": {"method": "euler"}}, r"run\.method: RunOptions\.method"),
    ({"body": [{"J": 1.0}], "run": {"units": 1}}, r"run\.units: must be a string"),
    ({"body": [{"J": 1.0}], "run": {"units": "deg"}}, r"run\.units: RunOptions\.units"),
    ({"body": [{"J": 1.0}, {"J": 1.0, "locked": True}], "link": [{"type": "none"}],
      "run": {"v0": [0.0, 1.0]}}, r"run\.v0: locked bodies must start at rest.*\[2\]"),
])
def test_config_errors_name_the_key(config, match):
    with pytest.raises(ConfigError, match=match):
        parse_drive_config(config, source="bad.toml")
    with pytest.raises(ConfigError, match=r"^bad\.toml: "):
        parse_drive_config(config, source="bad.toml")


def test_file_errors(tmp_path):
    with pytest.raises(ConfigError, match=r"cannot read the drive config .*missing\.toml"):
        load_drive_config(tmp_path / "missing.toml")
    with pytest.raises(ConfigError, match=r"broken\.toml: not valid TOML"):
        load_drive_config(_write(tmp_path, "[[body]\nJ = 1", "broken.toml"))
    with pytest.raises(ConfigError, match=r"^x\.toml: body\[1\]\.J: BodyParams\.J"):
        load_drive_config(_write(tmp_path, "[[body]]\nJ = 0.0\n", "x.toml"))


def test_cli_writes_csv_and_refuses_to_overwrite(tmp_path):
    out = tmp_path / "run.csv"
    config = _write(tmp_path, TESTBED_TOML)
    runner = CliRunner()
    result = runner.invoke(drive_command, [str(config), "--out", str(out)])
    assert result.exit_code == 0, result.output
    assert "501 samples" in result.output and "impacts" in result.output
    header = out.read_text(encoding="utf-8").splitlines()[2]
    assert header == ("t [s],x1 [rad],v1 [rad/s],x2 [rad],v2 [rad/s],x3 [rad],v3 [rad/s],"
                      "command [N·m]")
    params, run = load_drive_config(config)
    expected = simulate_config(params, run)
    record = read_record(out, columns={"x": "x2", "v": "v2", "u": "command"})
    # %.17g text round-trips doubles exactly
    np.testing.assert_array_equal(record.x, expected.x[1])
    np.testing.assert_array_equal(record.u, expected.command)

    again = runner.invoke(drive_command, [str(config), "--out", str(out)])
    assert again.exit_code == 2 and "exists" in again.output  # one clean line, no traceback
    forced = runner.invoke(drive_command, [str(config), "--out", str(out), "--force",
                                           "--duration", "0.5"])
    assert forced.exit_code == 0 and "251 samples" in forced.output


def test_cli_preset_translational_units(tmp_path):
    out = tmp_path / "cart.csv"
    result = CliRunner().invoke(drive_command, ["--preset", "pendulum-cart", "--duration",
                                                "0.2", "--out", str(out)])
    assert result.exit_code == 0, result.output
    header = out.read_text(encoding="utf-8").splitlines()[2]
    assert header == "t [s],x1 [m],v1 [m/s],command [N]"


def test_cli_errors_through_the_main_group(tmp_path):
    import click

    from driveid.cli import cli

    # the main group may load its subcommands lazily: ask it, as click does
    ctx = click.Context(cli)
    simulate = cli.get_command(ctx, "simulate")
    if simulate is None or simulate.get_command(ctx, "drive") is None:
        pytest.skip("`driveid simulate drive` is not registered in driveid.cli (yet)")
    out = tmp_path / "run.csv"
    out.write_text("keep me", encoding="utf-8")
    result = CliRunner().invoke(cli, ["simulate", "drive", "--preset", "testbed-a",
                                      "--out", str(out)])
    assert result.exit_code == 2 and "error: " in result.output and "--overwrite" in result.output
    assert out.read_text(encoding="utf-8") == "keep me"
    bad = _write(tmp_path, "[[body]]\nJ = -1.0\n", "bad.toml")
    result = CliRunner().invoke(cli, ["simulate", "drive", str(bad), "--out",
                                      str(tmp_path / "b.csv")])
    assert result.exit_code == 2 and "body[1].J" in result.output


@pytest.mark.parametrize("args, match", [
    ([], "either a CONFIG.toml file or --preset"),
    (["x.toml", "--preset", "testbed-a"], "either a CONFIG.toml file or --preset"),
])
def test_cli_usage_errors(tmp_path, args, match):
    result = CliRunner().invoke(drive_command, args + ["--out", str(tmp_path / "o.csv")])
    assert result.exit_code == 2 and match in result.output


def test_cli_bad_suffix_and_duration(tmp_path):
    runner = CliRunner()
    result = runner.invoke(drive_command, ["--preset", "testbed-a", "--out",
                                           str(tmp_path / "o.npz")])
    # the command reports the ConfigError as one line with exit status 2
    assert result.exit_code == 2 and "error: " in result.output
    assert "name the file *.csv" in result.output
    result = runner.invoke(drive_command, ["--preset", "testbed-a", "--duration", "-1",
                                           "--out", str(tmp_path / "o.csv")])
    assert result.exit_code == 2
    # the option is checked where it is parsed (click) or by RunOptions: either names it
    assert "--duration" in result.output and "must be" in result.output


def test_cli_reports_an_abort(tmp_path):
    config = _write(tmp_path, TESTBED_TOML.replace("delay = 0.01377",
                                                   "delay = 0.01377\nabort_limit = 1.0"))
    out = tmp_path / "aborted.csv"
    result = CliRunner().invoke(drive_command, [str(config), "--out", str(out)])
    # the first command P·x0 = 10 N·m exceeds the limit: abort at t = 0
    assert result.exit_code == 0 and "aborted: |command| = 10 N·m" in result.output
    assert "0 samples" in result.output
    assert len(out.read_text(encoding="utf-8").splitlines()) == 3  # header only


# -- cost known before work (issue 28) ------------------------------------------------------

STIFF_TOML = """
[[body]]
J = 1e-6
[[body]]
J = 1e-6
[[link]]
type = "backlash"
gap_plus = 1e-3
gap_minus = 1e-3
k = 1e15
[run]
duration = 2
x0 = [1.0, 0.0]
"""


def test_cost_of_a_stiff_contact_from_its_period():
    """Steps from the contact's own period, computed here independently of the estimator."""
    params, run = parse_drive_config(tomllib.loads(STIFF_TOML))
    cost = estimate_drive_cost(params, duration=run.duration, fs=run.fs)
    omega = math.sqrt(1e15 * (1 + 1e-6 / 1e-6) / 1e-6)  # relative mode, reduced inertia
    n_sub = math.ceil(1e-3 / (0.2 / omega))  # RK4 step 0.2/ω inside each 1 ms sample
    assert cost.n_steps == 2000 * n_sub
    assert cost.period == pytest.approx(2 * math.pi / omega, rel=1e-12)
    assert cost.n_samples == 2001
    assert "link 1 (backlash contact k = 1e+15" in cost.stiffest


def test_a_stiff_contact_is_refused_at_once_naming_the_cause(tmp_path):
    config = _write(tmp_path, STIFF_TOML, "stiff.toml")
    result = CliRunner().invoke(drive_command, [str(config), "--out", str(tmp_path / "o.csv")])
    assert result.exit_code == 2, result.output
    line = result.output.strip()
    assert line.startswith("error: ") and "\n" not in line
    for words in ("RK4 steps", "backlash contact k = 1e+15", "period 1.4e-10 s",
                  "--max-steps", "lower k"):
        assert words in line, line
    assert not (tmp_path / "o.csv").exists()


def test_a_huge_rate_is_refused_before_allocating(tmp_path, monkeypatch):
    # a machine with 16 GiB free, whatever this one has (2e9 samples need ~300 GiB)
    monkeypatch.setattr("driveid.io.consistency.available_memory", lambda: 16 << 30)
    config = _write(tmp_path, 'preset = "testbed-a"\n[run]\nduration = 2\nfs = 1e9\n',
                    "fast.toml")
    result = CliRunner().invoke(drive_command, [str(config), "--out", str(tmp_path / "o.csv")])
    assert result.exit_code == 2, result.output
    assert "2e+09 samples" in result.output and "memory available" in result.output
    assert "--duration" in result.output


def test_max_steps_budget_refuses_and_none_lifts_it():
    params = preset("testbed-a")
    cost = estimate_drive_cost(params, duration=0.5, fs=1000.0)
    assert 0 < cost.n_steps < 10**6
    with pytest.raises(ParameterError, match="over the budget of 10 steps"):
        simulate_config(params, RunOptions(duration=0.5, x0=(1.0,) * params.n_bodies),
                        max_steps=10)
    with pytest.raises(ParameterError, match="max_steps must be a positive int"):
        simulate_config(params, RunOptions(duration=0.5), max_steps=0)


def test_the_exact_closed_form_takes_no_steps():
    params = preset("testbed-a")
    one = dataclasses.replace(params, bodies=params.bodies[:1], links=(), feedback=None)
    one = dataclasses.replace(one, bodies=(dataclasses.replace(one.bodies[0], K=16.0),))
    assert estimate_drive_cost(one, duration=1e3, fs=1e3).n_steps == 0
    assert estimate_drive_cost(one, duration=1e3, fs=1e3, method="rk4").n_steps > 0


def test_a_long_feasible_run_is_announced_with_its_estimate(tmp_path, monkeypatch):
    monkeypatch.setattr("driveid.commands.drive._ANNOUNCE_SECONDS", 0.0)  # announce any run
    out = tmp_path / "o.csv"
    result = CliRunner().invoke(drive_command, ["--preset", "testbed-a", "--duration", "0.2",
                                                "--max-steps", "1e12", "--out", str(out)])
    assert result.exit_code == 0, result.output
    announce = [line for line in result.stderr.splitlines() if line.startswith("simulating")]
    assert len(announce) == 1 and "RK4 steps" in announce[0] and "201 samples" in announce[0]
    assert out.exists()
