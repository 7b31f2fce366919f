r"""Extended logarithmic decrement: asymmetric viscous and kinetic friction from free decays.

Two estimators over the same peak features (:func:`driveid.signal.peaks.find_oscillation_peaks`):

* :func:`estimate_log_decrement_thesis` — the closed forms of de Marchi (1998) §2.2.5,
  Eqs. (2.169)-(2.175), either *as printed* or *corrected* (errata below);
* :func:`estimate_log_decrement` — a least-squares fit of all peak values and peak times of
  one or several records at once (the "higher dimensions" extension the thesis mentions at
  the end of §2.2.5.3), with standard errors. Several records (e.g. a positive- and a
  negative-start run, the thesis's FMixLR "mixing", App. B.5.3) share the parameters.

The exact peak recursion
------------------------
While the velocity has sign ``s`` the motion is a damped linear oscillation about
``e_s = -(θk_mean·s + θk_delta)``, with ``θk = F_k/K`` (2.139, 2.156). Between two velocity
zeros it turns half a damped period, so for the peak ``x_n`` reached by motion in direction
``s_n = sgn(x_n - x_{n-1})``

.. math::

    x_n - e_{s_n} = -\rho_{s_n} (x_{n-1} - e_{s_n}),\qquad
    \rho_s = \exp\!\big(-\pi\zeta_s/\sqrt{1-\zeta_s^2}\big),\qquad
    t_n - t_{n-1} = \pi / \big(\omega_0\sqrt{1-\zeta_s^2}\big).

This is (2.168) with the direction taken from the data.

Errata of §2.2.5
----------------
Each is derived from the recursion above and checked numerically in
``tests/identify/test_logdec.py`` against the exact simulator.

* (2.166) prints ``πβ = -πζ/sqrt(1-ζ²) = -πσ/ω_d``; the definition before it makes
  ``πβ = -ln(-γ_n/γ_{n-1}) = +πζ/sqrt(1-ζ²)`` (the peak ratio is below one).
* (2.171) ``ζ = sqrt(β²/(π²+β²))`` is right only for the half-cycle decrement ``πβ``; with the
  β of (2.169) (``e^{-πβ}``) it must read ``ζ = β/sqrt(1+β²)``. As printed it returns about
  ζ/π.
* (2.169) is right as a ratio, but which of β⁺, β⁻ it gives is the direction of the motion
  into ``γ_n``, not the parity of ``n``: label by ``sgn(x_n - x_{n-1})``.
* (2.170a): the parity factor ``(-1)^n`` must be ``-s_n`` (the direction into peak n, with the
  sign reversal of the γ → θ substitution); with the thesis's own parity rule the printed
  form has the right sign only when the first swing is positive.
* (2.170b): applied to measured positions θ, the sign is reversed:
  ``Δθk = -(q_n + q_{n-1})/2`` with ``q_n = (x_n + ρ x_{n-1})/(1+ρ)``.
* (2.172) ``Δζ = |ζ⁺ - ζ⁻|/2`` discards the direction of the asymmetry; it is
  ``(ζ⁺ - ζ⁻)/2``, signed like ``c_delta``.
* (2.175) prints ``sqrt(1 - ζ)``; ``ω_0 = ω_d/sqrt(1 - ζ²)``.

A constant applied force ``u0`` shifts every equilibrium by ``u0/K`` and is indistinguishable
from ``fk_delta``: the estimate's ``fk_delta`` is ``fk_delta - u0``.

References
----------
.. [1] J. A. de Marchi, "Modeling of dynamic friction, impact backlash and elastic compliance
       nonlinearities in machine tools", PhD thesis, Rensselaer Polytechnic Institute, 1998,
       §2.2.2-§2.2.5, Table 5.1.
.. [2] B. F. Feeny, J. W. Liang, "A decrement method for the simultaneous estimation of
       Coulomb and viscous friction", J. Sound Vib. 195(1), 149-154, 1996.
       doi:10.1006/jsvi.1996.0411
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from scipy.optimize import least_squares

from driveid.errors import IdentificationError, ParameterError
from driveid.identify.core._plausibility import plausibility_checked
from driveid.identify.core.estimate import Estimate, Parameter
from driveid.io.record import Record
from driveid.signal._blas import with_one_blas_thread
from driveid.signal.peaks import Peaks, find_oscillation_peaks

__all__ = [
    "MIN_PEAKS",
    "estimate_log_decrement",
    "estimate_log_decrement_thesis",
    "peak_recursion",
]

#: Fewest peaks per record for the asymmetric estimators (two half cycles each way + 1).
MIN_PEAKS = 5


def _units(record: Record) -> dict[str, str]:
    xu = record.units.get("x", "rad")
    if xu == "m":
        return {"x": "m", "J": "kg", "K": "N/m", "c": "N·s/m", "f": "N"}
    return {"x": xu, "J": "kg·m²", "K": f"N·m/{xu}", "c": f"N·m·s/{xu}", "f": "N·m"}


def _ratio(zeta):
    return np.exp(-np.pi * zeta / np.sqrt(1.0 - zeta * zeta))


def peak_recursion(
    x_first: float,
    directions: np.ndarray,
    *,
    zeta_plus: float,
    zeta_minus: float,
    theta_k_mean: float,
    theta_k_delta: float,
) -> np.ndarray:
    """Predict successive peaks from the first one by the exact recursion (2.168).

    Parameters
    ----------
    x_first : float
        First peak [m or rad].
    directions : ndarray of int, shape (n,)
        Direction of the motion into each peak (+1/-1); ``directions[0]`` is ignored.
    zeta_plus, zeta_minus : float
        Damping ratios for positive and negative motion [-], |ζ| < 1.
    theta_k_mean, theta_k_delta : float
        Kinetic friction over stiffness, ``fk/K`` [m or rad].

    Returns
    -------
    ndarray, shape (n,)
        Predicted peak positions [m or rad].

    Examples
    --------
    >>> peak_recursion(1.0, np.array([0, -1, 1]), zeta_plus=0.0, zeta_minus=0.0,
    ...                theta_k_mean=0.1, theta_k_delta=0.0)
    array([ 1. , -0.8,  0.6])
    """
    n = len(directions)
    out = np.empty(n)
    out[0] = x_first
    if n == 1:
        return out
    s = np.where(np.asarray(directions[1:]) > 0, 1.0, -1.0)
    rho = np.where(s > 0, _ratio(zeta_plus), _ratio(zeta_minus))
    eq = -(theta_k_mean * s + theta_k_delta)
    # x_n = a_n + b_n x_{n-1}, solved in closed form per chunk with cumulative products:
    # x_j = P_j (x_start + sum_k a_k / P_k); chunks keep |P| >= ~1e-300 (no underflow), so a
    # long record costs a few numpy calls instead of a Python loop per peak (issue 18)
    a, b = eq * (1.0 + rho), -rho
    smallest = float(np.min(np.abs(b)))
    chunk = 1 if smallest <= 0.0 else int(max(1, min(256, 280 // max(1.0, -np.log10(smallest)))))
    start = 0
    previous = x_first
    while start < n - 1:
        stop = min(n - 1, start + chunk)
        product = np.cumprod(b[start:stop])
        if product[-1] == 0.0:  # zero damping ratio limit: one step at a time
            values = np.empty(stop - start)
            for j in range(start, stop):
                previous = a[j] + b[j] * previous
                values[j - start] = previous
        else:
            values = product * (previous + np.cumsum(a[start:stop] / product))
            previous = values[-1]
        out[1 + start:1 + stop] = values
        start = stop
    return out


def _peaks_of(records, peaks):
    if isinstance(records, Record):
        records = [records]
    records = list(records)
    if not records:
        raise IdentificationError("no record given; pass one record or a list of records")
    if peaks is None:
        peaks = [find_oscillation_peaks(r.resampled_uniform(purpose="peak refinement"))
                 for r in records]
    elif isinstance(peaks, Peaks):
        peaks = [peaks]
    if len(peaks) != len(records):
        raise ParameterError(f"got {len(records)} records but {len(peaks)} peak sets")
    for k, pk in enumerate(peaks):
        if len(pk) < MIN_PEAKS:
            raise IdentificationError(
                f"record {k} has {len(pk)} usable peaks; the asymmetric log decrement needs "
                f"at least {MIN_PEAKS}. Start from a larger displacement, reduce the damping "
                "(PD feedback with negative D) or lower the noise"
            )
    return records, peaks


def _check_known(mass, stiffness):
    if mass is not None and stiffness is not None:
        raise ParameterError("give the mass J or the stiffness K, not both (one fixes the other)")
    for name, value in (("mass", mass), ("stiffness", stiffness)):
        if value is not None and not (math.isfinite(value) and value > 0):
            raise ParameterError(f"{name} must be a positive number; got {value!r}")


def _physical(omega0, zp, zm, tkm, tkd, mass, stiffness):
    """Map (ω0, ζ±, θk) to J, K, c_mean, c_delta, fk_mean, fk_delta given J or K."""
    if mass is not None:
        J, K = mass, mass * omega0**2
    else:
        J, K = stiffness / omega0**2, stiffness
    crit = 2.0 * math.sqrt(J * K)
    cp, cm = crit * zp, crit * zm
    return {
        "J": J,
        "K": K,
        "c_mean": 0.5 * (cp + cm),
        "c_delta": 0.5 * (cp - cm),
        "fk_mean": K * tkm,
        "fk_delta": K * tkd,
    }


@plausibility_checked
@with_one_blas_thread
def estimate_log_decrement_thesis(
    record: Record,
    *,
    corrected: bool = True,
    mass: float | None = None,
    stiffness: float | None = None,
    peaks: Peaks | None = None,
) -> Estimate:
    """Closed-form extended log decrement of the thesis, as printed or corrected.

    Parameters
    ----------
    record : Record
        A free decay.
    corrected : bool
        False: Eqs. (2.169)-(2.175) exactly as printed, on the first five peaks with the
        literal parity ``(-1)^n`` (n = 4). True: the corrected forms (module docstring),
        the median over every five-peak window.
    mass, stiffness : float, optional
        Known J [kg or kg·m²] or K [N/m or N·m/rad]; gives forces and damping coefficients.
    peaks : Peaks, optional
        Precomputed peaks of ``record``.

    Returns
    -------
    Estimate
        ``omega0`` [rad/s], ``zeta_plus``, ``zeta_minus``, ``zeta_mean``, ``zeta_delta`` [-],
        ``theta_k_mean``, ``theta_k_delta`` [m or rad], and with J or K also ``J``, ``K``,
        ``c_mean``, ``c_delta``, ``fk_mean``, ``fk_delta``. Standard errors are the scatter
        over windows (corrected) or ``nan`` (printed: a single window).

    Raises
    ------
    IdentificationError
        If fewer than 5 peaks are found or the peak ratios are not decaying oscillations.
    """
    _check_known(mass, stiffness)
    (record,), (pk,) = _peaks_of([record], None if peaks is None else [peaks])
    x, t = pk.x, pk.t
    u = _units(record)
    with np.errstate(invalid="ignore", divide="ignore"):
        if corrected:
            result = _thesis_corrected(x, t, pk.time_valid)
        else:
            result = _thesis_printed(x, t)
    values, errors = result
    params = {
        "omega0": Parameter(values["omega0"], errors.get("omega0", math.nan), "rad/s"),
        "zeta_plus": Parameter(values["zeta_plus"], errors.get("zeta_plus", math.nan), "-"),
        "zeta_minus": Parameter(values["zeta_minus"], errors.get("zeta_minus", math.nan), "-"),
        "zeta_mean": Parameter(values["zeta_mean"], math.nan, "-"),
        "zeta_delta": Parameter(values["zeta_delta"], math.nan, "-"),
        "theta_k_mean": Parameter(values["theta_k_mean"], errors.get("theta_k_mean", math.nan),
                                  u["x"]),
        "theta_k_delta": Parameter(values["theta_k_delta"],
                                   errors.get("theta_k_delta", math.nan), u["x"]),
    }
    if mass is not None or stiffness is not None:
        if corrected:
            phys = _physical(values["omega0"], values["zeta_plus"], values["zeta_minus"],
                             values["theta_k_mean"], values["theta_k_delta"], mass, stiffness)
        else:
            # printed: c from ζ̄ ± Δζ (2.172) with the printed ω0
            phys = _physical(values["omega0"], values["zeta_mean"] + values["zeta_delta"],
                             values["zeta_mean"] - values["zeta_delta"],
                             values["theta_k_mean"], values["theta_k_delta"], mass, stiffness)
        for name, unit in (("J", u["J"]), ("K", u["K"]), ("c_mean", u["c"]),
                           ("c_delta", u["c"]), ("fk_mean", u["f"]), ("fk_delta", u["f"])):
            params[name] = Parameter(phys[name], math.nan, unit, fixed=(
                (name == "J" and mass is not None) or (name == "K" and stiffness is not None)))
    bad = [k for k, p in params.items() if not math.isfinite(p.value)]
    if bad:
        raise IdentificationError(
            f"the thesis formulas gave non-finite {bad}: the peaks do not decay like an "
            "underdamped oscillation (peak ratios outside (0, ∞)); use estimate_log_decrement"
        )
    return Estimate(
        method="logdec-thesis-corrected" if corrected else "logdec-thesis-printed",
        params=params,
        data_used={"peak_t": t, "peak_x": x},
        diagnostics={"n_peaks": len(pk)},
    )


def _thesis_printed(x, t):
    n = 4
    g = x
    r_plus = -(g[n] - g[n - 2]) / (g[n - 1] - g[n - 3])  # (2.169)
    r_minus = -(g[n - 1] - g[n - 3]) / (g[n - 2] - g[n - 4])
    beta_p, beta_m = -np.log(r_plus) / np.pi, -np.log(r_minus) / np.pi
    q_n = (g[n] + g[n - 1] * r_plus) / (1 + r_plus)
    q_m = (g[n - 1] + g[n - 2] * r_minus) / (1 + r_minus)
    theta_mean = (q_n - q_m) / (2 * (-1) ** n)  # (2.170a) as printed
    theta_delta = 0.5 * (q_n + q_m)  # (2.170b) as printed
    zeta_p = np.sqrt(beta_p**2 / (np.pi**2 + beta_p**2))  # (2.171) as printed
    zeta_m = np.sqrt(beta_m**2 / (np.pi**2 + beta_m**2))
    zeta_mean, zeta_delta = 0.5 * (zeta_p + zeta_m), abs(0.5 * (zeta_p - zeta_m))  # (2.172)
    wd_p, wd_m = np.pi / (t[n] - t[n - 1]), np.pi / (t[n - 1] - t[n - 2])  # (2.173, 2.174)
    omega0 = 0.5 * (wd_p / np.sqrt(1 - zeta_p) + wd_m / np.sqrt(1 - zeta_m))  # (2.175) printed
    values = {
        "omega0": omega0, "zeta_plus": zeta_p, "zeta_minus": zeta_m, "zeta_mean": zeta_mean,
        "zeta_delta": zeta_delta, "theta_k_mean": theta_mean, "theta_k_delta": theta_delta,
    }
    return {k: float(v) for k, v in values.items()}, {}


def _thesis_corrected(x, t, time_valid):
    s = np.sign(np.diff(x)).astype(int)  # s[n-1]: direction into peak n
    ratios: dict[int, list[float]] = {1: [], -1: []}
    for n in range(3, x.size):
        ratios[int(s[n - 1])].append(-(x[n] - x[n - 2]) / (x[n - 1] - x[n - 3]))
    if not ratios[1] or not ratios[-1]:
        raise IdentificationError("peaks do not alternate in direction; not an oscillation")
    # medians: the last windows, near the stop, hold tiny differences of tiny peaks
    rho = {d: float(np.median(v)) for d, v in ratios.items()}
    beta = {d: -math.log(r) / math.pi if r > 0 else math.nan for d, r in rho.items()}
    zeta = {d: b / math.sqrt(1 + b * b) for d, b in beta.items()}
    # q_n = -(θk_mean s_n + θk_delta): linear least squares over every peak pair
    rows, rhs = [], []
    for n in range(1, x.size):
        d = int(s[n - 1])
        rows.append([-d, -1.0])
        rhs.append((x[n] + rho[d] * x[n - 1]) / (1 + rho[d]))
    sol, *_ = np.linalg.lstsq(np.array(rows), np.array(rhs), rcond=None)
    half = {1: [], -1: []}
    for n in range(1, x.size):
        if time_valid[n] and time_valid[n - 1]:
            half[int(s[n - 1])].append(t[n] - t[n - 1])
    omegas, errors = [], {}
    for d in (1, -1):
        if half[d]:
            wd = math.pi / float(np.median(half[d]))
            omegas.append(wd / math.sqrt(1 - zeta[d] ** 2))
    omega0 = float(np.mean(omegas)) if omegas else math.nan
    for d, name in ((1, "zeta_plus"), (-1, "zeta_minus")):
        if len(ratios[d]) > 1:
            r_std = float(np.std(ratios[d], ddof=1) / math.sqrt(len(ratios[d])))
            # dζ/dρ from ζ = β/sqrt(1+β²), β = -ln ρ/π
            b = beta[d]
            errors[name] = r_std / (math.pi * rho[d]) / (1 + b * b) ** 1.5
    values = {
        "omega0": omega0,
        "zeta_plus": zeta[1],
        "zeta_minus": zeta[-1],
        "zeta_mean": 0.5 * (zeta[1] + zeta[-1]),
        "zeta_delta": 0.5 * (zeta[1] - zeta[-1]),
        "theta_k_mean": float(sol[0]),
        "theta_k_delta": float(sol[1]),
    }
    return values, errors


@plausibility_checked
@with_one_blas_thread
def estimate_log_decrement(
    records: Record | Sequence[Record],
    *,
    mass: float | None = None,
    stiffness: float | None = None,
    peaks: Peaks | Sequence[Peaks] | None = None,
) -> Estimate:
    """Least-squares extended log decrement over all peak values and times of one or more runs.

    Parameters
    ----------
    records : Record or sequence of Record
        Free decays of one system, e.g. a positive- and a negative-start run (FMixLR).
    mass : float, optional
        Known J [kg or kg·m²]; gives K, c and fk in physical units.
    stiffness : float, optional
        Known K [N/m or N·m/rad]; gives J, c and fk in physical units.
    peaks : Peaks or sequence of Peaks, optional
        Precomputed peak features, one per record (e.g. after removing PD feedback).

    Returns
    -------
    Estimate
        ``omega0`` [rad/s], ``zeta_plus``, ``zeta_minus`` [-], ``theta_k_mean``,
        ``theta_k_delta`` [m or rad] (= fk/K), and with J or K also ``J``, ``K``, ``c_mean``,
        ``c_delta`` [N·s/m or N·m·s/rad], ``fk_mean``, ``fk_delta`` [N or N·m]; each with a
        standard error from the weighted Jacobian.

    Raises
    ------
    IdentificationError
        Too few peaks (< 5 per record), no oscillation, or a fit that does not converge.
    ParameterError
        Both ``mass`` and ``stiffness`` given, or a non-positive one.

    Notes
    -----
    Unknowns: ω0, ζ⁺, ζ⁻, θk_mean, θk_delta, and per record its first peak value and time.
    Residuals: every peak value against the exact recursion (module docstring) and every
    valid peak time against the accumulated half periods ``π/(ω0 sqrt(1-ζ_s²))``. Each is
    weighted by the standard error of its local peak fit (a small peak's time is less
    certain), each group scaled by its own residual scatter (re-estimated three times), and the
    covariance is ``(JᵀJ)⁻¹`` of the weighted problem, so standard errors reflect the noise
    actually present.

    Examples
    --------
    >>> from driveid.sim import OscillatorParams, simulate_free_decay
    >>> p = OscillatorParams(J=1.0, K=16.0, c_mean=0.3, c_delta=0.1, fk_mean=0.07,
    ...                      fk_delta=0.03)
    >>> est = estimate_log_decrement(simulate_free_decay(p, x0=1.0, duration=20).record,
    ...                              mass=1.0)
    >>> round(est.value("fk_mean"), 4), round(est.value("c_delta"), 4)
    (0.07, 0.1)
    """
    _check_known(mass, stiffness)
    records, peaks = _peaks_of(records, peaks)
    u = _units(records[0])
    longest = max(range(len(peaks)), key=lambda k: len(peaks[k]))
    try:
        with np.errstate(invalid="ignore", divide="ignore"):
            start, _ = _thesis_corrected(peaks[longest].x, peaks[longest].t,
                                         peaks[longest].time_valid)
    except IdentificationError:
        start = {}
    dirs = []
    for pk in peaks:
        d = np.zeros(len(pk), int)
        d[1:] = np.sign(np.diff(pk.x)).astype(int)
        if np.any(d[1:] == 0) or np.any(d[1:-1] == d[2:]):
            raise IdentificationError("peaks do not alternate in direction; not an oscillation")
        dirs.append(d)
    half_mean = np.mean(np.concatenate([np.diff(pk.t)[pk.time_valid[1:] & pk.time_valid[:-1]]
                                        for pk in peaks]))
    guess = [
        _finite(start.get("omega0"), math.pi / half_mean),
        _finite(start.get("zeta_plus"), 0.05),
        _finite(start.get("zeta_minus"), 0.05),
        _finite(start.get("theta_k_mean"), 0.0),
        _finite(start.get("theta_k_delta"), 0.0),
    ]
    guess[1:3] = [float(np.clip(z, -0.95, 0.95)) for z in guess[1:3]]
    for pk in peaks:
        guess += [pk.x[0], pk.t[0]]
    amplitude = max(float(np.max(np.abs(pk.x - np.median(pk.x)))) for pk in peaks)

    # relative weights of every peak value and time: the standard errors of the local peak
    # fits, normalised so that the overall scale of each group is estimated below
    w_x = [pk.x_se / np.median(pk.x_se) if pk.x_se is not None else np.ones(len(pk))
           for pk in peaks]
    w_t = [pk.t_se / np.median(pk.t_se[pk.time_valid]) if pk.t_se is not None
           else np.ones(len(pk)) for pk in peaks]

    def residual_parts(p):
        omega0, zp, zm, tkm, tkd = p[:5]
        res_x, res_t = [], []
        for k, (pk, d) in enumerate(zip(peaks, dirs, strict=True)):
            x0, t0 = p[5 + 2 * k], p[6 + 2 * k]
            res_x.append((pk.x - peak_recursion(x0, d, zeta_plus=zp, zeta_minus=zm,
                                                theta_k_mean=tkm, theta_k_delta=tkd))
                         / w_x[k])
            half = np.where(d[1:] > 0, 1.0 / np.sqrt(1 - zp * zp), 1.0 / np.sqrt(1 - zm * zm))
            t_pred = t0 + np.concatenate([[0.0], np.cumsum(half)]) * (np.pi / omega0)
            res_t.append(((pk.t - t_pred) / w_t[k])[pk.time_valid])
        return np.concatenate(res_x), np.concatenate(res_t)

    n_x = sum(len(pk) for pk in peaks)
    n_t = sum(int(pk.time_valid.sum()) for pk in peaks)
    n_par = len(guess)
    if n_x + n_t <= n_par:
        raise IdentificationError(
            f"{n_x + n_t} peak values and times cannot determine {n_par} unknowns; record "
            "more peaks"
        )
    sigma_x = max(max(pk.x_std for pk in peaks), 1e-9 * amplitude)
    sigma_t = sigma_x / (amplitude * guess[0])
    lower = [0.0, -0.999, -0.999, -np.inf, -np.inf] + [-np.inf] * (n_par - 5)
    upper = [np.inf, 0.999, 0.999, np.inf, np.inf] + [np.inf] * (n_par - 5)
    p = np.array(guess, float)
    for _ in range(4):
        def weighted(q, sx=sigma_x, st=sigma_t):
            rx, rt = residual_parts(q)
            return np.concatenate([rx / sx, rt / st])

        sol = least_squares(weighted, p, bounds=(lower, upper), x_scale="jac",
                            xtol=1e-15, ftol=1e-15, gtol=1e-15, max_nfev=2000)
        p = sol.x
        rx, rt = residual_parts(p)
        # scatter of each group, with degrees of freedom shared in proportion to its size
        dof = max(n_x + n_t - n_par, 1)
        sx_new = math.sqrt(float(rx @ rx) / max(dof * n_x / (n_x + n_t), 1e-9))
        st_new = math.sqrt(float(rt @ rt) / max(dof * n_t / (n_x + n_t), 1e-9)) if n_t else 1.0
        sigma_x = max(sx_new, 1e-12 * amplitude)
        sigma_t = max(st_new, 1e-12 / p[0])
    if not sol.success:
        raise IdentificationError(f"the least-squares fit did not converge: {sol.message}")
    jac = sol.jac
    try:
        cov = np.linalg.inv(jac.T @ jac)
    except np.linalg.LinAlgError:
        raise IdentificationError(
            "the peaks cannot separate the unknowns (singular Jacobian); record more peaks "
            "in both directions"
        ) from None
    se = np.sqrt(np.clip(np.diag(cov), 0, None))
    names = ["omega0", "zeta_plus", "zeta_minus", "theta_k_mean", "theta_k_delta"]
    units = ["rad/s", "-", "-", u["x"], u["x"]]
    params = {nm: Parameter(float(p[i]), float(se[i]), un)
              for i, (nm, un) in enumerate(zip(names, units, strict=True))}
    if mass is not None or stiffness is not None:
        base = p[:5]

        def phys_vec(q):
            d = _physical(*q, mass, stiffness)
            return np.array([d[k] for k in ("J", "K", "c_mean", "c_delta", "fk_mean",
                                            "fk_delta")])

        g0 = phys_vec(base)
        G = np.empty((6, 5))
        for i in range(5):
            h = 1e-7 * max(abs(base[i]), 1e-3)
            step = np.zeros(5)
            step[i] = h
            G[:, i] = (phys_vec(base + step) - phys_vec(base - step)) / (2 * h)
        cov_phys = G @ cov[:5, :5] @ G.T
        se_phys = np.sqrt(np.clip(np.diag(cov_phys), 0, None))
        for i, (nm, un) in enumerate((("J", u["J"]), ("K", u["K"]), ("c_mean", u["c"]),
                                      ("c_delta", u["c"]), ("fk_mean", u["f"]),
                                      ("fk_delta", u["f"]))):
            known = (nm == "J" and mass is not None) or (nm == "K" and stiffness is not None)
            params[nm] = Parameter(float(g0[i]), 0.0 if known else float(se_phys[i]), un,
                                   fixed=known)
    fitted = []
    for k, d in enumerate(dirs):
        fitted.append(peak_recursion(p[5 + 2 * k], d, zeta_plus=p[1], zeta_minus=p[2],
                                     theta_k_mean=p[3], theta_k_delta=p[4]))
    return Estimate(
        method="logdec-lsq",
        params=params,
        data_used={
            "peak_t": [pk.t for pk in peaks],
            "peak_x": [pk.x for pk in peaks],
            "peak_fit": fitted,
            "time_valid": [pk.time_valid for pk in peaks],
        },
        diagnostics={
            "n_records": len(peaks),
            "n_peaks": n_x,
            "rms_peak_value": sigma_x,
            "rms_peak_time": sigma_t,
            "condition_number": float(np.linalg.cond(jac)),
        },
    )


def _finite(value, fallback):
    return float(value) if value is not None and math.isfinite(value) else fallback
