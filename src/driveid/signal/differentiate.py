"""Zero-phase low-pass filtering and numerical differentiation of sampled positions.

These are the signal steps of the inverse-dynamic-model (IDIM) recipe of the EMPS
benchmark (Janot, Gautier & Brunot 2019, §3): a Butterworth filter run forwards and
backwards (``filtfilt``), then central differences for velocity and acceleration.
"""

from __future__ import annotations

import numpy as np
from scipy import signal as sps

from driveid.errors import ParameterError, RecordError

__all__ = ["zero_phase_lowpass", "central_difference", "differentiate"]


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
