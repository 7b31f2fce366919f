"""Detection of steady (constant-level) segments and their means with honest uncertainty.

Python counterpart of the thesis's support function ``Steady.m`` (App. B.6.5, "finds the
steady-state region of a given oscillation"), applied here to a velocity (or any signal that
should sit on plateaus): a sample is steady when the signal in a window around it scatters no
more than its noise and does not drift. Steady-velocity friction maps (thesis §7 outline,
"a simple linear fit to the obtained data at different steady-state velocities") average
force and velocity over such segments.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from driveid.errors import ParameterError, RecordError

__all__ = ["SteadySegment", "find_steady_segments", "segment_mean", "noise_level", "n_effective",
           "position_noise", "standstill_mask"]


@dataclass(frozen=True)
class SteadySegment:
    """A steady run of samples ``[start, stop)`` with its mean levels.

    Attributes
    ----------
    start, stop : int
        Half-open sample range.
    velocity, velocity_stderr : float
        Mean velocity and its standard error [m/s or rad/s].
    force, force_stderr : float
        Mean force and its standard error [N or N·m]; ``nan`` without force data.
    n : int
        Samples in the segment [-].
    """

    start: int
    stop: int
    velocity: float
    velocity_stderr: float
    force: float = math.nan
    force_stderr: float = math.nan
    n: int = 0


def noise_level(y: np.ndarray) -> float:
    """Estimate the white-noise standard deviation of ``y`` from successive differences.

    Parameters
    ----------
    y : array_like, shape (n,)
        Signal [unit]; n >= 3.

    Returns
    -------
    float
        ``1.4826·median|Δy|/√2`` [unit], robust to steps and slow trends; falls back to
        ``mean|Δy|/√2`` for coarsely quantised signals whose median step is 0.

    Examples
    --------
    >>> import numpy as np
    >>> y = np.random.default_rng(1).normal(0.0, 2.0, 20000)
    >>> round(noise_level(y), 1)
    2.0
    """
    d = np.abs(np.diff(np.asarray(y, dtype=float)))
    if d.size < 2:
        raise RecordError(f"noise level needs at least 3 samples; got {d.size + 1}")
    sigma = 1.4826 * float(np.median(d)) / math.sqrt(2.0)
    if sigma == 0.0:
        sigma = float(np.mean(d)) / math.sqrt(2.0)
    return sigma


def n_effective(y: np.ndarray) -> float:
    """Effective number of independent samples of a correlated series (AR(1) model).

    Parameters
    ----------
    y : array_like, shape (n,)
        Samples [unit].

    Returns
    -------
    float
        ``n·(1 − ρ)/(1 + ρ)`` with ρ the lag-1 autocorrelation clipped to [0, 0.99] [-];
        at least 1.

    Examples
    --------
    >>> import numpy as np
    >>> round(n_effective(np.random.default_rng(0).standard_normal(10000)) / 1e4, 1)
    1.0
    """
    y = np.asarray(y, dtype=float)
    n = y.size
    if n < 3:
        return float(max(n, 1))
    d = y - y.mean()
    den = float(d @ d)
    rho = 0.0 if den == 0 else float(d[1:] @ d[:-1]) / den
    rho = min(max(rho, 0.0), 0.99)
    return max(1.0, n * (1.0 - rho) / (1.0 + rho))


def segment_mean(y: np.ndarray) -> tuple[float, float]:
    """Return the mean of ``y`` and its standard error ``std/sqrt(n_eff)``.

    Parameters
    ----------
    y : array_like, shape (n,)
        Samples of one steady segment [unit]; n >= 2.

    Returns
    -------
    tuple of float
        ``(mean, stderr)`` [unit].
    """
    y = np.asarray(y, dtype=float)
    if y.size < 2:
        raise RecordError(f"a segment mean needs at least 2 samples; got {y.size}")
    return float(y.mean()), float(y.std(ddof=1) / math.sqrt(n_effective(y)))


def _moving(y: np.ndarray, w: int) -> tuple[np.ndarray, np.ndarray]:
    kernel = np.ones(w) / w
    m = np.convolve(y, kernel, mode="same")
    m2 = np.convolve(y * y, kernel, mode="same")
    return m, np.sqrt(np.maximum(m2 - m * m, 0.0))


def find_steady_segments(
    y: np.ndarray,
    *,
    window: int = 25,
    rel_tol: float = 0.02,
    noise_factor: float = 3.0,
    min_samples: int = 50,
    noise: float | None = None,
) -> list[tuple[int, int]]:
    """Find runs of samples where ``y`` sits on a level (thesis ``Steady.m``).

    Parameters
    ----------
    y : array_like, shape (n,)
        Signal, typically velocity [m/s or rad/s].
    window : int
        Moving-window length [samples]; >= 3. Should span a few noise correlation times.
    rel_tol : float
        Allowed scatter and drift relative to the local level [-].
    noise_factor : float
        Allowed scatter in units of the noise level [-].
    min_samples : int
        Shortest steady run kept [samples]; >= window.
    noise : float, optional
        Scatter of ``y`` on a plateau [unit]; default the median moving standard
        deviation, i.e. the typical scatter when most of the record is steady.

    Returns
    -------
    list of (int, int)
        Half-open index ranges ``[start, stop)``. Because the drift test compares means a
        window apart, runs start and stop about a window inside the true plateau, so
        transients do not leak in.

    Raises
    ------
    ParameterError
        If a setting is out of range.

    Notes
    -----
    A sample ``i`` is steady when the moving standard deviation around it is at most
    ``tol = max(rel_tol·|m_i|, noise_factor·noise)`` and the moving means half a window
    before and after differ by at most ``tol`` (no drift); ``m_i`` is the moving mean. A run
    of such samples is then cut wherever ``m_i`` leaves the mean level of the run so far by
    more than ``tol``; each piece is kept from the first sample after which its
    least-squares trend changes it by at most ``tol/2`` from end to end and at least
    ``min_samples`` remain: the start of a slowly settling (e.g. first-order, τ of
    seconds) plateau is trimmed instead of the plateau being lost, and a larger tolerance
    trims less (a piece cut from a ramp changes by about ``tol``).

    Examples
    --------
    >>> import numpy as np
    >>> y = np.concatenate([np.linspace(0, 1, 100), np.ones(300), np.linspace(1, 2, 100),
    ...                     2 * np.ones(300)])
    >>> [(int(a), int(b)) for a, b in find_steady_segments(y, noise=1e-3)]
    [(114, 386), (510, 776)]
    """
    if int(window) != window or window < 3:
        raise ParameterError(f"window must be an integer >= 3 samples; got {window}")
    if int(min_samples) != min_samples or min_samples < window:
        raise ParameterError(
            f"min_samples must be an integer >= window ({window}); got {min_samples}"
        )
    if not rel_tol >= 0 or not noise_factor >= 0:
        raise ParameterError(
            f"rel_tol and noise_factor must be >= 0; got {rel_tol} and {noise_factor}"
        )
    y = np.asarray(y, dtype=float)
    if y.size < min_samples:
        return []
    w = int(window)
    m, s = _moving(y, w)
    # typical within-window scatter: white noise and stationary ripple alike (a difference
    # based estimate misses correlated ripple, e.g. gear-mesh torque in a worm drive)
    sigma = float(np.median(s[w:-w] if y.size > 3 * w else s)) if noise is None else float(noise)
    tol = np.maximum(rel_tol * np.abs(m), noise_factor * sigma)
    h = w // 2
    drift = np.full(y.size, np.inf)
    drift[h:-h] = np.abs(m[2 * h:] - m[: -2 * h])
    ok = (s <= tol) & (drift <= tol)
    ok[:h] = False
    ok[-h:] = False
    edges = np.flatnonzero(np.diff(np.concatenate([[0], ok.astype(np.int8), [0]])))
    out = []
    for a, b in zip(edges[::2], edges[1::2], strict=True):
        for i, j in _split_level(m, tol, int(a), int(b)):
            piece = _settled_tail(y, m, i, j, rel_tol, noise_factor * sigma, min_samples, h)
            if piece is not None:
                out.append(piece)
    return _merge_fragments(y, out, rel_tol, noise_factor * sigma, 2 * w)


def _merge_fragments(y: np.ndarray, segs: list[tuple[int, int]], rel_tol: float,
                     noise_tol: float, max_gap: int) -> list[tuple[int, int]]:
    # a plateau cut by a noise burst comes back as fragments on one level: join them
    merged: list[tuple[int, int]] = []
    for a, b in segs:
        if merged:
            pa, pb = merged[-1]
            m1, m2 = float(y[pa:pb].mean()), float(y[a:b].mean())
            limit = 0.5 * max(rel_tol * max(abs(m1), abs(m2)), noise_tol)
            if a - pb <= max_gap and abs(m1 - m2) <= limit:
                merged[-1] = (pa, b)
                continue
        merged.append((a, b))
    return merged


def _trend_change(y: np.ndarray) -> float:
    n = y.size
    k = np.arange(n) - 0.5 * (n - 1)
    return abs(float(k @ y) / float(k @ k)) * (n - 1)


def _settled_tail(y: np.ndarray, m: np.ndarray, i: int, j: int, rel_tol: float,
                  noise_tol: float, min_samples: int, step: int) -> tuple[int, int] | None:
    # settling is judged by the trend of the remaining samples against the tolerance: a
    # plateau changes across itself by no more than its noise, a piece of a ramp by about
    # tol; drop the start in steps until the rest is settled (a larger tolerance stops
    # earlier, so it never finds fewer segments)
    step = max(1, int(step))
    start = i
    while j - start >= min_samples:
        limit = 0.5 * max(rel_tol * abs(float(m[start:j].mean())), noise_tol)
        if _trend_change(y[start:j]) <= limit:
            return start, j
        start += step
    return None


def _split_level(m: np.ndarray, tol: np.ndarray, a: int, b: int) -> list[tuple[int, int]]:
    # a slow ramp passes the local tests everywhere; cut a run wherever its moving mean
    # leaves the level of the samples before it by more than the tolerance
    pieces, start, total = [], a, 0.0
    for i in range(a, b):
        if i > start and abs(m[i] - total / (i - start)) > tol[i]:
            pieces.append((start, i))
            start, total = i, 0.0
        total += m[i]
    pieces.append((start, b))
    return pieces


def standstill_mask(x: np.ndarray, window: int) -> np.ndarray:
    """Mark the samples at which a measured position holds still (static friction holds it).

    Still: the raw position moves by at most two encoder counts (its smallest step), or by at
    most 8 white-noise sd (:func:`position_noise`) on a noisy sensor, within ``2·window + 1``
    samples; widened by ``2·window`` on each side, since a zero-phase filter smears the stop.

    Parameters
    ----------
    x : ndarray, shape (n,)
        Position [m or rad].
    window : int
        Half-width in samples, e.g. ``fs/cutoff_hz`` of the velocity filter [-].

    Returns
    -------
    ndarray of bool, shape (n,)
    """
    from scipy.ndimage import maximum_filter1d, minimum_filter1d

    from driveid.signal.repair import _interval_blocks

    # smallest non-zero step over blocks of steps: no whole-record temporaries
    moving = [float(np.min(d[d > 0])) for d in (np.abs(d) for _, d in _interval_blocks(x))
              if np.any(d > 0)]
    if not moving:
        return np.ones(x.size, bool)
    quantum = min(moving)
    size = 2 * int(window) + 1
    ptp = maximum_filter1d(x, size, mode="nearest")
    ptp -= minimum_filter1d(x, size, mode="nearest")
    # a noisy (not only quantised) sensor never holds still to two counts: also call still
    # what moves by less than the range white noise spans in the window (8 σ: the range of
    # ~100 Gaussian samples exceeds it with probability ~1e-4)
    still = ptp <= max(2.0 * quantum * (1 + 1e-9), 8.0 * position_noise(x))
    del ptp
    # the zero-phase filter smears the stop over a few windows: its rows are unreliable too
    return maximum_filter1d(still.astype(np.int8), 4 * int(window) + 1) > 0


def position_noise(x: np.ndarray, blocks: int = 64, length: int = 8192) -> float:
    """Robust white-noise sd of a moving position from its second differences [m or rad].

    ``Δ²x`` of white noise of sd σ has sd ``√6 σ``; smooth motion adds only ``a·dt²`` (first
    differences, :func:`noise_level`, would carry the velocity). The median absolute value
    (×1.4826) over up to ``blocks`` evenly spaced blocks of ``length`` samples keeps it cheap
    on long records; 0 for a quantised record that mostly holds still.

    Parameters
    ----------
    x : ndarray, shape (n,)
        Position [m or rad].
    blocks, length : int
        How many blocks of how many samples are used [-].

    Returns
    -------
    float
        σ [m or rad].

    Examples
    --------
    >>> import numpy as np
    >>> t = np.arange(100000) / 1000.0
    >>> x = np.sin(t) + np.random.default_rng(0).normal(0.0, 1e-3, t.size)
    >>> round(position_noise(x) * 1e3, 2)
    1.0
    """
    starts = np.unique(np.linspace(0, max(x.size - length, 0), blocks).astype(int))
    d2 = np.concatenate([np.diff(x[a:a + length], 2) for a in starts])
    if d2.size == 0:
        return 0.0
    return float(1.4826 * np.median(np.abs(d2)) / math.sqrt(6.0))
