r"""Parametric harmonic oscillation (PHO): J, C, K and the loop delay from PD-feedback runs.

de Marchi (1998) §2.2.7, Eqs. (2.180)-(2.192). Delayed PD feedback
``τ(t) = -[D γ'(t-Δ) + P γ(t-Δ)]`` on ``J γ'' + C γ' + K γ = τ`` makes even an overdamped
drive oscillate; each run (P_i, D_i) gives a measured decay rate σ_i and damped frequency
ω_d,i (e.g. from :func:`driveid.identify.logdec.estimate_log_decrement`), and a campaign of
runs gives the physical J, C, K.

The exact form
--------------
The measured root ``s = -σ + jω_d`` satisfies the characteristic equation of (2.180),

.. math::

    J s^2 + C s + K + (D s + P)\,e^{-s\Delta} = 0,

which is *linear* in (J, C, K). Write ``z = (D s + P) e^{-sΔ} = a s + b`` with real
``a = Im z / ω_d`` and ``b = Re z + a σ`` (:func:`delay_factors`). Since ``s`` is a root of
``s² + 2σ s + ω_0²`` (``ω_0² = σ² + ω_d²``), the real and imaginary parts give two real
equations per run, the exact version of (2.190):

.. math::

    C + a = 2 J \sigma, \qquad K + b = J \omega_0^2 .

Errata of §2.2.7 (checked numerically in ``tests/identify/test_pho.py``)
----------------------------------------------------------------------
* (2.186b) ``γ'(t') = ω_0² α_2 γ + α_1 γ'`` drops a term: differentiating (2.186a),
  ``γ'(t') = α_1 γ' - α_2 γ'' = ω_0² α_2 γ + (α_1 + 2σ α_2) γ'`` by (2.184). Hence
  (2.189) ``C_i = C + D α_1 - P α_2`` must read ``C_i = C + D(α_1 + 2σα_2) - P α_2``; the
  printed form is exact only at σ = 0 (or D = 0). (2.186a), (2.187) and ``K_i`` are exact.
* (2.181) prints ``e^{Δt}`` for ``e^{σΔt}``.
* (2.180) writes ``D_j`` with ``P_i``; both belong to the same run i.

A run with growing oscillation (σ < 0) is as valid as a decaying one.

References
----------
.. [1] J. A. de Marchi, "Modeling of dynamic friction, impact backlash and elastic compliance
       nonlinearities in machine tools", PhD thesis, Rensselaer Polytechnic Institute, 1998,
       §2.2.7, Table 5.3.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize_scalar

from driveid.errors import IdentificationError, ParameterError
from driveid.identify.estimate import Estimate, Parameter

__all__ = [
    "PHORun",
    "delay_factors",
    "delay_factors_thesis",
    "estimate_pho_campaign",
]


@dataclass(frozen=True, kw_only=True)
class PHORun:
    """One PD-feedback run of a parametric harmonic oscillation campaign.

    Attributes
    ----------
    P : float
        Proportional gain [N·m/rad or N/m]; finite.
    D : float
        Derivative gain [N·m·s/rad or N·s/m]; finite.
    sigma : float
        Measured decay rate σ = ζ ω_0 [1/s]; finite (negative for a growing oscillation).
    sigma_se : float
        Standard error of ``sigma`` [1/s]; > 0.
    omega_d : float
        Measured damped frequency ω_d [rad/s]; > 0 (the run must oscillate).
    omega_d_se : float
        Standard error of ``omega_d`` [rad/s]; > 0.
    """

    P: float
    D: float
    sigma: float
    sigma_se: float
    omega_d: float
    omega_d_se: float

    def __post_init__(self) -> None:
        for name in ("P", "D", "sigma", "sigma_se", "omega_d", "omega_d_se"):
            value = getattr(self, name)
            if not math.isfinite(value):
                raise ParameterError(f"PHORun.{name} must be finite; got {value!r}")
            object.__setattr__(self, name, float(value))
        for name in ("sigma_se", "omega_d_se"):
            if getattr(self, name) <= 0:
                raise ParameterError(
                    f"PHORun.{name} must be > 0 (it weights the run); pass the standard error "
                    f"of the decay fit; got {getattr(self, name)!r}"
                )
        if self.omega_d <= 0:
            raise IdentificationError(
                "PHORun.omega_d must be > 0: a run that does not oscillate gives no "
                "frequency; raise P (or lower D) until it oscillates and measure again; "
                f"got {self.omega_d!r}"
            )


def delay_factors(sigma, omega_d, delay, *, P, D):
    r"""Exact effective damping and stiffness added by delayed PD feedback.

    Returns real ``(a, b)`` with ``(D s + P) e^{-sΔ} = a s + b`` at ``s = -σ + jω_d``, so that
    the run behaves as ``J γ'' + (C + a) γ' + (K + b) γ = 0`` (exact form of (2.188)-(2.189)).

    Parameters
    ----------
    sigma : float or ndarray
        Decay rate σ [1/s].
    omega_d : float or ndarray
        Damped frequency ω_d [rad/s]; > 0.
    delay : float
        Loop delay Δ [s].
    P : float or ndarray
        Proportional gain [N·m/rad or N/m].
    D : float or ndarray
        Derivative gain [N·m·s/rad or N·s/m].

    Returns
    -------
    a : float or ndarray
        Added damping ``C_i - C`` [N·m·s/rad or N·s/m]; ``a = Im z / ω_d``.
    b : float or ndarray
        Added stiffness ``K_i - K`` [N·m/rad or N/m]; ``b = Re z + a σ``.

    Notes
    -----
    With ``z = a s + b`` and ``s`` complex, ``Im z = a ω_d`` and ``Re z = -a σ + b``. This
    equals ``D(α_1 + 2σα_2) - P α_2`` and ``P α_1 + ω_0² D α_2`` with α of (2.187); the
    thesis's (2.189) lacks the ``2σ D α_2`` term (see :func:`delay_factors_thesis`).

    Examples
    --------
    >>> a, b = delay_factors(0.5, 10.0, 0.0, P=2.0, D=0.1)
    >>> round(float(a), 12), round(float(b), 12)
    (0.1, 2.0)
    """
    s = -np.asarray(sigma, dtype=float) + 1j * np.asarray(omega_d, dtype=float)
    z = (D * s + P) * np.exp(-s * delay)
    a = z.imag / s.imag
    b = z.real + a * (-s.real)
    return a, b


def delay_factors_thesis(sigma, omega_d, delay, *, P, D):
    r"""Return the thesis's printed added damping and stiffness, (2.187) and (2.189).

    ``α_1 = e^{σΔ}[cos ω_dΔ - (σ/ω_d) sin ω_dΔ]``, ``α_2 = e^{σΔ} sin(ω_dΔ)/ω_d``,
    ``C_i - C = D α_1 - P α_2`` and ``K_i - K = P α_1 + ω_0² D α_2``.

    Parameters
    ----------
    sigma : float or ndarray
        Decay rate σ [1/s].
    omega_d : float or ndarray
        Damped frequency ω_d [rad/s]; > 0.
    delay : float
        Loop delay Δ [s].
    P : float or ndarray
        Proportional gain [N·m/rad or N/m].
    D : float or ndarray
        Derivative gain [N·m·s/rad or N·s/m].

    Returns
    -------
    a : float or ndarray
        Printed ``C_i - C`` [N·m·s/rad or N·s/m].
    b : float or ndarray
        Printed ``K_i - K`` [N·m/rad or N/m] (exact).

    Notes
    -----
    Erratum: (2.186b) drops ``2σα_2 γ'`` (``γ'(t') = α_1γ' - α_2γ''`` with
    ``γ'' = -ω_0²γ - 2σγ'``), so the printed ``C_i`` is short by ``2σ D α_2``; it is exact only
    when σ = 0 or D = 0. :func:`delay_factors` is the exact form.
    """
    sigma = np.asarray(sigma, dtype=float)
    omega_d = np.asarray(omega_d, dtype=float)
    growth = np.exp(sigma * delay)
    phase = omega_d * delay
    alpha1 = growth * (np.cos(phase) - sigma / omega_d * np.sin(phase))
    alpha2 = growth * np.sin(phase) / omega_d
    omega0_sq = sigma**2 + omega_d**2
    return D * alpha1 - P * alpha2, P * alpha1 + omega0_sq * D * alpha2


def _units(units: str) -> dict[str, str]:
    if units == "rad":
        return {"J": "kg·m²", "K": "N·m/rad", "c": "N·m·s/rad"}
    if units == "m":
        return {"J": "kg", "K": "N/m", "c": "N·s/m"}
    raise ParameterError(f"units must be 'rad' (rotational) or 'm' (linear); got {units!r}")


def _residuals(theta, K, runs_arr, delay):
    """Stacked residuals (2n,): ``C - 2σJ + a`` and ``K - ω_0² J + b`` per run."""
    J, C = theta[0], theta[1]
    P, D, sig, _, wd, _ = runs_arr.T
    a, b = delay_factors(sig, wd, delay, P=P, D=D)
    r1 = C - 2.0 * sig * J + a
    r2 = K - (sig**2 + wd**2) * J + b
    return np.column_stack([r1, r2])


def _run_covariances(J, runs_arr, delay):
    """Covariance (n, 2, 2) of each run's two residuals from its σ and ω_d standard errors."""
    P, D, sig, sig_se, wd, wd_se = runs_arr.T
    s = -sig + 1j * wd
    z = (D * s + P) * np.exp(-s * delay)
    dz = (D - delay * (D * s + P)) * np.exp(-s * delay)
    a = z.imag / wd
    # s depends on σ as -1 and on ω_d as j, so dz/dσ = -dz, dz/dω_d = j dz.
    a_sig = -dz.imag / wd
    a_wd = dz.real / wd - a / wd
    b_sig = -dz.real + sig * a_sig + a
    b_wd = -dz.imag + sig * a_wd
    grad = np.empty((len(sig), 2, 2))
    grad[:, 0, 0] = -2.0 * J + a_sig
    grad[:, 0, 1] = a_wd
    grad[:, 1, 0] = -2.0 * sig * J + b_sig
    grad[:, 1, 1] = -2.0 * wd * J + b_wd
    scale = np.zeros((len(sig), 2, 2))
    scale[:, 0, 0] = sig_se**2
    scale[:, 1, 1] = wd_se**2
    return grad @ scale @ np.transpose(grad, (0, 2, 1))


def _solve(runs_arr, delay, K_known, n_iter=4):
    """Effective-variance weighted least squares at a fixed delay.

    Returns ``(theta, cov, chi2, cond)`` with theta = (J, C, K) or (J, C).
    """
    n = runs_arr.shape[0]
    sig, wd = runs_arr[:, 2], runs_arr[:, 4]
    P, D = runs_arr[:, 0], runs_arr[:, 1]
    a, b = delay_factors(sig, wd, delay, P=P, D=D)
    # Rows per run: [J, C, K] coefficients of (C - 2σJ) = -a and (K - ω0²J) = -b.
    A = np.zeros((n, 2, 3))
    A[:, 0, 0] = -2.0 * sig
    A[:, 0, 1] = 1.0
    A[:, 1, 0] = -(sig**2 + wd**2)
    A[:, 1, 2] = 1.0
    y = np.column_stack([-a, -b])
    if K_known is not None:
        y = y.copy()
        y[:, 1] -= K_known
        A = A[:, :, :2]
    p = A.shape[2]
    theta = np.linalg.lstsq(A.reshape(2 * n, p), y.reshape(2 * n), rcond=None)[0]
    for _ in range(n_iter):
        cov_r = _run_covariances(theta[0], runs_arr, delay)
        W = np.linalg.inv(cov_r)
        # Whitening per run: L^T with W = L L^T.
        L = np.linalg.cholesky(W)
        Lt = np.transpose(L, (0, 2, 1))
        Aw = (Lt @ A).reshape(2 * n, p)
        yw = np.einsum("nij,nj->ni", Lt, y).reshape(2 * n)
        theta = np.linalg.lstsq(Aw, yw, rcond=None)[0]
    resid = Aw @ theta - yw
    chi2 = float(resid @ resid)
    cov = np.linalg.inv(Aw.T @ Aw)
    return theta, cov, chi2, float(np.linalg.cond(Aw)), Lt, A, y


def _joint_jacobian(runs_arr, delay, K_known, scale):
    """Parameters at ``delay``, whitened Jacobian in (parameters, Δ) and whitened residuals."""
    theta, _, _, _, Lt, A, y = _solve(runs_arr, delay, K_known)
    n, p = A.shape[0], A.shape[2]
    h = 1e-7 * max(delay, scale)
    P, D, sig, _, wd, _ = runs_arr.T
    a_p, b_p = delay_factors(sig, wd, delay + h, P=P, D=D)
    a_m, b_m = delay_factors(sig, wd, delay - h, P=P, D=D)
    dr = np.column_stack([(a_p - a_m) / (2 * h), (b_p - b_m) / (2 * h)])
    Aw = (Lt @ A).reshape(2 * n, p)
    yw = np.einsum("nij,nj->ni", Lt, y).reshape(2 * n)
    dw = np.einsum("nij,nj->ni", Lt, dr).reshape(2 * n, 1)
    return theta, np.hstack([Aw, dw]), Aw @ theta - yw


def estimate_pho_campaign(
    runs: Sequence[PHORun],
    *,
    delay: float | None = None,
    K_known: float | None = None,
    delay_bounds: tuple[float, float] | None = None,
    units: str = "rad",
) -> Estimate:
    r"""Physical J, C, K (and the loop delay) from a campaign of PD-feedback oscillations.

    Parameters
    ----------
    runs : sequence of PHORun
        Runs with their gains [N·m/rad, N·m·s/rad] and measured σ [1/s], ω_d [rad/s] with
        standard errors; at least two with different (P, D) (three if ``delay`` is None and
        K is unknown).
    delay : float, optional
        Known loop delay Δ [s], >= 0; estimated from the runs when None.
    K_known : float, optional
        Known stiffness [N·m/rad or N/m] (e.g. 0 for a free drive, the correction of Table
        5.3); then only J and C are fitted.
    delay_bounds : tuple of float, optional
        Search interval (lo, hi) for Δ [s]; default ``(0, π / (2 max ω_d))`` (phase lag below
        a quarter period).
    units : {"rad", "m"}
        Rotational or linear displacement.

    Returns
    -------
    Estimate
        ``J`` [kg·m² or kg], ``c_mean`` (viscous C) [N·m·s/rad or N·s/m], ``K`` [N·m/rad or
        N/m] (given value with zero error when ``K_known``), ``delay`` [s] (zero error when
        given), with standard errors. Diagnostics: ``chi2`` (weighted residual sum of
        squares, ~ 2n - p for consistent standard errors), ``dof``, ``condition``.

    Raises
    ------
    IdentificationError
        If fewer than two runs, all runs share one (P, D), too few runs for an unknown
        delay, or the design is singular.
    ParameterError
        If ``delay``, ``K_known``, ``delay_bounds`` or ``units`` are invalid.

    Notes
    -----
    Per run the exact equations ``C - 2σJ = -a`` and ``K - ω_0²J = -b`` (module notes) are
    linear in the parameters, but their right-hand sides and the factors 2σ, ω_0² all come
    from the measured σ, ω_d. The residual covariance of a run is therefore ``G S G^T``
    with ``G`` the Jacobian of its two residuals with respect to (σ, ω_d) at the current J
    and ``S = diag(σ_se², ω_d_se²)`` (the effective-variance form of total least squares:
    errors are in the regressors, not in an observed output). The weighted problem is solved
    a few times re-evaluating ``G`` at the new J. With the delay unknown, Δ minimises the
    weighted residual (grid of 64 points, then bounded Brent), and the standard errors come
    from the Gauss-Newton covariance of (parameters, Δ) jointly.
    """
    spec = _units(units)
    runs = list(runs)
    for i, run in enumerate(runs):
        if not isinstance(run, PHORun):
            raise ParameterError(f"runs[{i}] must be a PHORun; got {type(run).__name__}")
    if len(runs) < 2:
        raise IdentificationError(
            "a PHO campaign needs at least two runs with different (P, D); add a run with "
            f"another P (and/or D); got {len(runs)} run(s)"
        )
    gains = {(r.P, r.D) for r in runs}
    if len(gains) < 2:
        raise IdentificationError(
            "all runs share one (P, D), so J cannot be separated from the feedback; add a "
            f"run with a different P (and/or D); got only {gains}"
        )
    if K_known is not None and not math.isfinite(K_known):
        raise ParameterError(f"K_known must be finite or None; got {K_known!r}")
    runs_arr = np.array(
        [[r.P, r.D, r.sigma, r.sigma_se, r.omega_d, r.omega_d_se] for r in runs], dtype=float
    )
    n = len(runs)
    p = 2 if K_known is not None else 3
    if delay is not None:
        if not (math.isfinite(delay) and delay >= 0):
            raise ParameterError(f"delay must be finite and >= 0 [s], or None; got {delay!r}")
        theta, cov, chi2, cond, *_ = _solve(runs_arr, delay, K_known)
        delay_se = 0.0
        delay_hat = float(delay)
    else:
        if 2 * n <= p + 1:
            raise IdentificationError(
                f"estimating the delay with {p} other unknowns needs at least "
                f"{(p + 2) // 2 + (p + 2) % 2} runs (2 equations each, more than {p + 1} "
                f"unknowns); add a run with another (P, D) or pass delay=; got {n} runs"
            )
        if delay_bounds is None:
            delay_bounds = (0.0, math.pi / (2.0 * float(runs_arr[:, 4].max())))
        lo, hi = (float(v) for v in delay_bounds)
        if not (math.isfinite(lo) and math.isfinite(hi) and 0 <= lo < hi):
            raise ParameterError(
                f"delay_bounds must be finite with 0 <= lo < hi [s]; got {delay_bounds!r}"
            )

        def objective(d: float) -> float:
            return _solve(runs_arr, d, K_known)[2]

        grid = np.linspace(lo, hi, 64)
        values = [objective(d) for d in grid]
        k = int(np.argmin(values))
        res = minimize_scalar(
            objective,
            bounds=(grid[max(k - 1, 0)], grid[min(k + 1, len(grid) - 1)]),
            method="bounded",
            options={"xatol": 1e-14 * max(hi, 1.0)},
        )
        delay_hat = float(res.x)
        # Brent on chi2 (quadratic near the minimum) resolves Δ only to ~sqrt(eps);
        # Gauss-Newton steps on the linear-in-Δ residuals finish the job.
        for _ in range(4):
            theta, full, resid = _joint_jacobian(runs_arr, delay_hat, K_known, hi)
            step = np.linalg.lstsq(full, -resid, rcond=None)[0][p]
            delay_hat = float(min(max(delay_hat + step, lo), hi))
        theta, full, resid = _joint_jacobian(runs_arr, delay_hat, K_known, hi)
        _, _, chi2, cond, *_ = _solve(runs_arr, delay_hat, K_known)
        cov_full = np.linalg.inv(full.T @ full)
        cov = cov_full[:p, :p]
        delay_se = float(math.sqrt(cov_full[p, p]))
    if not np.isfinite(cond) or cond > 1e12:
        raise IdentificationError(
            "the runs do not separate J, C and K (singular design); add runs with widely "
            f"different P so that ω_0 differs between runs; got condition number {cond:.3g}"
        )
    se = np.sqrt(np.diag(cov))
    params = {
        "J": Parameter(float(theta[0]), float(se[0]), spec["J"]),
        "c_mean": Parameter(float(theta[1]), float(se[1]), spec["c"]),
    }
    if K_known is None:
        params["K"] = Parameter(float(theta[2]), float(se[2]), spec["K"])
    else:
        params["K"] = Parameter(float(K_known), 0.0, spec["K"])
    params["delay"] = Parameter(delay_hat, delay_se, "s")
    return Estimate(
        method="pho-campaign",
        params=params,
        data_used={
            "P": runs_arr[:, 0],
            "D": runs_arr[:, 1],
            "sigma": runs_arr[:, 2],
            "omega_d": runs_arr[:, 4],
        },
        diagnostics={
            "chi2": chi2,
            "dof": 2 * n - p - (delay is None),
            "condition": cond,
            "n_runs": n,
        },
    )
