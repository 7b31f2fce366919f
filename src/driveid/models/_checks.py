"""Parameter checks shared by the friction models: each error states the rule, value and fix."""

from __future__ import annotations

from typing import Any

import numpy as np

from driveid.errors import ParameterError


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
