"""Plausibility guards applied to every estimate before a user sees it.

A least-squares fit always returns numbers; these checks say when the numbers cannot be
physical and name the likely cause and what to try:

- a mass or inertia that is zero or negative (``J``, ``M``, ``M_plus`` ...), or a stiffness
  ``K`` negative by more than two standard errors: the model lacks a load that the data
  carry (gravity on a vertical axis, a spring, backlash impacts, see the thesis's ch. 3), or
  the test did not excite inertia enough;
- viscous or Coulomb friction negative by more than two standard errors (``c_mean``,
  ``fk_mean``, ``fs_mean``, ``Fv``, ``Fc`` and their ``_plus``/``_minus``): motion in one
  direction only (mean and asymmetry are then not separable, thesis Eq. 2.155), an
  unmodelled load, or an uncompensated loop delay (PHO, thesis Sec. 5.3);
- a standard error larger than the value of a quantity that must be positive: too little
  excitation or too few data for that parameter.

- a backlash gap, a damping (viscous coefficient, damping ratio, decay rate) or a stiffness
  that is negative at all, or ill-determined (standard error at least half its value): a
  warning naming the likely cause, and ``diagnostics["at_bound"]`` recording the bound
  (0), the unconstrained value and standard error and the one-sided 95 % upper limit
  ``max(value + 1.645 s.e., 0)`` (the interval the data allow under the physical bound).

Signed asymmetries (``c_delta``, ``fk_delta``, ``offset`` ...) may legitimately be zero
within their error and are not checked for it. Given values (``Parameter.fixed``) are
never checked.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Callable
from typing import Any

from driveid.identify.core.estimate import Estimate

__all__ = ["check_plausibility", "plausibility_checked", "check_refit_stability",
           "held_at_zero", "GAP_HINT"]

_INERTIA = ("J", "M", "M_plus", "M_minus")
_STIFFNESS = ("K",)
_FRICTION = ("c_mean", "fk_mean", "fs_mean", "Fv", "Fc", "Fv_plus", "Fv_minus", "Fc_plus",
             "Fc_minus", "c_plus", "c_minus", "fk_plus", "fk_minus")
# K is not here: a free axis has K = 0, and an estimate within its error of 0 is right
_POSITIVE = (*_INERTIA, *_FRICTION, "omega0", "omega_d", "zeta", "zeta_plus", "zeta_minus",
             "sigma")
_SIGNIFICANT = 2.0
#: Bounded at 0 by physics, never negative without a warning (issue 24).
_GAP = ("gap", "gap_plus", "gap_minus", "gap_total", "b")
_DAMPING = ("c_mean", "c_plus", "c_minus", "c", "Fv", "Fv_plus", "Fv_minus", "zeta",
            "zeta_plus", "zeta_minus", "zeta_mean", "sigma")
_SPRING = ("K", "K0", "K_eff", "ks", "K_plus", "K_minus", "sigma0", "K_contact")
#: One-sided 95 % normal quantile [-].
_ONE_SIDED_95 = 1.645
#: Standard error at or above this fraction of |value|: ill-determined [-] (issue 24).
_ILL = 0.5

GAP_HINT = (
    "a gap cannot be negative; likely presliding friction or a preloaded (zero-backlash) "
    "transmission read as a dead zone, contact lines fitted where the driven side already "
    "slides, positions read before they settled, or a stiffness that is not linear at small "
    "loads; try slower full cycles, larger loads on both sides, or identify loop --kind "
    "presliding")
_DAMPING_HINT = (
    "damping cannot be negative in a passive drive; likely Coulomb friction read as viscous "
    "(a straight-line decay envelope: identify envelope tells them apart), quadratic (air) "
    "damping, drift or an offset in the record, a loop delay feeding energy in (PHO), or too "
    "short a record; try a window without drift (--t-start/--t-end), a friction model with "
    "Coulomb terms, or compensating the delay")
_SPRING_HINT = (
    "a passive stiffness cannot be negative; likely an unmodelled load (gravity, a preload), "
    "backlash impacts, or too little deflection to resolve the spring; try larger loads or "
    "amplitudes, a longer window, or give the value (--stiffness)")
_ILL_HINT = (
    "the data hardly determine it (the interval reaches zero); excite more (larger amplitude, "
    "more cycles or loads), or give the value if it is known")

_INERTIA_HINT = (
    "likely an unmodelled load (gravity on a vertical axis, a spring), backlash impacts, or "
    "too little excitation of inertia (accelerations small next to friction); try a larger or "
    "faster excitation, a window without impacts (--t-start/--t-end), a model with an offset, "
    "or give the value (--mass)")
_STIFFNESS_HINT = (
    "likely an unmodelled load (gravity, a preload), backlash, or a record too short to "
    "resolve the spring; try a longer window, both directions of motion, or give the value "
    "(--stiffness)")
_FRICTION_HINT = (
    "likely motion in one direction only (mean and asymmetry are then not separable), an "
    "unmodelled load such as gravity, or an uncompensated loop delay; try runs in both "
    "directions, a model with an offset, or compensating the delay")
_ERROR_HINT = (
    "too little excitation or too few data to identify it; try a longer record, a larger "
    "amplitude, more runs, or give the value if it is known")


def check_plausibility(est: Estimate) -> Estimate:
    """Return a copy of ``est`` with a warning for every physically implausible parameter.

    Parameters
    ----------
    est : Estimate
        Any estimate; parameters are looked up by the names of DESIGN.md.

    Returns
    -------
    Estimate
        The same estimate, its ``warnings`` extended (each message once; running the check
        twice adds nothing).

    Examples
    --------
    >>> from driveid.identify.core.estimate import Parameter
    >>> est = Estimate("demo", {"M": Parameter(-0.4, 0.1, "kg")})
    >>> check_plausibility(est).warnings[0][:33]
    'M = -0.4 kg is not positive: like'
    """
    messages = []
    at_bound: dict[str, Any] = {}
    for name, par in est.params.items():
        if par.fixed or not math.isfinite(par.value):
            continue
        value = f"{name} = {par.value:.4g} {par.unit}".rstrip()
        # below zero by more than 2 standard errors: a true value >= 0 gives that in < 2.3 %
        error = par.stderr if math.isfinite(par.stderr) and par.stderr > 0 else 0.0
        negative = par.value < -_SIGNIFICANT * error
        bounded = _bounded_hint(name)
        if name in (est.diagnostics.get("at_bound") or {}):
            continue  # the estimator held it at its bound and said so
        if bounded is not None and (par.value < 0 or error >= _ILL * abs(par.value)):
            at_bound[name] = _bound_record(par.value, error)
            messages.append(_bounded_message(value, par.value, error, bounded))
        elif name in _INERTIA and par.value <= 0:
            messages.append(f"{value} is not positive: {_INERTIA_HINT}")
        elif name in _STIFFNESS and negative:
            messages.append(f"{value} is negative: {_STIFFNESS_HINT}")
        elif name in _FRICTION and negative:
            messages.append(f"{value} is negative friction: {_FRICTION_HINT}")
        elif (name in _POSITIVE and error > abs(par.value) and par.value != 0):
            messages.append(f"{value} has a standard error {par.stderr:.3g} larger than its "
                            f"value: {_ERROR_HINT}")
    out = est.with_warnings(*messages)
    if at_bound:
        previous = dict(est.diagnostics.get("at_bound") or {})
        out = dataclasses.replace(out, diagnostics={
            **out.diagnostics, "at_bound": {**at_bound, **previous}})
    return out


def held_at_zero(name: str, value: float, stderr: float, unit: str, cause: str
                 ) -> tuple[dict[str, Any], str]:
    """Describe an estimate held at its physical bound 0 after an unconstrained fit fell below.

    Parameters
    ----------
    name : str
        Parameter name, e.g. ``"gap"``.
    value : float
        The unconstrained estimate [unit]; negative.
    stderr : float
        Its standard error [unit] (nan if none).
    unit : str
        Unit for the message.
    cause : str
        The likely cause and what to try, in plain words.

    Returns
    -------
    tuple of (dict, str)
        The ``diagnostics["at_bound"][name]`` entry and the warning.

    Examples
    --------
    >>> entry, msg = held_at_zero("gap", -0.037, 0.016, "rad", "preload")
    >>> entry["at_bound"], round(entry["upper_95"], 4), msg[:24]
    (True, 0.0, 'gap held at its bound 0:')
    """
    error = stderr if math.isfinite(stderr) and stderr > 0 else 0.0
    entry = _bound_record(min(value, 0.0), error)
    interval = (f"; the data allow [0, {entry['upper_95']:.3g}] {unit} (one-sided 95 %)"
                if error > 0 else "")
    if error > 0 and entry["upper_95"] == 0.0:
        interval = (f"; 0 is {abs(value) / error:.1f} standard errors above it, so the model "
                    "does not describe these data")
    se_text = f" ± {error:.2g}" if error > 0 else ""
    return entry, (f"{name} held at its bound 0: the unconstrained fit gave {value:.4g}"
                   f"{se_text} {unit}{interval}; {cause}")


def _bounded_hint(name: str) -> str | None:
    # multi-mode estimators number their modes: zeta_1, K_2 … are judged like zeta, K
    base, _, tail = name.rpartition("_")
    if base and tail.isdigit():
        name = base
    if name in _GAP:
        return GAP_HINT
    if name.startswith("Fv"):
        return _FRICTION_HINT  # viscous friction of a drive fitted from forces
    if name in _DAMPING:
        return _DAMPING_HINT
    if name in _SPRING:
        return _SPRING_HINT
    return None


def _bound_record(value: float, error: float) -> dict[str, Any]:
    """Return the bound 0, the unconstrained estimate and the one-sided 95 % upper limit."""
    upper = max(value + _ONE_SIDED_95 * error, 0.0) if error > 0 else max(value, 0.0)
    return {"bound": 0.0, "value": float(value), "stderr": float(error),
            "at_bound": bool(value <= 0.0), "upper_95": float(upper),
            "interval": "one-sided [0, upper_95]" if value <= 0.0 else "two-sided"}


def _bounded_message(text: str, value: float, error: float, hint: str) -> str:
    if value < 0:
        within = (f", {abs(value) / error:.1f} standard errors below 0" if error > 0 else "")
        upper = max(value + _ONE_SIDED_95 * error, 0.0)
        bound = (f"; under the bound >= 0 the data allow [0, {upper:.3g}] (one-sided 95 %)"
                 if error > 0 and upper > 0 else "")
        if error > 0 and value > -_SIGNIFICANT * error:
            # a true 0 (a free axis, no gap) lands this far below it in ~1 fit of 40
            return (f"{text} is negative but within {_SIGNIFICANT:g} standard errors of 0, so "
                    f"consistent with none{bound}; if it should not be 0: {hint}")
        return f"{text} is negative{within}{bound}: {hint}"
    if value == 0:
        return f"{text} sits at its bound 0: {_ILL_HINT}"
    return (f"{text} is ill-determined (standard error {error:.3g}, at least half its value): "
            f"{_ILL_HINT}")


def plausibility_checked(func: Callable[..., Estimate]) -> Callable[..., Estimate]:
    """Decorate an estimator so that its estimate passes :func:`check_plausibility`.

    Parameters
    ----------
    func : callable
        An ``estimate_<method>(...) -> Estimate`` function.

    Returns
    -------
    callable
        The same function (name, docstring, signature kept) whose result carries the
        plausibility warnings.
    """

    @functools.wraps(func)
    def wrapper(*args: Any, **kwargs: Any) -> Estimate:
        return check_plausibility(func(*args, **kwargs))

    return wrapper


#: Relative change below which two fits of the same data are the same to solver accuracy.
_SOLVER_RESOLUTION = 1e-6


def check_refit_stability(est: Estimate, refit: Estimate, *, change: str,
                          n_sigma: float = 3.0) -> Estimate:
    """Warn when a refit with changed settings moves a parameter beyond its standard errors.

    Parameters
    ----------
    est : Estimate
        The estimate as reported.
    refit : Estimate
        The same method on changed settings: a shorter window, another filter cut-off.
    change : str
        What was changed, named in the warning (e.g. ``"the last 20 % of the window
        dropped"``).
    n_sigma : float
        Threshold in standard errors [-]; the larger of the two estimates' errors is used,
        so a model that fits moves by far less (the refit uses a subset of the same data).

    Returns
    -------
    Estimate
        ``est`` with one warning per parameter that moved by more than ``n_sigma`` standard
        errors (a sign that the model misses something the data carry).
    """
    messages = []
    for name, par in est.params.items():
        other = refit.params.get(name)
        if other is None or par.fixed or other.fixed:
            continue
        error = max(par.stderr, other.stderr)
        if not (math.isfinite(error) and error > 0 and math.isfinite(other.value)):
            continue
        move = abs(other.value - par.value)
        # below ~1e-6 of the value a move is the solvers' own tolerance, not the data: on a
        # noise-free record the standard errors shrink to rounding level and any solver
        # difference would otherwise count as tens of "standard errors"
        if move > n_sigma * error and move > _SOLVER_RESOLUTION * max(abs(par.value), error):
            messages.append(
                f"{name} moves from {par.value:.6g} to {other.value:.6g} {par.unit} "
                f"({abs(other.value - par.value) / error:.1f} standard errors) with {change}: "
                "the model misses something the data carry (amplitude-dependent friction, "
                "backlash, an unmodelled load) or the record ends in noise; try another "
                "window (--t-start/--t-end) or a richer model")
    return est.with_warnings(*messages)


def few_repeats_warning(n: int, what: str) -> list[str]:
    """Warn that ±1.96 s.e. from the spread of few repeats covers less than 95 %.

    Parameters
    ----------
    n : int
        Number of repeats whose spread gave the standard error [-].
    what : str
        What was repeated, e.g. ``"ramps"``.

    Returns
    -------
    list of str
        One warning for 2 <= n < 10 (Student t with n - 1 degrees of freedom), else none.
    """
    if not 2 <= n < 10:
        return []
    from scipy.stats import t as student

    cover = 100.0 * (2.0 * float(student.cdf(1.96, n - 1)) - 1.0)
    return [f"standard errors from the spread of {n} {what}: ±1.96 s.e. covers only "
            f"{cover:.0f} % (Student t, {n - 1} degrees of freedom); use ±"
            f"{float(student.ppf(0.975, n - 1)):.2f} s.e. for 95 %, or repeat more"]
