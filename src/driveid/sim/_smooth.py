r"""Stiff path of the lumped drive: LuGre friction on bodies and a DC motor/amplifier.

:func:`simulate_smooth` integrates the chain of :mod:`driveid.sim.drive` when a body carries a
LuGre model (de Marchi 1998, Eqs. 2.23–2.26) or the drive has a motor/amplifier
(:class:`driveid.models.motor.MotorAmplifier`, Eqs. 2.105–2.108). The state holds, for every
unlocked body, ``x`` and ``v``, plus the bristle deflection ``z`` of a LuGre body, plus the
armature current when the motor has an electrical state; locked bodies are not in the state.

Body ``i`` obeys ``J v' = u_i - K x - F_link - F_fric`` with
``F_fric = (c_mean + c_delta sgn v) v + fk_delta + F_LuGre`` and
``F_LuGre = σ0 z + σ1 z' + σ2 v``, ``z' = v - σ0 |v| z / g(v)``,
``g = F_c + (F_s - F_c) exp(-(v/v_s)²)``.

Choices (why):

* Coulomb sticking (``fk_mean > 0`` or ``fs_mean > 0``) is not allowed on any body of this
  path: true sticking needs the event-located modes of ``simulate_drive`` and a smooth
  regulariser would silently change the model. Give every frictional body a LuGre model (which
  then carries the Coulomb, static and viscous levels; ``BodyParams`` rejects the static-map
  fields next to it). Bodies without LuGre keep ``c_mean``, ``c_delta`` and the constant
  ``fk_delta``.
* Backlash contact is the Kelvin–Voigt law of ``simulate_drive`` (no tension by default):
  ``f = k d + c d'`` while the penetration ``d > 0`` (and, without tension, ``f`` pushes).
  The force jumps by ``c d'`` at contact entry, so the contact state is a mode held fixed
  over each step; when a step ends with a mode that no longer holds, the crossing is found
  by bisection on the step's cubic Hermite interpolant and the step is redone to end just
  past it (by ``max(1e-12 t_end, 1e-6 h)``), where the mode switches. Without this the
  step-size control collapses at tight tolerances.
* The motor torque ``k_m i`` acts on the motor body: the feedback body, or body 0 without
  feedback (as ``DriveParams.motor`` says). Its amplifier input ``u`` is the saturated PD
  output (if any) plus the ``torque`` entry of the motor body, which with a motor is an
  amplifier command [V or A demand per ``k_a``], not a torque. Without a motor the PD output
  is a torque on the feedback body as in ``simulate_drive``.
* The PD delay reads a history of accepted steps (cubic Hermite in position and velocity);
  the step is kept <= the delay so that delayed values are always history.

Integrator: 2-stage Radau IIA (order 3, L-stable, stiffly accurate) with full Newton and the
analytic Jacobian re-evaluated at every iteration (the ``|v|`` kink of LuGre makes a
frozen Jacobian stall), the filtered embedded error estimate of Hairer & Wanner §IV.8, as in
:mod:`driveid.sim.lugre`, generalised to any state size; compiled with numba (``cache=True``).

Energy: ``input`` is the work of the external torques and of the actuator (motor torque
``k_m i`` or PD torque) on the bodies — electrical losses of the motor are outside the
balance; ``potential`` includes the bristle energy ``σ0 z²/2`` and closed contacts;
``dissipated`` closes ``initial + input = kinetic + potential + dissipated`` with every
integral taken by the Radau quadrature of each step (order 3) and Hermite-interpolated to the
output times; ``contact_release`` is the part of ``dissipated`` that no-tension contacts
still stored when they opened;
``impact`` is 0 (no restitution impacts on this path).

References
----------
.. [1] J. A. de Marchi, "Modeling of dynamic friction, impact backlash and elastic
       compliance nonlinearities in machine tools", PhD thesis, RPI, 1998.
.. [2] E. Hairer, G. Wanner, "Solving Ordinary Differential Equations II", 2nd ed.,
       Springer, 1996, §IV.8.
"""

from __future__ import annotations

import math

import numpy as np

from driveid.errors import ParameterError, SimulationError
from driveid.models.dynamic_friction import LuGreParams
from driveid.models.motor import MotorAmplifier
from driveid.sim import drive_types as _types
from driveid.sim._smooth_kernels import (
    _ABORTED,
    _J,
    _K,
    _MAX_STEPS,
    _S0,
    _STEP_TOO_SMALL,
    _TOO_MANY_STEPS,
    _smooth_kernel,
)

__all__ = ["simulate_smooth"]


def _check_tol(name: str, value, low: float, high: float) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not (
            low <= value <= high):
        raise ParameterError(f"{name} must be a number in [{low:g}, {high:g}]; got {value!r}")
    return float(value)


def _pack(params, motor):
    """Validate the smooth-path rules and build the parameter arrays of the kernel."""
    nb = params.n_bodies
    bpar = np.zeros((nb, 12))
    for i, b in enumerate(params.bodies):
        lg = getattr(b, "lugre", None)
        if lg is not None and not isinstance(lg, LuGreParams):
            raise ParameterError(
                f"bodies[{i}].lugre must be a LuGreParams or None; got {type(lg).__name__}")
        if b.fk_mean != 0.0 or b.fs_mean != 0.0:
            if lg is None:
                raise ParameterError(
                    "mix of Coulomb sticking and dynamic friction not supported; give every "
                    f"frictional body a LuGre model (bodies[{i}] has fk_mean={b.fk_mean!r}, "
                    f"fs_mean={b.fs_mean!r} and no lugre)")
            raise ParameterError(
                f"bodies[{i}] has a LuGre model, which carries the Coulomb and static levels "
                f"(fc, fs); set fk_mean=0 (and fs_mean=None or 0); got fk_mean={b.fk_mean!r}, "
                f"fs_mean={b.fs_mean!r}")
        bpar[i, :5] = (b.J, b.K, b.c_mean, b.c_delta, b.fk_delta)
        if lg is not None and not b.locked:
            bpar[i, 5:] = (1.0, lg.sigma0, lg.sigma1, lg.sigma2, lg.fc, lg.fs, lg.vs)
    lpar = np.zeros((max(nb - 1, 1), 7))  # column 6: contact mode (kernel)
    for j, ln in enumerate(params.links):
        if isinstance(ln, _types.ShaftLink):
            lpar[j, :3] = (1.0, ln.k, ln.c)
        elif isinstance(ln, _types.BacklashLink):
            if getattr(ln, "contact", "viscoelastic") != "viscoelastic":
                raise ParameterError(
                    f"links[{j}]: contact={ln.contact!r} is not supported with LuGre bodies or "
                    "a motor model; use contact='viscoelastic' (Kelvin-Voigt k, c)")
            lpar[j, :6] = (2.0, ln.k, ln.c, ln.gap_plus, ln.gap_minus, float(ln.allow_tension))
        elif ln is not None:
            raise ParameterError(f"links[{j}] must be a ShaftLink, BacklashLink or None; got "
                                 f"{type(ln).__name__}")
    fpar = np.zeros(7)
    fpar[6] = math.inf
    fb = params.feedback
    if fb is not None:
        fpar[:] = (1.0, fb.body, fb.P, fb.D, fb.delay, fb.saturation, fb.abort_limit)
    mpar = np.zeros(11)
    if motor is not None:
        if not isinstance(motor, MotorAmplifier):
            raise ParameterError(
                f"params.motor must be a MotorAmplifier or None; got {type(motor).__name__}")
        mpar[:] = (1.0, 0.0 if motor.mode == "voltage" else 1.0, motor.k_m, motor.k_emf,
                   motor.R_m, motor.L_m, motor.k_a, motor.current_bandwidth,
                   motor.voltage_limit, motor.current_limit,
                   0 if fb is None else fb.body)
        if params.bodies[int(mpar[10])].locked:
            raise ParameterError(
                "the motor body (the feedback body, else body 0) must not be locked; unlock "
                f"bodies[{int(mpar[10])}]")
    return bpar, lpar, fpar, mpar


def simulate_smooth(params, *, duration: float, fs: float = 1000.0, x0=None, v0=None,
                    torque=None, reference=None, rtol: float = 1e-6, atol=None):
    """Simulate the drive with LuGre friction and/or a DC motor/amplifier (stiff path).

    Parameters
    ----------
    params : DriveParams
        The drive; bodies may carry ``lugre`` (:class:`LuGreParams`), the drive ``motor``
        (:class:`MotorAmplifier`). Bodies must not have Coulomb sticking (``fk_mean`` or
        ``fs_mean`` > 0): see the module docstring.
    duration : float
        Simulated time [s]; > 0.
    fs : float, optional
        Output sampling rate [Hz]; > 0. Default 1000.
    x0, v0 : array_like, shape (n_bodies,), optional
        Initial positions [rad] and velocities [rad/s] (default 0). Bristles and the motor
        current start at 0. Locked bodies must start at rest.
    torque : array_like, optional
        External torque on each body [N·m]: shape (n_bodies,) constant, or (n_bodies, n)
        sampled at the output times and interpolated linearly. With a motor, the motor
        body's entry is the amplifier command instead [V or A demand per ``k_a``].
    reference : array_like, shape (n,), optional
        Feedback reference [rad] at the output times (default ``feedback.reference``).
    rtol : float, optional
        Relative tolerance of the local error [-], in [1e-12, 1e-2]. Default 1e-6.
    atol : float, optional
        Absolute tolerance [SI unit of each state], the same for all states. Default
        ``rtol`` times a scale per state: ``v_s`` for LuGre velocities, ``F_s/σ0`` for
        bristles, 1e-3 for other positions [rad], velocities [rad/s] and currents [A]
        (the breakaway amplifies micro-slip errors, see :mod:`driveid.sim.lugre`).

    Returns
    -------
    DriveResult
        Positions, velocities, command (PD torque, or the amplifier input with a motor),
        energy (see the
        module docstring), velocity reversals as ``n_mode_switches``, contact closures as
        ``n_impacts``, abort.

    Raises
    ------
    ParameterError
        If an argument is out of range or the drive mixes Coulomb sticking in.
    SimulationError
        If the step size collapses or too many steps are needed.

    Notes
    -----
    ``n_mode_switches`` counts velocity sign changes between accepted steps (LuGre has no
    stuck mode; micro-slip reversals while "stuck" count too, so the number depends on the
    tolerance). The safety abort tests the unsaturated PD command at the end of each accepted
    step, so ``abort_time`` is late by at most one step.

    Examples
    --------
    >>> from driveid.models.motor import MotorAmplifier
    >>> from driveid.sim.drive import BodyParams, DriveParams
    >>> motor = MotorAmplifier(k_m=0.1, k_emf=0.1, R_m=1.0, L_m=0.0, k_a=1.0)
    >>> drive = DriveParams(bodies=(BodyParams(J=1e-3, c_mean=1e-3),), motor=motor)
    >>> r = simulate_smooth(drive, duration=2.0, torque=[2.0])  # 2 V on the amplifier
    >>> round(float(r.v[0, -1]), 4)  # k_m V / (R c + k_m k_emf) = 0.2/0.011 rad/s
    18.1818
    """
    if not isinstance(params, _types.DriveParams):
        raise ParameterError(f"params must be a DriveParams; got {type(params).__name__}")
    _types._require(isinstance(duration, (int, float)) and 0 < duration < math.inf,
                    "duration must be positive and finite [s]", duration)
    _types._require(isinstance(fs, (int, float)) and 0 < fs < math.inf,
                    "fs must be positive; pass the output sampling rate in Hz", fs)
    rtol = _check_tol("rtol", rtol, 1e-12, 1e-2)
    if atol is not None:
        atol = _check_tol("atol", atol, 1e-300, math.inf)
    motor = getattr(params, "motor", None)
    bpar, lpar, fpar, mpar = _pack(params, motor)
    nb = params.n_bodies
    n_out = int(math.floor(duration * fs + 1e-9)) + 1
    if n_out > 10_000_000:
        raise ParameterError(
            f"duration * fs must give at most 1e7 samples; lower fs or duration; got {n_out}")
    x0 = _types._input_grid(x0, "x0", None, nb)
    v0 = _types._input_grid(v0, "v0", None, nb)
    locked = np.array([b.locked for b in params.bodies])
    if np.any(v0[locked] != 0.0):
        raise ParameterError(f"locked bodies must start at rest (v0 = 0); got v0={v0.tolist()}")
    torque = _types._input_grid(torque, "torque", nb, n_out)
    fb = params.feedback
    if reference is None:
        reference = fb.reference if fb is not None else 0.0
    reference = _types._input_grid(reference, "reference", None, n_out)[None, :]
    inp = np.ascontiguousarray(np.vstack([torque, reference]))

    # state layout: x, v (, z) per free body, then the motor current
    lay = np.full((4, nb), -1, dtype=np.int64)
    y0, scale = [], []
    for i, b in enumerate(params.bodies):
        if b.locked:
            continue
        lg = getattr(b, "lugre", None)
        lay[0, i], lay[1, i] = len(y0), len(y0) + 1
        y0 += [x0[i], v0[i]]
        scale += [1e-3, 1e-3 if lg is None else lg.vs]
        if lg is not None:
            lay[2, i] = len(y0)
            y0.append(0.0)
            scale.append(lg.fs / lg.sigma0)
    if motor is not None and not motor.quasi_static:
        lay[3, 0] = len(y0)  # the kernel reads the current index from lay[3, 0]
        y0.append(0.0)
        scale.append(1e-3)
    if not y0:
        raise ParameterError("every body is locked: nothing to simulate; unlock a body")
    y0 = np.array(y0, dtype=float)
    scale = np.array(scale, dtype=float)
    atol_v = rtol * scale if atol is None else np.full(len(y0), atol)
    h_cap = math.inf
    if inp.shape[1] > 2:
        # a sampled input kinks at every sample unless it is a straight line (a moving
        # spring end, W2 of issue 4); the steps must not straddle the kinks
        curv = np.abs(np.diff(inp, 2, axis=1)).max(axis=1)
        level = 1e-12 * (np.abs(inp).max(axis=1) + 1e-300)
        if np.any(curv > level):
            h_cap = 1.0 / fs
    if fb is not None and fb.delay > 0:
        h_cap = min(h_cap, fb.delay)
    t_end = (n_out - 1) / fs
    out, counts, status, t_stop, raw, n_acc, n_rej = _smooth_kernel(
        y0, lay, x0.copy(), bpar, lpar, fpar, mpar, inp, float(fs), atol_v, rtol,
        float(h_cap), t_end, float(fs), n_out, _MAX_STEPS)
    if status in (_TOO_MANY_STEPS, _STEP_TOO_SMALL):
        why = "the step size collapsed" if status == _STEP_TOO_SMALL else "too many steps"
        raise SimulationError(
            f"stiff drive integration stopped at t={t_stop:.6g} s: {why}; loosen rtol or "
            f"shorten duration; got rtol={rtol!r}, duration={duration!r}")
    aborted = status == _ABORTED
    reason = abort_time = None
    if aborted:
        abort_time = float(t_stop)
        reason = (f"|command| = {abs(raw):.6g} before saturation exceeded "
                  f"abort_limit={fb.abort_limit:g} at t={abort_time:.6g} s")
    ny = len(y0)
    t = np.arange(n_out) / fs
    x = np.empty((nb, n_out))
    v = np.empty((nb, n_out))
    z = {}
    for i in range(nb):
        if lay[0, i] < 0:
            x[i] = x0[i]
            v[i] = 0.0
            if aborted:
                x[i, np.isnan(out[0])] = np.nan
                v[i, np.isnan(out[0])] = np.nan
        else:
            x[i] = out[lay[0, i]]
            v[i] = out[lay[1, i]]
        if lay[2, i] >= 0:
            z[i] = out[lay[2, i]]
    energy = _energy(bpar, lpar, x, v, z, out[ny + 1:ny + 4], out[ny + 5], x0, v0)
    return _types.DriveResult(
        t=t, x=x, v=v, command=out[ny], energy=energy, n_mode_switches=int(counts[0]),
        n_impacts=int(counts[1]), aborted=aborted, abort_reason=reason,
        abort_time=abort_time, params=params)


def _contact_stored(lp, rel, vrel):
    """Energy [J] stored in a backlash contact (numpy twin of :func:`_contact_force`)."""
    dp = rel - lp[3]
    dm = -lp[4] - rel
    fp = lp[1] * dp + lp[2] * vrel
    fm = -lp[1] * dm + lp[2] * vrel
    on_p = (dp > 0) & ((lp[5] != 0.0) | (fp >= 0))
    on_m = (dm > 0) & ((lp[5] != 0.0) | (fm <= 0))
    return np.where(on_p, 0.5 * lp[1] * dp**2, 0.0) + np.where(on_m, 0.5 * lp[1] * dm**2, 0.0)


def _parts(bpar, lpar, x, v):
    """Kinetic, spring+shaft and contact energies [J] for states of shape (n_bodies, ...)."""
    nb = bpar.shape[0]
    kin = sum(0.5 * bpar[i, _J] * v[i] ** 2 for i in range(nb))
    pot = sum(0.5 * bpar[i, _K] * x[i] ** 2 for i in range(nb))
    contact = 0.0 * kin
    for j in range(nb - 1):
        rel = x[j] - x[j + 1]
        if lpar[j, 0] == 1.0:
            pot = pot + 0.5 * lpar[j, 1] * rel ** 2
        elif lpar[j, 0] == 2.0:
            contact = contact + _contact_stored(lpar[j], rel, v[j] - v[j + 1])
    return kin, pot, contact


def _energy(bpar, lpar, x, v, z, work, release, x0, v0) -> dict:
    kin, pot, contact = _parts(bpar, lpar, x, v)
    kin0, pot0, contact0 = (float(np.ravel(a)[0])
                            for a in _parts(bpar, lpar, x0[:, None], v0[:, None]))
    bristle = sum((0.5 * bpar[i, _S0] * zi**2 for i, zi in z.items()), 0.0 * kin)
    # friction and contact work minus what bristles and contacts still store (z0 = 0)
    dissipated = work[1] + work[2] - bristle - (contact - contact0)
    return {"input": work[0], "dissipated": dissipated, "kinetic": kin,
            "potential": pot + contact + bristle,
            "contact_release": release,
            "impact": np.zeros_like(work[0]),
            "initial": kin0 + pot0 + contact0}
