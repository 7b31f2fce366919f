r"""Parametric harmonic oscillation (PHO): J, C, K and the loop delay from PD-feedback runs.

de Marchi (1998) §2.2.7, Eqs. (2.180)-(2.192). Delayed PD feedback
``τ(t) = -[D γ'(t-Δ) + P γ(t-Δ)]`` on ``J γ'' + C γ' + K γ = τ`` makes even an overdamped
drive oscillate; each run (P_i, D_i) gives a measured decay rate σ_i and damped frequency
ω_d,i (e.g. from :func:`~driveid.identify.free_decay.logdec.estimate_log_decrement`), and a
campaign of runs gives the physical J, C, K.

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

Asymmetric friction under delayed feedback
------------------------------------------
With ``C = c_mean + c_delta·s`` and ``F_k = fk_mean·s + fk_delta`` while moving in direction
``s``, each half cycle is the delayed linear system above plus a constant force. A constant
passes the delayed loop unchanged (``(D s + P) e^{-sΔ}`` at ``s = 0`` is ``P``), so the centre
of the half cycle is ``-(fk_mean·s + fk_delta)/(K + P)``: the log decrement's
``θk = F_k/(K + P)``, *not* the free-decay ``F_k/(J ω_0²) = F_k/(K + b)`` (the delayed loop
adds ``b ≠ P`` to the oscillating part only). The two directions have their own roots
``s_± = -σ_± + jω_{d,±}``, so ``c_mean ± c_delta + a(s_±) = 2Jσ_±`` and
``c_delta = J(σ_+ - σ_-) - (a(s_+) - a(s_-))/2``.

The peaks see more than the centre, though. Write the response to a step ``ΔF`` of the
friction force (one at every reversal) as ``ΔF·h(t)`` with
``h(t) = g + Re(q e^{s_1 t}) + (fast roots)``, ``g = 1/(K + P)``, ``q = 2/(s_1 χ'(s_1))`` and
``χ(s) = J s² + C s + K + (D s + P) e^{-sΔ}``. Peaks are half periods apart, where the fast
roots have died out, so summing the steps gives the recursion

.. math::

    x_n = -ρ x_{n-1} + (1 + ρ) e_n - ρ ε ΔF_{n-1}, \qquad ε = g + \operatorname{Re} q,

with ``e_n = -g F_{s_n}`` and ``ρ = e^{-σπ/ω_d}``. Without delay ``ε = 0`` (the free
oscillator); with it, the reversal step ``ΔF = -2 fk_mean s`` leaves an extra term, so the
log decrement's offsets are ``θk_delta = g·fk_delta`` but
``θk_mean = fk_mean·(g - 2ρε/(1 + ρ))``. On the test bed (Δ = 13.77 ms) ignoring ε biases
``fk_mean`` by -0.02 % at P = 2 to -0.8 % at P = 8, D = 0.2; with it the simulated runs
agree to about 1e-4 (``tests/identify/test_pho_friction.py``). ``χ'`` uses the campaign's own
J, C, K and Δ.

With negative ``D`` the linear part grows (``σ < 0``) while kinetic friction still stops the
motion: the peaks shrink by ``2θk`` per half cycle and grow by ``e^{|σ|π/ω_d}``, so the
envelope narrows faster as it shrinks ("bullet-shaped", thesis §5, Fig. 5.3). The same
equations hold; the log decrement simply returns ``ζ < 0``.

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
from driveid.identify.core._plausibility import plausibility_checked
from driveid.identify.core.estimate import Estimate, Parameter
from driveid.identify.free_decay.logdec import MIN_PEAKS, estimate_log_decrement
from driveid.io.record import Record
from driveid.signal.peaks import Peaks, find_oscillation_peaks

__all__ = [
    "PHORun",
    "delay_factors",
    "delay_factors_thesis",
    "estimate_pho_campaign",
    "estimate_pho_records",
    "pho_peaks",
    "pho_run_from_records",
]


_FRICTION_FEATURES = ("sigma_delta", "sigma_delta_se", "theta_k_mean", "theta_k_mean_se",
                      "theta_k_delta", "theta_k_delta_se")


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
    sigma_delta, sigma_delta_se : float, optional
        Half the difference of the decay rates of the two directions, ``(σ_+ - σ_-)/2``
        [1/s], and its standard error; nan (default) when not measured. Gives ``c_delta``.
    theta_k_mean, theta_k_mean_se, theta_k_delta, theta_k_delta_se : float, optional
        Kinetic-friction offsets of the half-cycle centres (log decrement ``θk``) [rad or m]
        and their standard errors; nan (default) when not measured. Give ``fk_delta =
        θk_delta (K + P)`` and ``fk_mean`` (``≈ θk_mean (K + P)``, corrected for the
        delay, module notes).
    """

    P: float
    D: float
    sigma: float
    sigma_se: float
    omega_d: float
    omega_d_se: float
    sigma_delta: float = math.nan
    sigma_delta_se: float = math.nan
    theta_k_mean: float = math.nan
    theta_k_mean_se: float = math.nan
    theta_k_delta: float = math.nan
    theta_k_delta_se: float = math.nan

    def __post_init__(self) -> None:
        for name in ("P", "D", "sigma", "sigma_se", "omega_d", "omega_d_se"):
            value = getattr(self, name)
            if not math.isfinite(value):
                raise ParameterError(f"PHORun.{name} must be finite; got {value!r}")
            object.__setattr__(self, name, float(value))
        for name in _FRICTION_FEATURES:
            object.__setattr__(self, name, float(getattr(self, name)))
        for name in _FRICTION_FEATURES[1::2]:
            value = getattr(self, name)
            if value <= 0:
                raise ParameterError(
                    f"PHORun.{name} must be > 0 or nan (not measured); got {value!r}"
                )
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


@plausibility_checked
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
        given), with standard errors; when every run carries ``sigma_delta`` also
        ``c_delta``, and when every run carries the ``theta_k`` offsets also ``fk_mean``,
        ``fk_delta`` [N·m or N] (inverse-variance means over the runs, module notes).
        Diagnostics: ``chi2`` (weighted residual sum of squares, ~ 2n - p for consistent
        standard errors), ``dof``, ``condition``.

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
        params["K"] = Parameter(float(K_known), 0.0, spec["K"], fixed=True)
    params["delay"] = Parameter(delay_hat, delay_se, "s", fixed=delay is not None)
    friction, per_run = _friction(runs, params, delay_hat, spec)
    params.update(friction)
    P_arr, D_arr, sig, _, wd, _ = runs_arr.T
    a, b = delay_factors(sig, wd, delay_hat, P=P_arr, D=D_arr)
    J_hat = params["J"].value
    return Estimate(
        method="pho-campaign",
        params=params,
        data_used={
            "P": P_arr,
            "D": D_arr,
            "sigma": sig,
            "omega_d": wd,
            # what each run alone implies at the campaign's J and Δ (for consistency plots)
            "c_mean_per_run": 2.0 * J_hat * sig - a,
            "K_per_run": J_hat * (sig**2 + wd**2) - b,
            **per_run,
        },
        diagnostics={
            "chi2": chi2,
            "dof": 2 * n - p - (delay is None),
            "condition": cond,
            "n_runs": n,
        },
    )


def _weighted_mean(values, errors) -> tuple[float, float]:
    w = 1.0 / np.asarray(errors) ** 2
    return float(np.sum(w * values) / np.sum(w)), float(1.0 / math.sqrt(np.sum(w)))


def _friction(runs, params, delay, spec):
    """``c_delta``, ``fk_mean``, ``fk_delta`` from the runs' directional features.

    Returns the parameters and each run's own value of them (``<name>_per_run`` arrays).
    """
    out: dict[str, Parameter] = {}
    per_run: dict[str, np.ndarray] = {}
    J, J_se = params["J"].value, params["J"].stderr
    K, K_se = params["K"].value, params["K"].stderr
    force_unit = "N·m" if spec["J"] == "kg·m²" else "N"
    if all(math.isfinite(r.sigma_delta) for r in runs):
        values, errors, slopes = [], [], []
        for r in runs:
            w0sq = r.sigma**2 + r.omega_d**2
            a = []
            for sig in (r.sigma + r.sigma_delta, r.sigma - r.sigma_delta):
                wd = math.sqrt(max(w0sq - sig**2, 0.0))
                a.append(float(delay_factors(sig, wd, delay, P=r.P, D=r.D)[0]))
            values.append(2.0 * J * r.sigma_delta - 0.5 * (a[0] - a[1]))
            errors.append(2.0 * J * r.sigma_delta_se)
            slopes.append(2.0 * r.sigma_delta)
        value, se = _weighted_mean(values, errors)
        slope = _weighted_mean(slopes, errors)[0]
        out["c_delta"] = Parameter(value, math.hypot(se, slope * J_se), spec["c"])
        per_run["c_delta_per_run"] = np.array(values)
    if all(math.isfinite(r.theta_k_mean) for r in runs):
        stiff = np.array([K + r.P for r in runs])
        if np.any(stiff <= 0):
            raise IdentificationError(
                "K + P must be positive in every run for the kinetic-friction offset "
                f"F/(K + P); got K + P = {stiff.tolist()}; check the sign of P or of K_known"
            )
    for name in ("mean", "delta"):
        theta = [getattr(r, f"theta_k_{name}") for r in runs]
        theta_se = [getattr(r, f"theta_k_{name}_se") for r in runs]
        if not all(math.isfinite(v) for v in theta):
            continue
        if name == "delta":
            gain = stiff
        else:
            gain = np.array([1.0 / _mean_offset_gain(r, J, params["c_mean"].value, K, delay)
                             for r in runs])
        value, se = _weighted_mean(np.array(theta) * gain, np.array(theta_se) * gain)
        theta_bar = _weighted_mean(theta, theta_se)[0]
        out[f"fk_{name}"] = Parameter(value, math.hypot(se, theta_bar * K_se), force_unit)
        per_run[f"fk_{name}_per_run"] = np.array(theta) * gain
    return out, per_run


def _mean_offset_gain(run, J, C, K, delay) -> float:
    """``θk_mean / fk_mean`` of a delayed PD run: ``g - 2ρε/(1 + ρ)`` (module notes)."""
    s = complex(-run.sigma, run.omega_d)
    dchi = 2.0 * J * s + C + (run.D - delay * (run.D * s + run.P)) * np.exp(-s * delay)
    g = 1.0 / (K + run.P)
    eps = g + (2.0 / (s * dchi)).real
    rho = math.exp(-run.sigma * math.pi / run.omega_d)
    return g - 2.0 * rho * eps / (1.0 + rho)


def pho_peaks(record: Record) -> Peaks:
    """Oscillation peaks of one PD-feedback run, cut where the oscillation ends.

    Under delayed feedback a body that sticks can be nudged loose again by the delayed
    command and creep a little before it sticks for good; those late extrema are not half
    cycles of the oscillation. Peaks are kept while they alternate and are at least 0.6
    median half periods apart; the last kept one before such a cut is a stop, so its time
    is marked invalid (its value stays exact).

    Parameters
    ----------
    record : Record
        One run: position [rad or m] after release into the feedback loop.

    Returns
    -------
    Peaks
        The usable peaks (see :func:`driveid.signal.peaks.find_oscillation_peaks`).

    Raises
    ------
    IdentificationError
        If the record does not oscillate.
    """
    pk = find_oscillation_peaks(record)
    spacing = np.diff(pk.t)
    regular = pk.time_valid[1:] & ~pk.stuck[1:]
    half = float(np.median(spacing[regular])) if np.any(regular) else float(np.median(spacing))
    direction = np.sign(np.diff(pk.x))
    n = len(pk)
    for k in range(1, len(pk)):
        if spacing[k - 1] < 0.6 * half or direction[k - 1] == 0 or (
            k >= 2 and direction[k - 1] == direction[k - 2]
        ):
            n = k
            break
    time_valid = pk.time_valid[:n].copy()
    if n < len(pk):
        time_valid[-1] = False
    return Peaks(
        t=pk.t[:n], x=pk.x[:n], index=pk.index[:n], stuck=pk.stuck[:n], time_valid=time_valid,
        x_std=pk.x_std, x_se=None if pk.x_se is None else pk.x_se[:n],
        t_se=None if pk.t_se is None else pk.t_se[:n],
    )


def pho_run_from_records(records: Sequence[Record], *, P: float, D: float) -> PHORun:
    """Decay features of one (P, D) setting from its runs (usually a ± pair).

    The runs share one extended log-decrement fit
    (:func:`~driveid.identify.free_decay.logdec.estimate_log_decrement`): ω_0, ζ_± and the
    offsets θk.

    Parameters
    ----------
    records : sequence of Record
        Runs of the same gains, e.g. one from a positive and one from a negative initial
        displacement [rad or m]; both directions of motion must occur.
    P : float
        Proportional gain of these runs [N·m/rad or N/m].
    D : float
        Derivative gain [N·m·s/rad or N·s/m].

    Returns
    -------
    PHORun
        σ = ζ̄ ω_0 and ω_d [1/s, rad/s] of the mean damping, ``sigma_delta`` and the
        ``theta_k`` offsets, with standard errors from the fit.

    Raises
    ------
    IdentificationError
        If a run has fewer than 5 usable peaks or does not oscillate; the message names the run.
    """
    records = list(records)
    peaks = []
    for k, record in enumerate(records):
        try:
            pk = pho_peaks(record)
        except IdentificationError as exc:
            raise IdentificationError(
                f"run {k} with P={P}, D={D}: {exc}. Repeat it with a larger P or initial "
                "displacement (or a lower D), or leave it out of the campaign"
            ) from None
        if len(pk) < MIN_PEAKS:
            raise IdentificationError(
                f"run {k} with P={P}, D={D} has {len(pk)} usable peaks, the log decrement "
                f"needs {MIN_PEAKS}: start it from a larger displacement or lower D"
            )
        peaks.append(pk)
    ld = estimate_log_decrement(records, peaks=peaks)
    w0, w0_se = ld.value("omega0"), ld.stderr("omega0")
    zp, zm = ld.value("zeta_plus"), ld.value("zeta_minus")
    zp_se, zm_se = ld.stderr("zeta_plus"), ld.stderr("zeta_minus")
    zeta = 0.5 * (zp + zm)
    if not abs(zeta) < 1:
        raise IdentificationError(
            f"runs with P={P}, D={D} are not underdamped oscillations (ζ = {zeta:.3g}); "
            "raise P or lower D"
        )
    floor = 1e-12 * w0
    return PHORun(
        P=P, D=D,
        sigma=zeta * w0,
        sigma_se=max(math.hypot(0.5 * w0 * math.hypot(zp_se, zm_se), zeta * w0_se), floor),
        omega_d=w0 * math.sqrt(1.0 - zeta**2),
        omega_d_se=max(w0_se, floor),
        sigma_delta=0.5 * (zp - zm) * w0,
        sigma_delta_se=max(0.5 * w0 * math.hypot(zp_se, zm_se), floor),
        theta_k_mean=ld.value("theta_k_mean"),
        theta_k_mean_se=max(ld.stderr("theta_k_mean"), 1e-15),
        theta_k_delta=ld.value("theta_k_delta"),
        theta_k_delta_se=max(ld.stderr("theta_k_delta"), 1e-15),
    )


def _gains(record: Record, k: int) -> tuple[float, float]:
    try:
        P, D = float(record.meta["P"]), float(record.meta["D"])
    except (KeyError, TypeError, ValueError):
        raise ParameterError(
            f"record {k} has no numeric meta['P'] and meta['D']; give each record the gains "
            "of its run (a manifest entry's P and D)"
        ) from None
    if not (math.isfinite(P) and math.isfinite(D)):
        raise ParameterError(f"record {k}: P and D must be finite; got P={P!r}, D={D!r}")
    return P, D


@plausibility_checked
def estimate_pho_records(
    records: Sequence[Record],
    *,
    delay: float | None = None,
    K_known: float | None = None,
    units: str | None = None,
) -> Estimate:
    """Physical J, C, K, asymmetric viscous and kinetic friction from a campaign's records.

    Records are grouped by their gains ``meta["P"]``, ``meta["D"]``; each group (normally
    a run from a positive and one from a negative initial displacement) gives one
    :class:`PHORun` (:func:`pho_run_from_records`), and :func:`estimate_pho_campaign`
    combines them.

    Parameters
    ----------
    records : sequence of Record
        The accepted runs [rad or m], each with ``meta["P"]`` [N·m/rad or N/m] and
        ``meta["D"]`` [N·m·s/rad or N·s/m].
    delay : float, optional
        Loop delay Δ [s]; estimated from the campaign when None; ``0.0`` gives the
        uncompensated analysis (the thesis's Table 5.2 situation).
    K_known : float, optional
        Known stiffness [N·m/rad or N/m], e.g. 0 for a drive without a spring.
    units : {"rad", "m"}, optional
        Default: the records' position unit.

    Returns
    -------
    Estimate
        ``J``, ``c_mean``, ``c_delta``, ``K``, ``fk_mean``, ``fk_delta``, ``delay`` with
        standard errors (method ``"pho-campaign"``); diagnostics add ``n_records``.

    Raises
    ------
    IdentificationError
        For an ill-posed campaign (one setting, a run that does not oscillate ...); the
        message says which run to add or repeat.
    ParameterError
        If a record lacks its gains.
    """
    records = list(records)
    if not records:
        raise IdentificationError(
            "no records: a PHO campaign needs runs at two or more (P, D) settings, each "
            "released once from a positive and once from a negative displacement"
        )
    groups: dict[tuple[float, float], list[Record]] = {}
    for k, record in enumerate(records):
        if not isinstance(record, Record):
            raise ParameterError(f"records[{k}] must be a Record; got {type(record).__name__}")
        groups.setdefault(_gains(record, k), []).append(record)
    if len(groups) < 2:
        (gains,) = groups
        raise IdentificationError(
            f"all {len(records)} record(s) share P={gains[0]}, D={gains[1]}, so the feedback "
            "cannot be separated from J, C and K; add runs with a different P (and D)"
        )
    if units is None:
        units = records[0].units["x"]
    runs = [pho_run_from_records(group, P=P, D=D) for (P, D), group in groups.items()]
    est = estimate_pho_campaign(runs, delay=delay, K_known=K_known, units=units)
    diagnostics = dict(est.diagnostics, n_records=len(records))
    return Estimate(method=est.method, params=est.params, data_used=est.data_used,
                    diagnostics=diagnostics, warnings=est.warnings)
