"""Encoder records: detecting the quantum and the bootstrap error bars of a quantised fit.

An encoder's rounding is not white noise: it follows the signal (constant while the axis
sticks), so ``s²(JᵀJ)⁻¹`` misstates the error. The output-error fits (free decays here, PHO
campaigns in :mod:`driveid.identify.pho.pho_fit`) refit the fitted response re-quantised on
randomly shifted grids instead, and widen the replicate covariance for their number. With
coloured noise the replicates' noise is a long AR model of the residuals less the rounding's
white floor, and the covariance is calibrated for the record's own noise-model error (issue
24: low-pass noise with encoder steps under-covered, 0.81-0.88, with AR noise of the BIC
order that held the floor).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from scipy import stats

from driveid.errors import IdentificationError
from driveid.identify.core._adequacy import ljung_box
from driveid.identify.core._noise import MAX_ORDER, fit_noise_model
from driveid.identify.free_decay._free_response import SINK_ROWS
from driveid.signal.repair import _interval_blocks

__all__ = ["bootstrap_covariance", "detect_quantum", "noise_model_calibration",
           "replicate_covariance"]

#: samples per block of the quantum search (O(block) memory at any record length)
_BLOCK = 1 << 16
#: largest departure of a sample from the encoder grid [steps]: a file printed with ~3
#: significant digits fewer than the step still reads as quantised; unquantised data
#: depart by up to half a (smallest) step
_GRID_TOL = 1e-3


def detect_quantum(x: np.ndarray) -> float | None:
    """Return the encoder step of a quantised position signal, or ``None``.

    Parameters
    ----------
    x : ndarray, shape (n,)
        Position samples [m or rad].

    Returns
    -------
    float or None
        The step [m or rad] if every sample lies on one grid of at least 8 levels (to
        :data:`_GRID_TOL` of a step), else ``None``.

    Notes
    -----
    The smallest step between samples starts the search; the step is then refined over
    all steps and all levels, because a lab's export prints counts converted to metres or
    radians with a fixed number of decimals: 8000 counts/rev printed to 1e-7 rad leaves
    each step 1e-4 of itself off, which the smallest step alone carries to a whole count
    by level ~5000 (the drive fit then missed the encoder and biased the backlash gap).
    """
    x = np.asarray(x, float)
    # in blocks (O(block) memory at any length; the same numbers as whole-array passes)
    blocks = range(0, x.size, _BLOCK)
    floor = 1e-12 * max(max(float(np.max(np.abs(x[s:s + _BLOCK]))) for s in blocks), 1e-300)
    q = math.inf
    for _, step in _interval_blocks(x, _BLOCK):
        step = np.abs(step)
        step = step[step > floor]
        if step.size:
            q = min(q, float(np.min(step)))
    if q == math.inf:
        return None
    # refine over every step that is a whole number of smallest steps: Σ|step| / Σ counts
    total = counts = 0.0
    for _, step in _interval_blocks(x, _BLOCK):
        m = np.round(np.abs(step) / q)
        whole = (m >= 1) & (np.abs(np.abs(step) / q - m) <= 0.25)
        total += float(np.sum(np.abs(step[whole])))
        counts += float(np.sum(m[whole]))
    if counts > 0:
        q = total / counts
    for final in (False, True):
        # least squares over the levels (x - x0 = q k), then the largest departure
        worst, low, high, xk, kk = 0.0, math.inf, -math.inf, 0.0, 0.0
        for s in blocks:
            scaled = (x[s:s + _BLOCK] - x[0]) / q
            k = np.round(scaled)
            worst = max(worst, float(np.max(np.abs(scaled - k))))
            low, high = min(low, float(np.min(k))), max(high, float(np.max(k)))
            xk += float(np.sum((x[s:s + _BLOCK] - x[0]) * k))
            kk += float(np.sum(k * k))
        if final or kk == 0.0:
            break
        q = xk / kk
    if worst > _GRID_TOL or high - low < 8:
        return None
    return q


def bootstrap_covariance(problem, chosen, s2, quantum, replicates, rng, progress=None):
    """Covariance of refits to the fitted response re-quantised on randomly shifted grids.

    With a coloured noise model the noise re-added before re-quantising is Gaussian noise of
    a long AR model (order :data:`~driveid.identify.core._noise.MAX_ORDER`) of the residuals,
    less the rounding's white floor (:func:`_continuous_noise`), each replicate is refitted
    with the record's prewhitening, and the covariance is calibrated for the record's own
    noise-model error (:func:`noise_model_calibration`). Issue 24, low-pass noise at 5x the
    mode with 0.01 rad steps, 200 records: coverage 0.86-0.91 with AR noise of the BIC
    order, 0.89-0.91 with the long model less the floor alone, 0.93-0.94 with the
    calibration too (0.94-0.97 with the true noise in the replicates).

    Parameters
    ----------
    problem : _Problem
        The output-error problem of :mod:`~driveid.identify.free_decay.output_error` (its
        ``model``, ``fit``, ``noise`` and ``segments``); ``problem.boot_q`` receives each
        replicate's Ljung–Box statistic.
    chosen : dict
        The chosen candidate: ``p`` (parameter vector) and ``counts`` (half cycles).
    s2 : float
        Residual variance of the fit [m² or rad²].
    quantum : float
        Encoder step [m or rad].
    replicates : int
        Bootstrap refits [-].
    rng : Generator or int or None
        Random generator or seed; None is seed 0 (the same record, the same error bars).
    progress : callable, optional
        Called as ``progress(done, total)`` after each refit.

    Returns
    -------
    ndarray, shape (p, p)
        Covariance of the parameter vector, widened for the number of replicates (and,
        coloured, calibrated; the factors are left in ``problem.boot_calibration``).

    Raises
    ------
    IdentificationError
        If fewer than half the refits (or 10) converge.
    """
    gen = np.random.default_rng(0 if rng is None else rng)  # reproducible by default
    fitted, _ = problem.model(chosen["p"], chosen["counts"], jacobian=False)
    # noise beyond the rounding itself (variance q²/12), re-added before re-quantising
    noise = problem.noise
    raw_var = s2 if noise.is_white else noise.variance
    extra = math.sqrt(max(raw_var - quantum**2 / 12.0, 0.0))
    estimates = []
    problem.boot_q = []
    # coloured (issue 24): the replicates' noise is a long AR model of the residuals less the
    # rounding's white floor (see _continuous_noise), and the error bars the record's own
    # noise model gives are compared with those each replicate's refitted model gives
    # (noise_model_calibration)
    source = reading = None
    # a refused AR model (the white fit kept) still leaves coloured residuals: white
    # replicates would be several times short there (z of 8 seen, with no warning)
    if not noise.is_white or getattr(problem, "noise_rejected", False):
        source = fit_noise_model(_joined_y(problem) - fitted, segments=problem.segments,
                                 order=MAX_ORDER, n_params=chosen["p"].size)
    if not noise.is_white:
        jac = problem.model(chosen["p"], chosen["counts"])[1] \
            if problem.n <= SINK_ROWS else None
        reading = _analytic_variances(problem, chosen, noise, jac)
    readings = []
    for k in range(replicates):
        phase = gen.uniform(0.0, quantum)
        if source is not None:
            noisy = fitted + _continuous_noise(source, quantum, problem.segments, gen)
        else:
            noisy = fitted + (gen.normal(0.0, extra, fitted.size) if extra > 0 else 0.0)
        y_b = quantum * np.round((noisy - phase) / quantum) + phase
        sol = problem.fit(chosen["p"], chosen["counts"], y=y_b, max_iter=30)
        # from the optimum, 30 iterations that still gain are near the replicate's own
        if sol.status >= 0 and np.all(np.isfinite(sol.x)):
            estimates.append(sol.x)
            # whiteness statistic of a record that fits the model exactly: quantisation
            # alone makes residuals non-white, so the observed one is judged against these
            r_b = noise.whiten(y_b - problem.model(sol.x, chosen["counts"], False)[0],
                               problem.segments)
            problem.boot_q.append(ljung_box(r_b, fitted=noise.order)["statistic"])
            if reading is not None:
                raw_b = y_b - problem.model(sol.x, chosen["counts"], False)[0]
                refit = fit_noise_model(raw_b, segments=problem.segments,
                                        n_params=sol.x.size)
                readings.append(_analytic_variances(problem, chosen, refit, jac))
        if progress is not None:
            progress(k + 1, replicates)
    if len(estimates) < max(10, replicates // 2):
        raise IdentificationError(
            f"only {len(estimates)} of {replicates} bootstrap refits converged; the error bars "
            "of this quantised record cannot be trusted (record more cycles or a finer encoder)")
    cov = replicate_covariance(estimates)
    if reading is None:
        return cov
    factors = noise_model_calibration(reading, readings, len(estimates))
    problem.boot_calibration = factors
    return cov * np.outer(factors, factors)


def _joined_y(problem):
    return problem.y[0] if len(problem.y) == 1 else np.concatenate(problem.y)


def _continuous_noise(noise, quantum, segments, gen):
    """Gaussian noise of the model's spectrum less the rounding's white floor, per record.

    An AR model fitted to a quantised record's residuals holds the rounding (variance q²/12,
    white where the signal moves): noise of that whole spectrum, re-quantised, is dithered
    by its own white part, so its rounding comes out white where the record's follows a
    slow, smooth noise (at the turning points), and the replicates scatter less than the
    records (issue 24). The floor is taken off the spectrum (not off the variance, which
    would thin the low frequencies), and re-quantising puts the rounding back. Drawn by FFT
    on twice the record's length (the circular wrap falls in the discarded half).
    """
    parts = []
    for length in segments:
        size = 2 * length
        freq = np.fft.rfftfreq(size)  # [cycles a sample]
        a = np.ones(freq.size, complex)
        for j, coeff in enumerate(noise.ar, start=1):
            a -= coeff * np.exp(-2j * np.pi * freq * j)
        # two-sided density [unit² per cycle a sample]: integrates to the variance
        density = np.maximum(noise.innovation_variance / np.abs(a) ** 2 - quantum**2 / 12.0,
                             0.0)
        spec = np.sqrt(density * size / 2.0) * (gen.standard_normal(freq.size)
                                               + 1j * gen.standard_normal(freq.size))
        spec[0] = spec[0].real * math.sqrt(2.0)
        if size % 2 == 0:
            spec[-1] = spec[-1].real * math.sqrt(2.0)
        parts.append(np.fft.irfft(spec, size)[:length])
    return parts[0] if len(parts) == 1 else np.concatenate(parts)


def _analytic_variances(problem, chosen, noise, jac=None):
    """Diagonal of ``σ_w² (J_wᵀJ_w)⁻¹`` at the chosen fit, prewhitened by ``noise``."""
    if jac is not None:
        jw = noise.whiten(jac, problem.segments)
        jtj = jw.T @ jw
    else:
        _, jtj, _ = problem.normal_equations(chosen["p"], chosen["counts"],
                                             _joined_y(problem), noise)
    try:
        return np.diag(np.linalg.inv(jtj)) * noise.innovation_variance
    except np.linalg.LinAlgError:
        return np.full(jtj.shape[0], np.nan)


def noise_model_calibration(reading: np.ndarray, readings: Sequence[np.ndarray],
                            replicates: int) -> np.ndarray:
    """Factors on the bootstrap standard errors for the record's own noise-model error.

    The record's noise model is fitted (order by BIC) to residuals from which the fit has
    taken the noise that looks like a change of the parameters, and a quantised record's
    residuals hold a rounding that follows the signal: its error bars read the noise short
    by a different amount in each record (issue 24: 4th-order low-pass noise at 5x the
    mode with 0.01 rad encoder steps, reported/observed sd 0.7-0.9, misses of 3 s.e.).
    Each replicate's noise model is refitted the same way to its own residuals;
    ``reading / mean(readings)`` (at least 1) is the bootstrap's bias correction of that
    reading (Efron and Tibshirani 1993, §10.6), and the spread of ``readings`` is its
    sampling error: Satterthwaite degrees of freedom ``2/v``, pooled with the ``B - 1`` of
    the replicate variance, give the Student width that ±1.96 s.e. must have.

    Parameters
    ----------
    reading : ndarray, shape (p,)
        Analytic variances ``σ_w² (J_wᵀJ_w)⁻¹`` of the parameters under the record's own
        noise model [units²].
    readings : sequence of ndarray, shape (p,)
        The same under each replicate's refitted noise model [units²].
    replicates : int
        Converged bootstrap refits B [-].

    Returns
    -------
    ndarray, shape (p,)
        Factors >= 1 on the standard errors [-], replacing the ``t_{B-1}`` widening of
        :func:`replicate_covariance` (ones when fewer than 8 readings are usable).

    Examples
    --------
    Replicates that all read half the record's variance: the factor is √2 (and no Student
    widening beyond the replicates' own, as their readings do not scatter).

    >>> f = noise_model_calibration(np.array([1.0]), [np.array([0.5])] * 25, 25)
    >>> round(float(f[0]), 3)
    1.414
    """
    d = np.asarray(readings, float)
    d = d[np.all(np.isfinite(d) & (d > 0), axis=1)] if d.ndim == 2 else d[:0]
    if d.shape[0] < 8 or not np.all(np.isfinite(reading) & (reading > 0)):
        return np.ones(np.asarray(reading).size)
    mean = d.mean(axis=0)
    bias = np.maximum(reading / mean, 1.0)
    rel = d.var(axis=0, ddof=1) / mean**2 + 2.0 / max(replicates - 1, 1)
    nu = 2.0 / np.maximum(rel, 1e-12)
    widen_b = float(stats.t.ppf(0.975, replicates - 1) / stats.norm.ppf(0.975))
    widen = stats.t.ppf(0.975, nu) / stats.norm.ppf(0.975) / widen_b
    return np.sqrt(bias) * np.maximum(widen, 1.0)


def replicate_covariance(replicates: Sequence[np.ndarray]) -> np.ndarray:
    """Covariance of bootstrap replicates, widened for the number of replicates.

    A variance estimated from m replicates makes ``(estimate - truth)/se`` a Student t with
    m - 1 degrees of freedom, so the covariance is scaled by ``(t_{m-1,0.975}/1.96)²`` and the
    usual ±1.96 se interval has t's 95 % width (×1.053 on se at m = 25; 200 encoder decays
    gave c_mean coverage 0.92 without it, 0.93 with it).

    Parameters
    ----------
    replicates : sequence of ndarray, shape (p,)
        The refitted parameter vectors [their units].

    Returns
    -------
    ndarray, shape (p, p)
    """
    m = len(replicates)
    widen = float(stats.t.ppf(0.975, m - 1) / stats.norm.ppf(0.975))
    return np.atleast_2d(np.cov(np.array(replicates), rowvar=False)) * widen**2
