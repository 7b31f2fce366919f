r"""Position-dependent friction: a periodogram of the friction residual over position.

Friction that repeats with the screw lead or a gear tooth (thesis ch. 4) shows in runs at
constant speed (or slow sweeps) as a ripple of the command ``u`` that is periodic in the
*position* x, not in time. The residual of the friction at each speed,

.. math::

    r = \mathrm{sgn}\,v\,\big[u - (b_0 + b_1 v + b_2 \,\mathrm{sgn}\, v + b_3 |v|)\big]
    \quad\text{(per record)},

is taken in the direction of motion, because a ripple of the friction *magnitude* flips sign
with the direction of u. For a run at constant speed only ``b_0`` is removed: the speed
wobble caused by the ripple itself must not be regressed away. The residual is searched for
a sinusoid ``A cos(2π x / L + φ)`` with the generalised Lomb–Scargle periodogram over
position (floating mean, Zechmeister & Kürster [2]_; ``scipy.signal.lombscargle``), which
takes the unevenly spaced positions of a run whose speed wanders. The normalised power
``p(L)`` is the fraction of the residual variance the sinusoid explains.

Significance
------------
For Gaussian residuals without a periodic term, ``q = Prob(p > p_0) = (1 - p_0)^{(N-3)/2}``
at one trial period (Zechmeister & Kürster 2009, Eq. (24)). Over a band of trial periods the
false-alarm probability of the highest peak is Baluev's bound [3]_ (Eq. (3), "standard"
normalisation), ``FAP ≈ 1 - (1 - q) e^{-τ}``, ``τ = W (1-p)^{(N-4)/2} sqrt(N p/2)``,
``W = (1/L_min - 1/L_max) sqrt(4π var x)``. The simpler "M independent frequencies" rule
``1 - (1-q)^M`` (Horne & Baliunas) was 2.5 × too optimistic in our noise-only Monte Carlo
(``tests/identify/test_position_friction.py``); Baluev's form is calibrated. A ripple is
reported only
when ``FAP < fap_threshold`` (default 1 %); otherwise the estimate has no parameters and the
strongest peak is kept in the diagnostics only. Residuals that are not white (slow drift,
control-loop oscillation) make the FAP optimistic; keep the trial periods well inside the
range of position covered and away from the loop's time periods divided by the speed.

References
----------
.. [1] J. A. de Marchi, "Modeling of dynamic friction, impact backlash and elastic compliance
       nonlinearities in machine tools", PhD thesis, Rensselaer Polytechnic Institute, 1998,
       ch. 4.
.. [2] M. Zechmeister, M. Kürster, "The generalised Lomb-Scargle periodogram", Astron.
       Astrophys. 496, 577-584, 2009. doi:10.1051/0004-6361:200811296
.. [3] R. V. Baluev, "Assessing the statistical significance of periodogram peaks",
       Mon. Not. R. Astron. Soc. 385, 1279-1285, 2008. doi:10.1111/j.1365-2966.2008.12689.x
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from scipy.signal import lombscargle

from driveid.errors import IdentificationError, ParameterError, RecordError
from driveid.identify.core.estimate import Estimate, Parameter
from driveid.io.record import Record

__all__ = ["estimate_position_friction", "false_alarm_probability"]


def false_alarm_probability(power: float, n_samples: int, bandwidth: float) -> float:
    """False-alarm probability of the highest normalised GLS power (Baluev 2008).

    Parameters
    ----------
    power : float
        Normalised periodogram power ``p`` in [0, 1] [-].
    n_samples : int
        Residual samples N [-], > 4.
    bandwidth : float
        ``W = Δk · sqrt(4π var(x))``: searched band of spatial frequencies Δk [1/(rad or
        m)] times the effective position baseline [rad or m] [-], >= 0.

    Returns
    -------
    float
        ``1 - (1 - q) exp(-τ)`` with ``q = (1-p)^((N-3)/2)`` and
        ``τ = W (1-p)^((N-4)/2) sqrt(N p / 2)`` [-] (module notes).

    Raises
    ------
    ParameterError
        On a value out of range.

    Examples
    --------
    >>> false_alarm_probability(0.05, 1000, 100.0) < 1e-8
    True
    >>> round(false_alarm_probability(0.001, 1000, 100.0), 3)
    1.0
    """
    if not (0 <= power <= 1) or n_samples <= 4 or not (bandwidth >= 0):
        raise ParameterError(
            f"need 0 <= power <= 1, n_samples > 4, bandwidth >= 0; got {power!r}, "
            f"{n_samples!r}, {bandwidth!r}")
    if power >= 1.0:
        return 0.0
    log1mp = math.log1p(-power)
    single = math.exp(0.5 * (n_samples - 3) * log1mp)
    tau = bandwidth * math.exp(0.5 * (n_samples - 4) * log1mp) * math.sqrt(
        0.5 * n_samples * power)
    if single >= 1.0:
        return 1.0
    return float(-math.expm1(math.log1p(-single) - tau))


def _residual(record: Record, inertia: float | None) -> tuple[np.ndarray, np.ndarray]:
    if record.u is None:
        raise RecordError("position-dependent friction needs the command u (column 'u')")
    x = np.asarray(record.x, dtype=float)
    v = np.asarray(record.v, dtype=float) if record.v is not None else np.gradient(x, record.t)
    if np.ptp(v) < 0.2 * np.mean(np.abs(v)):
        # constant speed: the smooth friction is one constant; regressing on v would take
        # the ripple-driven speed fluctuation (and with it part of the ripple) away
        basis = np.ones((v.size, 1))
    else:
        basis = np.column_stack([np.ones_like(v), v, np.sign(v), np.abs(v)])
    u = np.asarray(record.u, dtype=float)
    if inertia is not None:
        u = u - inertia * np.gradient(v, record.t)
    coef, *_ = np.linalg.lstsq(basis, u, rcond=None)
    # friction opposes the motion: its ripple flips sign with the direction, so runs in
    # both directions add coherently only in the direction of motion
    return x, np.sign(v) * (u - basis @ coef)


def estimate_position_friction(
    records: Record | Sequence[Record],
    *,
    period_min: float,
    period_max: float,
    n_periods: int | None = None,
    fap_threshold: float = 0.01,
    inertia: float | None = None,
) -> Estimate:
    r"""Find friction periodic in position: period, amplitude and false-alarm probability.

    Parameters
    ----------
    records : Record or sequence of Record
        Constant-speed (or slowly swept) runs with ``x`` [rad or m], ``u`` [N·m or N] and
        optionally ``v``; each run's smooth friction is removed by its own fit of
        ``1, v, sgn v, |v|`` (module notes).
    period_min, period_max : float
        Range of trial periods in position [rad or m]; ``0 < period_min < period_max``;
        ``period_max`` at most half the position range covered.
    n_periods : int, optional
        Trial periods (evenly spaced in 1/L) [-]; default 10 × the independent ones.
    fap_threshold : float
        Largest false-alarm probability of a reported ripple [-], in (0, 1).
    inertia : float, optional
        Known J [kg·m² or kg]: ``J dv/dt`` is removed from u first. Under closed-loop speed
        control the ripple also shakes the axis, and the inertial share of u would otherwise
        lower the amplitude and, with runs at different speeds, shift the phase.

    Returns
    -------
    Estimate
        Method ``"position-periodogram"``. When significant: ``ripple_period`` [rad or m]
        (standard error from the peak width, ``L²/(span·sqrt(N p/2))``-type linearisation),
        ``ripple_amplitude`` [N·m or N] and ``ripple_phase`` [rad] (``A cos(2πx/L + φ)``),
        with standard errors from the least-squares sinusoid fit. Else no parameters and a
        warning. Diagnostics: ``false_alarm_probability``, ``peak_power``,
        ``peak_period``, ``n_independent``, ``n_samples``, ``significant``.
        ``data_used``: ``period`` and ``power`` of the periodogram.

    Raises
    ------
    RecordError
        A record without ``u``.
    IdentificationError
        The position range is shorter than two ``period_max``.
    ParameterError
        On a bad argument.

    Examples
    --------
    >>> x = np.linspace(0, 40 * np.pi, 4000)
    >>> u = 0.2 + 0.01 * np.cos(x) + 0.002 * np.random.default_rng(0).standard_normal(4000)
    >>> est = estimate_position_friction(Record(t=x, x=x, u=u, v=np.ones(4000)),
    ...                                  period_min=1.0, period_max=20.0)
    >>> L, A = est.value("ripple_period"), est.value("ripple_amplitude")
    >>> round(L / (2 * np.pi), 2), round(A, 3)
    (1.0, 0.01)
    """
    records = [records] if isinstance(records, Record) else list(records)
    if not records or not all(isinstance(r, Record) for r in records):
        raise ParameterError("records must be one or more Records")
    if not (0 < period_min < period_max < math.inf):
        raise ParameterError(
            f"need 0 < period_min < period_max [rad or m]; got {period_min!r}, {period_max!r}")
    if not (0 < fap_threshold < 1):
        raise ParameterError(f"fap_threshold must be in (0, 1); got {fap_threshold!r}")
    if inertia is not None and not (math.isfinite(inertia) and inertia >= 0):
        raise ParameterError(f"inertia must be >= 0 [kg·m² or kg]; got {inertia!r}")
    parts = [_residual(r, inertia) for r in records]
    x = np.concatenate([p[0] for p in parts])
    r = np.concatenate([p[1] for p in parts])
    span = float(np.ptp(x))
    if span < 2 * period_max:
        raise IdentificationError(
            f"the runs cover {span:.4g} of position; period_max={period_max:.4g} needs at "
            "least two periods: lower period_max or run over a longer stroke")
    n_indep = max((1.0 / period_min - 1.0 / period_max) * span, 1.0)
    bandwidth = (1.0 / period_min - 1.0 / period_max) * math.sqrt(4 * math.pi * np.var(x))
    n_trial = int(10 * math.ceil(n_indep)) if n_periods is None else int(n_periods)
    if n_trial < 2:
        raise ParameterError(f"n_periods must be >= 2; got {n_periods!r}")
    k = np.linspace(1.0 / period_max, 1.0 / period_min, n_trial)     # cycles per unit x
    power = lombscargle(x, r - r.mean(), 2 * np.pi * k, normalize=True, floating_mean=True)
    best = int(np.argmax(power))
    # refine the peak by a parabola through its neighbours (in 1/L)
    kb = k[best]
    if 0 < best < n_trial - 1:
        y0, y1, y2 = power[best - 1: best + 2]
        denom = y0 - 2 * y1 + y2
        if denom < 0:
            kb = k[best] + 0.5 * (y0 - y2) / denom * (k[1] - k[0])
    n = r.size
    p_peak = float(power[best])
    fap = false_alarm_probability(min(max(p_peak, 0.0), 1.0), n, bandwidth)
    significant = fap < fap_threshold
    unit_x = records[0].units.get("x", "rad")
    unit_u = records[0].units.get("u", "N·m")
    params: dict[str, Parameter] = {}
    cov = None
    warnings = []
    if significant:
        w = 2 * np.pi * kb
        basis = np.column_stack([np.cos(w * x), np.sin(w * x), np.ones_like(x)])
        coef, *_ = np.linalg.lstsq(basis, r, rcond=None)
        resid = r - basis @ coef
        s2 = float(resid @ resid) / max(n - 3, 1)
        cab = s2 * np.linalg.inv(basis.T @ basis)[:2, :2]
        a, b = coef[0], coef[1]
        amp = math.hypot(a, b)
        g_amp = np.array([a, b]) / amp
        g_phase = np.array([b, -a]) / amp**2     # φ = atan2(-b, a)
        se_amp = math.sqrt(max(g_amp @ cab @ g_amp, 0.0))
        se_phase = math.sqrt(max(g_phase @ cab @ g_phase, 0.0))
        # frequency error of a sinusoid fit: σ_ω = sqrt(24 s²/(N A² T²))-type bound with
        # T = span (Kay 1993, CRLB of frequency); L = 2π/ω
        se_w = math.sqrt(24.0 * s2 / (n * amp**2 * span**2)) if amp > 0 else math.nan
        period = float(1.0 / kb)
        params = {
            "ripple_period": Parameter(period, period**2 * se_w / (2 * np.pi), unit_x),
            "ripple_amplitude": Parameter(amp, se_amp, unit_u),
            "ripple_phase": Parameter(float(math.atan2(-b, a)), se_phase, "rad"),
        }
    else:
        warnings.append(
            f"no position-periodic friction: the strongest peak (period {1 / kb:.4g} "
            f"{unit_x}, power {p_peak:.3g}) has false-alarm probability {fap:.3g} >= "
            f"{fap_threshold}")
    return Estimate(
        method="position-periodogram", params=params, covariance=cov,
        data_used={"period": 1.0 / k, "power": power},
        diagnostics={"false_alarm_probability": fap, "peak_power": p_peak,
                     "peak_period": float(1.0 / kb), "n_independent": float(n_indep),
                     "n_samples": int(n), "significant": bool(significant),
                     "position_span": span},
        warnings=tuple(warnings),
    )
