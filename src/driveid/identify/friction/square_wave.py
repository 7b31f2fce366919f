r"""J, C, K, kinetic and static friction from DC-biased square-wave (step) runs.

The thesis's step test (ch. 4) yields only ζ and ω0 from the ringing after each step. Here
the whole record is used.

Moving samples: inverse-model least squares
-------------------------------------------
While the axis moves (thesis Eq. (2.155), DESIGN.md signs)

.. math:: u = J x'' + c_{mean} x' + c_{delta} |x'| + K x + fk_{mean}\,\mathrm{sgn}\,x' + fk_{delta},

linear in the parameters. ``x'`` and ``x''`` come from a Savitzky–Golay fit (quintic, window
``smooth`` s, by default the shortest window whose x'' noise is 5 % of the signal's, so
that the errors-in-variables bias towards J = 0 stays near 0.25 %; its bias on a ringing at
ω is ``O((ω·smooth)⁴)``); samples within one window
of a step of u or of a velocity reversal are skipped (there x'' jumps and the smoothed
derivatives are wrong), and so are samples slower than ``v_min``. Each step rings at ω_d, so
the regressors x'', x', x are well separated and J, C, K come out together. Standard errors:
OLS covariance ``s²(AᵀA)⁻¹`` multiplied by the smoothing window in samples (the residuals of
a smoothed derivative are correlated over about one window; a conservative inflation,
checked by the seeded Monte Carlo of ``tests/identify/test_square_wave.py``).

Stuck half-periods: static friction
-----------------------------------
With a low DC bias some half-periods do not move the axis: there the net force
``|u - K x|`` stayed within the static band. Every half-period that starts at rest bounds
the breakaway level ``fs_s`` in the direction ``s`` of the net force at the step: a stuck
one proves ``fs_s >= |u - K x|``, a breakaway proves ``fs_s <= |u - K x|``. The static
level per direction is the midpoint of the tightest bracket, its standard error the
bracket half-width over √3 (uniform within the bracket); ``fs_mean`` and ``fs_delta``
combine the two directions (thesis (2.137)-(2.138)).

References
----------
.. [1] J. A. de Marchi, "Modeling of dynamic friction, impact backlash and elastic compliance
       nonlinearities in machine tools", PhD thesis, Rensselaer Polytechnic Institute, 1998,
       Eqs. (2.137)-(2.138), (2.155), ch. 4.
.. [2] A. Savitzky, M. J. E. Golay, "Smoothing and differentiation of data by simplified least
       squares procedures", Anal. Chem. 36(8), 1627-1639, 1964. doi:10.1021/ac60214a047
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from scipy.signal import savgol_filter

from driveid.errors import IdentificationError, ParameterError, RecordError
from driveid.identify.core.estimate import Estimate, Parameter
from driveid.io.record import Record
from driveid.signal.differentiate import savgol_window

__all__ = ["estimate_square_wave"]

_NAMES = ("J", "c_mean", "c_delta", "K", "fk_mean", "fk_delta")


def _units(record: Record) -> dict[str, str]:
    if record.units.get("x", "rad") == "m":
        return {"J": "kg", "c_mean": "N·s/m", "c_delta": "N·s/m", "K": "N/m",
                "fk_mean": "N", "fk_delta": "N", "fs_mean": "N", "fs_delta": "N"}
    return {"J": "kg·m²", "c_mean": "N·m·s/rad", "c_delta": "N·m·s/rad", "K": "N·m/rad",
            "fk_mean": "N·m", "fk_delta": "N·m", "fs_mean": "N·m", "fs_delta": "N·m"}


def _near(mask: np.ndarray, half: int) -> np.ndarray:
    """Mark the samples within ``half`` samples of any True of ``mask``."""
    kernel = np.ones(2 * half + 1)
    return np.convolve(mask.astype(float), kernel, mode="same") > 0


def estimate_square_wave(records: Record | Sequence[Record], *, smooth: float | None = None,
                         v_min: float | None = None,
                         move_tol: float | None = None) -> Estimate:
    r"""J, C, K, kinetic and (where stuck half-periods exist) static friction.

    Parameters
    ----------
    records : Record or sequence of Record
        Runs with ``t`` [s], ``x`` [rad or m] and the square-wave input ``u`` [N·m or N]
        (DC-biased; a spring or position loop inside ``u`` is not allowed: u is the
        external force on the axis, which has its own stiffness K > 0).
    smooth : float, optional
        Savitzky–Golay window [s] for x' and x'' (>= 7 samples); default from the record's
        noise: the shortest window, at least 10 ms, whose x'' noise is 5 % of the x''
        signal (:func:`driveid.signal.differentiate.savgol_window`).
    v_min : float, optional
        Moving threshold [rad/s or m/s]; default 2 % of the largest |x'|.
    move_tol : float, optional
        A half-period whose position range stays below this counts as stuck [rad or m];
        default 20 × the rms of x - smoothed x (noise), at least 1e-9 of the range of x.

    Returns
    -------
    Estimate
        Method ``"square-wave"``: ``J``, ``c_mean``, ``c_delta``, ``K``, ``fk_mean``,
        ``fk_delta`` with standard errors and covariance; ``fs_mean``, ``fs_delta`` when
        both a stuck and a moving half-period bracket the static level in each direction.
        Diagnostics: ``n_used``, ``n_half_periods``, ``n_stuck``, ``residual_rms``.

    Raises
    ------
    RecordError
        A record without ``u``.
    IdentificationError
        Too few moving samples or a singular regressor (no ringing: add stiffness or
        shorten the steps).
    ParameterError
        On a bad argument.

    Examples
    --------
    >>> t = np.arange(4000) / 1000
    >>> x = np.exp(-t) * np.sin(10 * t) + 0.2 * np.sin(3 * t)
    >>> v = np.gradient(x, t); a = np.gradient(v, t)
    >>> u = 0.01 * a + 0.02 * v + 1.0 * x + 0.05 * np.sign(v)
    >>> est = estimate_square_wave(Record(t=t, x=x, u=u), smooth=0.02)
    >>> round(est.value("K"), 2), round(est.value("fk_mean"), 2)
    (1.0, 0.05)
    """
    records = [records] if isinstance(records, Record) else list(records)
    if not records or not all(isinstance(r, Record) for r in records):
        raise ParameterError("records must be one or more Records")
    if smooth is not None and not (math.isfinite(smooth) and smooth > 0):
        raise ParameterError(f"smooth must be a positive window [s]; got {smooth!r}")
    rows, ys, brackets = [], [], {1: [-math.inf, math.inf], -1: [-math.inf, math.inf]}
    n_half = n_stuck = 0
    windows: list[float] = []
    pending_static = []
    for rec in records:
        if rec.u is None:
            raise RecordError("a square-wave record needs the input u (column 'u'); got none")
        # Savitzky-Golay derivatives assume one interval: an uneven clock is resampled, warned
        rec = rec.resampled_uniform(purpose="the Savitzky-Golay derivatives of the square-wave "
                                    "fit")
        dt = rec.dt
        if smooth is None:
            # from the noise: the shortest window whose x'' noise is 5 % of the signal's
            win = max(savgol_window(rec.x, dt, polyorder=5, shortest=0.01), 7)
        else:
            win = max(int(round(smooth / dt)) | 1, 7)
        windows.append(win * dt)
        if win > rec.n // 2:
            raise RecordError(f"smooth={win * dt:g} s is {win} samples, over half the record; "
                              "use a shorter window")
        x, u = np.asarray(rec.x, float), np.asarray(rec.u, float)
        xs = savgol_filter(x, win, 5)
        v = savgol_filter(x, win, 5, deriv=1, delta=dt)
        a = savgol_filter(x, win, 5, deriv=2, delta=dt)
        vmin = 0.02 * float(np.max(np.abs(v))) if v_min is None else float(v_min)
        steps = np.zeros(rec.n, bool)
        steps[1:] = np.abs(np.diff(u)) > 0.1 * np.ptp(u)      # the square wave's edges
        reversals = np.zeros(rec.n, bool)
        reversals[1:] = np.sign(v[1:]) != np.sign(v[:-1])
        use = (np.abs(v) > vmin) & ~_near(steps | reversals, win)
        use[: win] = use[-win:] = False
        rows.append(np.column_stack([a, v, np.abs(v), x, np.sign(v), np.ones_like(v)])[use])
        ys.append(u[use])
        noise = float(np.sqrt(np.mean((x - xs) ** 2)))
        tol = max(20 * noise, 1e-9 * float(np.ptp(x))) if move_tol is None else move_tol
        edges = np.concatenate([[0], np.flatnonzero(steps), [rec.n]])
        for lo, hi in zip(edges[:-1], edges[1:], strict=True):
            if hi - lo < 3:
                continue
            n_half += 1
            moved = float(np.ptp(x[lo:hi])) > tol
            n_stuck += not moved
            # a static test only if the axis was at rest over the window before the step
            if lo >= win and float(np.ptp(x[lo - win:lo])) <= tol:
                pending_static.append((u[lo], x[lo - 1], moved))
    A, y = np.vstack(rows), np.concatenate(ys)
    p = A.shape[1]
    if y.size < 3 * p:
        why = ("excite larger motions, lower v_min or shorten the smoothing window"
               if smooth is not None else
               f"the position noise needs a {1e3 * max(windows):.3g} ms derivative window "
               "(x'' noise 5 % of the signal), which leaves too little between the steps: "
               "record with less noise or a finer encoder, excite larger motions, or give a "
               "shorter smoothing window (more noise, J biased low)")
        raise IdentificationError(
            f"{y.size} moving samples away from steps and reversals; need >= {3 * p}: {why}")
    scale = np.linalg.norm(A, axis=0)
    scale[scale == 0] = 1.0
    cond = float(np.linalg.cond(A / scale))
    if cond > 1e10:
        raise IdentificationError(
            f"the square-wave runs do not separate J, C, K and friction (condition "
            f"{cond:.3g}); steps must ring (K > 0) in both directions")
    theta, *_ = np.linalg.lstsq(A, y, rcond=None)
    resid = y - A @ theta
    s2 = float(resid @ resid) / max(y.size - p, 1)
    inflation = max(int(round(max(windows) / records[0].dt)), 1)
    cov = s2 * np.linalg.inv(A.T @ A) * inflation
    se = np.sqrt(np.diag(cov))
    units = _units(records[0])
    params = {n: Parameter(float(theta[k]), float(se[k]), units[n])
              for k, n in enumerate(_NAMES)}
    K = float(theta[3])
    # static brackets: net force on the axis at the step, signed by its direction
    for u0, x0, moved in pending_static:
        net = u0 - K * x0
        s = 1 if net > 0 else -1
        level = abs(net)
        lo_hi = brackets[s]
        if moved:
            lo_hi[1] = min(lo_hi[1], level)
        else:
            lo_hi[0] = max(lo_hi[0], level)
    warnings = []
    fs_dir = {}
    for s, (lo, hi) in brackets.items():
        if math.isfinite(lo) and math.isfinite(hi) and lo <= hi:
            fs_dir[s] = (0.5 * (lo + hi), (hi - lo) / (2 * math.sqrt(3)))
    if len(fs_dir) == 2:
        (fp, sp), (fm, sm) = fs_dir[1], fs_dir[-1]
        # thesis (2.137)-(2.138): breakaway at +(fs_mean + fs_delta) and -(fs_mean - fs_delta)
        params["fs_mean"] = Parameter(0.5 * (fp + fm), 0.5 * math.hypot(sp, sm),
                                      units["fs_mean"])
        params["fs_delta"] = Parameter(0.5 * (fp - fm), 0.5 * math.hypot(sp, sm),
                                       units["fs_delta"])
    else:
        warnings.append(
            "static friction not bracketed: it needs, in each direction, a half-period "
            "that stayed stuck and one that broke away (lower the DC bias or the amplitude "
            f"step by step); stuck half-periods: {n_stuck} of {n_half}")
    return Estimate(
        method="square-wave", params=params,
        covariance={"names": list(_NAMES), "matrix": cov},
        data_used={"static_brackets": {"plus": brackets[1], "minus": brackets[-1]}},
        diagnostics={"n_used": int(y.size), "n_half_periods": n_half, "n_stuck": n_stuck,
                     "residual_rms": math.sqrt(s2), "condition": cond,
                     "se_inflation": inflation, "smooth_s": [float(w) for w in windows]},
        warnings=tuple(warnings),
    )
