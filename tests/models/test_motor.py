"""Tests of driveid.models.motor against the motor's state equations."""

import numpy as np
import pytest
from scipy.signal import StateSpace

from driveid.errors import ParameterError
from driveid.models import motor as mo

DC = mo.DCMotorParams(k_m=0.05, J_m=2e-5, R_m=1.2, L_m=1e-3, k_emf=0.05, nu_m=1e-4)
W = np.logspace(0, 5, 60)  # rad/s


def _freq(sys, w=W):
    """Frequency response evaluated directly (no conversions between representations)."""
    s = 1j * np.asarray(w)
    if isinstance(sys, StateSpace):
        n = sys.A.shape[0]
        return np.array([(sys.C @ np.linalg.solve(si * np.eye(n) - sys.A, sys.B))[0, 0]
                         for si in s])
    return np.polyval(sys.num, s) / np.polyval(sys.den, s)


def _voltage_state_space(p, L):
    """theta/v_a from J w' = -nu w + k_m i, L i' = -R i - k_emf w + v, theta' = w."""
    if L > 0:
        A = [[0, 1, 0], [0, -p.nu_m / p.J_m, p.k_m / p.J_m], [0, -p.k_emf / L, -p.R_m / L]]
        return StateSpace(A, [[0], [0], [1 / L]], [[1, 0, 0]], [[0]])
    # L = 0: i = (v - k_emf w)/R eliminated
    A = [[0, 1], [0, -(p.nu_m + p.k_m * p.k_emf / p.R_m) / p.J_m]]
    return StateSpace(A, [[0], [p.k_m / (p.R_m * p.J_m)]], [[1, 0]], [[0]])


def test_dc_full_form_equals_state_equations_times_impedance():
    ss = _voltage_state_space(DC, DC.L_m)
    expected = _freq(ss) * (DC.L_m * 1j * W + DC.R_m)  # (2.105) input is v_a/(L s + R)
    got = _freq(mo.dc_motor_tf(DC))
    err = np.max(np.abs(got / expected - 1))
    print(f"(2.105) vs state equations: max rel err {err:.1e}")
    assert err < 1e-10  # same rational function, rounding only


def test_dc_reduced_form_and_amplifier():
    p = mo.DCMotorParams(k_m=0.05, J_m=2e-5, R_m=1.2, L_m=0.0, k_emf=0.05, nu_m=1e-4)
    expected = _freq(_voltage_state_space(p, 0.0)) * p.R_m
    got = _freq(mo.dc_motor_tf(p, reduced=True))
    assert np.max(np.abs(got / expected - 1)) < 1e-10  # exact, rounding only
    # (2.106) is the L -> 0 limit of (2.105) with k_emf = k_m: tiny L changes it by ~ L w/R.
    p_small_l = mo.DCMotorParams(k_m=0.05, J_m=2e-5, R_m=1.2, L_m=1e-9, k_emf=0.05, nu_m=1e-4)
    diff = np.max(np.abs(_freq(mo.dc_motor_tf(p_small_l)) / got - 1))
    print(f"(2.105) with L=1e-9 H vs (2.106): max rel diff {diff:.1e}")
    assert diff < 1e-6  # L w_max / R ~ 1e-4 at most, and it cancels to first order
    amp = mo.dc_motor_tf(p, reduced=True, amplifier_gain=3.0)  # (2.108)
    np.testing.assert_allclose(_freq(amp), 3.0 * got, rtol=1e-12)


def test_dc_presliding_friction_gives_spring_gain():
    # mu = sigma0/s (presliding spring): static angle per amp = k_m/sigma0.
    sigma0 = 2.0
    tf = mo.dc_motor_tf(DC, friction=([sigma0], [1.0, 0.0]), reduced=True)
    h0 = _freq(tf, np.array([1e-6]))[0]
    assert h0.real == pytest.approx(DC.k_m / sigma0, rel=1e-6)  # w = 1e-6 vs corner ~1e4


def test_dc_split_branches():
    tfs = mo.dc_motor_tf_split(DC, friction_plus=1e-4, friction_zero=([2.0], [1.0, 0.0]),
                               friction_minus=3e-4, amplifier_gain=2.0)
    assert set(tfs) == {"plus", "zero", "minus"}
    for key, fr in (("plus", 1e-4), ("minus", 3e-4)):
        ref = mo.dc_motor_tf(DC, friction=fr, reduced=True, amplifier_gain=2.0)
        np.testing.assert_allclose(_freq(tfs[key]), _freq(ref), rtol=1e-12)
    # Steady speed per volt differs by direction: k_a k_m R/(mu R + k_m^2).
    for key, mu in (("plus", 1e-4), ("minus", 3e-4)):
        w = 1e-3
        speed_gain = abs(_freq(tfs[key], np.array([w]))[0] * 1j * w)
        expected = 2.0 * DC.k_m * DC.R_m / (mu * DC.R_m + DC.k_m**2)
        assert speed_gain == pytest.approx(expected, rel=1e-6)  # w = 1e-3 far below the pole


def test_ac_motor():
    p = mo.ACMotorParams(k_m=3.0, J_m=0.02, nu_m=0.01, p=-0.03)
    assert p.time_constant == pytest.approx(0.5)
    tf = mo.ac_motor_tf(p)
    np.testing.assert_allclose(np.sort(tf.poles.real), [-2.0, 0.0], atol=1e-12)
    w = 1e-4
    assert abs(_freq(tf, np.array([w]))[0] * 1j * w) == pytest.approx(3.0, rel=1e-7)  # speed/V
    big = mo.ac_motor_tf(p, large_inertia=True)
    w_hi = np.array([1e4])  # w t_m = 5000
    ratio = abs(_freq(tf, w_hi)[0] / _freq(big, w_hi)[0])
    assert ratio == pytest.approx(1.0, abs=1e-6)  # asymptote: error ~ 1/(2 (w t_m)^2)


GOOD = dict(k_m=0.1, J_m=1.0, R_m=1.0, L_m=0.0, k_emf=0.1, nu_m=0.0)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({**GOOD, "J_m": -1.0}, r"J_m must be positive.*got -1.0"),
        ({**GOOD, "R_m": 0.0}, "R_m must be positive"),
        ({**GOOD, "L_m": -1.0}, "L_m must be non-negative"),
        ({**GOOD, "nu_m": np.nan}, "nu_m must be finite"),
        ({**GOOD, "k_emf": 0.0}, "k_emf must be positive"),
    ],
)
def test_bad_dc_params(kwargs, match):
    with pytest.raises(ParameterError, match=match):
        mo.DCMotorParams(**kwargs)


def test_bad_ac_params_and_arguments():
    with pytest.raises(ParameterError, match="nu_m - p must be positive"):
        mo.ACMotorParams(k_m=1.0, J_m=1.0, nu_m=0.1, p=0.2)
    with pytest.raises(ParameterError, match="k_m must be positive"):
        mo.ACMotorParams(k_m=0.0, J_m=1.0, nu_m=0.1, p=0.0)
    with pytest.raises(ParameterError, match="amplifier_gain k_a must be positive"):
        mo.dc_motor_tf(DC, amplifier_gain=-1.0)
    with pytest.raises(ParameterError, match="friction must be a non-negative"):
        mo.dc_motor_tf(DC, friction=-1.0)
    with pytest.raises(ParameterError, match="friction must be a number"):
        mo.dc_motor_tf(DC, friction=(1.0, 2.0, 3.0))
    with pytest.raises(ParameterError, match="non-zero denominator"):
        mo.dc_motor_tf(DC, friction=([1.0], [0.0]))
