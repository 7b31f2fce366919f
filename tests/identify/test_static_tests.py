"""Tests of driveid.identify.friction.static_tests on synthetic data with closed-form truth."""

import math

import numpy as np
import pytest
from scipy.optimize import brentq

from driveid.errors import IdentificationError, ParameterError, RecordError
from driveid.identify.friction.static_tests import (
    estimate_backlash_stiffness,
    estimate_breakaway,
    estimate_rising_friction,
    estimate_static_stiffness,
    estimate_step_response,
    step_metrics,
)
from driveid.io.record import Record
from driveid.models.friction_memory import (
    KatoRisingParams,
    rising_static_friction_kato,
)

# kinetic friction and peak force chosen so that the mass sticks again before the force
# changes sign: each ramp then starts from rest
FS_PLUS, FS_MINUS, FK, KS, MASS = 10.0, 9.0, 7.0, 1e6, 1.0


def _ramp_record(seed=0, sigma_x=1e-8, sigma_u=0.01, rate=10.0, dt=1e-3):
    """Stick-slip mass under a triangular force: stuck = presliding spring (2.13)."""
    peak = 1.1 * FS_PLUS
    t_quarter = peak / rate
    t = np.arange(0.0, 4 * t_quarter, dt)
    u = peak * np.interp(t, [0, t_quarter, 3 * t_quarter, 4 * t_quarter], [0, 1, -1, 0])
    x = np.empty_like(t)
    pos, vel, anchor, stuck, sub = 0.0, 0.0, 0.0, True, 20
    for i in range(t.size):
        x[i] = pos
        if i + 1 == t.size:
            break
        for j in range(sub):  # fine explicit sub-steps: 50 µs
            uj = u[i] + (u[i + 1] - u[i]) * j / sub
            if stuck:
                pos = anchor + uj / KS
                if uj > FS_PLUS or uj < -FS_MINUS:
                    stuck, vel = False, 0.0
                    direction = math.copysign(1.0, uj)
                continue
            acc = (uj - FK * direction) / MASS
            new_vel = vel + acc * dt / sub
            if new_vel * direction <= 0:
                stuck, vel = True, 0.0
                anchor = pos - uj / KS
                continue
            pos += 0.5 * (vel + new_vel) * dt / sub
            vel = new_vel
    rng = np.random.default_rng(seed)
    return Record(t=t, x=x + sigma_x * rng.standard_normal(t.size),
                  u=u + sigma_u * rng.standard_normal(t.size),
                  meta={"units": {"x": "m", "u": "N"}})


def test_breakaway_and_presliding_stiffness_within_one_percent():
    est = estimate_breakaway(_ramp_record(), x_break=1e-4)
    # detection lags breakaway by ~1 sample of a 10 N/s ramp (0.01 N = 0.1 %): 1 % bound
    assert est.value("fs_plus") == pytest.approx(FS_PLUS, rel=0.01)
    assert est.value("fs_minus") == pytest.approx(FS_MINUS, rel=0.01)
    assert est.value("fs_delta") == pytest.approx(0.5, abs=0.02)
    # (2.14): presliding displacements +fs+/ks = 1e-5 m, -fs-/ks = -9e-6 m; 10 nm noise: 1 %
    assert est.value("xs_plus") == pytest.approx(FS_PLUS / KS, rel=0.01)
    assert est.value("xs_minus") == pytest.approx(-FS_MINUS / KS, rel=0.01)
    assert est.value("ks") == pytest.approx(KS, rel=0.01)
    assert est.diagnostics["ks_regression_plus"] == pytest.approx(KS, rel=0.01)


def test_breakaway_errors():
    rec = _ramp_record()
    with pytest.raises(ParameterError, match="x_break must be"):
        estimate_breakaway(rec, x_break=0.0)
    with pytest.raises(IdentificationError, match="force ramp reaches sliding"):
        estimate_breakaway(rec, x_break=10.0)
    with pytest.raises(RecordError, match="needs the applied force"):
        estimate_breakaway(Record(t=rec.t, x=rec.x), x_break=1e-4)


def test_rising_static_friction_fit_within_one_percent():
    truth = {"fs_inf": 12.0, "fk": 8.0, "gamma": 5.0, "kappa": 0.6}
    t_dwell = np.logspace(-2, 3, 30)
    rng = np.random.default_rng(2)
    sigma = 0.005  # 0.05 % of fs: repeatable breakaway on a good ramp
    params = KatoRisingParams(mu_inf=truth["fs_inf"], mu_k=truth["fk"], gamma=truth["gamma"],
                              kappa=truth["kappa"])
    fs = rising_static_friction_kato(t_dwell, params) + sigma * rng.standard_normal(t_dwell.size)
    est = estimate_rising_friction(t_dwell, fs, fs_stderr=np.full(t_dwell.size, sigma))
    for name, value in truth.items():
        # task bound 1 %; the standard errors here are 0.1–0.5 %
        assert est.value(name) == pytest.approx(value, rel=0.01), name
        assert abs(est.value(name) - value) < 4 * est.stderr(name), name


def test_rising_friction_errors():
    with pytest.raises(IdentificationError, match="at least 5 breakaway"):
        estimate_rising_friction([1.0, 2.0], [1.0, 2.0])
    with pytest.raises(ParameterError, match="dwell times must be"):
        estimate_rising_friction([-1.0, 1, 2, 3, 4], [1.0, 2, 3, 4, 5])
    t = np.array([1000.0, 2000, 3000, 4000, 5000])
    params = KatoRisingParams(mu_inf=12.0, mu_k=8.0, gamma=5.0, kappa=0.6)
    with pytest.raises(IdentificationError, match="outside the measured"):
        estimate_rising_friction(t, rising_static_friction_kato(t, params)
                                 + 1e-3 * np.array([1, -1, 1, -1, 1]))


def test_backlash_gap_and_stiffness_within_one_percent():
    gap, K, xc = 0.01, 500.0, 0.002
    T = np.array([-4.0, -3, -2, -1, 1, 2, 3, 4])
    x = xc + 0.5 * gap * np.sign(T) + T / K
    x = x + 1e-6 * np.random.default_rng(5).standard_normal(T.size)  # 1 µrad encoder noise
    est = estimate_backlash_stiffness(T, x, x_ref=0.0)
    # deflections 2–8 mrad against 1 µrad noise: errors ~0.1 %; 1 % bound
    assert est.value("gap") == pytest.approx(gap, rel=0.01)
    assert est.value("K") == pytest.approx(K, rel=0.01)
    assert est.value("gap_plus") == pytest.approx(xc + gap / 2, rel=0.01)
    assert est.value("gap_minus") == pytest.approx(gap / 2 - xc, rel=0.01)
    stiff = estimate_static_stiffness(T[T > 0], x[T > 0] - xc - gap / 2)
    assert stiff.value("K") == pytest.approx(K, rel=0.01)


def test_backlash_and_stiffness_errors():
    with pytest.raises(IdentificationError, match="at least 2 distinct levels"):
        estimate_backlash_stiffness([-1.0, 1.0, 2.0], [0.0, 0.1, 0.2])
    with pytest.raises(IdentificationError, match="compliance is not positive"):
        estimate_backlash_stiffness([-2.0, -1.0, 1.0, 2.0], [0.0, -0.1, 0.1, 0.0])
    with pytest.raises(ParameterError, match="equal length"):
        estimate_backlash_stiffness([1.0], [1.0, 2.0])
    with pytest.raises(IdentificationError, match="at least 3 tests"):
        estimate_static_stiffness([1.0, 2.0], [0.1, 0.2])
    with pytest.raises(IdentificationError, match="does not grow"):
        estimate_static_stiffness([1.0, 2.0, 3.0], [0.3, 0.2, 0.1])


ZETA, W0 = 0.3, 2 * np.pi * 5.0


def _unit_step(t):
    wd = W0 * np.sqrt(1 - ZETA**2)
    s = 1 - np.exp(-ZETA * W0 * t) * (np.cos(wd * t) + ZETA / np.sqrt(1 - ZETA**2)
                                       * np.sin(wd * t))
    return np.where(t >= 0, s, 0.0)


def _square_record(noise=1e-4, seed=1):
    fs, half = 1000.0, 1.0
    t = np.arange(0.0, 8.0, 1 / fs)
    r = 1.5 + 0.5 * np.where((t // half) % 2 == 0, -1.0, 1.0)  # DC-biased square wave
    y = np.full_like(t, r[0])
    for k in np.flatnonzero(np.diff(r)) + 1:
        y += (r[k] - r[k - 1]) * _unit_step(t - t[k])
    y += noise * np.random.default_rng(seed).standard_normal(t.size)
    return Record(t=t, x=np.cumsum(y) / fs, v=y, u=r)


def test_step_response_second_order_within_one_percent():
    est = estimate_step_response(_square_record())
    wd = W0 * np.sqrt(1 - ZETA**2)
    overshoot = 100 * np.exp(-ZETA * np.pi / np.sqrt(1 - ZETA**2))
    # closed forms: OS, tp = π/ωd; 1 ms sampling + 1e-4 noise keep errors ≈ 0.1–0.3 %
    assert est.value("overshoot_pct") == pytest.approx(overshoot, rel=0.01)
    assert est.value("peak_time") == pytest.approx(np.pi / wd, rel=0.01)
    assert est.value("zeta") == pytest.approx(ZETA, rel=0.01)
    assert est.value("omega0") == pytest.approx(W0, rel=0.01)
    # rise (10–90 %) and 2 % settling times: fine root finding on the closed form
    t10 = brentq(lambda s: _unit_step(s) - 0.1, 1e-6, np.pi / wd)
    t90 = brentq(lambda s: _unit_step(s) - 0.9, 1e-6, np.pi / wd)
    assert est.value("rise_time") == pytest.approx(t90 - t10, rel=0.01)
    grid = np.linspace(0, 1.0, 200001)
    last = grid[np.flatnonzero(np.abs(_unit_step(grid) - 1) > 0.02)[-1]]
    # settling time jumps by a half period when noise moves the last exit; 1 % still holds
    assert est.value("settling_time") == pytest.approx(last, rel=0.01)
    assert est.diagnostics["n_steps"] == 7


def test_step_metrics_and_errors():
    t = np.linspace(0, 1, 1001)
    with pytest.raises(IdentificationError, match="step size"):
        step_metrics(t, t, y0=1.0, y_final=1.0)
    with pytest.raises(IdentificationError, match="never reaches"):
        step_metrics(t, 0.5 * t, y0=0.0, y_final=1.0)
    first_order = 1 - np.exp(-t / 0.05)
    m = step_metrics(t, first_order, y0=0.0, y_final=1.0)
    # first order: rise time ln 9·τ = 0.1099 s; settling (2 %) ln 50·τ = 0.1956 s
    assert m["rise_time"] == pytest.approx(np.log(9) * 0.05, rel=0.01)
    assert m["settling_time"] == pytest.approx(np.log(50) * 0.05, rel=0.01)
    assert m["overshoot_pct"] == 0.0
    delayed = np.where(t > 0.3, 1 - np.exp(-(t - 0.3) / 0.05), 0.0)
    rec = Record(t=t, x=delayed, u=(t > 0.3).astype(float))
    with pytest.raises(IdentificationError, match="no overshoot"):
        estimate_step_response(rec)
    with pytest.raises(IdentificationError, match="no jumps"):
        estimate_step_response(Record(t=t, x=first_order, u=np.ones_like(t)))
