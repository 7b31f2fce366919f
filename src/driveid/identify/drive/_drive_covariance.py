"""Error bars of the drive fit: polish with the local Jacobian, covariance, adequacy.

The covariance ``s² (JᵀJ)⁻¹`` of the prewhitened *local* Jacobian
(:meth:`DriveProblem.local_jacobian`), a Newey-West sandwich where the encoder's rounding
is not dithered or the residual is not white after the noise model, the Ljung-Box test of
each channel's residual; see :mod:`driveid.identify.drive.drive_fit`.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.optimize import least_squares
from threadpoolctl import threadpool_limits

from driveid.identify.drive._drive_encoder import _quantised

__all__: list[str] = []

_BOUND_TOL = 1e-6  # relative distance to a bound counted as "at the bound" [-]


def _channel_noise(y: np.ndarray) -> float:
    """Noise level of a channel from its second differences [its unit] (start weight)."""
    d2 = np.diff(y, 2)
    s = float(np.sqrt(np.mean(d2 * d2) / 6.0)) if d2.size else 0.0
    span = float(np.ptp(y)) or 1.0
    return max(s, 1e-9 * span)


def _finish(st: dict, recs, warnings: list[str]) -> dict:
    """Polish a stage's fit and compute its covariance, bounds and residual whiteness."""
    sol, fit = st["sol"], st["fit"]
    all_names, scale_all = st["all_names"], st["scale_all"]
    lower, upper = st["lower"], st["upper"]
    sol = _polish(fit, sol, lower, upper)
    with threadpool_limits(limits=1):
        jac = fit.jacobian(sol.x, local=True)
        resid = fit.residual(sol.x)
    if not sol.success:
        warnings.append(f"the least-squares fit stopped without converging ({sol.message})")
    z = sol.x
    span = np.maximum(np.abs(z), 1.0)
    at_bound = [j for j in range(z.size)
                if (z[j] - lower[j] <= _BOUND_TOL * span[j])
                or (z[j] - upper[j] >= -_BOUND_TOL * span[j])]
    free = [j for j in range(z.size) if j not in at_bound]
    n_obs = resid.size
    s2 = float(resid @ resid) / max(n_obs - len(free), 1)
    cov_z = np.full((z.size, z.size), np.nan)
    cond = math.nan
    if free:
        jf = jac[:, free]
        u_, sv, vt = np.linalg.svd(jf, full_matrices=False)
        cond = float(sv[0] / sv[-1]) if sv[-1] > 0 else math.inf
        if sv[-1] <= 1e-12 * sv[0]:
            warnings.append("the estimated parameters are not identifiable from these "
                            "channels (singular Jacobian); fix some or measure more channels")
        inv = (vt.T / np.maximum(sv, 1e-300) ** 2) @ vt
        cov_z[np.ix_(free, free)] = s2 * inv
    cov_method = "ar-prewhitened" if fit.filters is not None else "white"
    if free and _quantised(recs, fit, sol.x):
        # encoder rounding that noise does not dither follows the signal for long
        # stretches (constant while a body sticks): a Newey-West sandwich over the
        # weighted, unwhitened residual takes in that long-range correlation
        cov_z[np.ix_(free, free)] = _sandwich(fit, sol.x, free, recs)
        cov_method = "newey-west (quantised)"
    white = _whiteness(recs, fit, sol.x)
    if free and not all(w["white"] for w in white.values()) \
            and not cov_method.startswith("newey-west"):
        cov_z[np.ix_(free, free)] = _sandwich(fit, sol.x, free, recs)
        cov_method = "newey-west (not white)"
    cov = cov_z * np.outer(scale_all, scale_all)
    theta = z * scale_all
    for j in at_bound:
        warnings.append(f"{all_names[j]} = {theta[j]:.6g} ended at its bound "
                        f"({'lower' if z[j] - lower[j] <= _BOUND_TOL * span[j] else 'upper'}); "
                        "its standard error is not available and the others' hold it there")
    # the same shape as every estimator's (see _plausibility): name -> its bound
    held = {all_names[j]: {"bound": float((lower[j] if z[j] - lower[j] <= _BOUND_TOL * span[j]
                                           else upper[j]) * scale_all[j]),
                           "value": float(theta[j]), "at_bound": True} for j in at_bound}
    return {"stage": st, "sol": sol, "all_names": list(all_names), "theta": theta,
            "cov": cov, "problems": list(st["problems"]), "states0": st["states0"],
            "held": held, "nfev": int(sol.nfev), "cond": cond, "s2": s2,
            "cov_method": cov_method, "white": white}


def _warn_coloured(white: dict, warnings: list[str]) -> None:
    coloured = [key for key, w in white.items() if not w["white"]]
    if coloured:
        warnings.append(
            "the drive model does not explain the record: the residual of "
            + ", ".join(f"{key} (rms {white[key]['rms']:.3g})" for key in coloured)
            + " is not white after the noise model (Ljung-Box p < 0.01), so it holds motion "
            "the model misses; the error bars are a Newey-West sandwich instead, and even "
            "that is short where the fit is poor. An open-loop drive whose bodies stick and "
            "impact can be so sensitive to its parameters over a long record that the fit "
            "has no smooth minimum (docs/drive-fit.md): fit shorter records or a "
            "closed-loop test, or check the drive's structure (friction, a missing link)")


def _sandwich(fit, z: np.ndarray, free: list[int], recs) -> np.ndarray:
    """Newey-West covariance of the free parameters from the weighted, unwhitened residual."""
    from driveid.identify.core._noise import hac_covariance

    filters, fit.filters = fit.filters, None
    try:
        with threadpool_limits(limits=1):
            jw = fit.jacobian(z, local=True)[:, free]
            rw = fit.residual(z)
    finally:
        fit.filters = filters
    lengths = [rec.t.size for rec, prob in zip(recs, fit.problems, strict=True)
               for _ in prob.channels]
    return hac_covariance(jw, rw, segments=lengths)


def _whiteness(recs, fit, z: np.ndarray) -> dict:
    """Ljung-Box test of each channel's prewhitened residual, and its raw rms."""
    from driveid.validate import whiteness

    out = {}
    for r, (prob, res) in enumerate(zip(fit.problems, fit.raw_residuals(z), strict=True)):
        for c, ch in enumerate(prob.channels):
            key = ch if len(recs) == 1 else f"{ch}@{r + 1}"
            test = whiteness(fit._whiten(r, c, res[c] / fit.sigma[r][c]))
            out[key] = {"p_value": test["p_value"], "white": test["white"],
                        "rms": float(np.sqrt(np.mean(res[c] ** 2)))}
    return out


def _polish(fit, sol, lower, upper, max_nfev: int = 10):
    """Finish the fit with the local Jacobian (see :meth:`DriveProblem.local_jacobian`).

    The fit's 1e-3 secant straddles event kinks; where parameters nearly trade, the point
    where the *secant* gradient vanishes can sit about a standard error from the minimum
    along the weak direction (test bed, white noise, seed 1: the motor's viscous friction
    2.9 % and the delay 0.015 % from it, against standard errors of 3.3 % and 0.016 %). A few
    trust-region steps with the local derivative go on from there; kept only if they lower
    the objective.
    """
    lo = np.where(np.isfinite(lower), lower, -np.inf)
    try:
        with threadpool_limits(limits=1):
            pol = least_squares(fit.residual, sol.x,
                                jac=lambda z: fit.jacobian(z, local=True),
                                bounds=(lo, upper), method="trf", x_scale="jac",
                                max_nfev=max_nfev, xtol=1e-12, ftol=1e-12, gtol=1e-12)
    except ValueError:  # a non-finite trial: keep the fit's point
        return sol
    if pol.cost < sol.cost:
        pol.nfev += sol.nfev
        pol.success = sol.success or pol.success
        return pol
    return sol


#: Correlation of a parameter with an estimated start velocity above which the fit warns
#: [-]: two-body drive under delayed PD, c_1 against v0_1 -0.97 and -0.965 (seeds 1, 3),
#: where the error bars were half the scatter and giving v0 = 0 made them honest
#: (docs/drive-fit.md).
STATE_TRADE = 0.9


def start_velocity_trades(names, all_names, cov) -> list[str]:
    """Warn of parameters that trade with an estimated start velocity (``.v0`` states)."""
    cov = np.asarray(cov, float)
    sd = np.sqrt(np.abs(np.diag(cov)))
    states = [j for j, n in enumerate(all_names) if ".v0" in n]
    out = []
    for n in names:
        i = all_names.index(n)
        best = None
        for j in states:
            if sd[i] > 0 and sd[j] > 0 and np.isfinite(cov[i, j]):
                rho = float(cov[i, j] / (sd[i] * sd[j]))
                if abs(rho) >= STATE_TRADE and (best is None or abs(rho) > abs(best[1])):
                    best = (all_names[j], rho)
        if best is not None:
            out.append(
                f"{n} trades with the estimated start velocity {best[0]} (correlation "
                f"{best[1]:+.2f}): such error bars were measured about half the scatter; if "
                "the record starts at rest, give the start velocities (the TOML's [run] v0 "
                "= [0.0, ...]), which made them honest and the scatter several times smaller")
    return out
