r"""Friction with memory, de Marchi (1998) §2.1.1.2–2.1.1.5, Eqs. (2.6)–(2.14).

Rising static friction with dwell time (Kato/Howe 2.6, Armstrong 2.7–2.8), the Stribeck maps
with rising static friction (2.9–2.11), frictional memory as a pure time lag (2.12) and the
presliding spring (2.13–2.14). The memoryless maps are in :mod:`driveid.models.friction`.

Units: forces in N or N·m, velocities in m/s or rad/s, times in s.

References
----------
.. [1] J. A. de Marchi, "Modeling of dynamic friction, impact backlash and elastic
       compliance nonlinearities in machine tools", PhD thesis, RPI, 1998.
.. [2] B. Armstrong-Hélouvry, P. Dupont, C. Canudas de Wit, "A survey of models, analysis
       tools and compensation methods for the control of machines with friction",
       Automatica 30(7), 1083–1138, 1994. doi:10.1016/0005-1098(94)90209-7
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from driveid.errors import ParameterError
from driveid.models._checks import (
    _asarray,
    _nonnegative,
    _positive,
    _require,
    _stribeck_levels,
)

__all__ = [
    "KatoRisingParams",
    "rising_static_friction_kato",
    "ArmstrongRisingParams",
    "rising_static_friction_armstrong",
    "RisingStribeckParams",
    "rising_lorentzian_friction",
    "rising_gaussian_friction",
    "lag_signal",
    "lagged_friction",
    "PreslidingParams",
    "presliding_friction",
    "presliding_stiffness",
]

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
