"""Command line of ``driveid identify transfer`` (through the registered group)."""

import json
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from driveid import cli as cli_module

FIXTURE = Path(__file__).parent / "fixtures" / "transfer" / "ced_like.csv"
# the fixture's truth (tests/fixtures/transfer/make_ced_like.py)
CED = {"omega0_1": 20.0, "zeta_1": 0.15, "sigma_1": 5.0}


def _run(*args):
    return CliRunner().invoke(cli_module.cli, ["identify", "transfer", *map(str, args)])


def _json(res):
    assert res.exit_code == 0, res.output
    return json.loads(res.stdout)


def test_coupled_drives_like_file_without_time_speed_magnitude_only():
    res = _run(FIXTURE, "--input", "u1", "--output", "z1", "--fs", 50, "--order", 3,
               "--output-nonlinearity", "abs", "--input-unit", "V", "--json")
    data = _json(res)
    par = data["parameters"]
    for name, truth in CED.items():
        # 4.4 standard errors: calibrated errors of a 500-sample record (false alarm 1e-5)
        assert abs(par[name]["value"] - truth) < 4.4 * par[name]["stderr"], name
    # 2 % (the acceptance of issue 25) for omega0, whose standard error is 0.2 %; zeta's is
    # 1.1 % on 500 samples at this noise, so 2 % would be a 1.8-sigma test (7 % false alarms)
    assert par["omega0_1"]["value"] == pytest.approx(CED["omega0_1"], rel=0.02)
    assert par["zeta_1"]["stderr"] < 0.02 * CED["zeta_1"]
    assert par["b_0"]["unit"] == "(rad/s)/(V)/s^3"  # a voltage command keeps its unit
    assert data["inputs"][0]["columns"] == {"u": "u1", "v": "z1"}
    assert data["data_used"]["output_nonlinearity"] == "abs"
    assert len(data["data_used"]["den"]) == 4  # third order, handed on as num/den
    # the saved result hands the model on: its poles carry the reported resonance
    from driveid.identify.core.estimate import Estimate
    from driveid.identify.forced.transfer import transfer_function

    poles = transfer_function(Estimate.from_dict(data)).poles
    assert np.max(np.abs(poles)) == pytest.approx(par["omega0_1"]["value"], rel=1e-9)


def test_order_chosen_by_bic_on_the_fixture():
    data = _json(_run(FIXTURE, "--input", "u3", "--output", "z3", "--fs", 50,
                      "--output-nonlinearity", "abs", "--max-order", 4, "--json"))
    bic = data["diagnostics"]["bic_by_order"]
    assert min(bic, key=bic.get) == "3"


def test_voltage_command_two_mass_with_a_free_gain():
    # the fixture's model has no zero: a load-side two-mass with c ≈ 0; a free gain needs
    # one mechanical value given (J_m), and is then in N·m per volt
    data = _json(_run(FIXTURE, "--input", "u2", "--output", "z2", "--fs", 50,
                      "--output-nonlinearity", "abs", "--input-unit", "V", "--structure",
                      "two-mass", "--side", "load", "--free", "gain", "--fix", "J_m=0.01",
                      "--json"))
    par = data["parameters"]
    assert par["gain"]["unit"] == "N·m/(V)" and not par["gain"]["fixed"]
    assert par["J_m"]["fixed"] and par["J_m"]["stderr"] is None
    for name in ("omega0_1", "zeta_1"):
        # 4.4 standard errors: calibrated errors (false alarm 1e-5)
        assert abs(par[name]["value"] - CED[name]) < 4.4 * par[name]["stderr"], name


def _two_mass_csv(tmp_path):
    from scipy.signal import cont2discrete, dlsim

    Jm, Jl, k, c, cm = 2e-3, 6e-3, 40.0, 0.02, 0.01
    A = np.array([[0, 1, -1], [-k / Jm, -(c + cm) / Jm, c / Jm], [k / Jl, c / Jl, -c / Jl]])
    B = np.array([[0.0], [1 / Jm], [0.0]])
    C = np.array([[0.0, 1.0, 0.0]])
    fs = 1000.0
    rng = np.random.default_rng(7)
    u = np.repeat(rng.choice([-0.2, 0.2], 1000), 4)
    Ad, Bd, Cd, Dd, _ = cont2discrete((A, B, C, np.zeros((1, 1))), 1 / fs, method="zoh")
    w = dlsim((Ad, Bd, Cd, Dd, 1 / fs), u)[1][:, 0]
    w = w + 0.02 * np.std(w) * rng.normal(size=w.size)
    path = tmp_path / "drive.csv"
    rows = "\n".join(f"{i / fs:.6f},{ui:.6f},{wi * 60 / (2 * np.pi):.8f}"
                     for i, (ui, wi) in enumerate(zip(u, w, strict=True)))
    path.write_text("t [s],tau [N·m],speed [rpm]\n" + rows + "\n")
    return path


def test_time_column_rpm_and_two_mass(tmp_path):
    path = _two_mass_csv(tmp_path)
    data = _json(_run(path, "--input", "tau", "--output", "speed", "--structure", "two-mass",
                      "--json"))
    par = data["parameters"]
    # rpm converted to rad/s at reading: J_m and J_l come out in kg·m² (2 %: 2 % noise
    # gives standard errors ~1e-3 relative)
    assert par["J_m"]["value"] == pytest.approx(2e-3, rel=0.02)
    assert par["J_l"]["value"] == pytest.approx(6e-3, rel=0.02)
    assert par["gain"]["fixed"] and par["c_l"]["fixed"]
    assert "omega0_1" in par and par["omega0_1"]["stderr"] > 0


def test_report_and_figure_with_bode_and_coherence(tmp_path):
    report, figure = tmp_path / "r.html", tmp_path / "f.png"
    res = _run(FIXTURE, "--input", "u2", "--output", "z2", "--fs", 50, "--order", 3,
               "--output-nonlinearity", "abs", "--report", report, "--figure", figure)
    assert res.exit_code == 0, res.output
    html = report.read_text()
    assert "data:image/png;base64" in html and "omega0_1" in html
    assert figure.stat().st_size > 10_000
    again = _run(FIXTURE, "--input", "u2", "--output", "z2", "--fs", 50, "--order", 3,
                 "--report", report)
    assert again.exit_code == 2 and "--overwrite" in again.output  # never overwritten


@pytest.mark.parametrize(("args", "message"), [
    (["--input", "u1", "--output", "z1"], "--fs HZ"),
    (["--input", "u9", "--output", "z1", "--fs", "50"], "for the command (--input)"),
    (["--input", "u1", "--output", "z9", "--fs", "50"], "for the output (--output)"),
    (["--input", "u1", "--output", "z1", "--fs", "50", "--fix", "J_m=1"], "--structure two-mass"),
    (["--input", "u1", "--output", "z1", "--fs", "50", "--structure", "two-mass",
      "--fix", "mass=1"], "--fix takes NAME=VALUE"),
    (["--input", "u1", "--output", "z1", "--fs", "0"], "--fs"),
    (["--input", "u1", "--output", "z1", "--fs", "50", "--order", "3",
      "--output-nonlinearity", "abs", "--strict"], "under --strict"),
])
def test_bad_input_is_one_error_line_exit_2(args, message):
    res = _run(FIXTURE, *args)
    assert res.exit_code == 2, res.output
    errors = [line for line in res.output.splitlines() if line.startswith("error:")]
    assert len(errors) == 1 and message in errors[0], res.output
    assert "Traceback" not in res.output


def test_a_position_column_read_as_speed_names_this_commands_options(tmp_path):
    t = np.arange(400) * 1e-3
    src = tmp_path / "pos.csv"
    src.write_text("t [s],x [rad],u [V]\n" + "\n".join(
        f"{a:.4f},{np.sin(9 * a):.6f},{np.sign(np.sin(31 * a)):.1f}" for a in t) + "\n")
    res = _run(src, "--input", "u", "--output", "x")
    assert res.exit_code == 2
    assert "--output-quantity position" in res.output and "--unit v=" not in res.output
    res = _run(src, "--input", "u", "--output", "x", "--output-unit", "furlong")
    assert res.exit_code == 2 and "--output-unit UNIT" in res.output
