r"""Noise slower than an AR model sees: a power-law excess at the record's slowest frequencies.

An AR(p) noise model fitted to a fit's residuals is set by the one-step prediction error,
i.e. by the whole spectrum (Whittle), in which the few Fourier frequencies near zero count
little; 1/f-like noise has most of its power there. Those frequencies are also the ones the
offset- and drift-like unknowns absorb. Restricted maximum likelihood of the AR coefficients
(:mod:`driveid.identify.core._noise_reml`) corrects the absorption but not the AR family's
blindness there: on the issue-24 1/f records its model still held 3 % of the true power at
0.02 Hz and 13 % at 0.1 Hz (Burg: 3 % and 12 %).

What a record does show is the periodogram of its prewhitened residuals at its slowest
Fourier frequencies ``f_j = j/T``. Under the noise model, ``E I_j = σ_w² (1 - h_j)`` with
``h_j = ‖F_j Q‖²/n`` the share of that frequency the fit absorbs (``Q`` an orthonormal basis
of the prewhitened Jacobian; the restricted-likelihood correction, in the frequency domain).
The ratios ``R_j = I_j / (σ_w²(1 - h_j))`` are fitted by Whittle's likelihood with
``g(f) = 1 + A (f/f_1)^{-α}`` (``A ≥ 0``, ``0 ≤ α ≤ 3``); where the excess is significant
(likelihood ratio, ``χ²₂``), the prewhitened noise is given that extra spectrum, taken flat
below ``f_1/2`` (a record cannot see further down; the choice is stated, not fitted), and
its covariance through the fit, ``M Σ_extra Mᵀ`` with ``M = (J_wᵀJ_w)⁻¹J_wᵀ``, is added to
the estimate's (a sandwich for the part of the noise the model misses; circulant embedding
on a grid of ≥ 8 record lengths). Not in the thesis.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from scipy.optimize import minimize
from scipy.stats import chi2

from driveid.identify.core._noise import NoiseModel, segment_lengths

__all__ = ["slow_noise_covariance", "ORDINATES", "LEVEL"]

#: Slowest Fourier frequencies of each record whose periodogram is fitted [-] (periods T..T/10).
ORDINATES = 10
#: Significance of the excess below which no extra covariance is added [-].
LEVEL = 0.05
#: The excess is taken flat below this multiple of the record's fundamental 1/T [-].
FLAT_BELOW = 0.5
#: Ordinates the fit absorbs more than this share of are not used [-].
_MAX_LEVERAGE = 0.5


def _whittle(ratio: np.ndarray, rel_f: np.ndarray) -> tuple[float, float, float, np.ndarray]:
    """Fit ``g = 1 + A rel_f^-α`` to periodogram ratios.

    Returns A, α, the deviance gain over ``g = 1`` and the covariance of ``(ln A, α)`` (the
    inverse of the Whittle information ``Σ ∇ln g ∇ln gᵀ``).
    """
    def nll(v):
        g = 1.0 + math.exp(v[0]) * rel_f ** (-v[1])
        return float(np.sum(np.log(g) + ratio / g))

    base = float(np.sum(ratio))  # g = 1
    best = None
    for a0 in (-2.0, 0.0, 2.0):
        for alpha0 in (0.5, 1.5):
            res = minimize(nll, [a0, alpha0], method="L-BFGS-B",
                           bounds=[(-20.0, 20.0), (0.0, 3.0)])
            if best is None or res.fun < best.fun:
                best = res
    gain = max(0.0, 2.0 * (base - best.fun))
    amp, alpha = math.exp(best.x[0]), float(best.x[1])
    excess = amp * rel_f ** (-alpha)
    share = excess / (1.0 + excess)  # ∂ln g/∂ln A; ∂ln g/∂α = -share ln f
    grad = np.column_stack([share, -share * np.log(rel_f)])
    info = grad.T @ grad
    try:
        cov = np.linalg.inv(info)
    except np.linalg.LinAlgError:
        cov = np.diag([1.0 / max(info[0, 0], 1e-12), 0.0])
    if not np.all(np.isfinite(cov)) or cov[0, 0] <= 0:
        cov = np.diag([1.0 / max(info[0, 0], 1e-12), 0.0])
    return amp, alpha, gain, cov


def _through_fit(m_map: np.ndarray, kept: list[int], scale: float, alpha: float) -> np.ndarray:
    """``M Σ Mᵀ`` for the excess spectrum ``scale (ν m)^-α`` (flat below ν m = 1/2), per record."""
    k = m_map.shape[0]
    out = np.zeros((k, k))
    start = 0
    for m in kept:
        block = m_map[:, start:start + m]
        start += m
        if m < 2:
            continue
        size = 1 << int(math.ceil(math.log2(8 * m)))
        nu = np.abs(np.fft.fftfreq(size))  # cycles per sample
        spec = scale * np.maximum(nu * m, FLAT_BELOW) ** (-alpha)
        g = np.fft.fft(block, size, axis=1)
        out += ((g * spec) @ g.conj().T).real / size
    return out


def slow_noise_covariance(jac: np.ndarray, residual: np.ndarray, noise: NoiseModel, *,
                          segments: Sequence[int] | None = None, ordinates: int = ORDINATES,
                          level: float = LEVEL) -> tuple[np.ndarray, dict]:
    """Covariance of a prewhitened fit's estimate due to noise power its AR model misses.

    Parameters
    ----------
    jac : ndarray, shape (n, k)
        Jacobian at the estimate, not prewhitened [unit per parameter unit].
    residual : ndarray, shape (n,)
        Raw residuals at the estimate [unit].
    noise : NoiseModel
        The fit's prewhitening model.
    segments : sequence of int, optional
        Samples of each stacked record [-].
    ordinates : int
        Slowest Fourier frequencies of each record fitted [-].
    level : float
        Significance the excess must reach [-]; 1 adds the fitted excess whatever its size.

    Returns
    -------
    (ndarray, ndarray, dict)
        The extra covariance, shape (k, k) [parameter units²] (zeros when the excess is not
        significant); the sampling variance of its diagonal, shape (k,) [parameter units⁴],
        from that of ``(ln A, α)``; and the test: ``amplitude`` A [-], ``slope`` α [-],
        ``p_value``, ``ordinates`` used, ``applied`` (bool).
    """
    jac = np.asarray(jac, float)
    k = jac.shape[1]
    lengths = segment_lengths(segments, jac.shape[0])
    p = noise.order
    jw = noise.whiten(jac, lengths)
    rw = noise.whiten(np.asarray(residual, float), lengths)
    kept = [max(m - p, 0) for m in lengths]
    q, upper = np.linalg.qr(jw)
    m_map = np.linalg.solve(upper, q.T)  # (J_wᵀJ_w)⁻¹J_wᵀ, shape (k, n_w)
    s2 = float(rw @ rw) / max(rw.size - k, 1)
    ratios, rel_f = [], []
    start = 0
    for m in kept:
        part, basis = rw[start:start + m], q[start:start + m]
        start += m
        top = min(ordinates, m // 2 - 1)
        if top < 1:
            continue
        spec = np.fft.rfft(part)[1:top + 1]
        lev = np.sum(np.abs(np.fft.rfft(basis, axis=0)[1:top + 1]) ** 2, axis=1) / m
        for j in range(top):
            if lev[j] < _MAX_LEVERAGE:
                ratios.append(abs(spec[j]) ** 2 / m / (s2 * (1.0 - lev[j])))
                rel_f.append(j + 1.0)
    info = {"amplitude": 0.0, "slope": 0.0, "p_value": 1.0, "ordinates": len(ratios),
            "applied": False}
    extra = np.zeros((k, k))
    none = np.zeros(k)
    if len(ratios) < 3 or not s2 > 0:
        return extra, none, info
    amp, alpha, gain, fit_cov = _whittle(np.asarray(ratios), np.asarray(rel_f))
    p_value = float(chi2.sf(gain, 2))
    info.update(amplitude=amp, slope=alpha, p_value=p_value)
    if p_value >= level:
        return extra, none, info
    extra = _through_fit(m_map, kept, s2 * amp, alpha)
    # the sampling error of (ln A, α): central differences of the added variances
    step = 1e-3
    d_amp = np.diag(extra) * (math.exp(step) - math.exp(-step)) / (2.0 * step)
    d_alpha = (np.diag(_through_fit(m_map, kept, s2 * amp, alpha + step))
               - np.diag(_through_fit(m_map, kept, s2 * amp, alpha - step))) / (2.0 * step)
    grad = np.column_stack([d_amp, d_alpha])
    var_extra = np.einsum("ij,jk,ik->i", grad, fit_cov, grad)
    info["applied"] = True
    info["extra_variance_relsd"] = [float(v) for v in
                                    np.sqrt(np.maximum(var_extra, 0.0))
                                    / np.maximum(np.diag(extra), 1e-300)]
    return extra, var_extra, info
