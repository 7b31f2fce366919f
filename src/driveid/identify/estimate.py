"""The :class:`Estimate`: what every identification method returns."""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

from driveid._json import to_jsonable

__all__ = ["Parameter", "Estimate"]


@dataclass(frozen=True)
class Parameter:
    """One identified value with its standard error and unit.

    Attributes
    ----------
    value : float
        Estimated value [unit].
    stderr : float
        One-sigma standard error [unit]; ``nan`` where none is available.
    unit : str
        SI unit, e.g. ``"N·m"``; ``"-"`` for dimensionless.
    fixed : bool
        True for a value that was given (``--mass 1``), not estimated; its ``stderr`` is
        ``nan`` and JSON shows ``"fixed": true, "stderr": null`` (never a misleading 0).
    """

    value: float
    stderr: float = math.nan
    unit: str = "-"
    fixed: bool = False

    def to_dict(self) -> dict[str, Any]:
        """Return ``{"value", "stderr", "unit"}`` with NaN written as ``None``."""
        return {
            "value": _finite_or_none(self.value),
            "stderr": _finite_or_none(self.stderr),
            "unit": self.unit,
        }


@dataclass(frozen=True)
class Estimate:
    """Parameter values with standard errors, the method, the data used and diagnostics.

    Attributes
    ----------
    method : str
        Name of the estimator, e.g. ``"logdec-lsq"``.
    params : mapping of str to Parameter
        Parameters under the names of DESIGN.md (``omega0``, ``c_mean`` ...).
    data_used : mapping
        What the estimator used: peak indices and times, segments, windows (arrays allowed).
    diagnostics : mapping
        Scalar diagnostics: residual rms, condition number, counts.
    warnings : tuple of str
        Reasons to trust the estimate less.
    covariance : mapping or None
        ``{"names": [...], "matrix": ndarray (p, p)}`` of the estimated parameters in their
        units, where the method provides it.
    inputs : tuple of mapping
        Provenance of each record used: ``path``, ``sha256``, ``rows``, ``columns``,
        ``window`` [s], ``units``.
    """

    method: str
    params: Mapping[str, Parameter]
    data_used: Mapping[str, Any] = field(default_factory=dict)
    diagnostics: Mapping[str, Any] = field(default_factory=dict)
    warnings: tuple[str, ...] = ()
    covariance: Mapping[str, Any] | None = None
    inputs: tuple[Mapping[str, Any], ...] = ()

    def __post_init__(self) -> None:
        object.__setattr__(self, "params", MappingProxyType(dict(self.params)))
        object.__setattr__(self, "data_used", MappingProxyType(dict(self.data_used)))
        object.__setattr__(self, "diagnostics", MappingProxyType(dict(self.diagnostics)))
        object.__setattr__(self, "warnings", tuple(self.warnings))
        object.__setattr__(self, "inputs", tuple(self.inputs))

    def __getitem__(self, name: str) -> Parameter:
        try:
            return self.params[name]
        except KeyError:
            raise KeyError(
                f"{self.method} estimate has no parameter {name!r}; it has {sorted(self.params)}"
            ) from None

    def __contains__(self, name: object) -> bool:
        return name in self.params

    def value(self, name: str) -> float:
        """Return the value of parameter ``name``."""
        return self[name].value

    def stderr(self, name: str) -> float:
        """Return the standard error of parameter ``name``."""
        return self[name].stderr

    def to_dict(self) -> dict[str, Any]:
        """Return a JSON-ready dict: ``method``, one key per parameter, diagnostics, warnings."""
        out: dict[str, Any] = {"method": self.method}
        for name, par in self.params.items():
            out[name] = par.to_dict()
        out["diagnostics"] = to_jsonable(dict(self.diagnostics))
        out["warnings"] = list(self.warnings)
        return out

    def to_json(self, **kwargs: Any) -> str:
        """Serialise :meth:`to_dict` to a JSON string (``kwargs`` go to :func:`json.dumps`)."""
        return json.dumps(self.to_dict(), **kwargs)

    def table(self) -> str:
        """Return a plain-text table: name, value ± standard error, unit."""
        rows = [("parameter", "value", "std. error", "unit")]
        for name, par in self.params.items():
            rows.append((name, f"{par.value:.6g}", f"{par.stderr:.3g}", par.unit))
        widths = [max(len(r[i]) for r in rows) for i in range(4)]
        lines = [
            "  ".join(cell.ljust(w) for cell, w in zip(row, widths, strict=True)) for row in rows
        ]
        lines.insert(1, "  ".join("-" * w for w in widths))
        return "\n".join(lines)

    def plot(self, record: Any = None, ax: Any = None) -> Any:
        """Draw the estimate (over ``record`` where the method supports it); return the figure."""
        from driveid.report.figures import plot_estimate

        return plot_estimate(self, record=record, ax=ax)


def _finite_or_none(value: float) -> float | None:
    value = float(value)
    return value if math.isfinite(value) else None
