r"""Parameter and result types of the lumped drive (thesis §2.1.4, §3.2.2, App. B.2).

The bottom of :mod:`driveid.sim`: the engines (the event-located RK4 of
:mod:`driveid.sim._kernels`, the smooth integrator :mod:`driveid.sim._smooth`) read these
types, :func:`driveid.sim.drive.simulate_drive` chooses an engine, and
:mod:`driveid.sim.batch` runs many drives on top of it. Nothing here imports an engine.

Friction of a moving body (direction ``s = sgn(x')``), thesis 2.155 with the sign conventions
of ``shared/DESIGN.md`` and an optional level periodic in position (cogging, gear-mesh or
ball-screw ripple):

.. math:: F_{fric} = (c_{mean} + c_{delta} s) x' + (f_{k,mean} + r(x)) s + f_{k,delta},
   \qquad r(x) = A \sin(2\pi x / P + \varphi)

with ``A = ripple_amplitude``, ``P = ripple_period``, ``φ = ripple_phase``: the ripple adds
to the kinetic (Coulomb) level and so always opposes the motion. Sticking uses the static
band ``[fs_delta - fs_mean, fs_delta + fs_mean]`` (2.137, 2.138), which must enclose the
kinetic band at every position.

With a Stribeck map (``stribeck``, thesis Eqs. 2.3, 2.5; 2.2 through 2.4) the friction of a
body moving in direction ``s`` falls from the static edge ``fs_s = fs_mean + s fs_delta`` at
v = 0 to the kinetic level ``fk_s = fk_mean + s fk_delta``:

.. math:: F_{fric} = s\,[f_{k,s} + \rho\,(f_{s,s} - f_{k,s})\, g(|x'| / v_{S,s})]
   + (c_{mean} + c_{delta} s) x', \qquad v_{S,s} = v_s + s\, v_{s,delta}

with ``g(r) = 1/(1 + r²)`` (Lorentzian) or ``exp(-r**delta)`` (Bo–Pavelescu), so each
direction is a one-sided map of :mod:`driveid.models.friction` (the ``±`` branches of
``asymmetric_friction``). ``ρ = 1`` unless the static friction rises with dwell
(``dwell_gamma``, Kato/Howe Eq. 2.6): then the band a stuck body must overcome is
``fk + (fs - fk)·ρ(t)``, ``ρ(t) = 1 - exp(-t**kappa/gamma)`` of the time ``t`` it has been
stuck, and the slip phase keeps the ``ρ`` reached at breakaway (Eq. 2.9). With frictional
memory (``memory`` = Δt, Eq. 2.12) the shape ``g`` reads the velocity one lag ago,
``g(|x'(t - Δt)| / v_{S,s})``, while ``s`` and the viscous term stay those of the current
velocity.

References
----------
.. [1] J. A. de Marchi, "Modeling of dynamic friction, impact backlash and elastic
       compliance nonlinearities in machine tools", PhD thesis, RPI, 1998, §2.1.4, §3.2.2,
       App. B.2.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from driveid.errors import ParameterError
from driveid.io.record import Record

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
        takes the kinetic value. The band must enclose the kinetic band (with a Stribeck
        map only 0: the map starts at the static edge, so no jump follows a breakaway).
    locked : bool
        True: the body is clamped and never moves (a locked axis of the test bed).
    lugre : driveid.models.dynamic_friction.LuGreParams or None
        Dynamic (LuGre) friction on this body instead of the static map: then c_mean,
        c_delta, fk_mean, fk_delta must be 0 and fs_mean, fs_delta None (simulated by the
        smooth integrator ``driveid.sim._smooth``).
    ripple_amplitude : float
        Amplitude ``A`` of a friction level periodic in position [N·m or N], 0 <= A <=
        fk_mean (default 0: none): the kinetic level becomes ``fk_mean + A sin(2π x / P +
        φ)``, always opposing the motion (module docstring); a position-dependent Coulomb
        friction (cogging, gear mesh, ball screw). Event-located RK4 path only.
    ripple_period : float or None
        Its period ``P`` in position [rad or m], > 0; required when ``ripple_amplitude > 0``.
    ripple_phase : float
        Its phase ``φ`` at ``x = 0`` [rad] (default 0).
    stribeck : {None, "lorentzian", "bo_pavelescu"}
        Stribeck map of the slip phase (default None: the static level drops to the kinetic
        one at once). ``"lorentzian"`` is Eq. 2.3, ``"bo_pavelescu"`` Eq. 2.5 (Hess–Soom 2.2
        through :meth:`from_hess_soom`): in direction ``s`` friction falls from the static
        edge ``fs_s`` at v = 0 towards the kinetic level ``fk_s`` as ``g(|v|/v_s,s)``
        (module docstring); not with a ripple or LuGre.
    v_s : float or None
        Stribeck velocity [rad/s or m/s], > 0; required with ``stribeck``.
    v_s_delta : float
        Signed asymmetry of the Stribeck velocity [rad/s or m/s]: ``v_s ± v_s_delta`` for
        v > 0 and v < 0 (default 0); ``|v_s_delta| < v_s``.
    stribeck_exponent : float
        Exponent ``delta`` of the Bo–Pavelescu map [-], > 0 (default 2: Gaussian).
    dwell_gamma : float or None
        Rising static friction with dwell (Kato/Howe, Eq. 2.6): the static band rises from the
        kinetic band at the moment of sticking to ``fs_mean, fs_delta`` as ``1 - exp(-t**kappa
        / gamma)`` of the time stuck ``t`` [s**kappa], > 0 (default None: no rise). A body at
        rest at the start has stuck at t = 0. With ``stribeck`` the slip phase's excess is the
        risen one (Eq. 2.9).
    dwell_kappa : float
        Exponent ``kappa`` of Eq. 2.6 [-], > 0 (default 1).
    memory : float
        Frictional memory Δt [s], >= 0 (default 0: none; Eq. 2.12, Hess–Soom): the Stribeck
        shape of the slip friction reads the velocity Δt ago, so friction lags the velocity
        and traces a hysteresis loop against it (lower while accelerating, higher while
        decelerating). The direction (sign) and the viscous term stay those of the current
        velocity, so friction never pushes. The velocity history is the body's own motion,
        zero while it is stuck: right after a breakaway the friction starts at the static
        edge and falls along the map Δt late; before t = 0 the history is the initial
        velocity. Sticking and breakaway still follow the static band (2.137). Needs
        ``stribeck`` (the memory acts on the Stribeck part only; a Coulomb level has no
        velocity to lag). Event-located RK4 path only, every grid step (no strides), and
        not with a ``controller`` callback (its resumed runs would lose the history).
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
    ripple_amplitude: float = 0.0
    ripple_period: float | None = None
    ripple_phase: float = 0.0
    stribeck: str | None = None
    v_s: float | None = None
    v_s_delta: float = 0.0
    stribeck_exponent: float = 2.0
    dwell_gamma: float | None = None
    dwell_kappa: float = 1.0
    memory: float = 0.0

    def __post_init__(self) -> None:
        for name in ("J", "K", "c_mean", "c_delta", "fk_mean", "fk_delta", "ripple_amplitude",
                     "ripple_phase"):
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
        self._check_ripple()
        self._check_stribeck_and_dwell()
        # the static band must hold the kinetic level at every position: with a ripple its
        # default is the kinetic peak
        fs_mean = self.fk_mean + self.ripple_amplitude if self.fs_mean is None else _finite(
            "BodyParams", "fs_mean", self.fs_mean)
        fs_delta = self.fk_delta if self.fs_delta is None else _finite(
            "BodyParams", "fs_delta", self.fs_delta)
        object.__setattr__(self, "fs_mean", fs_mean)
        object.__setattr__(self, "fs_delta", fs_delta)
        eps = 1e-12 * max(1.0, abs(self.fk_mean) + abs(self.fk_delta))
        fk_peak = self.fk_mean + self.ripple_amplitude
        if self.stribeck is not None:
            # the map is continuous at breakaway (it starts at the static edge), so the
            # static level may lie below the kinetic one (friction rising with speed); each
            # edge must still oppose the motion
            _require(fs_mean >= abs(fs_delta) - eps, "BodyParams.fs_mean must be >= "
                     "|fs_delta| with a Stribeck map so each static edge opposes the motion",
                     fs_mean)
        elif (fs_delta + fs_mean < self.fk_delta + fk_peak - eps
                or fs_delta - fs_mean > self.fk_delta - fk_peak + eps):
            raise ParameterError(
                "static friction must hold at least the kinetic friction (with its ripple "
                "peak) in each direction; raise fs_mean or pass None; got "
                f"fs_mean={fs_mean}, fs_delta={fs_delta}, fk_mean={self.fk_mean}, "
                f"fk_delta={self.fk_delta}, ripple_amplitude={self.ripple_amplitude}"
            )

    def _check_ripple(self) -> None:
        a = self.ripple_amplitude
        _require(0.0 <= a <= self.fk_mean, "BodyParams.ripple_amplitude must be in [0, "
                 "fk_mean] [N·m] so the kinetic level fk_mean + A sin(...) never drops below "
                 "0; lower it or raise fk_mean", a)
        if self.ripple_period is not None:
            _require(_finite("BodyParams", "ripple_period", self.ripple_period) > 0,
                     "BodyParams.ripple_period must be positive [rad or m]",
                     self.ripple_period)
        _require(a == 0.0 or self.ripple_period is not None, "BodyParams.ripple_period "
                 "[rad or m] is needed with ripple_amplitude > 0; pass the period", None)

    def _check_stribeck_and_dwell(self) -> None:
        _require(self.stribeck in (None, "lorentzian", "bo_pavelescu"),
                 'BodyParams.stribeck must be None, "lorentzian" or "bo_pavelescu"',
                 self.stribeck)
        for name in ("v_s_delta", "stribeck_exponent", "dwell_kappa"):
            _finite("BodyParams", name, getattr(self, name))
        if self.stribeck is not None:
            _require(self.v_s is not None and _finite("BodyParams", "v_s", self.v_s) > 0,
                     "BodyParams.v_s [rad/s or m/s] must be positive with a Stribeck map; "
                     "pass the Stribeck velocity", self.v_s)
            _require(abs(self.v_s_delta) < self.v_s, "BodyParams.v_s_delta must lie inside "
                     "(-v_s, v_s) so both branches have a positive Stribeck velocity",
                     self.v_s_delta)
        _require(self.stribeck_exponent > 0, "BodyParams.stribeck_exponent must be > 0",
                 self.stribeck_exponent)
        if self.dwell_gamma is not None:
            _require(_finite("BodyParams", "dwell_gamma", self.dwell_gamma) > 0,
                     "BodyParams.dwell_gamma must be positive [s**kappa] or None",
                     self.dwell_gamma)
        _require(self.dwell_kappa > 0, "BodyParams.dwell_kappa must be > 0",
                 self.dwell_kappa)
        _require(_finite("BodyParams", "memory", self.memory) >= 0,
                 "BodyParams.memory must be >= 0 [s] (0: no frictional memory)", self.memory)
        _require(self.memory == 0.0 or self.stribeck is not None,
                 "BodyParams.memory acts on the Stribeck part of the slip friction only: set "
                 'stribeck (e.g. "lorentzian" with v_s) or memory = 0', self.memory)
        extended = self.stribeck is not None or self.dwell_gamma is not None
        _require(not (extended and (self.has_ripple or self.lugre is not None)),
                 "BodyParams.stribeck and dwell_gamma take the Coulomb + viscous map: set "
                 "ripple_amplitude = 0 and lugre = None with them", self.stribeck)

    @classmethod
    def from_hess_soom(cls, *, J: float, params, **others) -> BodyParams:
        """Build a body whose slip friction is Hess and Soom's map, Eqs. (2.1)-(2.2), via (2.4).

        Parameters
        ----------
        J : float
            Mass [kg] (Hess and Soom's map is translational).
        params : driveid.models.friction.HessSoomParams
            Static friction ``mu_s`` [N], constants ``c1`` [-], ``c2`` [N], viscosity, load,
            modulus and contact length.
        **others
            Further :class:`BodyParams` fields (``K``, ``locked`` ...), not friction.

        Returns
        -------
        BodyParams
            ``stribeck="lorentzian"`` with ``fk_mean = 0``, ``fs_mean = mu_s``,
            ``v_s = sqrt(W E) / (eta sqrt(c1))`` and ``c_mean = c2 eta l / W`` (the inverse of
            Eq. 2.4); ``c1 = 0`` gives Coulomb friction ``mu_s`` without a Stribeck drop.

        Examples
        --------
        >>> from driveid.models.friction import HessSoomParams
        >>> hs = HessSoomParams(mu_s=4.0, c1=1.0, c2=0.5, eta=1.0, W=1.0, E=1.0, l=1.0)
        >>> b = BodyParams.from_hess_soom(J=1.0, params=hs)
        >>> (b.v_s, b.c_mean, b.fs_mean)
        (1.0, 0.5, 4.0)
        """
        p = params
        c_mean = p.c2 * p.eta * p.l / p.W
        if p.c1 == 0.0:
            return cls(J=J, fk_mean=p.mu_s, c_mean=c_mean, **others)
        v_s = math.sqrt(p.W * p.E) / (p.eta * math.sqrt(p.c1))
        return cls(J=J, fk_mean=0.0, fs_mean=p.mu_s, c_mean=c_mean, stribeck="lorentzian",
                   v_s=v_s, **others)

    @property
    def is_plain_coulomb(self) -> bool:
        """True if friction is Coulomb + viscous with a static band alone (the exact path).

        No ripple, Stribeck map, rising static friction or LuGre.
        """
        return (not self.has_ripple and self.stribeck is None and self.dwell_gamma is None
                and self.lugre is None)

    @property
    def stribeck_slope(self) -> float:
        """Steepest fall of the Stribeck term with speed, ``max |dF/dv|`` [N·m·s/rad].

        Sets the body's negative damping for the RK4 step (0 without a Stribeck map).
        """
        if self.stribeck is None:
            return 0.0
        excess = max(self.fs_mean + abs(self.fs_delta) - self.fk_mean + abs(self.fk_delta),
                     0.0)
        if self.stribeck == "lorentzian":
            shape = 3.0 * math.sqrt(3.0) / 8.0  # max of 2r/(1+r²)² at r = 1/sqrt(3)
        else:  # max of d exp(-r^d)/dr, at r^d = (d-1)/d (d < 1: steep only near v = 0)
            d = max(self.stribeck_exponent, 1.0)
            q = (d - 1.0) / d
            shape = d * q ** q * math.exp(-q) if q > 0 else 1.0
        return excess * shape / (self.v_s - abs(self.v_s_delta))

    @property
    def has_ripple(self) -> bool:
        """True if the kinetic friction level varies with position (ripple_amplitude > 0)."""
        return self.ripple_amplitude > 0.0


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
        Stick, breakaway and reversal transitions of the bodies [-] (a body whose friction
        is viscous alone has none: the sign of its velocity changes nothing).
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

    @property
    def record(self) -> Record:
        """The response of body 0 as a :class:`~driveid.io.record.Record`.

        The same kind of member as :attr:`driveid.sim.FreeDecay.record`; other bodies:
        :meth:`body_record`.
        """
        return self.body_record(0)

    def body_record(self, body: int = 0) -> Record:
        """Return the response of one body as a :class:`~driveid.io.record.Record`.

        Parameters
        ----------
        body : int
            Body index, 0-based as in ``DriveParams.bodies`` and the TOML paths
            (``body[0]``); the CSV written by ``driveid simulate drive`` numbers its columns
            from 1 (``x1`` is body 0), as the thesis letters bodies A, B, C.

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
