r"""Static friction maps of de Marchi (1998), §2.1.1.1–2.1.1.5, Eqs. (2.1)–(2.14), (2.155).

Every map is a pure, vectorised function ``name(v, params)`` of the sliding velocity
``v`` [m/s or rad/s] returning the friction force [N or N·m] that *resists* motion: it has
the sign of ``v`` and enters the equation of motion as ``J x'' + F(x') + K x = u``
(package sign convention, thesis Eq. 2.155).

The thesis writes the Stribeck maps (2.2)–(2.5) for ``v > 0`` only. Here they are extended
as odd functions, ``F(v) = sgn(v) |F(|v|)|``; at ``v = 0`` every map returns 0 because the
force during stick is a force of constraint decided by the simulator, not by the map.
Direction-dependent friction is obtained either from the asymmetric Coulomb + viscous map
(2.155) or by combining two one-sided parameter sets with :func:`asymmetric_friction`.

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

from driveid.errors import ParameterError

__all__ = [
    "CoulombViscousParams",
    "LorentzianParams",
    "BoPavelescuParams",
    "HessSoomParams",
    "KatoRisingParams",
    "ArmstrongRisingParams",
    "RisingStribeckParams",
    "PreslidingParams",
    "STATIC_MAPS",
    "coulomb_viscous_friction",
    "lorentzian_friction",
    "bo_pavelescu_friction",
    "hess_soom_friction",
    "modified_stribeck_parameter",
    "hess_soom_from_lorentzian",
    "asymmetric_friction",
    "rising_static_friction_kato",
    "rising_static_friction_armstrong",
    "rising_lorentzian_friction",
    "rising_gaussian_friction",
    "lag_signal",
    "lagged_friction",
    "presliding_friction",
    "presliding_stiffness",
]


# --- validation helpers -------------------------------------------------------------------


def _require(ok: bool, name: str, rule: str, value: Any, fix: str) -> None:
    """Raise ParameterError stating the rule, the value and the fix."""
    if not ok:
        raise ParameterError(f"{name} must be {rule}; {fix}; got {name}={value!r}")


def _finite(name: str, value: float) -> float:
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ParameterError(f"{name} must be a real number; got {name}={value!r}") from None
    _require(np.isfinite(x), name, "finite", value, "pass a finite number")
    return x


def _positive(name: str, value: float, unit: str) -> None:
    x = _finite(name, value)
    _require(x > 0.0, name, f"> 0 [{unit}]", value, "pass a strictly positive value")


def _nonnegative(name: str, value: float, unit: str) -> None:
    x = _finite(name, value)
    _require(x >= 0.0, name, f">= 0 [{unit}]", value, "friction dissipates; pass a value >= 0")


def _stribeck_levels(mu_k: float, mu_s: float) -> None:
    _nonnegative("mu_k", mu_k, "N or N·m")
    _nonnegative("mu_s", mu_s, "N or N·m")
    _require(
        mu_s >= mu_k,
        "mu_s",
        f">= mu_k={mu_k!r} (static friction is not below kinetic friction)",
        mu_s,
        "swap the two levels or set mu_s = mu_k for no Stribeck effect",
    )


def _asarray(v: Any) -> np.ndarray:
    return np.asarray(v, dtype=float)


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


# --- Rising static friction (2.6)–(2.11) -------------------------------------------------


@dataclass(frozen=True, kw_only=True)
class KatoRisingParams:
    """Parameters of Kato/Howe rising static friction, Eq. (2.6).

    Parameters
    ----------
    mu_k : float
        Kinetic friction, the static friction at zero dwell [N or N·m]; >= 0.
    mu_inf : float
        Plateau static friction after a long dwell, ``mu_s(t_inf)`` [N or N·m]; >= mu_k.
    gamma : float
        Lubricant time constant [s**kappa]; > 0.
    kappa : float
        Dimensionless lubricant exponent [-]; > 0.
    """

    mu_k: float
    mu_inf: float
    gamma: float
    kappa: float

    def __post_init__(self) -> None:
        _stribeck_levels(self.mu_k, self.mu_inf)
        _positive("gamma", self.gamma, "s**kappa")
        _positive("kappa", self.kappa, "-")


def _dwell(t_dwell: Any) -> np.ndarray:
    t = _asarray(t_dwell)
    if np.any(~np.isfinite(t)) or np.any(t < 0.0):
        bad = t[~(np.isfinite(t) & (t >= 0.0))].flat[0]
        raise ParameterError(
            f"t_dwell must be finite and >= 0 [s]; pass dwell times since sticking; "
            f"got t_dwell={bad!r}"
        )
    return t


def rising_static_friction_kato(t_dwell: Any, params: KatoRisingParams) -> np.ndarray:
    r"""Compute Kato/Howe static friction after a dwell time, de Marchi (1998) Eq. (2.6).

    Parameters
    ----------
    t_dwell : array_like, shape (n,) or scalar
        Time spent stuck [s]; >= 0.
    params : KatoRisingParams
        Kinetic and plateau friction, lubricant constants ``gamma`` and ``kappa``.

    Returns
    -------
    ndarray, shape like ``t_dwell``
        Static friction magnitude [N or N·m].

    Raises
    ------
    ParameterError
        If a dwell time is negative or not finite.

    Notes
    -----
    .. math:: \mu_s(t) = \mu_\infty + (\mu_k - \mu_\infty)\, e^{-t_{dwell}^\kappa/\gamma}
              \qquad (2.6)

    The thesis lists ``gamma`` in s; dimensional consistency needs s**kappa.

    Examples
    --------
    >>> p = KatoRisingParams(mu_k=1.0, mu_inf=4.0, gamma=1.0, kappa=1.0)
    >>> rising_static_friction_kato([0.0], p)
    array([1.])
    """
    t = _dwell(t_dwell)
    p = params
    return p.mu_inf + (p.mu_k - p.mu_inf) * np.exp(-(t**p.kappa) / p.gamma)


@dataclass(frozen=True, kw_only=True)
class ArmstrongRisingParams:
    """Parameters of Armstrong-Hélouvry's rising static friction, Eqs. (2.7)–(2.8).

    Parameters
    ----------
    mu_inf : float
        Plateau static friction after a long dwell [N or N·m]; >= 0.
    gamma : float
        Rising time constant [s]; > 0.
    """

    mu_inf: float
    gamma: float

    def __post_init__(self) -> None:
        _nonnegative("mu_inf", self.mu_inf, "N or N·m")
        _positive("gamma", self.gamma, "s")


def rising_static_friction_armstrong(
    t_dwell: Any, mu_start: Any, params: ArmstrongRisingParams, *, form: str = "rational"
) -> np.ndarray:
    r"""Compute Armstrong-Hélouvry static friction after a dwell, Eqs. (2.7) and (2.8).

    Parameters
    ----------
    t_dwell : array_like, shape (n,) or scalar
        Time spent stuck [s]; >= 0.
    mu_start : array_like, broadcastable to ``t_dwell``
        Static friction when sticking began, ``mu_s(t - t_dwell)`` [N or N·m]; the kinetic
        friction after a long slide.
    params : ArmstrongRisingParams
        Plateau friction and rising time constant.
    form : {"rational", "exponential"}
        ``"rational"`` is (2.7), ``t/(gamma + t)``; ``"exponential"`` is (2.8),
        ``exp(-gamma/t)``.

    Returns
    -------
    ndarray
        Static friction magnitude [N or N·m].

    Raises
    ------
    ParameterError
        If ``form`` is unknown or a dwell time is negative.

    Notes
    -----
    .. math:: \mu_s(t) = \mu_s(t - t_d) + [\mu_\infty - \mu_s(t - t_d)]\,
              \frac{t_d}{\gamma + t_d} \qquad (2.7)

    With ``mu_start = mu_k`` and ``kappa = 1`` (2.7) agrees with (2.6) to first order in
    ``t_dwell`` (both have slope ``(mu_inf - mu_k)/gamma`` at 0).

    Examples
    --------
    >>> p = ArmstrongRisingParams(mu_inf=4.0, gamma=1.0)
    >>> rising_static_friction_armstrong([0.0, 1.0], 1.0, p)
    array([1. , 2.5])
    """
    t = _dwell(t_dwell)
    mu0 = _asarray(mu_start)
    if form == "rational":
        frac = t / (params.gamma + t)
    elif form == "exponential":
        with np.errstate(divide="ignore"):
            frac = np.exp(-params.gamma / t)
    else:
        raise ParameterError(
            f"form must be 'rational' (2.7) or 'exponential' (2.8); got form={form!r}"
        )
    return mu0 + (params.mu_inf - mu0) * frac


@dataclass(frozen=True, kw_only=True)
class RisingStribeckParams:
    """Parameters of the Stribeck maps with rising friction, Eqs. (2.9)–(2.10).

    Parameters
    ----------
    mu_k : float
        Kinetic friction [N or N·m]; >= 0.
    nu : float
        Viscous coefficient [N·s/m or N·m·s/rad]; >= 0.
    v_s : float
        Critical Stribeck velocity [m/s or rad/s]; > 0.
    """

    mu_k: float
    nu: float
    v_s: float

    def __post_init__(self) -> None:
        _nonnegative("mu_k", self.mu_k, "N or N·m")
        _nonnegative("nu", self.nu, "N·s/m or N·m·s/rad")
        _positive("v_s", self.v_s, "m/s or rad/s")


def _rising(v: Any, mu_rise: Any, shape: np.ndarray, params: RisingStribeckParams) -> np.ndarray:
    v = _asarray(v)
    a = np.abs(v)
    rise = _asarray(mu_rise)
    if np.any(rise < 0.0):
        raise ParameterError(
            "mu_rise must be >= 0 [N or N·m] (it is the excess of static over kinetic "
            f"friction, Eq. 2.11); got mu_rise={rise[rise < 0.0].flat[0]!r}"
        )
    return np.sign(v) * (params.mu_k + rise * shape + params.nu * a)


def rising_lorentzian_friction(v: Any, mu_rise: Any, params: RisingStribeckParams) -> np.ndarray:
    r"""Lorentzian Stribeck map with rising static friction, de Marchi (1998) Eq. (2.9).

    Parameters
    ----------
    v : array_like, shape (n,) or scalar
        Sliding velocity [m/s or rad/s].
    mu_rise : array_like, broadcastable to ``v``
        Rising Stribeck friction, the excess of static over kinetic friction [N or N·m];
        >= 0. Without rising friction it is ``mu_s - mu_k`` (2.11).
    params : RisingStribeckParams
        Kinetic friction, viscous coefficient and Stribeck velocity.

    Returns
    -------
    ndarray
        Friction force [N or N·m], odd in ``v``.

    Raises
    ------
    ParameterError
        If ``mu_rise`` is negative.

    Notes
    -----
    .. math:: f = \mu_k + \frac{\mu_s(t)}{1 + (\dot x/\dot x_S)^2} + \nu\dot x \qquad (2.9)

    With (2.11) it equals :func:`lorentzian_friction` (2.3).

    Examples
    --------
    >>> p = RisingStribeckParams(mu_k=1.0, nu=0.5, v_s=1.0)
    >>> rising_lorentzian_friction([1.0], 3.0, p)
    array([3.])
    """
    a = np.abs(_asarray(v))
    return _rising(v, mu_rise, 1.0 / (1.0 + (a / params.v_s) ** 2), params)


def rising_gaussian_friction(v: Any, mu_rise: Any, params: RisingStribeckParams) -> np.ndarray:
    r"""Gaussian (Bo–Pavelescu) Stribeck map with rising friction, de Marchi (1998) Eq. (2.10).

    Parameters
    ----------
    v : array_like, shape (n,) or scalar
        Sliding velocity [m/s or rad/s].
    mu_rise : array_like, broadcastable to ``v``
        Rising Stribeck friction [N or N·m]; >= 0; ``mu_s - mu_k`` without rising friction.
    params : RisingStribeckParams
        Kinetic friction, viscous coefficient and Stribeck velocity.

    Returns
    -------
    ndarray
        Friction force [N or N·m], odd in ``v``.

    Raises
    ------
    ParameterError
        If ``mu_rise`` is negative.

    Notes
    -----
    .. math:: f = [\mu_k + \mu_s(t)\, e^{-(\dot x/\dot x_S)^2}]\,\mathrm{sgn}(\dot x)
              + \nu\dot x \qquad (2.10)

    The exponent is fixed at 2, so the thesis's statement that (2.10) "collapses to (2.5)"
    under (2.11) holds only for ``delta = 2`` (checked in tests).

    Examples
    --------
    >>> p = RisingStribeckParams(mu_k=1.0, nu=0.0, v_s=1.0)
    >>> rising_gaussian_friction([0.0, 1.0], 3.0, p)
    array([0.        , 2.10363832])
    """
    a = np.abs(_asarray(v))
    return _rising(v, mu_rise, np.exp(-((a / params.v_s) ** 2)), params)


# --- Frictional memory (2.12) --------------------------------------------------------------


def lag_signal(signal: Any, dt: float, lag: float) -> np.ndarray:
    """Delay a uniformly sampled signal by ``lag`` seconds, ``s(t - lag)``.

    Parameters
    ----------
    signal : array_like, shape (n,)
        Samples at times ``k*dt`` [any unit].
    dt : float
        Sample interval [s]; > 0.
    lag : float
        Time lag [s]; >= 0.

    Returns
    -------
    ndarray, shape (n,)
        Linearly interpolated delayed signal; before the first sample the first value is
        held (the history is assumed constant).

    Raises
    ------
    ParameterError
        If ``dt <= 0``, ``lag < 0`` or ``signal`` is not one-dimensional.

    Examples
    --------
    >>> lag_signal([0.0, 1.0, 2.0, 3.0], 1.0, 1.5)
    array([0. , 0. , 0.5, 1.5])
    """
    _positive("dt", dt, "s")
    _nonnegative("lag", lag, "s")
    s = _asarray(signal)
    if s.ndim != 1:
        raise ParameterError(f"signal must be one-dimensional (a time series); got shape {s.shape}")
    k = np.arange(s.size, dtype=float)
    # Interpolate in sample units so that lags of whole samples are exact shifts.
    return np.interp(k - lag / dt, k, s)


def lagged_friction(
    v: Any, dt: float, *, lag: float, friction: Callable[[np.ndarray], np.ndarray]
) -> np.ndarray:
    r"""Friction with frictional memory as a pure time lag, de Marchi (1998) Eq. (2.12).

    Parameters
    ----------
    v : array_like, shape (n,)
        Velocity time series sampled every ``dt`` [m/s or rad/s].
    dt : float
        Sample interval [s]; > 0.
    lag : float
        Frictional memory constant Δt [s]; >= 0.
    friction : callable
        Static map ``friction(v) -> F`` [N or N·m], e.g.
        ``functools.partial(lorentzian_friction, params=p)``.

    Returns
    -------
    ndarray, shape (n,)
        :math:`f(t) = f(\dot x(t - \Delta t))` (2.12) [N or N·m].

    Raises
    ------
    ParameterError
        If ``dt <= 0`` or ``lag < 0``.

    Examples
    --------
    >>> lagged_friction([1.0, 2.0, 3.0], 1.0, lag=1.0, friction=lambda v: 2.0 * v)
    array([2., 2., 4.])
    """
    return np.asarray(friction(lag_signal(v, dt, lag)), dtype=float)


# --- Presliding (2.13)–(2.14) ---------------------------------------------------------------


@dataclass(frozen=True, kw_only=True)
class PreslidingParams:
    """Presliding spring with breakaway, Eqs. (2.13)–(2.14).

    Parameters
    ----------
    k_s : float
        Presliding (contact) stiffness [N/m or N·m/rad]; > 0.
    fs_plus : float
        Breakaway force for positive displacement [N or N·m]; > 0.
    fs_minus : float
        Breakaway force magnitude for negative displacement [N or N·m]; > 0.
    """

    k_s: float
    fs_plus: float
    fs_minus: float

    def __post_init__(self) -> None:
        _positive("k_s", self.k_s, "N/m or N·m/rad")
        _positive("fs_plus", self.fs_plus, "N or N·m")
        _positive("fs_minus", self.fs_minus, "N or N·m")


def presliding_friction(x: Any, params: PreslidingParams) -> np.ndarray:
    r"""Presliding spring force up to breakaway, de Marchi (1998) Eq. (2.13).

    Parameters
    ----------
    x : array_like, shape (n,) or scalar
        Presliding displacement from the point where sticking began [m or rad].
    params : PreslidingParams
        Contact stiffness and the two breakaway forces.

    Returns
    -------
    ndarray, shape like ``x``
        Resisting force ``k_s x`` [N or N·m], saturated at ``fs_plus`` and ``-fs_minus``
        (breakaway displacements ``x_s+ = fs_plus/k_s``, ``x_s- = -fs_minus/k_s``).

    Notes
    -----
    The thesis writes :math:`\mu_s = -k_s x` (2.13), the force *on* the body; in the
    package convention the resisting force enters the equation of motion with a plus sign,
    hence ``+k_s x`` here.

    Examples
    --------
    >>> p = PreslidingParams(k_s=100.0, fs_plus=2.0, fs_minus=1.0)
    >>> presliding_friction([-1.0, 0.01, 1.0], p)
    array([-1.,  1.,  2.])
    """
    x = _asarray(x)
    return np.clip(params.k_s * x, -params.fs_minus, params.fs_plus)


def presliding_stiffness(
    *, fs_plus: float, fs_minus: float, x_plus: float, x_minus: float
) -> float:
    r"""Presliding stiffness from the breakaway points, de Marchi (1998) Eq. (2.14).

    Parameters
    ----------
    fs_plus : float
        Breakaway force in the positive direction, ``mu_s+`` [N or N·m].
    fs_minus : float
        Breakaway force in the negative direction, ``mu_s-`` (signed, normally < 0)
        [N or N·m].
    x_plus : float
        Breakaway displacement in the positive direction [m or rad].
    x_minus : float
        Breakaway displacement in the negative direction (signed) [m or rad].

    Returns
    -------
    float
        :math:`k_s = (\mu_{s+} - \mu_{s-})/(x_{s+} - x_{s-})` [N/m or N·m/rad].

    Raises
    ------
    ParameterError
        If ``x_plus <= x_minus`` or the slope is not positive.

    Examples
    --------
    >>> presliding_stiffness(fs_plus=2.0, fs_minus=-1.0, x_plus=0.02, x_minus=-0.01)
    100.0
    """
    _require(
        x_plus > x_minus,
        "x_plus",
        f"> x_minus={x_minus!r}",
        x_plus,
        "pass the signed breakaway displacements",
    )
    k = (fs_plus - fs_minus) / (x_plus - x_minus)
    _require(k > 0.0, "k_s", "> 0", k, "fs_plus must exceed fs_minus (signed)")
    return float(k)


#: Registry of the static maps an identifier can fit: name -> (function, params class).
STATIC_MAPS: dict[str, tuple[Callable[[Any, Any], np.ndarray], type]] = {
    "coulomb_viscous": (coulomb_viscous_friction, CoulombViscousParams),
    "lorentzian": (lorentzian_friction, LorentzianParams),
    "bo_pavelescu": (bo_pavelescu_friction, BoPavelescuParams),
    "hess_soom": (hess_soom_friction, HessSoomParams),
}
