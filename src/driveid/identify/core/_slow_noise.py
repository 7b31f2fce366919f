r"""Noise slower than an AR model sees: a power-law excess at the record's slowest frequencies.

An AR(p) noise model fitted to a fit's residuals is set by the one-step prediction error,
i.e. by the whole spectrum (Whittle), in which the few Fourier frequencies near zero count
little; 1/f-like noise has most of its power there. Those frequencies are also the ones the
offset- and drift-like unknowns absorb. Restricted maximum likelihood of the AR coefficients
(the likelihood of the residuals' error contrasts, which accounts for that absorption) was
measured and does not help: on the issue-24 1/f records its model held 3 % of the true power
at 0.02 Hz and 13 % at 0.1 Hz (Burg: 3 % and 12 %), because the AR family, not the
absorption, is what is blind there (docs/output-error.md).

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

__all__ = ["slow_noise_covariance", "excess_covariance", "ORDINATES", "LEVEL", "FLAT_BELOW"]

#: Slowest Fourier frequencies of each record whose periodogram is fitted [-] (periods T..T/10).
ORDINATES = 10
#: Significance of the excess below which no extra covariance is added [-].
LEVEL = 0.05
#: The excess is taken flat below this multiple of the record's fundamental 1/T [-].
FLAT_BELOW = 0.5
#: Ordinates the fit absorbs more than this share of are not used [-].
_MAX_LEVERAGE = 0.5


def _whittle(ratio: np.ndarray, rel_f: np.ndarray) -> tuple[float, float, float]:
    """Fit ``g = 1 + A rel_f^-α`` to periodogram ratios by Whittle's likelihood.

    Returns A, α and the deviance gain over ``g = 1`` (a few starts: the likelihood is flat
    in α where A is small).
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
    return math.exp(best.x[0]), float(best.x[1]), max(0.0, 2.0 * (base - best.fun))


def _through_fit(m_map: np.ndarray, kept: list[int], scale: float, alpha: float,
                 ar: Sequence[float] = ()) -> np.ndarray:
    """``M Σ Mᵀ`` for the excess spectrum ``scale (ν m)^-α`` (flat below ν m = 1/2), per record.

    With ``ar`` the map acts on unwhitened rows, whose excess is the prewhitened one over
    ``|A(ν)|²``, ``A(ν) = 1 - Σ a_j e^{-2πiνj}`` (the AR model's whitening filter).
    """
    k = m_map.shape[0]
    out = np.zeros((k, k))
    start = 0
    for m in kept:
        block = m_map[:, start:start + m]
        start += m
        if m < 2:
            continue
        size = 1 << int(math.ceil(math.log2(8 * m)))
        freq = np.fft.fftfreq(size)  # cycles per sample
        spec = scale * np.maximum(np.abs(freq) * m, FLAT_BELOW) ** (-alpha)
        if len(ar):
            lags = np.arange(1, len(ar) + 1)
            spec = spec / np.abs(1.0 - np.exp(-2j * np.pi * np.outer(freq, lags)) @ np.asarray(
                ar, float)) ** 2
        g = np.fft.fft(block, size, axis=1)
        out += ((g * spec) @ g.conj().T).real / size
    return out


def slow_noise_covariance(jac: np.ndarray, residual: np.ndarray, noise: NoiseModel, *,
                          segments: Sequence[int] | None = None, ordinates: int = ORDINATES,
                          level: float | None = None) -> tuple[np.ndarray, dict]:
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
    level : float, optional
        Significance the excess must reach [-]; default :data:`LEVEL` (0: never widen).

    Returns
    -------
    (ndarray, dict)
        The extra covariance, shape (k, k) [parameter units²] (zeros when the excess is not
        significant), and the test (:func:`excess_covariance`).

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> n = 2000
    >>> jac = np.column_stack([np.ones(n), np.sin(np.arange(n) / 50.0)])
    >>> e = rng.normal(size=n)
    >>> r = e - jac @ np.linalg.lstsq(jac, e, rcond=None)[0]
    >>> from driveid.identify.core._noise import white_noise
    >>> extra, test = slow_noise_covariance(jac, r, white_noise(r))
    >>> test["applied"], float(np.abs(extra).max())
    (False, 0.0)
    """
    lengths = segment_lengths(segments, np.asarray(jac).shape[0])
    kept = [max(m - noise.order, 0) for m in lengths]
    return excess_covariance(noise.whiten(jac, lengths), noise.whiten(residual, lengths), kept,
                             ordinates=ordinates, level=level)


def excess_covariance(jac_w: np.ndarray, residual_w: np.ndarray, kept: Sequence[int], *,
                      ordinates: int = ORDINATES, level: float | None = None,
                      unwhitened: tuple[np.ndarray, Sequence[int], NoiseModel] | None = None,
                      ) -> tuple[np.ndarray, dict]:
    """:func:`slow_noise_covariance` on an already prewhitened Jacobian and residual.

    Parameters
    ----------
    jac_w : ndarray, shape (n_w, k)
        Prewhitened Jacobian ``J_w`` [unit per parameter unit].
    residual_w : ndarray, shape (n_w,)
        Prewhitened residuals [unit].
    kept : sequence of int
        Prewhitened rows of each record, in stacking order [-].
    ordinates : int
        Slowest Fourier frequencies of each record fitted [-].
    level : float, optional
        Significance the excess must reach [-]; default :data:`LEVEL` (0: never widen).
    unwhitened : (ndarray, sequence of int, NoiseModel), optional
        ``(J, lengths, model)`` when the estimate is the ordinary least-squares one of the
        unwhitened rows ``J`` [unit per parameter unit] (records of ``lengths`` rows) and
        ``jac_w``, ``residual_w`` are its prewhitening by ``model``: the excess is tested on
        the prewhitened residual and taken through ``(JᵀJ)⁻¹Jᵀ`` with its spectrum over the
        model's ``|A(ν)|²``.

    Returns
    -------
    (ndarray, dict)
        The extra covariance ``M Σ_extra Mᵀ``, shape (k, k) [parameter units²] (zeros when
        the excess is not significant), and the test: ``amplitude`` A [-], ``slope`` α [-],
        ``p_value``, ``ordinates`` used, ``applied`` (bool).
    """
    jw = np.asarray(jac_w, float)
    rw = np.asarray(residual_w, float)
    kept = [int(m) for m in kept]
    k = jw.shape[1]
    q, upper = np.linalg.qr(jw)
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
        # E I_j = σ_w² (1 - h_j): h_j the share of frequency j the fit absorbs
        lev = np.sum(np.abs(np.fft.rfft(basis, axis=0)[1:top + 1]) ** 2, axis=1) / m
        for j in range(top):
            if lev[j] < _MAX_LEVERAGE:
                ratios.append(abs(spec[j]) ** 2 / m / (s2 * (1.0 - lev[j])))
                rel_f.append(j + 1.0)
    info = {"amplitude": 0.0, "slope": 0.0, "p_value": 1.0, "ordinates": len(ratios),
            "applied": False}
    extra = np.zeros((k, k))
    if len(ratios) < 3 or not s2 > 0:
        return extra, info
    amp, alpha, gain = _whittle(np.asarray(ratios), np.asarray(rel_f))
    p_value = float(chi2.sf(gain, 2))
    info.update(amplitude=amp, slope=alpha, p_value=p_value)
    if p_value >= (LEVEL if level is None else level):
        return extra, info
    info["applied"] = True
    if unwhitened is not None:
        jac, lengths, model = unwhitened
        q_raw, upper_raw = np.linalg.qr(np.asarray(jac, float))
        return _through_fit(_solve_upper(upper_raw, q_raw.T), [int(m) for m in lengths],
                            s2 * amp, alpha, model.ar), info
    m_map = _solve_upper(upper, q.T)  # (J_wᵀJ_w)⁻¹J_wᵀ, shape (k, n_w)
    return _through_fit(m_map, kept, s2 * amp, alpha), info


def _solve_upper(upper: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """Return ``R⁻¹ rhs``; by least squares where R is singular.

    A singular R is an unknown the record does not determine: its share of the extra
    variance is left out rather than raising (the fit's own checks name that unknown).
    """
    try:
        return np.linalg.solve(upper, rhs)
    except np.linalg.LinAlgError:
        return np.linalg.lstsq(upper, rhs, rcond=None)[0]
