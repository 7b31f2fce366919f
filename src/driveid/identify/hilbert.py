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
from scipy.optimize import least_squares

from driveid.errors import IdentificationError, ParameterError, RecordError
from driveid.identify.estimate import Estimate, Parameter
from driveid.io.record import Record
from driveid.signal.envelope import (
    analytic_signal,
    count_crossings,
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
        x = x - float(np.median(uniform_filter1d(x, period_n, mode="nearest")))
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
        raise RecordError(
            f"the record must span at least {MIN_PERIODS:g} periods of the oscillation for "
            f"instantaneous identification; record for longer; got {periods:.2g} periods"
        )
    snr = peak / noise if noise > 0 else math.inf
    if snr < min_snr:
        raise IdentificationError(
            f"the record is too noisy: peak amplitude / noise std must be >= {min_snr:g} "
            f"(min_snr); filter the record or excite harder; got {snr:.3g}"
        )
    return Oscillation(x=x, omega=omega, noise=noise, snr=snr)


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
    for name, value in (("smoothing_periods", smoothing_periods),
                        ("trim_periods", trim_periods), ("ripple_threshold", ripple_threshold),
                        ("min_snr", min_snr)):
        if not (math.isfinite(value) and value > 0):
            raise ParameterError(f"{name} must be positive and finite; got {value!r}")
    if mass is not None and not (math.isfinite(mass) and mass > 0):
        raise ParameterError(
            f"mass must be a positive inertia [kg·m² or kg] or None; got {mass!r}"
        )
    osc = check_oscillation(record, min_snr=min_snr)
    fs = record.fs
    period = 2 * np.pi / osc.omega
    z = analytic_signal(osc.x, fs, omega=osc.omega)
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
    use_force = record.u is not None and np.any(record.u != 0) if forced is None else forced
    if use_force and record.u is None:
        raise RecordError("forced=True needs a force column 'u' in the record; got none")
    with np.errstate(divide="ignore", invalid="ignore"):
        free_part = omega**2 + sigma**2 + dsigma - sigma * domega / omega
    if use_force:
        ua = analytic_signal(record.u - np.mean(record.u), fs, omega=osc.omega)
        ratio = ua / z
        alpha = smooth_derivatives(ratio.real, fs, window)[0]
        beta = smooth_derivatives(ratio.imag, fs, window)[0]
        force_part = alpha + sigma * beta / omega
    amp_smooth = np.exp(lna)
    ripple = uniform_filter1d(np.abs(amplitude / amp_smooth - 1.0), max(window, 1))
    t = record.t
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
        ripple_max=float(np.max(ripple[sl])),
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
        (amplitude, omega0), ``damping_curve`` (amplitude, damping force ``2 J h omega A``)
        and ``window`` [s].

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
    data_used: dict[str, Any] = {
        "t": inst.t, "omega0": inst.omega0, "zeta": zeta_t, "amplitude": inst.amplitude,
        "omega": inst.omega, "sigma": inst.sigma,
        "backbone": {"amplitude": inst.amplitude, "omega0": inst.omega0},
        "damping_curve": {"amplitude": inst.amplitude, "force": damping_force,
                          "mass_normalised": not math.isfinite(inst.mass)},
        "window": (float(inst.t[0]), float(inst.t[-1])),
        "window_index": (inst.i0, inst.i1),
    }
    diagnostics = {
        "window_start": float(inst.t[0]), "window_stop": float(inst.t[-1]),
        "n_window": int(inst.i1 - inst.i0), "noise_std": inst.osc.noise, "snr": inst.osc.snr,
        "ripple_max": inst.ripple_max, "forced": inst.forced,
    }
    return Estimate(method="hilbert-forcevib" if inst.forced else "hilbert-freevib",
                    params=params, data_used=data_used, diagnostics=diagnostics)


def _envelope_models(period: float) -> dict[str, tuple[Any, list[str]]]:
    """Envelope models E(t; p) of a free decay, t measured from the window start.

    Exact half-cycle recurrence of a viscous + Coulomb oscillator: peaks obey
    ``A_{n+1} = q (A_n - d) - d`` with ``d = fk/K`` and ``q = exp(-sigma T_d/2)``, whose
    continuous interpolation is ``A + beta = (A0 + beta) exp(-sigma t)`` with
    ``beta = d coth(sigma T_d/4)``. Within a half cycle the amplitude about the centre
    falls from ``A_n - d`` to ``|A_{n+1}| + d``, so the period-averaged Hilbert envelope
    follows the peak envelope ``A(t)`` itself (checked in the tests to ~0.1 d).
    """
    def viscous(p: np.ndarray, t: np.ndarray) -> np.ndarray:
        return p[0] * np.exp(-p[1] * t)

    def coulomb(p: np.ndarray, t: np.ndarray) -> np.ndarray:
        return p[0] - p[1] * t

    def combined(p: np.ndarray, t: np.ndarray) -> np.ndarray:
        return (p[0] + p[2]) * np.exp(-p[1] * t) - p[2]

    return {"viscous": (viscous, ["E0", "sigma"]), "coulomb": (coulomb, ["E0", "rate"]),
            "combined": (combined, ["E0", "sigma", "beta"])}


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
    trim_periods, ripple_threshold, min_snr : float
        Valid-window options as in :func:`estimate_hilbert` [periods], [-], [-].

    Returns
    -------
    Estimate
        ``c_mean``, ``fk_mean`` (zero without standard error when the chosen model lacks the
        term), ``omega0`` [rad/s]; ``data_used["models"]`` holds every model's parameters,
        AIC and fitted envelope, ``data_used["chosen"]`` the one with the least AIC.

    Raises
    ------
    RecordError, IdentificationError, ParameterError
        As :func:`estimate_hilbert`.

    Notes
    -----
    Models of the envelope E(t) over the valid window: viscous ``E0 exp(-sigma t)``, Coulomb
    ``E0 - r t`` (the amplitude drops ``4 fk/K`` per cycle, ``K = J omega0²``, so
    ``fk = K r T_d/4``), and combined ``(E0 + beta) exp(-sigma t) - beta`` with
    ``fk = K beta tanh(x)``, ``x = sigma T_d/4`` (exact half-cycle recurrence of the peaks,
    derived in ``_envelope_models``), ``c = 2 J sigma``. Standard errors come from the
    Jacobian of :func:`scipy.optimize.least_squares`, inflated for the correlation of
    envelope samples (one independent sample per period, the smoothing length); AIC uses
    the same count.

    Examples
    --------
    >>> t = np.arange(4000) / 200.0
    >>> x = np.exp(-0.1 * t) * np.cos(2 * np.pi * t)
    >>> est = estimate_envelope_damping(Record(t=t, x=x), mass=1.0)
    >>> est.data_used["chosen"], round(est.value("c_mean"), 3)
    ('viscous', 0.2)
    """
    inst = _instantaneous(
        record, mass=mass, forced=False, smoothing_periods=1.0, trim_periods=trim_periods,
        ripple_threshold=ripple_threshold, min_snr=min_snr,
    )
    J = 1.0 if mass is None else float(mass)
    tw = inst.t - inst.t[0]
    env = inst.amplitude
    wd, _ = weighted_slope(inst.t, inst.phase, inst.amplitude**2, 10.0)
    period = 2 * np.pi / wd
    n_eff = max(tw[-1] / period, 4.0)
    e0, e1 = float(env[0]), float(env[-1])
    rate0 = max((e0 - e1) / tw[-1], 1e-12 * e0)
    sigma0 = max(math.log(e0 / e1) / tw[-1], 1e-9)
    starts = {"viscous": [e0, sigma0], "coulomb": [e0, rate0],
              "combined": [e0, 0.5 * sigma0, 0.5 * rate0 / sigma0]}
    models: dict[str, dict[str, Any]] = {}
    for name, (fun, names) in _envelope_models(period).items():
        fit = least_squares(lambda p, f=fun: f(p, tw) - env, starts[name], x_scale="jac")
        rss = float(fit.fun @ fit.fun)
        k = len(names)
        s2 = rss / max(env.size - k, 1)
        try:
            cov = np.linalg.inv(fit.jac.T @ fit.jac) * s2 * env.size / n_eff
        except np.linalg.LinAlgError:
            cov = np.full((k, k), np.nan)
        aic = n_eff * math.log(max(rss / env.size, 1e-300)) + 2 * k
        models[name] = {"params": dict(zip(names, fit.x.tolist(), strict=True)),
                        "stderr": dict(zip(names, np.sqrt(np.abs(np.diag(cov))).tolist(),
                                           strict=True)),
                        "cov": cov, "aic": aic, "fitted": fun(fit.x, tw)}
    chosen = min(models, key=lambda m: models[m]["aic"])
    m = models[chosen]
    p, cov = np.array(list(m["params"].values())), m["cov"]
    if chosen == "viscous":
        sigma = p[1]
        w0 = math.hypot(wd, sigma)
        c, c_err = 2 * J * sigma, 2 * J * math.sqrt(cov[1, 1])
        fk, fk_err = 0.0, math.nan
    elif chosen == "coulomb":
        w0 = wd
        c, c_err = 0.0, math.nan
        scale = J * w0**2 * period / 4
        fk, fk_err = scale * p[1], scale * math.sqrt(cov[1, 1])
    else:
        sigma = p[1]
        w0 = math.hypot(wd, sigma)
        c, c_err = 2 * J * sigma, 2 * J * math.sqrt(cov[1, 1])

        def fk_of(q: np.ndarray) -> float:
            return J * w0**2 * q[2] * math.tanh(q[1] * period / 4)

        fk = fk_of(p)
        grad = np.array([(fk_of(p + dp) - fk_of(p - dp)) / (2 * dp[i]) if dp[i] else 0.0
                         for i, dp in enumerate(np.diag(np.abs(p) * 1e-6 + 1e-12))])
        fk_err = float(np.sqrt(grad @ cov @ grad))
    xu, uu = record.units["x"], record.units["u"]
    cu = f"{uu}·s/{xu}" if mass is not None else "1/s"
    fu = uu if mass is not None else f"{xu}/s²"
    params = {
        "c_mean": Parameter(float(c), float(c_err), cu),
        "fk_mean": Parameter(float(fk), float(fk_err), fu),
        "omega0": Parameter(float(w0), math.nan, "rad/s"),
    }
    for entry in models.values():
        entry.pop("cov")
    data_used = {"t": inst.t, "amplitude": env, "models": models, "chosen": chosen,
                 "window": (float(inst.t[0]), float(inst.t[-1])),
                 "window_index": (inst.i0, inst.i1), "mass_normalised": mass is None}
    diagnostics = {"chosen": chosen, "n_eff": n_eff,
                   **{f"aic_{k}": v["aic"] for k, v in models.items()},
                   "window_start": float(inst.t[0]), "window_stop": float(inst.t[-1])}
    return Estimate(method="hilbert-envelope", params=params, data_used=data_used,
                    diagnostics=diagnostics)
