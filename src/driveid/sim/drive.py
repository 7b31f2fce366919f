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
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from driveid.errors import ParameterError, SimulationError
from driveid.io.record import Record
from driveid.sim import _kernels as _k

if TYPE_CHECKING:  # imported lazily at run time (validation), see BodyParams, DriveParams
    from driveid.models.dynamic_friction import LuGreParams
    from driveid.models.motor import MotorAmplifier

__all__ = [
    "BodyParams",
    "ShaftLink",
    "BacklashLink",
    "PDFeedback",
    "DriveParams",
    "DriveResult",
    "simulate_drive",
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
    lugre : driveid.models.dynamic_friction.LuGreParams or None
        Dynamic (LuGre) friction on this body instead of the static map: then c_mean,
        c_delta, fk_mean, fk_delta must be 0 and fs_mean, fs_delta None (simulated by the
        smooth integrator ``driveid.sim._smooth``).
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
    lugre: LuGreParams | None = None

    def __post_init__(self) -> None:
        for name in ("J", "K", "c_mean", "c_delta", "fk_mean", "fk_delta"):
            _finite("BodyParams", name, getattr(self, name))
        if self.lugre is not None:
            from driveid.models.dynamic_friction import LuGreParams

            _require(isinstance(self.lugre, LuGreParams),
                     "BodyParams.lugre must be a LuGreParams or None", self.lugre)
            static = [getattr(self, n) for n in ("c_mean", "c_delta", "fk_mean", "fk_delta",
                                                   "fs_mean", "fs_delta")]
            # fs_* may come back as 0.0 from dataclasses.replace of a filled instance
            if any(v not in (None, 0.0) for v in static):
                raise ParameterError(
                    "choose one friction model: with BodyParams.lugre set, c_mean, c_delta, "
                    "fk_mean, fk_delta must be 0 and fs_mean, fs_delta None; got "
                    f"c_mean={self.c_mean}, c_delta={self.c_delta}, fk_mean={self.fk_mean}, "
                    f"fk_delta={self.fk_delta}, fs_mean={self.fs_mean}, "
                    f"fs_delta={self.fs_delta}")
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
        return [_k.LINK_SHAFT, self.k, self.c, 0.0, 0.0, 0.0, 0.0, 0.0]


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
    contact : {"viscoelastic", "restitution"}
        ``"viscoelastic"`` (default): the Kelvin–Voigt contact above. ``"restitution"``: an
        instantaneous Newton impact at the gap edge, ``v_rel' = -e v_rel`` with momentum
        kept (``v1' = v1 - (1+e) m2/(m1+m2) v_rel``, ``v2' = v2 + (1+e) m1/(m1+m2) v_rel``;
        a locked body has infinite inertia), losing ``½ μ (1 - e²) v_rel²`` [J],
        ``μ = m1 m2/(m1+m2)``.
    restitution : float or None
        Coefficient of restitution e [-], 0 <= e <= 1; required with ``"restitution"``.
    rest_velocity : float
        Resting-contact rule of ``"restitution"`` [rad/s], > 0: an impact slower than this
        (the tail of a Zeno sequence of bounces under a steady push) closes the compliant
        ``k``, ``c`` contact instead, so the bodies move together until its force would
        become tensile, then separate (default 1e-4).
    """

    gap_plus: float
    gap_minus: float
    k: float
    c: float = 0.0
    allow_tension: bool = False
    contact: str = "viscoelastic"
    restitution: float | None = None
    rest_velocity: float = 1e-4

    def __post_init__(self) -> None:
        for name in ("gap_plus", "gap_minus", "c"):
            _require(_finite("BacklashLink", name, getattr(self, name)) >= 0,
                     f"BacklashLink.{name} must be >= 0", getattr(self, name))
        _require(_finite("BacklashLink", "k", self.k) > 0, "BacklashLink.k must be positive",
                 self.k)
        _require(self.contact in ("viscoelastic", "restitution"),
                 'BacklashLink.contact must be "viscoelastic" or "restitution"', self.contact)
        if self.contact == "restitution":
            _require(self.restitution is not None
                     and 0.0 <= _finite("BacklashLink", "restitution", self.restitution) <= 1.0,
                     "BacklashLink.restitution must be in [0, 1] with contact=\"restitution\"",
                     self.restitution)
            _require(not self.allow_tension, "a restitution contact cannot pull; pass "
                     "allow_tension=False", self.allow_tension)
            _require(_finite("BacklashLink", "rest_velocity", self.rest_velocity) > 0,
                     "BacklashLink.rest_velocity must be positive [rad/s]", self.rest_velocity)
        else:
            _require(self.restitution is None, "BacklashLink.restitution needs "
                     'contact="restitution"', self.restitution)

    def _row(self) -> list[float]:
        if self.contact == "restitution":
            return [_k.LINK_IMPACT, self.k, self.c, self.gap_plus, self.gap_minus, 0.0,
                    float(self.restitution), self.rest_velocity]
        return [_k.LINK_BACKLASH, self.k, self.c, self.gap_plus, self.gap_minus,
                float(self.allow_tension), 0.0, 0.0]


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
    motor : driveid.models.motor.MotorAmplifier or None
        Electrical motor/amplifier on the feedback body (body 0 without feedback): the
        feedback or external command becomes the amplifier input [V or A, per the model]
        (simulated by the smooth integrator ``driveid.sim._smooth``).
    """

    bodies: tuple
    links: tuple = ()
    feedback: PDFeedback | None = None
    motor: MotorAmplifier | None = None

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
        if self.motor is not None:
            try:  # lazy: sim imports models, and the motor model is optional
                from driveid.models.motor import MotorAmplifier
            except ImportError:  # pragma: no cover - only while the model is missing
                raise ParameterError("DriveParams.motor needs driveid.models.motor."
                                     "MotorAmplifier, which is not available") from None
            _require(isinstance(self.motor, MotorAmplifier),
                     "DriveParams.motor must be a driveid.models.motor.MotorAmplifier or None",
                     self.motor)

    @property
    def smooth(self) -> bool:
        """True if a body has LuGre friction or a motor model is set (smooth integrator)."""
        return self.motor is not None or any(b.lugre is not None for b in self.bodies)

    @property
    def n_bodies(self) -> int:
        """Number of bodies [-]."""
        return len(self.bodies)


@dataclass(frozen=True)
class DriveResult:
    """Sampled response of :func:`simulate_drive`.

    Built by keyword with every field below (other simulators of the package, e.g. the
    smooth integrator ``driveid.sim._smooth``, return it too): ``DriveResult(t=, x=, v=,
    command=, energy=, n_mode_switches=, n_impacts=, aborted=, abort_reason=, abort_time=,
    params=)``.

    Attributes
    ----------
    t : ndarray, shape (n,)
        Output times [s].
    x, v : ndarray, shape (n_bodies, n)
        Positions [rad] and velocities [rad/s]; NaN after an abort.
    command : ndarray, shape (n,) or (n_bodies, n)
        Saturated feedback or controller command [N·m] (zeros without feedback); shape
        (n_bodies, n) when a controller callback returns one torque per body.
    energy : dict of str to ndarray, shape (n,)
        ``input`` (work of external torques and command) [J], ``dissipated`` (friction,
        viscous, shaft and contact damping, contact release, impacts) [J], ``kinetic``,
        ``potential`` (ground springs, shafts, closed contacts) [J], ``contact_release``
        (the part of ``dissipated`` lost when no-tension contacts open) [J], ``impact``
        (the part lost in restitution impacts) [J] and ``initial`` (scalar) [J]. A
        simulator may add keys; the balance ``initial + input = kinetic + potential +
        dissipated`` must hold.
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
        u = self.command if self.command.ndim == 1 else self.command[body]
        return Record(t=self.t[keep], x=self.x[body][keep], v=self.v[body][keep],
                      u=u[keep], meta=meta, max_jitter=None)


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
    controller=None,
    control_rate: float | None = None,
    controller_delay: int = 0,
    controller_body: int = 0,
    saturation: float = math.inf,
    abort_limit: float = math.inf,
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
        Largest RK4 step [s]; default ``0.2/rate`` for the fastest rate of the drive (and
        no larger than the delay or the output interval).
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

    Returns
    -------
    DriveResult
        Positions, velocities, command, energy balance, switch and impact counts, abort.

    Raises
    ------
    ParameterError
        If an argument is out of range or of the wrong shape.
    SimulationError
        If more than ``max_events_per_step`` switches happen inside one step, or the
        controller returns a non-finite torque.

    Notes
    -----
    Energy balance closed by the result: ``initial + input = kinetic + potential +
    dissipated``; a contact that opens (no-tension rule) with residual penetration ``δ``
    loses its stored ``k δ²/2``, booked as dissipated, and so is the loss of restitution
    impacts.

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
        return _simulate_controlled(
            params, duration, fs, x0, v0, torque, max_step, max_events_per_step, method,
            controller, control_rate, controller_delay, controller_body, saturation,
            abort_limit)
    _require(control_rate is None, "control_rate needs a controller callback", control_rate)
    run = _prepare(params, duration, fs, x0, v0, torque, reference, max_step,
                   max_events_per_step)
    nb, torque, fb = params.n_bodies, run["torque"], params.feedback
    exact_ok = (nb == 1 and not run["locked"][0] and params.bodies[0].K > 0 and fb is None
                and np.all(torque == torque[:, :1]))
    if method == "exact" and not exact_ok:
        raise ParameterError(
            'method="exact" needs one unlocked body with K > 0, no feedback and a constant '
            f"torque; use method=\"rk4\"; got {nb} bodies, feedback={fb is not None}"
        )
    if method != "rk4" and exact_ok:
        return _simulate_exact(params, duration, fs, run["x0"], run["v0"],
                               float(torque[0, 0]))
    out = _k.drive_kernel(run["y0"], run["modes0"], run["par"], run["inp"],
                          run["abort_limit"], float(fs), run["n_out"], run["n_sub"],
                          max_events_per_step, False, np.zeros(2))
    return _finish(params, run, *out[:8], max_events_per_step)


def _prepare(params, duration, fs, x0, v0, torque, reference, max_step, max_events) -> dict:
    """Validate the run and build the kernel's inputs (see :func:`_k.drive_kernel`)."""
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
    torque = _input_grid(torque, "torque", nb, n_out)
    fb = params.feedback
    if reference is None:
        reference = 0.0 if fb is None else fb.reference
    reference = _input_grid(reference, "reference", None, n_out)[None, :]
    rate = _highest_rate(params)
    if max_step is None:
        max_step = 0.2 / rate if rate > 0 else 1.0 / fs
    _require(isinstance(max_step, (int, float)) and max_step > 0,
             "max_step must be positive [s]", max_step)
    if fb is not None and fb.delay > 0:
        max_step = min(max_step, fb.delay)
    rows = [b._row() for b in params.bodies]
    rows += [[0.0] * 8 if ln is None else ln._row() for ln in params.links]
    rows.append([0.0] * 8 if fb is None else
                [1.0, fb.body, fb.P, fb.D, fb.delay, fb.saturation, 0.0, 0.0])
    return {
        "t": np.arange(n_out) / fs, "n_out": n_out, "x0": x0, "v0": v0, "locked": locked,
        "torque": torque, "fs": float(fs), "max_step": max_step,
        "n_sub": max(1, math.ceil((1.0 / fs) / max_step - 1e-9)),
        "par": np.array(rows, dtype=float),
        "inp": np.ascontiguousarray(np.vstack([torque, reference])),
        "y0": np.concatenate([x0, v0, np.zeros(3)]),
        "modes0": np.concatenate([np.where(locked, _k.LOCKED, 1),
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
    energy = _energy(params, x, v, e, run["x0"], run["v0"])
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
    run = _prepare(params, duration, fs, x0, v0, torque, None, max_step, max_events)
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
        xk, vk, _, ek, ck, st, ai, _, modes = _k.drive_kernel(
            y, modes, par, inp, math.inf, fs_in, s1 - s0 + 1, n_sub, max_events, k > 0, jump)
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
    from driveid.sim.batch import simulate_free_decay_batch  # batch builds on this module

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
              "potential": pot, "contact_release": np.zeros_like(work),
              "impact": np.zeros_like(work), "initial": initial}
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
    return {"input": e[0], "dissipated": e[1] + e[2] - e[4] + e[5] + contact0,
            "kinetic": kin, "potential": pot + e[4], "contact_release": e[3], "impact": e[5],
            "initial": float(kin0[0] + pot0[0]) + contact0}
