r"""Replicates of a fitted noise model through the linearised fit: bias and RSS calibration.

A whole-record fit estimates its AR noise model from its own residuals
``r = y - f(θ̂)``, and the fit has already taken out of ``r`` the part of the noise that
looks like a change of the parameters: ``r ≈ (I - J M A) e`` with ``M = (J_wᵀJ_w)⁻¹J_wᵀ``,
``J_w = A(q)J`` (prediction error, Ljung [1]_ §7.3). For white noise that is the familiar
``n - k`` degrees of freedom. For strongly coloured noise it is not small: the offset,
release and frequency columns of a free decay absorb most of the noise's slow wander, so
the AR coefficients fitted to ``r`` are biased towards less colour (AR(1) φ = 0.97 from a
2000-sample decay: 0.961 on average; 0.968 from the noise itself). Near the unit circle the
low-frequency power ``σ_w²/(1 - φ)²`` is very sensitive to φ, and the error bars came out
25 % short.

:func:`linearised_replicates` draws noise from the fitted model, passes it through the same
linearised fit (``e → (I - J M A) e``) and refits the AR model of the same order: the mean
shift of the coefficients is the bias, removed by two rounds of the bootstrap bias
correction ``â_c = â - (E*[â*] - â_c)`` (Efron and Tibshirani [2]_ §10.6; the same idea as
the Kendall correction of AR(1), here with the fit's own projection). The same replicates
give the distribution of ``RSS_raw(PE)/RSS_raw(LS)``, the growth of the raw residual sum
of squares when the fit is prewhitened, against which a prewhitened fit that "wandered" (an
AR model fitted to a misfit) is judged: strongly coloured noise has few effective degrees
of freedom, so a genuine prewhitened fit may raise the raw RSS by 10-20 %.

Random numbers come from a fixed seed, so that the same record always gets the same noise
model (and error bars).

References
----------
.. [1] L. Ljung, *System Identification: Theory for the User*, 2nd ed., Prentice Hall, 1999.
.. [2] B. Efron, R. J. Tibshirani, *An Introduction to the Bootstrap*, Chapman & Hall, 1993.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
from scipy.signal import lfilter
from scipy.stats import t as student_t

from driveid.identify.core._noise import NoiseModel, fit_noise_model, segment_lengths

__all__ = ["Replicates", "linearised_replicates", "simulate_noise", "process_variance",
           "student_widening"]

#: Replicates per round [-]: the mean coefficient shift to ~1/6 of its own spread.
DRAWS = 32
#: Rounds of the bias correction [-].
ROUNDS = 2
_SEED = 24


def simulate_noise(noise: NoiseModel, segments: Sequence[int], variance: float,
                   rng: np.random.Generator) -> np.ndarray:
    """Draw stacked AR noise of the model's spectrum, scaled to ``variance``.

    Parameters
    ----------
    noise : NoiseModel
        AR model (white for order 0).
    segments : sequence of int
        Samples of each record [-].
    variance : float
        Variance of the drawn noise [unit²].
    rng : Generator
        Random generator.

    Returns
    -------
    ndarray, shape (sum(segments),)
        Noise [unit]; a burn-in of 10/(1 - max|pole|) samples (at most 5000) per record
        puts each record in the stationary state.
    """
    a = np.concatenate([[1.0], -np.asarray(noise.ar, float)])
    poles = np.abs(np.roots(a)) if noise.order else np.zeros(1)
    burn = int(min(5000, 10.0 / max(1.0 - float(np.max(poles)), 1e-3))) if noise.order else 0
    parts = []
    for length in segments:
        w = rng.normal(size=length + burn)
        parts.append(lfilter([1.0], a, w)[burn:] if noise.order else w)
    e = np.concatenate(parts)
    scale = math.sqrt(max(variance, 0.0) / max(float(e @ e) / e.size, 1e-300))
    return e * scale


def process_variance(ar: Sequence[float], innovation_variance: float) -> float:
    """Stationary variance ``σ_w² Σ h_k²`` of an AR process [unit²].

    Parameters
    ----------
    ar : sequence of float
        ``a_1 … a_p`` [-]; all poles inside the unit circle.
    innovation_variance : float
        σ_w² [unit²].

    Returns
    -------
    float
    """
    if not len(ar):
        return float(innovation_variance)
    a = np.concatenate([[1.0], -np.asarray(ar, float)])
    pole = float(np.max(np.abs(np.roots(a))))
    length = int(min(2_000_000, 40.0 / max(1.0 - pole, 1e-6) + 100))
    pulse = np.zeros(length)
    pulse[0] = 1.0
    h = lfilter([1.0], a, pulse)
    return float(innovation_variance * (h @ h))


@dataclass(frozen=True)
class Replicates:
    """Result of :func:`linearised_replicates`.

    Attributes
    ----------
    noise : NoiseModel
        The bias-corrected model (the given one for white noise).
    shift : tuple of float
        Coefficients removed as bias, ``â - â_c`` [-].
    rss_ratio_mean, rss_ratio_sd : float
        Mean and sd of ``RSS_raw(PE)/RSS_raw(LS)`` over the replicates [-].
    ar_draws : tuple of tuple of float
        The refitted coefficients of the last round's replicates [-]: the sampling spread
        of the noise model.
    """

    noise: NoiseModel
    shift: tuple[float, ...]
    rss_ratio_mean: float
    rss_ratio_sd: float
    ar_draws: tuple[tuple[float, ...], ...] = ()

    def rss_limit(self, floor: float = 1.05, cap: float = 2.0) -> float:
        """Largest plausible ``RSS_raw(PE)/RSS_raw(LS)`` [-]: mean + 5 sd within [floor, cap].

        Five sd: the ratio is skewed to the right and its sd comes from 32 draws (±13 %).
        The cap: an AR model fitted to a misfit (air drag at the mode) puts a pole on the
        mode, and its own replicates then allow anything (limits of 10⁴ were seen); a noise
        model that explains more than half of the raw residual power as absorbed by the
        parameters is not describing noise.

        Parameters
        ----------
        floor : float
            Smallest limit returned [-].
        cap : float
            Largest limit returned [-].

        Returns
        -------
        float
        """
        return min(cap, max(floor, self.rss_ratio_mean + 5.0 * self.rss_ratio_sd))


def _stationary(a: np.ndarray) -> bool:
    return bool(np.max(np.abs(np.roots(np.concatenate([[1.0], -a])))) < 1.0 - 1e-6)


def linearised_replicates(noise: NoiseModel, jac: np.ndarray, residual: np.ndarray, *,
                          segments: Sequence[int] | None = None, draws: int = DRAWS,
                          rounds: int = ROUNDS,
                          whitening: NoiseModel | None = None) -> Replicates:
    """Bias-correct an AR noise model fitted to a fit's residuals; calibrate the RSS growth.

    Parameters
    ----------
    noise : NoiseModel
        AR model fitted (Burg) to ``residual``.
    jac : ndarray, shape (n, k)
        Jacobian of the fitted model at the estimate, not prewhitened [unit per parameter
        unit].
    residual : ndarray, shape (n,)
        The residuals the model was fitted to [unit].
    segments : sequence of int, optional
        Samples of each stacked record [-].
    draws : int
        Replicates per round [-].
    rounds : int
        Rounds of the bias correction [-].
    whitening : NoiseModel, optional
        The prewhitening filter of the fit that left ``residual`` (its projection is what
        the replicates pass through); default the model being corrected.

    Returns
    -------
    Replicates
        The corrected model (same order; its innovation variance from the residuals
        whitened by it, its variance the process's) and the RSS-growth distribution.

    Examples
    --------
    >>> rng = np.random.default_rng(3)
    >>> t = np.arange(2000) / 200.0
    >>> jac = np.column_stack([np.ones_like(t), t, np.sin(4 * t)])
    >>> e = lfilter([1.0], [1.0, -0.97], rng.normal(size=2000))
    >>> r = e - jac @ np.linalg.lstsq(jac, e, rcond=None)[0]
    >>> fitted = fit_noise_model(r, order=1)
    >>> rep = linearised_replicates(fitted, jac, r)
    >>> bool(rep.noise.ar[0] > fitted.ar[0])
    True
    """
    if noise.is_white:
        return Replicates(noise, (), 1.0, 0.0)
    jac = np.asarray(jac, float)
    r = np.asarray(residual, float)
    lengths = segment_lengths(segments, r.size)
    p = noise.order
    a_hat = np.asarray(noise.ar, float)
    a = a_hat.copy()
    ratios: list[float] = []
    for _ in range(max(rounds, 1)):
        model = replace(noise, ar=tuple(float(v) for v in a))
        fitter = model if whitening is None else whitening
        jw = fitter.whiten(jac, lengths)
        gram = jw.T @ jw
        gen = np.random.default_rng(_SEED)  # common random numbers: rounds comparable
        found, ratios = [], []
        for _ in range(draws):
            e = simulate_noise(model, lengths, 1.0, gen)
            r_pe = e - jac @ np.linalg.lstsq(gram, jw.T @ fitter.whiten(e, lengths),
                                             rcond=None)[0]
            r_ls = e - jac @ np.linalg.lstsq(jac, e, rcond=None)[0]
            ratios.append(float(r_pe @ r_pe) / max(float(r_ls @ r_ls), 1e-300))
            refit = fit_noise_model(r_pe, segments=lengths, order=p)
            if refit.order == p:
                found.append(refit.ar)
        if not found:
            break
        bias = np.mean(np.asarray(found, float), axis=0) - a
        new = a_hat - bias
        step = 1.0
        while not _stationary(new) and step > 1e-3:  # a correction never leaves the circle
            step *= 0.5
            new = a_hat - step * bias
        if not _stationary(new):
            new = a_hat
        a = new
    corrected = replace(noise, ar=tuple(float(v) for v in a))
    white = corrected.whiten(r, lengths)
    scale = noise.innovation_variance / max(_power(noise.whiten(r, lengths)), 1e-300)
    innovation = _power(white) * scale  # the caller's n/(n - n_params) scaling kept
    corrected = replace(corrected, innovation_variance=innovation,
                        variance=process_variance(corrected.ar, innovation),
                        method="burg, bias-corrected")
    q = np.asarray(ratios, float)
    # the spread about the corrected model: the replicates' spread about their own mean
    spread = [tuple(float(v) for v in a + (np.asarray(d) - np.mean(found, axis=0)))
              for d in found] if found else []
    return Replicates(corrected, tuple(float(v) for v in a_hat - a),
                      float(np.mean(q)) if q.size else 1.0,
                      float(np.std(q, ddof=1)) if q.size > 1 else 0.0,
                      tuple(d for d in spread if _stationary(np.asarray(d))))


def student_widening(jac: np.ndarray, residual: np.ndarray, replicates: Replicates, *,
                     segments: Sequence[int] | None = None, n_params: int = 0) -> np.ndarray:
    """Factors on the standard errors for the noise model's own sampling error.

    The prewhitened covariance ``s_w² (J_wᵀJ_w)⁻¹`` is evaluated at the estimated AR
    coefficients; near the unit circle its diagonal moves by ±20-30 % between equally
    likely noise models (AR(1) 0.97 from 2000 samples: φ̂ sd 0.007). A variance estimate
    with relative variance ``v`` has Satterthwaite degrees of freedom ``ν = 2/v``; the 95 %
    interval is then Student's, and the factor ``t_{ν,0.975}/1.96`` puts that width on
    ±1.96 standard errors (as the bootstrap error bars of quantised records do).

    Parameters
    ----------
    jac : ndarray, shape (n, k)
        Jacobian at the estimate, not prewhitened [unit per parameter unit].
    residual : ndarray, shape (n,)
        Raw residuals at the estimate [unit].
    replicates : Replicates
        From :func:`linearised_replicates` (its ``ar_draws``).
    segments : sequence of int, optional
        Samples of each stacked record [-].
    n_params : int
        Unknowns of the fit [-] (degrees of freedom of ``s_w²``).

    Returns
    -------
    ndarray, shape (k,)
        Factors >= 1 [-]; ones when there are fewer than 8 draws.
    """
    jac = np.asarray(jac, float)
    k = jac.shape[1]
    if len(replicates.ar_draws) < 8:
        return np.ones(k)
    lengths = segment_lengths(segments, jac.shape[0])
    diags = []
    for ar in replicates.ar_draws:
        model = replace(replicates.noise, ar=ar)
        jw = model.whiten(jac, lengths)
        rw = model.whiten(residual, lengths)
        s2 = float(rw @ rw) / max(rw.size - n_params, 1)
        try:
            diags.append(np.diag(np.linalg.inv(jw.T @ jw)) * s2)
        except np.linalg.LinAlgError:
            continue
    if len(diags) < 8:
        return np.ones(k)
    d = np.asarray(diags)
    rel = np.var(d, axis=0, ddof=1) / np.maximum(np.mean(d, axis=0) ** 2, 1e-300)
    nu = 2.0 / np.maximum(rel, 1e-12)
    return np.maximum(student_t.ppf(0.975, nu) / 1.959964, 1.0)


def _power(x: np.ndarray) -> float:
    return float(x @ x) / x.size if x.size else math.nan
