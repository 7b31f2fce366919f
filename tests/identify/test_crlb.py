"""Cramér–Rao bound of free decays (issue 13): closed-form check and a seeded Monte-Carlo."""

import math

import numpy as np
import pytest

from driveid.errors import IdentificationError, ParameterError
from driveid.identify.crlb import free_decay_crlb, regression_crlb, required_duration
from driveid.identify.free_decay.output_error import estimate_output_error
from driveid.sim import OscillatorParams, measure, simulate_free_decay

P = OscillatorParams(J=1.0, K=16.0, c_mean=0.3, c_delta=0.1, fk_mean=0.07, fk_delta=0.03)


def test_bound_scales_with_noise_and_sample_rate():
    a = free_decay_crlb(P, fs=100, duration=30, x0=10, noise_std=0.01)
    b = free_decay_crlb(P, fs=100, duration=30, x0=10, noise_std=0.02)
    c = free_decay_crlb(P, fs=400, duration=30, x0=10, noise_std=0.01)
    for name in ("omega0", "c_mean", "fk_mean", "fk_delta", "K"):
        # Fisher information ∝ 1/σ² (exact) and ∝ number of samples (to sampling error)
        assert b[name] == pytest.approx(2 * a[name], rel=1e-9)
        assert c[name] == pytest.approx(a[name] / 2, rel=0.02)
    assert "J" not in a and "K" in a
    assert "J" in free_decay_crlb(P, fs=100, duration=30, x0=10, noise_std=0.01, known="K")


def test_undamped_frequency_bound_matches_sinusoid_closed_form():
    """A pure sinusoid A cos(ω t) in white noise: var(ω) = 24 σ² / (A² N T²) (large N)."""
    p = {"J": 1.0, "K": 16.0, "c_mean": 1e-9}
    fs, T, A, sigma = 200.0, 20.0, 1.0, 0.01
    bound = free_decay_crlb(p, fs=fs, duration=T, x0=A, noise_std=sigma)
    n = int(fs * T) + 1
    closed = math.sqrt(24 * sigma**2 / (A**2 * n * T**2))
    # the closed form is for known phase and amplitude uncertain only by the fit; ζ± and
    # the friction nuisance terms barely correlate with ω: agreement within 15 %
    assert bound["omega0"] == pytest.approx(closed, rel=0.15)


def test_bound_matches_observed_scatter():
    """Efficiency = bound variance / observed variance ~ 1 over 24 seeded records."""
    noise = 0.02
    rec = simulate_free_decay(P, x0=10.0, duration=30.0, fs=100.0).record
    bound = free_decay_crlb(P, fs=100, duration=30, x0=10, noise_std=noise)
    values = {n: [] for n in ("omega0", "c_mean", "c_delta", "fk_mean")}
    for seed in range(24):
        est = estimate_output_error(measure(rec, noise_std=noise, rng=100 + seed), mass=1.0)
        for n in values:
            values[n].append(est.value(n))
    for n, v in values.items():
        eff = bound[n] ** 2 / np.var(v, ddof=1)
        # a 24-sample variance has relative sd sqrt(2/23) = 0.29: 0.45-2.2 is ~2.7 sigma
        assert 0.45 < eff < 2.2, (n, eff)


def test_required_duration_reaches_target():
    d = required_duration(P, fs=100, x0=2.0, noise_std=0.005, parameter="fk_mean",
                          relative=0.01)
    sd = free_decay_crlb(P, fs=100, duration=d, x0=2.0, noise_std=0.005)["fk_mean"]
    assert sd <= 0.01 * 0.07
    shorter = free_decay_crlb(P, fs=100, duration=0.95 * d, x0=2.0, noise_std=0.005)
    assert shorter["fk_mean"] > 0.01 * 0.07 * 0.999


def test_required_duration_refuses_impossible_and_bad_targets():
    with pytest.raises(IdentificationError, match="does not reach"):
        required_duration(P, fs=10, x0=0.05, noise_std=0.05, relative=1e-4,
                          max_duration=60)
    with pytest.raises(ParameterError, match="is 0"):
        required_duration({"J": 1.0, "K": 16.0, "c_mean": 0.3}, fs=100, x0=1,
                          noise_std=0.01, parameter="fk_delta")
    with pytest.raises(ParameterError, match="noise_std"):
        free_decay_crlb(P, fs=100, duration=10, x0=1, noise_std=0)
    with pytest.raises(ParameterError, match="underdamped"):
        free_decay_crlb({"J": 1.0, "K": 1.0, "c_mean": 3.0}, fs=100, duration=10, x0=1,
                        noise_std=0.01)


def test_coloured_noise_bound():
    """The coloured-noise bound: φ = 0 is the white bound; AR(1) is the exact Gaussian one."""
    white = free_decay_crlb(P, fs=100, duration=30, x0=10, noise_std=0.01)
    zero = free_decay_crlb(P, fs=100, duration=30, x0=10, noise_std=0.01, noise_ar=[0.0])
    for name in ("omega0", "c_mean", "fk_mean"):
        # σ_w = σ for φ = 0 and A(q) = 1; only the first of 3001 samples is conditioned on
        # (dropped), and it is the release itself: 0.3 % measured, 1 % allowed
        assert zero[name] == pytest.approx(white[name], rel=0.01)
    # independent truth: the exact Gaussian Fisher information Jᵀ Σ⁻¹ J with the AR(1)
    # Toeplitz covariance σ² φ^|i-j|
    from scipy.linalg import toeplitz

    from driveid.identify.crlb import _base
    from driveid.identify.free_decay._free_response import kinetic_stop_count, response

    phi, fs, duration = 0.9, 20.0, 15.0
    red = free_decay_crlb(P, fs=fs, duration=duration, x0=10, noise_std=0.01,
                          noise_ar=[phi])
    t = np.arange(int(duration * fs) + 1) / fs
    base = _base(P)
    n_half, _ = kinetic_stop_count(base, 10.0, 0.0, float(t[-1]))
    _, jac, _ = response(t, base, 10.0, 0.0, n_half)
    sigma = 0.01**2 * toeplitz(phi ** np.arange(t.size))
    # p(x) = p(x_1) p(x_2.. | x_1): the conditional information is the exact one less the
    # first sample's own, j_1 j_1ᵀ / σ² (exact for AR(1))
    fisher = jac.T @ np.linalg.solve(sigma, jac) - np.outer(jac[0], jac[0]) / 0.01**2
    cov = np.linalg.inv(fisher)
    for i, name in enumerate(("omega0", "zeta_plus", "zeta_minus", "theta_k_mean")):
        # two routes to the same matrix: round-off of a Toeplitz solve (cond ~1e6)
        assert red[name] == pytest.approx(math.sqrt(cov[i, i]), rel=1e-6), name
    with pytest.raises(ParameterError, match="stationary"):
        free_decay_crlb(P, fs=100, duration=30, x0=10, noise_std=0.01, noise_ar=[1.1])


def test_regression_bound_of_a_mean_under_ar1_noise_is_the_closed_form():
    # y_t = m + e_t, e AR(1) with pole phi and sd sigma: prewhitening leaves n-1 rows of
    # (1 - phi) and innovation variance sigma²(1 - phi²), so var(m) = sigma²(1+phi)/((n-1)(1-phi))
    # exactly (Whittle's form conditions on the first sample); the 200 000-sample impulse
    # response behind sigma_w² is exact to double precision for phi = 0.9
    n, sigma, phi = 500, 0.3, 0.9
    cov = regression_crlb([np.ones((n, 1))], noise_std=sigma, noise_ar=[phi])
    assert cov[0, 0] == pytest.approx(sigma**2 * (1 + phi) / ((n - 1) * (1 - phi)), rel=1e-12)
    # two independent records of the same design: half the variance
    two = regression_crlb([np.ones((n, 1))] * 2, noise_std=sigma, noise_ar=[phi])
    assert two[0, 0] == pytest.approx(cov[0, 0] / 2, rel=1e-12)


def test_regression_bound_matches_the_exact_gls_covariance_of_a_long_record():
    # the exact bound is (Jᵀ Σ⁻¹ J)⁻¹ with Σ the AR(1) Toeplitz covariance; Whittle's form
    # drops the first sample's information, a 1/n effect that the columns' correlation
    # amplifies: 2 % at n = 400, 0.42 % at n = 2000, so 1 % there
    n, sigma, phi = 2000, 1.0, 0.5
    t = np.arange(n) / n
    jac = np.column_stack([np.ones(n), np.sin(7 * t), t])
    lags = np.abs(np.subtract.outer(np.arange(n), np.arange(n)))
    exact = np.linalg.inv(jac.T @ np.linalg.solve(sigma**2 * phi**lags, jac))
    cov = regression_crlb([jac], noise_std=sigma, noise_ar=[phi])
    np.testing.assert_allclose(np.sqrt(np.diag(cov)), np.sqrt(np.diag(exact)), rtol=1e-2)
    # white noise: the ordinary least-squares covariance, exactly
    np.testing.assert_allclose(regression_crlb([jac], noise_std=sigma),
                               sigma**2 * np.linalg.inv(jac.T @ jac), rtol=1e-12)


def test_regression_bound_refuses_bad_input():
    ones = np.ones((50, 1))
    with pytest.raises(ParameterError, match="noise_std must be a positive"):
        regression_crlb([ones], noise_std=0.0)
    with pytest.raises(ParameterError, match="every Jacobian must be"):
        regression_crlb([ones, np.ones((50, 2))], noise_std=1.0)
    with pytest.raises(ParameterError, match="stationary AR"):
        regression_crlb([ones], noise_std=1.0, noise_ar=[1.2])
    with pytest.raises(ParameterError, match="at least one"):
        regression_crlb([], noise_std=1.0)
    with pytest.raises(IdentificationError, match="singular"):
        regression_crlb([np.ones((50, 2))], noise_std=1.0)
