"""Errors in variables of the IDIM least squares: position noise in the acceleration column.

Helpers of :func:`driveid.identify.friction.idim.estimate_idim`. The acceleration column is the
measured position filtered and differentiated twice, so white position noise of sd ``σ_x``
(an encoder's rounding, ``q/√12``) reaches it amplified by ``(2π f)²`` up to the cut-off. Least
squares then sees ``E[WᵀW] = W₀ᵀW₀ + n Σ_Δ`` and attenuates the inertia towards 0 (Fuller 1987
§1.1). Prewhitening for strongly coloured force noise (AR(1) 0.97: ``1 − 0.97 q⁻¹``, almost a
difference) weights exactly the band where that noise lives; issue 24's benchmark saw M 2.2 %
low, 1.5 standard errors, coverage 0.60.

The rows are linear in the position noise up to the ``sgn v`` and one-sided columns: each
row's error is ``Δ_i = Σ_k g[k] e[q i − k]`` with one kernel ``g`` per column (zero-phase
Butterworth, central differences, block means of ``q`` samples, the AR filter of the noise
model), so ``Σ_Δ`` and the lagged ``C(ℓ) = E[Δ_i Δ_{i+ℓ}ᵀ]`` follow from ``σ_x²`` and the
kernels. The corrected estimator ``θ_c = (XᵀX − n Σ_Δ)⁻¹ Xᵀy`` (Fuller 1987 §2.2, eq. 2.2.8
with a known error covariance) removes the bias; its covariance is the path's, carried
through ``(XᵀX − nΣ_Δ)⁻¹ XᵀX``, plus the spread of ``ΔᵀΔ`` about ``n Σ_Δ`` for Gaussian
``Δ`` (Isserlis): ``n Σ_ℓ [C(ℓ) θᵀC(ℓ)θ + C(ℓ)θ (C(ℓ)ᵀθ)ᵀ]``. The residual's ``−Δθ``
part is left to the path's noise model: adding its correlation across rows exactly
(``Σ_ℓ≠0 X_iX_{i+ℓ}ᵀ θᵀC(ℓ)θ``, negative for the high-passed noise) shrank the bars
and cut M's coverage from 0.91 to 0.85 at ``decimate=10`` under low-passed force noise.

``σ_x`` comes from the position's fourth differences, where white noise leaves ``70 σ_x²``
and a smooth motion a slowly varying part (removed by a running mean), as a mean square
trimmed at 8 robust sd (the robust sd alone reads rounding noise 23 % high: it is not
Gaussian), over moving samples only.

References
----------
.. [1] W. A. Fuller, *Measurement Error Models*, Wiley, 1987, §1.1, §2.2.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from driveid.signal.differentiate import differentiate
from driveid.signal.steady import standstill_mask

__all__: list[str] = []

#: Largest share of an acceleration column's power that may be noise [-]: beyond it the
#: correction divides by a difference of near-equal numbers, and a lower cut-off is the fix.
MAX_NOISE_SHARE = 0.5


@dataclass(frozen=True)
class RowNoise:
    """White position noise of one record and the rows' kernels it passes through.

    Attributes
    ----------
    sigma : float
        Standard deviation of the position noise [m or rad].
    kernels : ndarray, shape (2, m)
        Unit-noise impulse responses of a row's acceleration and velocity [1/s², 1/s],
        before the noise model's filter, at the raw sample rate.
    decimate : int
        Samples per row [-].
    """

    sigma: float
    kernels: np.ndarray
    decimate: int


def position_noise_sigma(x: np.ndarray, fs: float, cutoff_hz: float) -> float:
    """Return the sd of white noise on a sampled position from its fourth differences.

    Parameters
    ----------
    x : ndarray, shape (n,)
        Uniformly sampled position [m or rad].
    fs : float
        Sample rate [Hz].
    cutoff_hz : float
        The IDIM filter's cut-off [Hz]; sets the standstill window.

    Returns
    -------
    float
        σ_x [m or rad]; 0 when the record is too short, holds still throughout, or is
        exact to floating-point rounding (below 1e-11 of its span).
    """
    x = np.asarray(x, float)
    if x.size < 16:
        return 0.0
    window = max(1, round(fs / cutoff_hz))
    d4 = np.diff(x, 4)
    # a fast motion's own fourth differences are smooth: a running mean over 2·fs/cutoff + 1
    # samples takes them out and leaves noise's (whose running mean is almost 0: Δ⁴ has a
    # zero at 0 Hz)
    box = 2 * window + 1 if d4.size > 2 * window + 1 else 1
    d4 = d4 - np.convolve(d4, np.ones(box) / box, mode="same")
    still = standstill_mask(x, window)
    moving = ~(still[:-4] | still[4:])
    d4 = d4[moving]
    if d4.size < 8:
        return 0.0
    centre = float(np.median(d4))
    spread = 1.4826 * float(np.median(np.abs(d4 - centre)))
    if spread > 0:  # glitches out; 8 sd keeps every sample of Gaussian or rounding noise
        d4 = d4[np.abs(d4 - centre) < 8.0 * spread]
    sigma = math.sqrt(float(np.mean(d4 ** 2)) / 70.0)
    # floating-point rounding of an exact (simulated) position is noise of ~1e-16 of its
    # span: nothing to correct; a 1e-11 floor sits far below any sensor (a 30-bit encoder)
    return sigma if sigma > 1e-11 * float(np.ptp(x)) else 0.0


def row_noise(x: np.ndarray, fs: float, cutoff_hz: float, decimate: int,
              sigma: float | None) -> RowNoise:
    """Return the position noise of one record and its rows' kernels.

    Parameters
    ----------
    x : ndarray, shape (n,)
        Uniformly sampled position [m or rad].
    fs : float
        Sample rate [Hz].
    cutoff_hz : float
        Zero-phase Butterworth cut-off of the differentiation [Hz].
    decimate : int
        Samples per row [-].
    sigma : float or None
        Known position noise sd [m or rad]; None estimates it (:func:`position_noise_sigma`).

    Returns
    -------
    RowNoise
    """
    s = position_noise_sigma(x, fs, cutoff_hz) if sigma is None else float(sigma)
    half = 2 * math.ceil(10.0 * fs / cutoff_hz) + 8  # the filter has decayed by 1e-9
    impulse = np.zeros(2 * half + 1)
    impulse[half] = 1.0
    _, v, a = differentiate(impulse, fs, cutoff_hz=cutoff_hz)
    k = np.vstack([a, v])
    if decimate > 1:
        box = np.ones(int(decimate)) / int(decimate)
        k = np.vstack([np.convolve(row, box) for row in k])
    live = np.flatnonzero(np.max(np.abs(k), axis=0) > 1e-12 * float(np.max(np.abs(k))))
    return RowNoise(s, k[:, live[0]:live[-1] + 1], int(decimate))


def _lagged(kernels: np.ndarray, q: int) -> np.ndarray:
    """``C(ℓ) = Σ_m g[m] g[m + qℓ]ᵀ`` for ℓ = −L..L, unit noise; shape (2L + 1, k, k)."""
    k, m = kernels.shape
    ell = np.arange(-((m - 1) // q), (m - 1) // q + 1)
    out = np.empty((ell.size, k, k))
    for i in range(k):
        for j in range(k):
            # correlate(g_j, g_i)[m - 1 + s] = Σ_t g_j[t + s] g_i[t]
            out[:, i, j] = np.correlate(kernels[j], kernels[i], mode="full")[m - 1 + q * ell]
    return out


def _whitened(kernels: np.ndarray, q: int, ar: tuple[float, ...]) -> np.ndarray:
    b = np.concatenate([[1.0], -np.asarray(ar, float)])
    out = np.zeros((kernels.shape[0], kernels.shape[1] + q * (b.size - 1)))
    for j, bj in enumerate(b):
        out[:, q * j:q * j + kernels.shape[1]] += bj * kernels
    return out


def correct(X: np.ndarray, y: np.ndarray, theta: np.ndarray, cov: np.ndarray,
            columns: list[int | None], blocks: list[tuple[RowNoise, float, int]],
            ar: tuple[float, ...]) -> tuple[np.ndarray, np.ndarray, dict[str, Any]]:
    """Correct a least-squares fit for the position noise in its acceleration column.

    Parameters
    ----------
    X : ndarray, shape (n, p)
        The reported fit's rows (prewhitened where it is) [mixed units].
    y : ndarray, shape (n,)
        Its force [N or N·m].
    theta : ndarray, shape (p,)
        Its estimate [parameter units].
    cov : ndarray, shape (p, p)
        Its covariance [parameter units²].
    columns : list
        Position in ``X`` of the acceleration and the velocity column (None: not there) [-].
    blocks : list of (RowNoise, float, int)
        Per record: its noise, row weight ``w`` [-] and number of rows in ``X`` [-].
    ar : tuple of float
        The AR filter the rows passed through (empty: none) [-].

    Returns
    -------
    tuple
        ``(theta, cov, info)``; ``info["applied"]`` False leaves the fit as it was
        (no noise, no acceleration column, or noise above ``MAX_NOISE_SHARE``).
    """
    p = X.shape[1]
    sigma_rows = np.zeros((p, p))
    lagged: list[tuple[float, int, np.ndarray]] = []
    embed = np.zeros((p, 2))
    for j, col in enumerate(columns):
        if col is not None:
            embed[col, j] = 1.0
    for noise, weight, rows in blocks:
        if noise.sigma <= 0 or rows == 0 or columns[0] is None:
            continue
        g = _whitened(noise.kernels, noise.decimate, ar)
        c = np.einsum("pi,lij,qj->lpq", embed, _lagged(g, noise.decimate), embed)
        scale = weight * noise.sigma ** 2
        sigma_rows += rows * scale * c[c.shape[0] // 2]
        lagged.append((scale, rows, c))
    info: dict[str, Any] = {"applied": False, "sigma": [b[0].sigma for b in blocks]}
    if not lagged:
        return theta, cov, info
    xtx = X.T @ X
    a = columns[0]
    share = float(sigma_rows[a, a] / xtx[a, a])
    info["noise_share"] = share
    if not share < MAX_NOISE_SHARE:
        return theta, cov, info
    corrected = xtx - sigma_rows
    try:
        lower = np.linalg.cholesky(corrected)
    except np.linalg.LinAlgError:  # the noise swamps a direction of the fit
        return theta, cov, info
    inv = np.linalg.inv(corrected)
    theta_c = inv @ (X.T @ y)
    spread = np.zeros((p, p))
    for scale, rows, c in lagged:
        c = scale * c
        across = np.einsum("i,lij,j->l", theta_c, c, theta_c)  # E[Δ_iᵀθ Δ_{i+ℓ}ᵀθ]
        spread += rows * (np.einsum("l,lij->ij", across, c)
                          + np.einsum("li,lj->ij", c @ theta_c, c.transpose(0, 2, 1) @ theta_c))
    carry = inv @ xtx
    cov_c = carry @ cov @ carry.T + inv @ spread @ inv
    se = np.sqrt(np.diag(cov))
    # the bounded refit minimises θᵀ(XᵀX − nΣ_Δ)θ − 2θᵀXᵀy = ‖Lᵀθ − L⁻¹Xᵀy‖² + const
    info.update(applied=True,
                shift_se=((theta_c - theta) / np.where(se > 0, se, np.inf)).tolist(),
                system=(lower.T, np.linalg.solve(lower, X.T @ y)))
    return theta_c, cov_c, info
