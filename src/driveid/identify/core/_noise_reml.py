r"""Restricted (residual) maximum likelihood of an AR noise model fitted to a fit's residuals.

A whole-record fit estimates its AR noise model from its residuals ``r = y - f(θ̂)``; the
fit has taken out of ``r`` the noise in the directions of the Jacobian's columns ``X``
(n x k). Restricted maximum likelihood (Patterson and Thompson [1]_, Harville [2]_) is the
likelihood of the error contrasts ``Kᵀy`` (``KᵀX = 0``), which do not depend on θ:

.. math::

    \ell_R(\phi) = -\tfrac12\left[\log|\Sigma_\phi| + \log|X^\top\Sigma_\phi^{-1}X|
                   + r^\top P_\phi r\right],\quad
    P_\phi = \Sigma_\phi^{-1} - \Sigma_\phi^{-1}X(X^\top\Sigma_\phi^{-1}X)^{-1}X^\top
    \Sigma_\phi^{-1},

with ``Σ_φ = σ_w² V_φ`` the exact AR(p) covariance. ``V_φ⁻¹ = LᵀL``: ``L`` is the
prediction-error filter ``A(q)`` from sample p on, and before it the Durbin–Levinson
predictors of orders 0..p-1 scaled to unit innovation variance, so that
``log|V_φ| = -Σ_j j log(1 - κ_j²)`` per record in the partial autocorrelations ``κ_j``
(Brockwell and Davis [3]_ §5.2, §8.7). ``r ᵀP r`` is the residual sum of squares of ``L r``
regressed on ``L X`` (``P X = 0``, so any residual of a linear fit gives the same value).
σ_w² is profiled out (``σ̂_w² = rᵀP r / (n - k)``); the ``κ_j = tanh u_j`` are
unconstrained, so every model tried is stationary.

Not in the thesis (§2.2.5 fits peaks and models no noise).

References
----------
.. [1] H. D. Patterson, R. Thompson, "Recovery of inter-block information when block sizes
       are unequal", Biometrika 58 (1971) 545-554, doi:10.1093/biomet/58.3.545.
.. [2] D. A. Harville, "Maximum likelihood approaches to variance component estimation and
       to related problems", J. Amer. Statist. Assoc. 72 (1977) 320-338,
       doi:10.1080/01621459.1977.10480998.
.. [3] P. J. Brockwell, R. A. Davis, *Time Series: Theory and Methods*, 2nd ed., Springer,
       1991.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import replace

import numpy as np
from scipy.optimize import minimize
from scipy.signal import lfilter

from driveid.identify.core._noise import NoiseModel, segment_lengths
from driveid.identify.core._noise_replicates import process_variance

__all__ = ["reml_noise_model", "reml_order", "restricted_loglik", "to_partial", "from_partial"]

#: Largest |partial autocorrelation| an optimum may reach [-] (a pole 1 - 1e-5 from the
#: circle: a time constant of 10⁵ samples, far beyond any record this fits).
_KAPPA_MAX = 1.0 - 1e-5


def from_partial(kappa: np.ndarray) -> np.ndarray:
    """AR coefficients ``a_1 … a_p`` from partial autocorrelations (Levinson step-up).

    Parameters
    ----------
    kappa : ndarray, shape (p,)
        Partial autocorrelations, each in (-1, 1) [-].

    Returns
    -------
    ndarray, shape (p,)
        ``a`` of ``e_t = Σ a_j e_{t-j} + w_t`` [-] (stationary).
    """
    a = np.zeros(0)
    for k in np.asarray(kappa, float):
        a = np.concatenate([a - k * a[::-1], [k]])
    return a


def to_partial(ar: Sequence[float]) -> np.ndarray:
    """Partial autocorrelations of a stationary AR model (Levinson step-down).

    Parameters
    ----------
    ar : sequence of float, length p
        ``a_1 … a_p`` [-].

    Returns
    -------
    ndarray, shape (p,)
        ``κ_1 … κ_p`` [-]; all of modulus < 1 when the model is stationary.
    """
    a = np.asarray(ar, float).copy()
    p = a.size
    kappa = np.zeros(p)
    for m in range(p, 0, -1):
        k = a[m - 1]
        kappa[m - 1] = k
        if m > 1:
            head = a[:m - 1]
            a = (head + k * head[::-1]) / max(1.0 - k * k, 1e-300)
    return kappa


def _exact_whiten(z: np.ndarray, kappa: np.ndarray, lengths: list[int]) -> np.ndarray:
    """``L z`` record by record: the exact AR prewhitening, first p rows included."""
    p = kappa.size
    steps = [np.zeros(0)]
    for k in kappa:  # predictors of every order 0..p
        a = steps[-1]
        steps.append(np.concatenate([a - k * a[::-1], [k]]))
    b = np.concatenate([[1.0], -steps[-1]])
    one_minus = 1.0 - kappa * kappa
    # v_t / σ_w² = 1 / Π_{i>t} (1 - κ_i²): the head rows' prediction-error variances
    head_scale = np.sqrt(np.array([float(np.prod(one_minus[t:])) for t in range(p)]))
    parts, start = [], 0
    for length in lengths:
        block = z[start:start + length]
        start += length
        out = lfilter(b, [1.0], block, axis=0)
        for t in range(min(p, length)):
            phi = steps[t]
            pred = phi @ block[t - 1::-1][:t] if t else 0.0
            out[t] = (block[t] - pred) * head_scale[t]
        parts.append(out)
    return parts[0] if len(parts) == 1 else np.concatenate(parts)


def restricted_loglik(kappa: np.ndarray, residual: np.ndarray, jac: np.ndarray, *,
                      segments: Sequence[int] | None = None) -> tuple[float, float]:
    """Profiled restricted log-likelihood of an AR model and its innovation variance.

    Parameters
    ----------
    kappa : ndarray, shape (p,)
        Partial autocorrelations of the model [-], each of modulus < 1.
    residual : ndarray, shape (n,)
        Residuals of a linear(ised) fit ``y - X θ̂`` [unit].
    jac : ndarray, shape (n, k)
        The fit's Jacobian ``X`` [unit per parameter unit].
    segments : sequence of int, optional
        Samples of each stacked record [-]; the filter never runs across records.

    Returns
    -------
    (float, float)
        ``ℓ_R`` up to a constant [-] and ``σ̂_w² = rᵀPr/(n - k)`` [unit²]; ``-inf`` where
        ``L X`` is singular.
    """
    r = np.asarray(residual, float)
    x = np.asarray(jac, float)
    lengths = segment_lengths(segments, r.size)
    kappa = np.asarray(kappa, float)
    w = _exact_whiten(np.column_stack([r, x]), kappa, lengths)
    q, upper = np.linalg.qr(w[:, 1:])
    diag = np.abs(np.diag(upper))
    if not np.all(diag > 0):
        return -math.inf, math.nan
    rw = w[:, 0]
    quad = float(rw @ rw) - float(np.sum((q.T @ rw) ** 2))
    dof = max(r.size - x.shape[1], 1)
    s2 = max(quad, 1e-300) / dof
    log_v = -len(lengths) * float(np.sum(np.arange(1, kappa.size + 1)
                                         * np.log1p(-kappa * kappa)))
    return -0.5 * (dof * math.log(s2) + log_v + 2.0 * float(np.sum(np.log(diag)))), s2


def reml_noise_model(start: NoiseModel, residual: np.ndarray, jac: np.ndarray, *,
                     segments: Sequence[int] | None = None,
                     max_iter: int = 200) -> NoiseModel:
    """Refit an AR noise model of a fit's residuals by restricted maximum likelihood.

    Parameters
    ----------
    start : NoiseModel
        The model to start from (Burg's, of the order to keep); returned as it is when white.
    residual : ndarray, shape (n,)
        Residuals of the fit [unit].
    jac : ndarray, shape (n, k)
        The fit's Jacobian at the estimate, not prewhitened [unit per parameter unit].
    segments : sequence of int, optional
        Samples of each stacked record [-].
    max_iter : int
        Most quasi-Newton iterations [-].

    Returns
    -------
    NoiseModel
        Same order, ``method="reml"``; its innovation variance ``σ̂_w²`` and process variance.
        The start itself when the optimum is not better than it.

    Examples
    --------
    >>> rng = np.random.default_rng(3)
    >>> t = np.arange(2000) / 200.0
    >>> jac = np.column_stack([np.ones_like(t), t, np.sin(4 * t)])
    >>> e = lfilter([1.0], [1.0, -0.97], rng.normal(size=2000))
    >>> r = e - jac @ np.linalg.lstsq(jac, e, rcond=None)[0]
    >>> from driveid.identify.core._noise import fit_noise_model
    >>> burg = fit_noise_model(r, order=1)
    >>> reml = reml_noise_model(burg, r, jac)
    >>> bool(reml.ar[0] > burg.ar[0])
    True
    """
    if start.is_white:
        return start
    r = np.asarray(residual, float)
    x = np.asarray(jac, float)
    lengths = segment_lengths(segments, r.size)
    limit = math.atanh(_KAPPA_MAX)
    u0 = np.arctanh(np.clip(to_partial(start.ar), -_KAPPA_MAX, _KAPPA_MAX))

    def cost(u):
        value, _ = restricted_loglik(np.tanh(u), r, x, segments=lengths)
        return -value if math.isfinite(value) else 1e300

    base = cost(u0)
    found = minimize(cost, u0, method="L-BFGS-B", bounds=[(-limit, limit)] * u0.size,
                     options={"maxiter": int(max_iter)})
    if not (np.all(np.isfinite(found.x)) and found.fun < base):
        return start
    kappa = np.tanh(found.x)
    _, s2 = restricted_loglik(kappa, r, x, segments=lengths)
    ar = from_partial(kappa)
    return replace(start, ar=tuple(float(v) for v in ar), innovation_variance=s2,
                   variance=process_variance(ar, s2), method="reml")


def reml_order(residual: np.ndarray, jac: np.ndarray, *, segments: Sequence[int] | None = None,
               max_order: int = 40) -> NoiseModel:
    """Burg's model of the order that minimises ``-2 ℓ_R + p ln n`` (REML + BIC penalty).

    Parameters
    ----------
    residual : ndarray, shape (n,)
        Residuals of the fit [unit].
    jac : ndarray, shape (n, k)
        The fit's Jacobian, not prewhitened [unit per parameter unit].
    segments : sequence of int, optional
        Samples of each stacked record [-].
    max_order : int
        Highest order tried [-].

    Returns
    -------
    NoiseModel
        Burg's coefficients of the chosen order (the reflection coefficients of the longest
        fit are the partial autocorrelations of every shorter one).
    """
    from driveid.identify.core._noise import fit_noise_model

    r = np.asarray(residual, float)
    lengths = segment_lengths(segments, r.size)
    longest = fit_noise_model(r, segments=lengths, order=max_order, n_params=jac.shape[1])
    kappa = to_partial(longest.ar)
    crit = []
    for p in range(kappa.size + 1):
        value, _ = restricted_loglik(kappa[:p], r, jac, segments=lengths)
        crit.append(-2.0 * value + p * math.log(r.size))
    best = int(np.argmin(crit))
    if best == 0:
        return replace(longest, ar=(), innovation_variance=longest.variance)
    ar = from_partial(kappa[:best])
    _, s2 = restricted_loglik(kappa[:best], r, jac, segments=lengths)
    return replace(longest, ar=tuple(float(v) for v in ar), innovation_variance=s2,
                   variance=process_variance(ar, s2))
