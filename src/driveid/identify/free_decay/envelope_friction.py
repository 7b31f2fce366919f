r"""Viscous and Coulomb friction from the amplitude dependence of the damping.

The Hilbert (:func:`driveid.identify.free_decay.hilbert.estimate_hilbert`) and wavelet
(:func:`driveid.identify.free_decay.wavelet.estimate_wavelet`) methods return the instantaneous
amplitude ``A(t)``, natural frequency ``ω0(t)`` and damping ratio ``ζ(t)`` of a free decay
(their ``data_used["amplitude"]``, ``["omega0"]``, ``["zeta"]``). Their figures show the
Coulomb signature: ζ rises as the amplitude falls. First-order averaging of
``J x'' + c x' + K x + fk sgn x' = 0`` over one cycle (energy lost per cycle
``π c ω A² + 4 fk A`` against the energy ``K A²/2``; the equivalent linearisation behind the
thesis's describing-function view of §2.2.5) gives the envelope decay rate

.. math::

    σ(A) = ζ ω_0 = \frac{c}{2J} + \frac{2 f_k}{π J ω_0 A},

linear in ``(c/2J, 2 fk/(π J))`` with the regressors ``1`` and ``1/(ω0 A)``. With
``α = c/2J`` and ``β = 2 fk/(π J ω0)`` the envelope obeys ``dA/dt = -α A - β``, solved by
``A(t) = (A_0 + β/α) e^{-α t} - β/α`` (Feeny & Liang's mixed decay, [3]_); fitting that to
``A(t)`` (default) or ``ζ ω0`` to the regressors gives ``c_mean`` and ``fk_mean`` (per unit
inertia without ``mass``), and ``K = J ω̄0²`` as the backbone mean.

Asymmetry (``c_delta``, ``fk_delta``) is not identifiable from these envelopes: to first
order ``c_delta |x'|`` and ``fk_delta`` have no component at the oscillation frequency (they
shift the centre of the oscillation, which the Hilbert/wavelet amplitude discards), so the
estimate carries ``c_mean`` and ``fk_mean`` only, and ``c_mean`` is the period-weighted
mean of ``c±`` (for the log-decrement asymmetry use :mod:`driveid.identify.free_decay.logdec`).

Standard errors: ordinary LS on samples that are correlated over about one period; the
covariance is multiplied by the number of samples per period (a conservative effective
sample count).

References
----------
.. [1] J. A. de Marchi, "Modeling of dynamic friction, impact backlash and elastic compliance
       nonlinearities in machine tools", PhD thesis, Rensselaer Polytechnic Institute, 1998,
       §2.2.5, Table 5.1.
.. [2] M. Feldman, *Hilbert Transform Applications in Mechanical Vibration*, Wiley, 2011,
       §7.3 (friction from the damping curve). doi:10.1002/9781119991656
.. [3] B. F. Feeny, J. W. Liang, "A decrement method for the simultaneous estimation of
       Coulomb and viscous friction", J. Sound Vib. 195(1), 149-154, 1996.
       doi:10.1006/jsvi.1996.0411
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from scipy.optimize import least_squares

from driveid.errors import IdentificationError, ParameterError
from driveid.identify.core.estimate import Estimate, Parameter

__all__ = ["friction_from_envelope"]


def _arrays(source: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    if isinstance(source, Estimate):
        data = source.data_used
        missing = [k for k in ("t", "amplitude", "zeta", "omega0") if k not in data]
        if missing:
            raise ParameterError(
                f"the {source.method} estimate has no data_used {missing}; pass a one-mode "
                "Hilbert or wavelet estimate, or the arrays (t, amplitude, zeta, omega0)")
        vals = [np.asarray(data[k], dtype=float) for k in ("t", "amplitude", "zeta", "omega0")]
    else:
        try:
            vals = [np.asarray(v, dtype=float) for v in source]
        except TypeError:
            raise ParameterError(
                "source must be an Estimate or a tuple (t, amplitude, zeta, omega0) of "
                f"arrays; got {type(source).__name__}") from None
        if len(vals) != 4:
            raise ParameterError(f"expected 4 arrays (t, amplitude, zeta, omega0); got {len(vals)}")
    shapes = {v.shape for v in vals}
    if len(shapes) != 1 or vals[0].ndim != 1:
        raise ParameterError(f"the arrays must be 1-D of one length; got shapes {shapes}")
    return tuple(vals)


def _fit_amplitude(t: np.ndarray, amp: np.ndarray, w0: float):
    """Fit A(t) = (A0 + β/α) e^{-α τ} - β/α; return (α, β·ω0), covariance, residual."""
    tau = t - t[0]

    def model(p):
        a0, alpha, beta = p
        if abs(alpha) < 1e-12:
            return a0 - beta * tau
        return (a0 + beta / alpha) * np.exp(-alpha * tau) - beta / alpha

    # start: straight-line and log-linear guesses
    slope = -np.polyfit(tau, amp, 1)[0]
    p0 = np.array([amp[0], 1e-3 / max(tau[-1], 1e-12), max(slope, 0.0)])
    res = least_squares(lambda p: model(p) - amp, p0, method="lm", x_scale="jac")
    jac = res.jac
    resid = res.fun
    s2 = float(resid @ resid) / max(amp.size - 3, 1)
    cov = s2 * np.linalg.pinv(jac.T @ jac)
    # θ = (α, β ω0): β = 2 fk/(π J ω0) so β ω0 = 2 fk/(π J), the damping form's slope
    T = np.diag([1.0, w0])
    theta = T @ res.x[1:]
    return theta, T @ cov[1:, 1:] @ T, resid


def friction_from_envelope(source: Any, *, mass: float | None = None,
                           amplitude_min: float = 0.0, units: str = "rad",
                           method: str = "amplitude") -> Estimate:
    r"""Fit ``ζ ω0 = c/(2J) + 2 fk/(π J ω0 A)`` to a Hilbert or wavelet decay.

    Parameters
    ----------
    source : Estimate or tuple of ndarray
        A one-mode result of :func:`~driveid.identify.free_decay.hilbert.estimate_hilbert` or
        :func:`~driveid.identify.free_decay.wavelet.estimate_wavelet`, or the arrays
        ``(t [s], amplitude [rad or m], zeta [-], omega0 [rad/s])`` of equal length.
    mass : float, optional
        Inertia J [kg·m² or kg]; without it ``c_mean`` [1/s] and ``fk_mean`` [rad/s² or
        m/s²] are per unit inertia and K is not reported.
    amplitude_min : float
        Samples with a smaller amplitude are ignored [rad or m] (e.g. the stuck tail).
    units : {"rad", "m"}
        Rotational or translational units of the result.
    method : {"amplitude", "damping"}
        ``"amplitude"`` (default): fit the closed-form solution of
        ``dA/dt = -σ(A) A`` (module notes) to A(t), which uses the amplitude itself;
        ``"damping"``: linear LS of ``ζ ω0`` on ``1, 1/(ω0 A)`` (uses the instantaneous ζ,
        noisier and biased where the method's ζ is smoothed).

    Returns
    -------
    Estimate
        Method ``"envelope-friction"``: ``c_mean``, ``fk_mean``, ``omega0`` (mean of the
        samples used) and, with ``mass``, ``J`` (given) and ``K``; covariance of
        (c_mean, fk_mean). ``data_used``: ``amplitude`` and ``decay_rate`` samples used.

    Raises
    ------
    IdentificationError
        Fewer than 3 usable samples, or amplitudes that do not vary (the viscous and
        Coulomb terms then cannot be told apart).
    ParameterError
        On a bad argument.

    Examples
    --------
    >>> A = np.linspace(1.0, 0.2, 200); w = np.full(200, 4.0)
    >>> zeta = (0.3 / 2 + 2 * 0.07 / (np.pi * 4.0 * A)) / 4.0
    >>> est = friction_from_envelope((np.arange(200.0), A, zeta, w), mass=1.0,
    ...                              method="damping")
    >>> round(est.value("c_mean"), 9), round(est.value("fk_mean"), 9)
    (0.3, 0.07)
    """
    t, amp, zeta, w0 = _arrays(source)
    if mass is not None and not (isinstance(mass, (int, float)) and mass > 0):
        raise ParameterError(f"mass must be a positive inertia [kg·m² or kg]; got {mass!r}")
    if units not in ("rad", "m"):
        raise ParameterError(f'units must be "rad" or "m"; got {units!r}')
    if method not in ("amplitude", "damping"):
        raise ParameterError(f'method must be "amplitude" or "damping"; got {method!r}')
    ok = np.isfinite(amp) & np.isfinite(zeta) & np.isfinite(w0) & (amp > amplitude_min)
    ok &= (amp > 0) & (w0 > 0)
    if ok.sum() < 3:
        raise IdentificationError(
            f"{int(ok.sum())} usable envelope samples (finite, amplitude > {amplitude_min}); "
            "need >= 3: lower amplitude_min or use a longer decay")
    amp, zeta, w0, t = amp[ok], zeta[ok], w0[ok], t[ok]
    # a decay ends where its envelope is lowest; after that comes the stuck tail or the
    # method's end effect, neither of them the friction law
    stop = int(np.argmin(amp)) + 1
    amp, zeta, w0, t = amp[:stop], zeta[:stop], w0[:stop], t[:stop]
    if amp.size < 3:
        raise IdentificationError(
            "the envelope is lowest at its start; this is no decay (use a free-decay "
            "Hilbert or wavelet estimate)")
    if np.ptp(amp) < 0.1 * amp.max():
        raise IdentificationError(
            "the amplitude varies by less than 10 % over the samples; the viscous and "
            f"Coulomb terms cannot be separated (got {amp.min():.4g} to {amp.max():.4g})")
    y = zeta * w0
    period = 2 * np.pi / float(np.mean(w0))
    dt = float(np.median(np.diff(t))) if t.size > 1 else period
    per_period = max(period / dt, 1.0) if dt > 0 else 1.0
    if method == "damping":
        A = np.column_stack([np.ones_like(y), 1.0 / (w0 * amp)])
        theta, *_ = np.linalg.lstsq(A, y, rcond=None)
        resid = y - A @ theta
        s2 = float(resid @ resid) / max(y.size - 2, 1)
        cov_theta = s2 * np.linalg.inv(A.T @ A) * per_period
    else:
        theta, cov_theta, resid = _fit_amplitude(t, amp, float(np.mean(w0)))
        cov_theta = cov_theta * per_period
        s2 = float(resid @ resid) / max(y.size - 3, 1)
    J = 1.0 if mass is None else float(mass)
    # c = 2 J θ0, fk = (π J / 2) θ1
    G = np.diag([2.0 * J, 0.5 * np.pi * J])
    cov = G @ cov_theta @ G
    c, fk = float(G[0, 0] * theta[0]), float(G[1, 1] * theta[1])
    se = np.sqrt(np.diag(cov))
    w_mean = float(np.mean(w0))
    w_se = float(np.std(w0, ddof=1) / math.sqrt(max(y.size / per_period, 1.0)))
    if mass is None:
        unit = {"c": "1/s", "f": "rad/s²" if units == "rad" else "m/s²"}
    else:
        unit = ({"c": "N·m·s/rad", "f": "N·m", "J": "kg·m²", "K": "N·m/rad"} if units == "rad"
                else {"c": "N·s/m", "f": "N", "J": "kg", "K": "N/m"})
    params = {"c_mean": Parameter(c, float(se[0]), unit["c"]),
              "fk_mean": Parameter(fk, float(se[1]), unit["f"]),
              "omega0": Parameter(w_mean, w_se, "rad/s")}
    if mass is not None:
        params["J"] = Parameter(J, math.nan, unit["J"], fixed=True)
        params["K"] = Parameter(J * w_mean**2, 2 * J * w_mean * w_se, unit["K"])
    warnings = []
    if fk < -2 * se[1]:
        warnings.append(f"fk_mean = {fk:.4g} is negative beyond 2σ: the damping falls as the "
                        "amplitude falls (not Coulomb friction; check the window)")
    return Estimate(
        method="envelope-friction", params=params,
        covariance={"names": ["c_mean", "fk_mean"], "matrix": cov},
        data_used={"amplitude": amp, "decay_rate": y},
        diagnostics={"n_samples": int(y.size), "samples_per_period": per_period,
                     "residual_rms": math.sqrt(s2),
                     "source": source.method if isinstance(source, Estimate) else "arrays"},
        warnings=tuple(warnings),
    )


# Phasor-model helpers of driveid.identify.free_decay.hilbert.estimate_envelope_damping (moved here
# to keep hilbert.py small; same subject: friction from the envelope).

_RIPPLE_HARMONICS = (-1, 1)


def _limit_cycle_phasor(sigma: float, omega0: float, n: int = 4096) -> complex:
    """Cycle phasor of the friction limit cycle per unit ``d = fk/K`` (symmetric damping).

    Between two velocity reversals the motion is a damped cosine about the centre
    ``-d sgn(v)``; the reversals are a fixed half period ``pi/omega_d`` apart whatever the
    amplitude, so a free decay is ``x = x_p(t) + exp(-sigma t) P(t)`` with ``x_p`` and ``P``
    of period ``T = 2 pi/omega_d``: ``x_p`` the (virtual) periodic solution of the friction
    forcing, ``exp(-sigma t) P`` the homogeneous part. Returns twice the fundamental Fourier
    coefficient of ``x_p`` (what :func:`~driveid.signal.envelope.cycle_phasor` gives for it)
    with the phase of the fundamental of ``P`` removed, for ``d = 1``.
    """
    wd = math.sqrt(omega0**2 - sigma**2)
    half = math.pi / wd
    tau = (np.arange(n) + 0.5) * half / n
    shape = np.exp(-sigma * tau) * (np.cos(wd * tau) + sigma / wd * np.sin(wd * tau))
    rho = math.exp(-sigma * half)
    # half cycle with v > 0 from the minimum m0 about the centre -d; the limit cycle is
    # half-wave symmetric, x(t + T/2) = -x(t), with m0 = d (1 + rho) / (1 - rho)
    xp = -1.0 + (1 + rho) / (1 - rho) * shape + shape
    hom = -shape * np.exp(sigma * tau)
    kernel = np.exp(-1j * wd * tau)
    # half-wave symmetry: the fundamental over a period is twice that over a half period
    xp1, hom1 = np.mean(xp * kernel), np.mean(hom * kernel)
    return complex(2 * xp1 * np.conj(hom1) / abs(hom1))


#: Fewest periods in the window for fitting the non-decaying ripple terms [-].
_DRIFT_RIPPLE_PERIODS = 4.0


def _phasor_basis(kind: str, s: float, tw: np.ndarray, omega: float,
                  drift: bool) -> np.ndarray:
    """Columns of the complex envelope models (see :func:`estimate_envelope_damping`)."""
    ones = np.ones_like(tw)
    decay = ones if kind == "coulomb" else np.exp(-s * tw)
    cols = {"viscous": [decay], "coulomb": [ones, tw], "combined": [ones, decay]}[kind]
    cols = cols + [decay * np.exp(1j * m * omega * tw) for m in _RIPPLE_HARMONICS]
    if drift and kind != "coulomb":
        cols = cols + [np.exp(1j * m * omega * tw) for m in _RIPPLE_HARMONICS]
    return np.column_stack(cols).astype(complex)


def _fit_phasor(kind: str, tw: np.ndarray, y: np.ndarray, omega: float,
                sigma0: float, drift: bool) -> dict[str, Any]:
    """Fit ``Y = exp(j dw t) B(sigma) c``: variable projection over (sigma, dw)."""
    def unpack(q: np.ndarray) -> tuple[float, float]:
        return (0.0, float(q[0])) if kind == "coulomb" else (float(q[0]), float(q[1]))

    def project(q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        s, dw = unpack(q)
        yr = y * np.exp(-1j * dw * tw)
        basis = _phasor_basis(kind, s, tw, omega, drift)
        coef = np.linalg.lstsq(basis, yr, rcond=None)[0]
        return yr - basis @ coef, coef

    def residual(q: np.ndarray) -> np.ndarray:
        r = project(q)[0]
        return np.concatenate([r.real, r.imag])

    span = float(tw[-1])
    dw_scale = 0.1 / span
    if kind == "coulomb":
        starts, lower, scale = [[0.0]], [-np.inf], [dw_scale]
    else:
        starts = [[k * sigma0, 0.0] for k in (0.3, 1.0, 3.0)]
        # below ~1e-3 / span the decay is a straight line: the Coulomb model
        lower, scale = [1e-3 / span, -np.inf], [sigma0, dw_scale]
    best = None
    for q0 in starts:
        q0 = np.maximum(q0, np.array(lower) * (1 + 1e-9))
        fit = least_squares(residual, q0, bounds=(lower, np.inf), x_scale=scale)
        if best is None or fit.cost < best.cost:
            best = fit
    s, dw = unpack(best.x)
    r, coef = project(best.x)
    # full Jacobian of the real-stacked residual in (nonlinear..., Re c, Im c)
    rot = np.exp(1j * dw * tw)
    basis = _phasor_basis(kind, s, tw, omega, drift)
    model = rot * (basis @ coef)
    cols = []
    if kind != "coulomb":
        dbasis = -tw[:, None] * basis
        if kind == "combined":
            dbasis[:, 0] = 0.0
        if drift:
            dbasis[:, -len(_RIPPLE_HARMONICS):] = 0.0  # the non-decaying ripple terms
        cols.append(rot * (dbasis @ coef))
    cols.append(1j * tw * model)
    for k in range(coef.size):
        cols += [rot * basis[:, k], 1j * rot * basis[:, k]]
    jac = np.column_stack(cols)
    jac = np.vstack([jac.real, jac.imag])
    return {"sigma": s, "dw": dw, "coef": coef, "rss": float(np.vdot(r, r).real),
            "jac": jac, "model": model,
            "p": np.concatenate([[s] if kind != "coulomb" else [], [dw],
                                 np.column_stack([coef.real, coef.imag]).ravel()])}


def _crossings(x: np.ndarray, t: np.ndarray, band: float) -> tuple[float, float]:
    """Time of the last crossing of the midline beyond ``±band`` [s] and the frequency.

    The frequency [rad/s] counts whole cycles between crossings: asymmetric friction
    offsets the centre every half cycle, so half-cycle intervals alternate but cycles don't.
    """
    state = np.where(x > band, 1, np.where(x < -band, -1, 0))
    idx = np.flatnonzero(state)
    crossings = idx[1:][np.diff(state[idx]) != 0]
    if crossings.size < 3:
        raise IdentificationError(
            "the record does not oscillate enough for envelope damping separation: it needs "
            f"at least 3 crossings of the midline beyond ±{band:.3g} (1 % of the peak or 5x "
            f"noise); record a longer free decay; got {crossings.size}"
        )
    tc = t[crossings]
    n_cycles = (tc.size - 1) // 2
    return float(tc[-1]), 2 * np.pi * n_cycles / float(tc[2 * n_cycles] - tc[0])
