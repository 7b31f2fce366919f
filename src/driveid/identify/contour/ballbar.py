"""Coulomb friction and backlash of each axis from a ball-bar record (radial deviation only).

A ball bar measures the radial deviation ``Δr(t)`` of the tool from the nominal circle and
nothing else: no command, no motor position. With the axes' masses, links and controllers
known (the config), the quadrant glitches and the lost-motion steps are still a function of
each axis's Coulomb friction ``fk_mean`` and backlash gap: an output-error fit of the simulated
radial deviation (:func:`driveid.sim.contour.simulate_contour`'s axes, friction on the table,
the gap split evenly) to the measured one finds them by Gauss-Newton (scipy
``least_squares``, forward-difference Jacobian; each axis is re-simulated only when its own
parameters change). Viscous friction and the friction asymmetry leave (almost) no radial
trace under a PID (the integral takes the offset, the viscous force lags tangentially), so
they are taken from the config and reported as given, with a warning saying so.

Standard errors: ``s² (JᵀJ)⁻¹`` at the optimum with ``s²`` the residual variance, the usual
output-error covariance for white measurement noise (thesis §4; Ljung 1999, §9.3).

References
----------
.. [1] J. A. de Marchi, "Modeling of dynamic friction, impact backlash and elastic
       compliance nonlinearities in machine tools", PhD thesis, RPI, 1998, §6.1.
.. [2] L. Ljung, *System Identification: Theory for the User*, 2nd ed., Prentice Hall, 1999.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np

from driveid.errors import IdentificationError
from driveid.identify.core.estimate import Estimate, Parameter
from driveid.sim.contour import circle_reference
from driveid.sim.contour_config import ContourConfig
from driveid.sim.drive_types import BacklashLink, BodyParams

__all__ = ["estimate_ball_bar", "identified_config"]


def _nominal(config: ContourConfig, a: str) -> dict[str, float]:
    axis = config.axes[a]
    bodies = axis.drive.bodies
    gap = sum(ln.gap_plus + ln.gap_minus for ln in axis.drive.links
              if ln is not None and hasattr(ln, "gap_plus"))
    return {"fk_mean": sum(b.fk_mean for b in bodies), "fk_delta": sum(b.fk_delta for b in bodies),
            "c_mean": sum(b.c_mean for b in bodies), "gap": gap}


def estimate_ball_bar(record: Any, config: ContourConfig, *, max_nfev: int = 12) -> Estimate:
    """Fit each plane axis's ``fk_mean`` and ``gap`` to a ball-bar radial deviation.

    Parameters
    ----------
    record : ContourRecord
        ``t`` [s] from the start of the path and ``radial`` [m], shape (n,).
    config : ContourConfig
        The axes and path; its friction and gaps are the starting values, its viscous
        friction and asymmetry are used as given.
    max_nfev : int
        Largest number of Gauss-Newton evaluations [-].

    Returns
    -------
    Estimate
        ``a.fk_mean`` [N] and ``a.gap`` [m] with standard errors; ``a.c_mean`` [N·s/m] and
        ``a.fk_delta`` [N] fixed (given); diagnostics ``rms_residual`` [m], ``nfev``,
        ``whiteness_p``.

    Raises
    ------
    IdentificationError
        If the record covers no constant-feed part of the path.
    """
    from scipy.optimize import least_squares

    from driveid.sim.contour import _axis_run
    from driveid.validate import whiteness

    path = config.path
    plane = path.axes
    t = np.asarray(record.t, float)
    dr = np.asarray(record.radial, float)
    steady = (t >= path.ramp) & (t <= path.ramp + path.constant_feed)
    if np.count_nonzero(steady) < 20:
        raise IdentificationError("the ball-bar record covers no constant-feed part of the "
                                  "path; its time must run from the start of the path (ramp "
                                  f"{path.ramp} s, then {path.constant_feed:.4g} s at feed)")
    nominal = {a: _nominal(config, a) for a in plane}
    scale = np.array([v for a in plane for v in (max(nominal[a]["fk_mean"], 1.0),
                                                  max(nominal[a]["gap"], 1e-6))])
    cache: dict[tuple, np.ndarray] = {}

    def axis_position(a: str, fk: float, gap: float) -> np.ndarray:
        key = (a, round(fk, 12), round(gap, 15))
        if key not in cache:
            params = {f"{b}.{n}": Parameter(v, math.nan, "-") for b in plane
                      for n, v in nominal[b].items()}
            params[f"{a}.fk_mean"] = Parameter(fk, math.nan, "N")
            params[f"{a}.gap"] = Parameter(gap, math.nan, "m")
            model = identified_config(Estimate(method="ball-bar-trial", params=params), config)
            axis = model.axes[a]
            res = _axis_run(axis, path, "1" if a == plane[0] else "2", None)
            cache[key] = res.x[axis.table]
        return cache[key]

    def radial(q: np.ndarray) -> np.ndarray:
        th = q * scale
        p1 = axis_position(plane[0], th[0], th[1])
        p2 = axis_position(plane[1], th[2], th[3])
        n = min(p1.size, t.size)
        return np.hypot(p1[:n], p2[:n]) - path.radius

    n = min(t.size, int(math.floor(path.duration * path.fs + 1e-9)) + 1)
    keep = steady[:n]

    def residual(q: np.ndarray) -> np.ndarray:
        return (radial(q)[:n] - dr[:n])[keep] * 1e6  # in µm: well scaled

    q0 = np.ones(4)
    fit = least_squares(residual, q0, bounds=(np.zeros(4), np.full(4, np.inf)),
                        diff_step=1e-3, max_nfev=max_nfev, x_scale=1.0)
    J = fit.jac / 1e6 / scale[None, :]  # d(residual [m]) / d(theta)
    e = fit.fun / 1e6
    dof = max(e.size - 4, 1)
    s2 = float(e @ e) / dof
    try:
        cov = s2 * np.linalg.inv(J.T @ J)
    except np.linalg.LinAlgError:
        raise IdentificationError("the ball-bar record does not determine the friction and "
                                  "gaps (singular Jacobian); record a whole revolution with "
                                  "all four reversals") from None
    theta = fit.x * scale
    se = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    params: dict[str, Parameter] = {}
    names = []
    for k, a in enumerate(plane):
        params[f"{a}.fk_mean"] = Parameter(float(theta[2 * k]), float(se[2 * k]), "N")
        params[f"{a}.gap"] = Parameter(float(theta[2 * k + 1]), float(se[2 * k + 1]), "m")
        params[f"{a}.c_mean"] = Parameter(nominal[a]["c_mean"], math.nan, "N·s/m", fixed=True)
        params[f"{a}.fk_delta"] = Parameter(nominal[a]["fk_delta"], math.nan, "N", fixed=True)
        names += [f"{a}.fk_mean", f"{a}.gap"]
    white = whiteness(e)
    theta_path = circle_reference(path, t[:n])["theta"]
    sign = 1.0 if path.direction == "ccw" else -1.0
    warnings = [f"ball-bar record: {', '.join(f'{a}.c_mean, {a}.fk_delta' for a in plane)} "
                "are taken from the config (they leave almost no radial trace under a PID); "
                "only fk_mean and the gap of each axis are fitted"]
    if not white["white"]:
        warnings.append(f"the ball-bar residual is not white (Ljung-Box p = "
                        f"{white['p_value']:.2g}): the model misses part of the contour; "
                        "the standard errors may be too small")
    return Estimate(
        method="contour-ballbar", params=params,
        data_used={"t": t[:n], "radial_measured": dr[:n], "angle": sign * theta_path,
                   "steady": steady[:n], "radial_simulated": radial(fit.x)[:n]},
        diagnostics={"rms_residual": float(math.sqrt(float(e @ e) / e.size)),
                     "nfev": int(fit.nfev), "whiteness_p": white["p_value"],
                     "simulated_axis_runs": len(cache), "plane": path.plane},
        warnings=tuple(warnings),
        covariance={"names": names, "matrix": cov},
        inputs=tuple(getattr(record, "meta", {}).get("inputs", ())))


def identified_config(estimate: Estimate, config: ContourConfig) -> ContourConfig:
    """Return the config with each plane axis's friction and gap taken from the estimate.

    The identified friction is put on the table (the last body), the other bodies keep their
    mass and lose their friction; the first backlash link takes the gap split evenly.

    Parameters
    ----------
    estimate : Estimate
        An :func:`~driveid.identify.contour.circle.estimate_contour` or
        :func:`estimate_ball_bar` result.
    config : ContourConfig
        The configuration the record came from.

    Returns
    -------
    ContourConfig
        The identified model of the axes.
    """
    axes = dict(config.axes)
    for a in config.path.axes:
        axis = axes[a]
        bodies = []
        for i, b in enumerate(axis.drive.bodies):
            keep = {"J": b.J, "K": b.K, "locked": b.locked}
            if i == axis.table:
                keep.update(c_mean=estimate.value(f"{a}.c_mean"),
                            fk_mean=max(estimate.value(f"{a}.fk_mean"), 0.0),
                            fk_delta=estimate.value(f"{a}.fk_delta"))
            bodies.append(BodyParams(**keep))
        links = list(axis.drive.links)
        gap = estimate.value(f"{a}.gap")
        for j, ln in enumerate(links):
            if isinstance(ln, BacklashLink) and math.isfinite(gap):
                links[j] = dataclasses.replace(ln, gap_plus=max(gap, 0.0) / 2,
                                               gap_minus=max(gap, 0.0) / 2)
                break
        drive = dataclasses.replace(axis.drive, bodies=tuple(bodies), links=tuple(links))
        axes[a] = dataclasses.replace(axis, drive=drive)
    return dataclasses.replace(config, axes=axes)
