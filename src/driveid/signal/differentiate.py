"""Zero-phase low-pass filtering and numerical differentiation of sampled positions.

These are the signal steps of the inverse-dynamic-model (IDIM) recipe of the EMPS
benchmark (Janot, Gautier & Brunot 2019, §3): a Butterworth filter run forwards and
backwards (``filtfilt``), then central differences for velocity and acceleration.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import signal as sps

from driveid.errors import ParameterError, RecordError

__all__ = ["zero_phase_lowpass", "central_difference", "differentiate", "position_noise_std",
           "savgol_window"]


def zero_phase_lowpass(
    y: np.ndarray, fs: float, cutoff_hz: float, *, order: int = 4
) -> np.ndarray:
    """Filter ``y`` with a zero-phase Butterworth low-pass (``filtfilt``).

    Parameters
    ----------
    y : array_like, shape (n,)
        Sampled signal [any unit].
    fs : float
        Sampling frequency [Hz]; > 0.
    cutoff_hz : float
        Cut-off frequency of the one-way filter [Hz]; 0 < cutoff_hz < fs/2.
    order : int
        Order of the one-way Butterworth filter [-]; the zero-phase response has twice
        the attenuation slope.

    Returns
    -------
    ndarray, shape (n,)
        Filtered signal [unit of ``y``].

    Raises
    ------
    ParameterError
        If the cut-off is not inside (0, fs/2) or the order is not a positive integer.
    RecordError
        If ``y`` is too short for ``filtfilt``'s edge padding.

    Examples
    --------
    >>> import numpy as np
    >>> y = zero_phase_lowpass(np.ones(100), 1000.0, 100.0)
    >>> bool(np.allclose(y, 1.0))
    True
    """
    fs = float(fs)
    cutoff_hz = float(cutoff_hz)
    if not fs > 0:
        raise ParameterError(f"sampling frequency fs must be > 0 Hz; got {fs}")
    if not 0 < cutoff_hz < fs / 2:
        raise ParameterError(
            f"cutoff_hz must lie in (0, fs/2) = (0, {fs / 2:g}) Hz; lower it; got {cutoff_hz}"
        )
    if int(order) != order or order < 1:
        raise ParameterError(f"filter order must be a positive integer; got {order}")
    y = np.asarray(y, dtype=float)
    b, a = sps.butter(int(order), cutoff_hz / (fs / 2))
    padlen = 3 * max(len(a), len(b))
    if y.size <= padlen:
        raise RecordError(
            f"zero-phase filtering needs more than {padlen} samples; record a longer "
            f"signal; got {y.size}"
        )
    return sps.filtfilt(b, a, y)


def central_difference(y: np.ndarray, dt: float) -> np.ndarray:
    """Differentiate ``y`` by central differences, one-sided at the two ends.

    Parameters
    ----------
    y : array_like, shape (n,)
        Uniformly sampled signal [unit]; n >= 3.
    dt : float
        Sampling interval [s]; > 0.

    Returns
    -------
    ndarray, shape (n,)
        Derivative [unit/s]; second-order accurate inside, first-order at the ends (drop
        the edges, as the IDIM recipe does).

    Raises
    ------
    ParameterError
        If ``dt`` is not positive.
    RecordError
        If fewer than 3 samples are given.

    Examples
    --------
    >>> import numpy as np
    >>> central_difference(np.array([0.0, 1.0, 4.0, 9.0]), 1.0)[1:3].tolist()
    [2.0, 4.0]
    """
    dt = float(dt)
    if not dt > 0:
        raise ParameterError(f"sampling interval dt must be > 0 s; got {dt}")
    y = np.asarray(y, dtype=float)
    if y.size < 3:
        raise RecordError(f"central differences need at least 3 samples; got {y.size}")
    return np.gradient(y, dt)


def differentiate(
    x: np.ndarray, fs: float, *, cutoff_hz: float | None = None, order: int = 4
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Return filtered position, velocity and acceleration of a sampled position.

    Parameters
    ----------
    x : array_like, shape (n,)
        Position [m or rad].
    fs : float
        Sampling frequency [Hz].
    cutoff_hz : float or None
        Zero-phase Butterworth cut-off [Hz]; ``None`` differentiates unfiltered data.
    order : int
        One-way Butterworth order [-].

    Returns
    -------
    tuple of ndarray, each shape (n,)
        ``(x_filtered, v, a)`` in [m, m/s, m/s²] or [rad, rad/s, rad/s²].

    Examples
    --------
    >>> import numpy as np
    >>> t = np.arange(2000) / 1000.0
    >>> xf, v, a = differentiate(0.5 * t**2, 1000.0, cutoff_hz=100.0)
    >>> bool(np.allclose(a[100:-100], 1.0, atol=1e-6))
    True
    """
    xf = np.asarray(x, dtype=float)
    if cutoff_hz is not None:
        xf = zero_phase_lowpass(xf, fs, cutoff_hz, order=order)
    dt = 1.0 / float(fs)
    v = central_difference(xf, dt)
    a = central_difference(v, dt)
    return xf, v, a


def position_noise_std(x: np.ndarray) -> float:
    """Return the standard deviation of the noise on a sampled position [unit of ``x``].

    The third difference of a smooth signal sampled finely is almost nothing, that of white
    noise has variance 20 σ²: σ is taken from a robust (median absolute deviation) spread of
    ``Δ³x``. An encoder whose steps are mostly zero differences gives a spread of 0 there:
    for samples on one grid the rounding's own ``q/√12`` (q the smallest non-zero step) is
    the floor.

    Parameters
    ----------
    x : array_like, shape (n,)
        Position samples [m or rad], n >= 8.

    Returns
    -------
    float
        σ [m or rad]; 0 for an exactly smooth (cubic or lower) signal.

    Examples
    --------
    >>> import numpy as np
    >>> gen = np.random.default_rng(0)
    >>> x = np.sin(np.arange(20000) / 2000.0) + gen.normal(0, 1e-3, 20000)
    >>> round(position_noise_std(x), 5)
    0.001
    """
    x = np.asarray(x, dtype=float)
    if x.size < 8:
        raise RecordError(f"a noise estimate needs at least 8 samples; got {x.size}")
    d3 = np.diff(x, 3)
    spread = 1.4826 * float(np.median(np.abs(d3 - np.median(d3)))) / math.sqrt(20.0)
    steps = np.abs(np.diff(x))
    steps = steps[steps > 1e-12 * max(float(np.max(np.abs(x))), 1e-300)]
    floor = 0.0
    if steps.size:
        q = float(np.min(steps))
        levels = (x - x[0]) / q
        if float(np.max(np.abs(levels - np.round(levels)))) < 1e-6:  # an encoder's grid
            floor = q / math.sqrt(12.0)
    return max(spread, floor)


def savgol_window(x: np.ndarray, dt: float, *, polyorder: int = 5, target: float = 0.05,
                  shortest: float | None = None) -> int:
    """Shortest Savitzky–Golay window whose acceleration noise is ``target`` of the signal's.

    A least-squares regression on a noisy acceleration is biased towards zero inertia by
    the ratio of noise to total variance of the regressor (errors in variables): at
    ``target`` = 0.05 of the rms that bias is 0.25 %. Longer windows lower the noise (as
    ``W^{-5/2}`` for the second derivative) and raise the smoothing bias (``(ω W)^4`` on a
    ringing at ω), so the shortest window that meets the target is taken. The noise std comes
    from :func:`position_noise_std`, its gain from the filter's coefficients.

    Parameters
    ----------
    x : array_like, shape (n,)
        Position [m or rad] on a uniform clock.
    dt : float
        Sampling interval [s].
    polyorder : int
        Polynomial order of the filter [-].
    target : float
        Acceleration noise rms over the acceleration signal rms [-].
    shortest : float, optional
        Shortest window to consider [s] (default: polyorder + 2 samples).

    Returns
    -------
    int
        Odd window length [samples], at most a quarter of the record (then the target may be
        missed: the record is too noisy for its derivatives).

    Examples
    --------
    >>> import numpy as np
    >>> t = np.arange(20000) / 2000.0
    >>> gen = np.random.default_rng(1)
    >>> savgol_window(np.sin(5 * t), 1 / 2000.0) < savgol_window(
    ...     np.sin(5 * t) + gen.normal(0, 1e-4, t.size), 1 / 2000.0)
    True
    """
    x = np.asarray(x, dtype=float)
    least = polyorder + 2 if shortest is None else max(int(round(shortest / dt)), polyorder + 2)
    least |= 1
    top = max(x.size // 4 - 1 | 1, least)
    sigma = position_noise_std(x)
    if sigma == 0.0:
        return least
    win = least
    while True:
        gain = float(np.linalg.norm(sps.savgol_coeffs(win, polyorder, deriv=2, delta=dt)))
        a = sps.savgol_filter(x, win, polyorder, deriv=2, delta=dt)
        total = float(np.mean(a[win:-win] ** 2)) if x.size > 3 * win else float(np.mean(a**2))
        noise = (gain * sigma) ** 2
        if noise <= target**2 * max(total - noise, 0.0) or win >= top:
            return win
        win = min(int(win * 1.25) | 1, top)


def lowpass_cutoff(x: np.ndarray, fs: float, *, order: int = 4, target: float = 0.05,
                   highest: float | None = None, lowest: float = 0.1) -> float:
    """Highest zero-phase low-pass cut-off whose acceleration noise is ``target`` of the signal's.

    The counterpart of :func:`savgol_window` for :func:`differentiate` (the IDIM recipe:
    ``filtfilt`` Butterworth, then central differences twice). White position noise of std
    σ (:func:`position_noise_std`) reaches the acceleration with variance
    ``σ² (2/fs) ∫₀^{fs/2} |H(f)|⁴ (sin²(2πf/fs) fs²)² df`` (``|H|²`` the one-way Butterworth
    power response, applied twice); the cut-off is lowered from ``highest`` by factors of
    1.25 until that is at most ``target²`` of the acceleration signal's variance.

    Parameters
    ----------
    x : array_like, shape (n,)
        Position [m or rad] on a uniform clock.
    fs : float
        Sampling frequency [Hz].
    order : int
        One-way Butterworth order [-].
    target : float
        Acceleration noise rms over the acceleration signal rms [-].
    highest : float, optional
        Highest cut-off considered [Hz] (default fs/5).
    lowest : float
        Lowest cut-off returned [Hz] (then the target may be missed).

    Returns
    -------
    float
        Cut-off [Hz].

    Examples
    --------
    >>> import numpy as np
    >>> t = np.arange(20000) / 1000.0
    >>> x = np.sin(2 * np.pi * t) + np.random.default_rng(2).normal(0, 1e-4, t.size)
    >>> 1.0 < lowpass_cutoff(x, 1000.0) < 200.0
    True
    """
    x = np.asarray(x, dtype=float)
    fs = float(fs)
    cutoff = 0.2 * fs if highest is None else min(float(highest), 0.45 * fs)
    sigma = position_noise_std(x)
    if sigma == 0.0:
        return cutoff
    f = np.linspace(0.0, fs / 2, 4097)
    diff2 = (np.sin(2 * np.pi * f / fs) * fs) ** 4  # |central difference|² twice
    while True:
        power = 1.0 / (1.0 + (f / cutoff) ** (2 * order))  # |H|² one way
        noise = sigma**2 * float(np.mean(power**2 * diff2))
        _, _, a = differentiate(x, fs, cutoff_hz=cutoff, order=order)
        edge = min(x.size // 10, int(2 * fs / cutoff) + 1)
        total = float(np.mean(a[edge:x.size - edge] ** 2))
        if noise <= target**2 * max(total - noise, 0.0) or cutoff <= lowest:
            return max(cutoff, lowest)
        cutoff /= 1.25
