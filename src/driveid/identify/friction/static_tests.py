"""Static and quasi-static identification tests (thesis §2.1.1.2–2.1.1.4 and §7 outline).

* breakaway (static) friction per direction from a slow force ramp, with the presliding
  displacement and stiffness (2.13)–(2.14);
* rise of static friction with dwell time, Kato/Howe form (2.6);
* backlash gap and stiffness from ± constant-torque (static deflection) tests;
* step-response metrics of a DC-biased square wave (the thesis's support functions
  ``OverSht.m``, ``Rising.m``, ``Settling.m``, App. B.6.5) and the second-order ζ, ω0
  they imply.

Sign convention (DESIGN.md): static friction ``fs_mean + fs_delta·sgn(applied force)``;
``fs_plus = fs_mean + fs_delta`` and ``fs_minus = fs_mean − fs_delta`` are magnitudes.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from scipy import optimize

from driveid.errors import IdentificationError, ParameterError, RecordError
from driveid.identify.core._plausibility import GAP_HINT, held_at_zero
from driveid.identify.core.estimate import Estimate, Parameter
from driveid.io.record import Record
from driveid.models.friction_memory import (
    KatoRisingParams,
    presliding_stiffness,
    rising_static_friction_kato,
)
from driveid.signal.steady import noise_level

__all__ = [
    "estimate_breakaway",
    "estimate_rising_friction",
    "estimate_backlash_stiffness",
    "estimate_static_stiffness",
    "step_metrics",
    "estimate_step_response",
]


def _units(record: Record) -> tuple[str, str]:
    xu = record.units.get("x", "rad")
    fu = record.units.get("u", "N·m")
    return xu, fu


# -- breakaway and presliding -------------------------------------------------------------

def estimate_breakaway(record: Record, *, x_break: float) -> Estimate:
    """Breakaway force per direction from a quasi-static force ramp, with presliding.

    Parameters
    ----------
    record : Record
        Position ``x`` [m or rad] and slowly ramped applied force ``u`` [N or N·m]. Each
        run of one sign of ``u`` that starts from rest is one ramp; the record needs at
        least one ramp of each sign.
    x_break : float
        Displacement from the rest position that counts as gross sliding [m or rad]; > 0.
        Choose it a few times the presliding displacement and far above the position
        noise.

    Returns
    -------
    Estimate
        ``fs_plus``, ``fs_minus`` (magnitudes) [N or N·m], ``fs_mean``, ``fs_delta``;
        ``xs_plus``, ``xs_minus`` presliding displacements at breakaway [m or rad] and
        ``ks`` [N/m or N·m/rad] from (2.14). Standard errors: spread over repeated ramps,
        or for a single ramp the force step per sample and force noise. Diagnostics
        ``ks_regression_plus``/``_minus``: the slope of (2.13) fitted per direction.
        ``data_used["breakaway_index"]`` lists the breakaway samples.

    Raises
    ------
    ParameterError
        If ``x_break`` is not positive.
    RecordError
        If the record has no force.
    IdentificationError
        If no ramp of one sign reaches sliding; the message says which ramp to add.

    Notes
    -----
    Breakaway is the last sample before the displacement from rest first exceeds
    ``x_break``, walked back to where it leaves the presliding line ``x = x0 + u/ks``
    (2.13) by more than 4 position-noise deviations. Presliding stiffness (2.14):
    ``ks = (fs+ − (−fs−)) / (xs+ − xs−)`` with signed displacements.
    """
    if not (math.isfinite(x_break) and x_break > 0):
        raise ParameterError(f"x_break must be a positive displacement [m or rad]; got {x_break}")
    if record.u is None:
        raise RecordError("breakaway needs the applied force u; got a record without it")
    x, u = np.asarray(record.x, float), np.asarray(record.u, float)
    su = noise_level(u)
    found: dict[int, list[tuple[float, float, int]]] = {1: [], -1: []}
    slopes: dict[int, list[float]] = {1: [], -1: []}
    noise_x: list[float] = []
    sgn = np.sign(u)
    edges = np.flatnonzero(np.diff(sgn) != 0) + 1
    bounds = np.concatenate([[0], edges, [u.size]])
    for a, b in zip(bounds[:-1], bounds[1:], strict=True):
        s = int(sgn[a]) if b > a else 0
        if s == 0 or b - a < 5:
            continue
        x0 = x[a]
        moved = np.flatnonzero(np.abs(x[a:b] - x0) > x_break)
        if moved.size == 0:
            continue
        i_m = a + int(moved[0])
        # presliding line (2.13) fitted on the first half of the stuck ramp; its residual
        # scatter is the position noise (a global estimate would see the sliding phases)
        pre = slice(a, max(a + 4, a + (i_m - a) // 2))
        uu, xx = u[pre], x[pre]
        if np.ptp(uu) > 0:
            slope, icpt = np.polyfit(uu, xx, 1)
        else:
            slope, icpt = 0.0, x0
        res = xx - (icpt + slope * uu)
        s_run = float(np.sqrt(res @ res / max(res.size - 2, 1)))
        dev = np.abs(x[a:i_m] - (icpt + slope * u[a:i_m]))
        inside = np.flatnonzero(dev <= 4 * s_run + 1e-300)
        i_b = a + int(inside[-1]) if inside.size else a
        found[s].append((float(abs(u[i_b])), float(x[i_b] - x0), i_b))
        slopes[s].append(float(slope))
        noise_x.append(s_run)
    for s, name in ((1, "positive"), (-1, "negative")):
        if not found[s]:
            raise IdentificationError(
                f"no {name} force ramp reaches sliding (displacement > x_break = {x_break:g}); "
                f"add a slow {name} force ramp from rest that ends in gross sliding, or lower "
                f"x_break; got {len(found[s])} breakaways"
            )
    xu, fu = _units(record)
    sx = float(np.median(noise_x))
    step = float(np.median(np.abs(np.diff(u)))) if u.size > 1 else 0.0
    params: dict[str, Parameter] = {}
    stats = {}
    for s, tag in ((1, "plus"), (-1, "minus")):
        f = np.array([r[0] for r in found[s]])
        d = np.array([r[1] for r in found[s]])
        if f.size > 1:
            fse, dse = f.std(ddof=1) / math.sqrt(f.size), d.std(ddof=1) / math.sqrt(d.size)
        else:
            fse, dse = math.hypot(step / math.sqrt(12), su), sx
        stats[tag] = (float(f.mean()), fse, float(d.mean()), dse)
        params[f"fs_{tag}"] = Parameter(float(f.mean()), fse, fu)
    (fp, fpe, dp, dpe), (fm, fme, dm, dme) = stats["plus"], stats["minus"]
    params["fs_mean"] = Parameter(0.5 * (fp + fm), 0.5 * math.hypot(fpe, fme), fu)
    params["fs_delta"] = Parameter(0.5 * (fp - fm), 0.5 * math.hypot(fpe, fme), fu)
    params["xs_plus"] = Parameter(dp, dpe, xu)
    params["xs_minus"] = Parameter(dm, dme, xu)
    if dp - dm > 0 and fp + fm > 0:
        ks = presliding_stiffness(fs_plus=fp, fs_minus=-fm, x_plus=dp, x_minus=dm)
        ks_se = ks * math.hypot(math.hypot(fpe, fme) / (fp + fm), math.hypot(dpe, dme) / (dp - dm))
        params["ks"] = Parameter(ks, ks_se, f"{fu}/{xu}")
    return Estimate(
        method="breakaway-ramp",
        params=params,
        data_used={"breakaway_index": [r[2] for s in (1, -1) for r in found[s]]},
        diagnostics={"n_plus": len(found[1]), "n_minus": len(found[-1]),
                     "x_break": x_break, "position_noise": sx, "force_noise": su,
                     "ks_regression_plus": _inv(np.mean(slopes[1])),
                     "ks_regression_minus": _inv(np.mean(slopes[-1]))},
    )


def _inv(slope: float) -> float:
    return 1.0 / slope if slope > 0 else math.nan


# -- rising static friction ---------------------------------------------------------------

def estimate_rising_friction(
    t_dwell: np.ndarray, fs: np.ndarray, *, fs_stderr: np.ndarray | None = None,
    unit: str = "N",
) -> Estimate:
    """Fit the rise of static friction with dwell time, (2.6), by nonlinear least squares.

    The model is :func:`driveid.models.friction_memory.rising_static_friction_kato`:
    ``fs(t) = fs_inf + (fk − fs_inf)·exp(−t^κ/γ)``. The thesis's γ is the reciprocal of
    the rate in Kato's original ``exp(−γ' t^κ)`` (hence its "1/γ roughly 0.04–0.29") and
    has the unit s^κ, not s as printed.

    Parameters
    ----------
    t_dwell : array_like, shape (n,)
        Dwell times before each breakaway ramp [s]; >= 0, n >= 5, spanning the rise.
    fs : array_like, shape (n,)
        Breakaway forces measured after those dwells [N or N·m].
    fs_stderr : array_like, shape (n,), optional
        Standard errors of ``fs`` [N or N·m] used as weights.
    unit : str
        Force unit for the result.

    Returns
    -------
    Estimate
        ``fs_inf``, ``fk`` [unit], ``gamma`` [s^kappa], ``kappa`` [-], with standard errors
        scaled by the reduced χ² when it exceeds 1.

    Raises
    ------
    IdentificationError
        If fewer than 5 dwell times, or they do not span the rise (the fitted time scale
        ``gamma^(1/kappa)`` outside the measured dwell range).
    """
    t = np.asarray(t_dwell, dtype=float).ravel()
    f = np.asarray(fs, dtype=float).ravel()
    if t.size != f.size or t.size < 5:
        raise IdentificationError(
            "rising static friction needs at least 5 breakaway tests at different dwell "
            f"times (equal-length arrays); add dwell times; got {t.size} and {f.size}"
        )
    if np.any(t < 0):
        raise ParameterError(f"dwell times must be >= 0 s; got min {t.min()}")
    w = np.ones_like(f) if fs_stderr is None else 1.0 / np.asarray(fs_stderr, float).ravel()
    tpos = t[t > 0]
    t_mid = float(np.exp(np.mean(np.log(tpos)))) if tpos.size else 1.0
    x0 = [f.max(), f.min(), t_mid**0.6, 0.6]

    # free parameters (fs_inf - fk, fk, gamma, kappa): the model requires mu_inf >= mu_k
    def model(th: np.ndarray) -> np.ndarray:
        rise, fk, gamma, kappa = th
        params = KatoRisingParams(mu_k=fk, mu_inf=fk + rise, gamma=gamma, kappa=kappa)
        return rising_static_friction_kato(t, params)

    def resid(th: np.ndarray) -> np.ndarray:
        return (model(th) - f) * w

    x0 = [max(x0[0] - x0[1], 0.0), max(x0[1], 0.0), x0[2], x0[3]]
    sol = optimize.least_squares(resid, x0, bounds=([0.0, 0.0, 1e-12, 0.05],
                                                    [np.inf, np.inf, np.inf, 5.0]),
                                 x_scale="jac")
    T = np.eye(4)
    T[0, 1] = 1.0  # fs_inf = rise + fk
    sol.x = T @ sol.x
    sol.jac = sol.jac @ np.linalg.inv(T)
    n, k = t.size, 4
    chi2 = float(sol.fun @ sol.fun) / max(n - k, 1)
    scale = max(chi2, 1.0) if fs_stderr is not None else chi2
    cov = np.linalg.pinv(sol.jac.T @ sol.jac) * scale
    se = np.sqrt(np.abs(np.diag(cov)))
    fs_inf, fk, gamma, kappa = map(float, sol.x)
    tau = gamma ** (1.0 / kappa)
    if not (tpos.size and tpos.min() <= tau <= tpos.max()):
        raise IdentificationError(
            f"the rise time scale gamma^(1/kappa) = {tau:.3g} s lies outside the measured "
            "dwell times; add breakaway tests with dwell times around it (log-spaced); got "
            f"dwell range {t.min():.3g}…{t.max():.3g} s"
        )
    names = ("fs_inf", "fk", "gamma", "kappa")
    units = (unit, unit, "s^kappa", "-")
    return Estimate(
        method="rising-static-friction-2.6",
        params={nm: Parameter(v, s, un) for nm, v, s, un in
                zip(names, map(float, sol.x), map(float, se), units, strict=True)},
        diagnostics={"chi2_red": chi2, "n": n, "time_scale_s": tau},
    )


# -- backlash and static stiffness --------------------------------------------------------

def estimate_backlash_stiffness(
    load: np.ndarray, position: np.ndarray, *, x_ref: float | None = None,
    load_unit: str = "N·m", position_unit: str = "rad",
) -> Estimate:
    """Backlash gap and stiffness from ± constant-load (static deflection) tests.

    Parameters
    ----------
    load : array_like, shape (n,)
        Constant torques or forces applied in each test, both signs [N·m or N]; at least
        two distinct levels per sign.
    position : array_like, shape (n,)
        Settled output-relative position under each load [rad or m].
    x_ref : float, optional
        Reference position (e.g. the assembly zero) for ``gap_plus``/``gap_minus`` [rad
        or m].
    load_unit, position_unit : str
        Units for the result.

    Returns
    -------
    Estimate
        ``gap`` total gapwidth [rad or m], ``x_center``, ``K`` stiffness [N·m/rad or N/m],
        and with ``x_ref``: ``gap_plus = x_center + gap/2 − x_ref``,
        ``gap_minus = x_ref − (x_center − gap/2)``.

    Raises
    ------
    IdentificationError
        If one sign is missing or a sign has a single load level (gap and deflection
        then cannot be separated).

    Notes
    -----
    Model: ``x = x_center + (gap/2)·sgn(T) + T/K`` — the load takes up the gap, then
    deflects the compliance linearly (thesis §7 outline: "backlash can be determined by
    applying some constant torque and measuring the relative shaft displacements").
    The gap is bounded, ``gap >= 0``: when the unconstrained fit gives a negative gap the
    constrained least squares holds it at 0 (``x_center`` and ``K`` refitted without the
    sign column), ``diagnostics["at_bound"]["gap"]`` gives the unconstrained value and the
    one-sided 95 % upper limit, and a warning names the likely cause.

    Examples
    --------
    >>> import numpy as np
    >>> T = np.array([-2.0, -1.0, 1.0, 2.0])
    >>> est = estimate_backlash_stiffness(T, 0.005 * np.sign(T) + T / 100.0)
    >>> round(est.value("gap"), 6), round(est.value("K"), 3)
    (0.01, 100.0)
    """
    T = np.asarray(load, dtype=float).ravel()
    x = np.asarray(position, dtype=float).ravel()
    if T.size != x.size:
        raise ParameterError(f"load and position must have equal length; got {T.size}, {x.size}")
    for s, name in ((1, "positive"), (-1, "negative")):
        levels = np.unique(T[np.sign(T) == s])
        if levels.size < 2:
            raise IdentificationError(
                f"{name} load needs at least 2 distinct levels to separate the gap from the "
                f"elastic deflection; add a {name} constant-load test at another level; got "
                f"{levels.size}"
            )
    A = np.column_stack([np.ones_like(T), np.sign(T), T])
    theta, se, _ = _linear_fit(A, x)
    xc, half, comp = map(float, theta)
    se = [float(v) for v in se]
    if not comp > 0:
        raise IdentificationError(
            "fitted compliance is not positive; the tests do not show elastic deflection "
            f"(loads too small or positions not settled); got {comp:.3g}"
        )
    diagnostics: dict[str, Any] = {"n": int(T.size)}
    warnings: list[str] = []
    if half < 0:
        # gap >= 0: the constrained least squares has the gap at 0, the rest refitted
        entry, message = held_at_zero("gap", 2 * half, 2 * se[1], position_unit, GAP_HINT)
        diagnostics["at_bound"] = {"gap": entry}
        warnings.append(message)
        theta2, se2, _ = _linear_fit(np.column_stack([np.ones_like(T), T]), x)
        xc, comp, half = float(theta2[0]), float(theta2[1]), 0.0
        se = [float(se2[0]), se[1], float(se2[1])]
        if not comp > 0:
            raise IdentificationError(
                "with the gap held at its bound 0 (the unconstrained fit gave "
                f"{2 * float(theta[1]):.3g}) the compliance is not positive: the positions fall "
                "as the load rises through zero, which neither backlash nor a spring does "
                "(positions read before they settled, a sign error in load or position, or a "
                f"preload); check the test; got compliance {comp:.3g}")
    K = 1.0 / comp
    params = {
        "gap": Parameter(2 * half, 2 * se[1], position_unit),
        "x_center": Parameter(xc, se[0], position_unit),
        "K": Parameter(K, K * se[2] / comp, f"{load_unit}/{position_unit}"),
    }
    if x_ref is not None:
        gse = math.hypot(se[0], se[1])
        params["gap_plus"] = Parameter(xc + half - x_ref, gse, position_unit)
        params["gap_minus"] = Parameter(x_ref - (xc - half), gse, position_unit)
    return Estimate(method="backlash-static-deflection", params=params,
                    diagnostics=diagnostics, warnings=tuple(warnings))


def estimate_static_stiffness(
    load: np.ndarray, deflection: np.ndarray, *, load_unit: str = "N·m",
    position_unit: str = "rad",
) -> Estimate:
    """Stiffness from a static deflection test: ``deflection = x0 + load/K``.

    Parameters
    ----------
    load : array_like, shape (n,)
        Applied static loads [N·m or N]; n >= 3, not all equal.
    deflection : array_like, shape (n,)
        Measured deflections [rad or m].
    load_unit, position_unit : str
        Units for the result.

    Returns
    -------
    Estimate
        ``K`` [N·m/rad or N/m] and ``x0`` [rad or m] with standard errors.

    Raises
    ------
    IdentificationError
        If fewer than 3 tests or fewer than 2 distinct loads.

    Examples
    --------
    >>> import numpy as np
    >>> est = estimate_static_stiffness(np.array([1.0, 2.0, 3.0]), np.array([0.01, 0.02, 0.03]))
    >>> round(est.value("K"), 6)
    100.0
    """
    T = np.asarray(load, dtype=float).ravel()
    x = np.asarray(deflection, dtype=float).ravel()
    if T.size != x.size or T.size < 3 or np.unique(T).size < 2:
        raise IdentificationError(
            "static stiffness needs at least 3 tests at 2 or more load levels (equal-length "
            f"arrays); add loads; got {T.size} loads at {np.unique(T).size} level(s), "
            f"{x.size} deflections"
        )
    theta, se, _ = _linear_fit(np.column_stack([np.ones_like(T), T]), x)
    x0, comp = map(float, theta)
    se = [float(v) for v in se]
    if not comp > 0:
        raise IdentificationError(f"deflection does not grow with load; got slope {comp:.3g}")
    K = 1.0 / comp
    return Estimate(method="static-deflection", params={
        "K": Parameter(K, K * se[1] / comp, f"{load_unit}/{position_unit}"),
        "x0": Parameter(x0, se[0], position_unit),
    }, diagnostics={"n": int(T.size)})


def _linear_fit(A: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    m, p = A.shape
    theta, *_ = np.linalg.lstsq(A, y, rcond=None)
    e = y - A @ theta
    s2 = float(e @ e) / (m - p) if m > p else 0.0
    cov = s2 * np.linalg.pinv(A.T @ A)
    return theta, np.sqrt(np.abs(np.diag(cov))), s2


# -- step response ------------------------------------------------------------------------

def _crossing(t: np.ndarray, y: np.ndarray, level: float) -> float:
    i = int(np.argmax(y >= level))
    if i == 0:
        return float(t[0])
    return float(t[i - 1] + (level - y[i - 1]) * (t[i] - t[i - 1]) / (y[i] - y[i - 1]))


def step_metrics(
    t: np.ndarray, y: np.ndarray, *, y0: float, y_final: float, band: float = 0.02,
    rise: tuple[float, float] = (0.1, 0.9),
) -> dict[str, float]:
    """Measure overshoot, peak, rise and settling times of one step response.

    Python counterparts of the thesis's ``OverSht.m``, ``Rising.m`` and ``Settling.m``
    (App. B.6.5).

    Parameters
    ----------
    t : array_like, shape (n,)
        Times from the step instant [s] (t[0] = 0 at the step).
    y : array_like, shape (n,)
        Response [any unit].
    y0, y_final : float
        Level before the step and settled level after it [unit of y]; must differ.
    band : float
        Settling band as a fraction of the step size [-] (2 % default).
    rise : tuple of float
        Rise-time fractions of the step [-] (10–90 % default).

    Returns
    -------
    dict
        ``overshoot_pct`` [%], ``peak_time`` [s] (parabolic sub-sample refinement),
        ``rise_time`` [s], ``settling_time`` [s] (linear interpolation at the last band
        exit).

    Raises
    ------
    IdentificationError
        If the step size is zero or the response never reaches the upper rise fraction.
    """
    t = np.asarray(t, dtype=float)
    y = np.asarray(y, dtype=float)
    step = y_final - y0
    if step == 0:
        raise IdentificationError("step size y_final − y0 is zero; got 0")
    z = (y - y0) / step  # normalised, rising to 1
    if not np.any(z >= rise[1]):
        raise IdentificationError(
            f"response never reaches {100 * rise[1]:g} % of the step; lengthen the half "
            f"period of the square wave; got max {100 * float(z.max()):.3g} %"
        )
    i = int(np.argmax(z))
    if 0 < i < z.size - 1:
        a, b, c = z[i - 1], z[i], z[i + 1]
        den = a - 2 * b + c
        d = 0.5 * (a - c) / den if den != 0 else 0.0
        zmax = b - 0.25 * (a - c) * d
        tpk = t[i] + d * (t[i + 1] - t[i])
    else:
        zmax, tpk = z[i], t[i]
    t_rise = _crossing(t, z, rise[1]) - _crossing(t, z, rise[0])
    out = np.flatnonzero(np.abs(z - 1.0) > band)
    if out.size == 0:
        t_settle = float(t[0])
    elif out[-1] == z.size - 1:
        t_settle = math.nan
    else:
        j = int(out[-1])
        e0, e1 = abs(z[j] - 1) - band, abs(z[j + 1] - 1) - band
        t_settle = float(t[j] + e0 / (e0 - e1) * (t[j + 1] - t[j]))
    return {"overshoot_pct": 100.0 * max(float(zmax) - 1.0, 0.0), "peak_time": float(tpk),
            "rise_time": float(t_rise), "settling_time": t_settle}


def estimate_step_response(
    record: Record, *, reference: np.ndarray | None = None, band: float = 0.02,
    settle_fraction: float = 0.2,
) -> Estimate:
    """Second-order ζ and ω0 from the steps of a DC-biased square-wave test.

    Parameters
    ----------
    record : Record
        Response in ``v`` (velocity, for a speed-loop test) if present, else ``x``
        [any unit]; the square-wave command in ``u`` unless ``reference`` is given.
    reference : array_like, shape (n,), optional
        Square-wave command [any unit]; its jumps mark the steps.
    band : float
        Settling band fraction [-].
    settle_fraction : float
        Final fraction of each half period averaged as the settled level [-]; the
        response must have settled there.

    Returns
    -------
    Estimate
        Means over all steps (standard error = std/√n, nan for one step):
        ``overshoot_pct`` [%], ``peak_time``, ``rise_time``, ``settling_time`` [s],
        ``zeta`` [-], ``omega_d``, ``omega0`` [rad/s].

    Raises
    ------
    IdentificationError
        If the command has no jumps, or a step shows no overshoot above the settled
        scatter and 0.1 % (ζ near or above 1 cannot be read from overshoot: raise the
        loop gain or use another test).

    Notes
    -----
    For an underdamped second-order system the overshoot ``OS = exp(−ζπ/√(1−ζ²))`` gives
    ``ζ = −ln OS / √(π² + ln² OS)``, and the peak time ``tp = π/ω_d`` gives
    ``ω_d = π/tp`` and ``ω0 = ω_d/√(1−ζ²)``. These two are exact; rise and settling
    times are reported but not used (their second-order formulas are approximations).
    """
    r = np.asarray(record.u if reference is None else reference, dtype=float)
    if r is None or r.size != record.n:
        raise RecordError("a step-response test needs the square-wave command (record.u or "
                          f"reference) with one value per sample; got {np.size(r)}")
    y = np.asarray(record.v if record.v is not None else record.x, dtype=float)
    jumps = np.abs(np.diff(r))
    thr = 0.5 * float(jumps.max()) if jumps.size else 0.0
    edges = np.flatnonzero(jumps > thr) + 1 if thr > 0 else np.array([], int)
    if edges.size == 0:
        raise IdentificationError("the command has no jumps; apply a DC-biased square wave; "
                                  "got a constant command")
    bounds = list(edges) + [record.n]
    rows = []
    for k in range(len(edges)):
        a, b = int(bounds[k]), int(bounds[k + 1])
        n_set = max(3, int(settle_fraction * (b - a)))
        if b - a < 20:
            continue
        y_final = float(np.mean(y[b - n_set:b]))
        y0 = float(np.mean(y[max(0, a - n_set):a]))
        # the command switches at sample a (zero-order hold): time runs from t[a]
        m = step_metrics(record.t[a:b] - record.t[a], y[a:b], y0=y0, y_final=y_final,
                         band=band)
        os_ = m["overshoot_pct"] / 100.0
        # an overshoot inside the settled scatter (or below 0.1 %, ζ > 0.91) is not one
        floor = max(3.0 * float(np.std(y[b - n_set:b])) / abs(y_final - y0), 1e-3)
        if os_ <= floor:
            raise IdentificationError(
                "a step shows no overshoot, so ζ cannot be read from it (ζ >= 1); raise the "
                f"loop gain or identify by another test; got overshoot 0 at t = "
                f"{record.t[a]:.4g} s"
            )
        lo = math.log(os_)
        zeta = -lo / math.sqrt(math.pi**2 + lo**2)
        wd = math.pi / m["peak_time"]
        rows.append({**m, "zeta": zeta, "omega_d": wd, "omega0": wd / math.sqrt(1 - zeta**2)})
    if not rows:
        raise IdentificationError("no complete step found; record whole half periods; got 0")
    units = {"overshoot_pct": "%", "peak_time": "s", "rise_time": "s", "settling_time": "s",
             "zeta": "-", "omega_d": "rad/s", "omega0": "rad/s"}
    params = {}
    for name, unit in units.items():
        vals = np.array([row[name] for row in rows])
        se = float(vals.std(ddof=1) / math.sqrt(vals.size)) if vals.size > 1 else math.nan
        params[name] = Parameter(float(np.mean(vals)), se, unit)
    return Estimate(method="step-response-2nd-order", params=params,
                    data_used={"step_index": [int(e) for e in edges]},
                    diagnostics={"n_steps": len(rows)})
