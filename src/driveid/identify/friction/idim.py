"""Inverse-dynamic-model least squares (IDIM-LS) with Coulomb + viscous friction.

The model is the rigid-body equation of motion solved for the applied force,

    u = M·a + Fv·v + Fc·sgn(v) + offset                                (symmetric)
    u = M·a + Fv+·v⁺ + Fc+·[v>0] + Fv−·v⁻ − Fc−·[v<0]                    (asymmetric)

(EMPS benchmark, Janot, Gautier & Brunot 2019, eq. 1 and §4.2; the thesis's equation of
motion (2.155) with ``K = 0``), which is linear in the parameters. Velocity and
acceleration come from a zero-phase filtered position and central differences; the
observation matrix and the force are decimated before least squares, as in the benchmark's
recipe — but by block means, not its Chebyshev filter, whose stopband coloured the noise
beyond what the AR noise model follows (issue 24; parameters within 0.44 published σ of
EMPS's). In the asymmetric model
``v⁺ = max(v, 0)``, ``v⁻ = min(v, 0)``; all friction parameters are positive for a
dissipative drive.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from driveid.errors import IdentificationError, ParameterError, RecordError
from driveid.identify.core._expressions import parse_expression
from driveid.identify.core.estimate import Estimate, Parameter
from driveid.identify.friction._idim_eiv import row_noise
from driveid.identify.friction._idim_noise import _held, _lag1, _solve
from driveid.identify.friction._idim_rows import (
    MODELS,
    IdimRecordTooShort,
    idim_regressor,
)
from driveid.identify.friction._idim_simulate import IdimSimulation, simulate_idim_model
from driveid.io.record import Record

__all__ = [
    "estimate_idim",
    "validate_idim",
    "simulate_idim_model",
    "IdimValidation",
    "IdimSimulation",
    "IdimRecordTooShort",
    "idim_regressor",
    "MODELS",
]

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


def _names(model: str, translational: bool, force: str | None = None
           ) -> tuple[tuple[str, ...], tuple[str, ...]]:
    inertia = "M" if translational else "J"
    lin = "m" if translational else "rad"
    force = force or ("N" if translational else "N·m")
    m_unit = "kg" if translational else "kg·m²"
    if model == "symmetric":
        names = (inertia, "Fv", "Fc", "offset")
        units = (m_unit, f"{force}·s/{lin}", force, force)
    else:
        names = (inertia, "Fv_plus", "Fc_plus", "Fv_minus", "Fc_minus")
        units = (m_unit, f"{force}·s/{lin}", force, f"{force}·s/{lin}", force)
    return names, units


def _as_records(records: Record | Sequence[Record]) -> list[Record]:
    recs = [records] if isinstance(records, Record) else list(records)
    if not recs or not all(isinstance(r, Record) for r in recs):
        raise ParameterError("records must be a Record or a non-empty sequence of Records; "
                             f"got {type(records).__name__}")
    # once here, so that the cut-off check's refits do not warn again
    return [r.resampled_uniform(purpose="IDIM's zero-phase filter, differentiation and "
                                "decimation") for r in recs]


def _refuse_repeated_regressors(blocks, regressors, p, model, offset) -> None:
    """Refuse an extra regressor proportional to another column (``--regressor v``).

    The rank check said "excite both acceleration and velocity", the wrong fix for a
    column given twice (fifth hostile campaign).
    """
    if not regressors:
        return
    gram = sum(b[0].T @ b[0] for b in blocks)  # p x p: no stacked copy of the rows
    names = list(_names(model, False, "N")[0])
    if offset is not None and model == "symmetric":
        names = names[:-1]
    names += [f"k[{r}]" for r in regressors]
    norms = np.sqrt(np.diag(gram))
    for j in range(p - len(regressors), p):
        for k in range(j):
            if norms[j] > 0 and norms[k] > 0 and \
                    abs(gram[j, k]) >= (1 - 1e-9) * norms[j] * norms[k]:
                raise ParameterError(
                    f"the regressor {regressors[j - p + len(regressors)]!r} is proportional "
                    f"to the column of {names[k]} on this record, so their coefficients "
                    "cannot be told apart: drop it (--regressor) if the model already has "
                    "it, else record a motion in which the two differ (a sine makes x and a "
                    "proportional)")


def _stack(recs: list[Record], loads: list[Any], settings: dict[str, Any]
           ) -> tuple[list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]], int]:
    blocks = [idim_regressor(r, load=ld, **settings) for r, ld in zip(recs, loads, strict=True)]
    return blocks, blocks[0][0].shape[1]


def estimate_idim(
    records: Record | Sequence[Record],
    *,
    model: str = "symmetric",
    cutoff_hz: float = 100.0,
    decimate: int = 10,
    edge: int = 50,
    offset: float | None = None,
    load: str | np.ndarray | Sequence[np.ndarray] | None = None,
    regressors: Sequence[str] = (),
    weights: str | Sequence[float] | None = None,
    min_speed: float | None = None,
    sensitivity: bool = True,
    noise: str = "ar",
    parallel: bool = False,
    position_noise_std: float | None = None,
) -> Estimate:
    """Estimate inertia, viscous and Coulomb friction (and offset) by IDIM-LS.

    Parameters
    ----------
    records : Record or sequence of Record
        Position ``x`` [m or rad] and applied force ``u`` [N or N·m]; several records (a
        campaign of runs) are each filtered and differentiated on their own and their rows
        stacked into one least-squares problem (EMPS: ``DATA_EMPS.mat``, force =
        gtau·vir).
    model : {"symmetric", "asymmetric"}
        ``"symmetric"``: parameters M (or J), Fv, Fc, offset. ``"asymmetric"``: M,
        Fv_plus, Fc_plus, Fv_minus, Fc_minus and no offset (EMPS §4.2); a direction the
        runs never move in is reported as ``nan`` with a warning.
    cutoff_hz : float
        Zero-phase 4th-order Butterworth cut-off on the position [Hz] (EMPS: 5 × the
        20 Hz position-loop bandwidth = 100 Hz).
    decimate : int
        Decimation factor of observation matrix and force [-] (EMPS: 10): each row the
        mean of ``decimate`` consecutive samples (see :func:`idim_regressor`). ``1`` uses
        every sample; with coloured force noise the friction terms then come out far more
        precise (AR(1) 0.9, 6 s at 500 Hz: Fv and Fc at 0.78 and 1.07 of the Cramér–Rao
        efficiency against 0.40 and 0.35 at 10; docs/validation.md), at the cost of
        memory on long records.
    edge : int
        Samples dropped at each end of every record after differentiation [-] (EMPS: 50).
    offset : float or None
        Known force offset [N or N·m] (``0.0`` for a drive without one): makes runs in one
        direction identifiable; reported as a fixed parameter. ``None`` estimates it
        (symmetric model only; needs both directions).
    load : str, array_like or sequence of array_like, optional
        Known load [N or N·m] subtracted from the force: an expression of ``t x v a u``
        (e.g. gravity ``"1.47*sin(x)"``), one array for a single record, or one array per
        record.
    regressors : sequence of str
        Extra regressors with unknown coefficients, expressions of ``t x v a u``; the
        coefficient of ``"sin(x)"`` is reported as ``k[sin(x)]`` [force unit].
    weights : None, "auto" or sequence of float
        Row weight per record [-]: ``None`` equal; a sequence, one relative weight per
        record (inverse force-noise variance); ``"auto"`` two passes, weighting each record
        by the inverse of its own residual variance.
    min_speed : float or None
        Rows slower than this are also dropped [m/s or rad/s]; standstill rows (static
        friction holds the force) always are, see :func:`idim_regressor`.
    sensitivity : bool
        Also estimate at ``cutoff_hz/√2`` and ``cutoff_hz·√2`` (below 0.45 fs) and warn
        when the inertia moves by more than its standard error (and more than 1 %).
    noise : {"ar", "white"}
        ``"ar"`` (default): feasible generalised least squares with an AR(p) model of the
        force residual (order by BIC, fitted per contiguous run), the regressors and force
        prewhitened and the fit repeated; white residuals give exactly the ordinary
        least-squares fit. ``"white"``: ordinary least squares with white-noise error bars
        (the EMPS benchmark's published recipe).
    parallel : bool
        Parallel filtering of the force and the friction columns below the decimation's
        band (see :func:`idim_regressor`); ``identify auto`` uses it with a cut-off lowered
        for the position noise.
    position_noise_std : float or None
        Standard deviation of white noise on the measured position [m or rad] (an
        encoder's rounding: ``q/√12``): the acceleration column carries it, twice
        differentiated, and the fit is corrected for the bias it causes (errors in
        variables, Notes). ``None`` (default) estimates it from the fourth differences of
        each record's position; ``0`` turns the correction off (the EMPS recipe).

    Returns
    -------
    Estimate
        ``M`` [kg] (``J`` [kg·m²] when x is not in m), ``Fv`` [N·s/m], ``Fc`` [N],
        ``offset`` [N] (fixed when given) or the asymmetric set, and ``k[<expr>]``, each
        with the standard error ``sqrt(σ²·diag((WᵀΛW)⁻¹))``, ``σ² = eᵀΛe/(m − p)``.
        ``covariance`` of the estimated parameters (from the prewhitened regressors; the
        Newey–West sandwich when even the prewhitened residuals are not white).
        Diagnostics: ``noise_model`` (order, AR coefficients, ``n_eff``), ``adequacy``
        (Ljung–Box whiteness of the prewhitened residuals, their cross-correlation with the
        prewhitened velocity, covariance kind, notes), ``slow_noise`` (the test for noise
        power at the record's slowest frequencies beyond the AR model, 1/f-like drift:
        ``amplitude``, ``slope``, ``p_value``, ``applied``; where applied its covariance is
        added, on the Newey–West sandwich paths too, :mod:`driveid.identify.core._slow_noise`;
        None where not tested: ``noise="white"``),
        ``stderr_white`` (the ordinary
        least-squares standard errors, for comparison), ``cond``,
        ``relative_error_pct`` (``100·||e||/||y||``), ``error_norm``, ``error_std``,
        ``n``, ``n_records``, ``residual_lag1`` (lag-1 autocorrelation of the residual;
        the noise model accounts for it), ``inertia_share_pct`` (the part of the
        force that ``M·a`` explains), ``cutoff_sensitivity`` (inertia at the three
        cut-offs), ``unphysical`` (names with a sign impossible for a passive drive),
        ``at_bound`` (M, Fv, Fc held at 0 by the bounded fit: the unconstrained value and
        the one-sided 95 % upper limit) and
        the settings. ``data_used`` holds decimated ``t``, ``force``, ``predicted``,
        ``velocity`` and ``record_index``.

    Raises
    ------
    RecordError
        If a record lacks force or is too short.
    IdentificationError
        If the drive never moves, moves in one direction only with an unknown offset, or
        the observation matrix is rank-deficient.
    ParameterError
        If a setting or expression is invalid, or ``cutoff_hz`` is too low for a record's
        length (the filter's start-up transient would leave too few samples).

    Notes
    -----
    Force residuals of real drives are coloured (unmodelled dynamics, the loop's own
    noise, the decimation filter): ordinary least squares stays consistent but its
    white-noise error bars are too small by up to ``sqrt(n/n_eff)``. With ``noise="ar"``
    the residual ``e`` of each contiguous run of decimated rows is modelled as AR(p),
    ``A(q) e = w``, and θ re-estimated from ``A(q) y = A(q) W θ + w`` (feasible GLS,
    Ljung 1999 §7.2; two passes), with covariance ``σ_w² (W_wᵀ W_w)⁻¹`` of the
    prewhitened ``W_w`` (:mod:`driveid.identify.core._noise`).

    The fit is bounded by physics (M > 0, Fv >= 0, Fc >= 0 and their ``_plus``/``_minus``
    forms): when the unconstrained estimate crosses a bound, bounded least squares
    (:func:`scipy.optimize.lsq_linear`) on the same rows holds it at 0 and refits the
    others; ``diagnostics["at_bound"]`` and a warning say so.

    Ordinary least squares is unbiased only if the force noise is uncorrelated with the
    regressors; in closed loop it is not, but the benchmark shows the bias is small when
    the filter cut-off is well above the loop bandwidth (Janot et al. 2019, §3.3). Noise
    in the position enters the acceleration column amplified by ``(2π f)²`` up to the
    cut-off and biases the inertia towards 0 (errors in variables); prewhitening for
    strongly coloured force noise weights that band most. The fit subtracts the noise's
    expected share of ``XᵀX`` (Fuller 1987 §2.2) and widens the covariance for it
    (:mod:`driveid.identify.friction._idim_eiv`; ``diagnostics["errors_in_variables"]``;
    issue 24: M coverage 0.60 → 0.90 under AR(1) 0.97 force noise with a 1 µm encoder,
    200 records, docs/validation.md);
    the cut-off check exposes what is left. The
    inertia is identifiable only where the acceleration carries a visible part of the
    force: steps, reversals and sine sweeps do, constant speeds do not.

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
    >>> est = estimate_idim(rec, decimate=1, cutoff_hz=50.0, sensitivity=False)
    >>> abs(est.value("M") - 2.0) < 0.05, abs(est.value("Fv") - 3.0) < 0.2
    (True, True)
    """
    recs = _as_records(records)
    if load is None and not offset and all(r.u is not None and not np.any(r.u) for r in recs):
        # nothing to fit: θ = 0 explains a zero force exactly (issue 28: was a division by 0)
        raise IdentificationError(
            "IDIM fits the applied force, and the force of every record is all zero (a free "
            "decay or an unpowered run?); give the column holding the drive's force or "
            "torque (--force COLUMN), or fit a free decay with identify logdec; got "
            "max |u| = 0")
    if offset is not None and not math.isfinite(float(offset)):
        raise ParameterError(f"offset must be a finite force [N or N·m] or None; got {offset}")
    loads = _loads(load, recs)
    regressors = tuple(regressors)
    for r in regressors:
        parse_expression(r)
    settings = {"model": model, "cutoff_hz": float(cutoff_hz), "decimate": decimate,
                "parallel": bool(parallel),
                "edge": edge, "offset": offset, "regressors": regressors,
                "min_speed": min_speed}
    blocks, p = _stack(recs, loads, settings)
    if load is not None and not any(np.any(b[1]) for b in blocks):
        # issue 28, campaign 4: --load u (the force itself) left nothing, a division by 0
        raise IdentificationError(
            "the force minus the known load is zero on every row, so there is nothing left "
            "for IDIM to fit; check the known load (load=): it must be a force the "
            "drive does not supply (gravity, a spring), not the force column itself")
    for j, expr in enumerate(regressors, start=p - len(regressors)):
        if not any(np.any(b[0][:, j]) for b in blocks):  # reported as nan before
            raise IdentificationError(
                f"the regressor {expr!r} is zero on every row, so its coefficient cannot be "
                "estimated; drop it (--regressor) or check its expression")
    _refuse_repeated_regressors(blocks, regressors, p, model, offset)
    v_all = np.concatenate([b[3] for b in blocks])
    _check_motion(v_all, model, offset)
    w = _weights(weights, len(recs))
    support = _support(v_all, model, p)
    if noise not in ("ar", "white"):
        raise ParameterError(f"noise must be 'ar' or 'white'; got {noise!r}")
    positive = np.array([True] * (5 if model == "asymmetric" else 3) + [False] * (
        p - (5 if model == "asymmetric" else 3)))
    sigmas = _position_noise(position_noise_std, recs, settings)
    eiv = {"position_noise": _row_noise(recs, settings, sigmas),
           "velocity_column": 1 if model == "symmetric" else None}
    theta, cov, e, W, y, keep, fit = _solve(blocks, w, support, noise=noise, positive=positive,
                                            **eiv)
    if weights == "auto":
        var = np.array([max(float(np.mean(e[i] ** 2)), 1e-300) for i in range(len(blocks))])
        w = 1.0 / var
        theta, cov, e, W, y, keep, fit = _solve(blocks, w, support, noise=noise,
                                                positive=positive, **eiv)
    first = recs[0]
    translational = first.units.get("x", "rad") == "m"
    force_unit = first.units.get("u", "N" if translational else "N·m")
    names, units = _names(model, translational, force_unit)
    if offset is not None and model == "symmetric":
        names, units = names[:-1], units[:-1]
    names = names + tuple(f"k[{r}]" for r in regressors)
    units = units + tuple(f"{force_unit}/({r})" for r in regressors)
    stderr = np.sqrt(np.diag(cov))
    params: dict[str, Parameter] = {}
    est_names: list[str] = []
    for j, (nm, un) in enumerate(zip(names, units, strict=True)):
        if keep[j]:
            params[nm] = Parameter(float(theta[j]), float(stderr[j]), un)
            est_names.append(nm)
        else:
            params[nm] = Parameter(math.nan, math.nan, un)
    if offset is not None:
        params["offset"] = Parameter(float(offset), math.nan, force_unit, fixed=True)
    y_all = np.concatenate(y)
    e_all = np.concatenate(e)
    pred = y_all - e_all
    err_norm = float(np.linalg.norm(e_all))
    lag1 = _lag1(e)
    inertia = names[0]
    a_part = np.concatenate([b[0][:, 0] for b in blocks]) * params[inertia].value
    diagnostics: dict[str, Any] = {
        "model": model,
        "cond": float(np.linalg.cond(W[:, keep])),
        "relative_error_pct": 100.0 * err_norm / float(np.linalg.norm(y_all)),
        "error_norm": err_norm,
        "error_std": float(np.sqrt(err_norm**2 / max(y_all.size - int(keep.sum()), 1))),
        "n": int(y_all.size),
        "n_records": len(recs),
        "residual_lag1": lag1,
        "inertia_share_pct": 100.0 * float(np.linalg.norm(a_part) / np.linalg.norm(y_all)),
        "cutoff_hz": float(cutoff_hz),
        "decimate": int(decimate),
        "parallel": bool(parallel),
        "edge": int(edge),
        "min_speed": min_speed,
        "offset_fixed": None if offset is None else float(offset),
        "regressors": list(regressors),
        "load": load if isinstance(load, str) else (None if load is None else "array"),
        "weights": [float(x) for x in w],
        "source": str(first.meta.get("source", "")),
        "force_unit": force_unit,
        "noise": noise,
        "errors_in_variables": _eiv_diagnostics(fit, sigmas, est_names),
        "noise_model": fit["noise_model"].to_dict(),
        "adequacy": fit["adequacy"].to_dict(),
        "slow_noise": fit.get("slow_noise"),
        "stderr_white": {nm: float(s_) for nm, s_ in
                         zip(est_names, np.sqrt(np.diag(fit["cov_white"])), strict=True)},
    }
    held = _held(fit, theta, names, units, stderr)
    warnings = _warnings(params, names, keep, diagnostics, model) + fit["warnings"]
    if held:
        diagnostics["at_bound"] = {nm: entry for nm, (entry, _) in held.items()}
        diagnostics["unphysical"] = sorted(set(diagnostics["unphysical"]) | set(held),
                                           key=names.index)
        warnings += [message for _, message in held.values()]
    if sensitivity:
        warnings += _cutoff_check(recs, loads, settings, w, params[inertia], inertia,
                                  diagnostics, noise, sigmas, eiv["velocity_column"])
    est = Estimate(
        method=f"idim-ls-{model}",
        params=params,
        data_used={"t": np.concatenate([b[2] for b in blocks]), "force": y_all,
                   "predicted": pred, "velocity": v_all,
                   "record_index": np.concatenate([np.full(b[1].size, i)
                                                   for i, b in enumerate(blocks)])},
        diagnostics=diagnostics,
        warnings=tuple(warnings),
        covariance={"names": est_names, "matrix": cov[np.ix_(keep, keep)]},
    )
    return _plausibility(est)


def _plausibility(est: Estimate) -> Estimate:
    try:
        from driveid.identify.core._plausibility import check_plausibility
    except ImportError:
        return est
    out = check_plausibility(est)
    return out if isinstance(out, Estimate) else est


def _loads(load: Any, recs: list[Record]) -> list[Any]:
    if load is None or isinstance(load, str):
        return [load] * len(recs)
    if len(recs) == 1 and np.ndim(load) == 1:
        return [np.asarray(load, float)]
    loads = list(load)
    if len(loads) != len(recs):
        raise ParameterError(f"load needs one array per record ({len(recs)}) [N or N·m]; "
                             f"got {len(loads)}")
    return loads


def _weights(weights: Any, n: int) -> np.ndarray:
    if weights is None or weights == "auto":
        return np.ones(n)
    w = np.asarray(weights, dtype=float).ravel()
    if w.size != n or not np.all(np.isfinite(w)) or np.any(w <= 0):
        raise ParameterError(f"weights must be 'auto' or one positive number per record "
                             f"({n}) [-]; got {list(np.atleast_1d(weights))}")
    return w


def _support(v: np.ndarray, model: str, p: int) -> np.ndarray:
    support = np.ones(p, bool)
    if model == "asymmetric":
        moving = np.abs(v) > 0.01 * float(np.max(np.abs(v)))
        support[1:3] = np.count_nonzero(moving & (v > 0)) >= 5
        support[3:5] = np.count_nonzero(moving & (v < 0)) >= 5
    return support


def _warnings(params: dict[str, Parameter], names: tuple[str, ...], keep: np.ndarray,
              diag: dict[str, Any], model: str) -> list[str]:
    out = []
    missing = [nm for nm, k in zip(names, keep, strict=True) if not k]
    if missing:
        out.append(f"{', '.join(missing)} not identifiable: the runs never excite them "
                   "(no motion in that direction); add runs in the other direction")
    if diag["cond"] > 1e3:
        out.append(f"observation matrix is ill-conditioned (cond = {diag['cond']:.3g}); the "
                   "excitation does not separate the parameters well")
    inertia = names[0]
    pj = params[inertia]
    if math.isfinite(pj.stderr) and (pj.value == 0 or pj.stderr > 0.1 * abs(pj.value)):
        out.append(
            f"inertia {inertia} is poorly identified ({pj.value:.4g} ± {pj.stderr:.2g}; "
            f"M·a explains {diag['inertia_share_pct']:.2g} % of the force): the runs lack "
            "acceleration; add steps, reversals or a sine sweep")
    unphysical = []
    for nm in names:
        p = params[nm]
        physical_positive = nm == inertia or nm.startswith(("Fv", "Fc"))
        if physical_positive and math.isfinite(p.value) and p.value < 0:
            unphysical.append(nm)
            sig = "significantly " if p.value < -2 * p.stderr else ""
            out.append(
                f"{nm} = {p.value:.4g} ± {p.stderr:.2g} is {sig}negative, which a passive "
                "drive cannot have: the model misses an effect of the data (backlash, "
                "compliance, stiction, a load or an offset), or the excitation is too weak")
    diag["unphysical"] = unphysical
    loose = {nm: abs(p.stderr / p.value) for nm, p in params.items()
             if not p.fixed and math.isfinite(p.value) and p.value != 0
             and abs(p.stderr / p.value) > 0.3}
    if loose:
        which = ", ".join(f"{nm} ±{100 * r:.0f} %" for nm, r in loose.items())
        # an offset is a force at rest: more motion does not resolve a small one
        advice = ("excite the drive over a wider range of velocity and acceleration"
                  if set(loose) - {"offset"} else
                  "an offset this small is not resolved by the force noise; give it if "
                  "known (--offset 0 for a drive without one)")
        out.append(f"relative standard errors above 30 % ({which}): {advice}")
    return out


def _position_noise(given: float | None, recs: list[Record], settings: dict[str, Any]
                    ) -> list[float | None]:
    """Per record the position noise sd [m or rad]: given, or None (estimated per cut-off)."""
    if given is None:
        return [None] * len(recs)
    value = float(given)
    if not (math.isfinite(value) and value >= 0):
        raise ParameterError("position_noise_std must be >= 0 [m or rad]: 0 turns the "
                             "errors-in-variables correction off, leaving it out estimates "
                             f"the noise from the record; got {given}")
    return [value] * len(recs)


def _row_noise(recs: list[Record], settings: dict[str, Any], sigmas: list[float | None]
               ) -> list[Any] | None:
    if all(s == 0 for s in sigmas):
        return None
    return [row_noise(np.asarray(r.x, float), r.fs, settings["cutoff_hz"],
                      int(settings["decimate"]), s) for r, s in zip(recs, sigmas, strict=True)]


def _eiv_diagnostics(fit: dict[str, Any], sigmas: list[float | None],
                     names: list[str]) -> dict[str, Any]:
    info = fit.get("errors_in_variables")
    if info is None:
        return {"applied": False, "position_noise_std": [s or 0.0 for s in sigmas]}
    out = {"applied": bool(info["applied"]), "position_noise_std": info["sigma"],
           "noise_share": info.get("noise_share")}
    if info["applied"]:
        out["shift_se"] = dict(zip(names, info["shift_se"], strict=True))
    return out


def _cutoff_check(recs: list[Record], loads: list[Any], settings: dict[str, Any],
                  w: np.ndarray, pj: Parameter, inertia: str, diag: dict[str, Any],
                  noise: str = "white", sigmas: list[float | None] | None = None,
                  velocity_column: int | None = 1) -> list[str]:
    fc = settings["cutoff_hz"]
    fs_min = min(r.fs for r in recs)
    values = {fc: pj.value}
    for f in (fc / math.sqrt(2.0), fc * math.sqrt(2.0)):
        if f >= 0.45 * fs_min:
            continue
        try:
            at_f = {**settings, "cutoff_hz": f}
            blocks, _ = _stack(recs, loads, at_f)
            theta, *_ = _solve(blocks, w, _support(np.concatenate([b[3] for b in blocks]),
                                                   settings["model"], blocks[0][0].shape[1]),
                               noise=noise, velocity_column=velocity_column,
                               position_noise=_row_noise(recs, at_f, sigmas or
                                                         [0.0] * len(recs)))
        except (IdentificationError, RecordError, ParameterError):
            continue
        values[f] = float(theta[0])
    diag["cutoff_sensitivity"] = {f"{k:.4g}": v for k, v in sorted(values.items())}
    worst = max(abs(v - pj.value) for v in values.values())
    # a floor of 1 %: smaller moves are below any use of an inertia value
    if math.isfinite(pj.stderr) and worst > max(pj.stderr, 0.01 * abs(pj.value)):
        span = ", ".join(f"{v:.4g} at {k:.3g} Hz" for k, v in sorted(values.items()))
        return [f"inertia {inertia} depends on the filter cut-off by more than its standard "
                f"error {pj.stderr:.2g} ({span}); choose the cut-off where it is flat, or "
                "excite more acceleration"]
    return []


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
        If ``estimate`` did not come from :func:`estimate_idim`, or the record's force is
        all zero.
    """
    diag = estimate.diagnostics
    if not estimate.method.startswith("idim-ls-") or "model" not in diag:
        raise IdentificationError(
            "validate_idim needs an estimate made by estimate_idim; got method "
            f"{estimate.method!r}"
        )
    model = str(diag["model"])
    load = diag.get("load")
    if load == "array":
        raise IdentificationError("validate_idim cannot reuse a load given as an array; "
                                  "estimate with a load expression instead; got load=array")
    W, y, t, _ = idim_regressor(record, model=model, cutoff_hz=float(diag["cutoff_hz"]),
                                decimate=int(diag["decimate"]), edge=int(diag["edge"]),
                                offset=diag.get("offset_fixed"), load=load,
                                regressors=tuple(diag.get("regressors", ())),
                                min_speed=diag.get("min_speed"),
                                parallel=bool(diag.get("parallel", False)))
    theta = np.array([p.value for p in estimate.params.values() if not p.fixed])
    theta = np.where(np.isfinite(theta), theta, 0.0)
    pred = W @ theta
    err = float(np.linalg.norm(y - pred))
    scale = float(np.linalg.norm(y))
    if not scale > 0.0:
        # the relative error divides by the measured force (issue 28: was a division by 0)
        raise IdentificationError(
            "the cross-test record's force is all zero after filtering (a free decay or an "
            "unpowered run?), so there is no force to predict; give --validate a record of "
            "the drive in motion with its force or torque column (--force COLUMN); got "
            "|u| = 0")
    return IdimValidation(
        relative_error=100.0 * err / scale,
        error_norm=err,
        cond=float(np.linalg.cond(W)),
        t=t,
        measured=y,
        predicted=pred,
    )


def _check_motion(v: np.ndarray, model: str, offset: float | None = None) -> None:
    scale = float(np.max(np.abs(v))) if v.size else 0.0
    if scale == 0.0:
        raise IdentificationError(
            "the drive never moves, so friction and inertia cannot be identified; record "
            "a run with motion in both directions; got max |v| = 0"
        )
    moving = np.abs(v) > 0.01 * scale
    n_pos = int(np.count_nonzero(moving & (v > 0)))
    n_neg = int(np.count_nonzero(moving & (v < 0)))
    if max(n_pos, n_neg) < 5 or (model == "symmetric" and offset is None
                                 and min(n_pos, n_neg) < 5):
        raise IdentificationError(
            "Coulomb friction and offset cannot be separated without both directions; add "
            "a run in the other direction, or fix the offset (offset=0.0, CLI --offset 0); "
            f"got {n_pos} positive and {n_neg} negative-velocity samples"
        )
