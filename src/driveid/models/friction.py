r"""Static friction maps of de Marchi (1998), §2.1.1.1, Eqs. (2.1)–(2.5), (2.155).

Every map is a pure, vectorised function ``name(v, params)`` of the sliding velocity
``v`` [m/s or rad/s] returning the friction force [N or N·m] that *resists* motion: it has
the sign of ``v`` and enters the equation of motion as ``J x'' + F(x') + K x = u``
(package sign convention, thesis Eq. 2.155).

The thesis writes the Stribeck maps (2.2)–(2.5) for ``v > 0`` only. Here they are extended
as odd functions, ``F(v) = sgn(v) |F(|v|)|``; at ``v = 0`` every map returns 0 because the
force during stick is a force of constraint decided by the simulator, not by the map.
Direction-dependent friction is obtained either from the asymmetric Coulomb + viscous map
(2.155) or by combining two one-sided parameter sets with :func:`asymmetric_friction`.

Friction with memory (rising static friction, time lag, presliding, Eqs. 2.6–2.14) is in
:mod:`driveid.models.friction_memory`.

Units: forces in N (translation) or N·m (rotation), velocities in m/s or rad/s, viscous
coefficients in N·s/m or N·m·s/rad. Every map works in either system as long as it is used
consistently.

References
----------
.. [1] J. A. de Marchi, "Modeling of dynamic friction, impact backlash and elastic
       compliance nonlinearities in machine tools", PhD thesis, RPI, 1998.
.. [2] B. Armstrong-Hélouvry, P. Dupont, C. Canudas de Wit, "A survey of models, analysis
       tools and compensation methods for the control of machines with friction",
       Automatica 30(7), 1083–1138, 1994. doi:10.1016/0005-1098(94)90209-7
.. [3] D. P. Hess, A. Soom, "Friction at a lubricated line contact operating at oscillating
       sliding velocities", J. Tribology 112(1), 147–152, 1990. doi:10.1115/1.2920220
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from driveid.models._checks import (
    _asarray,
    _finite,
    _nonnegative,
    _positive,
    _require,
    _stribeck_levels,
)

__all__ = [
    "CoulombViscousParams",
    "LorentzianParams",
    "BoPavelescuParams",
    "HessSoomParams",
    "STATIC_MAPS",
    "coulomb_viscous_friction",
    "lorentzian_friction",
    "bo_pavelescu_friction",
    "hess_soom_friction",
    "modified_stribeck_parameter",
    "hess_soom_from_lorentzian",
    "asymmetric_friction",
]



# --- Coulomb + viscous with asymmetry (2.155) -------------------------------------------


@dataclass(frozen=True, kw_only=True)
class CoulombViscousParams:
    """Asymmetric Coulomb + viscous friction, de Marchi (1998) Eq. (2.155).

    Parameters
    ----------
    fk_mean : float
        Mean kinetic (Coulomb) friction [N or N·m]; >= 0.
    fk_delta : float
        Signed asymmetry of the kinetic friction [N or N·m]; ``|fk_delta| <= fk_mean`` so
        that friction resists motion in both directions.
    c_mean : float
        Mean viscous coefficient [N·s/m or N·m·s/rad]; >= 0.
    c_delta : float
        Signed asymmetry of the viscous coefficient [same unit]; ``|c_delta| <= c_mean``.
    """

    fk_mean: float
    fk_delta: float
    c_mean: float
    c_delta: float

    def __post_init__(self) -> None:
        _nonnegative("fk_mean", self.fk_mean, "N or N·m")
        _finite("fk_delta", self.fk_delta)
        _require(
            abs(self.fk_delta) <= self.fk_mean,
            "fk_delta",
            f"within [-fk_mean, fk_mean] = [{-self.fk_mean!r}, {self.fk_mean!r}]",
            self.fk_delta,
            "otherwise friction would push in one direction; check the sign convention",
        )
        _nonnegative("c_mean", self.c_mean, "N·s/m or N·m·s/rad")
        _finite("c_delta", self.c_delta)
        _require(
            abs(self.c_delta) <= self.c_mean,
            "c_delta",
            f"within [-c_mean, c_mean] = [{-self.c_mean!r}, {self.c_mean!r}]",
            self.c_delta,
            "otherwise the viscous term would feed energy in one direction",
        )

    @classmethod
    def from_sides(
        cls, *, fk_plus: float, fk_minus: float, c_plus: float, c_minus: float
    ) -> CoulombViscousParams:
        """Build the parameters from one-sided magnitudes.

        Parameters
        ----------
        fk_plus, fk_minus : float
            Kinetic friction magnitude for v > 0 and for v < 0 [N or N·m]; >= 0.
        c_plus, c_minus : float
            Viscous coefficient for v > 0 and for v < 0 [N·s/m or N·m·s/rad]; >= 0.

        Returns
        -------
        CoulombViscousParams
            ``fk_mean = (fk_plus + fk_minus)/2``, ``fk_delta = (fk_plus - fk_minus)/2``,
            and likewise for ``c``.

        Examples
        --------
        >>> CoulombViscousParams.from_sides(fk_plus=3.0, fk_minus=1.0, c_plus=0.5, c_minus=0.5)
        CoulombViscousParams(fk_mean=2.0, fk_delta=1.0, c_mean=0.5, c_delta=0.0)
        """
        return cls(
            fk_mean=0.5 * (fk_plus + fk_minus),
            fk_delta=0.5 * (fk_plus - fk_minus),
            c_mean=0.5 * (c_plus + c_minus),
            c_delta=0.5 * (c_plus - c_minus),
        )


def coulomb_viscous_friction(v: Any, params: CoulombViscousParams) -> np.ndarray:
    r"""Asymmetric Coulomb + viscous friction while moving, de Marchi (1998) Eq. (2.155).

    Parameters
    ----------
    v : array_like, shape (n,) or scalar
        Sliding velocity [m/s or rad/s].
    params : CoulombViscousParams
        Kinetic and viscous friction with their signed asymmetries.

    Returns
    -------
    ndarray, shape like ``v``
        Friction force [N or N·m]; 0 where ``v == 0`` (stick is handled by the caller).

    Notes
    -----
    .. math:: F = f_{k,mean}\,\mathrm{sgn}(v) + f_{k,\Delta}
              + (c_{mean} + c_{\Delta}\,\mathrm{sgn}(v))\,v \qquad (2.155)

    Examples
    --------
    >>> p = CoulombViscousParams(fk_mean=2.0, fk_delta=0.5, c_mean=1.0, c_delta=0.0)
    >>> coulomb_viscous_friction([-1.0, 0.0, 1.0], p)
    array([-2.5,  0. ,  3.5])
    """
    v = _asarray(v)
    s = np.sign(v)
    p = params
    force = p.fk_mean * s + p.fk_delta + (p.c_mean + p.c_delta * s) * v
    return np.where(v == 0.0, 0.0, force)


# --- Stribeck maps (2.1)–(2.5) ------------------------------------------------------------


@dataclass(frozen=True, kw_only=True)
class LorentzianParams:
    """One-sided parameters of Armstrong's Lorentzian Stribeck map, Eq. (2.3).

    Parameters
    ----------
    mu_k : float
        Kinetic (Coulomb) friction [N or N·m]; >= 0.
    mu_s : float
        Static friction [N or N·m]; >= mu_k.
    nu : float
        Viscous coefficient [N·s/m or N·m·s/rad]; >= 0.
    v_s : float
        Critical Stribeck velocity [m/s or rad/s]; > 0.
    """

    mu_k: float
    mu_s: float
    nu: float
    v_s: float

    def __post_init__(self) -> None:
        _stribeck_levels(self.mu_k, self.mu_s)
        _nonnegative("nu", self.nu, "N·s/m or N·m·s/rad")
        _positive("v_s", self.v_s, "m/s or rad/s")


def lorentzian_friction(v: Any, params: LorentzianParams) -> np.ndarray:
    r"""Armstrong-Hélouvry's Lorentzian Stribeck map, de Marchi (1998) Eq. (2.3).

    Parameters
    ----------
    v : array_like, shape (n,) or scalar
        Sliding velocity [m/s or rad/s].
    params : LorentzianParams
        Kinetic and static friction, viscous coefficient and Stribeck velocity.

    Returns
    -------
    ndarray, shape like ``v``
        Friction force [N or N·m], odd in ``v``; 0 at ``v == 0``.

    Notes
    -----
    .. math:: f = \mu_k + \frac{\mu_s - \mu_k}{1 + (\dot x/\dot x_S)^2} + \nu \dot x,
              \quad \dot x > 0 \qquad (2.3)

    At ``v = v_s`` the Stribeck term is the mean of static and kinetic friction (thesis
    footnote 49).

    Examples
    --------
    >>> p = LorentzianParams(mu_k=1.0, mu_s=4.0, nu=0.5, v_s=1.0)
    >>> lorentzian_friction([-1.0, 1.0], p)
    array([-3.,  3.])
    """
    v = _asarray(v)
    a = np.abs(v)
    p = params
    mag = p.mu_k + (p.mu_s - p.mu_k) / (1.0 + (a / p.v_s) ** 2) + p.nu * a
    return np.sign(v) * mag


@dataclass(frozen=True, kw_only=True)
class BoPavelescuParams:
    """One-sided parameters of the Bo–Pavelescu exponential Stribeck map, Eq. (2.5).

    Parameters
    ----------
    mu_k : float
        Kinetic (Coulomb) friction [N or N·m]; >= 0.
    mu_s : float
        Static friction [N or N·m]; >= mu_k.
    nu : float
        Viscous coefficient [N·s/m or N·m·s/rad]; >= 0.
    v_s : float
        Critical Stribeck velocity [m/s or rad/s]; > 0.
    delta : float
        Empirical exponent [-]; > 0 (typically 0.5–2; 2 is the "Gaussian" map).
    """

    mu_k: float
    mu_s: float
    nu: float
    v_s: float
    delta: float

    def __post_init__(self) -> None:
        _stribeck_levels(self.mu_k, self.mu_s)
        _nonnegative("nu", self.nu, "N·s/m or N·m·s/rad")
        _positive("v_s", self.v_s, "m/s or rad/s")
        _positive("delta", self.delta, "-")


def bo_pavelescu_friction(v: Any, params: BoPavelescuParams) -> np.ndarray:
    r"""Bo–Pavelescu exponential Stribeck map, de Marchi (1998) Eq. (2.5).

    Parameters
    ----------
    v : array_like, shape (n,) or scalar
        Sliding velocity [m/s or rad/s].
    params : BoPavelescuParams
        Kinetic and static friction, viscous coefficient, Stribeck velocity, exponent.

    Returns
    -------
    ndarray, shape like ``v``
        Friction force [N or N·m], odd in ``v``; 0 at ``v == 0``.

    Notes
    -----
    .. math:: f = \mu_k + (\mu_s - \mu_k)\, e^{-(\dot x/\dot x_S)^\delta} + \nu \dot x,
              \quad \dot x > 0 \qquad (2.5)

    Examples
    --------
    >>> p = BoPavelescuParams(mu_k=1.0, mu_s=4.0, nu=0.0, v_s=1.0, delta=2.0)
    >>> bool(np.isclose(bo_pavelescu_friction(1.0, p), 1.0 + 3.0 / np.e))
    True
    """
    v = _asarray(v)
    a = np.abs(v)
    p = params
    mag = p.mu_k + (p.mu_s - p.mu_k) * np.exp(-((a / p.v_s) ** p.delta)) + p.nu * a
    return np.sign(v) * mag


@dataclass(frozen=True, kw_only=True)
class HessSoomParams:
    """Parameters of Hess and Soom's map with the modified Stribeck parameter, Eqs. (2.1)–(2.2).

    Parameters
    ----------
    mu_s : float
        Static friction [N]; >= 0.
    c1 : float
        Dimensionless Stribeck constant [-]; >= 0.
    c2 : float
        Viscous constant [N]; >= 0.
    eta : float
        Lubricant viscosity [Pa·s]; > 0.
    W : float
        Normal contact force [N]; > 0.
    E : float
        Effective (Young's) modulus of the interface [Pa]; > 0.
    l : float
        Hertzian line-contact length [m]; > 0.
    """

    mu_s: float
    c1: float
    c2: float
    eta: float
    W: float
    E: float
    l: float

    def __post_init__(self) -> None:
        _nonnegative("mu_s", self.mu_s, "N")
        _nonnegative("c1", self.c1, "-")
        _nonnegative("c2", self.c2, "N")
        _positive("eta", self.eta, "Pa·s")
        _positive("W", self.W, "N")
        _positive("E", self.E, "Pa")
        _positive("l", self.l, "m")


def modified_stribeck_parameter(v: Any, *, eta: float, W: float, E: float) -> np.ndarray:
    r"""Hess and Soom's modified Stribeck parameter, de Marchi (1998) Eq. (2.1).

    Parameters
    ----------
    v : array_like, shape (n,) or scalar
        Sliding velocity [m/s].
    eta : float
        Lubricant viscosity [Pa·s]; > 0.
    W : float
        Normal contact force [N]; > 0.
    E : float
        Effective modulus of the interface [Pa]; > 0.

    Returns
    -------
    ndarray, shape like ``v``
        :math:`c_S = \eta \dot x / \sqrt{W E}` [-], signed like ``v``.

    Raises
    ------
    ParameterError
        If ``eta``, ``W`` or ``E`` is not positive.

    Examples
    --------
    >>> float(modified_stribeck_parameter(2.0, eta=1.0, W=1.0, E=4.0))
    1.0
    """
    _positive("eta", eta, "Pa·s")
    _positive("W", W, "N")
    _positive("E", E, "Pa")
    return eta * _asarray(v) / np.sqrt(W * E)


def hess_soom_friction(v: Any, params: HessSoomParams) -> np.ndarray:
    r"""Hess and Soom's Coulomb + viscous + Stribeck map, de Marchi (1998) Eqs. (2.1)–(2.2).

    Parameters
    ----------
    v : array_like, shape (n,) or scalar
        Sliding velocity [m/s].
    params : HessSoomParams
        Static friction, constants c1 and c2, viscosity, normal load, modulus, length.

    Returns
    -------
    ndarray, shape like ``v``
        Friction force [N], odd in ``v``; 0 at ``v == 0``.

    Notes
    -----
    .. math:: f = \frac{\mu_s}{1 + c_1 c_S^2} + c_2 c_S\, l \sqrt{E/W},
              \quad c_S = \frac{\eta\dot x}{\sqrt{W E}}, \quad \dot x > 0 \qquad (2.1, 2.2)

    The thesis gives ``c2`` the unit N; then ``c_S l sqrt(E/W)`` is dimensionless since
    ``l`` [m] times ``sqrt(E/W)`` [1/m] is. With (2.4) the map equals (2.3) with
    ``mu_k = 0`` (see :func:`hess_soom_from_lorentzian`).

    Examples
    --------
    >>> p = HessSoomParams(mu_s=4.0, c1=1.0, c2=0.0, eta=1.0, W=1.0, E=1.0, l=1.0)
    >>> hess_soom_friction([1.0], p)
    array([2.])
    """
    v = _asarray(v)
    p = params
    cs = np.abs(modified_stribeck_parameter(v, eta=p.eta, W=p.W, E=p.E))
    mag = p.mu_s / (1.0 + p.c1 * cs**2) + p.c2 * cs * p.l * np.sqrt(p.E / p.W)
    return np.sign(v) * mag


def hess_soom_from_lorentzian(
    params: LorentzianParams, *, eta: float, W: float, E: float, l: float
) -> HessSoomParams:
    r"""Hess–Soom constants equivalent to a Lorentzian map without kinetic friction, Eq. (2.4).

    Parameters
    ----------
    params : LorentzianParams
        Lorentzian map (2.3); ``mu_k`` must be 0 because (2.2) has no kinetic level.
    eta : float
        Lubricant viscosity [Pa·s]; > 0.
    W : float
        Normal contact force [N]; > 0.
    E : float
        Effective modulus [Pa]; > 0.
    l : float
        Line-contact length [m]; > 0.

    Returns
    -------
    HessSoomParams
        With :math:`c_1 = W E / (\eta \dot x_S)^2` and :math:`c_2 = \nu W / (\eta l)`.

    Raises
    ------
    ParameterError
        If ``params.mu_k != 0`` or a physical constant is not positive.

    Examples
    --------
    >>> lp = LorentzianParams(mu_k=0.0, mu_s=4.0, nu=0.5, v_s=1.0)
    >>> hp = hess_soom_from_lorentzian(lp, eta=1.0, W=2.0, E=10.0, l=1.0)
    >>> (hp.c1, hp.c2)
    (20.0, 1.0)
    """
    _require(
        params.mu_k == 0.0,
        "mu_k",
        "0 for the Hess–Soom equivalence (2.4)",
        params.mu_k,
        "(2.2) has no kinetic level; set mu_k=0",
    )
    for name, value, unit in (("eta", eta, "Pa·s"), ("W", W, "N"), ("E", E, "Pa"), ("l", l, "m")):
        _positive(name, value, unit)
    c1 = W * E / (eta * params.v_s) ** 2
    c2 = params.nu * W / (eta * l)
    return HessSoomParams(mu_s=params.mu_s, c1=c1, c2=c2, eta=eta, W=W, E=E, l=l)


def asymmetric_friction(
    v: Any,
    friction: Callable[[np.ndarray, Any], np.ndarray],
    *,
    plus: Any,
    minus: Any,
) -> np.ndarray:
    """Direction-dependent friction from two one-sided parameter sets.

    Parameters
    ----------
    v : array_like, shape (n,) or scalar
        Sliding velocity [m/s or rad/s].
    friction : callable
        An odd static map ``friction(v, params)`` of this module (e.g.
        :func:`lorentzian_friction`), returning [N or N·m].
    plus : params
        Parameters used where ``v > 0``.
    minus : params
        Parameters used where ``v < 0`` (magnitudes; the map's oddness gives the sign).

    Returns
    -------
    ndarray, shape like ``v``
        Friction force [N or N·m]; 0 at ``v == 0``.

    Examples
    --------
    >>> plus = LorentzianParams(mu_k=2.0, mu_s=2.0, nu=0.0, v_s=1.0)
    >>> minus = LorentzianParams(mu_k=1.0, mu_s=1.0, nu=0.0, v_s=1.0)
    >>> asymmetric_friction([-1.0, 0.0, 1.0], lorentzian_friction, plus=plus, minus=minus)
    array([-1.,  0.,  2.])
    """
    v = _asarray(v)
    f_plus = friction(v, plus)
    f_minus = friction(v, minus)
    return np.where(v > 0.0, f_plus, np.where(v < 0.0, f_minus, 0.0))


#: Registry of the static maps an identifier can fit: name -> (function, params class).
STATIC_MAPS: dict[str, tuple[Callable[[Any, Any], np.ndarray], type]] = {
    "coulomb_viscous": (coulomb_viscous_friction, CoulombViscousParams),
    "lorentzian": (lorentzian_friction, LorentzianParams),
    "bo_pavelescu": (bo_pavelescu_friction, BoPavelescuParams),
    "hess_soom": (hess_soom_friction, HessSoomParams),
}
