r"""Morlet-wavelet identification of modal frequency and damping (de Marchi 1998, §2.2.10-2.2.11).

The transform is the thesis's FFT form (2.238)-(2.244), with the translation ``b`` folded
into the output time (the thesis carries both ``t`` and ``b``, but ``W`` depends only on
``t + b``):

.. math::

    W(a, t) = \sqrt{\frac{a}{2\pi}} \int X(\omega)\,
              e^{-\frac{1}{2}(a\omega-\omega_c)^2} e^{j\omega t}\, d\omega,

with the symmetric Fourier transform ``X``, i.e. ``W = sqrt(a) * ifft(fft(x) * G)``
discretely, ``G = exp(-(a omega - omega_c)^2 / 2)``. For a mode
:math:`x = A(t)\cos\phi(t)` and a dilation tuned to it, :math:`a = \omega_c/\dot\phi` (2.246),
:math:`W = \tfrac{1}{2}\sqrt{a}\,A\,e^{j\phi}`, so :math:`\omega_d = d\angle W/dt` (2.248) and
:math:`\sigma = -d\ln|W|/dt` (2.249); then :math:`\omega_0 = \sqrt{\omega_d^2+\sigma^2}` and
:math:`\zeta = \sigma/\omega_0` (2.143, 2.150). For an exponentially decaying mode these
relations are exact for any dilation (the Gaussian window shifts, it does not distort, an
exponential), so dilation tuning mainly suppresses the other modes.

Errata (derived here; the tests recover known modes with them):

* (2.247)/(2.249): for a *real* signal half of the spectrum lies at negative frequencies,
  which the Morlet filter rejects; the amplitude is :math:`A = 2|W|/\sqrt a`, not
  :math:`|W|/\sqrt a` (Ruzzene et al. 1997, Eq. 8, have the factor 1/2).
* (2.249), last member: :math:`\sqrt{\dot\phi/\omega_c}\,|W|` is not
  :math:`|W|\,(d\angle W/dt)/\sqrt{\omega_c}`; the square root is missing.
* (2.244)/(2.248): ``b`` in (2.243) and ``t`` of the inverse transform are the same
  translation counted twice; ``angle W = omega_d (t + b)`` reduces to ``omega_d t`` with
  ``b = 0``, which is what is computed.
* footnote 79 is right that Ruzzene et al.'s :math:`G(\omega)` needs the exponent halved:
  (2.242) with (2.233) gives :math:`G^* = \sqrt a\,e^{-(a\omega-\omega_c)^2/2} e^{j\omega b}`
  (2.243), which we use.

Implementation choice: the transform is ~30 lines of :mod:`scipy.fft` evaluated only at
the few dilations needed (a log-spaced grid for the scalogram, at a few hundred instants,
and one tuned dilation per mode at every sample), each only on the frequency bins its
Gaussian passes: O(n log n) time and O(n) memory (see :func:`morlet_transform`).
PyWavelets' ``cwt`` convolves in the time domain with a differently normalised
Morlet (no ``omega_c`` parameter) and ssqueezepy normalises for synchrosqueezing; neither is
installed and matching their normalisation to (2.244) would cost more than writing it.

End effects: the record is zero-padded by the wavelet support (8 a), and
the *cone of influence* ``|t - t_end| < coi_factor * a`` (``a`` in seconds is the standard
deviation of the Gaussian window) is excluded, together with samples whose amplitude is
below ``min_snr`` times the in-band noise.

References
----------
.. [1] J. A. de Marchi, "Modeling of dynamic friction, impact backlash and elastic
       compliance nonlinearities in machine tools", PhD thesis, RPI, 1998.
.. [2] M. Ruzzene, A. Fasana, L. Garibaldi, B. Piombo, "Natural frequencies and dampings
       identification using wavelet transform: application to real data", Mech. Syst.
       Signal Process. 11(2), 207-218, 1997. doi:10.1006/mssp.1996.0078
.. [3] C. Torrence, G. P. Compo, "A practical guide to wavelet analysis", Bull. Am.
       Meteorol. Soc. 79(1), 61-78, 1998.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from scipy.signal import find_peaks

from driveid.errors import IdentificationError, ParameterError
from driveid.identify.core._plausibility import plausibility_checked
from driveid.identify.core.estimate import Estimate, Parameter
from driveid.identify.free_decay.backbone import backbone_entries
from driveid.identify.free_decay.hilbert import check_oscillation
from driveid.io.record import Record, needs_uniform_sampling
from driveid.signal._blas import with_one_blas_thread
from driveid.signal.envelope import (
    block_decimate,
    block_decimation,
    block_mean_gain,
    longest_run,
    smooth_derivatives,
    weighted_slope,
)

__all__ = ["morlet_transform", "estimate_wavelet", "scalogram", "MIN_PEAK_RATIO", "MAX_OMEGA_C"]

#: Least spectral peak magnitude, relative to the largest, that counts as a mode [-].
MIN_PEAK_RATIO = 1e-2

#: Largest automatic wavelet centre frequency [-]; closer modes need a longer record.
MAX_OMEGA_C = 40.0


def morlet_transform(
    x: np.ndarray, fs: float, dilations: np.ndarray | float, *, omega_c: float, step: int = 1
) -> np.ndarray:
    """Morlet wavelet transform by FFT, normalised as de Marchi (1998) Eq. (2.244).

    Parameters
    ----------
    x : ndarray, shape (n,)
        Real signal [unit].
    fs : float
        Sampling rate [Hz].
    dilations : float or ndarray, shape (m,)
        Dilations ``a`` [s]; the wavelet centred at ``omega_c / a`` [rad/s].
    omega_c : float
        Centre frequency of the mother wavelet (2.235) [-]; >= 3 keeps the negative-frequency
        leakage below ``exp(-2 omega_c²)``.
    step : int
        Output decimation [samples], >= 1: ``W`` at the samples ``0, step, 2 step, ...``
        only (exactly those values, not a filtered resampling).

    Returns
    -------
    ndarray of complex, shape (m, ceil(n / step)) or (ceil(n / step),)
        ``W(a, t)``; for ``x = A cos(omega t)`` and ``a = omega_c/omega``,
        ``W = sqrt(a) A exp(j omega t) / 2``.

    Notes
    -----
    O(n log n) time and O(n) memory whatever the number of dilations: one real FFT of the
    zero-padded record (padding ``8 a`` [s] past the end, beyond which the Gaussian window
    is below ``exp(-32)``, so the circular wrap is negligible), then per dilation only the
    bins where the filter ``G`` exceeds ``exp(-37)`` (about ``17/a`` rad/s wide) are
    multiplied, folded modulo ``nfft/step`` (time decimation by ``step`` is exactly
    spectral folding) and inverse transformed on ``nfft/step`` points.

    Examples
    --------
    >>> t = np.arange(2000) / 100.0
    >>> w = morlet_transform(np.cos(2 * np.pi * t), 100.0, 5.0 / (2 * np.pi), omega_c=5.0)
    >>> round(float(2 * abs(w[1000]) / np.sqrt(5.0 / (2 * np.pi))), 6)
    1.0
    """
    from scipy import fft as _fft

    x = np.asarray(x, dtype=float)
    a = np.atleast_1d(np.asarray(dilations, dtype=float))
    step = int(step)
    if step < 1:
        raise ParameterError(f"step must be a positive number of samples; got {step}")
    n = x.size
    need = n + int(math.ceil(8 * a.max() * fs)) + 1
    nfft = step * _fft.next_fast_len(-(-need // step), real=True)
    fold = nfft // step
    spec = _fft.rfft(x, nfft)
    bin_w = 2 * np.pi * fs / nfft  # bin spacing [rad/s]
    n_out = -(-n // step)
    out = np.empty((a.size, n_out), dtype=complex)
    for i, ai in enumerate(a):
        # bins where exp(-(a w - omega_c)^2 / 2) > exp(-37), inside [-nfft/2, nfft/2)
        k_lo = max(int(math.floor((omega_c - 8.6) / ai / bin_w)), -(nfft // 2))
        k_hi = min(int(math.ceil((omega_c + 8.6) / ai / bin_w)), (nfft - 1) // 2)
        ks = np.arange(k_lo, k_hi + 1)
        band = np.where(ks >= 0, spec[np.abs(ks)], np.conj(spec[np.abs(ks)]))
        band *= math.sqrt(ai) * np.exp(-0.5 * (ai * bin_w * ks - omega_c) ** 2)
        idx = ks % fold
        folded = (np.bincount(idx, band.real, fold) + 1j * np.bincount(idx, band.imag, fold))
        out[i] = _fft.ifft(folded, overwrite_x=True)[:n_out] / step
    return out[0] if np.ndim(dilations) == 0 else out


def scalogram(
    x: np.ndarray, fs: float, omegas: np.ndarray, *, omega_c: float, step: int = 1
) -> np.ndarray:
    """Amplitude scalogram ``2|W|/sqrt(a)`` at the tuned dilations ``a = omega_c/omega``.

    Parameters
    ----------
    x : ndarray, shape (n,)
        Real signal [unit].
    fs : float
        Sampling rate [Hz].
    omegas : ndarray, shape (m,)
        Analysis frequencies [rad/s].
    omega_c : float
        Centre frequency of the mother wavelet [-].
    step : int
        Time decimation [samples] (see :func:`morlet_transform`).

    Returns
    -------
    ndarray, shape (m, ceil(n / step))
        Amplitude of the component at each frequency [unit of x] (2.249 with the factor 2)
        at the samples ``0, step, 2 step, ...``.

    Examples
    --------
    >>> t = np.arange(2000) / 100.0
    >>> s = scalogram(np.cos(2 * np.pi * t), 100.0, np.array([np.pi, 2 * np.pi]), omega_c=5.0)
    >>> bool(s[1, 1000] > 0.99 and s[0, 1000] < 0.01)
    True
    """
    a = omega_c / np.asarray(omegas, dtype=float)
    w = morlet_transform(x, fs, a, omega_c=omega_c, step=step)
    return 2 * np.abs(w) / np.sqrt(a)[:, None]


def _mode_frequencies(x: np.ndarray, fs: float, modes: int, omega_min: float) -> np.ndarray:
    """Return the frequencies [rad/s] of the ``modes`` largest spectral peaks."""
    n = 4 * x.size
    # taper only the last quarter: a free decay carries its energy at the start, which a
    # symmetric window would suppress, while the end taper removes truncation sidelobes
    window = np.ones(x.size)
    m = x.size // 4
    window[x.size - m :] = 0.5 * (1 + np.cos(np.pi * np.arange(1, m + 1) / m))
    spec = np.abs(np.fft.rfft((x - x.mean()) * window, n))
    freq = 2 * np.pi * np.fft.rfftfreq(n, 1.0 / fs)
    spec[freq < omega_min] = 0.0
    peaks, _ = find_peaks(spec)
    peaks = peaks[spec[peaks] >= MIN_PEAK_RATIO * spec.max()]
    if peaks.size < modes:
        raise IdentificationError(
            f"the spectrum shows {peaks.size} peak(s) above {MIN_PEAK_RATIO:g} of the largest;"
            f" the record holds fewer than modes={modes} modes; lower modes; got peaks at "
            f"{np.round(freq[peaks] / (2 * np.pi), 3).tolist()} Hz"
        )
    best = peaks[np.argsort(spec[peaks])[::-1][:modes]]
    return np.sort(freq[best])


@plausibility_checked
@needs_uniform_sampling("the wavelet transform")
@with_one_blas_thread
def estimate_wavelet(
    record: Record,
    *,
    modes: int = 1,
    omega_c: float | None = None,
    coi_factor: float = 3.0,
    min_snr: float = 10.0,
    iterations: int = 2,
    n_scales: int = 60,
    mass: float | None = None,
) -> Estimate:
    r"""Modal frequency and damping of a free decay by the Morlet wavelet transform.

    Parameters
    ----------
    record : Record
        Free decay of one or more modes, >= 20 samples per period of the highest mode.
    modes : int
        Number of modes to identify [-]; the most prominent spectral peaks.
    omega_c : float, optional
        Wavelet centre frequency [-]; by default 3 for one mode, otherwise large enough
        that each tuned wavelet passes a neighbouring mode at most ``exp(-12)``.
    coi_factor : float
        Half-width of the cone of influence in Gaussian standard deviations ``a`` [-].
    min_snr : float
        Least ratio of mode amplitude to in-band noise amplitude inside the window [-].
    iterations : int
        Dilation-tuning iterations (2.246) [-].
    n_scales : int
        Number of analysis frequencies of the scalogram (for ridges and figures) [-].
    mass : float, optional
        Inertia or mass J [kg·m² or kg] of the mode, only to express the backbone as a
        stiffness ``K_eff = J omega0²``; without it the stiffness is per unit inertia.

    Returns
    -------
    Estimate
        For one mode ``omega0`` [rad/s] and ``zeta`` [-]; for several ``omega0_1``,
        ``zeta_1``, ``omega0_2`` ... in increasing frequency. ``data_used["modes"]`` is a list
        of dicts with ``t``, ``omega0``, ``zeta``, ``omega_d``, ``sigma``, ``amplitude``,
        ``window`` [s], ``dilation`` [s], ``ridge`` (scalogram ridge frequency [rad/s]),
        ``backbone`` and ``backbone_fit`` (binned ``omega0(A)``, ``K_eff(A)``, fit
        ``K0 + K2 A²`` and verdict; :mod:`driveid.identify.free_decay.backbone`);
        ``data_used["scalogram"]`` holds ``omegas`` and ``amplitude`` (decimated in time).
        For one mode the mode's entries are also at the top level of ``data_used``.

    Raises
    ------
    RecordError
        Record shorter than 4 periods.
    IdentificationError
        Non-oscillating or too noisy record, fewer modes than requested, or a window shorter
        than one period for some mode.
    ParameterError
        ``modes < 1``, ``omega_c < 3`` or other non-positive options.

    Notes
    -----
    Summary values come from a straight-line fit of the unwrapped phase of ``W``
    (:math:`\omega_d`) and a weighted fit of :math:`\ln|W|` (:math:`\sigma`, weights
    :math:`|W|^2`) over the valid window; the instantaneous series use Savitzky-Golay
    derivatives over one period. See the module docstring for the equations and errata.
    A record with more than 1000 samples per period of the dominant mode is first averaged
    in blocks of ``q`` samples down to >= 500 per period
    (:func:`driveid.signal.envelope.block_decimate`; ``diagnostics["decimation"]`` = q),
    and each mode's amplitude is divided by the block mean's gain at its frequency; modes
    above ~25 times the dominant frequency would then have < 20 samples per period.

    Examples
    --------
    >>> t = np.arange(4000) / 200.0
    >>> x = np.exp(-0.25 * t) * np.cos(4 * np.pi * t)
    >>> est = estimate_wavelet(Record(t=t, x=x))
    >>> round(est.value("omega0"), 3), round(est.value("zeta"), 4)
    (12.569, 0.0199)
    """
    if int(modes) != modes or modes < 1:
        raise ParameterError(f"modes must be a positive integer; got {modes!r}")
    if omega_c is not None and not omega_c >= 3.0:
        raise ParameterError(
            f"omega_c must be >= 3 so that the Morlet wavelet is nearly analytic; got {omega_c!r}"
        )
    for name, value in (("coi_factor", coi_factor), ("min_snr", min_snr)):
        if not (math.isfinite(value) and value > 0):
            raise ParameterError(f"{name} must be positive and finite; got {value!r}")
    if mass is not None and not (math.isfinite(mass) and mass > 0):
        raise ParameterError(
            f"mass must be a positive inertia [kg·m² or kg] or None; got {mass!r}")
    if int(iterations) != iterations or iterations < 1:
        raise ParameterError(f"iterations must be a positive integer; got {iterations!r}")
    osc = check_oscillation(record, min_snr=min_snr)
    # oversampled records are boxcar-decimated to >= 500 samples per period of the
    # dominant mode (memory and time); white noise keeps its density, std / sqrt(q)
    q = block_decimation(record.fs, osc.omega)
    if q > 1:
        fs, t, x = record.fs / q, block_decimate(record.t, q), block_decimate(osc.x, q)
    else:
        fs, t, x = record.fs, record.t, osc.x
    noise = osc.noise / math.sqrt(q)
    omega_min = 2 * np.pi * 2.0 / record.duration
    omegas = _mode_frequencies(x, fs, int(modes), omega_min)
    if omega_c is None:
        if modes == 1:
            omega_c = 3.0
        else:
            sep = float(np.min(1.0 - omegas[:-1] / omegas[1:]))
            omega_c = max(5.0, math.sqrt(2 * 12.0) / sep)
            if omega_c > MAX_OMEGA_C:
                raise IdentificationError(
                    f"modes closer than {math.sqrt(24.0) / MAX_OMEGA_C:.3g} relative frequency"
                    f" need omega_c > {MAX_OMEGA_C:g} to separate; pass omega_c= explicitly "
                    f"with a long record, or fewer modes; got modes at "
                    f"{np.round(omegas / (2 * np.pi), 4).tolist()} Hz"
                )
    grid = np.geomspace(omegas[0] / 2, min(omegas[-1] * 2, np.pi * fs * 0.8), n_scales)
    # the scalogram serves ridges and figures: a few hundred instants, not every sample
    step = max(1, t.size // 400)
    scal = scalogram(x, fs, grid, omega_c=omega_c, step=step)
    params: dict[str, Parameter] = {}
    mode_data: list[dict[str, Any]] = []
    for k, w_init in enumerate(omegas):
        res = _identify_mode(t, x, fs, w_init, omega_c=omega_c, coi_factor=coi_factor,
                             min_snr=min_snr, noise=noise, iterations=int(iterations))
        if q > 1:  # the boxcar's gain at the mode's frequency
            res["amplitude"] = res["amplitude"] / block_mean_gain(res["omega_d"], q, record.fs)
        # ridge search band: +-2 standard deviations of the wavelet's Gaussian passband,
        # and not past the geometric midpoint to a neighbouring mode
        band = np.abs(np.log(grid / w_init)) < 2.0 / omega_c
        if modes > 1:
            mids = np.sqrt(omegas[:-1] * omegas[1:])
            lo = mids[k - 1] if k > 0 else 0.0
            hi = mids[k] if k < modes - 1 else np.inf
            band &= (grid > lo) & (grid < hi)
        idx = np.flatnonzero(band) if band.any() else np.array([np.argmin(abs(grid - w_init))])
        i0, i1 = res["window_index"]
        # ridge at the scalogram's instants, held to the nearest one at every sample
        near = np.clip(np.rint(np.arange(i0, i1) / step).astype(int), 0, scal.shape[1] - 1)
        res["ridge"] = grid[idx[np.argmax(scal[idx], axis=0)]][near]
        res["backbone"], res["backbone_fit"] = backbone_entries(
            res["t"], res["amplitude"], res["omega0"],
            mass=mass, units=(record.units["x"], record.units["u"]))
        suffix = "" if modes == 1 else f"_{k + 1}"
        params["omega0" + suffix] = Parameter(res.pop("omega0_value"), res.pop("omega0_err"),
                                              "rad/s")
        params["zeta" + suffix] = Parameter(res.pop("zeta_value"), res.pop("zeta_err"), "-")
        mode_data.append(res)
    data_used: dict[str, Any] = {
        "modes": mode_data,
        "scalogram": {"t": t[::step], "omegas": grid, "amplitude": scal},
        "omega_c": omega_c,
    }
    if modes == 1:
        data_used.update({key: mode_data[0][key] for key in
                          ("t", "omega0", "zeta", "amplitude", "window", "window_index",
                           "backbone", "backbone_fit")})
    diagnostics: dict[str, Any] = {"omega_c": omega_c, "noise_std": osc.noise, "snr": osc.snr,
                                   "decimation": q}
    for k, m in enumerate(mode_data):
        suffix = "" if modes == 1 else f"_{k + 1}"
        diagnostics["window_start" + suffix], diagnostics["window_stop" + suffix] = m["window"]
        diagnostics["backbone_verdict" + suffix] = m["backbone_fit"]["verdict"]
        diagnostics["backbone_p_value" + suffix] = m["backbone_fit"].get("p_value", math.nan)
    return Estimate(method="wavelet-morlet", params=params, data_used=data_used,
                    diagnostics=diagnostics)


def _identify_mode(
    t: np.ndarray, x: np.ndarray, fs: float, w_init: float, *, omega_c: float,
    coi_factor: float, min_snr: float, noise: float, iterations: int,
) -> dict[str, Any]:
    """Tune the dilation to one mode (2.246), extract its ridge quantities and summary."""
    wd = w_init
    for _ in range(iterations + 1):
        a = omega_c / wd
        w = morlet_transform(x, fs, a, omega_c=omega_c)
        coi = coi_factor * a
        mag = np.abs(w)
        # in-band noise amplitude of white noise through the filter sqrt(a) G (Parseval)
        # white noise through sqrt(a) G: E|W|^2 = noise^2 a mean(G^2) = noise^2 sqrt(pi)/(2 pi fs)
        noise_w = noise * math.sqrt(math.sqrt(math.pi) / (2 * math.pi * fs))
        mask = (t >= t[0] + coi) & (t <= t[-1] - coi) & (mag > min_snr * noise_w)
        i0, i1 = longest_run(mask)
        period = 2 * np.pi / wd
        if (i1 - i0) / fs < period:
            raise IdentificationError(
                f"the valid window of the mode near {wd / (2 * np.pi):.4g} Hz (outside the cone"
                f" of influence, {coi_factor:g} a = {coi:.3g} s at each end, and above "
                f"{min_snr:g} x in-band noise) must span at least one period; record longer "
                f"or with less noise; got {(i1 - i0) / fs:.3g} s"
            )
        sl = slice(i0, i1)
        tw = t[sl]
        n_eff = max((tw[-1] - tw[0]) / period, 3.0)
        phase = np.unwrap(np.angle(w[sl]))
        wd_new, wd_err = weighted_slope(tw, phase, mag[sl] ** 2, n_eff)
        if not wd_new > 0:
            raise IdentificationError(
                f"the wavelet phase must advance for an oscillating mode; got omega_d = {wd_new}"
            )
        wd = wd_new
    slope, s_err = weighted_slope(tw, np.log(mag[sl]), mag[sl] ** 2, n_eff)
    sigma = -slope
    w0 = math.hypot(wd, sigma)
    window = int(round(period * fs))
    _, omega_t, _ = smooth_derivatives(phase, fs, window)
    _, dlnw, _ = smooth_derivatives(np.log(mag[sl]), fs, window)
    sigma_t = -dlnw
    omega0_t = np.hypot(omega_t, sigma_t)
    # gain of the tuned wavelet on a decaying mode: exp(((a s - j omega_c)^2)/2) with
    # s = -sigma + j omega_d, i.e. (2.247) plus the a^2 sigma^2/2 term of the decay
    gain = np.exp(-0.5 * (a * omega_t - omega_c) ** 2 + 0.5 * (a * sigma_t) ** 2)
    return {
        "t": tw, "omega0": omega0_t, "zeta": sigma_t / omega0_t, "omega_d": omega_t,
        "sigma": sigma_t, "amplitude": 2 * mag[sl] / (math.sqrt(a) * gain),
        "window": (float(tw[0]), float(tw[-1])), "window_index": (i0, i1), "dilation": a,
        "omega0_value": w0, "omega0_err": math.hypot(wd * wd_err, sigma * s_err) / w0,
        "zeta_value": sigma / w0, "zeta_err": s_err / w0,
    }
