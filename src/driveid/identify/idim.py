"""Inverse-dynamic-model least squares (IDIM-LS) with Coulomb + viscous friction.

The model is the rigid-body equation of motion solved for the applied force,

    u = M·a + Fv·v + Fc·sgn(v) + offset                                (symmetric)
    u = M·a + Fv+·v⁺ + Fc+·[v>0] + Fv−·v⁻ − Fc−·[v<0]                    (asymmetric)

(EMPS benchmark, Janot, Gautier & Brunot 2019, eq. 1 and §4.2; the thesis's equation of
motion (2.155) with ``K = 0``), which is linear in the parameters. Velocity and
acceleration come from a zero-phase filtered position and central differences; the
observation matrix and the force are decimated (low-pass + downsample) before ordinary
least squares, exactly the benchmark's recipe. In the asymmetric model
``v⁺ = max(v, 0)``, ``v⁻ = min(v, 0)``; all friction parameters are positive for a
dissipative drive.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy import signal as sps

from driveid.errors import IdentificationError, ParameterError, RecordError
from driveid.identify.estimate import Estimate, Parameter
from driveid.io.record import Record
from driveid.signal.differentiate import differentiate

__all__ = [
    "estimate_idim",
    "validate_idim",
    "simulate_idim_model",
    "IdimValidation",
    "IdimSimulation",
    "idim_regressor",
    "MODELS",
]

#: Friction models understood by :func:`estimate_idim`.
MODELS = ("symmetric", "asymmetric")


@dataclass(frozen=True)
class IdimValidation:
    """Cross-test of an IDIM estimate on another record (same θ, new observation matrix).

    Attributes
    ----------
    relative_error : float
        ``100·||u − Wθ|| / ||u||`` [%] on the decimated data.
    error_norm : float
        ``||u − Wθ||`` [N or N·m].
    cond : float
        Condition number of the new observation matrix [-].
    t : ndarray, shape (m,)
        Decimated sample times [s].
    measured : ndarray, shape (m,)
        Decimated measured force [N or N·m].
    predicted : ndarray, shape (m,)
        ``Wθ`` [N or N·m].
    """

    relative_error: float
    error_norm: float
    cond: float
    t: np.ndarray
    measured: np.ndarray
    predicted: np.ndarray

    def to_dict(self) -> dict[str, Any]:
        """Return the scalar results as a JSON-ready dict."""
        return {
            "relative_error_pct": float(self.relative_error),
            "error_norm": float(self.error_norm),
            "cond": float(self.cond),
            "n": int(self.t.size),
        }


def _names(model: str, translational: bool) -> tuple[tuple[str, ...], tuple[str, ...]]:
    inertia = "M" if translational else "J"
    lin = "m" if translational else "rad"
    force = "N" if translational else "N·m"
    m_unit = "kg" if translational else "kg·m²"
    if model == "symmetric":
        names = (inertia, "Fv", "Fc", "offset")
        units = (m_unit, f"{force}·s/{lin}", force, force)
    else:
        names = (inertia, "Fv_plus", "Fc_plus", "Fv_minus", "Fc_minus")
        units = (m_unit, f"{force}·s/{lin}", force, f"{force}·s/{lin}", force)
    return names, units


def _check_settings(model: str, cutoff_hz: float, decimate: int, edge: int) -> None:
    if model not in MODELS:
        raise ParameterError(f"model must be one of {MODELS}; got {model!r}")
    if int(decimate) != decimate or decimate < 1:
        raise ParameterError(f"decimate must be an integer >= 1 [-]; got {decimate}")
    if int(edge) != edge or edge < 0:
        raise ParameterError(f"edge must be an integer >= 0 [samples]; got {edge}")
    if not (math.isfinite(cutoff_hz) and cutoff_hz > 0):
        raise ParameterError(f"cutoff_hz must be a positive frequency [Hz]; got {cutoff_hz}")


def idim_regressor(
    record: Record,
    *,
    model: str = "symmetric",
    cutoff_hz: float = 100.0,
    decimate: int = 10,
    edge: int = 50,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Build the decimated observation matrix and force of the IDIM model.

    Parameters
    ----------
    record : Record
        Position ``x`` [m or rad] and force ``u`` [N or N·m].
    model : {"symmetric", "asymmetric"}
        Friction model (see module docstring).
    cutoff_hz : float
        Zero-phase 4th-order Butterworth cut-off on the position [Hz]; EMPS uses 100.
    decimate : int
        Decimation factor of observation matrix and force [-]; 1 disables it. Uses
        :func:`scipy.signal.decimate` (order-8 Chebyshev I, zero phase) like MATLAB.
    edge : int
        Samples dropped at both ends after differentiation [-].

    Returns
    -------
    tuple of ndarray
        ``(W, y, t, v)``: W shape (m, p) [mixed units], force y shape (m,) [N or N·m],
        times t shape (m,) [s], decimated velocity v shape (m,) [m/s or rad/s].

    Raises
    ------
    RecordError
        If the record has no force column or is too short after dropping the edges.
    ParameterError
        If a setting is invalid.
    """
    _check_settings(model, cutoff_hz, decimate, edge)
    if record.u is None:
        raise RecordError(
            "IDIM needs the applied force or torque u; read the record with a force column "
            "(CLI: --force-column NAME); got a record with columns "
            f"{list(record.columns)}"
        )
    fs = record.fs
    if not cutoff_hz < fs / 2:
        raise ParameterError(
            f"cutoff_hz must be below fs/2 = {fs / 2:g} Hz; got {cutoff_hz}"
        )
    _, v, a = differentiate(record.x, fs, cutoff_hz=cutoff_hz)
    sl = slice(edge, record.n - edge)
    v, a, y, t = v[sl], a[sl], np.asarray(record.u, float)[sl], record.t[sl]
    min_len = 27 * int(decimate) if decimate > 1 else 8  # decimate's filtfilt padding
    if v.size < min_len:
        raise RecordError(
            f"record too short for IDIM after dropping {edge} edge samples and decimating "
            f"by {decimate}; need >= {min_len} samples; got {v.size}"
        )
    if model == "symmetric":
        cols = [a, v, np.sign(v), np.ones_like(v)]
    else:
        pos, neg = v > 0, v < 0
        cols = [a, np.where(pos, v, 0.0), pos.astype(float), np.where(neg, v, 0.0),
                -neg.astype(float)]
    W = np.column_stack(cols)
    if decimate > 1:
        W = sps.decimate(W, int(decimate), axis=0)
        y = sps.decimate(y, int(decimate))
        v_dec = v[:: int(decimate)]
        t = t[:: int(decimate)]
    else:
        v_dec = v
    return W, y, t, v_dec


def estimate_idim(
    record: Record,
    *,
    model: str = "symmetric",
    cutoff_hz: float = 100.0,
    decimate: int = 10,
    edge: int = 50,
) -> Estimate:
    """Estimate inertia, viscous and Coulomb friction (and offset) by IDIM-LS.

    Parameters
    ----------
    record : Record
        Position ``x`` [m or rad] and applied force ``u`` [N or N·m] of a closed-loop run
        that moves in both directions (EMPS: ``DATA_EMPS.mat``, force = gtau·vir).
    model : {"symmetric", "asymmetric"}
        ``"symmetric"``: parameters M (or J), Fv, Fc, offset. ``"asymmetric"``: M,
        Fv_plus, Fc_plus, Fv_minus, Fc_minus and no offset (EMPS §4.2).
    cutoff_hz : float
        Zero-phase 4th-order Butterworth cut-off on the position [Hz] (EMPS: 5 × the
        20 Hz position-loop bandwidth = 100 Hz).
    decimate : int
        Decimation factor of observation matrix and force [-] (EMPS: 10).
    edge : int
        Samples dropped at each end after differentiation [-] (EMPS: 50).

    Returns
    -------
    Estimate
        ``M`` [kg] (``J`` [kg·m²] when x is not in m), ``Fv`` [N·s/m], ``Fc`` [N],
        ``offset`` [N] (or the asymmetric set), each with the standard error
        ``sqrt(σ²·diag((WᵀW)⁻¹))``, ``σ² = ||e||²/(m − p)``. Diagnostics: ``cond``,
        ``relative_error_pct`` (``100·||e||/||y||``), ``error_norm``, ``error_std``,
        ``n``, and the settings. ``data_used`` holds decimated ``t``, ``force``,
        ``predicted`` and ``velocity``.

    Raises
    ------
    RecordError
        If the record lacks force or is too short.
    IdentificationError
        If the drive never moves, moves in one direction only (asymmetric model), or
        the observation matrix is rank-deficient.
    ParameterError
        If a setting is invalid.

    Notes
    -----
    Ordinary least squares is unbiased only if the force noise is uncorrelated with the
    regressors; in closed loop it is not, but the benchmark shows the bias is small when
    the filter cut-off is well above the loop bandwidth (Janot et al. 2019, §3.3).

    Examples
    --------
    >>> import numpy as np
    >>> from driveid.io.record import Record
    >>> t = np.arange(4000) / 1000.0
    >>> x = 0.1 * np.sin(2 * np.pi * 0.5 * t)
    >>> v = 0.1 * np.pi * np.cos(np.pi * t); a = -0.1 * np.pi**2 * np.sin(np.pi * t)
    >>> noise = 0.3 * np.random.default_rng(0).standard_normal(t.size)
    >>> u = 2.0 * a + 3.0 * v + 1.5 * np.sign(v) + 0.2 + noise
    >>> rec = Record(t=t, x=x, u=u, meta={"units": {"x": "m", "u": "N"}})
    >>> est = estimate_idim(rec, decimate=1, cutoff_hz=50.0)
    >>> abs(est.value("M") - 2.0) < 0.05, abs(est.value("Fv") - 3.0) < 0.2
    (True, True)
    """
    W, y, t, v = idim_regressor(record, model=model, cutoff_hz=cutoff_hz,
                                decimate=decimate, edge=edge)
    _check_motion(v, model)
    translational = record.units.get("x", "rad") == "m"
    names, units = _names(model, translational)
    theta, stderr, cond, e = _ols(W, y)
    params = {n: Parameter(float(th), float(se), u)
              for n, th, se, u in zip(names, theta, stderr, units, strict=True)}
    err_norm = float(np.linalg.norm(e))
    diagnostics = {
        "model": model,
        "cond": cond,
        "relative_error_pct": 100.0 * err_norm / float(np.linalg.norm(y)),
        "error_norm": err_norm,
        "error_std": float(np.sqrt(err_norm**2 / (y.size - W.shape[1]))),
        "n": int(y.size),
        "cutoff_hz": float(cutoff_hz),
        "decimate": int(decimate),
        "edge": int(edge),
        "source": str(record.meta.get("source", "")),
        "force_unit": record.units.get("u", "N" if translational else "N·m"),
    }
    warnings = []
    if cond > 1e3:
        warnings.append(f"observation matrix is ill-conditioned (cond = {cond:.3g}); the "
                        "excitation does not separate the parameters well")
    rel_se = [abs(se / th) for th, se in zip(theta, stderr, strict=True) if th != 0]
    if any(r > 0.3 for r in rel_se):
        warnings.append("some relative standard errors exceed 30 %; excite the drive "
                        "over a wider range of velocity and acceleration")
    return Estimate(
        method=f"idim-ls-{model}",
        params=params,
        data_used={"t": t, "force": y, "predicted": W @ theta, "velocity": v},
        diagnostics=diagnostics,
        warnings=tuple(warnings),
    )


def validate_idim(estimate: Estimate, record: Record) -> IdimValidation:
    """Cross-test: apply the estimated θ to another record's observation matrix.

    Parameters
    ----------
    estimate : Estimate
        Result of :func:`estimate_idim` (its settings are reused).
    record : Record
        Validation record with position [m or rad] and force [N or N·m] (EMPS:
        ``DATA_EMPS_PULSES.mat``; published relative error 5.9824 %).

    Returns
    -------
    IdimValidation
        Relative error [%], error norm, condition number and the decimated signals.

    Raises
    ------
    IdentificationError
        If ``estimate`` did not come from :func:`estimate_idim`.
    """
    diag = estimate.diagnostics
    if not estimate.method.startswith("idim-ls-") or "model" not in diag:
        raise IdentificationError(
            "validate_idim needs an estimate made by estimate_idim; got method "
            f"{estimate.method!r}"
        )
    model = str(diag["model"])
    W, y, t, _ = idim_regressor(record, model=model, cutoff_hz=float(diag["cutoff_hz"]),
                                decimate=int(diag["decimate"]), edge=int(diag["edge"]))
    theta = np.array([p.value for p in estimate.params.values()])
    pred = W @ theta
    err = float(np.linalg.norm(y - pred))
    return IdimValidation(
        relative_error=100.0 * err / float(np.linalg.norm(y)),
        error_norm=err,
        cond=float(np.linalg.cond(W)),
        t=t,
        measured=y,
        predicted=pred,
    )


@dataclass(frozen=True)
class IdimSimulation:
    """Direct closed-loop simulation of an IDIM model (EMPS §3.5 validation).

    Attributes
    ----------
    t : ndarray, shape (n,)
        Sample times [s].
    x : ndarray, shape (n,)
        Simulated position [m or rad].
    u : ndarray, shape (n,)
        Simulated actuator force [N or N·m].
    position_error_pct, force_error_pct : float
        ``100·||measured − simulated|| / ||measured||`` [%] for position and force.
    """

    t: np.ndarray
    x: np.ndarray
    u: np.ndarray
    position_error_pct: float
    force_error_pct: float


def simulate_idim_model(
    estimate: Estimate,
    record: Record,
    *,
    q_ref: np.ndarray,
    kp: float,
    kv: float,
    gtau: float,
    saturation: float = 10.0,
    substeps: int = 10,
    input_offset: np.ndarray | None = None,
) -> IdimSimulation:
    """Simulate the identified axis under the EMPS position/velocity control loop.

    Parameters
    ----------
    estimate : Estimate
        Result of :func:`estimate_idim` (symmetric or asymmetric).
    record : Record
        The measured run [m or rad, N or N·m], for its timeline, initial position and the
        error measures.
    q_ref : array_like, shape (n,)
        Reference position [m or rad] (EMPS: ``qg``).
    kp : float
        Position-loop gain [1/s] (EMPS: 160.18).
    kv : float
        Velocity-loop gain [V/(m/s)] (EMPS: 243.45).
    gtau : float
        Drive gain [N/V] (EMPS: 35.1507).
    saturation : float
        Controller output limit [V] (EMPS: 10).
    substeps : int
        Plant integration sub-steps per control period [-].
    input_offset : array_like, shape (n,), optional
        Signal added to the controller output before saturation [V] (EMPS PULSES file:
        ``pulses_N``, 0/5 V steps — the recorded ``vir`` jumps by exactly 5 V at each
        edge, so the pulses enter at the drive input, not as a carriage force).

    Returns
    -------
    IdimSimulation
        Simulated position and force with their relative errors.

    Raises
    ------
    ParameterError
        If gains are not positive or ``q_ref`` has the wrong length.

    Notes
    -----
    EMPS pdf eq. 6: ``ν = kp·kv·(qr − q) − kv·q̇``, the velocity taken from the 2-tap
    filtered position ``qf(k) = (q(k) + q(k−1))/2`` by a backward difference, held over a
    sample (zero-order hold), force ``gtau·ν``. The plant ``M q̈ = τ − friction(q̇)`` is
    integrated by semi-implicit Euler with ``substeps`` per sample.
    """
    q_ref = np.asarray(q_ref, dtype=float).ravel()
    if q_ref.size != record.n:
        raise ParameterError(f"q_ref must have one value per sample ({record.n}); got "
                             f"{q_ref.size}")
    for name, val in (("kp", kp), ("kv", kv), ("gtau", gtau), ("saturation", saturation)):
        if not (math.isfinite(val) and val > 0):
            raise ParameterError(f"{name} must be > 0; got {val}")
    model = str(estimate.diagnostics.get("model", ""))
    theta = [p.value for p in estimate.params.values()]
    if model == "symmetric":
        mass, fv, fc, off = theta

        def friction(v: float) -> float:
            return fv * v + fc * (v > 0) - fc * (v < 0) + off
    elif model == "asymmetric":
        mass, fvp, fcp, fvm, fcm = theta

        def friction(v: float) -> float:
            return fvp * v + fcp if v > 0 else (fvm * v - fcm if v < 0 else 0.0)
    else:
        raise IdentificationError(
            f"simulate_idim_model needs an estimate made by estimate_idim; got {estimate.method!r}"
        )
    dt = record.dt
    h = dt / int(substeps)
    n = record.n
    extra = np.zeros(n) if input_offset is None else np.asarray(input_offset, float).ravel()
    if extra.size != n:
        raise ParameterError(f"input_offset must have one value per sample ({n}); got "
                             f"{extra.size}")
    xs, us = np.empty(n), np.empty(n)
    x, v = float(record.x[0]), 0.0
    q_prev, qf_prev = x, x
    for k in range(n):
        xs[k] = x
        qf = 0.5 * (x + q_prev)
        nu = kp * kv * (q_ref[k] - x) - kv * (qf - qf_prev) / dt + extra[k]
        tau = gtau * min(max(nu, -saturation), saturation)
        us[k] = tau
        q_prev, qf_prev = x, qf
        for _ in range(int(substeps)):
            v += h * (tau - friction(v)) / mass
            x += h * v
    xm = np.asarray(record.x, float)
    pos_err = 100.0 * float(np.linalg.norm(xm - xs) / np.linalg.norm(xm))
    f_err = math.nan
    if record.u is not None:
        um = np.asarray(record.u, float)
        f_err = 100.0 * float(np.linalg.norm(um - us) / np.linalg.norm(um))
    return IdimSimulation(t=record.t, x=xs, u=us, position_error_pct=pos_err,
                          force_error_pct=f_err)


def _check_motion(v: np.ndarray, model: str) -> None:
    scale = float(np.max(np.abs(v))) if v.size else 0.0
    if scale == 0.0:
        raise IdentificationError(
            "the drive never moves, so friction and inertia cannot be identified; record "
            "a run with motion in both directions; got max |v| = 0"
        )
    moving = np.abs(v) > 0.01 * scale
    n_pos = int(np.count_nonzero(moving & (v > 0)))
    n_neg = int(np.count_nonzero(moving & (v < 0)))
    if min(n_pos, n_neg) < 5:
        hint = ("the asymmetric model needs motion in both directions" if model == "asymmetric"
                else "Coulomb friction and offset cannot be separated without both directions")
        raise IdentificationError(
            f"{hint}; add a run in the other direction; got {n_pos} positive and {n_neg} "
            "negative-velocity samples"
        )


def _ols(W: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray, float, np.ndarray]:
    m, p = W.shape
    if m <= p:
        raise IdentificationError(f"need more samples than parameters ({p}); got {m}")
    theta, _, rank, sv = np.linalg.lstsq(W, y, rcond=None)
    if rank < p:
        raise IdentificationError(
            f"observation matrix is rank-deficient (rank {rank} < {p}); excite both "
            "acceleration and velocity in both directions; got rank "
            f"{rank}"
        )
    e = y - W @ theta
    sigma2 = float(e @ e) / (m - p)
    cov = sigma2 * np.linalg.inv(W.T @ W)
    return theta, np.sqrt(np.diag(cov)), float(sv[0] / sv[-1]), e
