"""Passivity conditions of the dynamic friction models, checked by integrating them."""

import numpy as np
import pytest

from driveid.errors import ParameterError
from driveid.models.dynamic_friction import (
    ArmstrongParams,
    CanudasParams,
    DahlParams,
    LuGreParams,
    armstrong_friction,
    canudas_friction,
    canudas_state_derivative,
    dahl_friction,
    dahl_state_derivative,
    lugre_friction,
    lugre_state_derivative,
)
from driveid.models.passivity import check_passivity

DT = 1e-5


def _velocities(rng, n_runs=64, n=20000):
    """Random smooth velocity histories with reversals [m/s]: sums of random sines."""
    t = np.arange(n) * DT
    out = np.zeros((n_runs, n))
    for _ in range(4):
        amp = rng.uniform(0, 0.5, (n_runs, 1))
        f = rng.uniform(5, 200, (n_runs, 1))
        ph = rng.uniform(0, 2 * np.pi, (n_runs, 1))
        out += amp * np.sin(2 * np.pi * f * t + ph)
    return out


def _supply_minus_storage(state0, rate, force, storage, v):
    """∫F v dt - (V(T) - V(0)) by RK2 (midpoint) on each run; >= 0 for a passive map."""
    s = state0.copy()
    work = np.zeros(s.shape)
    for k in range(v.shape[1] - 1):
        vk, vm = v[:, k], 0.5 * (v[:, k] + v[:, k + 1])
        s_mid = s + 0.5 * DT * rate(s, vk)
        work += DT * force(s_mid, vm) * vm
        s = s + DT * rate(s_mid, vm)
    return work - (storage(s) - storage(state0))


@pytest.mark.parametrize("gamma", [0.5, 1.0, 2.0])
def test_dahl_is_passive_from_any_initial_force(gamma):
    p = DahlParams(k_s=2e3, mu_k=1.0, gamma=gamma, nu=0.1)
    assert check_passivity(p).passive
    rng = np.random.default_rng(int(gamma * 10))
    v = _velocities(rng)
    f0 = rng.uniform(-1.5, 1.5, v.shape[0])      # also outside |f| <= mu_k
    slack = _supply_minus_storage(f0, lambda f, vk: dahl_state_derivative(f, vk, p),
                                  lambda f, vk: dahl_friction(f, vk, p),
                                  lambda f: f * f / (2 * p.k_s), v)
    # midpoint rule error ~ (k_s |v| DT)² relative: the slack may dip below 0 only by
    # integration error, bounded here by 1e-6 J against supplied work of ~1e-2 J
    assert slack.min() > -1e-6


def test_canudas_force_has_the_sign_of_velocity():
    p = CanudasParams(mu_k=1.0, mu_s=1.6, nu=0.2, v_s=0.05, memory=0.01, k_s=1e3,
                      nu_s=0.0)
    assert check_passivity(p).passive
    rng = np.random.default_rng(2)
    v = _velocities(rng, n_runs=16)
    g = rng.uniform(0, 1, v.shape[0])
    for k in range(v.shape[1]):
        F = canudas_friction(g, v[:, k], p)
        assert np.all(F * v[:, k] >= 0)
        g = g + DT * canudas_state_derivative(g, v[:, k], p)
        assert np.all((g >= 0) & (g <= 1))


def test_armstrong_work_bounded_by_presliding_storage():
    p = ArmstrongParams(mu_k=1.0, mu_s_a=0.5, mu_s_inf=0.8, nu=0.1, v_s=0.05, lag=0.002,
                        gamma=0.1, k_s=1e4)
    assert check_passivity(p).passive
    rng = np.random.default_rng(3)
    v = _velocities(rng, n_runs=8)[:, ::10]
    dt = 10 * DT
    worst = np.inf
    for vk in v:
        x = np.concatenate([[0.0], np.cumsum(vk[:-1]) * dt])
        F = armstrong_friction(vk, x, dt, p)
        work = np.cumsum(F * vk) * dt
        worst = min(worst, work.min())
    # the only storage is the presliding spring, at most (breakaway)²/(2 k_s) = 1.6e-4 J
    assert worst >= -(p.mu_k + p.mu_s_inf) ** 2 / (2 * p.k_s) - 1e-9


def _lugre(sigma1):
    return LuGreParams(sigma0=1e4, sigma1=sigma1, sigma2=0.4, fc=1.0, fs=1.5, vs=1e-2,
                       check_passivity=False)


def test_lugre_bound_separates_passive_from_active():
    # bound sigma2 Fc/(Fs - Fc) = 0.8 N·s/m
    assert check_passivity(_lugre(0.5)).passive
    report = check_passivity(_lugre(50.0))
    assert not report.passive and report.margin == pytest.approx(0.8 - 50.0)
    # Necessity (Barabanov & Ortega): from sigma0 z = Fs, a step to v = +2 m/s makes z
    # relax in 1/(sigma0 v) = 50 µs with dz/dt < 0, so sigma1 ż v returns about
    # sigma1 (Fs/Fc - 1) v² · 50 µs; over 200 µs this beats the Coulomb and viscous loss
    # (~7e-4 J) for sigma1 = 50 (5e-3 J) but not for the passive 0.5 (5e-5 J)
    v = np.full((1, 21), 2.0)
    for sigma1, sign in ((0.5, 1), (50.0, -1)):
        p = _lugre(sigma1)
        z0 = np.array([p.fs / p.sigma0])
        slack = _supply_minus_storage(
            z0, lambda z, vk, p=p: lugre_state_derivative(z, vk, p),
            lambda z, vk, p=p: lugre_friction(z, vk, p), lambda z, p=p: p.sigma0 * z * z / 2, v)
        assert np.sign(slack[0]) == sign, (sigma1, slack)


def test_unknown_model_is_rejected():
    with pytest.raises(ParameterError, match="DahlParams"):
        check_passivity(object())
