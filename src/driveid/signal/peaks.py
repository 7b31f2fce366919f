"""Oscillation peaks with sub-sample refinement: the features of the logarithmic decrement.

The thesis used raw samples as peaks; here each peak is refined by a local least-squares
polynomial through the samples around it, which removes the sampling error (a raw sample
misses the true peak by up to ``A (ω dt)² / 8``) and averages noise and encoder quantisation.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize_scalar
from scipy.signal import find_peaks

from driveid.errors import IdentificationError, RecordError
from driveid.io.record import Record
from driveid.signal.repair import _interval_blocks

__all__ = ["Peaks", "find_oscillation_peaks", "dominant_period"]


@dataclass(frozen=True)
class Peaks:
    """Alternating extrema of one oscillation record.

    Attributes
    ----------
    t : ndarray, shape (n,)
        Refined peak times [s].
    x : ndarray, shape (n,)
        Refined peak values [m or rad].
    index : ndarray of int, shape (n,)
        Sample index nearest each peak.
    stuck : ndarray of bool, shape (n,)
        True for a peak at which the body stays stuck: its value is exact but its time is
        only where the rest begins (not a half period after the previous peak).
    time_valid : ndarray of bool, shape (n,)
        False where the peak time is not a velocity zero located to sub-sample accuracy
        (a stuck end, or a release from a held position after the record started).
    x_std : float
        Standard deviation of the position noise around the peaks [m or rad] (0 if none).
    x_se, t_se : ndarray, shape (n,)
        Standard errors of each refined peak value [m or rad] and time [s], from the
        residuals of its local fit (relative weights for a global fit).
    """

    t: np.ndarray
    x: np.ndarray
    index: np.ndarray
    stuck: np.ndarray
    time_valid: np.ndarray
    x_std: float
    x_se: np.ndarray | None = None
    t_se: np.ndarray | None = None

    def __len__(self) -> int:
        return int(self.t.size)

    @property
    def direction(self) -> np.ndarray:
        """Sign of the motion that ends at each peak (+1 or -1); 0 for the first peak."""
        d = np.zeros(self.x.size, dtype=int)
        d[1:] = np.sign(np.diff(self.x)).astype(int)
        return d


def dominant_period(record: Record) -> float:
    """Estimate the dominant oscillation period [s] from the spectrum of the moving part.

    Parameters
    ----------
    record : Record
        A uniformly sampled oscillation.

    Returns
    -------
    float
        Period [s] of the largest spectral peak of the position (mean removed, Hann window).

    Notes
    -----
    The peak of the spectrum zero-padded to ``n_fft`` (>= 8 n, a power of 2) is found
    without the padded FFT (2^27 points at 1e7 samples): the unpadded FFT locates it, then
    the DFT is evaluated on the same ``n_fft`` grid within +-2 coarse bins only, summed over
    blocks of samples. Memory: the windowed signal and its FFT, about 3 x 8 B a sample (the
    chirp z-transform used before took 1.1 GB at 1e7 samples).
    """
    from scipy.fft import next_fast_len

    n = record.n
    mean = np.mean(record.x)
    xw = np.empty(n)
    for s in range(0, n, _BLOCK):
        xw[s:s + _BLOCK] = _windowed(record.x, mean, s, n)
    fs = 1.0 / record.dt
    low = 2.0 / record.duration  # under two cycles per record is drift, not an oscillation
    n_fft = 1 << int(np.ceil(np.log2(8 * n)))
    n1 = next_fast_len(n, real=True)
    coarse = np.abs(np.fft.rfft(xw, n1))
    coarse[np.fft.rfftfreq(n1, record.dt) < low] = 0.0
    k1 = int(np.argmax(coarse))
    if k1 == 0 or coarse[k1] == 0:
        raise IdentificationError("the record does not move; no oscillation to analyse")
    del coarse
    df = fs / n_fft
    j0 = max(int(np.floor((k1 - 2) * fs / n1 / df)), 0)
    j1 = min(int(np.ceil((k1 + 2) * fs / n1 / df)), n_fft // 2)
    freqs = np.arange(j0, j1 + 1) * df
    spec = np.abs(_dft_at(xw, freqs / fs))
    spec[freqs < low] = 0.0
    k = int(np.argmax(spec))
    if freqs[k] == 0 or spec[k] == 0:
        raise IdentificationError("the record does not move; no oscillation to analyse")
    return float(1.0 / freqs[k])


#: Samples per block of the chunked passes over a record (64 k: 0.5 MB of float64).
_BLOCK = 1 << 16


def _windowed(x: np.ndarray, mean: float, s: int, n: int) -> np.ndarray:
    """``(x - mean) * np.hanning(n)`` on samples ``s .. s + _BLOCK`` (same arithmetic)."""
    e = min(s + _BLOCK, n)
    m = float(n)
    k = np.arange(1 - m + 2 * s, 1 - m + 2 * e, 2)[: e - s]
    return (x[s:e] - mean) * (0.5 + 0.5 * np.cos(np.pi * k / (m - 1)))


def _dft_at(x: np.ndarray, cycles: np.ndarray, block: int = 4096) -> np.ndarray:
    """``sum_k x[k] exp(-2 pi i c k)`` for each ``c`` in ``cycles`` [cycles a sample].

    A ``(len(cycles), block)`` table of phases is reused for every block of samples and
    rotated by the block's start phase (reduced modulo one cycle, so the phase of a late
    block keeps its precision): O(n len(cycles)) work, O(block len(cycles)) memory.
    """
    # a record shorter than a block needs no wider table (a 1200-sample fleet record with a
    # 4096-wide one spent most of its spectral time making and zeroing 4 MB, issue 28)
    block = max(1, min(block, x.size))
    phase = -2 * np.pi * np.outer(cycles, np.arange(block))
    table = np.vstack([np.cos(phase), np.sin(phase)])  # real products: one dgemv a block
    m = cycles.size
    out = np.zeros(m, complex)
    for s in range(0, x.size, block):
        part = x[s:s + block]
        sums = (table @ part) if part.size == block else table[:, :part.size] @ part
        out += np.exp(-2j * np.pi * np.mod(cycles * s, 1.0)) * (sums[:m] + 1j * sums[m:])
    return out


def find_oscillation_peaks(
    record: Record,
    *,
    period: float | None = None,
    min_prominence: float | None = None,
    window: float = 0.08,
) -> Peaks:
    """Locate the alternating peaks of a decaying oscillation to sub-sample accuracy.

    Parameters
    ----------
    record : Record
        Uniformly sampled position record of a (free or PD-driven) oscillation.
    period : float, optional
        Approximate oscillation period [s]; estimated from the spectrum if omitted.
    min_prominence : float, optional
        Smallest peak-to-valley swing accepted [m or rad]; default 40 noise standard
        deviations plus 4 encoder quanta: weaker peaks are biased inward by the noise
        (measured in tests/identify/test_logdec.py), so they are not used.
    window : float
        Half-width of the refinement window as a fraction of the period [-]; 0.08 gives
        ``ω·w = 0.5 rad``.

    Returns
    -------
    Peaks
        The peaks, alternating in sign of curvature, in time order.

    Raises
    ------
    RecordError
        If the record contains corrupted bursts.
    IdentificationError
        If the record does not oscillate.

    Notes
    -----
    Each peak is refined over ``±window·period`` by a two-sided quartic with a shared velocity
    zero (Coulomb friction makes the acceleration jump at the peak; see ``_refine``), or a
    3-point parabola when fewer than 7 samples are available. A final plateau (the body
    stuck) ends the list with a peak whose value is the plateau's median.

    Memory (issue 12): at most about 24 B a sample beyond the record - the period estimate
    (windowed signal, unpadded FFT), or scipy's ``find_peaks`` on ``-x`` (a negated copy
    and three n/2 index arrays); the noise level works in place on one difference array;
    the refinement takes batches of at most 65 536 window samples (~10 MB).
    """
    if record.corrupted:
        i0, i1 = record.corrupted[0]
        raise RecordError(
            f"record has corrupted samples between t={record.t[i0]:.4g} s and "
            f"t={record.t[i1 - 1]:.4g} s; crop them out (Record.crop) or repeat the run"
        )
    x = np.asarray(record.x)
    spread = float(np.ptp(x))
    if spread == 0:
        raise IdentificationError("position is constant; the record shows no oscillation")
    if period is None:
        period = dominant_period(record)
    fs = 1.0 / record.dt
    noise, quantum = _noise_level(x)
    if min_prominence is None:
        min_prominence = 40 * noise + 4 * quantum + 1e-9 * spread
    distance = max(1, int(0.3 * period * fs))
    # prominence within +-2 periods: the adjacent valleys decide it, and without a window
    # scipy searches to the end of a decaying record from every peak (O(n) a peak)
    wlen = max(3, int(4 * period * fs)) | 1
    hi, _ = find_peaks(x, distance=distance, prominence=min_prominence, wlen=wlen)
    lo, _ = find_peaks(-x, distance=distance, prominence=min_prominence, wlen=wlen)
    idx = np.concatenate([hi, lo])
    kind = np.concatenate([np.ones(hi.size, int), -np.ones(lo.size, int)])
    order = np.argsort(idx)
    idx, kind = idx[order], kind[order]
    idx, kind = _alternate(x, idx, kind)
    # the initial displacement (released at rest) is the zeroth peak when it is an extremum
    near_start = max(2, int(0.05 * period * fs))
    released_late = False
    if idx.size and 0 < idx[0] <= near_start:
        idx[0] = 0  # a noisy flat top at the start: the release itself, at t[0]
    elif idx.size and idx[0] > 0:
        first_kind = -kind[0]
        head = x[: idx[0]]
        j = int(np.argmax(head) if first_kind > 0 else np.argmin(head))
        if j <= near_start:
            j = 0  # noise decides which early sample is largest: the release is t[0]
        # at rest there: over m samples it moves far less than at full speed
        m = max(3, near_start // 2)
        max_step = max(float(np.max(np.abs(d))) for _, d in _interval_blocks(x, _BLOCK))
        k_end = min(j + m, x.size - 1)
        at_rest = abs(x[k_end] - x[j]) <= 0.25 * m * max_step + 3 * noise + 2 * quantum
        if abs(x[j] - x[idx[0]]) >= min_prominence and at_rest and (j == 0 or _is_release(x, j)):
            idx = np.concatenate([[j], idx])
            kind = np.concatenate([[first_kind], kind])
            released_late = j > 0
    half_w = max(1, int(round(window * period * fs)))
    t_pk = np.empty(idx.size)
    x_pk = np.empty(idx.size)
    t_se = np.empty(idx.size)
    x_se = np.empty(idx.size)
    inner = (idx - half_w >= 0) & (idx + half_w < x.size) & (half_w >= 3)
    for k in np.flatnonzero(~inner):
        t_pk[k], x_pk[k], t_se[k], x_se[k] = _refine(record.t, x, int(idx[k]), half_w)
    # bounded memory on long records: a batch holds at most _CHUNK_SAMPLES window samples
    # (each with 7 fit columns and their QR: ~150 B a window sample, ~10 MB a batch)
    per_batch = max(1, min(_CHUNK, _CHUNK_SAMPLES // (2 * half_w + 1)))
    for c in range(0, int(inner.sum()), per_batch):
        k = np.flatnonzero(inner)[c:c + per_batch]
        t_pk[k], x_pk[k], t_se[k], x_se[k] = _refine_many(record.t, x, idx[k], half_w)
    stuck = np.zeros(idx.size, bool)
    time_valid = np.ones(idx.size, bool)
    if released_late:
        # released from a held position: the held value is exact, the release instant is not
        t_pk[0], x_pk[0] = record.t[idx[0]], float(np.median(x[: idx[0] + 1]))
        x_se[0] = (noise + quantum) / np.sqrt(idx[0] + 1)
        time_valid[0] = False
    elif idx.size and idx[0] == 0:
        # released at the first sample: one-sided fit with zero slope at t[0]
        t_pk[0], x_pk[0], x_se[0] = record.t[0], *_release_value(record.t, x, half_w)
        t_se[0] = float(np.median(t_se[1:])) if idx.size > 1 else record.dt
    # a stuck end: the last motion runs into a plateau longer than half a period
    last = idx[-1] if idx.size else 0
    tail = x[last:]
    plateau = _plateau_start(tail, noise + quantum, int(0.5 * period * fs))
    if idx.size and plateau is not None:
        j = last + plateau
        value = float(np.median(x[j:]))
        if abs(value - x_pk[-1]) >= min_prominence:
            idx = np.append(idx, j)
            t_pk = np.append(t_pk, record.t[j])
            x_pk = np.append(x_pk, value)
            stuck = np.append(stuck, True)
            time_valid = np.append(time_valid, False)
            x_se = np.append(x_se, (noise + quantum) / np.sqrt(x.size - j))
            t_se = np.append(t_se, np.inf)
    if idx.size < 2:
        raise IdentificationError(
            f"found {idx.size} oscillation peak(s) above the noise "
            f"(prominence >= {min_prominence:.3g}); the record does not oscillate. Excite "
            "a larger motion, reduce damping (e.g. negative D feedback) or record longer"
        )
    # clean records give round-off standard errors: floor them at a relative 1e-12
    x_se = np.maximum(x_se, 1e-12 * spread)
    t_se = np.maximum(t_se, 1e-9 * record.dt)
    return Peaks(
        t=t_pk, x=x_pk, index=idx.astype(int), stuck=stuck, time_valid=time_valid, x_std=noise,
        x_se=x_se, t_se=t_se,
    )


def _noise_level(x: np.ndarray) -> tuple[float, float]:
    """Robust noise std from third differences, and the apparent quantisation step."""
    # memory: one array of third differences (8 B a sample), made and reduced in place; the
    # order of its values does not matter to a median, so both medians partition it in place
    d3 = np.diff(x)
    for size in (d3.size - 1, d3.size - 2):  # np.diff(x, 3), one block at a time
        for s in range(0, size, _BLOCK):
            e = min(s + _BLOCK, size)
            np.subtract(d3[s + 1:e + 1], d3[s:e], out=d3[s:e])
    d3 = d3[: max(x.size - 3, 0)]
    # third differences of white noise have variance 20 σ²; smooth motion contributes ~0
    centre = np.median(d3, overwrite_input=True)
    np.abs(np.subtract(d3, centre, out=d3), out=d3)
    noise = float(1.4826 * np.median(d3, overwrite_input=True) / np.sqrt(20.0))
    del d3
    smallest = math.inf
    for _, step in _interval_blocks(x, _BLOCK):  # two passes over blocks of steps
        step = np.abs(step)
        if np.any(step > 0):
            smallest = min(smallest, float(np.min(step[step > 0])))
    quantum = 0.0
    # an encoder grid: every step is a whole number of the smallest step
    if 0 < smallest < math.inf and all(
            np.allclose(part / smallest, np.round(part / smallest), atol=1e-6)
            for part in (_moving(step) for _, step in _interval_blocks(x, _BLOCK))):
        quantum = smallest
    return noise, quantum


def _moving(step: np.ndarray) -> np.ndarray:
    """Return the non-zero step sizes of a block of steps."""
    step = np.abs(step)
    return step[step > 0]


def _alternate(x, idx, kind):
    """Enforce max/min alternation, keeping the more extreme of two same-kind neighbours."""
    keep_i: list[int] = []
    keep_k: list[int] = []
    for i, k in zip(idx.tolist(), kind.tolist(), strict=True):
        if keep_k and keep_k[-1] == k:
            if k * x[i] > k * x[keep_i[-1]]:
                keep_i[-1] = i
            continue
        keep_i.append(i)
        keep_k.append(k)
    return np.array(keep_i, int), np.array(keep_k, int)


def _is_release(x: np.ndarray, j: int) -> bool:
    """Tell whether the samples before ``j`` rest near x[j] (a release from a held position)."""
    before = x[:j]
    return bool(np.ptp(before) <= 0.05 * abs(x[j] - np.median(x))) if before.size else True


def _refine(t, x, i, half_w):
    """Sub-sample peak (time, value, s.e. of time, s.e. of value), two-sided fit.

    Coulomb friction switches sign at the peak, so the acceleration jumps there: a single
    polynomial through the peak is biased. Each side gets its own quartic,
    ``x = x_p + Σ_{k=2..4} a_{k±} (t - t_p)^k``, joined with zero slope at ``t_p``; ``t_p``
    minimises the residual (the other coefficients are linear least squares). The standard
    error of ``x_p`` comes from the linear fit, that of ``t_p`` from the curvature of the
    residual sum of squares, ``var(t_p) = 2 s² / RSS''(t_p)``.
    """
    lo = max(0, i - half_w)
    hi = min(x.size, i + half_w + 1)
    dt = t[min(i + 1, t.size - 1)] - t[max(i - 1, 0)]
    if i - lo < 3 or hi - i - 1 < 3:
        if 0 < i < x.size - 1:
            y0, y1, y2 = x[i - 1], x[i], x[i + 1]
            denom = y0 - 2 * y1 + y2
            shift = 0.5 * (y0 - y2) / denom if denom != 0 else 0.0
            shift = float(np.clip(shift, -1, 1))
            step = t[i + 1] - t[i]
            return t[i] + shift * step, y1 - 0.25 * (y0 - y2) * shift, step, abs(denom)
        return t[i], x[i], dt, 0.0
    tt = t[lo:hi] - t[i]
    xx = x[lo:hi]
    scale = max(abs(tt[0]), abs(tt[-1]))

    def fit(tp):
        s = (tt - tp) / scale
        left = s < 0
        cols = np.column_stack(
            [np.ones_like(s)]
            + [left * s**k for k in (2, 3, 4)]
            + [~left * s**k for k in (2, 3, 4)]
        )
        coef, *_ = np.linalg.lstsq(cols, xx, rcond=None)
        resid = xx - cols @ coef
        return float(resid @ resid), coef[0], cols

    res = minimize_scalar(
        # the largest noisy sample may lie many samples from the true peak of a flat top
        lambda tp: fit(tp)[0], bounds=(-0.5 * scale, 0.5 * scale), method="bounded",
        options={"xatol": 1e-9 * dt},
    )
    tp = float(res.x)
    rss, value, cols = fit(tp)
    dof = max(xx.size - cols.shape[1] - 1, 1)
    s2 = rss / dof
    cov00 = float(np.linalg.pinv(cols.T @ cols)[0, 0])
    h = 0.05 * dt
    curv = (fit(tp + h)[0] - 2 * rss + fit(tp - h)[0]) / (h * h)
    t_se = float(np.sqrt(2 * s2 / curv)) if curv > 0 else dt
    return t[i] + tp, float(value), t_se, float(np.sqrt(s2 * cov00))


#: Peaks refined together (each holds a window of 2 half_w + 1 samples and 7 columns).
_CHUNK = 512
#: Most window samples refined together (at 100 kHz a window holds ~25 000 samples).
_CHUNK_SAMPLES = 1 << 16
_GOLDEN = 0.5 * (3.0 - 5.0**0.5)
_GOLDEN_STEPS = 13
_NEWTON_STEPS = 3


def _fit_many(tt, xx, scale, tp):
    """Two-sided quartic fits (see ``_refine``) of many windows at once.

    tt, xx: (p, w) window times relative to the sample peak [s] and values; scale, tp: (p,).
    Returns the residual sums of squares (p,), the fitted peak values (p,) and the
    ``[(A^T A)^+]_00`` factor of their variance (p,). Batched QR on long windows; batched
    pseudo-inverse (SVD, as ``lstsq``) on short ones, where a side may hold too few samples
    for its three columns.
    """
    s = (tt - tp[:, None]) / scale[:, None]
    left = (s < 0)[..., None]
    s2 = s * s
    powers = np.stack([s2, s2 * s, s2 * s2], axis=2)
    cols = np.concatenate([np.ones(s.shape + (1,)), powers * left, powers * ~left], axis=2)
    if s.shape[1] >= 17:
        q, r = np.linalg.qr(cols)
        qtx = np.einsum("pwk,pw->pk", q, xx)
        resid = xx - np.einsum("pwk,pk->pw", q, qtx)
        r_inv = np.linalg.inv(r)
        coef0 = np.einsum("pk,pk->p", r_inv[:, 0, :], qtx)
        row0 = r_inv[:, 0, :]
    else:
        pinv = np.linalg.pinv(cols)
        coef = np.einsum("pkw,pw->pk", pinv, xx)
        resid = xx - np.einsum("pwk,pk->pw", cols, coef)
        coef0, row0 = coef[:, 0], pinv[:, 0, :]
    return np.einsum("pw,pw->p", resid, resid), coef0, np.einsum("pk,pk->p", row0, row0)


def _refine_many(t, x, idx, half_w):
    """``_refine`` for many peaks with full windows at once: O(window) numpy work per peak.

    The scalar bounded Brent search of ``_refine`` (about 20 fits, each a separate
    ``lstsq`` call) is replaced by a golden-section bracket and safeguarded Newton steps
    run on all peaks together, so the Python overhead is per batch, not per peak: the
    refinement is linear in the record length with a small constant.
    """
    offs = np.arange(-half_w, half_w + 1)
    win = idx[:, None] + offs
    tt = t[win] - t[idx][:, None]
    xx = x[win]
    scale = np.maximum(np.abs(tt[:, 0]), np.abs(tt[:, -1]))
    dt = t[idx + 1] - t[idx - 1]
    a, b = -0.5 * scale, 0.5 * scale
    c, d = a + _GOLDEN * (b - a), b - _GOLDEN * (b - a)
    fc, fd = _fit_many(tt, xx, scale, c)[0], _fit_many(tt, xx, scale, d)[0]
    for _ in range(_GOLDEN_STEPS):  # bracket the minimum to ~0.2 % of the window
        go_left = fc <= fd  # the minimum lies in [a, d]
        b = np.where(go_left, d, b)
        a = np.where(go_left, a, c)
        c_new = np.where(go_left, a + _GOLDEN * (b - a), d)
        d_new = np.where(go_left, c, b - _GOLDEN * (b - a))
        f_new = _fit_many(tt, xx, scale, np.where(go_left, c_new, d_new))[0]
        fc, fd = np.where(go_left, f_new, fd), np.where(go_left, fc, f_new)
        c, d = c_new, d_new
    tp = np.where(fc <= fd, c, d)
    # then Newton steps on the residual (C1 in tp, smooth between samples), kept inside
    # the bracket: a few fits instead of the ~40 more a bracketing search needs for 1e-9 dt
    for _ in range(_NEWTON_STEPS):
        h = np.maximum(1e-3 * (b - a), 1e-7 * dt)
        f0 = _fit_many(tt, xx, scale, tp)[0]
        fp = _fit_many(tt, xx, scale, tp + h)[0]
        fm = _fit_many(tt, xx, scale, tp - h)[0]
        curv = fp - 2 * f0 + fm
        with np.errstate(all="ignore"):
            step = np.where(curv > 0, -0.5 * h * (fp - fm) / curv, 0.0)
        tp = np.clip(tp + step, a, b)
    rss, value, cov00 = _fit_many(tt, xx, scale, tp)
    dof = max(xx.shape[1] - 7 - 1, 1)
    s2 = rss / dof
    h = 0.05 * dt
    curv = (_fit_many(tt, xx, scale, tp + h)[0] - 2 * rss
            + _fit_many(tt, xx, scale, tp - h)[0]) / (h * h)
    with np.errstate(all="ignore"):
        t_se = np.where(curv > 0, np.sqrt(2 * s2 / curv), dt)
    t_out, x_out, x_se = t[idx] + tp, value, np.sqrt(s2 * cov00)
    bad = ~(np.isfinite(x_out) & np.isfinite(x_se))
    for k in np.flatnonzero(bad):  # a degenerate window: the scalar path handles it
        t_out[k], x_out[k], t_se[k], x_se[k] = _refine(t, x, int(idx[k]), half_w)
    return t_out, x_out, t_se, x_se


def _release_value(t, x, half_w):
    """Position at t[0] (and its s.e.) of a motion released from rest there."""
    hi = min(x.size, half_w + 1)
    if hi < 6:
        return float(x[0]), 0.0
    s = (t[:hi] - t[0]) / (t[hi - 1] - t[0])
    cols = np.column_stack([np.ones_like(s), s**2, s**3, s**4])
    coef, *_ = np.linalg.lstsq(cols, x[:hi], rcond=None)
    resid = x[:hi] - cols @ coef
    s2 = float(resid @ resid) / (hi - 4)
    return float(coef[0]), float(np.sqrt(s2 * np.linalg.pinv(cols.T @ cols)[0, 0]))


def _plateau_start(tail: np.ndarray, tol: float, min_len: int) -> int | None:
    """Index in ``tail`` where it settles for good within ``tol`` of its end value."""
    if tail.size < max(min_len, 3):
        return None
    end = float(np.median(tail[-max(3, min_len // 2):]))
    away = np.flatnonzero(np.abs(tail - end) > max(tol, 1e-12 * (1 + abs(end))))
    start = int(away[-1]) + 1 if away.size else 0
    if tail.size - start < min_len:
        return None
    return start
