"""The slow-noise excess of a prewhitened fit (issue 24, 1/f-like noise): its sandwich and test.

Truth: dense Toeplitz covariances from the excess spectrum integrated numerically (not the
circulant embedding the module uses), white and AR(1) records of known spectrum, and the
1/f-like records of benchmarks/bench_noise_coverage.py.
"""

import math

import numpy as np
from scipy.linalg import toeplitz

from driveid.identify.core._noise import white_noise
from driveid.identify.core._slow_noise import FLAT_BELOW, _through_fit, slow_noise_covariance


def _design(n):
    t = np.arange(n) / n
    return np.column_stack([np.ones(n), t, np.sin(16 * math.pi * t), np.cos(16 * math.pi * t)])


def test_excess_through_the_fit_matches_a_dense_toeplitz_covariance():
    """``M Σ Mᵀ`` for the spectrum ``s (ν n)^-α`` flat below ``ν n = FLAT_BELOW``."""
    n, scale, alpha = 300, 2.0, 1.3
    x = _design(n)
    m_map = np.linalg.pinv(x)
    # autocovariance by the trapezoid rule on a grid 200x finer than the record's 1/n
    nu = np.linspace(0.0, 0.5, 200 * n + 1)
    spec = scale * np.maximum(nu * n, FLAT_BELOW) ** (-alpha)
    lags = np.arange(n)
    gamma = 2.0 * np.trapezoid(spec[None, :] * np.cos(2 * math.pi * np.outer(lags, nu)), nu,
                               axis=1)
    dense = m_map @ toeplitz(gamma) @ m_map.T
    fast = _through_fit(m_map, [n], scale, alpha)
    # the circulant embedding on 8n points aliases lags beyond 4n (γ decays there to
    # ~1e-3 of γ₀ for this flat-below-1/(2n) spectrum) and samples the spectrum at 1/(8n):
    # 2 % on the diagonal
    np.testing.assert_allclose(np.diag(fast), np.diag(dense), rtol=0.02)


def test_excess_through_an_ordinary_fit_divides_by_the_whitening_filter():
    """The map of an ordinary (unwhitened) fit sees the prewhitened excess over ``|A(ν)|²``:
    against the dense Toeplitz covariance of that spectrum, integrated numerically."""
    n, scale, alpha, ar = 300, 2.0, 1.3, (0.6, -0.2)
    m_map = np.linalg.pinv(_design(n))
    nu = np.linspace(0.0, 0.5, 200 * n + 1)
    a = 1.0 - ar[0] * np.exp(-2j * math.pi * nu) - ar[1] * np.exp(-4j * math.pi * nu)
    spec = scale * np.maximum(nu * n, FLAT_BELOW) ** (-alpha) / np.abs(a) ** 2
    gamma = 2.0 * np.trapezoid(spec[None, :] * np.cos(2 * math.pi * np.outer(np.arange(n), nu)),
                               nu, axis=1)
    dense = m_map @ toeplitz(gamma) @ m_map.T
    fast = _through_fit(m_map, [n], scale, alpha, ar)
    # as above: the 8n-point circulant embedding, 2 % on the diagonal; without the filter
    # the diagonal is 2.8x smaller (1/|A(0)|², the excess sits at the slowest frequencies)
    np.testing.assert_allclose(np.diag(fast), np.diag(dense), rtol=0.02)
    assert np.all(np.diag(_through_fit(m_map, [n], scale, alpha)) < 0.7 * np.diag(dense))


def test_white_residuals_add_nothing():
    """White noise and a correct white model: the excess test does not fire (5 % level)."""
    rng = np.random.default_rng(5)
    n = 2000
    x = _design(n)
    fired = 0
    for _ in range(20):
        e = rng.normal(size=n)
        r = e - x @ np.linalg.lstsq(x, e, rcond=None)[0]
        extra, info = slow_noise_covariance(x, r, white_noise(r))
        fired += info["applied"]
        if not info["applied"]:
            assert not np.any(extra)
    # Binomial(20, 0.05): P(>= 4) = 1.6 %
    assert fired <= 3, fired


def test_white_record_is_untouched(monkeypatch):
    """A white-noise record (order 0) runs no excess test: its fit and error bars are exact."""
    from driveid.identify.core import _slow_noise
    from driveid.identify.free_decay.output_error import estimate_output_error
    from driveid.sim import OscillatorParams, simulate_free_decay

    params = OscillatorParams(J=1.0, K=16.0, c_mean=0.3, c_delta=0.1, fk_mean=0.07,
                              fk_delta=0.03)
    rec = simulate_free_decay(params, x0=1.0, duration=10.0, fs=200.0).record
    x = rec.x + np.random.default_rng(11).normal(0.0, 0.01, rec.n)
    est = estimate_output_error(rec.replace(x=x), mass=1.0)
    assert est.diagnostics["noise_model"]["order"] == 0
    assert est.diagnostics["adequacy"]["slow_noise"]["excess_fit"] is None
    monkeypatch.setattr(_slow_noise, "LEVEL", 1.0)  # would widen any record it saw
    again = estimate_output_error(rec.replace(x=x), mass=1.0)
    for name in ("c_mean", "c_delta", "fk_mean", "fk_delta", "K"):
        assert again.stderr(name) == est.stderr(name)
        assert again.value(name) == est.value(name)


def test_sandwich_of_a_singular_jacobian_is_unknown_not_an_exception():
    # a parameter the record never moves (a zero column): the Newey-West sandwich used to
    # raise numpy's LinAlgError out of a drive fit; now that parameter's variance is
    # unknown (nan, never 0) and the others are what the regular columns alone give
    from driveid.identify.core._noise import hac_covariance

    rng = np.random.default_rng(3)
    n = 500
    regular = np.column_stack([np.ones(n), np.linspace(-1.0, 1.0, n)])
    r = rng.normal(size=n)
    cov = hac_covariance(np.column_stack([regular, np.zeros(n)]), r)
    alone = hac_covariance(regular, r)
    assert np.all(np.isnan(cov[2])) and np.all(np.isnan(cov[:, 2]))
    # the regular block is unchanged (the null direction is orthogonal to it)
    np.testing.assert_allclose(cov[:2, :2], alone, rtol=1e-9)
