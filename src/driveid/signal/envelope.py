"""Analytic-signal helpers: padded Hilbert transform, noise level, smooth derivatives.

These are the shared building blocks of the instantaneous-parameter methods of
de Marchi (1998) §2.2.8-§2.2.9 (:mod:`driveid.identify.free_decay.hilbert`) and of the Morlet
wavelet method (:mod:`driveid.identify.free_decay.wavelet`).

End effects of the discrete Hilbert transform decay only like ``1/t`` away from a
truncated end, so :func:`analytic_signal` extends the record at both ends with a damped
sinusoid fitted to the first and last periods, tapered to zero with a half-cosine, before
transforming (the padding is dropped again afterwards).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.fft import next_fast_len
from scipy.ndimage import uniform_filter1d
from scipy.optimize import least_squares
from scipy.signal import hilbert

__all__ = [
    "analytic_signal",
    "dominant_frequency",
    "noise_std",
    "smooth_derivatives",
    "count_crossings",
    "longest_run",
    "weighted_slope",
    "cycle_phasor",
    "block_decimation",
    "block_decimate",
    "block_mean_gain",
    "MAX_SAMPLES_PER_PERIOD",
]

#: Above this many samples per period the instantaneous methods decimate the record [-].
MAX_SAMPLES_PER_PERIOD = 1000

#: Samples per period they decimate to, at least [-].
TARGET_SAMPLES_PER_PERIOD = 500


def noise_std(x: np.ndarray) -> float:
    """Estimate the standard deviation of white measurement noise on an oversampled signal.

    Parameters
    ----------
    x : ndarray, shape (n,)
        Signal [any unit]; it should be sampled at >= 20 samples per period so that the
        second difference of the clean signal is small against that of the noise.

    Returns
    -------
    float
        Noise standard deviation [unit of x], from the median absolute second difference
        (white noise gives ``var(d2) = 6 var(noise)``).

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> x = np.sin(np.linspace(0, 20, 20000)) + 0.01 * rng.standard_normal(20000)
    >>> bool(abs(noise_std(x) - 0.01) < 1e-3)
    True
    """
    d2 = np.diff(np.asarray(x, dtype=float), 2)
    d2 -= np.median(d2)  # in place: one full-length temporary, not three
    np.abs(d2, out=d2)
    return float(1.4826 * np.median(d2) / np.sqrt(6.0))


def dominant_frequency(x: np.ndarray, fs: float) -> float:
    """Return the angular frequency of the largest spectral peak [rad/s].

    Parameters
    ----------
    x : ndarray, shape (n,)
        Signal [any unit].
    fs : float
        Sampling rate [Hz].

    Returns
    -------
    float
        Peak frequency [rad/s] (Hann window, 4x zero padding, parabolic interpolation of the
        log magnitude); 0.0 for a constant signal.

    Examples
    --------
    >>> t = np.arange(2000) / 100.0
    >>> round(dominant_frequency(np.cos(2 * np.pi * 3.0 * t), 100.0) / (2 * np.pi), 2)
    3.0
    """
    x = np.asarray(x, dtype=float)
    xw = x - x.mean()
    xw *= np.hanning(x.size)
    n = 4 * x.size
    # the 4x zero-padded spectrum is evaluated only near the peak of the unpadded one
    # (a Hann main lobe is +-2 bins wide): a 4x padded FFT of 1e7 samples needs ~1 GB
    coarse = np.abs(np.fft.rfft(xw))
    if coarse.max() == 0.0:
        return 0.0
    kc = int(np.argmax(coarse[1:])) + 1
    del coarse
    bins = np.arange(max(4 * kc - 6, 1), min(4 * kc + 7, n // 2 + 1))
    spec = np.abs(_dft_at(xw, bins, n))
    j = int(np.argmax(spec))
    k = int(bins[j])
    if 1 <= j < spec.size - 1:
        lm, l0, lp = np.log(spec[j - 1 : j + 2] + 1e-300)
        denom = lm - 2 * l0 + lp
        shift = 0.5 * (lm - lp) / denom if denom < 0 else 0.0
    else:
        shift = 0.0
    return float(2 * np.pi * (k + shift) * fs / n)


def _dft_at(x: np.ndarray, bins: np.ndarray, n: int, chunk: int = 1 << 14) -> np.ndarray:
    """DFT of ``x`` zero-padded to ``n`` points at the integer ``bins``, in chunks.

    Equals ``np.fft.rfft(x, n)[bins]`` with O(chunk * len(bins)) memory; the phase
    ``bins * i mod n`` is formed in integers, so it is exact for any record length.
    """
    b = bins.astype(np.int64)
    chunk = max(min(chunk, x.size // 64), min(256, x.size))  # kernel small against x
    # exp(-2 pi j b (s + i) / n) = exp(-2 pi j b s / n) exp(-2 pi j b i / n): the second
    # factor is the same for every chunk start s; real and imaginary parts separately so
    # that the products are real BLAS matrix-vector products
    angle = (2 * np.pi / n) * ((b[:, None] * np.arange(chunk)) % n)
    k_re, k_im = np.cos(angle), -np.sin(angle)
    del angle
    out = np.zeros(bins.size, dtype=complex)
    for start in range(0, x.size, chunk):
        seg = x[start : start + chunk]
        part = k_re[:, : seg.size] @ seg + 1j * (k_im[:, : seg.size] @ seg)
        out += np.exp(-2j * np.pi * ((b * start) % n) / n) * part
    return out


def count_crossings(x: np.ndarray, hysteresis: float) -> int:
    """Count sign changes of ``x`` that cross the band ``[-hysteresis, hysteresis]``.

    Parameters
    ----------
    x : ndarray, shape (n,)
        Zero-mean signal [any unit].
    hysteresis : float
        Half-width of the dead band [unit of x]; noise inside it is not counted.

    Returns
    -------
    int
        Number of crossings from above ``+hysteresis`` to below ``-hysteresis`` or back.

    Examples
    --------
    >>> count_crossings(np.sin(np.linspace(0, 4 * np.pi, 400)), 0.1)
    3
    """
    state = np.zeros(np.shape(x), dtype=np.int8)  # 1 byte a sample, not 8
    state[x > hysteresis] = 1
    state[x < -hysteresis] = -1
    state = state[state != 0]
    return int(np.count_nonzero(np.diff(state)))


def _fit_damped_sinusoid(
    t: np.ndarray, x: np.ndarray, omega: float, sigma: float
) -> np.ndarray:
    """Least-squares fit of ``exp(-s t)(a cos w t + b sin w t) + c``; return the parameters."""

    def model(p: np.ndarray) -> np.ndarray:
        s, w, a, b, c = p
        return np.exp(-s * t) * (a * np.cos(w * t) + b * np.sin(w * t)) + c

    basis = np.column_stack(
        [np.exp(-sigma * t) * np.cos(omega * t), np.exp(-sigma * t) * np.sin(omega * t),
         np.ones_like(t)]
    )
    ab = np.linalg.lstsq(basis, x, rcond=None)[0]
    p0 = np.array([max(sigma, 0.0), omega, ab[0], ab[1], ab[2]])
    lower = [0.0, 0.5 * omega, -np.inf, -np.inf, -np.inf]
    upper = [0.5 * omega, 1.5 * omega, np.inf, np.inf, np.inf]
    p0[0] = min(p0[0], 0.49 * omega)
    fit = least_squares(lambda p: model(p) - x, p0, bounds=(lower, upper), x_scale="jac")
    return fit.x


def analytic_signal(
    x: np.ndarray,
    fs: float,
    *,
    omega: float | None = None,
    pad_periods: float = 6.0,
    fit_periods: float = 6.0,
) -> np.ndarray:
    """Analytic signal ``x + j H{x}`` (2.195), with end effects reduced by model padding.

    Parameters
    ----------
    x : ndarray, shape (n,)
        Real signal [any unit], oscillating at about ``omega``.
    fs : float
        Sampling rate [Hz].
    omega : float, optional
        Angular frequency of the oscillation [rad/s]; found with
        :func:`dominant_frequency` when omitted.
    pad_periods : float
        Length of the tapered padding at each end [periods]; 0 disables padding.
    fit_periods : float
        Length of the end segments to which the damped sinusoids are fitted [periods].

    Returns
    -------
    ndarray of complex, shape (n,)
        The analytic signal over the original samples.

    Notes
    -----
    Each end is extended by a damped sinusoid fitted by least squares to the outermost
    ``fit_periods`` periods, multiplied by a half-cosine taper that falls to zero at the outer
    end; :func:`scipy.signal.hilbert` (the FFT form of (2.202)-(2.203)) is then applied.

    Examples
    --------
    >>> t = np.arange(1000) / 100.0
    >>> z = analytic_signal(np.exp(-0.1 * t) * np.cos(2 * np.pi * t), 100.0)
    >>> bool(np.max(np.abs(np.abs(z[200:800]) / np.exp(-0.1 * t[200:800]) - 1)) < 1e-3)
    True
    """
    x = np.asarray(x, dtype=float)
    if omega is None:
        omega = dominant_frequency(x, fs)
    npad = int(round(pad_periods * 2 * np.pi / omega * fs)) if omega > 0 else 0
    nfit = min(npad, int(round(fit_periods * 2 * np.pi / omega * fs)) if omega > 0 else 0,
               x.size // 2)
    if npad == 0 or nfit < 8:
        return hilbert(x)
    dt = 1.0 / fs
    tf = np.arange(nfit) * dt
    taper = 0.5 * (1 + np.cos(np.pi * np.arange(1, npad + 1) / npad))
    # right end: fit forward in time from the start of the last segment
    pr = _fit_damped_sinusoid(tf, x[-nfit:], omega, 0.0)
    s, w, a, b, c = pr
    tr = (nfit - 1 + np.arange(1, npad + 1)) * dt
    right = (np.exp(-s * tr) * (a * np.cos(w * tr) + b * np.sin(w * tr)) + c) * taper
    # left end: time-reverse the first segment so the fit runs away from the record
    pl = _fit_damped_sinusoid(tf, x[:nfit][::-1], omega, 0.0)
    s, w, a, b, c = pl
    left = ((np.exp(-s * tr) * (a * np.cos(w * tr) + b * np.sin(w * tr)) + c) * taper)[::-1]
    padded = np.concatenate([left, x, right])
    # the taper ends at zero, so extra zeros up to a fast FFT length change nothing
    z = hilbert(padded, next_fast_len(padded.size))
    return z[npad : npad + x.size]


def smooth_derivatives(
    y: np.ndarray, fs: float, window: int, *, polyorder: int = 3
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Savitzky-Golay smoothed value, first and second derivative of a sampled signal.

    Parameters
    ----------
    y : ndarray, shape (n,)
        Signal [unit].
    fs : float
        Sampling rate [Hz].
    window : int
        Window length [samples]; made odd and at least ``polyorder + 2``.
    polyorder : int
        Degree of the local polynomial [-].

    Returns
    -------
    value, first, second : ndarray, shape (n,)
        Smoothed ``y`` [unit], ``dy/dt`` [unit/s] and ``d2y/dt2`` [unit/s^2].

    Notes
    -----
    The same filter as ``scipy.signal.savgol_filter(..., mode="interp")``, built to stay
    sound and fast at any window length (a one-period window at a high sampling rate holds
    tens of thousands of samples): the coefficients come from a least-squares fit on the
    abscissa scaled to [-1, 1] (scipy's unscaled Vandermonde matrix loses all digits
    beyond ~17 000 samples), the interior is an FFT (overlap-add) convolution, O(n log w)
    instead of O(n w), and each end is the polynomial fitted to the first or last window.

    Examples
    --------
    >>> t = np.arange(100) / 10.0
    >>> _, d1, d2 = smooth_derivatives(t**2, 10.0, 11)
    >>> bool(np.allclose(d1, 2 * t) and np.allclose(d2, 2.0))
    True
    """
    y = np.asarray(y, dtype=float)
    window = max(int(window) | 1, polyorder + 2 | 1)
    window = min(window, (y.size - 1) | 1 if y.size % 2 == 0 else y.size)
    dt = 1.0 / fs
    return tuple(_savgol(y, window, polyorder, deriv, dt) for deriv in (0, 1, 2))


def _savgol(y: np.ndarray, window: int, polyorder: int, deriv: int, dt: float) -> np.ndarray:
    """Savitzky-Golay filter (mode "interp") with scaled-abscissa coefficients, FFT interior."""
    from scipy.signal import oaconvolve

    half = window // 2
    scale = max(half, 1)
    z = np.arange(-half, half + 1) / scale  # in [-1, 1]: a well-conditioned Vandermonde
    order = min(polyorder, window - 1)
    vander = np.vander(z, order + 1, increasing=True)
    pinv = np.linalg.pinv(vander)  # row k: coefficient of z^k from the window's samples
    if deriv > order:
        return np.zeros_like(y)
    # d^k/dx^k at the centre (z = 0) is k! c_k / (scale dt)^k
    coeffs = pinv[deriv] * math.factorial(deriv) / (scale * dt) ** deriv
    out = np.empty_like(y)
    if y.size >= window:
        # correlation with the coefficients = convolution with them reversed
        out[half:y.size - half] = oaconvolve(y, coeffs[::-1], mode="valid")
        for edge, rows in ((y[:window], slice(0, half)), (y[-window:], slice(y.size - half,
                                                                               y.size))):
            poly = pinv @ edge  # the polynomial fitted to the end window, in z
            at = z[:half] if rows.start == 0 else z[half + 1:]
            out[rows] = _poly_derivative(poly, at, deriv) / (scale * dt) ** deriv
    else:  # pragma: no cover - the window is clipped to the record above
        raise ValueError("window longer than the signal")
    return out


def _poly_derivative(coef: np.ndarray, z: np.ndarray, deriv: int) -> np.ndarray:
    """Value of the ``deriv``-th derivative of sum(coef[k] z^k) at z."""
    d = np.polynomial.polynomial.polyder(coef, deriv) if deriv else coef
    return np.polynomial.polynomial.polyval(z, d)


def longest_run(mask: np.ndarray) -> tuple[int, int]:
    """Return the half-open index range of the longest run of True in ``mask``.

    Parameters
    ----------
    mask : ndarray of bool, shape (n,)
        Samples that pass all validity tests.

    Returns
    -------
    tuple of int
        ``(start, stop)``; ``(0, 0)`` when no sample is True.

    Examples
    --------
    >>> longest_run(np.array([True, False, True, True, False]))
    (2, 4)
    """
    padded = np.concatenate([[False], np.asarray(mask, dtype=bool), [False]])
    edges = np.flatnonzero(np.diff(padded.astype(int)))
    if edges.size == 0:
        return 0, 0
    starts, stops = edges[::2], edges[1::2]
    k = int(np.argmax(stops - starts))
    return int(starts[k]), int(stops[k])


def weighted_slope(
    t: np.ndarray, y: np.ndarray, weights: np.ndarray, n_eff: float
) -> tuple[float, float]:
    """Slope of a weighted straight-line fit and its standard error.

    Parameters
    ----------
    t : ndarray, shape (n,)
        Abscissa, e.g. time [s].
    y : ndarray, shape (n,)
        Ordinate [unit].
    weights : ndarray, shape (n,)
        Relative weights, inverse variances up to a constant [-].
    n_eff : float
        Number of independent samples among the ``n`` (correlated) ones [-]; the standard
        error is inflated by ``sqrt(n / n_eff)``.

    Returns
    -------
    slope, stderr : float
        Slope [unit/(unit of t)] and its one-sigma standard error.

    Examples
    --------
    >>> t = np.arange(10.0)
    >>> round(weighted_slope(t, 3 * t + 1, np.ones(10), 10)[0], 12)
    3.0
    """
    sw = np.sqrt(weights)
    tc = t - np.average(t, weights=weights)
    a = np.column_stack([np.ones_like(tc), tc]) * sw[:, None]
    coef, *_ = np.linalg.lstsq(a, y * sw, rcond=None)
    res = y * sw - a @ coef
    s2 = float(res @ res) / max(n_eff - 2.0, 1.0)
    cov = s2 * np.linalg.inv(a.T @ a)
    return float(coef[1]), float(np.sqrt(cov[1, 1]))


def cycle_phasor(z: np.ndarray, fs: float, omega: float) -> np.ndarray:
    r"""Complex envelope: the analytic signal demodulated at ``omega``, averaged over a period.

    Parameters
    ----------
    z : ndarray of complex, shape (n,)
        Analytic signal :math:`A e^{j\phi}` [unit of x], e.g. from :func:`analytic_signal`.
    fs : float
        Sampling rate [Hz].
    omega : float
        Demodulation angular frequency [rad/s], > 0; the averaging window is one period
        ``2 pi / omega`` rounded to whole samples.

    Returns
    -------
    ndarray of complex, shape (n,)
        :math:`Y(t) = \langle A e^{j(\phi - \omega t)}\rangle_T` with t counted from the
        first sample; ``|Y|`` is the cycle-averaged instantaneous amplitude [unit of x]. The
        first and last half periods are biased by the window edge.

    Notes
    -----
    Averaging the phasor (not ``A`` or ``ln A``) keeps the average linear in the signal: a
    periodic component of period ``2 pi / omega`` contributes exactly its fundamental
    Fourier coefficient, whatever its shape, so an amplitude that alternates from half cycle
    to half cycle (asymmetric friction) averages out exactly rather than to first order.

    Examples
    --------
    >>> t = np.arange(4000) / 100.0
    >>> y = cycle_phasor(analytic_signal(np.cos(2 * np.pi * t + 0.3), 100.0), 100.0, 2 * np.pi)
    >>> bool(np.allclose(y[500:3500], np.exp(0.3j), atol=1e-3))
    True
    """
    z = np.asarray(z, dtype=complex)
    n = max(int(round(2 * np.pi / omega * fs)), 1)
    y = z * np.exp(-1j * omega * np.arange(z.size) / fs)
    return (uniform_filter1d(y.real, n, mode="nearest")
            + 1j * uniform_filter1d(y.imag, n, mode="nearest"))


def block_decimation(fs: float, omega: float, *,
                     max_samples_per_period: int = MAX_SAMPLES_PER_PERIOD,
                     target_samples_per_period: int = TARGET_SAMPLES_PER_PERIOD) -> int:
    """Decimation factor ``q`` for a record oscillating at ``omega``: 1 unless oversampled.

    Parameters
    ----------
    fs : float
        Sampling rate [Hz].
    omega : float
        Highest angular frequency of interest [rad/s].
    max_samples_per_period : int
        Records with at most this many samples per period are not decimated [-].
    target_samples_per_period : int
        Least samples per period after decimation [-].

    Returns
    -------
    int
        ``q >= 1``; ``fs / q`` keeps at least ``target_samples_per_period`` per period.

    Examples
    --------
    >>> block_decimation(1e5, 2 * np.pi * 5.0)
    40
    >>> block_decimation(1e3, 2 * np.pi * 2.0)
    1
    """
    per_period = 2 * math.pi * fs / omega if omega > 0 else 0.0
    if per_period <= max_samples_per_period:
        return 1
    return max(int(per_period // target_samples_per_period), 1)


def block_decimate(y: np.ndarray, q: int) -> np.ndarray:
    """Means of consecutive blocks of ``q`` samples (boxcar anti-alias filter, then 1 in q).

    Parameters
    ----------
    y : ndarray, shape (n,)
        Uniformly sampled signal [any unit].
    q : int
        Block length [samples], >= 1; the last ``n mod q`` samples are dropped.

    Returns
    -------
    ndarray, shape (n // q,)
        Block means; for the time axis they are the block centres.

    Notes
    -----
    The boxcar is the anti-alias filter: it passes a component at ``omega`` with the gain
    :func:`block_mean_gain` (``1 - 7e-6`` at 500 samples per period after decimation) and
    no phase error about the block centre; white noise leaves with variance ``1/q``, as
    through an ideal low-pass at the new Nyquist frequency. Its first sidelobe is -13 dB,
    so a component near the new Nyquist frequency would alias: the instantaneous methods
    decimate only to >= 500 samples per period of the mode, far below that. The reduction
    runs over a reshaped view: no full-length temporary.

    Examples
    --------
    >>> block_decimate(np.arange(7.0), 3)
    array([1., 4.])
    """
    q = int(q)
    m = y.size // q
    return np.asarray(y[: m * q], dtype=float).reshape(m, q).mean(axis=1)


def block_mean_gain(omega: np.ndarray | float, q: int, fs: float) -> np.ndarray | float:
    """Amplitude gain of the ``q``-sample block mean at ``omega`` (Dirichlet kernel).

    Parameters
    ----------
    omega : float or ndarray
        Angular frequency [rad/s].
    q : int
        Block length [samples].
    fs : float
        Sampling rate before decimation [Hz].

    Returns
    -------
    float or ndarray
        ``|sin(q omega / 2 fs) / (q sin(omega / 2 fs))|`` [-]; 1 for ``q = 1``.

    Examples
    --------
    >>> round(float(block_mean_gain(2 * np.pi, 10, 1000.0)), 6)
    0.999837
    """
    h = np.asarray(omega, dtype=float) / (2.0 * fs)
    with np.errstate(divide="ignore", invalid="ignore"):
        gain = np.where(h == 0, 1.0, np.abs(np.sin(q * h) / (q * np.sin(h))))
    return float(gain) if np.ndim(gain) == 0 else gain
