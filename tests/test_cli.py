"""The command line as a user runs it: exit codes, files, JSON keys, errors without tracebacks."""

import json

import numpy as np
import pytest
from click.testing import CliRunner

from driveid.cli import cli


@pytest.fixture
def runner():
    return CliRunner()


def test_simulate_then_identify_json(runner, tmp_path):
    out = tmp_path / "decay.csv"
    res = runner.invoke(cli, ["simulate", "free-decay", "--out", str(out),
                              "--counts-per-rev", "8000"])
    assert res.exit_code == 0, res.output
    res = runner.invoke(cli, ["identify", "logdec", str(out), "--mass", "1", "--json"])
    assert res.exit_code == 0, res.output
    data = json.loads(res.stdout)
    # the default is the whole-record output-error fit (issue 13); --method peaks is the
    # least-squares log decrement
    assert data["schema"] == "driveid-result/1" and data["method"] == "output-error"
    assert set(data) >= {"driveid", "command", "inputs", "parameters", "covariance",
                         "diagnostics", "warnings"}
    params = data["parameters"]
    for key in ("omega0", "zeta_plus", "zeta_minus", "J", "K", "c_mean", "c_delta", "fk_mean",
                "fk_delta"):
        assert set(params[key]) == {"value", "stderr", "unit", "fixed"}
    # the given mass is fixed, with no standard error (never a misleading 0)
    assert params["J"]["fixed"] is True and params["J"]["stderr"] is None
    # defaults of `simulate free-decay` are Table 5.1 case 3 with Δc = 0.1, Δfk = 0.03
    assert params["fk_mean"]["value"] == pytest.approx(0.07, rel=5e-3)  # encoder bound of issue
    assert params["c_delta"]["value"] == pytest.approx(0.1, rel=5e-3)
    assert data["inputs"][0]["path"] == str(out) and data["inputs"][0]["rows"] > 0


def test_refuses_to_overwrite(runner, tmp_path):
    out = tmp_path / "decay.csv"
    assert runner.invoke(cli, ["simulate", "free-decay", "--out", str(out)]).exit_code == 0
    res = runner.invoke(cli, ["simulate", "free-decay", "--out", str(out)])
    assert res.exit_code == 2 and "--overwrite" in res.output and "Traceback" not in res.output
    assert runner.invoke(cli, ["simulate", "free-decay", "--out", str(out),
                               "--overwrite"]).exit_code == 0
    # the old flag stays as a hidden alias on simulate commands only
    assert runner.invoke(cli, ["simulate", "free-decay", "--out", str(out),
                               "--force"]).exit_code == 0
    assert "--force" not in runner.invoke(cli, ["simulate", "free-decay", "--help"]).output


def test_plain_csv_header_and_table(runner, tmp_path):
    from driveid.sim import OscillatorParams, simulate_free_decay

    rec = simulate_free_decay(OscillatorParams(J=1, K=16, c_mean=0.3, fk_mean=0.07), x0=1.0,
                              duration=15.0).record
    path = tmp_path / "plain.csv"
    path.write_text("t,x\n" + "\n".join(f"{a:.17g},{b:.17g}" for a, b in
                                         zip(rec.t, rec.x, strict=True)))
    res = runner.invoke(cli, ["identify", "logdec", str(path), "--stiffness", "16"])
    assert res.exit_code == 0, res.output
    assert "fk_mean" in res.output and "N·m" in res.output


@pytest.mark.parametrize(
    "content, message",
    [
        ("t,x\n" + "\n".join(f"{i / 1000},{np.nan if i == 5 else 0.0}" for i in range(50)),
         "non-finite"),
        ("t,x\n" + "\n".join(f"{(49 - i) / 1000},0" for i in range(50)), "time is not increasing"),
        ("t,x\n" + "\n".join(f"{i / 1000},1.0" for i in range(50)), "constant"),
        ("t,x\n0,1\n", "at least 8 samples"),
    ],
)
def test_bad_input_exits_2_with_message(runner, tmp_path, content, message):
    path = tmp_path / "bad.csv"
    path.write_text(content)
    res = runner.invoke(cli, ["identify", "logdec", str(path)])
    assert res.exit_code == 2, res.output
    assert message in res.output and "Traceback" not in res.output


def test_demo_writes_a_new_numbered_folder(runner, tmp_path):
    res = runner.invoke(cli, ["demo", "--out", str(tmp_path)])
    assert res.exit_code == 0, res.output
    run = tmp_path / "run-001"
    assert (run / "free_decay_oe.png").stat().st_size > 10_000
    est = json.loads((run / "estimate.json").read_text())
    assert est["method"] == "output-error"
    assert est["parameters"]["fk_mean"]["value"] == pytest.approx(0.07, rel=5e-3)  # 8000 c/rev
    html = (run / "report.html").read_text()
    assert "fk_mean" in html and "fixed (given)" in html  # J was given, not estimated
    # the demo's estimate and records validate: fit >= 99 %, white residuals (issue 13)
    res = runner.invoke(cli, ["validate", str(run / "estimate.json"),
                              str(run / "free_decay_pos.csv"), str(run / "free_decay_neg.csv"),
                              "--json"])
    assert res.exit_code == 0, res.output
    check = json.loads(res.stdout)
    assert check["fit"] >= 99.0 and check["whiteness"]["white"], check
    res = runner.invoke(cli, ["demo", "--out", str(tmp_path)])
    assert res.exit_code == 0 and (tmp_path / "run-002").is_dir()  # run-001 kept as it was


def test_result_schema_round_trip_and_series():
    from driveid.identify.core.estimate import Estimate, Parameter
    from driveid.sim import OscillatorParams, simulate_free_decay

    rec = simulate_free_decay(OscillatorParams(J=1, K=16, c_mean=0.3, fk_mean=0.07), x0=1.0,
                              duration=15.0).record
    from driveid.identify.free_decay.logdec import estimate_log_decrement

    est = estimate_log_decrement(rec, mass=1.0).with_inputs([rec])
    data = json.loads(est.to_json(command=["driveid", "identify", "logdec"]))
    assert data["command"] == ["driveid", "identify", "logdec"]
    assert "peak_t" not in data["data_used"]  # long arrays only with series=True
    assert len(est.to_dict(series=True)["data_used"]["peak_t"][0]) > 5
    back = Estimate.from_dict(data)
    assert back.params["K"] == est.params["K"] and back.params["J"].fixed
    assert back.inputs[0]["rows"] == rec.n and back.warnings == est.warnings
    cov = Estimate("m", {"a": Parameter(1.0, 0.1)},
                   covariance={"names": ["a"], "matrix": np.array([[0.01]])})
    again = Estimate.from_dict(json.loads(cov.to_json()))
    assert again.covariance["names"] == ["a"] and again.covariance["matrix"][0, 0] == 0.01
    with pytest.raises(ValueError, match="driveid-result/1"):
        Estimate.from_dict({"method": "x", "parameters": {}})


def test_plausibility_guards_name_cause_and_remedy():
    from driveid.identify.core._plausibility import check_plausibility
    from driveid.identify.core.estimate import Estimate, Parameter

    est = Estimate("idim", {"M": Parameter(-0.4, 0.1, "kg"), "Fv": Parameter(-2.0, 0.5, "N·s/m"),
                            "Fc": Parameter(0.01, 0.5, "N"), "K": Parameter(0.0, 1.0, "N/m",
                                                                            fixed=True),
                            "fk_delta": Parameter(0.001, 0.01, "N")})
    checked = check_plausibility(est)
    assert len(checked.warnings) == 3  # M, Fv, Fc; a fixed K and a signed delta are not judged
    assert "gravity" in checked.warnings[0] and "backlash" in checked.warnings[0]
    assert "one direction" in checked.warnings[1]
    assert "too little excitation" in checked.warnings[2]
    assert check_plausibility(checked).warnings == checked.warnings  # idempotent


def test_backlash_damper_inverse_fit_warns_not_silently_negative(runner, tmp_path):
    """Issue-11 acceptance: a sinusoidal test of a damper with backlash gives a warning.

    A pure damper (no mass) driven through a gap: while the gap is open the measured force is
    zero while the motor accelerates, so the least-squares mass comes out negative; the
    inverse-model fit must say so instead of returning it silently.
    """
    from driveid.commands._output import OutputOptions, emit
    from driveid.identify.core.estimate import Estimate, Parameter

    t = np.arange(4000) * 1e-3
    x = 0.01 * np.sin(2 * np.pi * 2 * t)
    v = np.gradient(x, t)
    a = np.gradient(v, t)
    gap = 0.002
    inside = np.abs(x) < 0.01 - gap  # crude backlash: force only near the ends of travel
    u = np.where(inside, 0.0, 50.0 * v)
    A = np.column_stack([a, v, np.sign(v)])
    theta, *_ = np.linalg.lstsq(A, u, rcond=None)
    est = Estimate("idim-lsq", {"M": Parameter(theta[0], 0.01, "kg"),
                                "Fv": Parameter(theta[1], 0.1, "N·s/m"),
                                "Fc": Parameter(theta[2], 0.1, "N")})
    import click

    @click.command()
    def show():
        emit(est, OutputOptions())

    res = runner.invoke(show, [])
    assert theta[0] < 0 and res.exit_code == 0
    assert res.stderr.startswith("warning: M = ") and "backlash" in res.stderr


def test_check_window_warns_when_the_model_misses_something(tmp_path):
    from driveid.commands.logdec import logdec_command
    from driveid.io import Record, write_record
    from driveid.sim import OscillatorParams, simulate_free_decay

    rec = simulate_free_decay(OscillatorParams(J=1, K=16, c_mean=0.3, c_delta=0.1,
                                               fk_mean=0.07, fk_delta=0.03),
                              x0=1.0, duration=12.0).record
    ok = write_record(rec, tmp_path / "ok.csv")
    # a sensor with a quadratic error: peak ratios depend on amplitude, not in the model
    bent = write_record(Record(t=rec.t, x=rec.x + 0.05 * rec.x * np.abs(rec.x)),
                        tmp_path / "bent.csv")
    runner = CliRunner()
    res = runner.invoke(logdec_command, [str(ok), "--mass", "1", "--check-window"])
    assert res.exit_code == 0 and res.stderr == ""  # exact model: moves < 3 s.e.
    res = runner.invoke(logdec_command, [str(bent), "--mass", "1", "--check-window"])
    assert res.exit_code == 0 and "standard errors) with the last 20 %" in res.stderr
