r"""Lumped multi-body drive: inertias in a chain with friction, backlash, shafts and PD feedback.

The drive of thesis §2.1.4 (Fig. 2.9), §3.2.2 and App. B.2 is a chain of bodies (motor,
arm, tool ...) joined by links. Body ``i`` obeys

.. math:: J_i \ddot x_i = u_i + \tau_{fb}\,[i = b] - K_i x_i - F_{link} - F_{fric,i}

with, while moving in direction ``s = sgn(x')``, ``F_fric = (c_mean + c_delta·s) x' +
fk_mean·s + fk_delta`` (thesis 2.155, the sign conventions of ``shared/DESIGN.md``; an optional
ripple ``A sin(2π x/P + φ)`` adds to ``fk_mean``, see :mod:`driveid.sim.drive_types`), and true
sticking: a body at rest stays stuck while the force the other elements apply lies in
``[fs_delta - fs_mean, fs_delta + fs_mean]`` (2.137, 2.138; Karnopp-like switching, the
breakaway test runs on the applied force, not on a velocity band).

Links between consecutive bodies ``j`` and ``j + 1`` (force ``f`` pushes ``j + 1`` forward
and ``j`` back; ``δ = x_j - x_{j+1}``):

* :class:`ShaftLink` — compliant shaft ``f = k δ + c δ'`` (§2.1.3);
* :class:`BacklashLink` — deadzone ``-gap_minus < δ < gap_plus`` with a Kelvin–Voigt
  contact beyond it (2.27-2.29), without tension by default (``driveid.models.backlash``);
  or, with ``contact="restitution"``, an instantaneous Newton impact at the gap edge
  (``v_rel' = -e v_rel``, momentum kept, loss ``½ μ (1 - e²) v_rel²``). Impacts slower
  than ``rest_velocity`` close the compliant contact instead (resting contact), which
  ends the Zeno sequence of ever smaller bounces under a steady push.

Feedback, one of:

* :class:`PDFeedback`: ``τ = P (r - x_b(t - Δ)) - D x_b'(t - Δ)`` with a pure delay read
  from the history of past states (cubic Hermite interpolation, not a Padé approximation),
  saturation at ``±saturation`` and a safety abort when ``|τ|`` before saturation exceeds
  ``abort_limit``;
* a controller callback ``controller(t, x, v) -> torque`` of :func:`simulate_drive`,
  sampled at ``control_rate`` with a zero-order hold (as a digital controller is), an
  optional transport delay of whole periods, saturation and abort: the compiled kernel
  runs one control period at a time with the held torque.

The parameter and result types live in :mod:`driveid.sim.drive_types` (re-exported here);
this module chooses an engine: the exact closed form (:mod:`driveid.sim.free_decay_batch`),
the event-located RK4 (:mod:`driveid.sim._kernels`) or the smooth integrator.
:func:`driveid.sim.batch.simulate_drive_batch` runs many parameter sets in one compiled call
(Monte Carlo).
A body with dynamic (LuGre) friction, ``BodyParams.lugre``, or an electrical motor model,
``DriveParams.motor``, is simulated by the smooth integrator ``driveid.sim._smooth``
instead (:func:`simulate_drive` delegates).

Method: fixed-step classical Runge–Kutta (order 4) on a grid that divides the output
interval; every mode switch (velocity zero, breakaway, contact entry and exit) is located
inside the step by an Illinois secant on its event function and the step is split there,
so the integrator never steps across a discontinuity. The compiled loops are in
:mod:`driveid.sim._kernels` (numba, ``cache=True``).

References
----------
.. [1] J. A. de Marchi, "Modeling of dynamic friction, impact backlash and elastic
       compliance nonlinearities in machine tools", PhD thesis, RPI, 1998, §2.1.4, §3.2.2,
       App. B.2.
.. [2] D. Karnopp, "Computer simulation of stick-slip friction in mechanical dynamic
       systems", J. Dyn. Sys., Meas., Control 107 (1985) 100-103, doi:10.1115/1.3140698.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from driveid.errors import ParameterError, SimulationError
from driveid.sim import _kernels as _k
from driveid.sim._first_run import run_drive_kernel
from driveid.sim.drive_cost import (
    DEFAULT_MAX_STEPS,
    DriveCost,
    _highest_rate,
    _max_step,
    check_drive_cost,
    estimate_drive_cost,
)
from driveid.sim.drive_types import (
    BacklashLink,
    BodyParams,
    DriveParams,
    DriveResult,
    PDFeedback,
    ShaftLink,
    _input_grid,
    _require,
)

__all__ = [
    "BodyParams",
    "ShaftLink",
    "BacklashLink",
    "PDFeedback",
    "DriveParams",
    "DriveResult",
    "DriveCost",
    "DEFAULT_MAX_STEPS",
    "estimate_drive_cost",
    "check_drive_cost",
    "simulate_drive",
]


PAR_WIDTH = 23  # columns of the kernel's parameter rows (see _kernels._forces)
_STRIBECK_CODES = {None: _k.STRIBECK_NONE, "lorentzian": _k.STRIBECK_LORENTZIAN,
                   "bo_pavelescu": _k.STRIBECK_EXPONENTIAL}


def _body_row(b: BodyParams) -> list[float]:
    wavenumber = 2.0 * math.pi / b.ripple_period if b.has_ripple else 0.0
    v_s = 1.0 if b.v_s is None else b.v_s
    # columns 17-18 are the kernel's friction state (when stuck, rise at breakaway), 20-22
    # its velocity ring of the memory (first column, length, last step), all written there
    return [b.J, b.K, b.c_mean, b.c_delta, b.fk_mean, b.fk_delta,
            b.fs_delta - b.fs_mean, b.fs_delta + b.fs_mean,
            b.ripple_amplitude, wavenumber, b.ripple_phase,
            _STRIBECK_CODES[b.stribeck], v_s + b.v_s_delta, v_s - b.v_s_delta,
            b.stribeck_exponent, 0.0 if b.dwell_gamma is None else b.dwell_gamma,
            b.dwell_kappa, 0.0, 1.0, b.memory, 0.0, 0.0, 0.0]


def _link_row(ln) -> list[float]:
    if ln is None:
        row = [0.0] * 8
    elif isinstance(ln, ShaftLink):
        row = [_k.LINK_SHAFT, ln.k, ln.c, 0.0, 0.0, 0.0, 0.0, 0.0]
    elif ln.contact == "restitution":
        row = [_k.LINK_IMPACT, ln.k, ln.c, ln.gap_plus, ln.gap_minus, 0.0,
               float(ln.restitution), ln.rest_velocity]
    else:
        row = [_k.LINK_BACKLASH, ln.k, ln.c, ln.gap_plus, ln.gap_minus,
               float(ln.allow_tension), 0.0, 0.0]
    return row + [0.0] * (PAR_WIDTH - len(row))


def _feedback_row(fb: PDFeedback | None) -> list[float]:
    row = [0.0] * 6 if fb is None else [1.0, fb.body, fb.P, fb.D, fb.delay, fb.saturation]
    return row + [0.0] * (PAR_WIDTH - len(row))



def simulate_drive(
    params: DriveParams,
    *,
    duration: float,
    fs: float = 1000.0,
    x0=None,
    v0=None,
    torque=None,
    reference=None,
    max_step: float | None = None,
    rtol: float | None = None,
    max_events_per_step: int = 200,
    method: str = "auto",
    controller=None,
    control_rate: float | None = None,
    controller_delay: int = 0,
    controller_body: int = 0,
    saturation: float = math.inf,
    abort_limit: float = math.inf,
    max_steps: int | None = DEFAULT_MAX_STEPS,
) -> DriveResult:
    """Simulate the lumped drive with friction, backlash, shafts, locks and feedback.

    Parameters
    ----------
    params : DriveParams
        The drive.
    duration : float
        Simulated time [s]; > 0.
    fs : float
        Output sampling rate [Hz]; > 0.
    x0, v0 : array_like, shape (n_bodies,), optional
        Initial positions [rad] and velocities [rad/s] (default 0). Locked bodies must start
        at rest.
    torque : array_like, optional
        External torque on each body [N·m]: shape (n_bodies,) constant, or
        (n_bodies, n) sampled at the output times and interpolated linearly. With
        ``params.motor`` the motor body's entry is an amplifier command [V or A of
        demand], added to the feedback output before the amplifier.
    reference : array_like, shape (n,), optional
        Feedback reference [rad] at the output times, replacing ``feedback.reference``.
    max_step : float, optional
        RK4 step [s] (the grid step); default ``0.2/rate`` for the fastest rate of the drive
        (and no larger than the delay or the output interval).
    rtol : float, optional
        Step-size control, relative [-], e.g. ``1e-9``: where the embedded error estimate of
        a step is below ``rtol`` times the largest position (velocity) magnitude so far, the
        integrator strides over several grid steps at once (up to the output interval, the
        stability limit ``2.5/rate`` and short of the delay), and retakes a stride in grid
        steps if its estimate fails. A run that settles then costs little (the three-body
        drive of ``benchmarks/bench_drive.py``, rtol 1e-9: about 3.5x faster at the same
        error). Default ``None``: every grid step, as the thesis's fixed-step RK4. Strides
        check the event functions at their end, as steps do: a contact shorter than a
        stride can be missed, so keep ``None`` where brief touches matter. Not with a
        ``controller``.
    max_events_per_step : int
        Guard against chattering (Zeno) switching inside one step.
    method : {"auto", "rk4", "exact"}
        ``"exact"``: the piecewise closed form of
        :func:`driveid.sim.batch.simulate_free_decay_batch`, for one free body with
        ``K > 0``, no feedback and a constant torque; ``"rk4"``: the event-located
        integrator; ``"auto"`` (default) takes ``"exact"`` where it applies.
    controller : callable, optional
        Sampled-data controller ``controller(t, x, v) -> torque`` called every
        ``1/control_rate`` s with the time [s] and copies of the sampled positions [rad] and
        velocities [rad/s], shape (n_bodies,); it returns a scalar torque [N·m] on
        ``controller_body`` or an array (n_bodies,). Excludes ``params.feedback``.
    control_rate : float, optional
        Controller sampling rate [Hz]; required with ``controller``; ``fs/control_rate`` or
        ``control_rate/fs`` must be an integer.
    controller_delay : int
        Transport delay of the controller in whole control periods [-], >= 0: the command
        computed at sample k acts from sample k + controller_delay on (zero before).
    controller_body : int
        Body that receives a scalar controller torque (default 0, the motor).
    saturation : float
        Controller command limit [N·m], > 0 (default inf).
    abort_limit : float
        Safety abort when ``|torque|`` from the controller, before saturation, exceeds it
        [N·m], > 0 (default inf).
    max_steps : int or None
        Budget of RK4 grid steps [-] (default :data:`DEFAULT_MAX_STEPS`, 1e9): a run that
        needs more (a stiff contact or shaft forces a short step, see
        :func:`estimate_drive_cost`) is refused before it starts; ``None``: no budget. A
        run whose result would not fit in memory is refused whatever the budget.

    Returns
    -------
    DriveResult
        Positions, velocities, command, energy balance, switch and impact counts, abort.

    Raises
    ------
    ParameterError
        If an argument is out of range or of the wrong shape, or the run would need more
        memory than is available or more steps than ``max_steps``.
    SimulationError
        If more than ``max_events_per_step`` switches happen inside one step, or the
        controller returns a non-finite torque.

    Notes
    -----
    Energy balance closed by the result: ``initial + input = kinetic + potential +
    dissipated``, computed when ``result.energy`` is first read (the event-located RK4 then
    runs once more, with the three energy integrals it otherwise skips: about the cost of
    the simulation again, the same trajectory to the bit); a contact that opens (no-tension
    rule) with residual penetration ``δ`` loses its stored ``k δ²/2``, booked as
    dissipated, and so is the loss of restitution impacts.

    The controller callback is sampled with a zero-order hold, as on real hardware (a
    digital controller reads the encoders, computes, and holds its DAC output until the
    next tick): the command is constant over each control period, so the compiled kernel
    integrates every period without Python in its loop, and a continuous callback would
    need a Python call per RK4 stage. A ZOH of period T acts like a delay of about T/2:
    to compare with continuous feedback, choose ``control_rate`` well above the loop's
    bandwidth.

    A body with ``lugre`` friction or a ``params.motor`` runs on the smooth integrator
    ``driveid.sim._smooth.simulate_smooth`` (with ``duration``, ``fs``, ``x0``, ``v0``,
    ``torque``, ``reference``; not combined with ``method="exact"``, a controller or a
    restitution contact).

    Examples
    --------
    >>> drive = DriveParams(bodies=(BodyParams(J=1.0, K=16.0, c_mean=0.3, fk_mean=0.07),))
    >>> rk4 = simulate_drive(drive, duration=1.0, x0=[1.0], method="rk4")
    >>> exact = simulate_drive(drive, duration=1.0, x0=[1.0], method="exact")
    >>> bool(abs(rk4.x - exact.x).max() < 1e-9), rk4.n_mode_switches
    (True, 1)
    >>> held = simulate_drive(drive, duration=1.0, x0=[1.0], controller=lambda t, x, v: 0.0,
    ...                       control_rate=100.0)
    >>> bool(abs(held.x - rk4.x).max() < 1e-12)
    True
    """
    if not isinstance(params, DriveParams):
        raise ParameterError(f"params must be a DriveParams; got {type(params).__name__}")
    _require(method in ("auto", "rk4", "exact"), 'method must be "auto", "rk4" or "exact"',
             method)
    _require(max_steps is None or (isinstance(max_steps, int) and max_steps > 0),
             "max_steps must be a positive int (steps) or None", max_steps)
    # cost known before work (issue 28): fs = 1e9 or a contact of k = 1e15 on J = 1e-6 once
    # ran on silently for minutes
    varying = controller is not None or (torque is not None and np.ndim(torque) == 2)
    cost = estimate_drive_cost(params, duration=duration, fs=fs, max_step=max_step,
                               method="rk4" if varying else method)
    check_drive_cost(cost, duration=duration, max_steps=None if params.smooth else max_steps)
    if params.smooth:
        impact = any(isinstance(ln, BacklashLink) and ln.contact == "restitution"
                     for ln in params.links)
        if method == "exact" or controller is not None or impact:
            raise ParameterError(
                "LuGre friction and the motor model run on the smooth integrator, which "
                'does not take method="exact", a controller callback or a restitution '
                'contact; use method="auto", params.feedback, contact="viscoelastic"')
        from driveid.sim._smooth import simulate_smooth

        return simulate_smooth(params, duration=duration, fs=fs, x0=x0, v0=v0, torque=torque,
                               reference=reference)
    if controller is not None:
        _require(reference is None, "reference is for params.feedback; a controller "
                 "callback computes its own reference", "an array")
        _require(rtol is None, "rtol (strides) is not available with a controller callback, "
                 "which runs every step; leave rtol=None", rtol)
        return _simulate_controlled(
            params, duration, fs, x0, v0, torque, max_step, max_events_per_step, method,
            controller, control_rate, controller_delay, controller_body, saturation,
            abort_limit)
    _require(control_rate is None, "control_rate needs a controller callback", control_rate)
    run = _prepare(params, duration, fs, x0, v0, torque, reference, max_step,
                   max_events_per_step, rtol)
    nb, torque, fb = params.n_bodies, run["torque"], params.feedback
    exact_ok = (nb == 1 and not run["locked"][0] and params.bodies[0].K > 0 and fb is None
                and params.bodies[0].is_plain_coulomb
                and np.all(torque == torque[:, :1]))
    if method == "exact" and not exact_ok:
        raise ParameterError(
            'method="exact" needs one unlocked body with K > 0, no feedback, no friction '
            "ripple, Stribeck map or dwell and a constant torque; use method=\"rk4\"; got "
            f"{nb} bodies, "
            f"feedback={fb is not None}"
        )
    if method != "rk4" and exact_ok:
        return _simulate_exact(params, duration, fs, run["x0"], run["v0"],
                               float(torque[0, 0]))
    return _finish(params, run, *_run_kernel(run, max_events_per_step)[:8],
                   max_events_per_step)


def _run_kernel(run: dict, max_events: int, energy: bool = False) -> tuple:
    """One fresh (not resumed) run of the event-located RK4 kernel on ``_prepare``'s inputs.

    Without ``energy`` the kernel integrates positions and velocities only (a sixth less
    work a step) and the energy row block is returned as None; :func:`_finish` then runs
    the kernel again with the energy integrals when the balance is first read.
    """
    nb = run["x0"].size
    y0 = run["y0"] if energy else run["y0"][:2 * nb].copy()
    args = (y0, run["modes0"], run["par"], run["inp"], run["abort_limit"], run["fs"],
            run["n_out"], run["n_sub"], max_events, False, np.zeros(2), run["rtol"],
            run["max_stride"])
    # compiled, or interpreted while the kernel is not compiled yet (a first short run);
    # the energy pass repeats the first pass's choice (the same trajectory, bitwise)
    out, run["interpreted"] = run_drive_kernel(args, (run["n_out"] - 1) * run["n_sub"] * nb,
                                               interpreted=run.get("interpreted"))
    return out if energy else (*out[:3], None, *out[4:])


def _prepare(params, duration, fs, x0, v0, torque, reference, max_step, max_events,
             rtol=None, full_grid: bool = False) -> dict:
    """Validate the run and build the kernel's inputs (see :func:`_k.drive_kernel`).

    ``run["torque"]`` has one column for a constant torque and reference unless
    ``full_grid`` (the controller path slices it per control period).
    """
    _require(isinstance(duration, (int, float)) and 0 < duration < math.inf,
             "duration must be positive and finite [s]", duration)
    _require(isinstance(fs, (int, float)) and 0 < fs < math.inf,
             "fs must be positive; pass the output sampling rate in Hz", fs)
    _require(isinstance(max_events, int) and max_events > 0,
             "max_events_per_step must be a positive int", max_events)
    nb = params.n_bodies
    n_out = int(math.floor(duration * fs + 1e-9)) + 1
    x0 = _input_grid(x0, "x0", None, nb)
    v0 = _input_grid(v0, "v0", None, nb)
    locked = np.array([b.locked for b in params.bodies])
    if np.any(v0[locked] != 0.0):
        raise ParameterError(f"locked bodies must start at rest (v0 = 0); got v0={v0.tolist()}")
    fb = params.feedback
    if reference is None:
        reference = 0.0 if fb is None else fb.reference
    # constant inputs go to the kernel as one column (it holds values beyond the ends):
    # no (n_bodies + 1, n) grid to build for the common free or step run
    constant = (not full_grid and np.ndim(reference) == 0
                and (torque is None or np.ndim(torque) == 0 or np.shape(torque) == (nb,)))
    n_in = 1 if constant else n_out
    torque = _input_grid(torque, "torque", nb, n_in)
    reference = _input_grid(reference, "reference", None, n_in)[None, :]
    rate = _highest_rate(params)
    max_step = _max_step(params, fs, rate, max_step)
    _require(rtol is None or (isinstance(rtol, (int, float)) and 0 < rtol < 1),
             "rtol must be None (every step) or a relative tolerance in (0, 1), e.g. 1e-9",
             rtol)
    n_sub = max(1, math.ceil((1.0 / fs) / max_step - 1e-9))
    # a stride stays inside RK4's stability region for the fastest mode (|z| = 2.5 on the
    # imaginary axis: |R| = 0.51), so an unexcited stiff mode never grows
    max_stride = n_sub if rate == 0 else max(1, min(n_sub, int(2.5 / rate * fs * n_sub)))
    rows = [_body_row(b) for b in params.bodies]
    # a body whose friction is viscous alone: the sign of its velocity changes nothing
    free = np.array([not any(row[3:9]) for row in rows])
    rows += [_link_row(ln) for ln in params.links]
    rows.append(_feedback_row(fb))
    return {
        "t": np.arange(n_out) / fs, "n_out": n_out, "x0": x0, "v0": v0, "locked": locked,
        "torque": torque, "fs": float(fs), "max_step": max_step, "n_sub": n_sub,
        "rtol": 0.0 if rtol is None else float(rtol), "max_stride": max_stride,
        "par": np.array(rows, dtype=float),
        "inp": np.ascontiguousarray(np.vstack([torque, reference])),
        "y0": np.concatenate([x0, v0, np.zeros(3)]),
        "modes0": np.concatenate([np.where(locked, _k.LOCKED, np.where(free, _k.FREE, 1)),
                                  np.zeros(nb - 1)]).astype(np.int64),
        "abort_limit": math.inf if fb is None else float(fb.abort_limit),
    }


def _finish(params, run, x, v, cmd, e, counts, status, abort_index, abort_value,
            max_events) -> DriveResult:
    """Turn the kernel's outputs into a :class:`DriveResult` (or raise on chattering)."""
    h = 1.0 / (run["fs"] * run["n_sub"])
    if status == _k.TOO_MANY_EVENTS:
        raise SimulationError(
            f"more than max_events_per_step={max_events} mode switches in the step "
            f"at t={abort_index * h:.6g} s (chattering); add damping, reduce max_step or raise "
            "max_events_per_step"
        )
    aborted = status == _k.ABORTED
    reason = abort_time = None
    if aborted:
        abort_time = abort_index * h
        reason = (f"|command| = {abs(abort_value):.6g} N·m before saturation exceeded "
                  f"abort_limit={run['abort_limit']:g} N·m at t={abort_time:.6g} s")
    def balance() -> dict:
        # the kernel ran without the energy integrals: run it again with them (the same
        # trajectory: they do not feed back, and tests/sim checks it bitwise)
        rows = e if e is not None else _run_kernel(run, max_events, energy=True)[3]
        return _energy(params, x, v, rows, run["x0"], run["v0"])

    energy = _LazyEnergy(balance)
    return DriveResult(t=run["t"], x=x, v=v, command=cmd, energy=energy,
                       n_mode_switches=int(counts[0]), n_impacts=int(counts[1]),
                       aborted=aborted, abort_reason=reason, abort_time=abort_time,
                       params=params)


def _simulate_controlled(params, duration, fs, x0, v0, torque, max_step, max_events, method,
                         controller, control_rate, delay, body, saturation, abort_limit):
    """Sampled-data (ZOH) controller: one compiled kernel call per control period."""
    if params.feedback is not None:
        raise ParameterError("pass either params.feedback or a controller callback, not both; "
                             "set feedback=None to use the callback")
    _require(callable(controller), "controller must be callable as controller(t, x, v)",
             controller)
    _require(method != "exact", 'a controller needs method="rk4" or "auto"', method)
    memory = [i for i, b in enumerate(params.bodies) if b.memory > 0.0]
    _require(not memory, "frictional memory (BodyParams.memory) needs one uninterrupted run: "
             "a controller callback resumes the kernel every period and its velocity history "
             "would restart; use params.feedback (a PD loop) or memory = 0 on bodies",
             memory)
    _require(isinstance(control_rate, (int, float)) and 0 < control_rate < math.inf,
             "control_rate must be a positive rate [Hz] with a controller", control_rate)
    _require(isinstance(delay, int) and delay >= 0,
             "controller_delay must be a whole number of control periods >= 0", delay)
    _require(isinstance(body, int) and 0 <= body < params.n_bodies
             and not params.bodies[body].locked,
             "controller_body must index an unlocked body", body)
    for name, value in (("saturation", saturation), ("abort_limit", abort_limit)):
        _require(isinstance(value, (int, float)) and value > 0 and not math.isnan(value),
                 f"{name} must be positive [N·m] (inf: none)", value)
    run = _prepare(params, duration, fs, x0, v0, torque, None, max_step, max_events,
                   full_grid=True)
    hi, lo = max(fs, control_rate), min(fs, control_rate)
    ratio = round(hi / lo)
    if abs(hi / lo - ratio) > 1e-9 * ratio:
        raise ParameterError(
            f"fs/control_rate or control_rate/fs must be an integer; got fs={fs}, "
            f"control_rate={control_rate}; choose e.g. control_rate={fs}")
    r_out = ratio if control_rate > fs else 1  # fine samples per output sample
    r_c = 1 if control_rate > fs else ratio  # fine samples per control period
    fs_in = float(fs * r_out)
    nb, n_out = params.n_bodies, run["n_out"]
    n_fine = (n_out - 1) * r_out + 1
    n_sub = max(1, math.ceil((1.0 / fs_in) / run["max_step"] - 1e-9))
    torque = run["torque"]
    if r_out > 1:  # the kernel interpolates linearly: the finer grid keeps every knot
        tf = np.arange(n_fine) / fs_in
        torque = np.array([np.interp(tf, run["t"], row) for row in torque])
    x = np.full((nb, n_fine), np.nan)
    v = np.full((nb, n_fine), np.nan)
    e = np.full((6, n_fine), np.nan)
    cmd = np.full((nb, n_fine), np.nan)
    y = run["y0"].copy()
    modes = run["modes0"].copy()
    jump = np.zeros(2)
    counts = np.zeros(2, dtype=np.int64)
    queue = [np.zeros(nb)] * delay
    applied = np.zeros(nb)
    par = run["par"]
    vector = False
    status, abort_index, abort_value = _k.OK, -1, 0.0
    interpreted = None  # every period on the engine of the first (see _first_run)
    for k in range(math.ceil((n_fine - 1) / r_c)):
        s0 = k * r_c
        t_k = s0 / fs_in
        raw = np.asarray(controller(t_k, y[:nb].copy(), y[nb:2 * nb].copy()), dtype=float)
        if raw.shape not in ((), (nb,)):
            raise ParameterError(f"controller must return a scalar or shape ({nb},) torque "
                                 f"[N·m]; got shape {raw.shape} at t={t_k:.6g} s")
        if not np.all(np.isfinite(raw)):
            raise SimulationError(f"controller returned a non-finite torque {raw!r} at "
                                  f"t={t_k:.6g} s")
        if np.max(np.abs(raw)) > abort_limit:
            status, abort_index, abort_value = _k.ABORTED, s0 * n_sub, float(
                raw.flat[np.argmax(np.abs(raw))])
            break
        vector = vector or raw.ndim == 1
        u = np.zeros(nb)
        if raw.ndim:
            u[:] = np.clip(raw, -saturation, saturation)
        else:
            u[body] = min(max(float(raw), -saturation), saturation)
        queue.append(u)
        applied = queue.pop(0)
        s1 = min(s0 + r_c, n_fine - 1)
        inp = np.vstack([torque[:, s0:s1 + 1] + applied[:, None], np.zeros((1, s1 - s0 + 1))])
        (xk, vk, _, ek, ck, st, ai, _, modes), interpreted = run_drive_kernel(
            (y, modes, par, inp, math.inf, fs_in, s1 - s0 + 1, n_sub, max_events, k > 0, jump,
             0.0, 1), (n_fine - 1) * n_sub * nb if k == 0 else 0, interpreted=interpreted)
        counts += ck
        if st != _k.OK:
            status, abort_index = st, s0 * n_sub + ai
            break
        x[:, s0:s1], v[:, s0:s1], e[:, s0:s1] = xk[:, :-1], vk[:, :-1], ek[:, :-1]
        cmd[:, s0:s1] = applied[:, None]
        y = np.concatenate([xk[:, -1], vk[:, -1], ek[:3, -1]])
        jump = np.array([ek[3, -1], ek[5, -1]])
    if status == _k.OK:  # the last sample holds the last command
        x[:, -1], v[:, -1], cmd[:, -1] = y[:nb], y[nb:2 * nb], applied
        e[:3, -1], e[3, -1], e[5, -1] = y[2 * nb:], jump[0], jump[1]
        e[4, -1] = _stored_contacts(params, y[:nb], modes)
    sl = slice(None, None, r_out)
    run = run | {"fs": fs_in, "n_sub": n_sub, "abort_limit": abort_limit}
    result = _finish(params, run, x[:, sl], v[:, sl], cmd[:, sl] if vector else cmd[body, sl],
                     e[:, sl], counts, status, abort_index, abort_value, max_events)
    return result


def _stored_contacts(params, x, modes) -> float:
    """Energy [J] held by the closed compliant contacts at positions x."""
    stored = 0.0
    for j, ln in enumerate(params.links):
        m = modes[params.n_bodies + j]
        if isinstance(ln, BacklashLink) and m != 0:
            d = x[j] - x[j + 1] - ln.gap_plus if m > 0 else -ln.gap_minus - x[j] + x[j + 1]
            stored += 0.5 * ln.k * d * d
    return stored


def _simulate_exact(params, duration, fs, x0, v0, u0) -> DriveResult:
    from driveid.sim.free_decay_batch import simulate_free_decay_batch

    b = params.bodies[0]
    batch = simulate_free_decay_batch(
        J=b.J, K=b.K, c_mean=b.c_mean, c_delta=b.c_delta, fk_mean=b.fk_mean,
        fk_delta=b.fk_delta, fs_mean=b.fs_mean, fs_delta=b.fs_delta, x0=x0[0], v0=v0[0],
        u0=u0, duration=duration, fs=fs, return_velocity=True)
    x, v = batch.x, batch.v
    n_switch = int(batch.n_reversals[0])  # every velocity zero: a reversal or the final stick

    def balance() -> dict:
        kin, pot = _stored(params, x, v)
        kin0, pot0 = _stored(params, x0[:, None], v0[:, None])
        initial = float(kin0[0] + pot0[0])
        work = u0 * (x[0] - x0[0])
        return {"input": work, "dissipated": initial + work - kin - pot, "kinetic": kin,
                "potential": pot, "contact_release": np.zeros_like(work),
                "impact": np.zeros_like(work), "initial": initial}

    energy = _LazyEnergy(balance)
    return DriveResult(t=batch.t, x=x, v=v, command=np.zeros_like(batch.t), energy=energy,
                       n_mode_switches=n_switch, n_impacts=0, aborted=False, abort_reason=None,
                       abort_time=None, params=params)


class _LazyEnergy(Mapping):
    """The energy balance of a result, computed on first access.

    Half of a short single run's cost was this bookkeeping (kinetic and potential energy
    arrays of every sample), and the energy integrals a sixth of every RK4 step; most
    callers want positions only, so it waits until asked.
    """

    def __init__(self, build) -> None:
        self._build = build
        self._data: dict | None = None

    def _get(self) -> dict:
        if self._data is None:
            self._data = self._build()
            self._build = None
        return self._data

    def __getitem__(self, key):
        return self._get()[key]

    def __iter__(self):
        return iter(self._get())

    def __len__(self) -> int:
        return len(self._get())

    def __repr__(self) -> str:
        return "{...}" if self._data is None else repr(self._data)


def _stored(params: DriveParams, x, v):
    """Kinetic and potential energy [J] (without contacts) for states (n_bodies, ...)."""
    kin = sum(0.5 * b.J * v[i] ** 2 for i, b in enumerate(params.bodies))
    pot = sum(0.5 * b.K * x[i] ** 2 for i, b in enumerate(params.bodies))
    for j, ln in enumerate(params.links):
        if isinstance(ln, ShaftLink):
            pot = pot + 0.5 * ln.k * (x[j] - x[j + 1]) ** 2
    return kin, pot


def _energy(params, x, v, e, x0, v0) -> dict:
    kin, pot = _stored(params, x, v)
    kin0, pot0 = _stored(params, x0[:, None], v0[:, None])
    contact0 = 0.0
    for j, ln in enumerate(params.links):
        if isinstance(ln, BacklashLink):
            rel = x0[j] - x0[j + 1]
            d = max(rel - ln.gap_plus, -ln.gap_minus - rel, 0.0)
            contact0 += 0.5 * ln.k * d * d
    # contact work minus what the closed contacts still store is dissipated (damping and
    # the release loss of the no-tension rule)
    return {"input": e[0], "dissipated": e[1] + e[2] - e[4] + e[5] + contact0,
            "kinetic": kin, "potential": pot + e[4], "contact_release": e[3], "impact": e[5],
            "initial": float(kin0[0] + pot0[0]) + contact0}
