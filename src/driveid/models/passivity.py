r"""Passivity of the dynamic friction models (the map velocity -> friction force).

A friction model is *passive* when, for some storage ``V(state) >= 0``,
``F(t) v(t) - dV/dt >= 0`` along every trajectory (it never returns more energy than it
stored): a drive with a passive friction model cannot be destabilised by the friction
alone. :class:`~driveid.models.dynamic_friction.LuGreParams` already enforces the
Barabanov–Ortega bound; this module states and checks the conditions of every model of
:mod:`driveid.models.dynamic_friction` (de Marchi 1998, §2.1.1.6, Eqs. (2.15)-(2.26)).

Conditions
----------
Derived here; each is checked numerically in ``tests/models/test_passivity.py`` by
integrating the model under random velocity histories.

* **Dahl** (2.16): storage ``V = f²/(2 k_s)``. With ``φ = f sgn v`` and
  ``u = 1 - φ/μ_k``, ``F v - dV/dt = |v| φ (1 - sgn(u)|u|^γ) + ν v²``. Both factors of the
  first term change sign together at ``φ = 0`` (and for ``|φ| > μ_k`` the bracket exceeds 1
  while φ > 0), so it is ``>= 0`` for every state: passive for all ``k_s, μ_k, γ > 0``,
  ``ν >= 0``, from any initial force.
* **Canudas de Wit et al. memory model** (2.19)-(2.20): the output
  ``[(1-g) μ_s + g μ_k] sgn v + ν v`` gives ``F v = ((1-g) μ_s + g μ_k)|v| + ν v² >= 0``
  whenever ``g ∈ [0, 1]``; (2.20) keeps g in [0, 1] (it relaxes towards
  ``1 - e^{-(v/v_S)²} ∈ [0, 1)``). Passive with zero storage for ``μ_k, μ_s, ν >= 0`` and
  ``g(0) ∈ [0, 1]``. The steady form (2.21) is a static map with the sign of v in every
  term: ``F v >= 0``.
* **Armstrong-Hélouvry** (2.15): while sliding the force has the sign of v (``F v >= 0``
  when ``μ_k, μ_s, ν >= 0``: the lagged velocity enters only squared); while stuck the
  presliding spring ``k_s (x - x_stick)`` is lossless with storage ``k_s (x-x_stick)²/2``,
  released (dissipated) at breakaway. Passive for non-negative levels.
* **LuGre** (2.23)-(2.26): passive iff ``σ1 (F_s - F_c) <= σ2 F_c`` (Barabanov & Ortega;
  :func:`~driveid.models.dynamic_friction.lugre_passivity_bound`).

References
----------
.. [1] J. A. de Marchi, "Modeling of dynamic friction, impact backlash and elastic
       compliance nonlinearities in machine tools", PhD thesis, RPI, 1998, §2.1.1.6.
.. [2] N. Barabanov, R. Ortega, "Necessary and sufficient conditions for passivity of the
       LuGre friction model", IEEE Trans. Automatic Control 45(4), 830-832, 2000.
.. [3] H. Olsson, K. J. Åström, C. Canudas de Wit, M. Gäfvert, P. Lischinsky, "Friction
       models and friction compensation", European J. Control 4(3), 176-195, 1998.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from driveid.errors import ParameterError
from driveid.models.dynamic_friction import (
    ArmstrongParams,
    CanudasParams,
    DahlParams,
    LuGreParams,
    lugre_passivity_bound,
)

__all__ = ["PassivityReport", "check_passivity"]


@dataclass(frozen=True)
class PassivityReport:
    """Whether a friction model is passive, and why.

    Attributes
    ----------
    model : str
        ``"dahl"``, ``"canudas"``, ``"armstrong"`` or ``"lugre"``.
    passive : bool
        True if the condition holds.
    condition : str
        The condition checked, in words.
    margin : float
        How far inside the condition the parameters are, in the unit of the limiting
        parameter (``inf`` when the model is passive for every admissible value; negative
        when violated) [model units].
    storage : str
        The storage function that proves it.
    """

    model: str
    passive: bool
    condition: str
    margin: float
    storage: str


def check_passivity(params: Any) -> PassivityReport:
    """Check the passivity condition of a dynamic friction model (module notes).

    Parameters
    ----------
    params : DahlParams, CanudasParams, ArmstrongParams or LuGreParams
        The model parameters (already validated by their dataclass).

    Returns
    -------
    PassivityReport
        Verdict, condition, margin and storage function.

    Raises
    ------
    ParameterError
        If ``params`` is not one of the four parameter types.

    Examples
    --------
    >>> check_passivity(DahlParams(k_s=1e4, mu_k=1.0, gamma=2.0, nu=0.0)).passive
    True
    >>> p = LuGreParams(sigma0=1e5, sigma1=400.0, sigma2=0.4, fc=1.0, fs=1.5, vs=1e-3,
    ...                 check_passivity=False)
    >>> r = check_passivity(p); r.passive, round(r.margin, 6)
    (False, -399.2)
    """
    if isinstance(params, DahlParams):
        return PassivityReport(
            model="dahl", passive=True, margin=math.inf,
            condition="k_s, mu_k, gamma > 0 and nu >= 0 (always, from any initial force)",
            storage="V = f^2 / (2 k_s)")
    if isinstance(params, CanudasParams):
        levels = min(params.mu_k, params.mu_s, params.nu)
        return PassivityReport(
            model="canudas", passive=levels >= 0, margin=math.inf if levels >= 0 else levels,
            condition="mu_k, mu_s, nu >= 0 and g(0) in [0, 1] (F v >= 0 pointwise)",
            storage="V = 0 (memoryless in v given g)")
    if isinstance(params, ArmstrongParams):
        levels = min(params.mu_k, params.mu_s_a, params.mu_s_inf, params.nu)
        return PassivityReport(
            model="armstrong", passive=levels >= 0,
            margin=math.inf if levels >= 0 else levels,
            condition="mu_k, mu_s_a, mu_s_inf, nu >= 0 (sliding: F v >= 0; stuck: "
                      "lossless presliding spring)",
            storage="V = k_s (x - x_stick)^2 / 2 while stuck, 0 while sliding")
    if isinstance(params, LuGreParams):
        bound = lugre_passivity_bound(sigma2=params.sigma2, fc=params.fc, fs=params.fs)
        margin = bound - params.sigma1
        return PassivityReport(
            model="lugre", passive=margin >= 0, margin=float(margin),
            condition="sigma1 (F_s - F_c) <= sigma2 F_c (Barabanov & Ortega 2000); margin "
                      "= bound - sigma1 [N·s/m or N·m·s/rad]",
            storage="V = sigma0 z^2 / 2")
    raise ParameterError(
        "params must be DahlParams, CanudasParams, ArmstrongParams or LuGreParams; got "
        f"{type(params).__name__}")
