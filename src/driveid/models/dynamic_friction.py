r"""Dynamic friction models of de Marchi (1998), §2.1.1.6, Eqs. (2.15)–(2.26).

* Armstrong-Hélouvry's seven-parameter integrated model (2.15) on a sampled time series;
* the Dahl model (2.16)–(2.18), state = hysteretic friction force ``f`` [N or N·m];
* the Canudas de Wit et al. two-state model (2.19)–(2.22), state = Stribeck mix ``g`` [-];
* the LuGre model (2.23)–(2.26), state = mean bristle deflection ``z`` [m or rad].

Each state-space model exposes ``<model>_state_derivative(state, v, params)``,
``<model>_friction(state, v, params)`` and ``<model>_jacobian(state, v, params)``
(the analytic d(dstate/dt)/dstate), all vectorised over NumPy arrays. Friction is the
force that *resists* motion (sign of ``v``), as in :mod:`driveid.models.friction`.

Symbols: the thesis writes LuGre with ``k_s, nu_s, nu`` and a displacement-valued ``g``;
here the customary ``sigma0 = k_s``, ``sigma1 = nu_s``, ``sigma2 = nu`` and the force-valued
Stribeck curve ``g_F(v) = k_s g(v)`` (2.26) are used.

References
----------
.. [1] J. A. de Marchi, "Modeling of dynamic friction, impact backlash and elastic
       compliance nonlinearities in machine tools", PhD thesis, RPI, 1998.
.. [2] B. Armstrong-Hélouvry, P. Dupont, C. Canudas de Wit, "A survey of models, analysis
       tools and compensation methods for the control of machines with friction",
       Automatica 30(7), 1083–1138, 1994. doi:10.1016/0005-1098(94)90209-7
.. [3] C. Canudas de Wit, H. Olsson, K. J. Åström, P. Lischinsky, "A new model for control
       of systems with friction", IEEE Trans. Automatic Control 40(3), 419–425, 1995.
       doi:10.1109/9.376053
.. [4] N. Barabanov, R. Ortega, "Necessary and sufficient conditions for passivity of the
       LuGre friction model", IEEE Trans. Automatic Control 45(4), 830–832, 2000.
.. [5] H. Olsson, K. J. Åström, C. Canudas de Wit, M. Gäfvert, P. Lischinsky, "Friction
       models and friction compensation", European J. Control 4(3), 176–195, 1998.
.. [6] P. R. Dahl, "Solid friction damping of mechanical vibrations", AIAA Journal 14(12),
       1675–1682, 1976. doi:10.2514/3.61511
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from driveid.errors import ParameterError
from driveid.models.friction_memory import lag_signal

__all__ = [
    "ArmstrongParams",
    "DahlParams",
    "CanudasParams",
    "LuGreParams",
    "armstrong_friction",
    "dahl_state_derivative",
    "dahl_friction",
    "dahl_jacobian",
    "canudas_state_derivative",
    "canudas_friction",
    "canudas_jacobian",
    "canudas_steady_friction",
    "saturation",
    "lugre_stribeck",
    "lugre_state_derivative",
    "lugre_friction",
    "lugre_jacobian",
    "lugre_steady_friction",
    "lugre_passivity_bound",
]


def _check(name: str, value: Any, *, unit: str, strict: bool) -> None:
    """Raise ParameterError unless ``value`` is finite and > 0 (strict) or >= 0."""
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ParameterError(f"{name} must be a real number; got {name}={value!r}") from None
    ok = np.isfinite(x) and (x > 0.0 if strict else x >= 0.0)
    if not ok:
        rule = "> 0" if strict else ">= 0"
        raise ParameterError(
            f"{name} must be finite and {rule} [{unit}]; pass a physical value; "
            f"got {name}={value!r}"
        )


def _levels(low_name: str, low: float, high_name: str, high: float) -> None:
    if not high >= low:
        raise ParameterError(
            f"{high_name} must be >= {low_name}={low!r} (static friction is not below "
            f"kinetic friction); swap them or make them equal; got {high_name}={high!r}"
        )


# --- Armstrong-Hélouvry seven-parameter model (2.15) ------------------------------------


@dataclass(frozen=True, kw_only=True)
class ArmstrongParams:
    """Armstrong-Hélouvry's integrated (seven-parameter) friction model, Eq. (2.15).

    Parameters
    ----------
    mu_k : float
        Coulomb (kinetic) friction [N or N·m]; >= 0.
    mu_s_a : float
        Stribeck friction at the end of the previous slide, the rise's start [N or N·m]; >= 0.
    mu_s_inf : float
        Stribeck friction after a long dwell [N or N·m]; >= 0.
    nu : float
        Viscous coefficient [N·s/m or N·m·s/rad]; >= 0.
    v_s : float
        Stribeck velocity [m/s or rad/s]; > 0.
    lag : float
        Frictional memory time Δt [s]; >= 0.
    gamma : float
        Rising-friction time constant of (2.7) [s]; > 0.
    k_s : float
        Presliding (tangential contact) stiffness of (2.13) [N/m or N·m/rad]; > 0.
    """

    mu_k: float
    mu_s_a: float
    mu_s_inf: float
    nu: float
    v_s: float
    lag: float
    gamma: float
    k_s: float

    def __post_init__(self) -> None:
        for name in ("mu_k", "mu_s_a", "mu_s_inf"):
            _check(name, getattr(self, name), unit="N or N·m", strict=False)
        _check("nu", self.nu, unit="N·s/m or N·m·s/rad", strict=False)
        _check("v_s", self.v_s, unit="m/s or rad/s", strict=True)
        _check("lag", self.lag, unit="s", strict=False)
        _check("gamma", self.gamma, unit="s", strict=True)
        _check("k_s", self.k_s, unit="N/m or N·m/rad", strict=True)


def armstrong_friction(
    v: Any,
    x: Any,
    dt: float,
    params: ArmstrongParams,
    *,
    v_stick: float = 0.0,
    form: str = "survey",
) -> np.ndarray:
    r"""Armstrong-Hélouvry's integrated friction model on a time series, Eq. (2.15).

    Parameters
    ----------
    v : array_like, shape (n,)
        Velocity sampled every ``dt`` [m/s or rad/s].
    x : array_like, shape (n,)
        Displacement at the same samples [m or rad]; used only while stuck.
    dt : float
        Sample interval [s]; > 0.
    params : ArmstrongParams
        The model's parameters.
    v_stick : float, optional
        Samples with ``|v| <= v_stick`` [m/s or rad/s] count as stuck. Default 0.
    form : {"survey", "thesis"}
        ``"survey"`` (default) lags only the velocity inside the Stribeck term, the form
        usually quoted from [2] eqs. (9)–(11) (the memory is a lubricant state);
        ``"thesis"`` lags the sign and viscous terms but not the Stribeck velocity, as
        printed in (2.15). Both agree at steady velocity.

    Returns
    -------
    ndarray, shape (n,)
        Friction force [N or N·m].

    Raises
    ------
    ParameterError
        If shapes differ, ``dt <= 0``, ``v_stick < 0`` or ``form`` is unknown.

    Notes
    -----
    Sliding (``|v| > v_stick``):

    .. math:: f = \mathrm{sgn}(\dot x)\left[\mu_k + \frac{\mu_s(t_2)}
              {1 + (\dot x(t - \Delta t)/\dot x_S)^2}\right] + \nu\dot x  \qquad (2.15)

    where :math:`\mu_s(t_2)` follows (2.7) from ``mu_s_a`` to ``mu_s_inf`` over the
    duration ``t_2`` of the last stick interval (0 if none). Stuck: presliding spring
    (2.13), ``k_s`` times the displacement since sticking began, saturated at the current
    breakaway level ``mu_k + mu_s(t_dwell)``.

    Examples
    --------
    >>> p = ArmstrongParams(mu_k=1.0, mu_s_a=3.0, mu_s_inf=3.0, nu=0.5, v_s=1.0,
    ...                     lag=0.0, gamma=1.0, k_s=1e4)
    >>> armstrong_friction([1.0, 1.0], [0.0, 1.0], 1.0, p)
    array([3., 3.])
    """
    v = np.asarray(v, dtype=float)
    x = np.asarray(x, dtype=float)
    if v.ndim != 1 or v.shape != x.shape:
        raise ParameterError(
            f"v and x must be one-dimensional and of equal length; got shapes {v.shape} "
            f"and {x.shape}"
        )
    _check("dt", dt, unit="s", strict=True)
    _check("v_stick", v_stick, unit="m/s or rad/s", strict=False)
    if form not in ("survey", "thesis"):
        raise ParameterError(f"form must be 'survey' or 'thesis'; got form={form!r}")
    p = params
    n = v.size
    idx = np.arange(n)
    stuck = np.abs(v) <= v_stick
    starts = stuck & ~np.concatenate(([False], stuck[:-1]))
    run_start = np.maximum.accumulate(np.where(starts, idx, -1))
    last_stuck = np.maximum.accumulate(np.where(stuck, idx, -1))
    # Dwell of the most recent stick interval (duration up to the first sliding sample).
    dwell = np.where(last_stuck >= 0, (last_stuck - run_start + 1) * dt, 0.0)
    rise = p.mu_s_a + (p.mu_s_inf - p.mu_s_a) * dwell / (p.gamma + dwell)  # (2.7)

    v_lag = lag_signal(v, dt, p.lag)
    if form == "survey":
        sliding = np.sign(v) * (p.mu_k + rise / (1.0 + (v_lag / p.v_s) ** 2)) + p.nu * v
    else:
        sliding = np.sign(v_lag) * (p.mu_k + rise / (1.0 + (v / p.v_s) ** 2)) + p.nu * v_lag

    dwell_now = (idx - run_start) * dt
    rise_now = p.mu_s_a + (p.mu_s_inf - p.mu_s_a) * dwell_now / (p.gamma + dwell_now)
    limit = p.mu_k + rise_now
    x0 = x[np.clip(run_start, 0, None)]
    spring = np.clip(p.k_s * (x - x0), -limit, limit)  # (2.13), package sign
    return np.where(stuck, spring, sliding)


# --- Dahl (2.16)–(2.18) ------------------------------------------------------------------


@dataclass(frozen=True, kw_only=True)
class DahlParams:
    """Dahl model parameters, de Marchi (1998) Eq. (2.16).

    Parameters
    ----------
    k_s : float
        Rest stiffness, the slope dF/dx at F = 0 [N/m or N·m/rad]; > 0.
    mu_k : float
        Coulomb friction, the force reached after long sliding [N or N·m]; > 0.
    gamma : float
        Shape exponent [-]; > 0 (1 in most references, 2 in Häessig & Friedland).
    nu : float
        Viscous coefficient added to the output [N·s/m or N·m·s/rad]; >= 0.
    """

    k_s: float
    mu_k: float
    gamma: float
    nu: float

    def __post_init__(self) -> None:
        _check("k_s", self.k_s, unit="N/m or N·m/rad", strict=True)
        _check("mu_k", self.mu_k, unit="N or N·m", strict=True)
        _check("gamma", self.gamma, unit="-", strict=True)
        _check("nu", self.nu, unit="N·s/m or N·m·s/rad", strict=False)


def dahl_state_derivative(f: Any, v: Any, params: DahlParams) -> np.ndarray:
    r"""Rate of the Dahl hysteretic force, de Marchi (1998) Eq. (2.16).

    Parameters
    ----------
    f : array_like
        Dahl (hysteretic) friction state [N or N·m].
    v : array_like, broadcastable to ``f``
        Velocity [m/s or rad/s].
    params : DahlParams
        Stiffness, Coulomb level, exponent, viscous coefficient.

    Returns
    -------
    ndarray
        df/dt [N/s or N·m/s].

    Notes
    -----
    .. math:: \dot f = k_s \dot x\, \mathrm{sgn}(u) |u|^\gamma,
              \quad u = 1 - \mathrm{sgn}(\dot x) f/\mu_k

    Erratum: (2.16) adds :math:`\nu\dot x` to :math:`\dot f`, which mixes N/s with N;
    the viscous term belongs to the output force (:func:`dahl_friction`). Erratum: (2.18)
    prints :math:`\gamma_s = k_s\mu_k\,\mathrm{sgn}(u)`; expanding (2.16) with
    :math:`\gamma = 2`, :math:`u^2 = (f - \mu_k\mathrm{sgn}\dot x)^2/\mu_k^2`, so (2.17)
    needs :math:`\gamma_s = k_s\,\mathrm{sgn}(u)/\mu_k^2` (checked in tests). The thesis's
    time lag Δt can be applied to ``v`` with :func:`driveid.models.friction_memory.lag_signal`.

    Examples
    --------
    >>> p = DahlParams(k_s=100.0, mu_k=2.0, gamma=1.0, nu=0.0)
    >>> dahl_state_derivative([0.0, 2.0], 1.0, p)
    array([100.,   0.])
    """
    f = np.asarray(f, dtype=float)
    v = np.asarray(v, dtype=float)
    u = 1.0 - np.sign(v) * f / params.mu_k
    return params.k_s * v * np.sign(u) * np.abs(u) ** params.gamma


def dahl_friction(f: Any, v: Any, params: DahlParams) -> np.ndarray:
    """Dahl friction output: hysteretic state plus viscous term, Eq. (2.16).

    Parameters
    ----------
    f : array_like
        Dahl state [N or N·m].
    v : array_like, broadcastable to ``f``
        Velocity [m/s or rad/s].
    params : DahlParams
        Model parameters.

    Returns
    -------
    ndarray
        Friction force ``f + nu v`` [N or N·m].

    Examples
    --------
    >>> dahl_friction([1.0], 2.0, DahlParams(k_s=1.0, mu_k=2.0, gamma=1.0, nu=0.5))
    array([2.])
    """
    return np.asarray(f, dtype=float) + params.nu * np.asarray(v, dtype=float)


def dahl_jacobian(f: Any, v: Any, params: DahlParams) -> np.ndarray:
    r"""Analytic d(df/dt)/df of the Dahl model.

    Parameters
    ----------
    f : array_like
        Dahl state [N or N·m].
    v : array_like, broadcastable to ``f``
        Velocity [m/s or rad/s].
    params : DahlParams
        Model parameters.

    Returns
    -------
    ndarray
        :math:`-k_s |\dot x| \gamma |u|^{\gamma-1}/\mu_k` [1/s]; unbounded at ``u = 0``
        when ``gamma < 1``.

    Examples
    --------
    >>> dahl_jacobian([0.0], -1.0, DahlParams(k_s=100.0, mu_k=2.0, gamma=1.0, nu=0.0))
    array([-50.])
    """
    f = np.asarray(f, dtype=float)
    v = np.asarray(v, dtype=float)
    u = 1.0 - np.sign(v) * f / params.mu_k
    with np.errstate(divide="ignore"):
        du = params.gamma * np.abs(u) ** (params.gamma - 1.0)
    return -params.k_s * np.abs(v) * du / params.mu_k


# --- Canudas de Wit et al. two-state model (2.19)–(2.22) ----------------------------------


@dataclass(frozen=True, kw_only=True)
class CanudasParams:
    """Parameters of the Canudas de Wit et al. memory model, Eqs. (2.19)–(2.22).

    Parameters
    ----------
    mu_k : float
        Kinetic friction [N or N·m]; >= 0.
    mu_s : float
        Static friction [N or N·m]; >= mu_k.
    nu : float
        Viscous coefficient [N·s/m or N·m·s/rad]; >= 0.
    v_s : float
        Stribeck velocity [m/s or rad/s]; > 0.
    memory : float
        Frictional memory time constant Δt [s]; > 0.
    k_s : float
        Presliding stiffness [N/m or N·m/rad]; > 0 (only in (2.21)).
    nu_s : float
        Contact-interface damping [N·s/m or N·m·s/rad]; >= 0 (only in (2.21)).
    """

    mu_k: float
    mu_s: float
    nu: float
    v_s: float
    memory: float
    k_s: float
    nu_s: float

    def __post_init__(self) -> None:
        _check("mu_k", self.mu_k, unit="N or N·m", strict=False)
        _check("mu_s", self.mu_s, unit="N or N·m", strict=False)
        _levels("mu_k", self.mu_k, "mu_s", self.mu_s)
        _check("nu", self.nu, unit="N·s/m or N·m·s/rad", strict=False)
        _check("v_s", self.v_s, unit="m/s or rad/s", strict=True)
        _check("memory", self.memory, unit="s", strict=True)
        _check("k_s", self.k_s, unit="N/m or N·m/rad", strict=True)
        _check("nu_s", self.nu_s, unit="N·s/m or N·m·s/rad", strict=False)


def _g_steady(v: np.ndarray, v_s: float) -> np.ndarray:
    return 1.0 - np.exp(-((v / v_s) ** 2))


def canudas_state_derivative(g: Any, v: Any, params: CanudasParams) -> np.ndarray:
    r"""Rate of the Stribeck mix ``g``, de Marchi (1998) Eq. (2.20).

    Parameters
    ----------
    g : array_like
        Stribeck mix [-], 0 at stick, towards 1 in full sliding.
    v : array_like, broadcastable to ``g``
        Velocity [m/s or rad/s].
    params : CanudasParams
        Model parameters.

    Returns
    -------
    ndarray
        :math:`\dot g = [1 - e^{-(\dot x/\dot x_S)^2} - g]/\Delta t` [1/s].

    Examples
    --------
    >>> p = CanudasParams(mu_k=1.0, mu_s=2.0, nu=0.0, v_s=1.0, memory=0.5, k_s=1e3, nu_s=0.0)
    >>> canudas_state_derivative([0.0], 0.0, p)
    array([0.])
    """
    g = np.asarray(g, dtype=float)
    v = np.asarray(v, dtype=float)
    return (_g_steady(v, params.v_s) - g) / params.memory


def canudas_friction(g: Any, v: Any, params: CanudasParams) -> np.ndarray:
    r"""Friction of the Canudas de Wit et al. memory model, de Marchi (1998) Eq. (2.19).

    Parameters
    ----------
    g : array_like
        Stribeck mix state [-].
    v : array_like, broadcastable to ``g``
        Velocity [m/s or rad/s] (already lagged, if a lag is wanted).
    params : CanudasParams
        Model parameters.

    Returns
    -------
    ndarray
        :math:`[(1-g)\mu_s + g\mu_k]\,\mathrm{sgn}(\dot x) + \nu\dot x` [N or N·m].

    Examples
    --------
    >>> p = CanudasParams(mu_k=1.0, mu_s=2.0, nu=0.0, v_s=1.0, memory=0.5, k_s=1e3, nu_s=0.0)
    >>> canudas_friction([0.5], 1.0, p)
    array([1.5])
    """
    g = np.asarray(g, dtype=float)
    v = np.asarray(v, dtype=float)
    p = params
    return ((1.0 - g) * p.mu_s + g * p.mu_k) * np.sign(v) + p.nu * v


def canudas_jacobian(g: Any, v: Any, params: CanudasParams) -> np.ndarray:
    """Analytic d(dg/dt)/dg of Eq. (2.20).

    Parameters
    ----------
    g : array_like
        Stribeck mix state [-].
    v : array_like, broadcastable to ``g``
        Velocity [m/s or rad/s].
    params : CanudasParams
        Model parameters.

    Returns
    -------
    ndarray
        ``-1/memory`` [1/s], broadcast to the common shape.

    Examples
    --------
    >>> p = CanudasParams(mu_k=1.0, mu_s=2.0, nu=0.0, v_s=1.0, memory=0.5, k_s=1e3, nu_s=0.0)
    >>> canudas_jacobian([0.1, 0.2], 1.0, p)
    array([-2., -2.])
    """
    g, v = np.broadcast_arrays(np.asarray(g, dtype=float), np.asarray(v, dtype=float))
    return np.full(g.shape, -1.0 / params.memory)


def saturation(alpha: Any, beta: Any) -> np.ndarray:
    r"""Saturation function of de Marchi (1998) Eq. (2.22).

    Parameters
    ----------
    alpha : array_like
        Saturation level (>= 0) [N or N·m].
    beta : array_like, broadcastable to ``alpha``
        Argument [N or N·m].

    Returns
    -------
    ndarray
        ``alpha sgn(beta)`` where ``|beta| > alpha``, else ``beta``.

    Examples
    --------
    >>> saturation(1.0, [-3.0, 0.5, 2.0])
    array([-1. ,  0.5,  1. ])
    """
    alpha = np.asarray(alpha, dtype=float)
    beta = np.asarray(beta, dtype=float)
    return np.where(np.abs(beta) > alpha, alpha * np.sign(beta), beta)


def canudas_steady_friction(v: Any, params: CanudasParams) -> np.ndarray:
    r"""Steady-velocity friction with presliding saturation, de Marchi (1998) Eq. (2.21).

    Parameters
    ----------
    v : array_like
        Velocity [m/s or rad/s].
    params : CanudasParams
        Model parameters, including ``k_s`` and ``nu_s``.

    Returns
    -------
    ndarray, shape like ``v``
        Friction force [N or N·m]; 0 at ``v == 0``.

    Notes
    -----
    .. math:: f = g\,\mathrm{sgn}(\dot x)\mu_k + \nu\dot x + (1 - g)\,
              \mathrm{sat}\{\mu_s, k_s\dot x\Delta t (1-g)/g + \nu_s\dot x\},
              \quad g = 1 - e^{-(\dot x/\dot x_S)^2}

    Erratum: (2.21) prints :math:`\mu_s` in the first term; with it the force tends to
    :math:`\mu_s` instead of :math:`\mu_k` at high velocity, contradicting (2.19), so
    :math:`\mu_k` is used. Erratum: the definition below (2.22) prints
    :math:`g = 1 - e^{-\dot x/\dot x_S^2}`; (2.20) gives :math:`(\dot x/\dot x_S)^2`.
    Wherever the saturation is active the result equals (2.19) at steady state exactly.

    Examples
    --------
    >>> p = CanudasParams(mu_k=1.0, mu_s=2.0, nu=0.0, v_s=1.0, memory=0.5, k_s=1e3, nu_s=0.0)
    >>> bool(abs(canudas_steady_friction(0.01, p) - 2.0) < 1e-3)
    True
    """
    v = np.asarray(v, dtype=float)
    p = params
    g = _g_steady(v, p.v_s)
    with np.errstate(divide="ignore", invalid="ignore"):
        beta = p.k_s * v * p.memory * (1.0 - g) / g + p.nu_s * v
    f = g * np.sign(v) * p.mu_k + p.nu * v + (1.0 - g) * saturation(p.mu_s, beta)
    return np.where(v == 0.0, 0.0, f)


# --- LuGre (2.23)–(2.26) ----------------------------------------------------------------


@dataclass(frozen=True, kw_only=True)
class LuGreParams:
    """LuGre model parameters, de Marchi (1998) Eqs. (2.23)–(2.26), notation of [3].

    Parameters
    ----------
    sigma0 : float
        Bristle stiffness, the thesis's k_s [N/m or N·m/rad]; > 0.
    sigma1 : float
        Bristle damping, the thesis's nu_s [N·s/m or N·m·s/rad]; >= 0.
    sigma2 : float
        Viscous coefficient, the thesis's nu [N·s/m or N·m·s/rad]; >= 0.
    fc : float
        Coulomb friction, mu_k [N or N·m]; > 0.
    fs : float
        Static friction, mu_s [N or N·m]; >= fc.
    vs : float
        Stribeck velocity [m/s or rad/s]; > 0.
    check_passivity : bool
        If True (default), require the passivity condition of
        :func:`lugre_passivity_bound`; pass False to accept an active (energy-generating)
        parameter set deliberately.
    """

    sigma0: float
    sigma1: float
    sigma2: float
    fc: float
    fs: float
    vs: float
    check_passivity: bool = True

    def __post_init__(self) -> None:
        _check("sigma0", self.sigma0, unit="N/m or N·m/rad", strict=True)
        _check("sigma1", self.sigma1, unit="N·s/m or N·m·s/rad", strict=False)
        _check("sigma2", self.sigma2, unit="N·s/m or N·m·s/rad", strict=False)
        _check("fc", self.fc, unit="N or N·m", strict=True)
        _check("fs", self.fs, unit="N or N·m", strict=True)
        _levels("fc", self.fc, "fs", self.fs)
        _check("vs", self.vs, unit="m/s or rad/s", strict=True)
        if self.check_passivity:
            bound = lugre_passivity_bound(sigma2=self.sigma2, fc=self.fc, fs=self.fs)
            if self.sigma1 > bound:
                raise ParameterError(
                    f"sigma1 must be <= sigma2*fc/(fs - fc) = {bound!r} for the LuGre map "
                    "v -> F to be passive; raise sigma2, lower sigma1, or pass "
                    f"check_passivity=False deliberately; got sigma1={self.sigma1!r}"
                )


def lugre_passivity_bound(*, sigma2: float, fc: float, fs: float) -> float:
    r"""Largest bristle damping for which the LuGre map v -> F is passive.

    Parameters
    ----------
    sigma2 : float
        Viscous coefficient [N·s/m or N·m·s/rad]; >= 0.
    fc : float
        Coulomb friction [N or N·m]; > 0.
    fs : float
        Static friction [N or N·m]; >= fc.

    Returns
    -------
    float
        :math:`\sigma_2 F_c/(F_s - F_c)` [N·s/m or N·m·s/rad]; ``inf`` when ``fs == fc``.

    Notes
    -----
    Condition of Barabanov & Ortega [4] (see also [5]), re-derived: with storage
    :math:`V = \sigma_0 z^2/2`, :math:`\dot z = v - a z`, :math:`a = \sigma_0|v|/g_F(v)`
    and :math:`w = \sigma_0 z\,\mathrm{sgn}(v)/g_F` (:math:`|w| \le F_s/g_F` on the
    invariant set :math:`|\sigma_0 z| \le F_s`),

    .. math:: Fv - \dot V = v^2\left[\frac{g_F}{|v|} w^2 - \sigma_1 w + \sigma_1
              + \sigma_2\right],

    which is >= 0 for all reachable states iff :math:`\sigma_1 (F_s - F_c) \le \sigma_2
    F_c`. Necessity: a velocity step to a large ``v`` from :math:`\sigma_0 z = F_s`
    returns net energy proportional to ``v`` otherwise (checked in tests). This is a
    property of the friction map alone; the common bristle-damping choice near
    :math:`2\sqrt{\sigma_0 J}` for a body of inertia ``J`` is a separate design rule.

    Examples
    --------
    >>> lugre_passivity_bound(sigma2=0.4, fc=1.0, fs=1.5)
    0.8
    """
    if fs <= fc:
        return float("inf")
    return float(sigma2 * fc / (fs - fc))


def lugre_stribeck(v: Any, params: LuGreParams) -> np.ndarray:
    r"""Force-valued Stribeck curve :math:`g_F(v) = k_s g(v)`, de Marchi (1998) Eq. (2.26).

    Parameters
    ----------
    v : array_like
        Velocity [m/s or rad/s].
    params : LuGreParams
        Model parameters.

    Returns
    -------
    ndarray
        :math:`F_c + (F_s - F_c)e^{-(v/v_s)^2}` [N or N·m], even in ``v``.

    Examples
    --------
    >>> p = LuGreParams(sigma0=1e5, sigma1=0.0, sigma2=0.0, fc=1.0, fs=2.0, vs=0.1)
    >>> lugre_stribeck([0.0], p)
    array([2.])
    """
    v = np.asarray(v, dtype=float)
    p = params
    return p.fc + (p.fs - p.fc) * np.exp(-((v / p.vs) ** 2))


def lugre_state_derivative(z: Any, v: Any, params: LuGreParams) -> np.ndarray:
    r"""Bristle deflection rate of the LuGre model, de Marchi (1998) Eq. (2.23).

    Parameters
    ----------
    z : array_like
        Mean bristle deflection [m or rad].
    v : array_like, broadcastable to ``z``
        Velocity [m/s or rad/s].
    params : LuGreParams
        Model parameters.

    Returns
    -------
    ndarray
        :math:`\dot z = v - \sigma_0 |v| z / g_F(v)` [m/s or rad/s], which is (2.23)
        with :math:`g = g_F/\sigma_0`.

    Examples
    --------
    >>> p = LuGreParams(sigma0=100.0, sigma1=0.0, sigma2=0.0, fc=1.0, fs=1.0, vs=0.1)
    >>> lugre_state_derivative([0.0, 0.01], 1.0, p)
    array([1., 0.])
    """
    z = np.asarray(z, dtype=float)
    v = np.asarray(v, dtype=float)
    return v - params.sigma0 * np.abs(v) * z / lugre_stribeck(v, params)


def lugre_friction(z: Any, v: Any, params: LuGreParams) -> np.ndarray:
    r"""LuGre friction force, de Marchi (1998) Eq. (2.24).

    Parameters
    ----------
    z : array_like
        Mean bristle deflection [m or rad].
    v : array_like, broadcastable to ``z``
        Velocity [m/s or rad/s].
    params : LuGreParams
        Model parameters.

    Returns
    -------
    ndarray
        :math:`F = \sigma_0 z + \sigma_1 \dot z + \sigma_2 v` [N or N·m], with
        :math:`\dot z` from :func:`lugre_state_derivative`.

    Examples
    --------
    >>> p = LuGreParams(sigma0=100.0, sigma1=0.0, sigma2=0.5, fc=1.0, fs=1.0, vs=0.1)
    >>> lugre_friction([0.01], 2.0, p)
    array([2.])
    """
    z = np.asarray(z, dtype=float)
    v = np.asarray(v, dtype=float)
    p = params
    return p.sigma0 * z + p.sigma1 * lugre_state_derivative(z, v, p) + p.sigma2 * v


def lugre_jacobian(z: Any, v: Any, params: LuGreParams) -> np.ndarray:
    r"""Analytic d(dz/dt)/dz of the LuGre model.

    Parameters
    ----------
    z : array_like
        Mean bristle deflection [m or rad].
    v : array_like, broadcastable to ``z``
        Velocity [m/s or rad/s].
    params : LuGreParams
        Model parameters.

    Returns
    -------
    ndarray
        :math:`-\sigma_0 |v|/g_F(v)` [1/s], broadcast to the common shape.

    Examples
    --------
    >>> p = LuGreParams(sigma0=100.0, sigma1=0.0, sigma2=0.0, fc=1.0, fs=1.0, vs=0.1)
    >>> lugre_jacobian([0.0], -0.5, p)
    array([-50.])
    """
    z, v = np.broadcast_arrays(np.asarray(z, dtype=float), np.asarray(v, dtype=float))
    return -params.sigma0 * np.abs(v) / lugre_stribeck(v, params)


def lugre_steady_friction(v: Any, params: LuGreParams) -> np.ndarray:
    r"""Steady-velocity LuGre friction, the Stribeck map of (2.25)–(2.26).

    Parameters
    ----------
    v : array_like
        Constant velocity [m/s or rad/s].
    params : LuGreParams
        Model parameters.

    Returns
    -------
    ndarray
        :math:`g_F(v)\,\mathrm{sgn}(v) + \sigma_2 v` [N or N·m], the (2.5) map with
        ``delta = 2``. The thesis calls this "entirely equivalent to (2.15)", but (2.15)
        is Lorentzian; the exact steady-state match is (2.10)/(2.5) with ``delta = 2``.

    Examples
    --------
    >>> p = LuGreParams(sigma0=1e5, sigma1=0.0, sigma2=0.5, fc=1.0, fs=2.0, vs=0.1)
    >>> lugre_steady_friction([-10.0, 10.0], p)
    array([-6.,  6.])
    """
    v = np.asarray(v, dtype=float)
    return lugre_stribeck(v, params) * np.sign(v) + params.sigma2 * v
