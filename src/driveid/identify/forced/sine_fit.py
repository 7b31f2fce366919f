"""Steady-state sine fit of one forced run: amplitude, phase and distortion of x and u.

The measurement step of the forced response (de Marchi 1998, §2.2.6, Eqs. 2.176-2.177): once
the transient has died out, the input ``u = A_1 sin(ωt - φ_1)`` and the response
``x = A_2 sin(ωt - φ_2)`` are fitted over whole periods by linear least squares; the
dynamic stiffness ``H = R e^{jρ}`` (2.179) follows. Used by
:mod:`~driveid.identify.forced.forced` and :mod:`~driveid.identify.forced.forced_friction`,
below both.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.optimize import minimize_scalar

from driveid.errors import IdentificationError, ParameterError, RecordError
from driveid.identify.core._adequacy import ljung_box
from driveid.identify.core._noise import NoiseModel, fit_noise_model
from driveid.io.record import Record

__all__ = ["MAX_INPUT_DISTORTION", "SineResponse", "fit_sine_response", "record_list"]

#: Relative rms residual of the input sine fit above which u is "not sinusoidal" [-].
MAX_INPUT_DISTORTION = 0.05


@dataclass(frozen=True, kw_only=True)
class SineResponse:
    """Steady-state sine fit of one forced run at its excitation frequency.

    Phasors follow ``s(t) = Im(Z e^{jω(t - t_ref)})``, i.e. ``Z = A e^{-jφ}`` for
    ``A sin(ω (t - t_ref) - φ)``.

    Attributes
    ----------
    omega : float
        Excitation frequency ω [rad/s].
    force : complex
        Input phasor U [N·m or N].
    displacement : complex
        Response phasor X [rad or m].
    stiffness : complex
        Dynamic stiffness ``H = U / X = R e^{jρ}`` [N·m/rad or N/m].
    stiffness_cov : ndarray, shape (2, 2)
        Covariance of (Re H, Im H) [(N·m/rad)² or (N/m)²], from the residuals of both fits.
    t_start, t_stop : float
        Steady-state window used [s] (an integer number of periods).
    t_ref : float
        Time origin of the phasors [s] (first sample of the record).
    n_periods : int
        Periods in the steady window [-].
    input_distortion : float
        RMS residual of the input sine fit over the input rms [-].
    response_distortion : float
        RMS residual (harmonics, noise) of the response fit over the response rms [-].
    noise : dict
        Noise models of the two fits (``"x"``, ``"u"``: order, AR coefficients, ``n_eff``,
        see :meth:`driveid.identify.core._noise.NoiseModel.to_dict`) and ``"whiteness"``
        (Ljung–Box of the prewhitened response residual).
    """

    omega: float
    force: complex
    displacement: complex
    stiffness: complex
    stiffness_cov: np.ndarray
    t_start: float
    t_stop: float
    t_ref: float
    n_periods: int
    input_distortion: float
    response_distortion: float
    noise: dict[str, Any] = field(default_factory=dict)

    @property
    def amplitude_ratio(self) -> float:
        """Relative amplitude ``R = A_1 / A_2`` (2.179) [N·m/rad or N/m]."""
        return abs(self.stiffness)

    @property
    def phase_lag(self) -> float:
        """Relative phase lag ``ρ = φ_2 - φ_1`` (2.179) [rad], in (-π, π]."""
        return float(np.angle(self.stiffness))

    @property
    def amplitude_ratio_se(self) -> float:
        """Standard error of R [N·m/rad or N/m] (linearised)."""
        g = np.array([self.stiffness.real, self.stiffness.imag]) / abs(self.stiffness)
        return float(math.sqrt(max(g @ self.stiffness_cov @ g, 0.0)))

    @property
    def phase_lag_se(self) -> float:
        """Standard error of ρ [rad] (linearised)."""
        h = self.stiffness
        g = np.array([-h.imag, h.real]) / abs(h) ** 2
        return float(math.sqrt(max(g @ self.stiffness_cov @ g, 0.0)))


def _lsq(basis: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Coefficients, their covariance (white residuals) and the residual."""
    coef, *_ = np.linalg.lstsq(basis, y, rcond=None)
    resid = y - basis @ coef
    dof = max(basis.shape[0] - basis.shape[1], 1)
    s2 = float(resid @ resid) / dof
    cov = s2 * np.linalg.inv(basis.T @ basis)
    return coef, cov, resid


#: Harmonics removed from a residual before its noise model is fitted [-].
_HARMONICS = 5


def _noise_covariance(basis: np.ndarray, resid: np.ndarray, tau: np.ndarray, omega: float
                      ) -> tuple[np.ndarray, NoiseModel, dict[str, Any]]:
    """Covariance of least-squares sine coefficients under an AR(p) noise model.

    The harmonics 2ω…5ω of a nonlinear response are deterministic and orthogonal to the
    fundamental over whole periods: they are regressed out of the residual before the AR
    model is fitted, so that they are not mistaken for noise. The coefficients stay the
    ordinary least-squares ones (for sinusoidal regressors they are asymptotically as
    efficient as GLS: Grenander 1954); their covariance is ``σ_w² (B_wᵀ B_w)⁻¹`` with the
    prewhitened basis ``B_w`` — the white-noise one when the model has order 0.
    """
    cols = [f(k * omega * tau) for k in range(2, _HARMONICS + 1) for f in (np.sin, np.cos)]
    harm = np.column_stack(cols)
    # normal equations: harmonics over whole periods are near-orthogonal (and an SVD
    # lstsq costs ~30x more here)
    noise = resid - harm @ np.linalg.solve(harm.T @ harm, harm.T @ resid)
    model = fit_noise_model(noise, n_params=basis.shape[1] + harm.shape[1])
    bw = model.whiten(basis)
    cov = model.innovation_variance * np.linalg.inv(bw.T @ bw)
    if model.is_white:
        dof = max(basis.shape[0] - basis.shape[1], 1)
        cov = float(resid @ resid) / dof * np.linalg.inv(basis.T @ basis)
    white = ljung_box(model.whiten(noise), lags=max(20, model.order + 20),
                      fitted=model.order)
    return cov, model, {k: v for k, v in white.items() if k != "acf"}


def _sine_basis(tau: np.ndarray, omega: float, drift: bool = False) -> np.ndarray:
    cols = [np.sin(omega * tau), np.cos(omega * tau), np.ones_like(tau)]
    if drift:
        cols.append((tau - tau.mean()) / max(np.ptp(tau), 1e-300))
    return np.column_stack(cols)


def _distortion(coef: np.ndarray, resid: np.ndarray) -> float:
    """RMS residual over the rms of the fitted sinusoid [-]."""
    amp = math.hypot(coef[0], coef[1])
    return float(np.sqrt(np.mean(resid**2)) / (amp / math.sqrt(2) + 1e-300))


def _input_frequency(tau: np.ndarray, u: np.ndarray, dt: float) -> float:
    """Frequency [rad/s] of the dominant sinusoid of u: FFT peak, then best sine fit."""
    n = u.size
    m = 1 << int(math.ceil(math.log2(8 * n)))
    spec = np.abs(np.fft.rfft((u - u.mean()) * np.hanning(n), m))
    spec[0] = 0.0
    k = int(np.argmax(spec))
    step = 2 * math.pi / (m * dt)

    def rss(w: float) -> float:
        basis = _sine_basis(tau, w)
        coef, *_ = np.linalg.lstsq(basis, u, rcond=None)
        r = u - basis @ coef
        return float(r @ r)

    lo, hi = max(k - 1, 1e-3) * step, (k + 1) * step
    res = minimize_scalar(rss, bounds=(lo, hi), method="bounded",
                          options={"xatol": 1e-10 * hi})
    return float(res.x)


def fit_sine_response(
    record: Record,
    *,
    omega: float | None = None,
    settle_tol: float = 1e-4,
    min_periods: int = 3,
) -> SineResponse:
    r"""Fit the steady sinusoidal input and response of one forced run.

    Parameters
    ----------
    record : Record
        A run with ``t`` [s], ``x`` [rad or m] and the external sinusoidal input ``u``
        [N·m or N] (under feedback: the excitation only, not the total command).
    omega : float, optional
        Excitation frequency [rad/s], > 0; estimated from ``u`` when None.
    settle_tol : float
        The transient counts as over once every later one-period fit of x differs from the
        final steady fit by less than ``settle_tol`` times its amplitude [-] (or by five
        standard errors of a one-period fit, if larger); in (0, 1).
    min_periods : int
        Fewest whole excitation periods required after the transient [-]; >= 2.

    Returns
    -------
    SineResponse
        Phasors of u and x at ω, the dynamic stiffness ``U/X`` with its covariance, the
        steady window and the distortion of both signals.

    Raises
    ------
    RecordError
        If the record has no ``u``, has corrupted samples, or holds fewer than
        ``min_periods`` periods after the transient (also when x never settles).
    IdentificationError
        If u is not a sinusoid (at ``omega``) or is sampled with fewer than 4 points per
        period.
    ParameterError
        If ``omega``, ``settle_tol`` or ``min_periods`` are invalid.

    Notes
    -----
    ω comes from the FFT peak of u refined by the best sine fit; u must be one sinusoid over
    the whole record (rms residual below 5 % of its rms). Each one-period window of x is
    fitted by ``a sin ωτ + b cos ωτ + c`` (τ = t - t_0); the steady state starts after the
    last window that deviates from the fit over the last quarter of the windows by more
    than the threshold. Over the steady window (whole
    periods) x is fitted with ``sin, cos``, an offset and a linear drift, u with ``sin, cos``
    and an offset; their standard errors come from an AR(p) model of the residuals (order by
    BIC, :mod:`driveid.identify.core._noise`; white residuals give the white-noise ones), so a
    coloured sensor chain does not make them too small.
    Harmonics of a nonlinear response are orthogonal to the fundamental over whole periods
    and do not bias the phasors.

    Examples
    --------
    >>> t = np.arange(4001) * 1e-3
    >>> u = 2.0 * np.sin(10.0 * t)
    >>> x = 0.5 * np.sin(10.0 * t - 0.3)
    >>> fit = fit_sine_response(Record(t=t, x=x, u=u))
    >>> round(fit.amplitude_ratio, 9), round(fit.phase_lag, 9)
    (4.0, 0.3)
    """
    if not isinstance(record, Record):
        raise ParameterError(f"record must be a driveid.io.Record; got {type(record).__name__}")
    if record.u is None:
        raise RecordError(
            "a forced-response record needs the input u (the sinusoidal force or torque); "
            "record the excitation as column 'u'; got a record without u"
        )
    if record.corrupted:
        raise RecordError(
            f"the record has corrupted samples at {list(record.corrupted)[:3]}; crop them "
            "away (Record.crop) before the analysis"
        )
    if not (isinstance(settle_tol, (int, float)) and 0 < settle_tol < 1):
        raise ParameterError(f"settle_tol must be in (0, 1); got {settle_tol!r}")
    if not (isinstance(min_periods, int) and min_periods >= 2):
        raise ParameterError(f"min_periods must be an int >= 2; got {min_periods!r}")
    t = np.asarray(record.t, dtype=float)
    tau = t - t[0]
    x = np.asarray(record.x, dtype=float)
    u = np.asarray(record.u, dtype=float)
    dt = record.dt
    if float(np.ptp(u)) == 0.0:
        raise IdentificationError(
            "the input u is constant, not a sinusoid; record the excitation u(t) = F sin ωt "
            f"as column 'u'; got u = {u[0]!r} throughout"
        )
    if omega is None:
        omega = _input_frequency(tau, u, dt)
    elif not (isinstance(omega, (int, float)) and math.isfinite(omega) and omega > 0):
        raise ParameterError(f"omega must be a positive frequency [rad/s] or None; got {omega!r}")
    omega = float(omega)
    if omega * dt > math.pi / 2:
        raise IdentificationError(
            f"the excitation at ω = {omega:.6g} rad/s has fewer than 4 samples per period at "
            f"fs = {record.fs:.6g} Hz; sample faster or excite more slowly"
        )
    period = 2 * math.pi / omega
    n_win = int(math.floor(tau[-1] / period + 1e-9))
    if n_win < min_periods + 1:
        raise RecordError(
            f"the record holds {n_win} period(s) of ω = {omega:.6g} rad/s; it needs the "
            f"transient plus at least {min_periods} steady periods: record for longer than "
            f"{(min_periods + 1) * period:.4g} s plus the settling time; got {tau[-1]:.4g} s"
        )
    window = np.floor(tau / period + 1e-9).astype(int)
    whole = window < n_win
    cu, _, res_u = _lsq(_sine_basis(tau[whole], omega), u[whole])
    if _distortion(cu, res_u) > MAX_INPUT_DISTORTION:
        raise IdentificationError(
            f"the input u is not a sinusoid at ω = {omega:.6g} rad/s: the sine fit leaves "
            f"{100 * _distortion(cu, res_u):.3g} % rms residual (limit "
            f"{100 * MAX_INPUT_DISTORTION:g} %); excite with one sine per run, or pass the "
            "right omega"
        )
    fits = np.empty(n_win, dtype=complex)
    ses = np.empty(n_win)
    for k in range(n_win):
        sel = window == k
        coef, cov, _ = _lsq(_sine_basis(tau[sel], omega), x[sel])
        fits[k] = coef[0] + 1j * coef[1]
        ses[k] = math.sqrt(cov[0, 0] + cov[1, 1])
    tail = max(2, n_win // 4)
    sel = (window >= n_win - tail) & (window < n_win)
    coef, *_ = np.linalg.lstsq(_sine_basis(tau[sel], omega), x[sel], rcond=None)
    x_ref = coef[0] + 1j * coef[1]
    threshold = max(settle_tol * abs(x_ref), 5.0 * float(np.median(ses[-tail:])))
    outside = np.flatnonzero(np.abs(fits - x_ref) > threshold)
    first = int(outside[-1]) + 1 if outside.size else 0
    if n_win - first < min_periods:
        raise RecordError(
            f"after the transient only {n_win - first} whole period(s) of ω = {omega:.6g} "
            f"rad/s remain (the response settles to within settle_tol = {settle_tol:g} at "
            f"t = {t[0] + first * period:.4g} s); at least {min_periods} are needed: record "
            f"for longer, beyond {t[0] + (first + min_periods) * period:.4g} s (if it never "
            "settles, the loop may be unstable: check the feedback gains)"
        )
    sel = (window >= first) & (window < n_win)
    basis_x = _sine_basis(tau[sel], omega, drift=True)
    cx, _, res_x = _lsq(basis_x, x[sel])
    cu, _, res_u = _lsq(basis_x[:, :3], u[sel])
    cov_x, model_x, white_x = _noise_covariance(basis_x, res_x, tau[sel], omega)
    cov_u, model_u, _ = _noise_covariance(basis_x[:, :3], res_u, tau[sel], omega)
    input_distortion = _distortion(cu, res_u)
    X = complex(cx[0], cx[1])
    U = complex(cu[0], cu[1])
    if X == 0:
        raise IdentificationError("the response x does not move at the excitation frequency")
    response_distortion = _distortion(cx, res_x)
    H = U / X

    def as_real(w: complex) -> np.ndarray:
        return np.array([[w.real, -w.imag], [w.imag, w.real]])

    gu, gx = as_real(1.0 / X), as_real(-U / X**2)
    cov_h = gu @ cov_u[:2, :2] @ gu.T + gx @ cov_x[:2, :2] @ gx.T
    return SineResponse(
        omega=omega,
        force=U,
        displacement=X,
        stiffness=H,
        stiffness_cov=cov_h,
        t_start=float(t[0] + first * period),
        t_stop=float(t[0] + n_win * period),
        t_ref=float(t[0]),
        n_periods=n_win - first,
        input_distortion=input_distortion,
        response_distortion=response_distortion,
        noise={"x": model_x.to_dict(), "u": model_u.to_dict(), "whiteness": white_x},
    )


def record_list(records: Record | object) -> list[Record]:
    """Return one Record or a sequence of them as a list, refusing anything else.

    Parameters
    ----------
    records : Record or sequence of Record
        The runs.

    Returns
    -------
    list of Record

    Raises
    ------
    ParameterError
        An element that is not a :class:`~driveid.io.record.Record`.
    """
    if isinstance(records, Record):
        return [records]
    records = list(records)
    for i, rec in enumerate(records):
        if not isinstance(rec, Record):
            raise ParameterError(f"records[{i}] must be a Record; got {type(rec).__name__}")
    return records
