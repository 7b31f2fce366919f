r"""Lumped multi-body drive: inertias in a chain with friction, backlash, shafts and PD feedback.

The drive of thesis §2.1.4 (Fig. 2.9), §3.2.2 and App. B.2 is a chain of bodies (motor,
arm, tool ...) joined by links. Body ``i`` obeys

.. math:: J_i \ddot x_i = u_i + \tau_{fb}\,[i = b] - K_i x_i - F_{link} - F_{fric,i}

with, while moving in direction ``s = sgn(x')``, ``F_fric = (c_mean + c_delta·s) x' +
fk_mean·s + fk_delta`` (thesis 2.155, the sign conventions of ``shared/DESIGN.md``), and true
sticking: a body at rest stays stuck while the force the other elements apply lies in
``[fs_delta - fs_mean, fs_delta + fs_mean]`` (2.137, 2.138; Karnopp-like switching, the
breakaway test runs on the applied force, not on a velocity band).

Links between consecutive bodies ``j`` and ``j + 1`` (force ``f`` pushes ``j + 1`` forward
and ``j`` back; ``δ = x_j - x_{j+1}``):

* :class:`ShaftLink` — compliant shaft ``f = k δ + c δ'`` (§2.1.3);
* :class:`BacklashLink` — deadzone ``-gap_minus < δ < gap_plus`` with a Kelvin–Voigt
  contact beyond it (2.27-2.29), without tension by default (``driveid.models.backlash``).

Feedback (:class:`PDFeedback`): ``τ = P (r - x_b(t - Δ)) - D x_b'(t - Δ)`` with a pure delay
read from the history of past states (cubic Hermite interpolation, not a Padé
approximation), saturation at ``±saturation`` and a safety abort when ``|τ|`` before
saturation exceeds ``abort_limit``.

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
from dataclasses import dataclass, field

import numpy as np

from driveid.errors import ParameterError, SimulationError
from driveid.io.record import Record
from driveid.sim import _kernels as _k

__all__ = [
    "BodyParams",
    "ShaftLink",
    "BacklashLink",
    "PDFeedback",
    "DriveParams",
    "DriveResult",
    "FreeDecayBatch",
    "simulate_drive",
    "simulate_free_decay_batch",
]


def _finite(owner: str, name: str, value) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ParameterError(f"{owner}.{name} must be a finite number; got {value!r}")
    return float(value)


def _require(ok: bool, message: str, value) -> None:
    if not ok:
        raise ParameterError(f"{message}; got {value!r}")


@dataclass(frozen=True, kw_only=True)
class BodyParams:
    """One rigid body of the chain with its ground spring and friction.

    Attributes
    ----------
    J : float
        Inertia [kg·m²] (or mass [kg]); > 0.
    K : float
        Stiffness to ground [N·m/rad]; >= 0 (default 0: no spring).
    c_mean, c_delta : float
        Viscous friction ``c_mean + c_delta·sgn(x')`` [N·m·s/rad] (thesis 2.155).
    fk_mean, fk_delta : float
        Kinetic (Coulomb) friction ``fk_mean·sgn(x') + fk_delta`` [N·m]; fk_mean >= 0.
    fs_mean, fs_delta : float or None
        Static friction band ``[fs_delta - fs_mean, fs_delta + fs_mean]`` [N·m]; ``None``
        takes the kinetic value. The band must enclose the kinetic band.
    locked : bool
        True: the body is clamped and never moves (a locked axis of the test bed).
    """

    J: float
    K: float = 0.0
    c_mean: float = 0.0
    c_delta: float = 0.0
    fk_mean: float = 0.0
    fk_delta: float = 0.0
    fs_mean: float | None = None
    fs_delta: float | None = None
    locked: bool = False

    def __post_init__(self) -> None:
        for name in ("J", "K", "c_mean", "c_delta", "fk_mean", "fk_delta"):
            _finite("BodyParams", name, getattr(self, name))
        _require(self.J > 0, "BodyParams.J must be positive [kg·m²]", self.J)
        _require(self.K >= 0, "BodyParams.K must be >= 0 [N·m/rad]", self.K)
        _require(self.fk_mean >= 0, "BodyParams.fk_mean must be >= 0 [N·m]", self.fk_mean)
        fs_mean = self.fk_mean if self.fs_mean is None else _finite(
            "BodyParams", "fs_mean", self.fs_mean)
        fs_delta = self.fk_delta if self.fs_delta is None else _finite(
            "BodyParams", "fs_delta", self.fs_delta)
        object.__setattr__(self, "fs_mean", fs_mean)
        object.__setattr__(self, "fs_delta", fs_delta)
        eps = 1e-12 * max(1.0, abs(self.fk_mean) + abs(self.fk_delta))
        if (fs_delta + fs_mean < self.fk_delta + self.fk_mean - eps
                or fs_delta - fs_mean > self.fk_delta - self.fk_mean + eps):
            raise ParameterError(
                "static friction must hold at least the kinetic friction in each direction; "
                "raise fs_mean or pass None; got "
                f"fs_mean={fs_mean}, fs_delta={fs_delta}, fk_mean={self.fk_mean}, "
                f"fk_delta={self.fk_delta}"
            )

    def _row(self) -> list[float]:
        return [self.J, self.K, self.c_mean, self.c_delta, self.fk_mean, self.fk_delta,
                self.fs_delta - self.fs_mean, self.fs_delta + self.fs_mean]


@dataclass(frozen=True, kw_only=True)
class ShaftLink:
    """Compliant shaft between two consecutive bodies, ``f = k δ + c δ'`` (thesis §2.1.3).

    Attributes
    ----------
    k : float
        Torsional stiffness [N·m/rad]; >= 0.
    c : float
        Torsional damping [N·m·s/rad]; >= 0.
    """

    k: float
    c: float = 0.0

    def __post_init__(self) -> None:
        _require(_finite("ShaftLink", "k", self.k) >= 0, "ShaftLink.k must be >= 0", self.k)
        _require(_finite("ShaftLink", "c", self.c) >= 0, "ShaftLink.c must be >= 0", self.c)

    def _row(self) -> list[float]:
        return [_k.LINK_SHAFT, self.k, self.c, 0.0, 0.0, 0.0]


@dataclass(frozen=True, kw_only=True)
class BacklashLink:
    """Backlash between two consecutive bodies: deadzone plus Kelvin–Voigt contact (2.27-2.29).

    Attributes
    ----------
    gap_plus, gap_minus : float
        Clearances [rad], >= 0: contact when ``x_j - x_{j+1}`` exceeds ``gap_plus`` or falls
        below ``-gap_minus``.
    k : float
        Contact stiffness [N·m/rad]; > 0.
    c : float
        Contact damping [N·m·s/rad]; >= 0.
    allow_tension : bool
        False (default): the contact never pulls, it opens when ``k δ + c δ'`` reaches zero
        (Modelica ElastoBacklash); True: the thesis's linear contact, open when ``δ = 0``.
    """

    gap_plus: float
    gap_minus: float
    k: float
    c: float = 0.0
    allow_tension: bool = False

    def __post_init__(self) -> None:
        for name in ("gap_plus", "gap_minus", "c"):
            _require(_finite("BacklashLink", name, getattr(self, name)) >= 0,
                     f"BacklashLink.{name} must be >= 0", getattr(self, name))
        _require(_finite("BacklashLink", "k", self.k) > 0, "BacklashLink.k must be positive",
                 self.k)

    def _row(self) -> list[float]:
        return [_k.LINK_BACKLASH, self.k, self.c, self.gap_plus, self.gap_minus,
                float(self.allow_tension)]


@dataclass(frozen=True, kw_only=True)
class PDFeedback:
    """Delayed PD position feedback ``τ = P (r - x(t-Δ)) - D x'(t-Δ)`` on one body.

    Attributes
    ----------
    P : float
        Proportional gain [N·m/rad].
    D : float
        Derivative gain [N·m·s/rad] (on the measured velocity, not the error).
    delay : float
        Pure time delay Δ [s]; >= 0.
    body : int
        Index of the actuated and measured body (default 0, the motor).
    reference : float
        Step reference r [rad] applied at t = 0 (default 0); a time-varying reference is
        passed to :func:`simulate_drive` as ``reference``.
    saturation : float
        Command limit [N·m]; > 0 (default inf).
    abort_limit : float
        Safety abort when ``|τ|`` before saturation exceeds it [N·m]; > 0 (default inf).
    """

    P: float
    D: float
    delay: float = 0.0
    body: int = 0
    reference: float = 0.0
    saturation: float = math.inf
    abort_limit: float = math.inf

    def __post_init__(self) -> None:
        for name in ("P", "D", "delay", "reference"):
            _finite("PDFeedback", name, getattr(self, name))
        _require(self.delay >= 0, "PDFeedback.delay must be >= 0 [s]", self.delay)
        _require(isinstance(self.body, int) and self.body >= 0,
                 "PDFeedback.body must be a body index >= 0", self.body)
        for name in ("saturation", "abort_limit"):
            value = getattr(self, name)
            _require(isinstance(value, (int, float)) and value > 0 and not math.isnan(value),
                     f"PDFeedback.{name} must be positive [N·m] (inf: none)", value)


@dataclass(frozen=True, kw_only=True)
class DriveParams:
    """A chain of bodies, the links between neighbours and an optional feedback.

    Attributes
    ----------
    bodies : tuple of BodyParams
        The bodies, in chain order (e.g. motor, arm, tool).
    links : tuple of ShaftLink, BacklashLink or None
        ``len(bodies) - 1`` links; ``links[j]`` joins bodies ``j`` and ``j + 1``; None: no
        connection.
    feedback : PDFeedback or None
        Position feedback (default none).
    """

    bodies: tuple
    links: tuple = ()
    feedback: PDFeedback | None = None

    def __post_init__(self) -> None:
        bodies, links = tuple(self.bodies), tuple(self.links)
        object.__setattr__(self, "bodies", bodies)
        object.__setattr__(self, "links", links)
        _require(len(bodies) >= 1 and all(isinstance(b, BodyParams) for b in bodies),
                 "DriveParams.bodies must be a non-empty sequence of BodyParams", self.bodies)
        _require(len(links) == len(bodies) - 1,
                 f"DriveParams.links must hold len(bodies) - 1 = {len(bodies) - 1} links",
                 len(links))
        _require(all(ln is None or isinstance(ln, (ShaftLink, BacklashLink)) for ln in links),
                 "DriveParams.links must be ShaftLink, BacklashLink or None", links)
        fb = self.feedback
        if fb is not None:
            _require(isinstance(fb, PDFeedback), "DriveParams.feedback must be a PDFeedback",
                     fb)
            _require(fb.body < len(bodies), "PDFeedback.body must index a body", fb.body)
            _require(not bodies[fb.body].locked, "the feedback body must not be locked",
                     fb.body)

    @property
    def n_bodies(self) -> int:
        """Number of bodies [-]."""
        return len(self.bodies)


@dataclass(frozen=True)
class DriveResult:
    """Sampled response of :func:`simulate_drive`.

    Attributes
    ----------
    t : ndarray, shape (n,)
        Output times [s].
    x, v : ndarray, shape (n_bodies, n)
        Positions [rad] and velocities [rad/s]; NaN after an abort.
    command : ndarray, shape (n,)
        Saturated feedback command [N·m] (zeros without feedback).
    energy : dict of str to ndarray, shape (n,)
        ``input`` (work of external torques and command) [J], ``dissipated`` (friction,
        viscous, shaft and contact damping, contact release) [J], ``kinetic``,
        ``potential`` (ground springs, shafts, closed contacts) [J], ``contact_release``
        (the part of ``dissipated`` lost when no-tension contacts open) [J] and
        ``initial`` (scalar) [J].
    n_mode_switches : int
        Stick, breakaway and reversal transitions of the bodies [-].
    n_impacts : int
        Contact closures of the backlash links [-].
    aborted : bool
        True if the safety abort stopped the run.
    abort_reason : str or None
        Why the run stopped early.
    abort_time : float or None
        Time of the abort [s].
    params : DriveParams
        The simulated drive.
    """

    t: np.ndarray
    x: np.ndarray
    v: np.ndarray
    command: np.ndarray
    energy: dict = field(repr=False)
    n_mode_switches: int
    n_impacts: int
    aborted: bool
    abort_reason: str | None
    abort_time: float | None
    params: DriveParams = field(repr=False)

    def record(self, body: int = 0) -> Record:
        """Return the response of one body as a :class:`~driveid.io.record.Record`.

        Parameters
        ----------
        body : int
            Body index.

        Returns
        -------
        Record
            ``t`` [s], ``x`` [rad], ``v`` [rad/s], ``u`` = command [N·m] (finite part only).
        """
        keep = np.isfinite(self.x[body])
        meta = {"source": "driveid.sim.simulate_drive", "body": body,
                "units": {"x": "rad", "v": "rad/s", "u": "N·m"}}
        return Record(t=self.t[keep], x=self.x[body][keep], v=self.v[body][keep],
                      u=self.command[keep], meta=meta, max_jitter=None)


def _highest_rate(params: DriveParams) -> float:
    """Bound the fastest eigenvalue [1/s], to choose the RK4 step."""
    rate = 0.0
    nb = params.n_bodies
    for i, b in enumerate(params.bodies):
        k, c = b.K, abs(b.c_mean) + abs(b.c_delta)
        for j in (i - 1, i):
            if 0 <= j < nb - 1 and params.links[j] is not None:
                other = params.bodies[j + 1 if j == i else j]
                scale = 1.0 + b.J / other.J  # relative motion uses the reduced inertia
                k += params.links[j].k * scale
                c += params.links[j].c * scale
        fb = params.feedback
        if fb is not None and fb.body == i:
            k += abs(fb.P)
            c += abs(fb.D)
        rate = max(rate, math.sqrt(k / b.J), c / b.J)
    return rate


def _input_grid(value, name: str, n_bodies: int | None, n: int) -> np.ndarray:
    arr = np.asarray(0.0 if value is None else value, dtype=float)
    shape = (n,) if n_bodies is None else (n_bodies, n)
    if n_bodies is not None and arr.ndim == 1 and arr.shape[0] == n_bodies:
        arr = arr[:, None]
    try:
        arr = np.ascontiguousarray(np.broadcast_to(arr, shape), dtype=float)
    except ValueError:
        raise ParameterError(
            f"{name} must be a scalar or broadcast to shape {shape} (sampled at the output "
            f"times); got shape {np.shape(value)}"
        ) from None
    if not np.all(np.isfinite(arr)):
        raise ParameterError(f"{name} must be finite; got a non-finite value")
    return arr


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
    max_events_per_step: int = 200,
    method: str = "auto",
) -> DriveResult:
    """Simulate the lumped drive with friction, backlash, shafts, locks and delayed PD feedback.

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
        (n_bodies, n) sampled at the output times and interpolated linearly.
    reference : array_like, shape (n,), optional
        Feedback reference [rad] at the output times, replacing ``feedback.reference``.
    max_step : float, optional
        Largest RK4 step [s]; default ``0.2/rate`` for the fastest rate of the drive (and
        no larger than the delay or the output interval).
    max_events_per_step : int
        Guard against chattering (Zeno) switching inside one step.
    method : {"auto", "rk4", "exact"}
        ``"exact"``: the piecewise closed form of :func:`simulate_free_decay_batch`, for one
        free body with ``K > 0``, no feedback and a constant torque; ``"rk4"``: the event-
        located integrator; ``"auto"`` (default) takes ``"exact"`` where it applies.

    Returns
    -------
    DriveResult
        Positions, velocities, command, energy balance, switch and impact counts, abort.

    Raises
    ------
    ParameterError
        If an argument is out of range or of the wrong shape.
    SimulationError
        If more than ``max_events_per_step`` switches happen inside one step.

    Notes
    -----
    Energy balance closed by the result: ``initial + input = kinetic + potential +
    dissipated``; a contact that opens (no-tension rule) with residual penetration ``δ``
    loses its stored ``k δ²/2``, booked as dissipated.

    Examples
    --------
    >>> drive = DriveParams(bodies=(BodyParams(J=1.0, K=16.0, c_mean=0.3, fk_mean=0.07),))
    >>> rk4 = simulate_drive(drive, duration=1.0, x0=[1.0], method="rk4")
    >>> exact = simulate_drive(drive, duration=1.0, x0=[1.0], method="exact")
    >>> bool(abs(rk4.x - exact.x).max() < 1e-9), rk4.n_mode_switches
    (True, 1)
    """
    if not isinstance(params, DriveParams):
        raise ParameterError(f"params must be a DriveParams; got {type(params).__name__}")
    _require(isinstance(duration, (int, float)) and 0 < duration < math.inf,
             "duration must be positive and finite [s]", duration)
    _require(isinstance(fs, (int, float)) and 0 < fs < math.inf,
             "fs must be positive; pass the output sampling rate in Hz", fs)
    nb = params.n_bodies
    n_out = int(math.floor(duration * fs + 1e-9)) + 1
    t = np.arange(n_out) / fs
    x0 = _input_grid(x0, "x0", None, nb)
    v0 = _input_grid(v0, "v0", None, nb)
    locked = np.array([b.locked for b in params.bodies])
    if np.any(v0[locked] != 0.0):
        raise ParameterError(f"locked bodies must start at rest (v0 = 0); got v0={v0.tolist()}")
    torque = _input_grid(torque, "torque", nb, n_out)
    fb = params.feedback
    if reference is None:
        reference = 0.0 if fb is None else fb.reference
    reference = _input_grid(reference, "reference", None, n_out)[None, :]
    exact_ok = (nb == 1 and not locked[0] and params.bodies[0].K > 0 and fb is None
                and np.all(torque == torque[:, :1]))
    _require(method in ("auto", "rk4", "exact"), 'method must be "auto", "rk4" or "exact"',
             method)
    if method == "exact" and not exact_ok:
        raise ParameterError(
            'method="exact" needs one unlocked body with K > 0, no feedback and a constant '
            f"torque; use method=\"rk4\"; got {nb} bodies, feedback={fb is not None}"
        )
    if method != "rk4" and exact_ok:
        return _simulate_exact(params, duration, fs, x0, v0, float(torque[0, 0]))
    rate = _highest_rate(params)
    if max_step is None:
        max_step = 0.2 / rate if rate > 0 else 1.0 / fs
    _require(isinstance(max_step, (int, float)) and max_step > 0,
             "max_step must be positive [s]", max_step)
    if fb is not None and fb.delay > 0:
        max_step = min(max_step, fb.delay)
    n_sub = max(1, math.ceil((1.0 / fs) / max_step - 1e-9))
    _require(isinstance(max_events_per_step, int) and max_events_per_step > 0,
             "max_events_per_step must be a positive int", max_events_per_step)

    rows = [b._row() for b in params.bodies]
    rows += [[0.0] * 8 if ln is None else ln._row() + [0.0, 0.0] for ln in params.links]
    abort_limit = math.inf
    if fb is None:
        rows.append([0.0] * 8)
    else:
        rows.append([1.0, fb.body, fb.P, fb.D, fb.delay, fb.saturation, 0.0, 0.0])
        abort_limit = fb.abort_limit
    par = np.array(rows, dtype=float)
    inp = np.ascontiguousarray(np.vstack([torque, reference]))
    y0 = np.concatenate([x0, v0, np.zeros(3)])
    modes0 = np.concatenate([np.where(locked, _k.LOCKED, 1), np.zeros(nb - 1)]).astype(np.int64)
    x, v, cmd, e, counts, status, abort_index, abort_value = _k.drive_kernel(
        y0, modes0, par, inp, float(abort_limit), float(fs), n_out, n_sub,
        max_events_per_step)
    h = 1.0 / (fs * n_sub)
    if status == _k.TOO_MANY_EVENTS:
        raise SimulationError(
            f"more than max_events_per_step={max_events_per_step} mode switches in the step "
            f"at t={abort_index * h:.6g} s (chattering); add damping, reduce max_step or raise "
            "max_events_per_step"
        )
    aborted = status == _k.ABORTED
    reason = abort_time = None
    if aborted:
        abort_time = abort_index * h
        reason = (f"|command| = {abs(abort_value):.6g} N·m before saturation exceeded "
                  f"abort_limit={abort_limit:g} N·m at t={abort_time:.6g} s")
    energy = _energy(params, x, v, e, x0, v0)
    return DriveResult(t=t, x=x, v=v, command=cmd,
                       energy=energy, n_mode_switches=int(counts[0]), n_impacts=int(counts[1]),
                       aborted=aborted, abort_reason=reason, abort_time=abort_time,
                       params=params)


def _simulate_exact(params, duration, fs, x0, v0, u0) -> DriveResult:
    b = params.bodies[0]
    batch = simulate_free_decay_batch(
        J=b.J, K=b.K, c_mean=b.c_mean, c_delta=b.c_delta, fk_mean=b.fk_mean,
        fk_delta=b.fk_delta, fs_mean=b.fs_mean, fs_delta=b.fs_delta, x0=x0[0], v0=v0[0],
        u0=u0, duration=duration, fs=fs, return_velocity=True)
    x, v = batch.x, batch.v
    kin, pot = _stored(params, x, v)
    kin0, pot0 = _stored(params, x0[:, None], v0[:, None])
    initial = float(kin0[0] + pot0[0])
    work = u0 * (x[0] - x0[0])
    n_switch = int(batch.n_reversals[0])  # every velocity zero: a reversal or the final stick
    energy = {"input": work, "dissipated": initial + work - kin - pot, "kinetic": kin,
              "potential": pot, "contact_release": np.zeros_like(work), "initial": initial}
    return DriveResult(t=batch.t, x=x, v=v, command=np.zeros_like(batch.t), energy=energy,
                       n_mode_switches=n_switch, n_impacts=0, aborted=False, abort_reason=None,
                       abort_time=None, params=params)


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
    return {"input": e[0], "dissipated": e[1] + e[2] - e[4] + contact0,
            "kinetic": kin, "potential": pot + e[4], "contact_release": e[3],
            "initial": float(kin0[0] + pot0[0]) + contact0}


@dataclass(frozen=True)
class FreeDecayBatch:
    """Exact free decays of many 1-DOF parameter sets (:func:`simulate_free_decay_batch`).

    Attributes
    ----------
    t : ndarray, shape (n,)
        Output times [s].
    x : ndarray, shape (n_sets, n)
        Positions [rad or m].
    v : ndarray, shape (n_sets, n) or None
        Velocities [rad/s or m/s]; None unless ``return_velocity=True``.
    stuck_at : ndarray, shape (n_sets,)
        Time from which each body stays stuck [s]; NaN if it is still moving at the end.
    n_reversals : ndarray of int, shape (n_sets,)
        Velocity zeros after the start [-].
    """

    t: np.ndarray
    x: np.ndarray
    v: np.ndarray | None
    stuck_at: np.ndarray
    n_reversals: np.ndarray


_BATCH_FIELDS = ("J", "K", "c_mean", "c_delta", "fk_mean", "fk_delta", "fs_mean", "fs_delta")


def simulate_free_decay_batch(
    *,
    J,
    K,
    c_mean=0.0,
    c_delta=0.0,
    fk_mean=0.0,
    fk_delta=0.0,
    fs_mean=None,
    fs_delta=None,
    x0,
    v0=0.0,
    u0=0.0,
    duration: float,
    fs: float = 1000.0,
    max_reversals: int = 100_000,
    return_velocity: bool = False,
) -> FreeDecayBatch:
    """Exact free decays with stiction for many parameter sets at once (Monte Carlo).

    Parameters
    ----------
    J : array_like
        Mass or inertia [kg or kg·m²], > 0; all parameters broadcast to ``(n_sets,)``.
    K : array_like
        Stiffness [N/m or N·m/rad], > 0.
    c_mean, c_delta : array_like
        Viscous friction ``c_mean + c_delta·sgn(x')`` [N·s/m or N·m·s/rad].
    fk_mean, fk_delta : array_like
        Kinetic friction ``fk_mean·sgn(x') + fk_delta`` [N or N·m]; fk_mean >= 0.
    fs_mean, fs_delta : array_like, optional
        Static friction band ``fs_delta ± fs_mean`` [N or N·m]; default the kinetic values.
    x0, v0 : array_like
        Initial position [m or rad] and velocity [m/s or rad/s].
    u0 : array_like
        Constant applied force [N or N·m] (default 0: free decay).
    duration : float
        Simulated time [s]; > 0.
    fs : float
        Output sampling rate [Hz]; > 0.
    max_reversals : int
        Bound on the segments of one run.
    return_velocity : bool
        Also return the velocities (twice the memory: 1000 runs of 20 s at 1 kHz are 160 MB
        per array).

    Returns
    -------
    FreeDecayBatch
        Positions of every set at ``k/fs``, stick times and reversal counts.

    Raises
    ------
    ParameterError
        If a parameter is out of range (reported with the index of the first bad set).
    SimulationError
        If a run needs more than ``max_reversals`` segments.

    Notes
    -----
    The same exact piecewise closed form as :func:`driveid.sim.simulate_free_decay`
    (thesis 2.136-2.157), compiled; inside a segment the samples follow from the exact
    one-sample transition matrix, so a run costs a few flops per sample.

    Examples
    --------
    >>> b = simulate_free_decay_batch(J=1.0, K=16.0, c_mean=[0.3, 0.4], fk_mean=0.07,
    ...                               x0=1.0, duration=5.0)
    >>> b.x.shape
    (2, 5001)
    """
    _require(isinstance(duration, (int, float)) and 0 < duration < math.inf,
             "duration must be positive and finite [s]", duration)
    _require(isinstance(fs, (int, float)) and 0 < fs < math.inf,
             "fs must be positive; pass the output sampling rate in Hz", fs)
    fk_mean_a = np.asarray(fk_mean, dtype=float)
    fk_delta_a = np.asarray(fk_delta, dtype=float)
    values = [J, K, c_mean, c_delta, fk_mean_a, fk_delta_a,
              fk_mean_a if fs_mean is None else fs_mean,
              fk_delta_a if fs_delta is None else fs_delta, x0, v0, u0]
    try:
        arrays = np.broadcast_arrays(*[np.atleast_1d(np.asarray(a, dtype=float))
                                       for a in values])
    except ValueError:
        raise ParameterError(
            "parameters must broadcast to one shape (n_sets,); got shapes "
            f"{[np.shape(a) for a in values]}"
        ) from None
    arrays = [np.ascontiguousarray(a.ravel()) for a in arrays]
    Ja, Ka, cm, cd, fkm, fkd, fsm, fsd, xa, va, ua = arrays
    for name, a in zip(_BATCH_FIELDS + ("x0", "v0", "u0"), arrays, strict=True):
        bad = ~np.isfinite(a)
        if bad.any():
            i = int(np.argmax(bad))
            raise ParameterError(f"{name} must be finite; set {i} has {float(a[i])!r}")
    for name, a, ok in (("J", Ja, Ja > 0), ("K", Ka, Ka > 0), ("fk_mean", fkm, fkm >= 0),
                        ("fs band", fsm, (fsd + fsm >= fkd + fkm - 1e-12)
                         & (fsd - fsm <= fkd - fkm + 1e-12))):
        if not ok.all():
            i = int(np.argmax(~ok))
            rule = {"J": "positive", "K": "positive (the batch needs a spring)",
                    "fk_mean": ">= 0",
                    "fs band": "wide enough: fs_delta ± fs_mean must enclose fk_delta ± fk_mean"}
            raise ParameterError(f"{name} must be {rule[name]}; set {i} has {float(a[i])!r}")
    par = np.ascontiguousarray(np.stack([Ja, Ka, cm, cd, fkm, fkd, fsd - fsm, fsd + fsm],
                                        axis=1))
    n_out = int(math.floor(duration * fs + 1e-9)) + 1
    x, v, stuck_at, n_rev, ok = _k.free_decay_batch_kernel(
        par, xa, va, ua, float(fs), n_out, int(max_reversals), bool(return_velocity))
    if not ok.all():
        i = int(np.argmax(~ok))
        raise SimulationError(
            f"set {i} needs more than max_reversals={max_reversals} segments before "
            f"t={duration} s; raise max_reversals or add damping/friction"
        )
    return FreeDecayBatch(t=np.arange(n_out) / fs, x=x, v=v if return_velocity else None,
                          stuck_at=stuck_at, n_reversals=n_rev)
