"""Tests of driveid.identify.friction.idim: synthetic truth and the EMPS benchmark's published
values."""

from pathlib import Path

import numpy as np
import pytest

from driveid.errors import IdentificationError, ParameterError, RecordError
from driveid.identify.core.estimate import Estimate
from driveid.identify.friction.idim import estimate_idim, idim_regressor, validate_idim
from driveid.io.record import Record

DATA = Path(__file__).resolve().parents[2].parent / "shared" / "data" / "EMPS"
EMPS_KW = dict(columns={"x": "qm", "u": "vir"}, scale={"u": "gtau"}, units={"x": "m", "u": "N"})


def _synthetic(asym: bool = False, noise: float = 0.5, seed: int = 0) -> Record:
    # noise-free Coulomb jumps in u would trip Record's corrupted-burst detector
    t = np.arange(8000) / 1000.0
    w1, w2 = 2 * np.pi * 0.4, 2 * np.pi * 1.3
    x = 0.05 * np.sin(w1 * t) + 0.01 * np.sin(w2 * t)
    v = 0.05 * w1 * np.cos(w1 * t) + 0.01 * w2 * np.cos(w2 * t)
    a = -0.05 * w1**2 * np.sin(w1 * t) - 0.01 * w2**2 * np.sin(w2 * t)
    if asym:
        u = (10.0 * a + np.where(v > 0, 40.0 * v + 3.0, 0.0)
             + np.where(v < 0, 60.0 * v - 4.0, 0.0))
    else:
        u = 10.0 * a + 50.0 * v + 3.0 * np.sign(v) - 0.5
    u = u + noise * np.random.default_rng(seed).standard_normal(t.size)
    return Record(t=t, x=x, u=u, meta={"units": {"x": "m", "u": "N"}})


def test_symmetric_synthetic_recovers_truth():
    est = estimate_idim(_synthetic(noise=0.5), cutoff_hz=50.0)
    truth = {"M": 10.0, "Fv": 50.0, "Fc": 3.0, "offset": -0.5}
    for name, value in truth.items():
        # noise 0.5 N on 8000 samples: 4 standard errors bound a correct estimate
        assert abs(est.value(name) - value) < 4 * est.stderr(name) + 1e-3 * abs(value), name
    assert est["M"].unit == "kg" and est["Fv"].unit == "N·s/m"


def test_asymmetric_synthetic_recovers_truth():
    est = estimate_idim(_synthetic(asym=True), model="asymmetric", cutoff_hz=50.0)
    truth = {"M": 10.0, "Fv_plus": 40.0, "Fc_plus": 3.0, "Fv_minus": 60.0, "Fc_minus": 4.0}
    for name, value in truth.items():
        # 0.5 N noise: 4 standard errors, plus 0.5 % for smoothing of the sign columns
        assert abs(est.value(name) - value) < 4 * est.stderr(name) + 5e-3 * value, name


def test_rotational_units_use_J():
    rec = _synthetic()
    rec = Record(t=rec.t, x=rec.x, u=rec.u, meta={"units": {"x": "rad", "u": "N·m"}})
    est = estimate_idim(rec, cutoff_hz=50.0)
    assert "J" in est and est["J"].unit == "kg·m²"


def test_errors():
    rec = _synthetic()
    with pytest.raises(RecordError, match="needs the applied force"):
        estimate_idim(Record(t=rec.t, x=rec.x))
    with pytest.raises(ParameterError, match="model must be one of"):
        estimate_idim(rec, model="lugre")
    with pytest.raises(ParameterError, match="decimate must be"):
        estimate_idim(rec, decimate=0)
    with pytest.raises(ParameterError, match="cutoff_hz must be below"):
        estimate_idim(rec, cutoff_hz=600.0)
    one_way = Record(t=rec.t, x=rec.t * 0.1 + 0.01 * rec.t**2, u=rec.u)
    with pytest.raises(IdentificationError, match="other direction"):
        estimate_idim(one_way)
    # the asymmetric model identifies the travelled branch and flags the other one
    half = estimate_idim(one_way, model="asymmetric", cutoff_hz=50.0)
    assert np.isnan(half.value("Fc_minus")) and any("not identifiable" in w
                                                    for w in half.warnings)
    still = Record(t=rec.t, x=np.zeros_like(rec.t), u=rec.u)
    with pytest.raises(IdentificationError, match="never moves"):
        estimate_idim(still)
    with pytest.raises(RecordError, match="too short"):
        idim_regressor(Record(t=rec.t[:200], x=rec.x[:200], u=rec.u[:200]))
    with pytest.raises(IdentificationError, match="estimate made by estimate_idim"):
        validate_idim(Estimate(method="other", params={}), rec)


@pytest.fixture(scope="module")
def emps():
    if not (DATA / "DATA_EMPS.mat").is_file():
        pytest.skip("../shared/data/EMPS is absent")
    from driveid.io.files import read_record

    # no warning expected: the PULSES file's 5 V steps are in u, which a force may do
    return (read_record(DATA / "DATA_EMPS.mat", **EMPS_KW),
            read_record(DATA / "DATA_EMPS_PULSES.mat", **EMPS_KW))


@pytest.mark.shared_data
def test_emps_symmetric_within_one_published_sigma(emps):
    est = estimate_idim(emps[0])
    published = {"M": (95.1089, 0.1085), "Fv": (203.5034, 1.1460), "Fc": (20.3935, 0.1012),
                 "offset": (-3.1648, 0.0444)}
    for name, (value, sigma) in published.items():
        # acceptance rule of the task: within one published standard deviation
        assert abs(est.value(name) - value) < sigma, (name, est.value(name))
        # the white-noise standard errors follow the published formula: within 10 %
        assert est.diagnostics["stderr_white"][name] == pytest.approx(sigma, rel=0.1), name
        # the residuals are strongly coloured (AR(~20), n_eff ~ 40 of 2475 rows) and the
        # model is not adequate: honest error bars are wider than the white-noise ones
        assert est.stderr(name) > 1.5 * sigma, name
    assert est.diagnostics["adequacy"]["covariance"].startswith("sandwich")
    assert any("not white" in w for w in est.warnings)
    # published cond 25.9883, relative error 4.0834 %
    assert est.diagnostics["cond"] == pytest.approx(25.9883, rel=0.01)
    assert est.diagnostics["relative_error_pct"] == pytest.approx(4.0834, rel=0.03)
    val = validate_idim(est, emps[1])
    # published cross-test relative error 5.9824 %, cond 26.0217. The rows are block means
    # now, not EMPS's Chebyshev decimation (issue 24: its stopband coloured the noise); they
    # keep the band the Chebyshev removed above 0.8 of the new Nyquist, so the error norm
    # holds a little more noise: 6.24 % measured, hence 5 % (was 3 %)
    assert val.relative_error == pytest.approx(5.9824, rel=0.05)
    assert val.cond == pytest.approx(26.0217, rel=0.01)


@pytest.mark.shared_data
def test_emps_asymmetric_within_one_percent(emps):
    est = estimate_idim(emps[0], model="asymmetric")
    published = {"M": 95.1540, "Fv_plus": 166.7061, "Fc_plus": 20.1440,
                 "Fv_minus": 240.4236, "Fc_minus": 20.6277}
    for name, value in published.items():
        # acceptance rule of the task: 1 %
        assert est.value(name) == pytest.approx(value, rel=0.01), name
    assert "offset" not in est
    # published relative error 3.1117 %
    assert est.diagnostics["relative_error_pct"] == pytest.approx(3.1117, rel=0.05)


def test_idim_command_synthetic_and_error(tmp_path):
    from click.testing import CliRunner

    from driveid.commands.friction import idim_command
    from driveid.io import write_record

    path = write_record(_synthetic(), tmp_path / "rec.csv")
    res = CliRunner().invoke(idim_command, [str(path), "--validate", str(path), "--units", "m",
                                            "--cutoff-hz", "50", "--figure",
                                            str(tmp_path / "f.png")])
    assert res.exit_code == 0, res.output
    assert "cross-test" in res.output and (tmp_path / "f.png").is_file()
    res = CliRunner().invoke(idim_command, [str(path), "--cutoff-hz", "900"])
    assert res.exit_code == 2 and res.output.startswith("error: --cutoff-hz must be below")
    res = CliRunner().invoke(idim_command, [str(path), "--cutoff-hz", "50", "--simulate"])
    assert res.exit_code == 2 and "reads the EMPS loop variables" in res.output


@pytest.mark.shared_data
def test_emps_command_line(emps):
    from click.testing import CliRunner

    from driveid.commands.friction import idim_command

    res = CliRunner().invoke(idim_command, [
        str(DATA / "DATA_EMPS.mat"), "--validate", str(DATA / "DATA_EMPS_PULSES.mat"),
        "--position", "qm", "--force-column", "vir", "--force-scale", "gtau",
        "--units", "m", "--json"])
    assert res.exit_code == 0, res.output
    import json

    out = json.loads(res.stdout)
    assert out["parameters"]["M"]["value"] == pytest.approx(95.1089, abs=0.1085)
    # published cross-test relative error 5.9824 % (5 %: block means, see above)
    assert out["diagnostics"]["validation"]["relative_error_pct"] == pytest.approx(5.9824, rel=0.05)


@pytest.mark.shared_data
def test_emps_direct_simulation_within_published_errors(emps):
    from scipy.io import loadmat

    from driveid.identify.friction.idim import simulate_idim_model

    est = estimate_idim(emps[0])
    for rec, name, pub_pos, pub_force in ((emps[0], "DATA_EMPS.mat", 0.013752, 5.848),
                                          (emps[1], "DATA_EMPS_PULSES.mat", 0.0080248, 8.9409)):
        d = loadmat(DATA / name)
        pulses = d["pulses_N"].ravel().astype(float) if "pulses_N" in d else None
        sim = simulate_idim_model(est, rec, q_ref=d["qg"].ravel(), kp=d["kp"].item(),
                                  kv=d["kv"].item(), gtau=d["gtau"].item(),
                                  input_offset=pulses)
        # published direct-simulation errors (EMPS §3.5) are upper bounds for ours: we
        # measure 0.0012 % / 5.24 % and 0.0017 % / 5.91 %
        assert sim.position_error_pct < pub_pos, name
        assert sim.force_error_pct < pub_force, name


def test_simulate_idim_model_errors():
    from driveid.identify.friction.idim import simulate_idim_model

    rec = _synthetic()
    est = estimate_idim(rec, cutoff_hz=50.0)
    with pytest.raises(ParameterError, match="q_ref must have"):
        simulate_idim_model(est, rec, q_ref=np.zeros(3), kp=1.0, kv=1.0, gtau=1.0)
    with pytest.raises(ParameterError, match="kp must be"):
        simulate_idim_model(est, rec, q_ref=rec.x, kp=0.0, kv=1.0, gtau=1.0)
    with pytest.raises(IdentificationError, match="estimate made by estimate_idim"):
        simulate_idim_model(Estimate(method="x", params={}), rec, q_ref=rec.x, kp=1.0,
                            kv=1.0, gtau=1.0)
    # the loop tracks the reference with a lag of about |v|/kp = 0.3/160 m against a
    # 0.05 m amplitude: a few per cent
    sim = simulate_idim_model(est, rec, q_ref=rec.x, kp=160.0, kv=240.0, gtau=35.0)
    assert sim.position_error_pct < 5.0


def test_standstill_is_found_on_a_noisy_sensor_too():
    """Stick phases must be dropped whether the sensor is quantised or merely noisy.

    A slow sine torque on J = 0.02, Fv = 0.06, Fc = 0.1 sticks at every reversal. Before
    the noise-aware standstill test, 1e-6 rad of white noise hid every stop (the smallest
    step became ~1e-9) and Fc came out 0.087 instead of 0.097 (the clean record's value at
    this cut-off); the noisy estimate must now agree with the clean one.
    """
    from driveid.sim import BodyParams, DriveParams, simulate_drive

    t = np.arange(4001) / 1000.0
    u = 0.4 * np.sin(np.pi * t) + 0.2 * np.sin(2 * np.pi * 1.7 * t)
    res = simulate_drive(DriveParams(bodies=(BodyParams(J=0.02, c_mean=0.06, fk_mean=0.1),)),
                         duration=4.0, fs=1000.0, x0=[0.05], v0=[0.2],
                         torque=(u - 0.02)[None, :], max_step=2e-5)
    clean = Record(t=res.t, x=res.x[0], u=u)
    ref = estimate_idim(clean, cutoff_hz=20.0, sensitivity=False)
    for std in (1e-6, 1e-5):
        noisy = clean.replace(x=clean.x + np.random.default_rng(3).normal(0.0, std, clean.n))
        est = estimate_idim(noisy, cutoff_hz=20.0, sensitivity=False)
        # 1 %: the noise moves Fc by ~0.1 % here; the missed stops moved it by 11 %
        assert est.value("Fc") == pytest.approx(ref.value("Fc"), rel=0.01)
        assert est.value("Fv") == pytest.approx(ref.value("Fv"), rel=0.01)


def test_loose_parameters_are_named_with_advice_that_fits_them():
    """A small offset under noise: the warning names it and does not ask for more motion;
    a weakly excited Coulomb term gets the excitation advice."""
    rec = _synthetic(noise=0.5)
    small = Record(t=rec.t, x=rec.x, u=rec.u + 0.5 - 0.01, meta=rec.meta)  # offset -0.01 N
    est = estimate_idim(small, sensitivity=False)
    # offset s.e. 0.006 N against a value of 0.010 N (56 %); Fc below: 0.007 ± 0.011 N
    loose = [w for w in est.warnings if "above 30 %" in w]
    assert len(loose) == 1 and "offset ±" in loose[0] and "--offset 0" in loose[0]
    assert "excite" not in loose[0]
    weak = Record(t=rec.t, x=rec.x, u=rec.u - 3.0 * np.sign(np.gradient(rec.x)) + 0.01 *
                  np.sign(np.gradient(rec.x)), meta=rec.meta)  # Fc 0.01 N, s.e. ~0.01 N
    est = estimate_idim(weak, sensitivity=False)
    loose = [w for w in est.warnings if "above 30 %" in w]
    assert len(loose) == 1 and "Fc ±" in loose[0] and "excite" in loose[0], est.warnings
