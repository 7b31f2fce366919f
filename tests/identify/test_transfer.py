"""identify/transfer: command-to-speed models of a simulated two-mass drive.

Truth is independent of the estimator: the drive's state matrix is written out here, its
resonance is the eigenvalue pair of that matrix, and the record is simulated by
``scipy.signal.cont2discrete`` (zero-order hold) and ``dlsim``, not by
:mod:`driveid.identify.forced.transfer_models`.
"""

import math

import numpy as np
import pytest
from scipy.signal import cont2discrete, dlsim, lfilter

from driveid.errors import ConfigError, ParameterError, RecordError
from driveid.identify.forced.transfer import estimate_transfer, to_control, transfer_function
from driveid.io import Record
from driveid.signal.excitation import multisine, prbs

FS = 1000.0  # [Hz]
TRUTH = {"J_m": 2e-3, "J_l": 6e-3, "k": 40.0, "c": 0.02, "c_m": 0.01}  # SI


def _matrices(p=TRUTH, side="motor"):
    """States Δθ = θm - θl, ωm, ωl; torque on the motor; speed output."""
    Jm, Jl, k, c, cm = p["J_m"], p["J_l"], p["k"], p["c"], p["c_m"]
    A = np.array([[0.0, 1.0, -1.0],
                  [-k / Jm, -(c + cm) / Jm, c / Jm],
                  [k / Jl, c / Jl, -c / Jl]])
    B = np.array([[0.0], [1.0 / Jm], [0.0]])
    C = np.array([[0.0, 1.0, 0.0]]) if side == "motor" else np.array([[0.0, 0.0, 1.0]])
    return A, B, C


def _true_resonance(side="motor"):
    poles = np.linalg.eigvals(_matrices(side=side)[0])
    p = poles[np.argmax(poles.imag)]
    return abs(p), -p.real / abs(p)


def _simulate(u, side="motor"):
    A, B, C = _matrices(side=side)
    Ad, Bd, Cd, Dd, _ = cont2discrete((A, B, C, np.zeros((1, 1))), 1 / FS, method="zoh")
    _, y, _ = dlsim((Ad, Bd, Cd, Dd, 1 / FS), u)
    return y[:, 0]


def _record(kind, seed, *, rel_noise=0.05, ar=0.0, absolute=False, duration=4.0, side="motor"):
    if kind == "prbs":
        u = prbs(f_clock=250, duration=duration, fs=FS, amplitude=0.2).u
    else:
        u = multisine(f_min=0.5, f_max=150, duration=duration, fs=FS, amplitude=0.2,
                      period=2.0).u
    y = _simulate(u, side)
    rng = np.random.default_rng(seed)
    noise = lfilter([1.0], [1.0, -ar], rng.normal(size=u.size))
    noise *= rel_noise * np.std(y) / np.std(noise)
    y = (np.abs(y) if absolute else y) + noise
    t = np.arange(u.size) / FS
    return Record(t=t, x=np.zeros_like(t), v=y, u=u)


def test_two_mass_resonance_of_the_hand_written_matrix_is_the_closed_form():
    # with c = c_m = 0 the eigenvalue pair is ω0² = k (J_m + J_l)/(J_m J_l) exactly
    p = dict(TRUTH, c=0.0, c_m=0.0)
    poles = np.linalg.eigvals(_matrices(p)[0])
    expected = math.sqrt(p["k"] * (p["J_m"] + p["J_l"]) / (p["J_m"] * p["J_l"]))
    assert np.max(np.abs(poles)) == pytest.approx(expected, rel=1e-12)  # roundoff only


@pytest.mark.parametrize("side", ["motor", "load"])
def test_two_mass_start_inverts_the_transfer_coefficients_exactly(side):
    from driveid.identify.forced.transfer import _two_mass_from_coefficients

    A, B, C = _matrices(side=side)
    values = _two_mass_from_coefficients(A, B, C, side, "speed")
    for name, truth in TRUTH.items():
        # an algebraic inverse of the hand-written model: roundoff only
        assert values[name] == pytest.approx(truth, rel=1e-9), name


@pytest.mark.parametrize("kind", ["prbs", "multisine"])
@pytest.mark.parametrize("structure", ["tf", "two-mass"])
def test_resonance_within_2_percent_and_within_its_error(kind, structure):
    w0, z0 = _true_resonance()
    rec = _record(kind, seed=11)
    est = estimate_transfer(rec, structure=structure, **({"order": 3} if structure == "tf"
                                                           else {}),
                            period=2.0 if kind == "multisine" else None)
    w, z = est["omega0_1"], est["zeta_1"]
    # acceptance of issue 25: 2 %; at 5 % output noise the standard errors are ~1e-4
    # relative, so 2 % holds by far and the honest check is the next one
    assert w.value == pytest.approx(w0, rel=0.02)
    assert z.value == pytest.approx(z0, rel=0.02)
    # 4.4 standard errors: a 1e-5 false-alarm rate for a calibrated normal error
    assert abs(w.value - w0) < 4.4 * w.stderr
    assert abs(z.value - z0) < 4.4 * z.stderr
    if structure == "two-mass":
        for name, value in TRUTH.items():
            assert abs(est.value(name) - value) < 4.4 * est.stderr(name), name
        assert est["gain"].fixed and math.isnan(est["gain"].stderr)


def test_speed_magnitude_sensor_abs():
    w0, z0 = _true_resonance()
    rec = _record("prbs", seed=5, absolute=True)
    for structure in ("tf", "two-mass"):
        est = estimate_transfer(rec, structure=structure, output_nonlinearity="abs",
                                **({"order": 3} if structure == "tf" else {}))
        # the same 2 % acceptance; the sign of the gain is lost, the resonance is not
        assert est.value("omega0_1") == pytest.approx(w0, rel=0.02)
        assert est.value("zeta_1") == pytest.approx(z0, rel=0.02)
        assert abs(est.value("omega0_1") - w0) < 4.4 * est.stderr("omega0_1")
        assert any("sign" in w for w in est.warnings)


def test_load_side_speed_two_mass():
    w0, z0 = _true_resonance("load")
    rec = _record("prbs", seed=3, side="load")
    est = estimate_transfer(rec, structure="two-mass", side="load")
    assert abs(est.value("omega0_1") - w0) < 4.4 * est.stderr("omega0_1")
    assert abs(est.value("J_l") - TRUTH["J_l"]) < 4.4 * est.stderr("J_l")


def test_position_output_resonance():
    # motor angle from torque: a double integrator behind the two-mass speed response
    A3, B3, _ = _matrices()
    A = np.zeros((4, 4))
    A[0, 2] = 1.0  # θm' = ωm, then the speed states (Δθ, ωm, ωl) as before
    A[1:, 1:] = A3
    B = np.vstack([[0.0], B3])
    C = np.array([[1.0, 0.0, 0.0, 0.0]])
    u = prbs(f_clock=250, duration=3.0, fs=FS, amplitude=0.2).u
    Ad, Bd, Cd, Dd, _ = cont2discrete((A, B, C, np.zeros((1, 1))), 1 / FS, method="zoh")
    x = dlsim((Ad, Bd, Cd, Dd, 1 / FS), u)[1][:, 0]
    x = x + 1e-5 * np.random.default_rng(0).normal(size=x.size)  # 10 µrad encoder noise
    t = np.arange(u.size) / FS
    est = estimate_transfer(Record(t=t, x=x, u=u), output="x", order=4, relative_degree=2)
    w0, z0 = _true_resonance()
    # the 2 % acceptance; error bars of position fits are not yet checked by Monte Carlo
    assert est.value("omega0_1") == pytest.approx(w0, rel=0.02)
    assert est.value("zeta_1") == pytest.approx(z0, rel=0.02)


def test_order_by_bic_is_three_and_the_lti_hand_over():
    rec = _record("prbs", seed=2)
    est = estimate_transfer(rec, max_order=4)
    bic = est.diagnostics["bic_by_order"]
    assert min(bic, key=bic.get) == "3"  # the drive has three states
    tf = transfer_function(est)
    poles = np.sort_complex(tf.poles)
    w0, _ = _true_resonance()
    # the LTI system carries the same resonance as the parameters (one model, two views)
    assert np.max(np.abs(poles)) == pytest.approx(est.value("omega0_1"), rel=1e-9)
    assert np.max(np.abs(poles)) == pytest.approx(w0, rel=0.02)
    try:
        import control  # noqa: F401
    except ImportError:
        with pytest.raises(ConfigError, match="python-control is not installed"):
            to_control(est)
    else:  # pragma: no cover - python-control is not a dependency
        assert to_control(est) is not None


def test_coloured_noise_gets_an_ar_model_and_the_frf_has_coherence():
    rec = _record("multisine", seed=4, ar=0.8)
    est = estimate_transfer(rec, order=3, period=2.0)
    assert est.diagnostics["noise_model"]["order"] >= 1  # AR(1) noise is not white
    coh = np.asarray(est.data_used["coherence"])
    f = np.asarray(est.data_used["f"])
    assert coh.size == f.size > 10 and np.all((coh >= 0) & (coh <= 1))
    # the model's ZOH response follows the data's H1 where coherence is high (5 % noise:
    # per-line random error ~ sqrt(1-γ²)/γ/sqrt(2 n_d) < 10 %)
    good = coh > 0.99
    rel = np.abs(np.asarray(est.data_used["model_magnitude"])[good]
                 / np.asarray(est.data_used["frf_magnitude"])[good] - 1)
    assert np.median(rel) < 0.05


def test_coverage_of_95_percent_intervals_small_monte_carlo():
    # 24 seeded realisations with AR(1) noise (short records, 1.5 s): the intervals must
    # cover the truth in >= 19 of 24; for true 95 % coverage P(X <= 18) = 0.8 %. Measured
    # today: 24 and 22 of 24 with the AR noise model; white-noise error bars
    # (noise_model=False) cover only 18 and 15 of 24 on the same records, and fail
    w0, z0 = _true_resonance()
    hits_w = hits_z = 0
    n = 24
    for seed in range(n):
        rec = _record("prbs", seed=100 + seed, ar=0.6, rel_noise=0.2, duration=1.5)
        est = estimate_transfer(rec, order=3)
        hits_w += abs(est.value("omega0_1") - w0) < 1.96 * est.stderr("omega0_1")
        hits_z += abs(est.value("zeta_1") - z0) < 1.96 * est.stderr("zeta_1")
    assert hits_w >= 19 and hits_z >= 19, (hits_w, hits_z)


def test_errors():
    rec = _record("prbs", seed=1, duration=0.5)
    t = rec.t
    with pytest.raises(RecordError, match="command"):
        estimate_transfer(Record(t=t, x=rec.v, v=rec.v))
    with pytest.raises(RecordError, match="constant"):
        estimate_transfer(Record(t=t, x=rec.v, v=rec.v, u=np.ones_like(t)))
    with pytest.raises(ParameterError, match="structure"):
        estimate_transfer(rec, structure="three-mass")
    with pytest.raises(ParameterError, match="output_nonlinearity"):
        estimate_transfer(rec, output_nonlinearity="square")
    with pytest.raises(ParameterError, match="not identifiable"):
        estimate_transfer(rec, structure="two-mass", fixed={})
    with pytest.raises(ParameterError, match="unknown two-mass"):
        estimate_transfer(rec, structure="two-mass", fixed={"mass": 1.0, "gain": 1.0})
    with pytest.raises(ParameterError, match="order"):
        estimate_transfer(rec, order=0)
    with pytest.raises(ParameterError, match="carries no transfer function"):
        from driveid.identify.core.estimate import Estimate

        transfer_function(Estimate("logdec-lsq", {}))


def test_jittery_clock_is_resampled_and_warned():
    """Issue 24 item 5: a clock 20 % jittery (a controller that samples and updates at the
    same uneven instants) is put on the median grid, linearly, with a warning, and the
    first-order plant is still found; truth: the exact response, interval by interval."""
    from driveid.errors import RecordWarning

    rng = np.random.default_rng(4)
    dt, n, sigma = 1e-3, 3000, 20.0
    t = dt * np.arange(n) + rng.uniform(-0.2 * dt, 0.2 * dt, n)
    t[0] = 0.0
    u = np.sign(rng.standard_normal(n // 10)).repeat(10)  # u[k] acts on [t_k, t_k+1)
    v = np.zeros(n)
    for i in range(1, n):  # dv/dt = sigma (u - v), exact over each uneven interval
        a = math.exp(-sigma * (t[i] - t[i - 1]))
        v[i] = a * v[i - 1] + (1 - a) * u[i - 1]
    rec = Record(t=t, x=np.zeros(n), v=v + 1e-4 * rng.standard_normal(n), u=u,
                 max_jitter=None)
    with pytest.warns(RecordWarning, match="resampled linearly"):
        est = estimate_transfer(rec, order=1)
    # interpolation smears each switch over one grid step: 0.4 % on sigma, 0.2 % on the
    # gain measured (holding the last sample instead: 1.3 % and 2.4 %); 1 % leaves room
    assert est.value("sigma_1") == pytest.approx(sigma, rel=0.01)
    assert est.value("b_0") == pytest.approx(sigma, rel=0.01)
