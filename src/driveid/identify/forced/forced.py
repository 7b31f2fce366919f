r"""Forced harmonic response and forced PHO: J, C, K from steady sinusoidal runs.

de Marchi (1998) §2.2.6, Eqs. (2.176)-(2.179), and §2.2.7.2, Eqs. (2.193)-(2.194). The drive
``J x'' + C x' + K x = u - τ_fb`` is driven by ``u(t) = A_1 sin(ω t - φ_1)`` (2.176), with
no feedback (forced response) or under delayed PD feedback
``τ_fb = P x(t-Δ) + D x'(t-Δ)`` (forced PHO). Once the transient has died out the response
is ``x = A_2 sin(ω t - φ_2)`` (2.177).

Derivation
----------
Write a sinusoid as ``Im(Z e^{jωt})`` with the phasor ``Z = A e^{-jφ}``; ``x = Im(X e^{jωt})``,
``u = Im(U e^{jωt})``. A delayed signal has the phasor ``X e^{-jωΔ}``, so the steady state of
the linear drive obeys

.. math::

    H(ω) \equiv \frac{U}{X} = R\,e^{jρ}
         = K - Jω^2 + jωC + (P + jωD)\,e^{-jωΔ},

with ``R = A_1/A_2`` and ``ρ = φ_2 - φ_1`` (2.179): the *dynamic stiffness*. Per frequency
this gives two real equations, linear in (J, C, K):

.. math::

    K - Jω^2 = \operatorname{Re} H - \operatorname{Re} z, \qquad
    ωC = \operatorname{Im} H - \operatorname{Im} z, \qquad z = (P + jωD)\,e^{-jωΔ}.

``z = a jω + b`` with ``(a, b) =`` :func:`driveid.identify.pho.peaks.delay_factors` at σ = 0,
``ω_d = ω``, i.e. ``b = P cos ωΔ + ωD sin ωΔ`` and ``a = D cos ωΔ - (P/ω) sin ωΔ`` — the
thesis's (2.187)-(2.189) factors, which are exact at σ = 0. Without feedback z = 0 and
``K - Jω_0^2 = 0``, ``C = 2Jσ`` give (2.178) back. Several frequencies are combined by
weighted least squares (see :func:`estimate_forced_response`).

Errata and caveats of §2.2.6-2.2.7 (checked in ``tests/identify/test_forced.py``)
------------------------------------------------------------------------------
* (2.193b) prints ``(R_i sin ρ_i - D_i) ω_j``; it must read ``(R_i sin ρ_i - ω_i D_i) ω_j``
  (and likewise for j): from ``ω_i C = R_i sin ρ_i - ω_i D_i``. The printed form is right
  only at ω = 1 rad/s or D = 0. (2.193a), (2.193c), (2.194b) are right for Δ = 0.
* (2.193)-(2.194) ignore the loop delay. The exact forms replace ``P_i`` by
  ``Re z_i = P_i α_1 + ω_i² D_i α_2`` and ``ω_i D_i`` by ``Im z_i = ω_i (D_i α_1 - P_i α_2)``
  with α of (2.187) at σ = 0, ``ω_d = ω_i`` (α_1 = cos ω_iΔ, α_2 = sin(ω_iΔ)/ω_i). Ignoring
  Δ makes the mass low by about ``DΔ - PΔ²/2`` and the damping low by about ``PΔ``
  (``z ≈ P + jω(D - PΔ) + ω²(DΔ - PΔ²/2)`` for small ωΔ): on the thesis's test bed
  (Δ = 13.77 ms, P = 1.5, D = 0.05) J comes out 4.7 % low and C negative.
* (2.194) with a delay: the effective ``ω_0i``, ``ζ_i`` of a free PHO run come from the
  delay factors at ``s = -σ_i + jω_di``, not at ``s = jω_i``, so (2.194) is exact only for
  Δ = 0 (or σ_i = 0 and ω_i = ω_di); on the test bed above (2.194a) is 4.9 % off at
  ω = 8 rad/s.
* (2.178a)-(2.178b) are exact (no feedback).

Nonlinear friction
------------------
Coulomb friction ``fk sgn(x')`` on a motion that never sticks has its fundamental in phase
with the velocity: to first order it adds ``4 fk / (π ω A_2)`` to C (the describing
function) and leaves J, K unbiased. On J = 0.02, C = 0.06, K = 8 (SI) driven with 0.5 N·m
at 8-35 rad/s and fk = 0.005 N·m, each run matched the describing function within 1.04 %,
the fitted C came out 1.4 % high (between the smallest and largest per-run term) and J, K
within 1e-5. The estimate warns when the response has over 5 % harmonics. ``friction=True``
fits ``c_mean, c_delta, fk_mean, fk_delta`` (:mod:`driveid.identify.forced.forced_friction`).

References
----------
.. [1] J. A. de Marchi, "Modeling of dynamic friction, impact backlash and elastic compliance
       nonlinearities in machine tools", PhD thesis, Rensselaer Polytechnic Institute, 1998,
       §2.2.6, §2.2.7.2.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
from scipy.optimize import lsq_linear, minimize_scalar

from driveid.errors import IdentificationError, ParameterError, RecordError
from driveid.identify.core._plausibility import held_at_zero, plausibility_checked
from driveid.identify.core.estimate import Estimate, Parameter
from driveid.identify.forced.sine_fit import SineResponse, fit_sine_response, record_list  # noqa: F401 (re-export)
from driveid.identify.pho.peaks import delay_factors
from driveid.io.record import Record

# SineResponse and fit_sine_response live in driveid.identify.forced.sine_fit (shared with
# forced_friction); they stay importable from here.
__all__ = [
    "estimate_forced_response",
    "estimate_forced_pho",
]

#: Relative rms harmonic content of x above which the estimate carries a warning [-].
WARN_RESPONSE_DISTORTION = 0.05
#: Frequencies closer than this relative gap count as one frequency [-].
_SAME_FREQUENCY = 0.01


def _per_record(value, name: str, records: list[Record], unit: str) -> np.ndarray:
    """Return a scalar or per-record value as an array, or each ``meta[name]`` when None."""
    n = len(records)
    if value is None:
        missing = [i for i, r in enumerate(records) if name not in r.meta]
        if missing:
            raise ParameterError(
                f"{name} [{unit}] is not given and records {missing[:5]} have no "
                f"meta[{name!r}]; pass {name}= (a number or one per record)"
            )
        value = [r.meta[name] for r in records]
    arr = np.asarray(value, dtype=float)
    if arr.ndim == 0:
        arr = np.full(n, float(arr))
    if arr.shape != (n,) or not np.all(np.isfinite(arr)):
        raise ParameterError(
            f"{name} must be one finite number [{unit}] or one per record ({n}); got {value!r}"
        )
    return arr


def _units(records: list[Record]) -> dict[str, str]:
    xu = records[0].units.get("x", "rad")
    if xu == "m":
        return {"J": "kg", "K": "N/m", "c": "N·s/m"}
    return {"J": "kg·m²", "K": f"N·m/{xu}", "c": f"N·m·s/{xu}"}


def _fit_delay(solve, Aw, Lt, w, bounds, p):
    """Delay minimising the weighted residual, and the joint whitened Jacobian there.

    The joint Jacobian holds the columns of the linear parameters and, last, the derivative
    of the whitened residual with respect to Δ (``∂z/∂Δ = -jω z``).
    """
    lo, hi = bounds

    def chi2(d: float) -> float:
        r = solve(d)[1]
        return float(r @ r)

    def joint(d: float):
        _, r, z = solve(d)
        dz = -1j * w * z
        # the residual is A θ - (H - z): its Δ-derivative is +∂z/∂Δ
        col = np.einsum("nij,nj->ni", Lt, np.column_stack([dz.real, dz.imag.copy()]))
        return np.hstack([Aw, col.reshape(-1, 1)]), r

    grid = np.linspace(lo, hi, 64)
    k = int(np.argmin([chi2(d) for d in grid]))
    res = minimize_scalar(chi2, bounds=(grid[max(k - 1, 0)], grid[min(k + 1, 63)]),
                          method="bounded", options={"xatol": 1e-12 * hi})
    d = float(res.x)
    for _ in range(4):  # Brent on chi2 resolves Δ only to ~sqrt(eps); Gauss-Newton finishes
        full, r = joint(d)
        d = float(min(max(d + np.linalg.lstsq(full, -r, rcond=None)[0][p], lo), hi))
    return d, joint(d)[0]


def _estimate(records, omega, P, D, delay, K_known, settle_tol, min_periods, method,
              delay_bounds=None):
    records = record_list(records)
    if not records:
        raise IdentificationError("no records given; pass runs at 2 or more frequencies")
    if K_known is not None and not (isinstance(K_known, (int, float)) and math.isfinite(K_known)):
        raise ParameterError(f"K_known must be a finite stiffness or None; got {K_known!r}")
    if not (delay == "estimate" if isinstance(delay, str) else
            isinstance(delay, (int, float)) and math.isfinite(delay) and delay >= 0):
        raise ParameterError(
            f'delay must be finite and >= 0 [s], or "estimate"; got {delay!r}'
        )
    omegas = [None] * len(records) if omega is None else list(
        _per_record(omega, "omega", records, "rad/s"))
    fits = []
    for i, (rec, w) in enumerate(zip(records, omegas, strict=True)):
        try:
            fits.append(fit_sine_response(rec, omega=w, settle_tol=settle_tol,
                                          min_periods=min_periods))
        except (RecordError, IdentificationError) as err:
            raise type(err)(f"record {i}: {err}") from None
    w = np.array([f.omega for f in fits])
    need = 2 if K_known is not None else 3
    order = np.sort(w)
    n_freq = 1 + int(np.sum(np.diff(order) > _SAME_FREQUENCY * order[1:]))
    if n_freq < need:
        unknown = "J and C" if K_known is not None else "J, C and K"
        raise IdentificationError(
            f"{unknown} need runs at >= {need} distinct excitation frequencies (one more "
            "than the unknowns of the in-phase equation, to check the fit); add a run at "
            f"another frequency; got {n_freq} ({np.round(order, 6).tolist()} rad/s)"
        )
    H = np.array([f.stiffness for f in fits])
    A = np.zeros((len(fits), 2, 3))
    A[:, 0, 0] = -(w**2)
    A[:, 0, 2] = 1.0
    A[:, 1, 1] = w
    if K_known is not None:
        A = A[:, :, :2]
    p = A.shape[2]
    floor = (1e-12 * np.abs(H)) ** 2
    cov = np.array([f.stiffness_cov for f in fits]) + floor[:, None, None] * np.eye(2)
    Lt = np.transpose(np.linalg.cholesky(np.linalg.inv(cov)), (0, 2, 1))
    Aw = (Lt @ A).reshape(-1, p)

    def solve(d: float):
        a, b = delay_factors(np.zeros_like(w), w, d, P=P, D=D)
        y = np.column_stack([H.real - b, H.imag - w * a])
        if K_known is not None:
            y[:, 0] -= K_known
        yw = np.einsum("nij,nj->ni", Lt, y).reshape(-1)
        theta = np.linalg.lstsq(Aw, yw, rcond=None)[0]
        return theta, Aw @ theta - yw, b + 1j * w * a

    dof = Aw.shape[0] - p
    delay_se = 0.0
    estimated = isinstance(delay, str) and delay == "estimate"
    if estimated:
        dof -= 1  # >= 1: the frequency count above leaves two spare equations
        if delay_bounds is None:
            delay_bounds = (0.0, math.pi / (2.0 * float(w.max())))
        lo, hi = (float(v) for v in delay_bounds)
        if not (math.isfinite(lo) and math.isfinite(hi) and 0 <= lo < hi):
            raise ParameterError(
                f"delay_bounds must be finite with 0 <= lo < hi [s]; got {delay_bounds!r}"
            )
        delay, full = _fit_delay(solve, Aw, Lt, w, (lo, hi), p)
        delay_se = math.nan
    theta, resid, _ = solve(float(delay))
    unconstrained = None
    if not estimated and np.any(theta < 0):
        # J > 0, c >= 0, K >= 0: bounded least squares on the same whitened rows; the
        # covariance (below) stays the unconstrained one
        unconstrained = theta.copy()
        res = lsq_linear(Aw, Aw @ theta - resid, bounds=(0.0, np.inf))
        theta = np.where(res.active_mask < 0, 0.0, res.x)
    chi2 = float(resid @ resid)
    design = full if estimated else Aw
    norms = np.linalg.norm(design, axis=0)
    cond = float(np.linalg.cond(design / np.where(norms > 0, norms, 1.0)))
    if not np.isfinite(cond) or cond > 1e12:
        raise IdentificationError(
            "the runs do not separate the parameters (singular design); add runs at widely "
            "different frequencies (and, to estimate the delay, with different P); got "
            f"condition number {cond:.3g}"
        )
    birge = max(1.0, chi2 / dof) if dof > 0 else 1.0
    cov_theta = np.linalg.inv(design.T @ design) * birge
    se = np.sqrt(np.diag(cov_theta))
    if estimated:
        delay_se = float(se[p])
    spec = _units(records)
    params = {
        "J": Parameter(float(theta[0]), float(se[0]), spec["J"]),
        "c_mean": Parameter(float(theta[1]), float(se[1]), spec["c"]),
        "K": (Parameter(float(theta[2]), float(se[2]), spec["K"]) if K_known is None
              else Parameter(float(K_known), 0.0, spec["K"], fixed=True)),
    }
    if method == "forced-pho":
        params["delay"] = Parameter(float(delay), delay_se, "s", fixed=not estimated)
    warnings = []
    at_bound = {}
    if unconstrained is not None:
        for j, name in enumerate(("J", "c_mean", "K")[:p]):
            if unconstrained[j] < 0 and theta[j] == 0.0:
                at_bound[name], message = held_at_zero(
                    name, float(unconstrained[j]), float(se[j]), params[name].unit,
                    "a passive drive cannot have it; likely friction or backlash read as "
                    "linear damping or stiffness (the response is not sinusoidal), unsettled "
                    "runs, or too few frequencies around the resonance; the other "
                    "parameters were refitted with it at 0")
                warnings.append(message)
    distortion = np.array([f.response_distortion for f in fits])
    if distortion.max() > WARN_RESPONSE_DISTORTION:
        warnings.append(
            f"the response is not sinusoidal (up to {100 * distortion.max():.3g} % rms "
            "harmonics): friction or backlash act; c_mean includes their equivalent damping"
        )
    # unwhitened misfit per run relative to |H|: noiseless data can have a large chi2
    # from a tiny residual transient, which is no reason to warn
    misfit = np.linalg.solve(Lt, resid.reshape(-1, 2, 1))[:, :, 0]
    rel_misfit = float(np.max(np.hypot(misfit[:, 0], misfit[:, 1]) / np.abs(H)))
    if dof > 0 and chi2 / dof > 100.0 and rel_misfit > 1e-3:
        warnings.append(
            f"the frequencies disagree (chi2/dof = {chi2 / dof:.3g}, misfit up to "
            f"{100 * rel_misfit:.2g} % of |H|): the drive is not the "
            "linear J, C, K model (nonlinear friction, unsettled runs or a wrong delay); the "
            "standard errors are scaled up accordingly"
        )
    return Estimate(
        method=method,
        params=params,
        data_used={
            "omega": w,
            "amplitude_ratio": np.abs(H),
            "phase_lag": np.angle(H),
            "force_amplitude": np.array([abs(f.force) for f in fits]),
            "displacement_amplitude": np.array([abs(f.displacement) for f in fits]),
            "t_start": np.array([f.t_start for f in fits]),
            "n_periods": np.array([f.n_periods for f in fits]),
            "P": np.asarray(P, dtype=float),
            "D": np.asarray(D, dtype=float),
        },
        diagnostics={
            "chi2": chi2,
            "dof": dof,
            "birge_ratio": math.sqrt(birge),
            "condition": cond,
            "max_relative_misfit": rel_misfit,
            "n_records": len(fits),
            "n_frequencies": n_freq,
            "max_response_distortion": float(distortion.max()),
            "max_input_distortion": float(max(f.input_distortion for f in fits)),
            "noise": [f.noise for f in fits],
            "adequacy": _adequacy(fits, chi2, dof),
            **({"at_bound": at_bound} if at_bound else {}),
        },
        warnings=tuple(warnings),
    )


def _adequacy(fits: list[Any], chi2: float, dof: int) -> dict[str, Any]:
    """Per-run residual whiteness (after the AR noise model) and the across-run χ²."""
    white = [bool(f.noise.get("whiteness", {}).get("white", True)) for f in fits]
    notes = []
    coloured = [i for i, f in enumerate(fits) if f.noise.get("x", {}).get("order", 0) > 0]
    if coloured:
        notes.append(f"runs {coloured} have coloured response noise: their phasor errors come "
                     "from the AR noise model (the spectrum at the excitation frequency)")
    if not all(white):
        notes.append(f"runs {[i for i, ok in enumerate(white) if not ok]} leave residuals that "
                     "are not white even after the noise model (an unsettled transient, a "
                     "drifting offset or friction that is not viscous)")
    ratio = chi2 / dof if dof > 0 else math.nan
    return {"runs_white": white, "chi2_per_dof": ratio,
            "adequate": bool(all(white) and not ratio > 100.0), "notes": notes}


@plausibility_checked
def estimate_forced_response(
    records: Record | Sequence[Record],
    *,
    omega: float | Sequence[float] | None = None,
    K_known: float | None = None,
    settle_tol: float = 1e-4,
    min_periods: int = 3,
    friction: bool = False,
    x_ref: float | None = None,
) -> Estimate:
    r"""J, C, K from steady sinusoidal runs without feedback (thesis §2.2.6, 2.176-2.179).

    Parameters
    ----------
    records : Record or sequence of Record
        One run per excitation frequency, each with ``t`` [s], ``x`` [rad or m] and the
        sinusoidal input ``u`` [N·m or N]; at least 3 distinct frequencies (2 with
        ``K_known``). Several runs may share a frequency (e.g. different amplitudes).
    omega : float or sequence of float, optional
        Excitation frequency of every run, or one per run [rad/s]; estimated from each
        run's u when None.
    K_known : float, optional
        Known stiffness [N·m/rad or N/m] (e.g. 0 for a drive without spring); then only J
        and C are fitted.
    settle_tol : float
        Relative settling tolerance of the transient detection [-] (see
        :func:`fit_sine_response`).
    min_periods : int
        Fewest steady periods per run [-]; >= 2.
    friction : bool
        True: also fit asymmetric describing-function friction (``c_mean`` becomes the
        viscous part alone), see :mod:`driveid.identify.forced.forced_friction`; needs several
        velocity amplitudes ωA (a grid of frequencies × amplitudes).
    x_ref : float, optional
        Spring zero in the records' coordinates [rad or m] (with ``friction``): needed for
        ``fk_delta`` when the drive has a spring; None: unknown.

    Returns
    -------
    Estimate
        Method ``"forced-response"``: ``J`` [kg·m² or kg], ``c_mean`` (viscous C)
        [N·m·s/rad or N·s/m], ``K`` [N·m/rad or N/m] (``K_known`` with zero error), with
        standard errors. ``data_used``: per run ``omega`` [rad/s], ``amplitude_ratio`` R
        [N·m/rad], ``phase_lag`` ρ [rad], ``force_amplitude``, ``displacement_amplitude``,
        ``t_start`` [s], ``n_periods``. Diagnostics: ``chi2``, ``dof``, ``birge_ratio``,
        ``condition`` (of the column-scaled weighted design), ``max_relative_misfit`` (largest
        run residual over its |H|), ``n_records``, ``n_frequencies``,
        ``max_response_distortion``, ``max_input_distortion``, ``noise`` (per run the AR
        noise models of the sine fits, which set the phasor errors), ``adequacy`` (per-run
        whiteness after the noise model, χ²/dof) and ``at_bound`` (J, c_mean, K held at 0
        by the bounded fit: J > 0, c >= 0, K >= 0, with the unconstrained value and the
        one-sided 95 % limit; delay given). A warning is attached when a parameter is held
        at its bound, when the response has over 5 % harmonics, or when the runs disagree
        both statistically (chi2/dof > 100) and materially (misfit > 0.1 % of |H|). With
        ``friction``: the fields of
        :func:`driveid.identify.forced.forced_friction.estimate_forced_friction` (adds
        ``fk_mean``, ``c_delta``, ``fk_delta``; NaN where not identified).

    Raises
    ------
    IdentificationError
        Too few distinct frequencies, a non-sinusoidal input or a singular design.
    RecordError
        A record without ``u``, with corrupted samples, or too short after the transient
        (or never settling); the message names the record.
    ParameterError
        An invalid argument.

    Notes
    -----
    Each run gives the dynamic stiffness ``H = U/X = R e^{jρ}`` (module notes) and two
    equations ``K - Jω² = Re H`` and ``ωC = Im H``. They are solved by least squares
    weighted with the inverse covariance of (Re H, Im H) of each run. The parameter
    covariance is ``(AᵀWA)⁻¹`` multiplied by ``max(1, chi2/dof)`` (the Birge ratio squared),
    so model errors (friction, residual transient) widen the standard errors instead of
    hiding. With Coulomb friction the fitted C is about ``c + 4 fk/(π ω A_2)`` averaged over
    the runs (module notes).

    Examples
    --------
    >>> t = np.arange(6001) * 1e-3
    >>> runs = []
    >>> for w in (5.0, 10.0, 20.0):
    ...     H = 8.0 - 0.02 * w**2 + 1j * w * 0.06
    ...     x = np.imag(np.exp(1j * w * t) / H)
    ...     runs.append(Record(t=t, x=x, u=np.sin(w * t)))
    >>> est = estimate_forced_response(runs)
    >>> [round(est.value(k), 9) for k in ("J", "c_mean", "K")]
    [0.02, 0.06, 8.0]
    """
    n = 1 if isinstance(records, Record) else len(records)
    zero = np.zeros(n)
    if friction:
        from driveid.identify.forced.forced_friction import estimate_forced_friction

        return estimate_forced_friction(
            records, P=zero, D=zero, delay=0.0, omega=omega, K_known=K_known, x_ref=x_ref,
            settle_tol=settle_tol, min_periods=min_periods, method="forced-response")
    return _estimate(records, omega, zero, zero, 0.0, K_known, settle_tol, min_periods,
                     "forced-response")


@plausibility_checked
def estimate_forced_pho(
    records: Record | Sequence[Record],
    *,
    delay: float | str | None = None,
    P: float | Sequence[float] | None = None,
    D: float | Sequence[float] | None = None,
    omega: float | Sequence[float] | None = None,
    K_known: float | None = None,
    delay_bounds: tuple[float, float] | None = None,
    settle_tol: float = 1e-4,
    min_periods: int = 3,
    friction: bool = False,
    x_ref: float | None = None,
) -> Estimate:
    r"""Physical J, C, K from sinusoidal runs under delayed PD feedback (forced PHO, 2.193).

    Parameters
    ----------
    records : Record or sequence of Record
        Runs with ``t`` [s], ``x`` [rad or m] and the external sinusoidal excitation ``u``
        [N·m or N] added to the feedback command (not the total command); at least 3
        distinct frequencies (2 with ``K_known``). Gains may differ between runs.
    delay : float or "estimate", optional
        Loop delay Δ [s], >= 0 (e.g. from a free PHO campaign,
        :func:`driveid.identify.pho.peaks.estimate_pho_campaign`); taken from the records'
        ``meta["delay"]`` when None; fitted with J, C, K when ``"estimate"`` (needs runs
        with different P, see Notes). ``delay=0`` gives the uncompensated analysis.
    P : float or sequence of float, optional
        Proportional gain [N·m/rad or N/m], one or one per run; from ``meta["P"]`` when
        None.
    D : float or sequence of float, optional
        Derivative gain [N·m·s/rad or N·s/m], one or one per run; from ``meta["D"]`` when
        None.
    omega : float or sequence of float, optional
        Excitation frequency [rad/s], one or one per run; estimated from u when None.
    K_known : float, optional
        Known stiffness [N·m/rad or N/m] (0 for a free drive); then only J and C are fitted.
    delay_bounds : tuple of float, optional
        Search interval (lo, hi) for Δ [s] with ``delay="estimate"``; default
        ``(0, π / (2 max ω))`` (phase lag of the delay below a quarter period).
    settle_tol : float
        Relative settling tolerance of the transient detection [-] (see
        :func:`fit_sine_response`).
    min_periods : int
        Fewest steady periods per run [-]; >= 2.
    friction : bool
        True: also fit asymmetric describing-function friction (given delay only); the
        mean force balance under P gives ``c_delta``, ``fk_delta``
        (:mod:`driveid.identify.forced.forced_friction`).
    x_ref : float, optional
        Spring zero [rad or m] (with ``friction`` and a spring); None: unknown.

    Returns
    -------
    Estimate
        Method ``"forced-pho"``: ``J``, ``c_mean``, ``K`` as in
        :func:`estimate_forced_response`, plus ``delay`` [s] (given: zero error);
        ``data_used`` adds the gains ``P``, ``D``. With ``friction`` also ``fk_mean``,
        ``c_delta``, ``fk_delta``.

    Raises
    ------
    IdentificationError
        Too few distinct frequencies, a non-sinusoidal input or a singular design.
    RecordError
        A record without ``u``, with corrupted samples, or too short after the transient
        (or never settling); the message names the record.
    ParameterError
        An invalid or missing delay, gain or other argument.

    Notes
    -----
    The measured dynamic stiffness is ``K - Jω² + jωC + (P + jωD) e^{-jωΔ}``; the feedback
    term is subtracted exactly (module notes; the exact form of (2.193) with the delay
    factors of (2.187) at σ = 0), then the runs are combined as in
    :func:`estimate_forced_response`. A feedback that makes the loop unstable never
    settles and is reported as such.

    With ``delay="estimate"`` Δ minimises the weighted residual (64-point grid, bounded
    Brent, then Gauss-Newton), and the standard errors come from the joint Jacobian in
    (parameters, Δ). For small ωΔ the delay acts like a damping ``-PΔ`` and a mass
    ``-DΔ``; with one (P, D) for all runs these are confounded with C and J up to
    ``O((ωΔ)²)`` terms, so give the runs different P (at least two values) to estimate it.

    Examples
    --------
    >>> t = np.arange(8001) * 1e-3
    >>> runs = []
    >>> for w in (6.0, 12.0, 18.0):
    ...     z = (1.5 + 1j * w * 0.05) * np.exp(-1j * w * 0.01)
    ...     H = -0.0115 * w**2 + 1j * w * 0.001 + z
    ...     runs.append(Record(t=t, x=np.imag(np.exp(1j * w * t) / H), u=np.sin(w * t)))
    >>> est = estimate_forced_pho(runs, delay=0.01, P=1.5, D=0.05, K_known=0.0)
    >>> round(est.value("J"), 9), round(est.value("c_mean"), 9)
    (0.0115, 0.001)
    """
    recs = [records] if isinstance(records, Record) else list(records)
    if delay is None and recs:
        delays = _per_record(None, "delay", recs, "s")
        if np.ptp(delays) > 0:
            raise ParameterError(
                f"records disagree on meta['delay'] ({delays.tolist()} s); pass delay="
            )
        delay = float(delays[0])
    Pv = _per_record(P, "P", recs, "N·m/rad")
    Dv = _per_record(D, "D", recs, "N·m·s/rad")
    if friction:
        if isinstance(delay, str):
            raise ParameterError('friction=True needs a given delay [s], not "estimate"; '
                                 "estimate it first without friction or from free PHO runs")
        from driveid.identify.forced.forced_friction import estimate_forced_friction

        return estimate_forced_friction(
            recs, P=Pv, D=Dv, delay=delay, omega=omega, K_known=K_known, x_ref=x_ref,
            settle_tol=settle_tol, min_periods=min_periods, method="forced-pho")
    return _estimate(recs, omega, Pv, Dv, delay, K_known, settle_tol, min_periods,
                     "forced-pho", delay_bounds)
