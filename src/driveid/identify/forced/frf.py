r"""Forced-response identification from broadband and stepped-sine records.

Two estimators over records made by :mod:`driveid.experiment.excitation`:

* :func:`frequency_response` + :func:`estimate_frf` — the H1 estimate of the receptance
  ``G = X/U`` (Welch averaging, or whole periods of a periodic multisine), its coherence,
  and J, C, K by weighted least squares on the dynamic stiffness ``H = 1/G``;
* :func:`estimate_describing_friction` — stepped-sine runs at several frequencies and
  amplitudes (the thesis's grid, ch. 4): J, K, viscous ``c_mean`` and Coulomb ``fk_mean``
  from the describing function, and the asymmetric parts ``fk_delta``, ``c_delta`` from the
  mean (DC) force balance where the loop has a stiffness (a wrapper of
  :func:`driveid.identify.forced.forced_friction.estimate_forced_friction`; the grid test of
  friction and backlash amplitude dependence is
  :func:`driveid.identify.forced.forced_friction.sine_grid_test`).

Model
-----
``J x'' + C x' + K x = u - τ_fb`` with optional delayed PD feedback
``τ_fb = P x(t-Δ) + D x'(t-Δ)`` (thesis §2.2.6-2.2.7.2). For a steady sinusoid the dynamic
stiffness is (forced.py module notes, the exact form of (2.179) and (2.193))

.. math::

    H(ω) = U/X = K - Jω^2 + jωC + z(ω), \qquad z = (P + jωD) e^{-jωΔ}.

Per frequency ``Re H - Re z = K - Jω²`` and ``Im H - Im z = ωC``, linear in (J, C, K).

H1 and its error
----------------
``G_1 = S_ux / S_uu`` with Welch's cross and auto spectra; coherence
``γ² = |S_ux|² / (S_uu S_xx)``. Output noise does not bias H1; its random relative error
is ``ε = sqrt(1-γ²) / (|γ| sqrt(2 n_d))`` for ``n_d`` averages (Bendat & Piersol [2]_,
Table 9.6), used as the standard deviation of Re and Im of ``H = 1/G`` relative to ``|H|``.

Describing function of friction
-------------------------------
On a sinusoidal motion of amplitude ``A`` that does not stick, Coulomb friction
``fk_mean sgn x'`` has the fundamental ``(4 fk_mean / (π A)) x'/ω`` (first-order harmonic
balance), so ``Im H - Im z = ωc + 4 fk_mean / (π A)``: linear in (c, fk_mean) over runs of
different ``ωA``. The asymmetric terms ``c_delta |x'| + fk_delta`` have no fundamental but a
mean ``c_delta (2/π) ω A + fk_delta``, balanced by the stiffness:
``(K + P) x̄ = ū - fk_delta - (2/π) c_delta ω A`` (DC of (2.155), x measured from the
spring zero). This needs ``K + P ≠ 0``; otherwise the asymmetry is not identifiable from
sinusoids and is reported as not identified (NaN).

References
----------
.. [1] J. A. de Marchi, "Modeling of dynamic friction, impact backlash and elastic compliance
       nonlinearities in machine tools", PhD thesis, Rensselaer Polytechnic Institute, 1998,
       §2.2.6-§2.2.7.2, Eq. (2.155), ch. 4.
.. [2] J. S. Bendat, A. G. Piersol, *Random Data: Analysis and Measurement Procedures*,
       4th ed., Wiley, 2010, §9.2 (random errors of frequency response estimates).
       doi:10.1002/9781118032428
.. [3] A. Gelb, W. E. Vander Velde, *Multiple-Input Describing Functions and Nonlinear
       System Design*, McGraw-Hill, 1968 (relay describing function ``4F/(πA)``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy import signal as _sig

from driveid.errors import IdentificationError, ParameterError, RecordError
from driveid.identify.core.estimate import Estimate, Parameter
from driveid.io.record import Record

__all__ = ["FrequencyResponse", "frequency_response", "estimate_frf",
           "estimate_describing_friction"]

#: Coherence below which a frequency line is not used by :func:`estimate_frf` [-].
MIN_COHERENCE = 0.9
#: Relative error floor of one FRF line (numerical noise of noise-free data) [-].
_FLOOR = 1e-9


@dataclass(frozen=True, kw_only=True)
class FrequencyResponse:
    """H1 receptance estimate ``G = X/U`` with its coherence.

    Attributes
    ----------
    f : ndarray, shape (m,)
        Frequencies [Hz].
    G : ndarray of complex, shape (m,)
        Receptance [rad/(N·m) or m/N].
    coherence : ndarray, shape (m,)
        Ordinary coherence γ² [-].
    input_power : ndarray, shape (m,)
        Input auto spectrum S_uu [(N·m)²/Hz or N²/Hz].
    n_averages : int
        Segments averaged [-].
    """

    f: np.ndarray
    G: np.ndarray
    coherence: np.ndarray
    input_power: np.ndarray
    n_averages: int

    @property
    def relative_error(self) -> np.ndarray:
        """Random relative error of |G| per line, ``sqrt(1-γ²)/(|γ| sqrt(2 n_d))`` [-]."""
        g2 = np.clip(self.coherence, 1e-12, 1.0)
        return np.sqrt(1.0 - g2) / np.sqrt(g2 * 2.0 * self.n_averages)


def frequency_response(record: Record, *, nperseg: int | None = None,
                       period: float | None = None, skip: float = 0.0) -> FrequencyResponse:
    """H1 estimate of the receptance ``X/U`` and its coherence from one record.

    Parameters
    ----------
    record : Record
        ``t`` [s], ``x`` [rad or m] and the excitation ``u`` [N·m or N].
    nperseg : int, optional
        Welch segment length [samples] with a Hann window and 50 % overlap; default
        ``n // 8``. Ignored with ``period``.
    period : float, optional
        Period of a periodic excitation [s] (a multisine): whole periods after ``skip`` are
        averaged with a rectangular window, without leakage.
    skip : float
        Time to discard at the start (transient) [s], >= 0.

    Returns
    -------
    FrequencyResponse
        Lines with non-zero input power only.

    Raises
    ------
    RecordError
        If the record has no ``u`` or is too short for two segments.
    ParameterError
        On a bad argument.

    Examples
    --------
    >>> t = np.arange(20000) / 1000
    >>> u = np.sin(2 * np.pi * 5 * t)
    >>> frf = frequency_response(Record(t=t, x=0.5 * u, u=u), period=1.0)
    >>> k = np.argmin(abs(frf.f - 5)); round(float(frf.G[k].real), 9)
    0.5
    """
    if not isinstance(record, Record):
        raise ParameterError(f"record must be a Record; got {type(record).__name__}")
    if record.u is None:
        raise RecordError("the FRF needs the excitation u; record it as column 'u'; got none")
    if not (math.isfinite(skip) and skip >= 0):
        raise ParameterError(f"skip must be >= 0 [s]; got {skip!r}")
    fs = record.fs
    keep = record.t - record.t[0] >= skip - 0.5 / fs
    u, x = np.asarray(record.u)[keep], np.asarray(record.x)[keep]
    if period is not None:
        if not (math.isfinite(period) and period > 0):
            raise ParameterError(f"period must be > 0 [s]; got {period!r}")
        seg = int(round(period * fs))
        n_avg = u.size // seg
        if n_avg < 2:
            raise RecordError(
                f"{u.size / fs:.4g} s after skip hold {n_avg} period(s) of {period} s; need "
                "at least 2 whole periods: record longer or skip less")
        ur = (u[: n_avg * seg] - u.mean()).reshape(n_avg, seg)
        xr = (x[: n_avg * seg] - x.mean()).reshape(n_avg, seg)
        U, X = np.fft.rfft(ur, axis=1), np.fft.rfft(xr, axis=1)
        suu = np.mean(np.abs(U) ** 2, axis=0)
        sxx = np.mean(np.abs(X) ** 2, axis=0)
        sux = np.mean(np.conj(U) * X, axis=0)
        f = np.fft.rfftfreq(seg, 1.0 / fs)
        scale = 2.0 / (fs * seg)
        suu, sxx, sux = suu * scale, sxx * scale, sux * scale
    else:
        nperseg = max(u.size // 8, 8) if nperseg is None else int(nperseg)
        if nperseg < 8 or 2 * nperseg > u.size + nperseg // 2:
            raise RecordError(
                f"nperseg={nperseg} needs at least 1.5 segments of data; got {u.size} samples")
        f, suu = _sig.welch(u, fs=fs, nperseg=nperseg)
        _, sxx = _sig.welch(x, fs=fs, nperseg=nperseg)
        _, sux = _sig.csd(u, x, fs=fs, nperseg=nperseg)
        n_avg = max(1, (u.size - nperseg) // (nperseg // 2) + 1)
    excited = suu > 1e-10 * suu.max()
    excited[0] = False
    G = sux[excited] / suu[excited]
    coh = np.abs(sux[excited]) ** 2 / (suu[excited] * sxx[excited] + 1e-300)
    return FrequencyResponse(f=f[excited], G=G, coherence=np.clip(coh, 0.0, 1.0),
                             input_power=suu[excited], n_averages=int(n_avg))


def _units(record: Record) -> dict[str, str]:
    if record.units.get("x", "rad") == "m":
        return {"J": "kg", "K": "N/m", "c": "N·s/m", "f": "N"}
    return {"J": "kg·m²", "K": "N·m/rad", "c": "N·m·s/rad", "f": "N·m"}


def _feedback(record: Record, P, D, delay):
    out = []
    for name, value in (("P", P), ("D", D), ("delay", delay)):
        value = record.meta.get(name, 0.0) if value is None else value
        value = 0.0 if value is None else value
        if not (isinstance(value, (int, float)) and math.isfinite(value)):
            raise ParameterError(f"{name} must be a finite number; got {value!r}")
        out.append(float(value))
    return out


def _weighted_fit(A: np.ndarray, y: np.ndarray, sd: np.ndarray | None):
    """Weighted LS with Birge-scaled covariance; returns theta, cov, chi2, dof.

    ``sd=None``: unknown, equal errors; the covariance uses the residual variance.
    """
    if sd is None:
        theta, *_ = np.linalg.lstsq(A, y, rcond=None)
        resid = y - A @ theta
        dof = max(A.shape[0] - A.shape[1], 1)
        s2 = float(resid @ resid) / dof
        return theta, np.linalg.inv(A.T @ A) * s2, s2 * dof, dof
    Aw, yw = A / sd[:, None], y / sd
    theta, *_ = np.linalg.lstsq(Aw, yw, rcond=None)
    resid = yw - Aw @ theta
    dof = max(Aw.shape[0] - Aw.shape[1], 1)
    chi2 = float(resid @ resid)
    cov = np.linalg.inv(Aw.T @ Aw) * max(1.0, chi2 / dof)
    return theta, cov, chi2, dof


def estimate_frf(record: Record, *, f_band: tuple[float, float] | None = None,
                 period: float | None = None, skip: float = 0.0,
                 nperseg: int | None = None, P: float | None = None, D: float | None = None,
                 delay: float | None = None, K_known: float | None = None,
                 min_coherence: float = MIN_COHERENCE) -> Estimate:
    r"""J, C, K by weighted least squares on the H1 dynamic stiffness of one record.

    Parameters
    ----------
    record : Record
        ``t`` [s], ``x`` [rad or m], excitation ``u`` [N·m or N] (broadband: multisine,
        chirp, PRBS, random).
    f_band : tuple of float, optional
        Frequencies used ``(lo, hi)`` [Hz]; default all excited lines.
    period : float, optional
        Period of a periodic excitation [s] (see :func:`frequency_response`).
    skip : float
        Transient discarded at the start [s].
    nperseg : int, optional
        Welch segment length [samples] (non-periodic excitation).
    P : float, optional
        Proportional feedback gain [N·m/rad or N/m]; default ``meta["P"]`` or 0.
    D : float, optional
        Derivative feedback gain [N·m·s/rad or N·s/m]; default ``meta["D"]`` or 0.
    delay : float, optional
        Feedback delay [s]; default ``meta["delay"]`` or 0.
    K_known : float, optional
        Known stiffness [N·m/rad or N/m]; then only J and C are fitted.
    min_coherence : float
        Lines with lower coherence γ² are not used [-], in [0, 1).

    Returns
    -------
    Estimate
        Method ``"frf-h1"``: ``J``, ``c_mean``, ``K`` with standard errors and covariance;
        ``data_used``: ``f`` [Hz], ``G`` magnitude and phase, ``coherence``.

    Raises
    ------
    IdentificationError
        Fewer than 3 usable lines (coherent, in band).

    Notes
    -----
    Each line gives two rows ``[-ω², 0, 1]·θ = Re H - Re z`` and ``[0, ω, 0]·θ = Im H - Im z``
    (module notes), weighted by ``1/(ε|H|)`` with ε the H1 random error. The covariance
    is ``(AᵀWA)⁻¹·max(1, χ²/dof)``. Nonlinear friction leaves harmonics and lowers the
    coherence; its equivalent damping enters C (use
    :func:`estimate_describing_friction` on stepped sines to separate it).

    Examples
    --------
    >>> t = np.arange(40000) / 1000
    >>> w = 2 * np.pi * np.arange(1, 21)
    >>> u = sum(np.cos(wk * t + k * k) for k, wk in enumerate(w))
    >>> H = 8.0 - 0.02 * w**2 + 1j * w * 0.06
    >>> x = sum(np.real(np.exp(1j * (wk * t + k * k)) / H[k]) for k, wk in enumerate(w))
    >>> est = estimate_frf(Record(t=t, x=x, u=u), period=1.0)
    >>> [round(est.value(k), 6) for k in ("J", "c_mean", "K")]
    [0.02, 0.06, 8.0]
    """
    if not (0 <= min_coherence < 1):
        raise ParameterError(f"min_coherence must be in [0, 1); got {min_coherence!r}")
    frf = frequency_response(record, nperseg=nperseg, period=period, skip=skip)
    P, D, delay = _feedback(record, P, D, delay)
    use = frf.coherence >= min_coherence
    if f_band is not None:
        lo, hi = (float(v) for v in f_band)
        use &= (frf.f >= lo) & (frf.f <= hi)
    need = 2 if K_known is not None else 3
    if use.sum() < need:
        raise IdentificationError(
            f"{use.sum()} frequency line(s) with coherence >= {min_coherence} in the band; "
            f"need {need}: excite more strongly, average more periods or widen f_band")
    w = 2 * np.pi * frf.f[use]
    H = 1.0 / frf.G[use]
    z = (P + 1j * w * D) * np.exp(-1j * w * delay)
    sd = np.abs(H) * np.maximum(frf.relative_error[use], _FLOOR)
    rows_re = np.column_stack([-(w**2), np.zeros_like(w), np.ones_like(w)])
    rows_im = np.column_stack([np.zeros_like(w), w, np.zeros_like(w)])
    y = np.concatenate([H.real - z.real, H.imag - z.imag])
    A = np.vstack([rows_re, rows_im])
    if K_known is not None:
        y[: w.size] -= K_known
        A = A[:, :2]
    theta, cov, chi2, dof = _weighted_fit(A, y, np.concatenate([sd, sd]))
    se = np.sqrt(np.diag(cov))
    u_ = _units(record)
    params = {"J": Parameter(float(theta[0]), float(se[0]), u_["J"]),
              "c_mean": Parameter(float(theta[1]), float(se[1]), u_["c"])}
    names = ["J", "c_mean"]
    if K_known is None:
        params["K"] = Parameter(float(theta[2]), float(se[2]), u_["K"])
        names.append("K")
    else:
        params["K"] = Parameter(float(K_known), math.nan, u_["K"], fixed=True)
    warnings = []
    if np.median(frf.coherence[use]) < 0.98:
        warnings.append(
            f"median coherence {np.median(frf.coherence[use]):.3f} < 0.98: noise or "
            "nonlinear friction/backlash; c_mean includes the equivalent friction damping")
    return Estimate(
        method="frf-h1", params=params,
        covariance={"names": names, "matrix": cov},
        data_used={"f": frf.f[use], "magnitude": np.abs(frf.G[use]),
                   "phase": np.angle(frf.G[use]), "coherence": frf.coherence[use],
                   "P": P, "D": D, "delay": delay},
        diagnostics={"n_lines": int(use.sum()), "n_averages": frf.n_averages,
                     "chi2": chi2, "dof": dof, "birge_ratio": math.sqrt(max(1.0, chi2 / dof)),
                     "median_coherence": float(np.median(frf.coherence[use]))},
        warnings=tuple(warnings),
    )


def estimate_describing_friction(records: Sequence[Record], *, P: float | None = None,
                                 D: float | None = None, delay: float | None = None,
                                 K_known: float | None = None, x_ref: float | None = None,
                                 settle_tol: float = 1e-3) -> Estimate:
    r"""J, K, c_mean, fk_mean and the asymmetry c_delta, fk_delta from stepped-sine runs.

    Parameters
    ----------
    records : sequence of Record
        Sinusoidal runs (``u`` one sine each) at >= 2 frequencies and >= 2 amplitudes in
        all: a grid of frequencies × amplitudes (thesis ch. 4).
    P : float, optional
        Proportional feedback gain [N·m/rad or N/m]; default each ``meta["P"]`` or 0.
    D : float, optional
        Derivative feedback gain [N·m·s/rad or N·s/m]; default each ``meta["D"]`` or 0.
    delay : float, optional
        Feedback delay [s]; default ``meta["delay"]`` or 0.
    K_known : float, optional
        Known stiffness [N·m/rad or N/m] (0 for a free drive).
    x_ref : float, optional
        Spring zero [rad or m]; needed for ``fk_delta`` when K is fitted or non-zero.
    settle_tol : float
        Settling tolerance of :func:`~driveid.identify.forced.sine_fit.fit_sine_response` [-].

    Returns
    -------
    Estimate
        Method ``"describing-function"``: ``J``, ``K``, ``c_mean``, ``fk_mean``,
        ``c_delta``, ``fk_delta`` with standard errors and covariance (NaN where the data
        do not determine them, see
        :func:`driveid.identify.forced.forced_friction.estimate_forced_friction`); ``data_used``
        per run: ``omega``, ``displacement_amplitude``, ``equivalent_damping``
        ``c + 4 fk/(π ω A)``, ….

    Raises
    ------
    IdentificationError
        If the runs do not separate viscous from Coulomb friction (one ``ωA`` only).

    Notes
    -----
    A thin wrapper of :func:`driveid.identify.forced.forced_friction.estimate_forced_friction`:
    rows ``K - Jω² = Re H - Re z`` and ``ωc + (4/π) fk_mean / A = Im H - Im z``, then
    ``ū - P x̄ - K (x̄ - x_ref) = fk_delta + (2/π) c_delta ω A`` over the runs, with the
    error of K carried into the asymmetry by the delta method. The describing function is
    first-order harmonic balance; runs that stick are outside the model.

    Examples
    --------
    >>> t = np.arange(8000) / 1000
    >>> runs = []
    >>> for w, A in ((6.0, 0.2), (12.0, 0.1), (9.0, 0.3)):
    ...     H = 8.0 - 0.02 * w**2 + 1j * (w * 0.06 + 4 * 0.01 / (np.pi * A))
    ...     u = A * abs(H) * np.sin(w * t + np.angle(H))
    ...     runs.append(Record(t=t, x=A * np.sin(w * t), u=u))
    >>> est = estimate_describing_friction(runs)
    >>> round(est.value("fk_mean"), 6), round(est.value("c_mean"), 6)
    (0.01, 0.06)
    """
    from driveid.identify.forced.forced_friction import estimate_forced_friction

    records = list(records)
    if len(records) < 3 or not all(isinstance(r, Record) for r in records):
        raise IdentificationError(
            f"describing-function friction needs >= 3 sinusoidal runs; got {len(records)}")
    return estimate_forced_friction(records, P=P, D=D, delay=delay, K_known=K_known,
                                    x_ref=x_ref, settle_tol=settle_tol,
                                    method="describing-function")
