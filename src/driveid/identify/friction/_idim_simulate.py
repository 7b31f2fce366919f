"""Direct closed-loop simulation of an IDIM model under the EMPS control loop (EMPS §3.5).

:func:`simulate_idim_model` is re-exported by :mod:`driveid.identify.friction.idim`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from driveid.errors import IdentificationError, ParameterError
from driveid.identify.core.estimate import Estimate
from driveid.io.record import Record

__all__ = ["IdimSimulation", "simulate_idim_model"]


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
    if estimate.diagnostics.get("regressors") or estimate.diagnostics.get("load"):
        raise IdentificationError("simulate_idim_model simulates friction and inertia only; "
                                  "got an estimate with a load or extra regressors")
    par = {k: (p.value if math.isfinite(p.value) else 0.0) for k, p in estimate.params.items()}
    mass = par.get("M", par.get("J", math.nan))
    if model == "symmetric":
        fv, fc, off = par["Fv"], par["Fc"], par["offset"]

        def friction(v: float) -> float:
            return fv * v + fc * (v > 0) - fc * (v < 0) + off
    elif model == "asymmetric":
        fvp, fcp, fvm, fcm = par["Fv_plus"], par["Fc_plus"], par["Fv_minus"], par["Fc_minus"]
        off = par.get("offset", 0.0)

        def friction(v: float) -> float:
            base = fvp * v + fcp if v > 0 else (fvm * v - fcm if v < 0 else 0.0)
            return base + off
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
