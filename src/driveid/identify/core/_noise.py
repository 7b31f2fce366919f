r"""Noise models of the whole-record fits: AR(p) residuals, prewhitening, HAC covariance.

A whole-record fit compares a model ``f(θ)`` with every sample ``y``. Sensor chains colour
the noise (filtered encoders, tachometers, anti-alias filters): with ``e = y - f(θ)`` an
AR(p) process ``A(q) e = w``, ``A(q) = 1 - a_1 q⁻¹ - … - a_p q⁻ᵖ`` and ``w`` white, the
prediction-error estimate minimises ``‖A(q)(y - f(θ))‖²`` (Ljung [1]_, §7.2-7.3: output error
with a noise model, the Box–Jenkins structure with ``C = 1``). It is the maximum-likelihood
estimate for Gaussian ``w`` conditional on the first ``p`` samples of each record, and its
covariance is ``σ_w² (J_wᵀ J_w)⁻¹`` with the prewhitened Jacobian ``J_w = A(q) J`` — also the
Cramér–Rao bound for that noise spectrum (Whittle's approximation, [1]_ §9.2).

The AR coefficients come from Burg's method [2]_ (stable by construction, good at the
near-unit-circle poles of low-pass and mains noise), several records pooled; the order by
the Bayesian information criterion ``N ln σ̂²_p + p ln N``. White noise is order 0: the fit
and its error bars are then exactly the unweighted ones (no loss where none is needed).

Where the structure itself is wrong, whitening cannot help: :func:`hac_covariance` gives the
Newey–West sandwich [3]_ ``(JᵀJ)⁻¹ S (JᵀJ)⁻¹``, ``S = Σ_l w_l Σ_t g_t g_{t-l}ᵀ``,
``g_t = J_t r_t``, Bartlett weights, which stays honest for any stationary residual.

Not in the thesis: de Marchi (1998) fits peaks (§2.2.5) and never models the noise.

References
----------
.. [1] L. Ljung, *System Identification: Theory for the User*, 2nd ed., Prentice Hall, 1999.
.. [2] J. P. Burg, "Maximum entropy spectral analysis", PhD thesis, Stanford, 1975; the
       recursion as in P. Stoica, R. Moses, *Spectral Analysis of Signals*, 2005, §3.9.3.
.. [3] W. K. Newey, K. D. West, "A simple, positive semi-definite, heteroskedasticity and
       autocorrelation consistent covariance matrix", Econometrica 55 (1987) 703-708,
       doi:10.2307/1913610.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.signal import lfilter

from driveid.errors import IdentificationError

__all__ = ["NoiseModel", "white_noise", "fit_noise_model", "hac_covariance", "segment_lengths",
           "spectral_lines", "fit_lines"]

#: Highest AR order tried [-]; band-limited noise needs ~10-40, mains hum 2-4 per line.
MAX_ORDER = 40
#: Samples per AR coefficient below which a higher order is not tried [-].
_SAMPLES_PER_COEFF = 20


def segment_lengths(segments: Sequence[int] | None, n: int) -> list[int]:
    """Return the record lengths of a stacked vector (one record when ``segments`` is None).

    Parameters
    ----------
    segments : sequence of int or None
        Samples of each record, in stacking order [-].
    n : int
        Total samples [-]; must equal the sum.

    Returns
    -------
    list of int
    """
    if segments is None:
        return [int(n)]
    lengths = [int(s) for s in segments]
    if sum(lengths) != n or min(lengths, default=0) < 0:
        raise IdentificationError(
            f"segment lengths {lengths} do not add up to the {n} stacked samples")
    return lengths


@dataclass(frozen=True)
class NoiseModel:
    """An AR(p) model of a fit's residuals: ``e_t = Σ a_j e_{t-j} + w_t``.

    Attributes
    ----------
    ar : tuple of float
        ``a_1 … a_p`` [-]; empty for white noise.
    innovation_variance : float
        Variance σ_w² of the white innovations ``w`` [unit²].
    variance : float
        Variance of the residuals themselves [unit²].
    n : int
        Residual samples the model was fitted to [-].
    bic : tuple of float
        Bayesian information criterion of orders 0, 1, … tried [-].
    method : str
        ``"burg"`` or ``"white"`` (given, not fitted).
    """

    ar: tuple[float, ...] = ()
    innovation_variance: float = math.nan
    variance: float = math.nan
    n: int = 0
    bic: tuple[float, ...] = field(default=(), repr=False)
    method: str = "burg"

    @property
    def order(self) -> int:
        """AR order p [-] (0 = white)."""
        return len(self.ar)

    @property
    def is_white(self) -> bool:
        """True for order 0."""
        return not self.ar

    @property
    def n_eff(self) -> float:
        """Effective number of independent samples for a mean [-].

        ``n γ₀ / S(0)`` with the long-run variance ``S(0) = σ_w² / (1 - Σ a_j)²``; for AR(1)
        ``n (1 - φ)/(1 + φ)``. Equals ``n`` for white noise.
        """
        if self.is_white or not self.innovation_variance > 0:
            return float(self.n)
        gain = (1.0 - sum(self.ar)) ** 2
        return float(self.n * self.variance * gain / self.innovation_variance)

    @property
    def variance_inflation(self) -> float:
        """Ratio ``n / n_eff`` [-]: how much a white-noise error bar on a mean is too small²."""
        n_eff = self.n_eff
        return float(self.n / n_eff) if n_eff > 0 else math.inf

    def whiten(self, x: np.ndarray, segments: Sequence[int] | None = None) -> np.ndarray:
        """Apply ``A(q)`` along axis 0, record by record, dropping each record's first p rows.

        Parameters
        ----------
        x : ndarray, shape (n,) or (n, k)
            Stacked residuals, model values or Jacobian columns [any unit].
        segments : sequence of int, optional
            Samples of each stacked record [-]; the filter never runs across records.

        Returns
        -------
        ndarray, shape (n - p·records,) or (n - p·records, k)
            The prewhitened rows (x itself for white noise).
        """
        x = np.asarray(x, float)
        if self.is_white:
            return x
        p = self.order
        b = np.concatenate([[1.0], -np.asarray(self.ar, float)])
        parts, start = [], 0
        for length in segment_lengths(segments, x.shape[0]):
            block = x[start:start + length]
            start += length
            if length > p:
                parts.append(lfilter(b, [1.0], block, axis=0)[p:])
        if not parts:
            return x[:0]
        return parts[0] if len(parts) == 1 else np.concatenate(parts)

    def psd(self, freq: np.ndarray, fs: float) -> np.ndarray:
        """One-sided power spectral density of the residual process.

        Parameters
        ----------
        freq : ndarray, shape (m,)
            Frequencies [Hz], 0..fs/2.
        fs : float
            Sample rate [Hz].

        Returns
        -------
        ndarray, shape (m,)
            ``2 σ_w² / (fs |A(e^{iω})|²)`` [unit²/Hz].
        """
        freq = np.asarray(freq, float)
        z = np.exp(-2j * np.pi * freq / fs)
        a = np.ones_like(z)
        for j, coeff in enumerate(self.ar, start=1):
            a = a - coeff * z**j
        return 2.0 * self.innovation_variance / (fs * np.abs(a) ** 2)

    def to_dict(self) -> dict[str, Any]:
        """Return the JSON form: kind, order, coefficients, standard deviations, n_eff."""
        return {
            "kind": "white" if self.is_white else f"AR({self.order})",
            "order": self.order,
            "ar": [float(a) for a in self.ar],
            "innovation_std": _sqrt(self.innovation_variance),
            "std": _sqrt(self.variance),
            "n": int(self.n),
            "n_eff": float(self.n_eff),
            "method": self.method,
        }


def _sqrt(v: float) -> float | None:
    return math.sqrt(v) if math.isfinite(v) and v >= 0 else None


def white_noise(residual: np.ndarray) -> NoiseModel:
    """Return the order-0 model of ``residual`` (its mean square as the variance).

    Parameters
    ----------
    residual : ndarray, shape (n,)
        Residuals [unit].

    Returns
    -------
    NoiseModel
        ``method="white"``.
    """
    r = np.asarray(residual, float)
    var = float(r @ r / r.size) if r.size else math.nan
    return NoiseModel((), var, var, int(r.size), (), "white")


def fit_noise_model(residual: np.ndarray, *, segments: Sequence[int] | None = None,
                    max_order: int | None = None, n_params: int = 0,
                    order: int | None = None) -> NoiseModel:
    """Fit an AR(p) model to residuals by Burg's method, the order by BIC.

    Parameters
    ----------
    residual : ndarray, shape (n,)
        Stacked residuals ``y - f(θ)`` of one or more records [unit].
    segments : sequence of int, optional
        Samples of each stacked record [-]; lags never cross records.
    max_order : int, optional
        Highest order tried [-]; default :data:`MAX_ORDER`, and never more than one
        coefficient per 20 samples.
    n_params : int
        Parameters of the fitted model [-]; the innovation variance is scaled by
        ``n/(n - n_params)`` (the residuals are that much smaller than the noise).
    order : int, optional
        Fit exactly this order [-] (no BIC choice; still capped by the record length).

    Returns
    -------
    NoiseModel
        Order 0 when BIC prefers white noise.

    Raises
    ------
    IdentificationError
        Fewer than 8 residuals, or non-finite ones.

    Examples
    --------
    >>> rng = np.random.default_rng(1)
    >>> e = lfilter([1.0], [1.0, -0.8], rng.normal(size=20000))
    >>> m = fit_noise_model(e)
    >>> m.order, round(m.ar[0], 1), round(m.n_eff / m.n, 1)
    (1, 0.8, 0.1)
    """
    r = np.asarray(residual, float)
    if r.size < 8 or not np.all(np.isfinite(r)):
        raise IdentificationError(
            f"a noise model needs at least 8 finite residuals; got {r.size} (non-finite: "
            f"{int(np.sum(~np.isfinite(r)))})")
    lengths = segment_lengths(segments, r.size)
    limit = MAX_ORDER if max_order is None else int(max_order)
    if order is not None:
        limit = int(order)
    limit = max(0, min(limit, min(lengths) // _SAMPLES_PER_COEFF, r.size // _SAMPLES_PER_COEFF))
    variance = float(r @ r / r.size)
    dof = max(r.size - n_params, 1)
    scale = r.size / dof
    if variance == 0.0:
        return NoiseModel((), 0.0, 0.0, int(r.size), (), "burg")
    forward, backward, starts = [], [], 0
    for length in lengths:
        forward.append(r[starts:starts + length].copy())
        backward.append(r[starts:starts + length].copy())
        starts += length
    n_total = float(r.size)
    power = variance
    a = np.zeros(0)
    best_a, best_power = a, power
    bic = [n_total * math.log(power)]
    for m in range(1, limit + 1):
        num = den = 0.0
        for f, b in zip(forward, backward, strict=True):
            ff, bb = f[m:], b[m - 1:-1]
            num += float(ff @ bb)
            den += float(ff @ ff + bb @ bb)
        if den <= 0.0:
            break
        k = 2.0 * num / den
        for f, b in zip(forward, backward, strict=True):
            ff, bb = f[m:].copy(), b[m - 1:-1].copy()
            f[m:] = ff - k * bb
            b[m:] = bb - k * ff
        a = np.concatenate([a - k * a[::-1], [k]])
        power *= max(1.0 - k * k, 1e-300)
        bic.append(n_total * math.log(power) + m * math.log(n_total))
        if (order is None and bic[-1] == min(bic)) or m == order:
            best_a, best_power = a.copy(), power
    return NoiseModel(tuple(float(v) for v in best_a), best_power * scale, variance * scale,
                      int(r.size), tuple(bic), "burg")


def hac_covariance(jac: np.ndarray, residual: np.ndarray, *,
                   segments: Sequence[int] | None = None, lags: int | None = None,
                   bread: np.ndarray | None = None) -> np.ndarray:
    """Newey–West (Bartlett) sandwich covariance of a least-squares fit.

    Parameters
    ----------
    jac : ndarray, shape (n, p)
        Jacobian of the model at the estimate [unit per parameter unit].
    residual : ndarray, shape (n,)
        Residuals at the estimate [unit].
    segments : sequence of int, optional
        Samples of each stacked record; products never cross records.
    lags : int, optional
        Bandwidth L [-]; default ``⌊4 (n/100)^{2/9}⌋`` (Newey and West 1994), at least the
        lag where the residual autocorrelation first falls below 0.1.
    bread : ndarray, shape (p, p), optional
        ``(JᵀJ)⁻¹`` when already known.

    Returns
    -------
    ndarray, shape (p, p)
        Covariance of the estimate [parameter units²]; nan in the rows and columns of
        parameters the Jacobian cannot tell apart (singular within 1e-12).
    """
    jac = np.asarray(jac, float)
    r = np.asarray(residual, float)
    n = r.size
    unknown = np.zeros(jac.shape[1], bool)
    if bread is None:
        # by the SVD: a singular Jacobian (a parameter the record does not move) leaves the
        # parameters in its null direction unknown (nan) instead of raising; the sandwich
        # would give them a variance of 0 (callers warn that they are not identifiable)
        _, sv, vt = np.linalg.svd(jac, full_matrices=False)
        floor = max(1e-12 * float(sv[0]) if sv.size else 0.0, 1e-300)
        null = sv <= floor
        unknown = np.any(np.abs(vt[null]) > 1e-8, axis=0)
        bread = (vt[~null].T / sv[~null] ** 2) @ vt[~null]
    g = jac * r[:, None]
    lengths = segment_lengths(segments, n)
    if lags is None:
        lags = int(4.0 * (n / 100.0) ** (2.0 / 9.0))
        lags = max(lags, _decorrelation_lag(r, lengths))
    lags = max(0, min(int(lags), max(lengths) - 1))
    meat = g.T @ g
    for ell in range(1, lags + 1):
        weight = 1.0 - ell / (lags + 1.0)
        gamma = np.zeros_like(meat)
        start = 0
        for length in lengths:
            if length > ell:
                block = g[start:start + length]
                gamma += block[ell:].T @ block[:-ell]
            start += length
        meat += weight * (gamma + gamma.T)
    cov = bread @ meat @ bread
    cov[unknown, :] = np.nan
    cov[:, unknown] = np.nan
    return cov


def _decorrelation_lag(r: np.ndarray, lengths: list[int], limit: int = 2000) -> int:
    """First lag where the pooled autocorrelation drops below 0.1 (at most ``limit``)."""
    denom = float(r @ r)
    if denom == 0.0:
        return 0
    top = min(limit, max(lengths) - 1)
    # FFT autocorrelation per record, pooled
    acf = np.zeros(top + 1)
    start = 0
    for length in lengths:
        block = r[start:start + length]
        start += length
        size = 1 << int(math.ceil(math.log2(2 * length)))
        spec = np.fft.rfft(block, size)
        m = min(top + 1, length)  # a shorter record has no products at longer lags
        acf[:m] += np.fft.irfft(spec * np.conj(spec), size)[:m]
    acf /= denom
    below = np.nonzero(acf < 0.1)[0]
    return int(below[0]) if below.size else top


#: Neighbouring Fourier ordinates on each side whose median is a line's background [-].
LINE_NEIGHBOURS = 10


def spectral_lines(y: np.ndarray, *, max_lines: int = 3, level: float = 1e-3) -> list[float]:
    """Frequencies of sinusoidal lines (mains hum and its harmonics) in a noise record.

    An AR model of noise with a line of an integer period (50 Hz at 500 Hz: 10 samples)
    takes it as a seasonal near-unit root, which also puts a pole at zero frequency: the
    long-run variance ``S(0)`` it gives is several times too large (a friction-map plateau
    under the issue-24 mains class: error bars 1.9 times the scatter). A line is found as
    the periodogram ordinate of the residual (after the mean and the lines found so far)
    that stands out of its neighbours: against the median of the :data:`LINE_NEIGHBOURS`
    ordinates on each side (skipping the adjacent one, where a line leaks), divided by
    ln 2 (the median of an exponential), an ordinate of a smooth spectrum exceeds ``x``
    with probability ``e^{-x}``; the largest of ``m`` exceeds ``ln(m/level)`` with
    probability ``level``, and twice that threshold covers the noise of a 20-ordinate
    median (on 300 plateaus of 750 samples: no false line under white, AR(1) 0.9 and
    low-pass noise, 4 under AR(1) 0.97, none under 1/f-like; the mains line in all 300).

    Parameters
    ----------
    y : ndarray, shape (n,)
        The record [any unit], uniformly sampled.
    max_lines : int
        Lines to look for at most [-].
    level : float
        Probability of a false line on a smooth spectrum, before the factor 2 [-].

    Returns
    -------
    list of float
        Line frequencies [cycles per sample], at Fourier frequencies ``k/n``, strongest
        first.

    Examples
    --------
    >>> t = np.arange(750)
    >>> y = np.sin(2 * np.pi * t / 10) + np.random.default_rng(0).normal(0, 0.5, 750)
    >>> spectral_lines(y)
    [0.1]
    """
    return fit_lines(y, max_lines=max_lines, level=level)[0]


def fit_lines(y: np.ndarray, *, max_lines: int = 3,
              level: float = 1e-3) -> tuple[list[float], np.ndarray]:
    """Find the lines of :func:`spectral_lines` and take them and the mean out of ``y``.

    Parameters
    ----------
    y : ndarray, shape (n,)
        The record [any unit], uniformly sampled.
    max_lines, level
        As in :func:`spectral_lines`.

    Returns
    -------
    (list of float, ndarray)
        The line frequencies [cycles per sample] and the residual of ``y`` about its mean
        and those lines (least squares) [unit]; the number of fitted coefficients is
        ``1 + 2·len(lines)``.
    """
    y = np.asarray(y, float)
    n = y.size
    t = np.arange(n)
    cols = [np.ones(n)]
    found: list[float] = []
    r = y - np.mean(y)
    m = (n - 1) // 2
    if m < 2 * LINE_NEIGHBOURS + 4:
        return found, r
    threshold = 2.0 * math.log(m / level)
    for _ in range(max_lines):
        spec = np.abs(np.fft.rfft(r)[1:m + 1]) ** 2
        ratio = np.zeros(m)
        for j in range(3, m - 3):
            around = np.concatenate([spec[max(0, j - LINE_NEIGHBOURS - 1):j - 1],
                                     spec[j + 2:j + LINE_NEIGHBOURS + 2]])
            background = np.median(around) / math.log(2.0)
            ratio[j] = spec[j] / background if background > 0 else 0.0
        j = int(np.argmax(ratio))
        if ratio[j] < threshold:
            break
        freq = (j + 1) / n
        found.append(freq)
        cols += [np.cos(2 * math.pi * freq * t), np.sin(2 * math.pi * freq * t)]
        x = np.column_stack(cols)
        r = y - x @ np.linalg.lstsq(x, y, rcond=None)[0]
    return found, r
