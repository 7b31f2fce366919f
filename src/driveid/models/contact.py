r"""Kelvin–Voigt contact of two bodies: its law and closed forms (de Marchi 1998, §2.1.2).

The impact of two bodies ``m1``, ``m2`` through a contact of stiffness ``k`` and damping
``c`` (Eqs. 2.28–2.73) reduces to one damped oscillator of the effective mass: this module
holds :class:`ContactParams` and the mappings between ``(k, c)``, ``(zeta, omega0)``, the
coefficient of restitution and the contact duration, under both contact rules
(``allow_tension``; see :mod:`driveid.models.backlash`, which uses them and re-exports
every name here).

References
----------
.. [1] J. A. de Marchi, "Modeling of dynamic friction, impact backlash and elastic
       compliance nonlinearities in machine tools", PhD thesis, RPI, 1998, §2.1.2.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import brentq

from driveid.errors import ParameterError

__all__ = [
    "ContactParams",
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
]

_NO_TENSION_MIN_RESTITUTION = float(np.exp(-2.0))


def _check(name: str, value: float, ok: bool, rule: str, fix: str = "") -> None:
    if not ok:
        tail = f"; {fix}" if fix else ""
        raise ParameterError(f"{name} must be {rule}{tail}; got {value!r}")


def _finite(name: str, value: float) -> float:
    value = float(value)
    _check(name, value, bool(np.isfinite(value)), "finite")
    return value


def _zeta_array(zeta) -> np.ndarray:
    z = np.asarray(zeta, dtype=float)
    bad = ~((z >= 0.0) & (z < 1.0))
    if np.any(bad):
        raise ParameterError(
            "zeta must be in [0, 1) (underdamped contact; the closed forms need oscillation)"
            f"; got {float(z[bad].ravel()[0])!r}"
        )
    return z


def _positive_array(name: str, value) -> np.ndarray:
    a = np.asarray(value, dtype=float)
    bad = ~(a > 0.0) | ~np.isfinite(a)
    if np.any(bad):
        got = float(a[bad].ravel()[0])
        raise ParameterError(f"{name} must be positive and finite; got {got!r}")
    return a


def _out(a):
    return float(a) if np.ndim(a) == 0 else a


@dataclass(frozen=True, kw_only=True)
class ContactParams:
    """Kelvin–Voigt contact law (Eqs. 2.28–2.29).

    Parameters
    ----------
    k : float
        Lumped contact stiffness [N/m or N·m/rad], > 0; see :func:`lumped_stiffness`.
    c : float
        Lumped contact damping [N·s/m or N·m·s/rad], >= 0; see :func:`lumped_damping`.
    """

    k: float
    c: float

    def __post_init__(self):
        k = _finite("k", self.k)
        _check("k", k, k > 0.0, "positive [N/m or N·m/rad]")
        c = _finite("c", self.c)
        _check("c", c, c >= 0.0, "non-negative [N·s/m or N·m·s/rad]")



# --------------------------------------------------------------------------- mappings
def effective_mass(m1, m2):
    """Effective (reduced) mass ``m1*m2/(m1+m2)`` (Eq. 2.33).

    Parameters
    ----------
    m1, m2 : float or ndarray
        Masses or inertias [kg or kg·m²], > 0.

    Returns
    -------
    float or ndarray
        Effective mass [kg or kg·m²].
    """
    m1 = _positive_array("m1", m1)
    m2 = _positive_array("m2", m2)
    return _out(m1 * m2 / (m1 + m2))


def lumped_stiffness(k1, k2):
    """Series stiffness of the two contacting materials, ``k1*k2/(k1+k2)`` (Eq. 2.28).

    Parameters
    ----------
    k1, k2 : float or ndarray
        Material contact stiffnesses [N/m or N·m/rad], > 0.

    Returns
    -------
    float or ndarray
        Lumped stiffness [N/m or N·m/rad].
    """
    k1 = _positive_array("k1", k1)
    k2 = _positive_array("k2", k2)
    return _out(k1 * k2 / (k1 + k2))


def lumped_damping(c1, c2):
    """Lumped material damping ``c1 + c2`` as printed in Eq. (2.29).

    Parameters
    ----------
    c1, c2 : float or ndarray
        Material damping coefficients [N·s/m or N·m·s/rad], >= 0.

    Returns
    -------
    float or ndarray
        Lumped damping [N·s/m or N·m·s/rad].

    Notes
    -----
    Two Kelvin–Voigt elements in series are not in general a Kelvin–Voigt element; the sum
    follows the thesis, which treats the two dissipations as acting side by side.
    """
    c1 = np.asarray(c1, dtype=float)
    c2 = np.asarray(c2, dtype=float)
    for name, a in (("c1", c1), ("c2", c2)):
        if np.any(~(a >= 0.0)):
            got = float(a[~(a >= 0.0)].ravel()[0])
            raise ParameterError(f"{name} must be non-negative [N·s/m]; got {got!r}")
    return _out(c1 + c2)


def zeta_omega0_from_k_c(k, c, m):
    """Damping ratio and natural frequency of the contact (Eqs. 2.36–2.37).

    Parameters
    ----------
    k : float or ndarray
        Contact stiffness [N/m], > 0.
    c : float or ndarray
        Contact damping [N·s/m], >= 0.
    m : float or ndarray
        Effective mass [kg], > 0 (Eq. 2.33).

    Returns
    -------
    zeta : float or ndarray
        ``c/(2*sqrt(k*m))`` [-].
    omega0 : float or ndarray
        ``sqrt(k/m)`` [rad/s].
    """
    k = _positive_array("k", k)
    m = _positive_array("m", m)
    c = np.asarray(c, dtype=float)
    if np.any(~(c >= 0.0)):
        raise ParameterError(f"c must be non-negative [N·s/m]; got {float(c.ravel()[0])!r}")
    return _out(c / (2.0 * np.sqrt(k * m))), _out(np.sqrt(k / m))


def k_c_from_zeta_omega0(zeta, omega0, m):
    """Contact stiffness and damping from ``(zeta, omega0)`` (inverse of Eqs. 2.36–2.37).

    Parameters
    ----------
    zeta : float or ndarray
        Damping ratio [-], in [0, 1).
    omega0 : float or ndarray
        Undamped contact frequency [rad/s], > 0.
    m : float or ndarray
        Effective mass [kg], > 0.

    Returns
    -------
    k : float or ndarray
        ``m*omega0**2`` [N/m].
    c : float or ndarray
        ``2*m*zeta*omega0`` [N·s/m].

    Examples
    --------
    >>> k_c_from_zeta_omega0(0.1, 10.0, 2.0)
    (200.0, 4.0)
    """
    z = _zeta_array(zeta)
    w = _positive_array("omega0", omega0)
    m = _positive_array("m", m)
    return _out(m * w**2), _out(2.0 * m * z * w)


def restitution(zeta, allow_tension: bool = False):
    r"""Coefficient of restitution ``e = -v_r/v_c`` of the contact (Eq. 2.39).

    Parameters
    ----------
    zeta : float or ndarray
        Contact damping ratio [-], in [0, 1).
    allow_tension : bool, optional
        Contact rule, see the module docstring.

    Returns
    -------
    float or ndarray
        Restitution magnitude [-] in (0, 1].

    Notes
    -----
    The thesis's ``rho = v_r/v_c`` (2.39) is negative; this returns ``e = -rho > 0``.
    From (2.62b) at release: ``e = exp(-pi*zeta/sqrt(1-zeta**2))`` for the linear model,
    ``e = exp(-2*zeta*arccos(zeta)/sqrt(1-zeta**2))`` for the no-tension rule (the
    relative velocity at the force zero ``omega_d*t = 2*arccos(zeta)`` is
    ``-v_c*exp(-zeta*omega0*t)``).

    Examples
    --------
    >>> round(restitution(0.1, allow_tension=True), 6)
    0.729248
    """
    z = _zeta_array(zeta)
    root = np.sqrt(1.0 - z**2)
    if allow_tension:
        return _out(np.exp(-np.pi * z / root))
    return _out(np.exp(-2.0 * z * np.arccos(z) / root))


def zeta_from_restitution(e, allow_tension: bool = False):
    """Contact damping ratio giving a restitution (inverse of :func:`restitution`).

    Parameters
    ----------
    e : float or ndarray
        Restitution magnitude [-], in (0, 1]; under the no-tension rule in
        ``(exp(-2), 1]`` (≈ (0.1353, 1]), the range an underdamped contact can reach.
    allow_tension : bool, optional
        Contact rule, see the module docstring.

    Returns
    -------
    float or ndarray
        Damping ratio [-] in [0, 1).

    Raises
    ------
    ParameterError
        If ``e`` is outside its range.

    Examples
    --------
    >>> round(zeta_from_restitution(restitution(0.3)), 12)
    0.3
    """
    e = np.asarray(e, dtype=float)
    lo = 0.0 if allow_tension else _NO_TENSION_MIN_RESTITUTION
    bad = ~((e > lo) & (e <= 1.0))
    if np.any(bad):
        rule = "(0, 1]" if allow_tension else (
            f"({lo:.6g}, 1] under the no-tension rule (an underdamped contact cannot "
            "dissipate more); pass allow_tension=True for the linear model"
        )
        raise ParameterError(f"restitution e must be in {rule}; got {float(e[bad].ravel()[0])!r}")
    ln = -np.log(e)
    if allow_tension:
        return _out(ln / np.sqrt(np.pi**2 + ln**2))

    def g(beta, target):  # 2*beta*cot(beta) falls from 2 to 0 on (0, pi/2]
        return 2.0 * beta / np.tan(beta) - target

    out = np.empty(e.shape)
    for i, target in np.ndenumerate(ln):
        if target == 0.0:
            out[i] = 0.0
        else:
            beta = brentq(g, 1e-300, np.pi / 2, args=(target,), xtol=1e-15, rtol=1e-15)
            out[i] = np.cos(beta)
    return _out(out)


def contact_duration(zeta, omega0, allow_tension: bool = False):
    """Duration of contact force in one impact (Eqs. 2.71–2.72, with the contact rule).

    Parameters
    ----------
    zeta : float or ndarray
        Contact damping ratio [-], in [0, 1).
    omega0 : float or ndarray
        Undamped contact frequency [rad/s], > 0.
    allow_tension : bool, optional
        True: ``pi/omega_d`` (Eq. 2.72, penetration returns to zero). False (default):
        ``2*arccos(zeta)/omega_d``, the zero of the force (2.63); shorter.

    Returns
    -------
    float or ndarray
        Contact duration [s].

    Notes
    -----
    The time where the force (2.63) vanishes solves (2.66); since
    ``(1-2ζ²)sin θ + 2ζ√(1-ζ²)cos θ = sin(θ + 2 arcsin ζ)``, its first positive root is
    ``θ = π - 2 arcsin ζ = 2 arccos ζ``. See :func:`thesis_contact_duration` for (2.73).

    Examples
    --------
    >>> round(contact_duration(0.0, 1.0), 12) == round(float(np.pi), 12)
    True
    """
    z = _zeta_array(zeta)
    w = _positive_array("omega0", omega0)
    wd = w * np.sqrt(1.0 - z**2)
    if allow_tension:
        return _out(np.pi / wd)
    return _out(2.0 * np.arccos(z) / wd)


def phase_lag(zeta, omega0):
    """Phase lag ``t0`` of the impact response as printed in Eq. (2.70).

    Parameters
    ----------
    zeta : float or ndarray
        Damping ratio [-], in [0, sqrt(2)/2] as the thesis requires.
    omega0 : float or ndarray
        Undamped contact frequency [rad/s], > 0.

    Returns
    -------
    float or ndarray
        ``t0 = arctan(2ζω0ωd/((ζω0)² - ωd²))/ωd = -2*arcsin(zeta)/omega_d`` [s], <= 0.
    """
    z = _zeta_array(zeta)
    if np.any(z > np.sqrt(0.5)):
        raise ParameterError(
            "zeta must be <= sqrt(2)/2 for Eq. (2.70) (the arctan branch changes above); "
            f"got {float(z[z > np.sqrt(0.5)].ravel()[0])!r}"
        )
    w = _positive_array("omega0", omega0)
    wd = w * np.sqrt(1.0 - z**2)
    with np.errstate(divide="ignore"):
        return _out(np.arctan(2 * z * w * wd / ((z * w) ** 2 - wd**2)) / wd)


def thesis_contact_duration(zeta, omega0):
    """Contact duration as printed in Eq. (2.73), ``t_r = pi/omega_d - t0`` — for reference.

    Parameters
    ----------
    zeta : float or ndarray
        Damping ratio [-], in [0, sqrt(2)/2].
    omega0 : float or ndarray
        Undamped contact frequency [rad/s], > 0.

    Returns
    -------
    float or ndarray
        ``(pi + 2*arcsin(zeta))/omega_d`` [s].

    Notes
    -----
    Erratum (sign of the phase-lag correction): the force (2.63) has zeros at
    ``omega_d*t = -2 arcsin ζ + n*pi``. The thesis shifts the start of contact to the zero
    at ``t0 < 0`` (2.70) and so *lengthens* the contact. No trajectory of the
    Kelvin–Voigt contact ODE starts there (the penetration ``delta(t0) < 0``); integrating
    that ODE with the no-tension rule ends contact at the next zero,
    ``pi/omega_d + t0``, which is *shorter* than ``pi/omega_d``. Use
    :func:`contact_duration` (checked against ``solve_ivp`` in
    ``tests/models/test_backlash.py``).
    """
    return _out(np.pi / (np.asarray(omega0) * np.sqrt(1 - np.asarray(zeta) ** 2))
                - np.asarray(phase_lag(zeta, omega0)))


def contact_params_from_restitution(e, duration, m, allow_tension: bool = False) -> ContactParams:
    """Contact stiffness and damping giving a restitution and a contact duration.

    Parameters
    ----------
    e : float
        Restitution magnitude [-], see :func:`zeta_from_restitution` for its range.
    duration : float
        Contact duration [s], > 0, as defined by :func:`contact_duration`.
    m : float
        Effective mass [kg], > 0 (Eq. 2.33).
    allow_tension : bool, optional
        Contact rule, see the module docstring.

    Returns
    -------
    ContactParams
        ``k`` [N/m] and ``c`` [N·s/m].

    Examples
    --------
    >>> p = contact_params_from_restitution(0.8, 1e-3, 0.5)
    >>> round(float(contact_duration(*zeta_omega0_from_k_c(p.k, p.c, 0.5))), 12)
    0.001
    """
    z = float(zeta_from_restitution(e, allow_tension))
    d = float(_positive_array("duration", duration))
    angle = np.pi if allow_tension else 2.0 * np.arccos(z)
    omega0 = angle / d / np.sqrt(1.0 - z**2)
    k, c = k_c_from_zeta_omega0(z, omega0, m)
    return ContactParams(k=float(k), c=float(c))
