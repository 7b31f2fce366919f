r"""Friction and backlash of each feed axis from a circular contour test (thesis §6.1).

The record of a circle test on a CNC (``driveid simulate contour`` writes the same columns)
holds, per axis ``a`` of the plane, the reference ``a_ref``, the table position ``a`` (linear
scale or ball bar), the motor encoder position ``a_motor`` and the controller command
``u_a``. Two sound, cheap estimators read it:

* **Friction by inverse-model least squares on the command.** While an axis moves (speed
  above ``min_speed_fraction`` of the feed, which drops the reversal transients: the table
  sticking, the motor crossing the gap) the command balances the rigid-body equation of
  motion (2.136, 2.155 with ``K = 0``)

  .. math:: u = M \ddot x + c_{mean} \dot x + f_{k,mean}\,\mathrm{sgn}(\dot x) + f_{k,delta}

  which is linear in ``M, c_mean, fk_mean, fk_delta``:
  :func:`~driveid.identify.friction.idim.estimate_idim` (zero-phase filtered position, central
  differences, decimation, ordinary least squares) gives them with the standard errors of
  ``σ²(WᵀW)⁻¹``. On a circle ``ẍ``, ``ẋ`` and ``sgn(ẋ)`` are orthogonal over a turn, so the
  four are well conditioned. The command is what the controller computed, so measurement
  noise on it is independent of the regressors (no closed-loop bias; the position noise
  enters ``ẍ`` only through the filter). Whiteness of the residual is tested
  (:func:`driveid.validate.whiteness`); the standard errors assume it.
* **Backlash from the two encoders.** In contact the motor leads the table by
  ``gap_plus + F/k`` moving forward and lags by ``gap_minus + F/k`` moving back (2.27-2.29,
  ``F`` the force the screw transmits, ``k`` the contact stiffness of the config), so the
  lost motion ``gap = gap_plus + gap_minus`` is the difference of the mean of
  ``x_motor - x - F/k`` over the two directions. ``F`` is taken as the identified friction
  (the friction sits behind the backlash, on the guides, as in a feed drive); the share
  that acts before it is unknown, so a uniform share in [0, 1] of the wind-up ``2 fk/k``
  enters the standard error (GUM type B) besides the AR(1)-corrected statistical one.

A ball-bar record (time and radial deviation only) holds no command and no motor position:
viscous friction and the friction asymmetry leave almost no radial trace, so only each
axis's ``fk_mean`` and gap are fitted, by output error through the simulated loop
(:func:`driveid.identify.contour.ballbar.estimate_ball_bar`), the rest taken from the config
and reported as given, with a warning that says so.

Validation simulates the identified axes (friction on the table, the gap split evenly) over
the same path and compares the radial deviation with the measured one; the compensation
preview simulates them again with the identified friction feed-forward and backlash offset
(and with the friction 20 % low and high).

References
----------
.. [1] J. A. de Marchi, "Modeling of dynamic friction, impact backlash and elastic
       compliance nonlinearities in machine tools", PhD thesis, RPI, 1998, §2.1.3, §6.1.
.. [2] M. Janot, M. Gautier, M. Brunot, "Data set and reference models of EMPS", Nonlinear
       System Identification Benchmarks, 2019.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from driveid.errors import IdentificationError, ParameterError, RecordError
from driveid.identify.contour.ballbar import identified_config
from driveid.identify.core.estimate import Estimate, Parameter, inputs_of
from driveid.sim.contour import AxisCompensation, contour_metrics, simulate_contour
from driveid.sim.contour_config import ContourConfig
from driveid.sim.drive_types import BacklashLink, ShaftLink

__all__ = ["ContourRecord", "compensation_from_estimate", "estimate_contour",
           "identified_config", "read_contour_record"]

_FRICTION = {"M": ("J", "kg"), "Fv": ("c_mean", "N·s/m"), "Fc": ("fk_mean", "N"),
             "offset": ("fk_delta", "N")}


@dataclass(frozen=True)
class ContourRecord:
    """The channels of a circle test, in SI units, on one time base.

    Attributes
    ----------
    t : ndarray, shape (n,)
        Times [s] from the start of the path.
    reference, position, motor, command : dict of str to ndarray, shape (n,)
        Per axis name: reference [m], table position [m], motor encoder position [m],
        controller command [N]; ``motor`` and ``command`` may lack an axis.
    radial : ndarray, shape (n,) or None
        Radial deviation [m] of a ball-bar record (then the dicts may be empty).
    meta : dict
        Provenance (``source``, ``inputs``).
    """

    t: np.ndarray
    reference: Mapping[str, np.ndarray]
    position: Mapping[str, np.ndarray]
    motor: Mapping[str, np.ndarray] = dataclasses.field(default_factory=dict)
    command: Mapping[str, np.ndarray] = dataclasses.field(default_factory=dict)
    radial: np.ndarray | None = None
    meta: Mapping[str, Any] = dataclasses.field(default_factory=dict)

    @classmethod
    def from_columns(cls, columns: Mapping[str, np.ndarray], axes: Sequence[str] = ("x", "y"),
                     meta: Mapping[str, Any] | None = None) -> ContourRecord:
        """Build a record from named columns (``t``, ``x_ref``, ``x``, ``x_motor``, ``u_x`` ...).

        Parameters
        ----------
        columns : mapping of str to ndarray, shape (n,)
            As written by ``driveid simulate contour`` (``ContourResult.columns``); a
            ball-bar record has ``t`` and ``dr`` [m].
        axes : sequence of str
            The axes to take.
        meta : mapping, optional
            Provenance.

        Returns
        -------
        ContourRecord
            The record.
        """
        def take(fmt: str) -> dict[str, np.ndarray]:
            return {a: np.asarray(columns[fmt.format(a)], float) for a in axes
                    if fmt.format(a) in columns}

        radial = columns.get("dr")
        return cls(t=np.asarray(columns["t"], float), reference=take("{}_ref"),
                   position=take("{}"), motor=take("{}_motor"), command=take("u_{}"),
                   radial=None if radial is None else np.asarray(radial, float),
                   meta=dict(meta or {}))


def read_contour_record(path: str | Path, axes: Sequence[str] = ("x", "y"),
                        **read_kwargs: Any) -> ContourRecord:
    """Read a circle-test file through :func:`driveid.io.read_record`, channel by channel.

    Parameters
    ----------
    path : str or Path
        The file (any format the reading layer reads) with columns ``t``, ``<a>_ref``,
        ``<a>``, and where recorded ``<a>_motor`` and ``u_<a>`` per axis; or a ball-bar
        record ``t``, ``dr``.
    axes : sequence of str
        The axes of the plane.
    **read_kwargs
        Reading options of :func:`driveid.io.read_record` (``fs``, ``window``,
        ``max_jitter``, ``scale``, ``units`` ...), except ``columns``.

    Returns
    -------
    ContourRecord
        The channels in SI units.

    Raises
    ------
    RecordError
        If a reference or position column is missing (and the file is no ball-bar record).
    """
    from driveid.io import read_record

    read_kwargs = {k: v for k, v in read_kwargs.items() if k != "columns"}

    def channel(x: str, u: str | None = None):
        cols = {"x": x, "v": "none", "u": u or "none"}
        return read_record(path, columns=cols, **read_kwargs)

    columns: dict[str, np.ndarray] = {}
    try:
        first = channel(f"{axes[0]}_ref")
    except (RecordError, ValueError, KeyError) as exc:
        try:
            ball = channel("dr")
        except (RecordError, ValueError, KeyError):
            raise RecordError(f"a contour record needs the columns t, {axes[0]}_ref, "
                              f"{axes[0]}, ... (or t, dr for a ball-bar record); reading "
                              f"{Path(path).name} failed: {exc}") from None
        return ContourRecord(t=ball.t, reference={}, position={}, radial=ball.x,
                             meta={"source": str(path), "inputs": inputs_of([ball])})
    columns["t"] = first.t
    inputs = inputs_of([first])
    for a in axes:
        ref = channel(f"{a}_ref")
        columns[f"{a}_ref"] = ref.x
        for name, u in ((a, f"u_{a}"), (a, None)):
            try:
                rec = channel(name, u)
            except (RecordError, ValueError, KeyError):
                if u is None:
                    raise
                continue
            columns[a] = rec.x
            if rec.u is not None:
                columns[f"u_{a}"] = rec.u
            break
        try:
            columns[f"{a}_motor"] = channel(f"{a}_motor").x
        except (RecordError, ValueError, KeyError):
            pass
    return ContourRecord.from_columns(columns, axes, meta={"source": str(path),
                                                           "inputs": inputs})


def _link_stiffness(axis) -> float:
    """Stiffness [N/m] of the links between the actuated body and the table (in series)."""
    lo, hi = sorted((axis.controller.body, axis.table))
    compliance = 0.0
    for ln in axis.drive.links[lo:hi]:
        if isinstance(ln, (BacklashLink, ShaftLink)) and ln.k > 0:
            compliance += 1.0 / ln.k
    return math.inf if compliance == 0.0 else 1.0 / compliance


def _direction_mean(d: np.ndarray, mask: np.ndarray) -> tuple[float, float]:
    """Mean and its standard error, the variance inflated for AR(1) correlation."""
    x = d[mask]
    n = x.size
    if n < 10:
        raise IdentificationError(f"the lost motion needs at least 10 samples moving in each "
                                  f"direction above the speed threshold; got {n}; record a "
                                  "whole revolution")
    e = x - x.mean()
    rho = float(e[1:] @ e[:-1] / max(e @ e, 1e-300))
    rho = min(max(rho, 0.0), 0.99)
    n_eff = n * (1 - rho) / (1 + rho)
    return float(x.mean()), float(np.std(x, ddof=1) / math.sqrt(max(n_eff, 1.0)))


def _axis_friction(rec, name: str, config: ContourConfig, speed: float, cutoff_hz: float,
                   decimate: int, held: bool) -> tuple[Estimate, dict]:
    from driveid.identify.friction.idim import estimate_idim
    from driveid.io.record import Record

    t, x, u = rec.t, rec.position[name], np.asarray(rec.command[name], float)
    if held:
        # a command held over [t_k, t_k+1) (zero-order hold) acts on the motion of the
        # middle of its period: regress it on the position at t_k + T/2
        t, x, u = 0.5 * (t[1:] + t[:-1]), 0.5 * (x[1:] + x[:-1]), u[:-1]
    record = Record(t=t, x=x, u=u, meta={"units": {"x": "m", "u": "N"},
                                         "source": f"contour axis {name}"}, max_jitter=None)
    from driveid.identify.friction.idim import IdimRecordTooShort

    try:
        est = estimate_idim(record, model="symmetric", cutoff_hz=cutoff_hz, decimate=decimate,
                            edge=max(5, int(0.05 * t.size / decimate)), min_speed=speed,
                            sensitivity=False)
    except IdimRecordTooShort as exc:  # the decimation here is not a user's option
        raise RecordError(
            f"axis {name}: the circle gave {t.size} samples, too few for IDIM after dropping "
            f"{exc.dropped} edge samples and decimating by {exc.decimate} (need >= "
            f"{exc.need}; got {exc.got}): record the whole circle, and check that the "
            "config's path matches the record"
        ) from None
    return est, {"force": np.asarray(est.data_used["force"]),
                 "predicted": np.asarray(est.data_used["predicted"])}


def estimate_contour(record: ContourRecord, config: ContourConfig, *,
                     min_speed_fraction: float = 0.2, cutoff_hz: float | None = None,
                     decimate: int | None = None, validate: bool = True,
                     compensation: bool = True) -> Estimate:
    """Identify each axis's Coulomb and viscous friction and backlash from a circle test.

    Parameters
    ----------
    record : ContourRecord
        The circle test (:func:`read_contour_record`); time from the start of the path.
    config : ContourConfig
        The axes (masses, links, controllers) and the path the record followed.
    min_speed_fraction : float
        Samples slower than this fraction of the feed are left out [-], in (0, 1): the
        reversal transients (default 0.2: 11.5° either side of each reversal).
    cutoff_hz : float, optional
        Zero-phase low-pass of the position before differentiation [Hz]; default
        ``min(100, fs/10)``.
    decimate : int, optional
        Decimation of the regression rows [-], >= 1; default ``fs / (4 cutoff)`` (rows at
        four times the cut-off: less correlated residuals).
    validate : bool
        Simulate the identified axes over the path and compare the radial deviation.
    compensation : bool
        Also simulate them with the identified compensation (and friction ±20 %).

    Returns
    -------
    Estimate
        Per plane axis ``a``: ``a.fk_mean``, ``a.fk_delta`` [N], ``a.c_mean`` [N·s/m],
        ``a.J`` [kg] (the moving mass seen by the command), ``a.gap`` [m] (lost motion less
        the contact's elastic wind-up), each with its standard error; covariance
        (block-diagonal: the axes are independent). Diagnostics: per axis whiteness
        (``a.whiteness_p``), residual rms, the raw lost motion; ``validation`` (fit of
        the radial deviation [%], rms of the difference [m]); ``compensation`` (radial
        rms and peak without, with, and with the friction 20 % low and high).

    Raises
    ------
    IdentificationError
        If a ball-bar record (radial deviation only, fitted by
        :func:`~driveid.identify.contour.ballbar.estimate_ball_bar`) covers no constant-feed
        part or does not determine the parameters.
    RecordError
        If an axis lacks its reference, position or command column.
    ParameterError
        If a setting is out of range.

    Notes
    -----
    Friction: inverse-model least squares (EMPS, Janot et al. 2019) on the equation of
    motion (2.136) with the friction law (2.155); the gap: the two-encoder difference with
    the contact law (2.27-2.29). See the module docstring for why each is sound.

    Examples
    --------
    >>> from driveid.sim.contour_config import parse_contour_config
    >>> from driveid.sim.contour import simulate_contour
    >>> axis = {"body": [{"J": 50.0, "c_mean": 100.0, "fk_mean": 40.0}],
    ...         "controller": {"kp": 2e6, "kd": 1.5e4, "ki": 3e7, "rate": 1000.0}}
    >>> cfg = parse_contour_config({"x": axis, "y": axis, "path": {
    ...     "radius": 0.02, "feed": 0.05, "fs": 500.0}})
    >>> rec = ContourRecord.from_columns(simulate_contour(cfg).columns())
    >>> est = estimate_contour(rec, cfg, validate=False)
    >>> round(est.value("x.fk_mean"), 1), round(est.value("y.c_mean"))
    (40.0, 100)
    """
    if not 0 < min_speed_fraction < 1:
        raise ParameterError(f"min_speed_fraction must lie in (0, 1); got "
                             f"{min_speed_fraction}")
    if decimate is not None and (isinstance(decimate, bool) or not isinstance(decimate, int)
                                 or decimate < 1):
        raise ParameterError(f"decimate must be an integer >= 1; got {decimate!r}")
    path = config.path
    plane = path.axes
    if record.radial is not None and not record.command:
        from driveid.identify.contour.ballbar import estimate_ball_bar

        return estimate_ball_bar(record, config)
    for a in plane:
        for kind, chans in (("reference", record.reference), ("position", record.position),
                            ("command", record.command)):
            if a not in chans:
                col = {"reference": f"{a}_ref", "position": a, "command": f"u_{a}"}[kind]
                raise RecordError(f"the contour record lacks the {kind} of axis {a} (column "
                                  f"{col}); the friction regression needs it")
    # the references' own radius (an algebraic circle fit, any centre, any arc)
    rx, ry = (np.asarray(record.reference[a], float) for a in plane)
    finite = np.isfinite(rx) & np.isfinite(ry)
    rx, ry = rx[finite], ry[finite]
    A = np.column_stack([2 * rx, 2 * ry, np.ones_like(rx)])
    (cx, cy, c0), *_ = np.linalg.lstsq(A, rx**2 + ry**2, rcond=None)
    measured = float(math.sqrt(max(c0 + cx**2 + cy**2, 0.0)))
    if not 0.8 * path.radius <= measured <= 1.25 * path.radius:
        # a 1 nm config radius on a 5 cm record said "got 0 samples ... record a whole
        # revolution" (fifth hostile campaign)
        raise IdentificationError(
            f"the record's circle has a radius of {measured:.4g} m (a circle fitted to its "
            f"references) but the config's [path] radius is {path.radius:.4g} m: pass the "
            "config the record was run with (--config)")
    t = np.asarray(record.t, float)
    fs = 1.0 / float(np.median(np.diff(t)))
    cutoff = min(50.0, fs / 20.0) if cutoff_hz is None else float(cutoff_hz)
    if decimate is None:
        decimate = max(1, int(fs / (4.0 * cutoff)))
    speed = min_speed_fraction * path.feed
    params: dict[str, Parameter] = {}
    diagnostics: dict[str, Any] = {"plane": path.plane, "radius": path.radius,
                                   "feed": path.feed, "min_speed": speed, "cutoff_hz": cutoff,
                                   "decimate": decimate, "fs": fs}
    warnings: list[str] = []
    names, blocks = [], []
    data_used: dict[str, Any] = {"t": t}
    from driveid.validate import whiteness

    for a in plane:
        rate = config.axes[a].controller.rate
        held = abs(rate - fs) < 1e-6 * fs  # one recorded command per control period
        est, res = _axis_friction(record, a, config, speed, cutoff, decimate, held)
        # the residual is correlated (contact dynamics, the held command): inflate the
        # least-squares covariance by the AR(1) variance factor of its lag-1 correlation
        rho = min(max(float(est.diagnostics.get("residual_lag1", 0.0)), 0.0), 0.95)
        inflate = (1.0 + rho) / (1.0 - rho)
        for src, (dst, unit) in _FRICTION.items():
            p = est[src]
            params[f"{a}.{dst}"] = Parameter(p.value, p.stderr * math.sqrt(inflate), unit)
        cov_names = [f"{a}.{_FRICTION[n][0]}" for n in est.covariance["names"]]
        names += cov_names
        blocks.append(inflate * np.asarray(est.covariance["matrix"], float))
        diagnostics[f"{a}.residual_lag1"] = rho
        resid = res["force"] - res["predicted"]
        white = whiteness(resid)
        diagnostics[f"{a}.whiteness_p"] = white["p_value"]
        diagnostics[f"{a}.residual_rms"] = float(np.sqrt(np.mean(resid**2)))
        diagnostics[f"{a}.rows"] = int(resid.size)
        if not white["white"]:
            warnings.append(f"axis {a}: the friction-regression residual is not white "
                            f"(Ljung-Box p = {white['p_value']:.2g}); its standard errors are "
                            f"inflated {math.sqrt(inflate):.2g}x for the lag-1 correlation "
                            "but may still be too small")
        gap, gap_se, lost = _gap(record, a, config, params, speed)
        params[f"{a}.gap"] = Parameter(gap, gap_se, "m")
        if math.isfinite(gap_se):
            names.append(f"{a}.gap")
            blocks.append(np.array([[gap_se**2]]))
        diagnostics[f"{a}.lost_motion"] = lost
        if not math.isfinite(gap):
            warnings.append(f"axis {a}: no motor encoder column {a}_motor: the backlash gap "
                            "is not identified (the table position alone mixes it with the "
                            "loop's reversal transient); record the motor position")
    from scipy.linalg import block_diag

    covariance = {"names": names, "matrix": block_diag(*blocks)}
    estimate = Estimate(method="contour-idim", params=params, data_used=data_used,
                        diagnostics=diagnostics, warnings=tuple(warnings),
                        covariance=covariance,
                        inputs=tuple(record.meta.get("inputs", ())))
    if validate or compensation:
        estimate = _simulate_identified(estimate, record, config, validate, compensation)
    return estimate


def _gap(record, a: str, config: ContourConfig, params, speed: float):
    if a not in record.motor:
        return math.nan, math.nan, math.nan
    from driveid.sim.contour import circle_reference

    t = np.asarray(record.t, float)
    path = config.path
    ref = circle_reference(path, t)
    v = ref["v1"] if a == path.axes[0] else ref["v2"]
    steady = (t >= path.ramp) & (t <= path.ramp + path.constant_feed)
    acc = ref["a1"] if a == path.axes[0] else ref["a2"]
    axis = config.axes[a]
    k = _link_stiffness(axis)
    s = np.sign(v)
    fk = params[f"{a}.fk_mean"].value
    # the screw's force: the table's inertia and the friction (taken as behind the backlash)
    force = (axis.drive.bodies[axis.table].J * acc + params[f"{a}.c_mean"].value * v
             + fk * s + params[f"{a}.fk_delta"].value)
    sign = 1.0 if axis.controller.body < axis.table else -1.0
    d = sign * (record.motor[a] - record.position[a]) - force / k
    # where the screw clearly pushes (pulls): at high centripetal acceleration the table
    # decelerates on its own friction and the contact changes sides before the reversal
    margin = 0.25 * abs(fk)
    plus, se_plus = _direction_mean(d, steady & (v > speed) & (force > margin))
    minus, se_minus = _direction_mean(d, steady & (v < -speed) & (force < -margin))
    wind_up = 2.0 * params[f"{a}.fk_mean"].value / k
    # which share of the friction acts before the backlash is unknown: a uniform share in
    # [0, 1] of the wind-up (GUM type B) joins the statistical error
    stderr = math.sqrt(se_plus**2 + se_minus**2 + (wind_up / math.sqrt(12.0)) ** 2)
    return plus - minus, stderr, plus - minus + wind_up


def compensation_from_estimate(estimate: Estimate | Mapping[str, Any], *,
                               friction: float = 1.0,
                               config: ContourConfig | None = None
                               ) -> dict[str, AxisCompensation]:
    """Per-axis compensation from a contour estimate (or its ``--json`` dict).

    Parameters
    ----------
    estimate : Estimate or mapping
        An :func:`estimate_contour` result, or its ``driveid-result/1`` dict.
    friction : float
        Factor on the friction terms [-] (0.8 and 1.2: the model 20 % wrong).
    config : ContourConfig, optional
        The axes: the mass behind each backlash (the table) then times the backlash
        offset by the predicted screw force (:class:`~driveid.sim.contour.AxisCompensation`).

    Returns
    -------
    dict of str to AxisCompensation
        One per axis found (``x.fk_mean`` ...); a gap that was not identified is 0.

    Raises
    ------
    ParameterError
        If the estimate holds no contour parameters.
    """
    if isinstance(estimate, Mapping):
        estimate = Estimate.from_dict(estimate)
    axes = sorted({n.split(".")[0] for n in estimate.params if n.endswith(".fk_mean")})
    if not axes:
        raise ParameterError(f"the estimate holds no per-axis friction (x.fk_mean, ...); pass "
                             f"the result of 'driveid identify contour'; got method "
                             f"{estimate.method!r} with {sorted(estimate.params)}")
    out = {}
    for a in axes:
        def val(name: str, a: str = a) -> float:
            key = f"{a}.{name}"
            value = estimate.value(key) if key in estimate else 0.0
            return value if math.isfinite(value) else 0.0

        table_mass = 0.0
        if config is not None and a in config.axes:
            axis = config.axes[a]
            table_mass = axis.drive.bodies[axis.table].J
        out[a] = AxisCompensation(fk_mean=val("fk_mean"), fk_delta=val("fk_delta"),
                                  c_mean=val("c_mean"), gap=val("gap"),
                                  table_mass=table_mass).scaled(friction)
    return out


def _simulate_identified(estimate: Estimate, record, config, validate: bool,
                         compensation: bool) -> Estimate:
    path = config.path
    model = identified_config(estimate, config)
    p1, p2 = (record.position[a] for a in path.axes)
    t = np.asarray(record.t, float)
    measured = contour_metrics(t, p1, p2, path)
    diagnostics = dict(estimate.diagnostics)
    data_used = dict(estimate.data_used)
    data_used["radial_measured"] = measured["radial"]
    data_used["angle"] = measured["angle"]
    data_used["steady"] = measured["steady"]
    diagnostics["measured"] = {"rms": measured["rms"], "peak": measured["peak"],
                               "glitches": measured["glitches"],
                               "reversal_spikes": measured["reversals"]}
    if validate:
        sim = simulate_contour(model)
        n = min(sim.t.size, t.size)
        dm = measured["radial"][:n]
        ds = sim.metrics["radial"][:n]
        steady = measured["steady"][:n]
        diff = dm[steady] - ds[steady]
        spread = dm[steady] - dm[steady].mean()
        diagnostics["validation"] = {
            "radial_fit_pct": float(100.0 * (1.0 - np.linalg.norm(diff)
                                             / max(np.linalg.norm(spread), 1e-300))),
            "radial_difference_rms": float(np.sqrt(np.mean(diff**2))),
            "simulated_peak": sim.metrics["peak"]}
        data_used["radial_simulated"] = ds
    if compensation:
        preview = {}
        for label, factor in (("without", None), ("with", 1.0), ("friction_low", 0.8),
                              ("friction_high", 1.2)):
            comp = None if factor is None else compensation_from_estimate(
                estimate, friction=factor, config=config)
            res = simulate_contour(model, compensation=comp)
            preview[label] = {"rms": res.metrics["rms"], "peak": res.metrics["peak"]}
            if label in ("without", "with"):
                data_used[f"radial_model_{label}"] = res.metrics["radial"]
                data_used[f"angle_model_{label}"] = res.metrics["angle"]
        preview["peak_ratio"] = preview["without"]["peak"] / max(preview["with"]["peak"],
                                                                  1e-300)
        diagnostics["compensation"] = preview
    return dataclasses.replace(estimate, diagnostics=diagnostics, data_used=data_used)
