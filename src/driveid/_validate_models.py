r"""Drive models of identified estimates, simulated over a record (for :mod:`driveid.validate`).

Every estimate that identifies a simulatable model becomes one rigid body of the lumped drive
(:class:`driveid.sim.BodyParams`: ``J``, ``K``, ``c_mean``, ``c_delta``, ``fk_mean``,
``fk_delta``; de Marchi 1998, Eq. 2.155 with static = kinetic friction) with, where the
experiment had one, its input and its loop, and is simulated by
:func:`driveid.sim.simulate_drive` (event-located RK4, exact delayed feedback):

=========================  ==============================  =============================
kind (estimate methods)    input and loop                  initial state
=========================  ==============================  =============================
``pho``                    delayed PD loop ``P``, ``D``    ``meta["x0"]`` (else first
(``pho-campaign``,         of ``meta``, Δ = ``delay``;     sample), at rest at t = 0
``pho-output-error``)      no external input; the static   (a window keeps that clock)
                           band it chose
                           (``diagnostics["static_band"]``)
                           is simulated
``forced``                 ``u`` of the record; forced     fitted (exact linear least
(``forced-response``,      PHO adds the delayed PD loop    squares; nonlinear least
``forced-pho``)            (gains from ``meta`` or the     squares with friction)
                           estimate); with friction=True
                           also c_delta, fk_mean, fk_delta
``idim`` (``idim-ls-*``)   ``u - offset``, ``K = 0``       x0 the mean residual, v0 by
                                                           least squares from the first
                                                           samples' slope
``friction-map``           ``u``, ``K = 0``, ``J`` given   as ``idim``; J fitted with v0
(``friction-map-coulomb-   or fitted (output error)        when not given
viscous``)
=========================  ==============================  =============================

A stiffness estimate below zero but within three standard errors of it is simulated as 0
(the simulator needs ``K >= 0``); a clearly negative one is refused.

Free decays (``logdec-*``, ``output-error``) keep their exact closed form in
:mod:`driveid.validate`.

References
----------
.. [1] J. A. de Marchi, "Modeling of dynamic friction, impact backlash and elastic
       compliance nonlinearities in machine tools", PhD thesis, RPI, 1998, Eqs. (2.155),
       (2.176), (2.180).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from scipy.optimize import least_squares

from driveid.errors import IdentificationError, RecordError
from driveid.identify.core.estimate import Estimate
from driveid.io.record import Record

__all__ = ["FREE_DECAY", "SUPPORTED", "DriveModel", "drive_model", "kind_of",
           "simulate_model"]

FREE_DECAY = ("omega0", "zeta_plus", "zeta_minus", "theta_k_mean", "theta_k_delta")
PHO_METHODS = ("pho-campaign", "pho-output-error")
FORCED_METHODS = ("forced-response", "forced-pho")
#: One line naming every supported estimate (used in refusals).
SUPPORTED = ("free decays (logdec-*, output-error), pho-campaign, pho-output-error, "
             "forced-response, forced-pho, idim-ls-symmetric, idim-ls-asymmetric and "
             "friction-map-coulomb-viscous")


@dataclass(frozen=True)
class DriveModel:
    """One body, its loop and its input, ready to simulate over a record.

    Attributes
    ----------
    kind : str
        ``"pho"``, ``"forced"``, ``"idim"`` or ``"friction-map"``.
    body : BodyParams
        Identified inertia [kg·m² or kg], stiffness, viscous and kinetic friction.
    feedback : PDFeedback or None
        Delayed PD loop (P [N·m/rad], D [N·m·s/rad], delay [s]).
    input_offset : float
        Subtracted from the record's ``u`` before it drives the body [N·m or N].
    uses_input : bool
        True if the record's ``u`` is the model's input.
    linear : bool
        True without kinetic friction: the response is linear in the initial state.
    summary : dict
        JSON-ready description: kind, simulated parameters, where each came from.
    """

    kind: str
    body: Any
    feedback: Any
    input_offset: float = 0.0
    uses_input: bool = False
    linear: bool = False
    summary: Mapping[str, Any] = field(default_factory=dict)


def kind_of(estimate: Estimate) -> str:
    """Return the model kind of an estimate, or refuse it in one line.

    Parameters
    ----------
    estimate : Estimate
        Any estimate.

    Returns
    -------
    str
        ``"free-decay"``, ``"pho"``, ``"forced"``, ``"idim"`` or ``"friction-map"``.

    Raises
    ------
    IdentificationError
        For an estimate that identifies no simulatable model.
    """
    method = estimate.method
    if all(n in estimate for n in FREE_DECAY):
        return "free-decay"
    if method in PHO_METHODS:
        return "pho"
    if method in FORCED_METHODS:
        return "forced"
    if method.startswith("idim-ls-"):
        return "idim"
    if method == "friction-map-coulomb-viscous":
        return "friction-map"
    if method.startswith("friction-map-"):
        raise IdentificationError(
            f"a {method!r} estimate cannot be simulated: the drive simulator has Coulomb + "
            "viscous friction, not this Stribeck map; validate the friction-map-coulomb-"
            "viscous result instead")
    missing = [n for n in FREE_DECAY if n not in estimate]
    raise IdentificationError(
        f"validation of a {method!r} estimate is not supported: it is no free decay (it "
        f"lacks the free-decay parameters {missing}) and no other simulatable model; "
        f"supported: {SUPPORTED} (and drive-oe through driveid.validate_drive.compare_drive"
        ", which the validate command uses)")


def _value(estimate: Estimate, name: str, what: str) -> float:
    """Return a finite parameter value, or refuse in one line naming what is missing."""
    if name not in estimate or not math.isfinite(estimate.value(name)):
        have = "nan" if name in estimate else "no"
        raise IdentificationError(
            f"{what} cannot be simulated: it has {have} {name}; identify {name} (or give it) "
            f"and validate again; parameters: {sorted(estimate.params)}")
    return float(estimate.value(name))


def _optional(estimate: Estimate, name: str) -> float:
    """Return the value of an optional friction term; 0 when absent."""
    if name in estimate and math.isfinite(estimate.value(name)):
        return float(estimate.value(name))
    return 0.0


def _stiffness(estimate: Estimate, what: str) -> tuple[float, bool]:
    """Return K [N·m/rad or N/m] for the simulator, and whether a noisy K < 0 became 0."""
    K = _value(estimate, "K", what)
    if K >= 0:
        return K, False
    se = estimate.stderr("K")
    if estimate["K"].fixed or not (math.isfinite(se) and K + 3.0 * se >= 0):
        raise IdentificationError(
            f"{what} cannot be simulated: its stiffness K = {K:g} is negative (standard "
            f"error {se:g}); re-identify with the stiffness known (K_known=0, CLI --K 0)")
    return 0.0, True


def _gain(record: Record, estimate: Estimate, name: str, index: int | None,
          what: str) -> float:
    """Return a loop gain from the record's meta, else from the estimate's per-record data."""
    value = record.meta.get(name)
    if value is None and index is not None:
        arr = np.atleast_1d(np.asarray(estimate.data_used.get(name, []), dtype=float))
        if arr.size > index:
            value = arr[index]
    try:
        value = float(value)
    except (TypeError, ValueError):
        raise IdentificationError(
            f"{what} runs under PD feedback, but the record has no numeric meta[{name!r}]; "
            f"give the run's gain (a CSV written by driveid keeps meta P, D, x0 in its "
            f"header); got {value!r}") from None
    if not math.isfinite(value):
        raise IdentificationError(f"{what}: meta[{name!r}] must be finite; got {value!r}")
    return value


def _friction_body(J: float, K: float, c_mean: float, c_delta: float, fk_mean: float,
                   fk_delta: float, what: str, fs_mean: float | None = None,
                   fs_delta: float | None = None):
    from driveid.sim import BodyParams

    if not J > 0:
        raise IdentificationError(
            f"{what} cannot be simulated: its inertia J = {J:g} is not positive; the data "
            "did not identify it (excite accelerations, or give J)")
    if fk_mean < 0:
        raise IdentificationError(
            f"{what} cannot be simulated: its kinetic friction fk_mean = {fk_mean:g} < 0 is "
            "not a passive drive; re-identify (more motion in both directions)")
    return BodyParams(J=J, K=K, c_mean=c_mean, c_delta=c_delta, fk_mean=fk_mean,
                      fk_delta=fk_delta, fs_mean=fs_mean, fs_delta=fs_delta)


def _pho_model(estimate, record, index):
    from driveid.sim import PDFeedback

    what = f"a {estimate.method} estimate"
    J = _value(estimate, "J", what)
    K, clamped = _stiffness(estimate, what)
    c_mean = _value(estimate, "c_mean", what)
    delay = _value(estimate, "delay", what)
    P = _gain(record, estimate, "P", None, what)
    D = _gain(record, estimate, "D", None, what)
    sat = record.meta.get("saturation")
    sat = float(sat) if isinstance(sat, (int, float)) and sat > 0 else math.inf
    friction = {n: _optional(estimate, n) for n in ("c_delta", "fk_mean", "fk_delta")}
    # a campaign fit that found static above kinetic friction (pho_fit's static band) is
    # simulated with it: sticking then ends at the static level, as in the fitted model
    band = (estimate.diagnostics or {}).get("static_band")
    static = ({"fs_mean": float(band["fs_mean"]), "fs_delta": float(band["fs_delta"])}
              if isinstance(band, Mapping) and band.get("chosen") else {})
    body = _friction_body(J, K, c_mean, friction["c_delta"], friction["fk_mean"],
                          friction["fk_delta"], what, **static)
    fb = PDFeedback(P=P, D=D, delay=delay, saturation=sat)
    absent = [n for n in ("c_delta", "fk_mean", "fk_delta") if n not in estimate]
    return DriveModel("pho", body, fb, summary={
        "kind": "pho", "J": J, "K": K, "c_mean": c_mean, **friction, **static, "delay": delay,
        "P": P, "D": D, "terms_taken_as_zero": absent + ["K"] * clamped})


def _forced_model(estimate, record, index):
    from driveid.sim import PDFeedback

    what = f"a {estimate.method} estimate"
    J = _value(estimate, "J", what)
    K, clamped = _stiffness(estimate, what)
    c_mean = _value(estimate, "c_mean", what)
    if not J > 0:
        raise IdentificationError(f"{what} cannot be simulated: J = {J:g} is not positive")
    summary = {"kind": "forced", "J": J, "K": K, "c_mean": c_mean,
               "terms_taken_as_zero": ["K"] * clamped}
    fb = None
    if estimate.method == "forced-pho":
        delay = _value(estimate, "delay", what)
        P = _gain(record, estimate, "P", index, what)
        D = _gain(record, estimate, "D", index, what)
        fb = PDFeedback(P=P, D=D, delay=delay)
        summary.update(delay=delay, P=P, D=D)
    # a friction fit (friction=True) adds c_delta, fk_mean, fk_delta; fk_delta not identified
    # on a spring of unknown zero is replaced by the identified K·x_ref-inclusive offset,
    # which gives the same force in the record's own coordinates
    friction = {n: _optional(estimate, n) for n in ("c_delta", "fk_mean", "fk_delta")}
    offset = estimate.diagnostics.get("dc_force_offset")
    if ("fk_delta" in estimate and not math.isfinite(estimate.value("fk_delta"))
            and isinstance(offset, (int, float)) and math.isfinite(offset)):
        friction["fk_delta"] = float(offset)
        summary["fk_delta_from"] = "dc_force_offset (fk_delta - K·x_ref)"
    summary.update(friction)
    summary["terms_taken_as_zero"] += [
        n for n in ("c_delta", "fk_mean", "fk_delta")
        if n in estimate and not math.isfinite(estimate.value(n)) and friction[n] == 0.0]
    body = _friction_body(J, K, c_mean, friction["c_delta"], friction["fk_mean"],
                          friction["fk_delta"], what)
    linear = friction["fk_mean"] == 0 and friction["fk_delta"] == 0 and friction["c_delta"] == 0
    return DriveModel("forced", body, fb, uses_input=True, linear=linear, summary=summary)


def _idim_model(estimate, record, index):
    diag = estimate.diagnostics
    what = f"an IDIM estimate ({estimate.method})"
    if diag.get("regressors") or diag.get("load"):
        raise IdentificationError(
            f"{what} with a load or extra regressors ({diag.get('load') or ''} "
            f"{list(diag.get('regressors') or [])}) cannot be simulated: the drive model has "
            "inertia and friction only; estimate without --load/--regressor to validate")
    inertia = "M" if "M" in estimate else "J"
    J = _value(estimate, inertia, what)
    if estimate.method == "idim-ls-asymmetric":
        fvp, fcp = (_value(estimate, n, what) for n in ("Fv_plus", "Fc_plus"))
        fvm, fcm = (_value(estimate, n, what) for n in ("Fv_minus", "Fc_minus"))
        c_mean, c_delta = 0.5 * (fvp + fvm), 0.5 * (fvp - fvm)
        # F = Fc+ moving forward, -Fc- backward: fk_mean·s + fk_delta with these
        fk_mean, fk_delta = 0.5 * (fcp + fcm), 0.5 * (fcp - fcm)
        offset = _optional(estimate, "offset")
    else:
        c_mean, c_delta = _value(estimate, "Fv", what), 0.0
        fk_mean, fk_delta = _value(estimate, "Fc", what), 0.0
        offset = _value(estimate, "offset", what)
    body = _friction_body(J, 0.0, c_mean, c_delta, fk_mean, fk_delta, what)
    return DriveModel("idim", body, None, input_offset=offset, uses_input=True,
                      linear=fk_mean == 0 and fk_delta == 0, summary={
                          "kind": "idim", "J": J, "c_mean": c_mean, "c_delta": c_delta,
                          "fk_mean": fk_mean, "fk_delta": fk_delta, "offset": offset})


def _regressed_inertia(record: Record, friction) -> float:
    """Return the inertia [kg·m² or kg]: least squares of ``u - F(v) = J a`` while moving."""
    from driveid.signal.differentiate import differentiate

    fs = 1.0 / record.dt
    cutoff = fs / 20.0  # well above a drive's motion band, well below Nyquist
    _, v, a = differentiate(np.asarray(record.x, float), fs, cutoff_hz=cutoff)
    edge = min(int(3 * fs / cutoff), record.n // 4)  # the filter's start-up transient
    sl = slice(edge, record.n - edge)
    v, a, u = v[sl], a[sl], np.asarray(record.u, float)[sl]
    moving = np.abs(v) > 0.05 * max(float(np.max(np.abs(v))), 1e-300)
    s = np.sign(v)
    F = (friction["c_mean"] + friction["c_delta"] * s) * v + friction["fk_mean"] * s \
        + friction["fk_delta"]
    aa = a[moving]
    den = float(aa @ aa)
    J = float(aa @ (u[moving] - F[moving])) / den if den > 0 else math.nan
    if not (math.isfinite(J) and J > 0):
        raise IdentificationError(
            "a friction map identifies no inertia and the record does not give one "
            f"(regressed J = {J:.3g}); pass inertia= (CLI --inertia) [kg·m² or kg]")
    return J


def _map_model(estimate, record, index, inertia):
    what = "a friction-map estimate"
    friction = {n: _value(estimate, n, what) for n in ("c_mean", "c_delta", "fk_mean",
                                                      "fk_delta")}
    if inertia is not None:
        J, source = float(inertia), "given"
    else:
        J, source = _regressed_inertia(record, friction), "regressed from the record"
    body = _friction_body(J, 0.0, *friction.values(), what)
    return DriveModel("friction-map", body, None, uses_input=True, summary={
        "kind": "friction-map", "J": J, "J_source": source, **friction})


def drive_model(estimate: Estimate, record: Record, *, index: int | None = None,
                inertia: float | None = None) -> DriveModel:
    """Build the drive model of a non-free-decay estimate for one record.

    Parameters
    ----------
    estimate : Estimate
        A PHO, forced-response, IDIM or friction-map estimate.
    record : Record
        The record (its ``meta`` gains, its ``u``).
    index : int, optional
        Position of the record among the estimate's records (per-record gains).
    inertia : float, optional
        Inertia for a friction map [kg·m² or kg]; regressed from the record when None.

    Returns
    -------
    DriveModel
        The body, loop and input.

    Raises
    ------
    IdentificationError
        An estimate that cannot be simulated; the message names what is missing.
    RecordError
        A record without the input ``u`` the model needs.
    """
    kind = kind_of(estimate)
    if kind in ("forced", "idim", "friction-map") and record.u is None:
        raise RecordError(
            f"a {estimate.method} model is driven by the record's force/torque u, and this "
            "record has none; read it with its force column (--force COL)")
    if inertia is not None and not (math.isfinite(inertia) and inertia > 0):
        raise IdentificationError(f"inertia must be positive [kg·m² or kg]; got {inertia!r}")
    if kind == "pho":
        return _pho_model(estimate, record, index)
    if kind == "forced":
        return _forced_model(estimate, record, index)
    if kind == "idim":
        return _idim_model(estimate, record, index)
    if kind == "friction-map":
        return _map_model(estimate, record, index, inertia)
    raise IdentificationError(f"{estimate.method!r}: a free decay has no drive model here")


def _run(model: DriveModel, record: Record, x0: float, v0: float, *,
         with_input: bool = True, n: int | None = None) -> np.ndarray:
    """Return the simulated position [m or rad] at the record's times from the state (x0, v0).

    ``n``: simulate only the first n samples.
    """
    from driveid.sim import DriveParams, simulate_drive

    t = np.asarray(record.t, float)[:n]
    # a PHO run is released at t = 0 of its clock: a window of it starts the run there too
    t = t - (0.0 if model.kind == "pho" and t[0] >= 0 else float(t[0]))
    fs = 1.0 / record.dt
    n_grid = int(math.ceil(t[-1] * fs - 1e-6)) + 1
    grid = np.arange(n_grid) / fs
    torque = None
    if model.uses_input and with_input:
        u = np.asarray(record.u, float)[:n] - model.input_offset
        torque = np.interp(grid, t, u)[None, :]
    params = DriveParams(bodies=(model.body,), feedback=model.feedback)
    res = simulate_drive(params, duration=(n_grid - 1 + 1e-6) / fs, fs=fs, x0=[x0], v0=[v0],
                         torque=torque)
    x = res.x[0][:n_grid]
    if x.size < n_grid or not np.all(np.isfinite(x)):
        raise IdentificationError(
            f"the simulation of the identified {model.kind} model stopped early "
            f"({res.abort_reason or 'non-finite state'}); the model is unstable on this record")
    if x.size == t.size and np.allclose(grid, t, rtol=0.0, atol=1e-6 / fs):
        return x
    return np.interp(t, grid, x)


def _first_state(record: Record) -> tuple[float, float]:
    """Return position [m or rad] and velocity [m/s or rad/s] at the first sample (a line fit)."""
    if record.v is not None:
        return float(record.x[0]), float(record.v[0])
    m = min(record.n, 10)
    slope, intercept = np.polyfit(record.t[:m] - record.t[0], record.x[:m], 1)
    return float(intercept), float(slope)


def simulate_model(model: DriveModel, record: Record) -> tuple[np.ndarray, dict[str, Any]]:
    """Simulate a drive model over a record from its initial state (see module docstring).

    Parameters
    ----------
    model : DriveModel
        From :func:`drive_model`.
    record : Record
        Times [s], position [m or rad] and, where used, input ``u`` [N·m or N].

    Returns
    -------
    y_hat : ndarray, shape (n,)
        Simulated position [m or rad].
    state : dict
        ``x0`` [m or rad], ``v0`` [m/s or rad/s] and ``initial_state`` (how they were
        obtained).
    """
    y = np.asarray(record.x, float)
    if model.kind == "pho":
        x0 = record.meta.get("x0")
        how = "meta x0, released at rest"
        if not isinstance(x0, (int, float)) or not math.isfinite(x0):
            if record.t[0] > 0.5 * record.dt:
                raise IdentificationError(
                    f"this PHO record starts at t = {record.t[0]:g} s, after the release at "
                    "t = 0, and has no meta['x0']; give the release position x0 or validate "
                    "the whole run")
            x0, how = float(y[0]), "first sample, released at rest"
        x0 = float(x0)
        return _run(model, record, x0, 0.0), {"x0": x0, "v0": 0.0, "initial_state": how}
    if model.linear:
        # the response is y_u + x0·y_x + v0·y_v: the initial state by linear least squares
        base = _run(model, record, 0.0, 0.0)
        cols = np.column_stack([_run(model, record, 1.0, 0.0, with_input=False),
                                _run(model, record, 0.0, 1.0, with_input=False)])
        (x0, v0), *_ = np.linalg.lstsq(cols, y - base, rcond=None)
        return base + cols @ [x0, v0], {"x0": float(x0), "v0": float(v0),
                                        "initial_state": "fitted (linear least squares)"}
    if model.kind == "forced":
        return _fit_state(model, record, y)
    return _fit_free_body(model, record, y)


def _fit_state(model: DriveModel, record: Record, y: np.ndarray):
    """Fit the initial state of a forced model with friction (not linear in it).

    Started from the linear fit of the same drive without its Coulomb and asymmetric terms.
    """
    linear = replace(model, linear=True,
                     body=replace(model.body, c_delta=0.0, fk_mean=0.0, fk_delta=0.0))
    _, first = simulate_model(linear, record)
    sx = max(float(np.std(y)), 1e-12)
    sv = max(sx * 2.0 * math.pi / max(record.duration, record.dt), 1e-12)
    sol = least_squares(lambda q: _run(model, record, float(q[0]), float(q[1])) - y,
                        [first["x0"], first["v0"]], x_scale=[sx, sv])
    x0, v0 = (float(v) for v in sol.x)
    return _run(model, record, x0, v0), {"x0": x0, "v0": v0,
                                         "initial_state": "fitted (nonlinear least squares)"}


def _fit_free_body(model: DriveModel, record: Record, y: np.ndarray):
    """Simulate an input-driven body without spring or loop, its initial state fitted.

    Such a body's response is shift-invariant, ``y(x0) = y(0) + x0``, so x0 is the mean
    residual; v0 (and a friction map's inertia) are fitted by least squares. v0 matters only
    until viscous damping or sticking forgets it, so it is fitted on a leading window of
    five viscous time constants ``J/c``.
    """
    _, v0 = _first_state(record)
    fit_J = model.summary.get("J_source") == "regressed from the record"
    J0 = model.body.J
    c_low = model.body.c_mean - abs(model.body.c_delta)
    window = record.n
    if not fit_J and c_low > 0:
        window = min(record.n, max(200, int(5.0 * J0 / c_low * record.fs)))
    yw = y[:window]
    sx = max(float(np.std(y)), 1e-12)
    sv = max(abs(v0), sx * record.fs / max(record.n, 1), 1e-12)

    def with_inertia(J: float) -> DriveModel:
        return replace(model, body=replace(model.body, J=float(J)))

    def residual(q):
        m = with_inertia(q[1]) if fit_J else model
        r = _run(m, record, 0.0, float(q[0]), n=window) - yw
        return r - np.mean(r)

    # the first samples' velocity is only as good as their noise, and a regressed inertia is
    # biased low by the noise of the acceleration (errors in variables): a short output-
    # error refit removes both
    start, scale = [v0] + [J0] * fit_J, [sv] + [J0] * fit_J
    sol = least_squares(residual, start, x_scale=scale, max_nfev=30, diff_step=1e-6,
                        xtol=1e-6, ftol=1e-8,
                        bounds=([-np.inf] + [1e-6 * J0] * fit_J, [np.inf] * (1 + fit_J)))
    v0 = float(sol.x[0])
    state: dict[str, Any] = {"initial_state": "fitted (x0 by the mean residual, v0 by least "
                                               "squares from the first samples' slope)"}
    if fit_J:
        model = with_inertia(sol.x[1])
        state.update(J=float(sol.x[1]), J_source="fitted to the record (output error)")
    free = _run(model, record, 0.0, v0)
    x0 = float(np.mean(y - free))
    state.update(x0=x0, v0=v0)
    return free + x0, state
