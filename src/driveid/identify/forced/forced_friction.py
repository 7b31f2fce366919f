r"""Asymmetric describing-function friction from steady sine runs (forced response, forced PHO).

de Marchi (1998) §2.2.6-§2.2.7.2 (forced response and forced PHO, Eqs. 2.176-2.179, 2.193)
with the asymmetric friction of Eqs. (2.155b-c), (2.156): while moving in the direction
``s = sgn x'`` the drive ``J x'' + K x + F(x') = u - τ_fb`` feels

.. math:: F(x') = (c_{mean} + c_{delta} s)\,x' + f_{k,mean}\,s + f_{k,delta}

and the delayed PD feedback ``τ_fb = P x(t-Δ) + D x'(t-Δ)`` (forced PHO; P = D = 0 for the
forced response).

Harmonic balance
----------------
On a steady motion ``x = x̄ + A sin(ωt - φ)`` that never sticks, ``x' = V cos(ωt - φ)`` with
``V = ωA``. Split F into its odd and even parts in x':

* odd, ``c_mean x' + fk_mean s``: its fundamental is ``(c_mean + 4 fk_mean/(π V)) x'``
  (the relay describing function ``4F/(πV)``, Gelb & Vander Velde [2]_); it has no mean;
* even, ``c_delta |x'| + fk_delta``: no fundamental; mean ``fk_delta + (2/π) c_delta V``
  (``mean |cos| = 2/π``) and the even harmonics ``(4/(3π)) c_delta V cos 2(ωt-φ)``, ….

The fundamental gives, with the dynamic stiffness ``H = U/X`` and ``z = (P + jωD)e^{-jωΔ}``
(:mod:`driveid.identify.forced.forced`),

.. math::

    \operatorname{Re}(H - z) = K - Jω^2, \qquad
    \operatorname{Im}(H - z) = ω c_{mean} + \frac{4}{π} \frac{f_{k,mean}}{A},

so runs at different velocity amplitudes ``ωA`` separate ``c_mean`` from ``fk_mean``
(``C_eff(V) = c_mean + 4 fk_mean/(πV)``). The mean (DC) force balance is

.. math::

    K (x̄ - x_{ref}) + P x̄ + f_{k,delta} + \frac{2}{π} c_{delta} V = ū,

``x_ref`` being the spring zero in encoder coordinates (PD acts on the encoder reading, whose
zero is the loop reference). Runs at different V separate ``c_delta`` from ``fk_delta``.

The 2ω harmonic is an independent check of ``c_delta`` that needs neither x̄ nor
``x_ref``: ``(4/(3π)) c_delta V`` drives x at 2ω through the drive's dynamic stiffness at
2ω, plus the zero-crossing shift of ``fk_mean sgn x'`` (:func:`_second_harmonic_c_delta`);
each run's value is in ``data_used["c_delta_2w"]``, their median in the diagnostics. It is
not used in the fit: near ``2ω ≈ ω_0`` it is sensitive to the damping at 2ω.

What the data allow
-------------------
* ``K + P = 0`` for every run (a free drive without feedback): x̄ is free (the drive
  drifts), so ``c_delta`` and ``fk_delta`` are **not identified** (reported as NaN and
  listed in ``diagnostics["not_identified"]``).
* A spring (K ≠ 0, not known to be 0) whose zero ``x_ref`` is not given: the constant
  ``K x_ref`` is indistinguishable from ``fk_delta``; then only ``c_delta`` and the
  combination ``fk_delta - K x_ref`` (``diagnostics["dc_force_offset"]``) are identified.
  This holds under feedback too: pass ``K_known=0`` for a drive without spring.
* All runs at one velocity amplitude V: ``fk_mean`` is not separable from ``c_mean`` (an
  error), nor ``c_delta`` from ``fk_delta``.

Accuracy of the describing function
-----------------------------------
Harmonic balance is first order: the response harmonics move the zero crossings of x' and
so the harmonics of ``sgn x'``. To first order a 3ω velocity harmonic gives ``sgn x'`` a
fundamental in phase with x (a stiffness-like term, biasing K and J, not fk_mean), and a 2ω
velocity harmonic ``Re(E_2 e^{2jφ})`` shifts its mean by ``-2 Re E_2/(πV)``; through
``c_delta |x'| ≈ c_delta (|v_1| + s v_3)`` a 3ω harmonic ``Re(E_3 e^{3jφ})`` shifts the mean
by ``-(2/(3π)) c_delta Re E_3``. The DC row is corrected for both mean shifts with the
measured harmonics (the correction is linear in c_delta, and uses fk_mean from the
fundamental). The rest of the error scales with the relative velocity harmonics, which
the estimate reports per run (``velocity_distortion``) and warns about above 5 %. On the
runs of ``tests/identify/test_forced_friction.py`` (up to 14 % and 27 % velocity
harmonics) the exact Fourier coefficients of the simulated friction force differ from
the describing function by at most 3.8 % of ``4 fk_mean/π`` in the fundamental and 5.7 %
of ``fk_mean`` in the mean (1.1 % with the correction); the estimates were within 0.25 %
(0.64 % for a small ``c_mean``). Runs that stick are outside the model (a warning is given
when the velocity rests for over 2 % of the period).

References
----------
.. [1] J. A. de Marchi, "Modeling of dynamic friction, impact backlash and elastic compliance
       nonlinearities in machine tools", PhD thesis, Rensselaer Polytechnic Institute, 1998,
       §2.2.6-§2.2.7.2, Eqs. (2.155)-(2.156), ch. 4.
.. [2] A. Gelb, W. E. Vander Velde, *Multiple-Input Describing Functions and Nonlinear
       System Design*, McGraw-Hill, 1968 (relay describing function ``4F/(πA)``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from driveid.errors import IdentificationError, ParameterError, RecordError
from driveid.identify.core._noise import fit_noise_model
from driveid.identify.core._plausibility import plausibility_checked
from driveid.identify.core.estimate import Estimate, Parameter
from driveid.identify.forced.sine_fit import SineResponse, fit_sine_response, record_list
from driveid.identify.pho.peaks import delay_factors
from driveid.io.record import Record

__all__ = ["SineHarmonics", "sine_harmonics", "estimate_forced_friction", "SineGridTest",
           "sine_grid_test"]

#: Relative velocity harmonics above which the describing function is flagged [-].
WARN_VELOCITY_DISTORTION = 0.05
#: Fraction of a period with |x'| below 1 % of V above which a run is said to stick [-].
_STICK_FRACTION = 0.02
#: Relative spread of V below which the runs have "one velocity amplitude" [-].
_SAME_SPEED = 0.05
_NAMES = ("J", "c_mean", "K", "fk_mean", "c_delta", "fk_delta")


@dataclass(frozen=True, kw_only=True)
class SineHarmonics:
    """Fundamental, mean and low harmonics of one steady sine run.

    Attributes
    ----------
    fit : SineResponse
        The fundamental fit (:func:`driveid.identify.forced.forced.fit_sine_response`).
    x_mean, x_mean_se : float
        Mean position over the steady window and its standard error [rad or m].
    u_mean, u_mean_se : float
        Mean input and its standard error [N·m or N].
    x_drift : float
        Mean velocity over the window [rad/s or m/s] (non-zero: the drive creeps).
    velocity_amplitude : float
        ``V = ω |X|`` [rad/s or m/s].
    harmonics : ndarray, shape (3,)
        Amplitudes of the x harmonics at 2ω, 3ω, 4ω over ``|X|`` [-].
    velocity_distortion : float
        RMS of the velocity harmonics 2ω-4ω over the fundamental's, ``sqrt(Σ (k h_k)²)`` [-].
    stuck_fraction : float
        Fraction of the window with ``|x'|`` below 1 % of V (from the record's ``v``, or
        the harmonic fit when it has none) [-].
    second_harmonic, third_harmonic : complex
        Phasors of the x harmonics at 2ω and 3ω relative to the fundamental's phase,
        ``X_k e^{-kj arg X}`` [rad or m].
    harmonic_se : float
        Standard error of each harmonic's sine and cosine coefficient [rad or m].
    """

    fit: SineResponse
    x_mean: float
    x_mean_se: float
    u_mean: float
    u_mean_se: float
    x_drift: float
    velocity_amplitude: float
    harmonics: np.ndarray
    velocity_distortion: float
    stuck_fraction: float
    second_harmonic: complex
    third_harmonic: complex
    harmonic_se: float


def sine_harmonics(record: Record, *, omega: float | None = None, settle_tol: float = 1e-4,
                   min_periods: int = 3) -> SineHarmonics:
    """Fit the fundamental, the mean and the harmonics 2ω-4ω of one steady sine run.

    Parameters
    ----------
    record : Record
        ``t`` [s], ``x`` [rad or m], the sinusoidal input ``u`` [N·m or N]; ``v``
        [rad/s or m/s] is used for the sticking check when present.
    omega : float, optional
        Excitation frequency [rad/s]; estimated from u when None.
    settle_tol : float
        Settling tolerance of :func:`driveid.identify.forced.forced.fit_sine_response` [-].
    min_periods : int
        Fewest steady periods [-]; >= 2.

    Returns
    -------
    SineHarmonics
        Fundamental fit, means with standard errors (AR(p) residual noise model, white
        when BIC says so), drift, harmonics.

    Raises
    ------
    RecordError, IdentificationError, ParameterError
        As :func:`driveid.identify.forced.forced.fit_sine_response`.

    Examples
    --------
    >>> t = np.arange(4001) * 1e-3
    >>> rec = Record(t=t, x=0.1 + 0.5 * np.sin(10 * t) + 0.01 * np.sin(20 * t),
    ...              u=0.3 + np.sin(10 * t))
    >>> h = sine_harmonics(rec, omega=10.0)
    >>> round(h.x_mean, 9), round(h.u_mean, 9), round(float(h.harmonics[0]), 9)
    (0.1, 0.3, 0.02)
    """
    fit = fit_sine_response(record, omega=omega, settle_tol=settle_tol,
                            min_periods=min_periods)
    t = np.asarray(record.t, dtype=float)
    sel = (t >= fit.t_start - 0.25 * record.dt) & (t < fit.t_stop - 0.25 * record.dt)
    tau = t[sel] - fit.t_ref
    w = fit.omega
    cols = [np.ones_like(tau), (tau - tau.mean()) / max(np.ptp(tau), 1e-300)]
    for k in range(1, 5):
        cols += [np.sin(k * w * tau), np.cos(k * w * tau)]
    basis = np.column_stack(cols)
    x, u = np.asarray(record.x, float)[sel], np.asarray(record.u, float)[sel]
    cx, cov_x = _lsq(basis, x)
    cu, cov_u = _lsq(np.delete(basis, 1, axis=1), u)
    amp1 = math.hypot(cx[2], cx[3])
    harm = np.array([math.hypot(cx[2 * k], cx[2 * k + 1]) for k in (2, 3, 4)]) / amp1
    if record.v is not None:
        vel = np.abs(np.asarray(record.v, float)[sel])
    else:
        vel = np.abs(sum(k * w * (cx[2 * k] * np.cos(k * w * tau) - cx[2 * k + 1]
                                  * np.sin(k * w * tau)) for k in range(1, 5)))
    V = w * abs(fit.displacement)
    return SineHarmonics(
        fit=fit, x_mean=float(cx[0]), x_mean_se=float(math.sqrt(cov_x[0, 0])),
        u_mean=float(cu[0]), u_mean_se=float(math.sqrt(cov_u[0, 0])),
        x_drift=float(cx[1] / max(np.ptp(tau), 1e-300)), velocity_amplitude=float(V),
        harmonics=harm,
        velocity_distortion=float(np.sqrt(np.sum((np.arange(2, 5) * harm) ** 2))),
        stuck_fraction=float(np.mean(vel < 0.01 * V)),
        second_harmonic=complex(cx[4], cx[5]) * np.exp(-2j * np.angle(fit.displacement)),
        third_harmonic=complex(cx[6], cx[7]) * np.exp(-3j * np.angle(fit.displacement)),
        harmonic_se=float(math.sqrt(cov_x[4, 4])))


def _lsq(basis: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    # normal equations: harmonics over whole periods are near-orthogonal (well conditioned)
    inv = np.linalg.inv(basis.T @ basis)
    coef = inv @ (basis.T @ y)
    resid = y - basis @ coef
    s2 = float(resid @ resid) / max(basis.shape[0] - basis.shape[1], 1)
    # coloured noise (a filtered sensor) hits the means hardest: their error is set by the
    # noise spectrum near 0 Hz; an AR(p) model of the residual gives it (order 0: white)
    model = fit_noise_model(resid, n_params=basis.shape[1])
    if model.is_white:
        return coef, s2 * inv
    bw = model.whiten(basis)
    return coef, model.innovation_variance * np.linalg.inv(bw.T @ bw)


def _second_harmonic_c_delta(h, w, V, J, K, c, fk, Pv, Dv, delay) -> np.ndarray:
    """c_delta of each run from its 2ω harmonic, given the fundamental's J, K, c, fk.

    With the velocity ``V cos φ`` and the 2ω position phasor Y (``x_2 = Im(Y e^{2jφ})``),
    the 2ω balance to first order is ``-j(K - 4Jω² + z(2ω)) Y + 2ω c_mean Y
    + (4 fk_mean/(πV)) 2ω Re Y = -(4/(3π)) c_delta V``: the last term on the left is the
    shift of the zero crossings of ``sgn x'`` (it sees only the part of the 2ω velocity in
    phase with ``cos 2φ``). Linear in c_delta: Y = c_delta Y_1.
    """
    a, b = delay_factors(np.zeros_like(w), 2 * w, delay, P=Pv, D=Dv)
    lin = -1j * (K - 4 * J * w**2 + b + 2j * w * a) + 2 * w * c
    g = 8 * w * fk / (np.pi * V)
    out = np.empty(len(h))
    for i, r in enumerate(h):
        m = np.array([[lin[i].real + g[i], -lin[i].imag], [lin[i].imag, lin[i].real]])
        y1 = np.linalg.solve(m, [-4 * V[i] / (3 * np.pi), 0.0])
        y1 = complex(y1[0], y1[1])
        out[i] = (np.conj(y1) * r.second_harmonic).real / abs(y1) ** 2
    return out


def _wls(A: np.ndarray, y: np.ndarray):
    """Whitened least squares: θ, Birge-scaled covariance, χ², dof, condition number."""
    dof = A.shape[0] - A.shape[1]
    norms = np.linalg.norm(A, axis=0)
    cond = float(np.linalg.cond(A / np.where(norms > 0, norms, 1.0)))
    if dof < 1 or not np.isfinite(cond) or cond > 1e12:
        raise IdentificationError(
            "the runs do not separate the parameters (singular design or no spare "
            "equation); use a grid of widely different frequencies and amplitudes; got "
            f"{A.shape[0]} equations for {A.shape[1]} unknowns, condition number {cond:.3g}")
    theta = np.linalg.lstsq(A, y, rcond=None)[0]
    resid = A @ theta - y
    chi2 = float(resid @ resid)
    return theta, np.linalg.inv(A.T @ A) * max(1.0, chi2 / dof), chi2, dof, cond


def _units(record: Record) -> dict[str, str]:
    if record.units.get("x", "rad") == "m":
        return {"J": "kg", "K": "N/m", "c": "N·s/m", "f": "N", "x": "m"}
    return {"J": "kg·m²", "K": "N·m/rad", "c": "N·m·s/rad", "f": "N·m", "x": "rad"}


def _gains(records: list[Record], value, name: str, unit: str) -> np.ndarray:
    """One value per record: given, or ``meta[name]`` (0 when absent)."""
    if value is None:
        value = [r.meta.get(name, 0.0) or 0.0 for r in records]
    arr = np.asarray(value, dtype=float)
    if arr.ndim == 0:
        arr = np.full(len(records), float(arr))
    if arr.shape != (len(records),) or not np.all(np.isfinite(arr)):
        raise ParameterError(f"{name} must be one finite number [{unit}] or one per record "
                             f"({len(records)}); got {value!r}")
    return arr


def _harmonics_of(records, omega, settle_tol, min_periods) -> list[SineHarmonics]:
    try:
        omegas = [None] * len(records) if omega is None else list(
            np.broadcast_to(np.asarray(omega, dtype=float), (len(records),)))
    except ValueError:
        raise ParameterError(f"omega must be one frequency [rad/s] or one per record "
                             f"({len(records)}); got {omega!r}") from None
    out = []
    for i, (rec, w) in enumerate(zip(records, omegas, strict=True)):
        try:
            out.append(sine_harmonics(rec, omega=None if w is None else float(w),
                                      settle_tol=settle_tol, min_periods=min_periods))
        except (RecordError, IdentificationError) as err:
            raise type(err)(f"record {i}: {err}") from None
    return out


def _design(h: list[SineHarmonics], Pv, Dv, delay, K_known, x_ref):
    """Rows (re, im, dc) of every run and their right-hand sides, columns as ``_NAMES``.

    The caller drops the columns that are not identified, and weights and corrects the DC
    rows (they need K and fk_mean from the fundamental).
    """
    n = len(h)
    w = np.array([r.fit.omega for r in h])
    H = np.array([r.fit.stiffness for r in h])
    amp = np.array([abs(r.fit.displacement) for r in h])
    V = w * amp
    a, b = delay_factors(np.zeros(n), w, delay, P=Pv, D=Dv)
    z = b + 1j * w * a
    xbar = np.array([r.x_mean for r in h])
    ubar = np.array([r.u_mean for r in h])
    A = np.zeros((3, n, 6))
    y = np.zeros((3, n))
    A[0, :, 0], A[0, :, 2] = -(w**2), 1.0
    y[0] = H.real - z.real
    A[1, :, 1], A[1, :, 3] = w, 4.0 / (np.pi * amp)
    y[1] = H.imag - z.imag
    A[2, :, 2] = xbar - (0.0 if x_ref is None else x_ref)
    A[2, :, 4], A[2, :, 5] = 2.0 / np.pi * V, 1.0
    y[2] = ubar - Pv * xbar
    if K_known is not None:
        y[0] -= K_known
        y[2] -= K_known * A[2, :, 2]
    return w, H, amp, V, z, A, y


@plausibility_checked
def estimate_forced_friction(
    records: Sequence[Record],
    *,
    P: float | Sequence[float] | None = None,
    D: float | Sequence[float] | None = None,
    delay: float | None = None,
    omega: float | Sequence[float] | None = None,
    K_known: float | None = None,
    x_ref: float | None = None,
    settle_tol: float = 1e-4,
    min_periods: int = 3,
    method: str | None = None,
) -> Estimate:
    r"""J, K and asymmetric friction c_mean, c_delta, fk_mean, fk_delta from steady sine runs.

    Parameters
    ----------
    records : sequence of Record
        Steady sinusoidal runs, ``t`` [s], ``x`` [rad or m], the excitation ``u`` [N·m or
        N] (under feedback: the external excitation only), at >= 2 frequencies and >= 2
        velocity amplitudes ``ωA`` in all (the thesis's grid of frequencies × amplitudes,
        ch. 4); 3 frequencies when K is fitted.
    P : float or sequence of float, optional
        Proportional feedback gain [N·m/rad or N/m], one or one per run; default each
        record's ``meta["P"]``, else 0 (no feedback: the forced response).
    D : float or sequence of float, optional
        Derivative gain [N·m·s/rad or N·s/m]; default ``meta["D"]``, else 0.
    delay : float, optional
        Loop delay Δ [s], >= 0; default the first record's ``meta["delay"]``, else 0.
    omega : float or sequence of float, optional
        Excitation frequency of every run or one per run [rad/s]; estimated when None.
    K_known : float, optional
        Known stiffness [N·m/rad or N/m] (0 for a drive without spring).
    x_ref : float, optional
        Spring zero in the record's coordinates [rad or m]; needed for ``fk_delta`` when
        the drive has a spring (K not known to be 0). None: unknown.
    settle_tol : float
        Settling tolerance of :func:`driveid.identify.forced.forced.fit_sine_response` [-].
    min_periods : int
        Fewest steady periods per run [-]; >= 2.
    method : str, optional
        Method name of the estimate; default ``"forced-friction"``.

    Returns
    -------
    Estimate
        ``J`` [kg·m² or kg], ``c_mean``, ``c_delta`` [N·m·s/rad or N·s/m], ``K``
        [N·m/rad or N/m] (``fixed`` when given), ``fk_mean``, ``fk_delta`` [N·m or N],
        with standard errors and the covariance of the fitted ones (the intercept
        ``fk_delta - K x_ref`` is named ``dc_force_offset`` there). A parameter the data
        do not determine has value and error NaN and is listed in
        ``diagnostics["not_identified"]``. ``data_used`` per run: ``omega`` [rad/s],
        ``displacement_amplitude`` [rad or m], ``velocity_amplitude`` [rad/s or m/s],
        ``equivalent_damping`` ``Im(H - z)/ω`` [N·m·s/rad] with
        ``equivalent_damping_se``, ``equivalent_stiffness`` ``Re(H - z) + Jω²``
        [N·m/rad] with ``equivalent_stiffness_se``, ``harmonics`` (n, 3) [-], ``x_mean``
        [rad or m], ``u_mean`` [N·m or N], ``velocity_distortion`` [-], ``P``, ``D``.
        Diagnostics: ``chi2``, ``dof``,
        ``birge_ratio``, ``condition``, ``dc_force_offset`` (``fk_delta - K x_ref`` when
        x_ref is unknown) and its ``_se``, ``max_velocity_distortion``,
        ``max_stuck_fraction``, ``not_identified``.

    Raises
    ------
    IdentificationError
        Fewer than the needed distinct frequencies, a single velocity amplitude (viscous
        and Coulomb friction not separable), or a singular design.
    RecordError
        A record without ``u``, too short or never settling (the message names it).
    ParameterError
        An invalid argument.

    Notes
    -----
    Two weighted least-squares stages (module notes). Stage 1, the fundamental: the
    in-phase and quadrature rows of every run, weighted by the inverse covariance of
    ``(Re H, Im H)``, give J, c_mean, K, fk_mean. Stage 2, the mean force balance
    ``fk_delta + c_delta ((2/π) V - (2/(3π)) Re E_3) = ū - P x̄ - K̂ (x̄ - x_ref)
    + fk̂_mean 2 Re E_2/(πV)`` with K̂, fk̂_mean from stage 1 and the measured 2ω, 3ω
    velocity harmonics E_2, E_3 (the mean shifts of the module notes), weighted by its
    variance, gives c_delta, fk_delta; the errors of K̂ and fk̂_mean are carried into them,
    and their covariance with stage 1, by the delta method (``∂θ_2/∂K̂ = -G (x̄ - x_ref)``,
    ``∂θ_2/∂fk̂ = G 2 Re E_2/(πV)``, G the stage-2 gain). Stage 2 is not allowed to pull K
    towards its own describing-function error (in noise-free runs the means are far more
    precise than the fundamentals, so a joint fit would let them dominate K). Each stage's
    covariance is ``(AᵀWA)⁻¹ max(1, χ²/dof)``: the describing-function error of noise-free
    runs widens the errors instead of hiding. ``V = ωA`` is taken as exact (its relative
    error is that of |X|, negligible next to the means'). The equivalent damping's error
    is that of ``Im H`` over ω.

    Examples
    --------
    >>> t = np.arange(8001) / 1000
    >>> runs = []
    >>> for w, A in ((6.0, 0.2), (12.0, 0.1), (9.0, 0.3)):
    ...     H = 8.0 - 0.02 * w**2 + 1j * (w * 0.06 + 4 * 0.01 / (np.pi * A))
    ...     xbar = (0.05 - 0.004 - 2 / np.pi * 0.02 * w * A) / 8.0
    ...     u = 0.05 + A * abs(H) * np.sin(w * t + np.angle(H))
    ...     runs.append(Record(t=t, x=xbar + A * np.sin(w * t), u=u))
    >>> est = estimate_forced_friction(runs, x_ref=0.0)
    >>> [round(est.value(k), 6) for k in ("c_mean", "fk_mean", "c_delta", "fk_delta")]
    [0.06, 0.01, 0.02, 0.004]
    """
    records = record_list(records)
    if len(records) < 3:
        raise IdentificationError(
            "describing-function friction needs >= 3 sinusoidal runs (frequencies × "
            f"amplitudes); got {len(records)}")
    for name, value in (("K_known", K_known), ("x_ref", x_ref)):
        if value is not None and not (isinstance(value, (int, float))
                                      and math.isfinite(value)):
            raise ParameterError(f"{name} must be a finite number or None; got {value!r}")
    if delay is None:
        delay = records[0].meta.get("delay", 0.0) or 0.0
    if not (isinstance(delay, (int, float)) and math.isfinite(delay) and delay >= 0):
        raise ParameterError(f"delay must be a finite number >= 0 [s]; got {delay!r}")
    Pv = _gains(records, P, "P", "N·m/rad")
    Dv = _gains(records, D, "D", "N·m·s/rad")
    h = _harmonics_of(records, omega, settle_tol, min_periods)
    w, H, amp, V, z, A, y = _design(h, Pv, Dv, float(delay), K_known, x_ref)
    order = np.sort(w)
    n_freq = 1 + int(np.sum(np.diff(order) > 0.01 * order[1:]))
    need = 2 if K_known is not None else 3
    if n_freq < need:
        raise IdentificationError(
            f"{'J' if K_known is not None else 'J and K'} need runs at >= {need} distinct "
            f"frequencies; add a run at another frequency; got {n_freq} "
            f"({np.round(order, 6).tolist()} rad/s)")
    if np.ptp(V) < _SAME_SPEED * V.mean():
        raise IdentificationError(
            "the runs do not separate viscous from Coulomb friction: they need different "
            "velocity amplitudes ωA (change the force amplitude or the frequency); got "
            f"ωA = {np.round(V, 6).tolist()}")
    units = _units(records[0])
    free = [True, True, K_known is None, True, True, True]
    not_identified, notes = [], []
    has_stiffness = (K_known is None or K_known != 0.0) or bool(np.any(Pv != 0.0))
    if not has_stiffness:
        free[4] = free[5] = False
        not_identified += ["c_delta", "fk_delta"]
        notes.append("no spring and no feedback (K + P = 0): the mean position is free, so "
                     "c_delta and fk_delta are not identified; close a P loop or add a "
                     "spring to identify them")
    offset_free = has_stiffness and x_ref is None and (K_known is None or K_known != 0.0)
    if offset_free:
        not_identified.append("fk_delta")
        notes.append("the spring zero x_ref is unknown: fk_delta is not separable from "
                     "K·x_ref (diagnostics dc_force_offset = fk_delta - K·x_ref); pass "
                     "x_ref (CLI: --x-ref) to identify it")
    cov_h = np.array([r.fit.stiffness_cov for r in h])
    cov_h = cov_h + ((1e-9 * np.abs(H)) ** 2)[:, None, None] * np.eye(2)
    # stage 1, the fundamental: J, c_mean, K, fk_mean
    c1 = [i for i in range(4) if free[i]]
    Lt = np.transpose(np.linalg.cholesky(np.linalg.inv(cov_h)), (0, 2, 1))
    A1 = np.einsum("nij,njp->nip", Lt, np.stack([A[0], A[1]], axis=1)[:, :, c1])
    A1 = A1.reshape(-1, len(c1))
    y1 = np.einsum("nij,nj->ni", Lt, np.column_stack([y[0], y[1]])).reshape(-1)
    th1, cov1, chi2_1, dof1, cond = _wls(A1, y1)
    theta = np.full(6, math.nan)
    cov = np.zeros((6, 6))
    theta[c1] = th1
    cov[np.ix_(c1, c1)] = cov1
    chi2, dof = chi2_1, dof1
    if has_stiffness:
        # stage 2, the mean force balance with K, fk_mean from stage 1: c_delta, fk_delta,
        # with the mean shifts of the measured 2ω, 3ω velocity harmonics (module notes)
        k_hat = float(K_known) if K_known is not None else float(theta[2])
        fk_hat = float(theta[3])
        lever = A[2, :, 2]  # x̄ - x_ref (x̄ alone when x_ref is unknown)
        e2 = np.array([(2 * wi * r.second_harmonic).real for wi, r in zip(w, h, strict=True)])
        e3 = np.array([(3 * wi * r.third_harmonic).real for wi, r in zip(w, h, strict=True)])
        shift = 2.0 * e2 / (np.pi * V)
        a2 = np.column_stack([2.0 / np.pi * V - 2.0 / (3 * np.pi) * e3, np.ones_like(V)])
        y2 = y[2] - (0.0 if K_known is not None else k_hat * lever) + fk_hat * shift
        sd2 = np.sqrt(np.array([r.u_mean_se for r in h]) ** 2
                      + ((k_hat + Pv) * np.array([r.x_mean_se for r in h])) ** 2
                      + (fk_hat * 4 * w / (np.pi * V)
                         * np.array([r.harmonic_se for r in h])) ** 2
                      + (1e-9 * np.abs(y2) + 1e-300) ** 2)
        th2, cov2, chi2_2, dof2, cond2 = _wls(a2 / sd2[:, None], y2 / sd2)
        theta[4:] = th2
        cov[4:, 4:] = cov2
        # delta method: y2 depends on K̂ (-K̂·lever) and on fk̂_mean (+fk̂·shift)
        used = [i for i in (2, 3) if free[i]]
        dy = {2: -lever, 3: shift}
        gain = np.linalg.lstsq(a2 / sd2[:, None],
                               np.column_stack([dy[i] / sd2 for i in used]), rcond=None)[0]
        cov[4:, 4:] += gain @ cov[np.ix_(used, used)] @ gain.T
        cross = gain @ cov[used, :4]
        cov[4:, :4], cov[:4, 4:] = cross, cross.T
        chi2, dof, cond = chi2 + chi2_2, dof + dof2, max(cond, cond2)
    cols = [i for i in range(6) if free[i]]
    cov = cov[np.ix_(cols, cols)]
    se = np.sqrt(np.diag(cov))
    theta = theta[cols]
    unit_of = {"J": units["J"], "c_mean": units["c"], "K": units["K"], "fk_mean": units["f"],
               "c_delta": units["c"], "fk_delta": units["f"]}
    params = {}
    fitted = {_NAMES[c]: (float(theta[j]), float(se[j])) for j, c in enumerate(cols)}
    for name in _NAMES:
        if name == "K" and K_known is not None:
            params["K"] = Parameter(float(K_known), 0.0, units["K"], fixed=True)
        elif name in not_identified:
            params[name] = Parameter(math.nan, math.nan, unit_of[name])
        else:
            params[name] = Parameter(*fitted[name], unit_of[name])
    c2w = np.full(len(h), math.nan)
    if has_stiffness:  # a creeping free drive has even harmonics from the creep too
        c2w = _second_harmonic_c_delta(h, w, V, params["J"].value, params["K"].value,
                                       params["c_mean"].value, params["fk_mean"].value,
                                       Pv, Dv, float(delay))
    if method == "forced-pho":
        params["delay"] = Parameter(float(delay), 0.0, "s", fixed=True)
    diagnostics = {
        "chi2": chi2, "dof": int(dof), "birge_ratio": math.sqrt(max(1.0, chi2_1 / dof1)),
        "condition": cond,
        "n_records": len(h), "n_frequencies": n_freq,
        "max_velocity_distortion": float(max(r.velocity_distortion for r in h)),
        "max_response_distortion": float(max(r.fit.response_distortion for r in h)),
        "max_stuck_fraction": float(max(r.stuck_fraction for r in h)),
        "not_identified": sorted(set(not_identified)),
        "c_delta_2w_median": float(np.median(c2w)),
        "noise": [r.fit.noise for r in h],
        "runs_white": [bool(r.fit.noise.get("whiteness", {}).get("white", True)) for r in h],
    }
    if offset_free:
        diagnostics["dc_force_offset"], diagnostics["dc_force_offset_se"] = fitted["fk_delta"]
    warnings = list(notes)
    if diagnostics["max_velocity_distortion"] > WARN_VELOCITY_DISTORTION:
        warnings.append(
            f"the velocity has up to {100 * diagnostics['max_velocity_distortion']:.3g} % "
            "harmonics: the first-order describing function's error grows with them (up to "
            "that fraction of the friction); use larger amplitudes (friction small next to "
            "the force)")
    if diagnostics["max_stuck_fraction"] > _STICK_FRACTION:
        warnings.append(
            f"a run sticks ({100 * diagnostics['max_stuck_fraction']:.3g} % of its period at "
            "rest): the describing function assumes continuous sliding; drop low-amplitude "
            "runs or raise the force")
    drift = np.array([r.x_drift for r in h])
    if has_stiffness and np.any(np.abs(drift) > 0.01 * V):
        warnings.append("a run drifts (mean velocity above 1 % of V) although the loop has a "
                        "stiffness: the runs are not steady")
    # equivalent damping per run and its error (delta method on Im H)
    c_eq = (H.imag - z.imag) / w
    c_eq_se = np.sqrt(cov_h[:, 1, 1]) / w
    return Estimate(
        method=method or "forced-friction",
        params=params,
        covariance={"names": [("dc_force_offset" if offset_free and c == 5 else _NAMES[c])
                              for c in cols], "matrix": cov},
        data_used={
            "omega": w, "displacement_amplitude": amp, "velocity_amplitude": V,
            "equivalent_damping": c_eq, "equivalent_damping_se": c_eq_se,
            "equivalent_stiffness": H.real - z.real + params["J"].value * w**2,
            "equivalent_stiffness_se": np.sqrt(cov_h[:, 0, 0]),
            "x_mean": np.array([r.x_mean for r in h]),
            "u_mean": np.array([r.u_mean for r in h]),
            "velocity_distortion": np.array([r.velocity_distortion for r in h]),
            "harmonics": np.array([r.harmonics for r in h]),
            "c_delta_2w": c2w,
            "amplitude_ratio": np.abs(H), "phase_lag": np.angle(H),
            "force_amplitude": np.array([abs(r.fit.force) for r in h]),
            "t_start": np.array([r.fit.t_start for r in h]),
            "n_periods": np.array([r.fit.n_periods for r in h]), "P": Pv, "D": Dv,
            "delay": float(delay),
        },
        diagnostics=diagnostics,
        warnings=tuple(warnings),
    )


@dataclass(frozen=True, kw_only=True)
class SineGridTest:
    """Amplitude dependence of friction and stiffness over a grid of sine runs (ch. 4).

    Attributes
    ----------
    friction : Estimate
        :func:`estimate_forced_friction` on all runs.
    omega : ndarray, shape (n,)
        Excitation frequency of each run [rad/s].
    displacement_amplitude, velocity_amplitude : ndarray, shape (n,)
        ``A`` [rad or m] and ``V = ωA`` [rad/s or m/s].
    equivalent_damping, equivalent_damping_se : ndarray, shape (n,)
        Measured ``Im(H - z)/ω`` [N·m·s/rad or N·s/m] and its standard error.
    describing_damping : ndarray, shape (n,)
        The fitted model ``c_mean + 4 fk_mean/(π V)`` [N·m·s/rad or N·s/m].
    stiffness_residual, stiffness_residual_se : ndarray, shape (n,)
        ``Re(H - z) - (K - Jω²)`` with the fitted J, K [N·m/rad or N/m] and its error.
    harmonics : ndarray, shape (n, 3)
        x harmonics at 2ω, 3ω, 4ω over the fundamental [-] (2ω, 4ω: asymmetry; 3ω:
        Coulomb friction, backlash).
    stiffness_slope, stiffness_slope_se : float
        ``κ`` of ``Re(H - z) = K - Jω² + κ/A`` [N·m or N] and its standard error.
    stiffness_change : float
        ``κ (1/A_max - 1/A_min)`` over the median ``|H|``: relative rise of the in-phase
        stiffness from the smallest to the largest amplitude [-].
    friction_amplitude_dependent : bool
        ``fk_mean`` above 3 standard errors: the damping falls with the amplitude.
    backlash_indicated : bool
        The stiffness rises with the amplitude (κ below -3 standard errors and
        ``stiffness_change`` above ``min_stiffness_change``): a gap (backlash) or a softening
        compliance at small amplitudes.
    """

    friction: Estimate
    omega: np.ndarray
    displacement_amplitude: np.ndarray
    velocity_amplitude: np.ndarray
    equivalent_damping: np.ndarray
    equivalent_damping_se: np.ndarray
    describing_damping: np.ndarray
    stiffness_residual: np.ndarray
    stiffness_residual_se: np.ndarray
    harmonics: np.ndarray
    stiffness_slope: float
    stiffness_slope_se: float
    stiffness_change: float
    friction_amplitude_dependent: bool
    backlash_indicated: bool


def sine_grid_test(records: Sequence[Record], *, min_stiffness_change: float = 0.02,
                   **kwargs) -> SineGridTest:
    r"""Sine-sweep grid test of friction and backlash amplitude dependence (thesis ch. 4).

    Parameters
    ----------
    records : sequence of Record
        Steady sine runs on a grid of frequencies × amplitudes (``t`` [s], ``x`` [rad or
        m], ``u`` [N·m or N]); at least 2 amplitudes per frequency are advised.
    min_stiffness_change : float
        Smallest relative stiffness rise across the amplitudes called backlash [-], > 0
        (default 2 %: the describing-function error of friction alone, module notes).
    **kwargs
        Passed to :func:`estimate_forced_friction` (``P``, ``D``, ``delay``,
        ``K_known``, ``x_ref``, ``omega``, ``settle_tol``, ``min_periods``).

    Returns
    -------
    SineGridTest
        Per-run equivalent damping and in-phase stiffness against the describing-function
        model, harmonics, and the two verdicts.

    Raises
    ------
    IdentificationError, RecordError, ParameterError
        As :func:`estimate_forced_friction`.

    Notes
    -----
    Friction: asymmetric Coulomb friction makes the equivalent damping fall as ``1/V``
    (``4 fk_mean/(πV)``) and shifts the mean position (``c_delta``, ``fk_delta``); both are
    fitted by :func:`estimate_forced_friction`. Backlash: within a gap the driven body loses
    the load's stiffness (and inertia), so the in-phase dynamic stiffness rises with the
    amplitude, roughly as ``-κ/A`` (the describing function of a dead-zone spring tends to
    ``K (1 - 4b/(πA))`` for a gap ``2b ≪ A``). Coulomb friction alone has no in-phase
    fundamental; sticking acts as a stiffness at small amplitudes (κ > 0), the opposite
    sign. κ comes from a weighted least-squares fit of the stiffness residuals on ``1/A``
    with Birge-scaled errors.

    Examples
    --------
    >>> t = np.arange(8001) / 1000
    >>> runs = []
    >>> for w, A in ((6.0, 0.2), (12.0, 0.1), (9.0, 0.3), (9.0, 0.15)):
    ...     H = 8.0 - 0.02 * w**2 + 1j * (w * 0.06 + 4 * 0.01 / (np.pi * A))
    ...     u = A * abs(H) * np.sin(w * t + np.angle(H))
    ...     runs.append(Record(t=t, x=A * np.sin(w * t), u=u))
    >>> grid = sine_grid_test(runs, x_ref=0.0)
    >>> grid.friction_amplitude_dependent, grid.backlash_indicated
    (True, False)
    """
    if not (isinstance(min_stiffness_change, (int, float)) and min_stiffness_change > 0):
        raise ParameterError(
            f"min_stiffness_change must be > 0 [-]; got {min_stiffness_change!r}")
    est = estimate_forced_friction(records, **kwargs)
    du = est.data_used
    w, amp, V = du["omega"], du["displacement_amplitude"], du["velocity_amplitude"]
    scale = float(np.median(du["amplitude_ratio"]))
    K = est.value("K")
    c, fk = est.value("c_mean"), est.value("fk_mean")
    resid = du["equivalent_stiffness"] - K
    resid_se = np.maximum(du["equivalent_stiffness_se"], 1e-9 * scale)
    basis = np.column_stack([np.ones_like(w), 1.0 / amp]) / resid_se[:, None]
    slope, cov, *_ = _wls(basis, resid / resid_se)
    kappa, kappa_se = float(slope[1]), float(math.sqrt(cov[1, 1]))
    change = kappa * (1.0 / amp.max() - 1.0 / amp.min()) / scale
    fk_p = est["fk_mean"]
    return SineGridTest(
        friction=est, omega=w, displacement_amplitude=amp, velocity_amplitude=V,
        equivalent_damping=du["equivalent_damping"],
        equivalent_damping_se=du["equivalent_damping_se"],
        describing_damping=c + 4.0 * fk / (np.pi * V),
        stiffness_residual=resid, stiffness_residual_se=resid_se,
        harmonics=du["harmonics"], stiffness_slope=kappa, stiffness_slope_se=kappa_se,
        stiffness_change=float(change),
        friction_amplitude_dependent=bool(fk_p.value > 3.0 * fk_p.stderr),
        backlash_indicated=bool(kappa < -3.0 * kappa_se and change > min_stiffness_change))
