r"""Hilbert-transform identification: FREEVIB, FORCEVIB and envelope damping separation.

Implements de Marchi (1998) §2.2.8-§2.2.9, Eqs. (2.195)-(2.226), which restate Feldman's
FREEVIB [2]_ (free response) and FORCEVIB [3]_ (forced response). From the analytic signal
:math:`x_a = A e^{j\phi}` (2.195) of the displacement, with decay rate
:math:`\sigma = -\dot A/A` (2.223) and instantaneous frequency :math:`\omega = \dot\phi`
(2.214), and the complex ratio :math:`\alpha + j\beta = u_a / x_a` of the analytic force to
the analytic displacement, the instantaneous undamped natural frequency and decay are

.. math::

    \omega_0^2 = \omega^2 + \sigma^2 + \dot\sigma - \frac{\sigma\dot\omega}{\omega}
                 + \frac{1}{J}\Big(\alpha + \frac{\sigma\beta}{\omega}\Big), \qquad
    h = \zeta\omega_0 = \sigma - \frac{\dot\omega}{2\omega} + \frac{\beta}{2J\omega},

which with :math:`\sigma = -\dot A/A` is exactly Feldman's result.

Errata of the thesis (derived here; checked by the tests in
``tests/identify/test_hilbert.py``, which recover known :math:`\omega_0, \zeta`):

* (2.215) prints :math:`\dot\theta_a = -s\theta_a` and :math:`\ddot\theta_a = (s^2-\dot s)\theta_a`;
  differentiating (2.198) gives :math:`\dot\theta_a = s\theta_a`,
  :math:`\ddot\theta_a = (s^2+\dot s)\theta_a`.
* (2.224) prints :math:`s = -\dot\theta_a/\theta_a`; with the corrected (2.215)
  :math:`s = \dot\theta_a/\theta_a`, so :math:`\sigma = -\mathrm{Re}(\dot\theta_a/\theta_a)`
  and :math:`\omega = \mathrm{Im}(\dot\theta_a/\theta_a)` (2.225).
* (2.218) prints :math:`s^2 = (\sigma+j\omega)^2 = (\sigma^2-\omega^2) + 2j\omega`; with
  (2.199) :math:`s = -\sigma + j\omega`, so :math:`s^2 = \sigma^2-\omega^2 - 2j\sigma\omega`.
* (2.222a): the terms :math:`(\sigma\dot\omega-\dot\sigma\omega)/\omega` and
  :math:`-(\sigma/\omega)\,\mathrm{Im}` have the wrong sign; the imaginary part of
  :math:`s^2+\dot s+2h s+\omega_0^2 = u_a/(J x_a)` gives the form above.
* (2.222b) prints :math:`\zeta\omega_0 = -(\sigma + \dot\omega/2\omega) + \dots`; the sign of
  :math:`\sigma` is wrong (a free decay would get negative damping).
* (2.230b) prints :math:`\zeta\omega_0 = \mathrm{Im}/(4\omega_d)`, which is zero for a free
  decay; (2.222b) with :math:`\dot\omega = 0` gives :math:`\sigma + \beta/(2J\omega_d)`.

Instead of the ratios of analytic-signal derivatives (2.226), which amplify noise, the
derivatives are taken of :math:`\ln A` and of the unwrapped phase after a one-period boxcar
(the low-pass Feldman applies; it removes the :math:`2\omega` ripple), by Savitzky-Golay
filters over one period. The ends are handled by model padding
(:func:`driveid.signal.envelope.analytic_signal`) and by the valid window.

References
----------
.. [1] J. A. de Marchi, "Modeling of dynamic friction, impact backlash and elastic
       compliance nonlinearities in machine tools", PhD thesis, RPI, 1998.
.. [2] M. Feldman, "Non-linear system vibration analysis using Hilbert transform - I. Free
       vibration analysis method 'FREEVIB'", Mech. Syst. Signal Process. 8(2), 119-127,
       1994. doi:10.1006/mssp.1994.1011
.. [3] M. Feldman, "Non-linear system vibration analysis using Hilbert transform - II.
       Forced vibration analysis method 'FORCEVIB'", Mech. Syst. Signal Process. 8(3),
       309-318, 1994. doi:10.1006/mssp.1994.1023
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.ndimage import uniform_filter1d

from driveid.errors import IdentificationError, ParameterError, RecordError
from driveid.identify.core._plausibility import plausibility_checked
from driveid.identify.core.estimate import Estimate, Parameter
from driveid.identify.free_decay.backbone import backbone_entries
from driveid.identify.free_decay.envelope_friction import (
    _DRIFT_RIPPLE_PERIODS,
    _crossings,
    _fit_phasor,
    _limit_cycle_phasor,
)
from driveid.io.record import Record, needs_uniform_sampling
from driveid.signal._blas import with_one_blas_thread
from driveid.signal.envelope import (
    analytic_signal,
    block_decimate,
    block_decimation,
    count_crossings,
    cycle_phasor,
    dominant_frequency,
    longest_run,
    noise_std,
    smooth_derivatives,
    weighted_slope,
)

__all__ = [
    "estimate_hilbert",
    "estimate_envelope_damping",
    "check_oscillation",
    "Oscillation",
    "MIN_PERIODS",
    "DYNAMIC_RANGE",
]

#: Fewest oscillation periods a record must span [-].
MIN_PERIODS = 4.0

#: Smallest envelope, relative to its maximum, used even on noise-free data [-]: the padded
#: FFT Hilbert transform leaves absolute errors of ~1e-5 of the largest amplitude.
DYNAMIC_RANGE = 1e-2


@dataclass(frozen=True)
class Oscillation:
    """Basic facts of a checked record (see :func:`check_oscillation`).

    Attributes
    ----------
    x : ndarray, shape (n,)
        Position with its midline offset removed [m or rad].
    omega : float
        Dominant angular frequency [rad/s].
    noise : float
        Estimated white-noise standard deviation [m or rad].
    snr : float
        Peak amplitude over noise standard deviation [-].
    """

    x: np.ndarray
    omega: float
    noise: float
    snr: float


@dataclass(frozen=True)
class _Instantaneous:
    """Instantaneous quantities over the valid window [i0, i1)."""

    i0: int
    i1: int
    t: np.ndarray
    amplitude: np.ndarray
    omega: np.ndarray
    sigma: np.ndarray
    omega0: np.ndarray
    h: np.ndarray
    phase: np.ndarray
    mass: float
    forced: bool
    osc: Oscillation
    ripple_max: float
    decimation: int


def check_oscillation(record: Record, *, min_snr: float) -> Oscillation:
    """Check that a record oscillates long and cleanly enough for instantaneous methods.

    Parameters
    ----------
    record : Record
        The record.
    min_snr : float
        Least ratio of peak amplitude to noise standard deviation [-].

    Returns
    -------
    Oscillation
        Centred position, dominant frequency, noise level and SNR.

    Raises
    ------
    RecordError
        Corrupted bursts, or fewer than :data:`MIN_PERIODS` periods.
    IdentificationError
        Fewer than 3 zero crossings beyond the noise band, or SNR below ``min_snr``.
    """
    if record.corrupted:
        raise RecordError(
            f"record has corrupted bursts at samples {list(record.corrupted)[:3]}; crop them "
            "with Record.crop before identification"
        )
    x = record.x - np.mean(record.x)
    omega_guess = dominant_frequency(x, record.fs)
    if omega_guess > 0:
        # the record mean is biased by a decay; the median of the one-period moving
        # average (the midline) is not, to first order
        period_n = max(int(round(2 * np.pi / omega_guess * record.fs)), 1)
        x -= float(np.median(uniform_filter1d(x, period_n, mode="nearest")))
    noise = noise_std(x)
    peak = float(np.max(np.abs(x)))
    if peak == 0.0:
        raise IdentificationError(
            "the record does not oscillate: x is constant; record a free or forced vibration"
            f" response; got max |x - mean| = {peak}"
        )
    crossings = count_crossings(x, 3.0 * noise + 1e-9 * peak)
    if crossings < 3:
        raise IdentificationError(
            "the record does not oscillate: an oscillation needs at least 3 zero crossings "
            "beyond the noise band; use a method for non-oscillating data or excite the "
            f"system harder; got {crossings} crossing(s)"
        )
    omega = dominant_frequency(x, record.fs)
    periods = record.duration * omega / (2 * np.pi)
    if periods < MIN_PERIODS:
        # a held release or a stuck end puts the spectrum's peak at the step, not at the
        # oscillation: 'record for longer' alone was the wrong fix (fifth hostile campaign)
        raise RecordError(
            f"the record must span at least {MIN_PERIODS:g} periods of the oscillation for "
            f"instantaneous identification; got {periods:.2g} periods at its largest "
            f"spectral peak ({omega / (2 * np.pi):.3g} Hz): crop a rest before or after the "
            "oscillation (a held release, a stuck end) with --t-start/--t-end, or record "
            "for longer"
        )
    snr = peak / noise if noise > 0 else math.inf
    if snr < min_snr:
        raise IdentificationError(
            f"the record is too noisy: peak amplitude / noise std must be >= {min_snr:g} "
            f"(min_snr); filter the record or excite harder; got {snr:.3g}"
        )
    return Oscillation(x=x, omega=omega, noise=noise, snr=snr)


def _check_options(mass, **positive) -> None:
    """Raise ParameterError unless every option is positive and finite and mass is valid."""
    for name, value in positive.items():
        if not (math.isfinite(value) and value > 0):
            raise ParameterError(f"{name} must be positive and finite; got {value!r}")
    if mass is not None and not (math.isfinite(mass) and mass > 0):
        raise ParameterError(
            f"mass must be a positive inertia [kg·m² or kg] or None; got {mass!r}"
        )


def _instantaneous(
    record: Record,
    *,
    mass: float | None,
    forced: bool | None,
    smoothing_periods: float,
    trim_periods: float,
    ripple_threshold: float,
    min_snr: float,
) -> _Instantaneous:
    """Compute FREEVIB / FORCEVIB instantaneous parameters and the valid window."""
    _check_options(mass, smoothing_periods=smoothing_periods, trim_periods=trim_periods,
                   ripple_threshold=ripple_threshold, min_snr=min_snr)
    osc = check_oscillation(record, min_snr=min_snr)
    q = block_decimation(record.fs, osc.omega)
    if q > 1:  # oversampled: boxcar-decimate to >= 500 samples per period (memory, time)
        x, t, fs = block_decimate(osc.x, q), block_decimate(record.t, q), record.fs / q
        u = None if record.u is None else block_decimate(record.u, q)
    else:
        x, t, fs, u = osc.x, record.t, record.fs, record.u
    period = 2 * np.pi / osc.omega
    z = analytic_signal(x, fs, omega=osc.omega)
    amplitude = np.abs(z)
    if np.any(amplitude <= 0):
        raise IdentificationError("the envelope reaches zero; the record holds no oscillation "
                                  "there; crop the record; got A(t) = 0")
    window = int(round(smoothing_periods * period * fs))
    # a one-period boxcar removes the 2-omega ripple (Feldman's low-pass) exactly for a
    # stationary period; the Savitzky-Golay filter then differentiates
    boxcar = max(int(round(period * fs)), 1)
    lna, dlna, d2lna = smooth_derivatives(
        _period_mean(np.log(amplitude), boxcar), fs, window)
    phase, omega, domega = smooth_derivatives(
        _period_mean(np.unwrap(np.angle(z)), boxcar), fs, window)
    sigma, dsigma = -dlna, -d2lna
    use_force = u is not None and np.any(u != 0) if forced is None else forced
    if use_force and u is None:
        raise RecordError("forced=True needs a force column 'u' in the record; got none")
    with np.errstate(divide="ignore", invalid="ignore"):
        free_part = omega**2 + sigma**2 + dsigma - sigma * domega / omega
    if use_force:
        ua = analytic_signal(u - np.mean(u), fs, omega=osc.omega)
        ratio = ua / z
        alpha = smooth_derivatives(ratio.real, fs, window)[0]
        beta = smooth_derivatives(ratio.imag, fs, window)[0]
        force_part = alpha + sigma * beta / omega
    amp_smooth = np.exp(lna)
    ripple = uniform_filter1d(np.abs(amplitude / amp_smooth - 1.0), max(window, 1))
    trim = trim_periods * period
    mask = (
        (t >= t[0] + trim) & (t <= t[-1] - trim) & (ripple < ripple_threshold)
        & (amp_smooth > max(min_snr * osc.noise, DYNAMIC_RANGE * amp_smooth.max()))
        & (omega > 0)
    )
    i0, i1 = longest_run(mask)
    if (i1 - i0) / fs < period:
        raise IdentificationError(
            "the valid window (after trimming the ends and dropping samples whose envelope "
            f"ripple exceeds {ripple_threshold:g} or whose amplitude is below {min_snr:g} x "
            "noise) must span at least one period; record longer or with less noise; got "
            f"{(i1 - i0) / fs:.3g} s against a period of {period:.3g} s"
        )
    sl = slice(i0, i1)
    if use_force:
        J = mass if mass is not None else _feldman_mass(free_part[sl], force_part[sl])
        omega0_sq = free_part + force_part / J
        h = sigma - domega / (2 * omega) + beta / (2 * J * omega)
    else:
        J = mass if mass is not None else math.nan
        omega0_sq = free_part
        h = sigma - domega / (2 * omega)
    omega0 = np.sqrt(np.clip(omega0_sq, 0.0, None))
    return _Instantaneous(
        i0=i0, i1=i1, t=t[sl], amplitude=amp_smooth[sl], omega=omega[sl], sigma=sigma[sl],
        omega0=omega0[sl], h=h[sl], phase=phase[sl], mass=J, forced=bool(use_force), osc=osc,
        ripple_max=float(np.max(ripple[sl])), decimation=q,
    )


def _period_mean(y: np.ndarray, n: int) -> np.ndarray:
    """Average over ``n`` samples with point-reflected ends (keeps linear trends)."""
    n = max(min(int(n), y.size - 1), 1)
    left = 2 * y[0] - y[n:0:-1]
    right = 2 * y[-1] - y[-2 : -n - 2 : -1]
    padded = np.concatenate([left, y, right])
    return uniform_filter1d(padded, n, mode="nearest")[n : n + y.size]


def _feldman_mass(free_part: np.ndarray, force_part: np.ndarray) -> float:
    """Inertia from FORCEVIB's assumption that omega0 varies slowly [2, Eq. (5)].

    ``omega0² = P + Q/J`` with ``P`` the free part and ``Q`` the force part. Feldman writes
    this at two close instants and eliminates ``omega0``; here the same assumption is applied
    over the whole valid window, ``P = omega0² - Q/J`` by least squares, which differentiates
    nothing and so amplifies no noise.
    """
    q = force_part - force_part.mean()
    var_q = float(q @ q)
    # a stationary response leaves only numerical ripple (~1e-6) in Q
    variation = math.sqrt(var_q / q.size) / max(abs(float(force_part.mean())), 1e-300)
    if variation <= 1e-4:
        raise IdentificationError(
            "the inertia cannot be estimated: the force/response ratio must vary over the "
            "record (e.g. a sweep or a transient); pass mass= instead; got a stationary "
            f"response (relative variation {variation:.2g})"
        )
    inv_j = -float(q @ (free_part - free_part.mean())) / var_q
    if not inv_j > 0:
        raise IdentificationError(
            "the inertia estimated by FORCEVIB (Feldman's Eq. 5) must be positive; pass "
            f"mass= instead; got 1/J = {inv_j:.3g}"
        )
    return 1.0 / inv_j


@plausibility_checked
@needs_uniform_sampling("the Hilbert transform")
@with_one_blas_thread
def estimate_hilbert(
    record: Record,
    *,
    mass: float | None = None,
    forced: bool | None = None,
    smoothing_periods: float = 1.0,
    trim_periods: float = 1.0,
    ripple_threshold: float = 0.1,
    min_snr: float = 10.0,
) -> Estimate:
    r"""Instantaneous natural frequency and damping by the Hilbert transform (FREEVIB/FORCEVIB).

    Parameters
    ----------
    record : Record
        Free decay (``u`` absent or zero) or forced response (force/torque ``u``) of a single
        mode, sampled at >= 20 samples per period, spanning >= 4 periods.
    mass : float, optional
        Inertia or mass J [kg·m² or kg]. Free response: only scales the damping curve (without
        it the curve is mass-normalised). Forced response: estimated by Feldman's rule when
        omitted.
    forced : bool, optional
        Use FORCEVIB; by default when ``record.u`` is present and non-zero.
    smoothing_periods : float
        Savitzky-Golay window for the derivatives [periods].
    trim_periods : float
        Dropped at each end of the record [periods] (Hilbert end effects).
    ripple_threshold : float
        Largest allowed relative envelope ripple, averaged over a window [-].
    min_snr : float
        Least peak-amplitude / noise ratio of the record and least envelope / noise ratio
        inside the valid window [-].

    Returns
    -------
    Estimate
        ``omega0`` [rad/s] and ``zeta`` [-] over the valid window. Free response: from
        weighted straight-line fits of the unwrapped phase (:math:`\omega_d`) and of
        :math:`\ln A` (:math:`\sigma`, weights :math:`A^2`), :math:`\omega_0 =
        \sqrt{\omega_d^2+\sigma^2}`, :math:`\zeta = \sigma/\omega_0` (2.143, 2.150); forced:
        medians of the instantaneous values (and ``J`` when estimated). ``data_used`` holds
        ``t``, ``omega0``, ``zeta``, ``amplitude``, ``omega``, ``sigma``, ``backbone``
        (binned ``omega0(A)`` and ``K_eff(A) = J omega0²`` with standard errors,
        :meth:`driveid.identify.free_decay.backbone.Backbone.to_dict`, or None for too short a
        window), ``backbone_fit`` (``K_eff = K0 + K2 A²``, p-value, verdict
        hardening/softening/constant; :mod:`driveid.identify.free_decay.backbone`),
        ``damping_curve`` (amplitude, damping force ``2 J h omega A``) and ``window`` [s].

    Raises
    ------
    RecordError
        Record shorter than 4 periods or with corrupted bursts.
    IdentificationError
        Non-oscillating or too noisy record, or no valid window.
    ParameterError
        Non-positive options or mass.

    Notes
    -----
    The instantaneous formulas, and errata of Eqs. (2.215), (2.218), (2.222) and (2.230) of
    de Marchi (1998), are in the module docstring. The valid window drops ``trim_periods``
    at each end, samples whose envelope ripple exceeds ``ripple_threshold``, and samples whose
    envelope is below ``min_snr`` times the noise; the longest remaining run is used.
    A record with more than 1000 samples per period is first averaged in blocks of ``q``
    samples down to >= 500 per period (:func:`driveid.signal.envelope.block_decimate`,
    boxcar anti-alias filter, gain ``1 - 7e-6`` at the mode; ``diagnostics["decimation"]``
    = q): the series in ``data_used`` are then at ``fs / q`` and ``window_index`` counts
    decimated samples. This bounds memory and time on long records (issue 12).

    Examples
    --------
    >>> t = np.arange(3000) / 200.0
    >>> wd, s = 2 * np.pi * 2.0, 0.25
    >>> est = estimate_hilbert(Record(t=t, x=np.exp(-s * t) * np.cos(wd * t)))
    >>> round(est.value("omega0"), 3), round(est.value("zeta"), 4)
    (12.569, 0.0199)
    """
    inst = _instantaneous(
        record, mass=mass, forced=forced, smoothing_periods=smoothing_periods,
        trim_periods=trim_periods, ripple_threshold=ripple_threshold, min_snr=min_snr,
    )
    period = 2 * np.pi / inst.osc.omega
    n_eff = max((inst.t[-1] - inst.t[0]) / period, 3.0)
    zeta_t = inst.h / inst.omega0
    params: dict[str, Parameter] = {}
    if inst.forced:
        w0, z0 = float(np.median(inst.omega0)), float(np.median(zeta_t))
        params["omega0"] = Parameter(w0, float(np.std(inst.omega0) / np.sqrt(n_eff)), "rad/s")
        params["zeta"] = Parameter(z0, float(np.std(zeta_t) / np.sqrt(n_eff)), "-")
        if mass is None:
            params["J"] = Parameter(inst.mass, math.nan,
                                    f"{record.units['u']}·s²/{record.units['x']}")
    else:
        wd, wd_err = weighted_slope(inst.t, inst.phase, inst.amplitude**2, n_eff)
        slope, s_err = weighted_slope(inst.t, np.log(inst.amplitude), inst.amplitude**2,
                                      n_eff)
        sigma = -slope
        w0 = math.hypot(wd, sigma)
        params["omega0"] = Parameter(w0, math.hypot(wd * wd_err, sigma * s_err) / w0, "rad/s")
        params["zeta"] = Parameter(sigma / w0, s_err / w0, "-")
    J = inst.mass if math.isfinite(inst.mass) else 1.0
    damping_force = 2.0 * J * inst.h * inst.omega * inst.amplitude
    curve, fit = backbone_entries(
        inst.t, inst.amplitude, inst.omega0,
        mass=inst.mass if math.isfinite(inst.mass) else None,
        units=(record.units["x"], record.units["u"]))
    data_used: dict[str, Any] = {
        "t": inst.t, "omega0": inst.omega0, "zeta": zeta_t, "amplitude": inst.amplitude,
        "omega": inst.omega, "sigma": inst.sigma, "backbone": curve, "backbone_fit": fit,
        "damping_curve": {"amplitude": inst.amplitude, "force": damping_force,
                          "mass_normalised": not math.isfinite(inst.mass)},
        "window": (float(inst.t[0]), float(inst.t[-1])),
        "window_index": (inst.i0, inst.i1),
    }
    diagnostics = {
        "window_start": float(inst.t[0]), "window_stop": float(inst.t[-1]),
        "n_window": int(inst.i1 - inst.i0), "noise_std": inst.osc.noise, "snr": inst.osc.snr,
        "ripple_max": inst.ripple_max, "forced": inst.forced, "decimation": inst.decimation,
        "backbone_verdict": fit["verdict"], "backbone_p_value": fit.get("p_value", math.nan),
    }
    return Estimate(method="hilbert-forcevib" if inst.forced else "hilbert-freevib",
                    params=params, data_used=data_used, diagnostics=diagnostics)


@plausibility_checked
@needs_uniform_sampling("the envelope (Hilbert transform)")
@with_one_blas_thread
def estimate_envelope_damping(
    record: Record,
    *,
    mass: float | None = None,
    trim_periods: float = 1.0,
    ripple_threshold: float = 0.1,
    min_snr: float = 10.0,
) -> Estimate:
    r"""Separate viscous and Coulomb damping by fitting the Hilbert envelope of a free decay.

    Parameters
    ----------
    record : Record
        Free decay of a single mode (``u`` absent or zero), >= 4 periods.
    mass : float, optional
        Inertia J [kg·m²] (or mass [kg]); without it ``c_mean`` and ``fk_mean`` are per unit
        inertia ([1/s] and [rad/s²] or [m/s²]).
    trim_periods : float
        Dropped at the start and, while the record still oscillates there, at the end
        [periods] (Hilbert end effects).
    ripple_threshold : float
        Largest allowed RMS misfit of the chosen envelope model, relative to the mean
        envelope [-]; a larger misfit means the record is not a single-mode viscous/Coulomb
        decay and raises :class:`~driveid.errors.IdentificationError`.
    min_snr : float
        Least peak-amplitude / noise ratio of the record [-].

    Returns
    -------
    Estimate
        ``c_mean``, ``fk_mean`` (zero without standard error when the chosen model lacks the
        term), ``omega0`` [rad/s]; ``data_used["models"]`` holds every model's parameters,
        AIC and fitted envelope, ``data_used["chosen"]`` the one with the least AIC;
        ``data_used["t"]`` and ``["amplitude"]`` the cycle-averaged envelope ``|Y|`` [s],
        [m or rad] fitted (decimated to ~64 samples per period).

    Raises
    ------
    RecordError
        Record shorter than 4 periods or with corrupted bursts.
    IdentificationError
        Non-oscillating or too noisy record, fewer than one period between the trimmed
        start and the end of motion, or a misfit above ``ripple_threshold``.
    ParameterError
        Non-positive options or mass.

    Notes
    -----
    The envelope is the complex one, :math:`Y(t)`: the analytic signal (2.195) demodulated
    at the oscillation frequency and averaged over one period
    (:func:`driveid.signal.envelope.cycle_phasor`); ``|Y|`` is the cycle-averaged
    instantaneous amplitude. With viscous + Coulomb friction the velocity reverses every
    half period whatever the amplitude, so the decay is a periodic friction part plus
    ``exp(-sigma t)`` times a periodic part (see ``_limit_cycle_phasor``), and because the
    average is linear in the signal

    .. math:: Y(t) = e^{j\Delta\omega t}\big(a + e^{-\sigma t}(b + c_{+}e^{j\omega t}
              + c_{-}e^{-j\omega t} + \dots)\big)

    up to the Hilbert transform's own end effects, whatever the asymmetry: the half-cycle
    alternation of the amplitude (which
    biases fits of :math:`|z|` or of :math:`\langle\ln|z|\rangle`) only leaves the small
    ripple terms :math:`c_\pm` (size :math:`\sim\sigma/\omega`), which are fitted. With
    ``c_delta != 0`` the mean of the decay drifts, and the Hilbert transform of that slow
    drift leaves a ripple of nearly constant amplitude; when the window spans at least
    four periods two non-decaying ripple terms are fitted as well. Models:
    viscous (``a = 0``), Coulomb (``sigma -> 0``: ``a + b t``) and combined; ``dw``,
    ``sigma`` by variable projection, the rest linear. Friction from the fitted phasors:
    ``c = 2 J sigma`` (with ``c_delta`` the decay rate per cycle is the half-period-weighted
    mean of ``(c_mean ± c_delta)/2J``, relatively higher by about
    ``(c_delta / (2 J omega0))²``: 0.2-0.6 % for Table 5.1 cases 1, 2 and 5); combined:
    ``fk = J omega0² d`` with ``d`` the projection of
    :math:`a\,\bar b/|b|` on the limit-cycle phasor per unit ``d`` (computed for symmetric
    damping; ``c_delta`` makes the true phasor differ by about
    :math:`(1+\rho_+)(1+\rho_-)/(1+\sqrt{\rho_+\rho_-})^2-1`, 0.5 % for Table 5.1 case 1);
    Coulomb: the envelope falls ``4 d`` per period, ``d = r T/4``. The fit runs from
    ``trim_periods`` after the start to half a period before the motion ends (the last
    midline crossing plus a quarter period; the record is cut there before the Hilbert
    transform, so the stop does not leak into it) or ``trim_periods`` before the record
    ends. Standard errors come from the Jacobian, inflated for the correlation of envelope
    samples (one independent sample per period); AIC uses the same count.

    Examples
    --------
    >>> t = np.arange(4000) / 200.0
    >>> x = np.exp(-0.1 * t) * np.cos(2 * np.pi * t)
    >>> est = estimate_envelope_damping(Record(t=t, x=x), mass=1.0)
    >>> est.data_used["chosen"], round(est.value("c_mean"), 3)
    ('viscous', 0.2)
    """
    _check_options(mass, trim_periods=trim_periods, ripple_threshold=ripple_threshold,
                   min_snr=min_snr)
    osc = check_oscillation(record, min_snr=min_snr)
    J = 1.0 if mass is None else float(mass)
    t, fs = record.t, record.fs
    peak = float(np.max(np.abs(osc.x)))
    t_last, omega = _crossings(osc.x, t, max(DYNAMIC_RANGE * peak, 5.0 * osc.noise))
    for final in (False, True):
        # the second pass demodulates at the refined frequency: the period average then
        # cancels the periodic parts exactly
        period = 2 * np.pi / omega
        stop = min(int(np.searchsorted(t, t_last + period / 4)), t.size)
        z = np.zeros(t.size, dtype=complex)
        z[:stop] = analytic_signal(osc.x[:stop], fs, omega=omega)
        y_all = cycle_phasor(z, fs, omega)
        t_stop = t[stop - 1] - period / 2
        t_end = min(t_stop, t[-1] - trim_periods * period)
        i0 = int(np.searchsorted(t, t[0] + trim_periods * period))
        i1 = int(np.searchsorted(t, t_end, side="right"))
        if i1 <= i0 or (t[i1 - 1] - t[i0]) < period:
            got = max(t[i1 - 1] - t[i0], 0.0) if i1 > i0 else 0.0
            raise IdentificationError(
                "the envelope window (after trimming the start and the last half period of "
                "motion) must span at least one period; record a longer or less damped "
                f"decay, or lower trim_periods; got {got:.3g} s against a period of "
                f"{period:.3g} s"
            )
        step = max(int(round(period * fs)) // 64, 1)
        idx = np.arange(i0, i1, step)
        tw = t[idx] - t[idx[0]]
        y = y_all[idx] * np.exp(1j * omega * (idx[0] / fs))  # phase origin at window start
        env = np.abs(y)
        sigma0 = max(math.log(env[0] / max(env[-1], 1e-300 + 1e-12 * env[0])) / tw[-1],
                     1e-2 / tw[-1])
        kinds = ("viscous", "coulomb", "combined") if final else ("combined",)
        drift = tw[-1] >= _DRIFT_RIPPLE_PERIODS * period
        fits = {k: _fit_phasor(k, tw, y, omega, sigma0, drift) for k in kinds}
        if not final:
            omega = omega + fits["combined"]["dw"]
    n_eff = max(tw[-1] / period, 1.0)
    models: dict[str, dict[str, Any]] = {}
    for kind, f in fits.items():
        k = f["p"].size
        s2 = f["rss"] / max(2 * y.size - k, 1)
        try:
            cov = np.linalg.inv(f["jac"].T @ f["jac"]) * s2 * y.size / n_eff
        except np.linalg.LinAlgError:
            cov = np.full((k, k), np.nan)
        f["cov"] = cov
        aic = n_eff * math.log(max(f["rss"] / y.size, 1e-300)) + 2 * k
        models[kind] = {"aic": aic, "fitted": np.abs(f["model"])}
    chosen = min(models, key=lambda m: models[m]["aic"])
    f = fits[chosen]
    w = omega + f["dw"]
    misfit = math.sqrt(f["rss"] / y.size) / float(np.mean(env))
    if misfit > ripple_threshold:
        raise IdentificationError(
            f"the envelope does not follow a viscous/Coulomb decay: relative RMS misfit "
            f"must be <= {ripple_threshold:g} (ripple_threshold); check that the record is a "
            f"single-mode free decay; got {misfit:.3g}"
        )

    def friction(kind: str, p: np.ndarray) -> tuple[float, float, float]:
        """(c, fk, omega0) from a full parameter vector of model ``kind``."""
        if kind == "coulomb":
            wk = omega + p[0]
            a, slope = p[1] + 1j * p[2], p[3] + 1j * p[4]
            rate = -float((slope * np.conj(a)).real) / abs(a)
            return 0.0, J * wk**2 * rate * (2 * np.pi / wk) / 4, wk
        s, wk = p[0], omega + p[1]
        w0 = math.hypot(wk, s)
        if kind == "viscous":
            return 2 * J * s, 0.0, w0
        a, b = p[2] + 1j * p[3], p[4] + 1j * p[5]
        per_d = _limit_cycle_phasor(s, w0)
        d = float((np.conj(per_d) * a * np.conj(b) / abs(b)).real) / abs(per_d) ** 2
        return 2 * J * s, J * w0**2 * d, w0

    p, cov = f["p"], f["cov"]
    c, fk, w0 = friction(chosen, p)
    grads = np.zeros((2, p.size))
    for i in range(p.size):
        dp = np.zeros(p.size)
        dp[i] = 1e-6 * max(abs(p[i]), 1e-3 * np.max(np.abs(p)))
        hi, lo = friction(chosen, p + dp), friction(chosen, p - dp)
        grads[:, i] = [(hi[0] - lo[0]) / (2 * dp[i]), (hi[1] - lo[1]) / (2 * dp[i])]
    c_err, fk_err = (float(np.sqrt(max(g @ cov @ g, 0.0))) for g in grads)
    if chosen == "viscous":
        fk_err = math.nan
    if chosen == "coulomb":
        c_err = math.nan
    for kind, fit in fits.items():
        kc, kfk, _ = friction(kind, fit["p"])
        models[kind]["params"] = {"sigma": fit["sigma"], "omega": omega + fit["dw"],
                                  "c_mean": kc, "fk_mean": kfk}
        models[kind]["stderr"] = {"sigma": float(np.sqrt(abs(fit["cov"][0, 0])))
                                  if kind != "coulomb" else math.nan}
    xu, uu = record.units["x"], record.units["u"]
    cu = f"{uu}·s/{xu}" if mass is not None else "1/s"
    fu = uu if mass is not None else f"{xu}/s²"
    params = {
        "c_mean": Parameter(float(c), float(c_err), cu),
        "fk_mean": Parameter(float(fk), float(fk_err), fu),
        "omega0": Parameter(float(w0), math.nan, "rad/s"),
    }
    data_used = {"t": t[idx], "amplitude": env, "models": models, "chosen": chosen,
                 "window": (float(t[idx[0]]), float(t[idx[-1]])),
                 "window_index": (int(idx[0]), int(idx[-1]) + 1),
                 "mass_normalised": mass is None}
    diagnostics = {"chosen": chosen, "n_eff": n_eff, "misfit": misfit,
                   **{f"aic_{k}": v["aic"] for k, v in models.items()},
                   "window_start": float(t[idx[0]]), "window_stop": float(t[idx[-1]]),
                   "motion_end": float(t_last + period / 4), "omega": float(w)}
    return Estimate(method="hilbert-envelope", params=params, data_used=data_used,
                    diagnostics=diagnostics)
