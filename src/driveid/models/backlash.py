r"""Backlash: deadzone and viscoelastic two-body impact (de Marchi 1998, §2.1.2).

Two parts:

* the **deadzone** (play) of Eq. (2.27), with unequal clearances ``gap_plus`` and
  ``gap_minus`` (both given as non-negative magnitudes), and
* the **impact** of two bodies ``m1``, ``m2`` through a Kelvin–Voigt contact of stiffness
  ``k`` and damping ``c`` (Eqs. 2.28–2.73): modal coordinates, contact force, impulse,
  coefficient of restitution and contact duration in closed form, and the mappings
  between ``(k, c)``, ``(zeta, omega0)``, restitution and contact duration (those in
  :mod:`driveid.models.contact`, re-exported here).

Sign convention: the relative displacement ``delta = x1 - x2`` is the *penetration* on
the positive side of the gap; a positive contact force pushes body 2 forward (+) and
body 1 back (-).

Contact rule (the flag ``allow_tension``)
----------------------------------------
The linear Kelvin–Voigt force ``k*delta + c*delta_dot`` becomes negative (tensile, the
bodies pull each other) just before the penetration returns to zero, because
``delta_dot < 0`` there. Two rules are offered:

``allow_tension=False`` (default, Modelica ``ElastoBacklash``)
    The force is ``max(0, k*delta + c*delta_dot)``: damping never pulls the bodies
    together. Contact ends when the force reaches zero, at ``omega_d*t = 2*arccos(zeta)``,
    before the penetration has returned to zero; the bodies then part at constant relative
    velocity. Restitution ``e = exp(-2*zeta*arccos(zeta)/sqrt(1-zeta**2))``, which lies in
    ``(exp(-2), 1]`` for ``0 <= zeta < 1``.
``allow_tension=True`` (the thesis's linear model, Eqs. 2.62, 2.71-2.72)
    Contact ends when the penetration returns to zero, at ``omega_d*t = pi``. Restitution
    ``e = exp(-pi*zeta/sqrt(1-zeta**2))``, which tends to 0 as ``zeta -> 1``.

The no-tension rule is the default because a contact cannot transmit tension; it gives a
shorter contact and a larger restitution than the linear model for the same ``(k, c)``.

References
----------
.. [1] J. A. de Marchi, "Modeling of dynamic friction, impact backlash and elastic
       compliance nonlinearities in machine tools", PhD thesis, RPI, 1998, §2.1.2.
.. [2] Modelica Standard Library, ``Modelica.Mechanics.Rotational.Components.ElastoBacklash``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from driveid.errors import ParameterError
from driveid.models.contact import (
    ContactParams,
    _check,
    _finite,
    _out,
    _positive_array,
    contact_duration,
    contact_params_from_restitution,
    effective_mass,
    k_c_from_zeta_omega0,
    lumped_damping,
    lumped_stiffness,
    phase_lag,
    restitution,
    thesis_contact_duration,
    zeta_from_restitution,
    zeta_omega0_from_k_c,
)

__all__ = [
    "BacklashParams",
    "ContactParams",
    "ImpactParams",
    "ImpactResponse",
    "deadzone_map",
    "backlash_play",
    "backlash_rate",
    "contact_force",
    "backlash_contact_force",
    "effective_mass",
    "lumped_stiffness",
    "lumped_damping",
    "zeta_omega0_from_k_c",
    "k_c_from_zeta_omega0",
    "restitution",
    "zeta_from_restitution",
    "contact_duration",
    "phase_lag",
    "thesis_contact_duration",
    "contact_params_from_restitution",
    "impact_response",
    "impact_force",
    "impact_impulse",
    "post_impact_velocities",
]

# --------------------------------------------------------------------------- parameters
@dataclass(frozen=True, kw_only=True)
class BacklashParams:
    """Clearances of a backlash deadzone (Eq. 2.27).

    Parameters
    ----------
    gap_plus : float
        Clearance on the positive side [m or rad], >= 0: contact when ``x1 - x2 = gap_plus``.
    gap_minus : float
        Clearance on the negative side as a magnitude [m or rad], >= 0: contact when
        ``x1 - x2 = -gap_minus``. The thesis's signed ``x_-`` equals ``-gap_minus``.
    """

    gap_plus: float
    gap_minus: float

    def __post_init__(self):
        for name in ("gap_plus", "gap_minus"):
            v = _finite(name, getattr(self, name))
            _check(name, v, v >= 0.0, "non-negative [m or rad]", "give the clearance magnitude")


@dataclass(frozen=True, kw_only=True)
class ImpactParams:
    """Two bodies colliding through an underdamped Kelvin–Voigt contact (Eqs. 2.30–2.40).

    Parameters
    ----------
    m1 : float
        Mass (or inertia) of the impacting body [kg or kg·m²], > 0.
    m2 : float
        Mass (or inertia) of the impacted body [kg or kg·m²], > 0.
    k : float
        Contact stiffness [N/m or N·m/rad], > 0.
    c : float
        Contact damping [N·s/m or N·m·s/rad], >= 0, with ``zeta = c/(2*m*omega0) < 1``.

    Attributes
    ----------
    m : float
        Effective mass ``m1*m2/(m1+m2)`` [kg] (Eq. 2.33).
    omega0 : float
        Undamped contact frequency ``sqrt(k/m)`` [rad/s] (Eq. 2.36).
    zeta : float
        Damping ratio ``c/(2*m*omega0)`` [-] (Eq. 2.37).
    omega_d : float
        Damped contact frequency ``omega0*sqrt(1-zeta**2)`` [rad/s] (Eq. 2.40).
    """

    m1: float
    m2: float
    k: float
    c: float

    def __post_init__(self):
        for name in ("m1", "m2"):
            v = _finite(name, getattr(self, name))
            _check(name, v, v > 0.0, "positive [kg or kg·m²]")
        ContactParams(k=self.k, c=self.c)
        z = self.zeta
        _check(
            "zeta", z, z < 1.0, "< 1 (underdamped contact)",
            f"c={self.c!r} is at or above critical damping 2*sqrt(k*m)",
        )

    @property
    def m(self) -> float:
        """Effective mass [kg] (2.33)."""
        return self.m1 * self.m2 / (self.m1 + self.m2)

    @property
    def omega0(self) -> float:
        """Undamped contact frequency [rad/s] (2.36)."""
        return float(np.sqrt(self.k / self.m))

    @property
    def zeta(self) -> float:
        """Damping ratio [-] (2.37)."""
        return float(self.c / (2.0 * np.sqrt(self.k * self.m)))

    @property
    def omega_d(self) -> float:
        """Damped contact frequency [rad/s] (2.40)."""
        return self.omega0 * float(np.sqrt(1.0 - self.zeta**2))

    @property
    def contact(self) -> ContactParams:
        """The contact law ``(k, c)`` alone, for :func:`contact_force`."""
        return ContactParams(k=self.k, c=self.c)


# --------------------------------------------------------------------------- deadzone
def deadzone_map(x, params: BacklashParams):
    """Map an input through a static deadzone of unit slope (Fig. 1.3; Tao and Kokotović).

    Parameters
    ----------
    x : float or ndarray
        Input displacement [m or rad].
    params : BacklashParams
        Clearances [m or rad].

    Returns
    -------
    float or ndarray
        ``x - gap_plus`` above ``gap_plus``, ``x + gap_minus`` below ``-gap_minus``, else 0
        [m or rad].

    Examples
    --------
    >>> deadzone_map([-2.0, 0.5, 3.0], BacklashParams(gap_plus=1.0, gap_minus=0.5))
    array([-1.5,  0. ,  2. ])
    """
    x = np.asarray(x, dtype=float)
    y = np.where(x > params.gap_plus, x - params.gap_plus, 0.0)
    y = np.where(x < -params.gap_minus, x + params.gap_minus, y)
    return _out(y)


def backlash_play(x1, params: BacklashParams, *, x2_initial: float | None = None) -> np.ndarray:
    """Receiver position of a rigid backlash driven by a sampled input (Eq. 2.27).

    The exact discrete solution of Eq. (2.27): the receiver stays put until the actuator
    reaches one side of the gap, then follows it,
    ``x2[n] = min(max(x2[n-1], x1[n] - gap_plus), x1[n] + gap_minus)``.

    Parameters
    ----------
    x1 : array_like, shape (n,)
        Actuator positions [m or rad], in time order.
    params : BacklashParams
        Clearances [m or rad].
    x2_initial : float, optional
        Receiver position before the first sample [m or rad]; must lie inside the gap,
        ``x1[0] - gap_plus <= x2_initial <= x1[0] + gap_minus``. Default ``x1[0]``, clamped.

    Returns
    -------
    ndarray, shape (n,)
        Receiver positions [m or rad].

    Raises
    ------
    ParameterError
        If ``x2_initial`` lies outside the gap.

    Examples
    --------
    >>> backlash_play([0.0, 1.0, 2.0, 1.0, 0.0], BacklashParams(gap_plus=0.5, gap_minus=0.5))
    array([0. , 0.5, 1.5, 1.5, 0.5])
    """
    x1 = np.atleast_1d(np.asarray(x1, dtype=float))
    lo = x1 - params.gap_plus
    hi = x1 + params.gap_minus
    if x2_initial is None:
        prev = float(x1[0]) if x1.size else 0.0
    else:
        prev = float(x2_initial)
        if x1.size and not (lo[0] <= prev <= hi[0]):
            raise ParameterError(
                f"x2_initial must lie inside the gap [{lo[0]!r}, {hi[0]!r}] [m or rad]; "
                f"got {prev!r}"
            )
    out = np.empty_like(x1)
    for i in range(x1.size):
        prev = min(max(prev, lo[i]), hi[i])
        out[i] = prev
    return out


def backlash_rate(x1_dot, x1, x2, params: BacklashParams, *, tol: float = 0.0):
    """Receiver velocity of a rigid backlash, the state derivative of Eq. (2.27).

    Parameters
    ----------
    x1_dot : float or ndarray
        Actuator velocity [m/s or rad/s].
    x1 : float or ndarray
        Actuator position [m or rad].
    x2 : float or ndarray
        Receiver position [m or rad].
    params : BacklashParams
        Clearances [m or rad].
    tol : float, optional
        Distance to a gap side counted as contact [m or rad], >= 0 (for integrators).

    Returns
    -------
    float or ndarray
        ``x1_dot`` while pushing on either side of the gap, else 0 [m/s or rad/s].

    Notes
    -----
    Eq. (2.27): ``x2_dot = x1_dot`` if ``x1_dot > 0`` and ``x1 - x2 = x_+``, or
    ``x1_dot < 0`` and ``x1 - x2 = x_-``; here ``x_+ = gap_plus`` and ``x_- = -gap_minus``.
    """
    rel = np.asarray(x1, dtype=float) - np.asarray(x2, dtype=float)
    v = np.asarray(x1_dot, dtype=float)
    push_plus = (v > 0) & (rel >= params.gap_plus - tol)
    push_minus = (v < 0) & (rel <= -params.gap_minus + tol)
    return _out(np.where(push_plus | push_minus, v, 0.0))


# --------------------------------------------------------------------------- contact law
def contact_force(delta, delta_dot, params, allow_tension: bool = False):
    """Kelvin–Voigt contact force for a penetration (Eq. 2.63, first line).

    Cheap enough for a simulator's inner loop: scalars in, a Python float out.

    Parameters
    ----------
    delta : float or ndarray
        Penetration [m or rad]; no contact (force 0) when ``delta <= 0``.
    delta_dot : float or ndarray
        Penetration rate [m/s or rad/s].
    params : ContactParams or ImpactParams
        Anything with attributes ``k`` [N/m] and ``c`` [N·s/m].
    allow_tension : bool, optional
        False (default): ``max(0, k*delta + c*delta_dot)`` (Modelica ElastoBacklash).
        True: ``k*delta + c*delta_dot``, which can be negative near separation.

    Returns
    -------
    float or ndarray
        Compressive contact force [N or N·m].

    Examples
    --------
    >>> p = ContactParams(k=100.0, c=2.0)
    >>> contact_force(0.01, -1.0, p), contact_force(0.01, -1.0, p, allow_tension=True)
    (0.0, -1.0)
    """
    k, c = params.k, params.c
    if np.ndim(delta) == 0 and np.ndim(delta_dot) == 0:
        if delta <= 0.0:
            return 0.0
        f = k * float(delta) + c * float(delta_dot)
        return f if (allow_tension or f > 0.0) else 0.0
    delta = np.asarray(delta, dtype=float)
    f = k * delta + c * np.asarray(delta_dot, dtype=float)
    if not allow_tension:
        f = np.maximum(f, 0.0)
    return np.where(delta > 0.0, f, 0.0)


def backlash_contact_force(
    x_rel, v_rel, gap: BacklashParams, contact, allow_tension: bool = False
):
    """Signed force transmitted through an elastic backlash (both sides of the gap).

    Parameters
    ----------
    x_rel : float or ndarray
        Relative position ``x1 - x2`` [m or rad].
    v_rel : float or ndarray
        Relative velocity ``x1_dot - x2_dot`` [m/s or rad/s].
    gap : BacklashParams
        Clearances [m or rad].
    contact : ContactParams or ImpactParams
        Contact stiffness ``k`` and damping ``c``.
    allow_tension : bool, optional
        See :func:`contact_force`.

    Returns
    -------
    float or ndarray
        Force on body 2 [N or N·m] (body 1 receives the opposite): positive when pushed on
        the ``gap_plus`` side, negative on the ``gap_minus`` side, 0 inside the gap.

    Examples
    --------
    >>> g = BacklashParams(gap_plus=1.0, gap_minus=1.0)
    >>> backlash_contact_force(-1.5, 0.0, g, ContactParams(k=10.0, c=0.0))
    -5.0
    """
    plus = contact_force(x_rel - gap.gap_plus, v_rel, contact, allow_tension)
    minus = contact_force(-gap.gap_minus - x_rel, -np.asarray(v_rel), contact, allow_tension)
    return _out(np.asarray(plus) - np.asarray(minus))


# --------------------------------------------------------------------------- impact
@dataclass(frozen=True)
class ImpactResponse:
    """Positions and velocities of both bodies during contact (Eqs. 2.55–2.56).

    Attributes
    ----------
    x1, x2 : ndarray, shape (n,)
        Positions [m or rad].
    v1, v2 : ndarray, shape (n,)
        Velocities [m/s or rad/s].
    u1, u2 : ndarray, shape (n,)
        Modal coordinates (Eq. 2.47): mass-centre position [m] and vibration [m].
    """

    x1: np.ndarray
    x2: np.ndarray
    v1: np.ndarray
    v2: np.ndarray
    u1: np.ndarray
    u2: np.ndarray


def impact_response(t, params: ImpactParams, *, x10: float, x20: float, v10: float,
                    v20: float) -> ImpactResponse:
    """Closed-form motion of two bodies in linear contact (Eqs. 2.47, 2.55–2.60).

    Parameters
    ----------
    t : array_like, shape (n,)
        Times since the reference instant [s].
    params : ImpactParams
        Masses [kg], stiffness [N/m], damping [N·s/m].
    x10, x20 : float
        Positions at ``t = 0`` [m]; ``x10 - x20`` is the initial penetration.
    v10, v20 : float
        Velocities at ``t = 0`` [m/s].

    Returns
    -------
    ImpactResponse
        Valid while the bodies stay in (linear, tension-allowed) contact.

    Notes
    -----
    Modal matrix ``[[1, 1], [1, -m1/m2]]``; constants
    ``γ11 = (m1x10 + m2x20)/(m1+m2)``, ``γ22 = (m/m1)δx0``,
    ``γ12 = (m1v10 + m2v20)/(m1+m2)``, ``γ21 = m(δv0 + ζω0δx0)/(m1ωd)``.

    Erratum: (2.52) prints the vibration mode as ``[1, -m2/m1]``, contradicting the
    relation ``ω12/ω22 = -m2/m1`` stated just before it, which gives ``[1, -m1/m2]``
    (first row of (2.51) with ``cs + k = -m1m2s²/(m1+m2)`` from (2.32)). The printed mode
    carries momentum ``m1 - m2²/m1 ≠ 0``, so (2.53)–(2.60) with ``m2/m1`` violate momentum
    conservation unless ``m1 = m2``; with ``m1/m2`` there, ``γ22 = (m/m1)δx0`` and
    ``γ21 = m(δv0 + ζω0δx0)/(m1ωd)`` (not ``m/m2``, 2.59–2.60) and ``δx = (m1/m)u2``
    (2.62). The relative motion (2.62) and everything after it are unaffected. Checked
    against ``solve_ivp`` in ``tests/models/test_backlash.py``.
    """
    t = np.asarray(t, dtype=float)
    m1, m2, m = params.m1, params.m2, params.m
    w0, z, wd = params.omega0, params.zeta, params.omega_d
    dx0, dv0 = x10 - x20, v10 - v20
    g11 = (m1 * x10 + m2 * x20) / (m1 + m2)
    g12 = (m1 * v10 + m2 * v20) / (m1 + m2)
    g22 = m / m1 * dx0
    g21 = m / (m1 * wd) * (dv0 + z * w0 * dx0)
    ex = np.exp(-z * w0 * t)
    s, co = np.sin(wd * t), np.cos(wd * t)
    u1 = g11 + g12 * t
    u2 = ex * (g21 * s + g22 * co)
    du2 = ex * (-(g22 * wd + g21 * z * w0) * s + (g21 * wd - g22 * z * w0) * co)
    r = m1 / m2
    return ImpactResponse(x1=u1 + u2, x2=u1 - r * u2, v1=g12 + du2, v2=g12 - r * du2, u1=u1, u2=u2)


def impact_force(t, v_c, params: ImpactParams, allow_tension: bool = False):
    r"""Contact force during an impact starting at ``t = 0`` with zero penetration (Eq. 2.63).

    Parameters
    ----------
    t : float or ndarray
        Time since contact [s].
    v_c : float
        Relative approach velocity ``x1_dot - x2_dot`` at contact [m/s], > 0.
    params : ImpactParams
        Masses [kg], stiffness [N/m], damping [N·s/m].
    allow_tension : bool, optional
        Contact rule; the force is 0 outside ``[0, contact_duration]``.

    Returns
    -------
    float or ndarray
        Compressive contact force [N].

    Notes
    -----
    .. math:: \Delta f(t) = v_c\sqrt{km/(1-\zeta^2)}\,e^{-\zeta\omega_0 t}
              [(1-2\zeta^2)\sin\omega_d t + 2\zeta\sqrt{1-\zeta^2}\cos\omega_d t]

    Erratum: (2.63) and (2.65) omit the factor ``v_c`` that (2.64) then reinstates
    (``f0 = c*v_c``); from (2.62), ``c δẋ + k δx = (v_c/ω_d) m ω0² e^{..}[...]`` and
    ``m ω0²/ω_d = sqrt(km/(1-ζ²))``.
    """
    v_c = float(_positive_array("v_c", v_c))
    t = np.asarray(t, dtype=float)
    k, m, z, w0, wd = params.k, params.m, params.zeta, params.omega0, params.omega_d
    f = (v_c * np.sqrt(k * m / (1 - z**2)) * np.exp(-z * w0 * t)
         * ((1 - 2 * z**2) * np.sin(wd * t) + 2 * z * np.sqrt(1 - z**2) * np.cos(wd * t)))
    end = contact_duration(z, w0, allow_tension)
    return _out(np.where((t >= 0.0) & (t <= end), f, 0.0))


def impact_impulse(v_c, params: ImpactParams, allow_tension: bool = False):
    """Impulse transmitted in one impact, ``m*v_c*(1 + e)``.

    Parameters
    ----------
    v_c : float or ndarray
        Relative approach velocity at contact [m/s], > 0.
    params : ImpactParams
        Masses [kg], stiffness [N/m], damping [N·s/m].
    allow_tension : bool, optional
        Contact rule.

    Returns
    -------
    float or ndarray
        Impulse [N·s] given to body 2 (body 1 receives the opposite).
    """
    v_c = _positive_array("v_c", v_c)
    return _out(params.m * v_c * (1.0 + restitution(params.zeta, allow_tension)))


def post_impact_velocities(v1, v2, params: ImpactParams, allow_tension: bool = False):
    """Velocities after one impact, conserving momentum (Eq. 2.60: ``γ12`` is constant).

    Parameters
    ----------
    v1, v2 : float
        Velocities at contact [m/s]; the bodies approach, ``v1 > v2``.
    params : ImpactParams
        Masses [kg], stiffness [N/m], damping [N·s/m].
    allow_tension : bool, optional
        Contact rule.

    Returns
    -------
    v1_after, v2_after : float
        Velocities at the end of contact [m/s].

    Examples
    --------
    >>> p = ImpactParams(m1=1.0, m2=1.0, k=1e4, c=0.0)
    >>> post_impact_velocities(1.0, 0.0, p)
    (0.0, 1.0)
    """
    v1, v2 = float(v1), float(v2)
    if not v1 > v2:
        raise ParameterError(f"v1 must exceed v2 (bodies approaching) [m/s]; got {v1!r} <= {v2!r}")
    e = float(restitution(params.zeta, allow_tension))
    vcm = (params.m1 * v1 + params.m2 * v2) / (params.m1 + params.m2)
    rel_after = -e * (v1 - v2)
    mu1 = params.m2 / (params.m1 + params.m2)
    return vcm + mu1 * rel_after, vcm - (1.0 - mu1) * rel_after
