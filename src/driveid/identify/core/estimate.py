"""The :class:`Estimate`: what every identification method returns, and its result schema.

Every ``Estimate.to_dict()`` and every command's ``--json`` follow one schema,
``driveid-result/1`` (documented in ``docs/result-schema.md``)::

    {"driveid": "0.2.0", "schema": "driveid-result/1", "command": ["driveid", ...] or null,
     "inputs": [{"path", "sha256", "rows", "columns", "window", "units", ...}],
     "method": "logdec-lsq",
     "parameters": {"J": {"value": 1.0, "stderr": null, "unit": "kg·m²", "fixed": true}, ...},
     "covariance": {"names": [...], "matrix": [[...]]} or null,
     "diagnostics": {...}, "warnings": [...], "data_used": {...}}

``data_used`` holds only short entries unless ``series=True``.
"""

from __future__ import annotations

import dataclasses
import json
import math
import numbers
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

from driveid._json import to_jsonable

__all__ = ["Parameter", "Estimate", "SCHEMA", "inputs_of", "non_finite_problem"]

#: Name and version of the result schema; changes that break readers bump the number.
SCHEMA = "driveid-result/1"
_SHORT = 16  # longest array kept in data_used without series=True [-]


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
        True for a value that was given (``--mass 1``), not estimated. Its ``stderr`` is
        ``nan`` or 0 (estimators that propagate errors keep 0 internally); JSON always shows
        ``"fixed": true, "stderr": null`` (never a misleading 0) and the table ``(given)``.
    """

    value: float
    stderr: float = math.nan
    unit: str = "-"
    fixed: bool = False

    def to_dict(self) -> dict[str, Any]:
        """Return ``{"value", "stderr", "unit", "fixed"}``; NaN and a fixed stderr are ``None``."""
        return {
            "value": _finite_or_none(self.value),
            "stderr": None if self.fixed else _finite_or_none(self.stderr),
            "unit": self.unit,
            "fixed": bool(self.fixed),
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> Parameter:
        """Return the parameter written by :meth:`to_dict` (``None`` becomes ``nan``).

        Parameters
        ----------
        data : mapping
            ``{"value", "stderr", "unit", "fixed"}``.

        Returns
        -------
        Parameter
            The parameter.

        Raises
        ------
        ValueError
            If ``data`` is not an object, a value or standard error is not a number or null,
            the value is ``NaN`` or infinite, or the standard error infinite (``1e999``
            reads as infinity; :meth:`to_dict` writes a missing number as null, and a
            ``NaN`` standard error is read as missing).
        """
        if not isinstance(data, Mapping):  # issue 28: a hand-edited result ended in exit 70
            raise ValueError("a parameter must be an object {value, stderr, unit}; got a "
                             f"{type(data).__name__}")

        def number(v: Any, what: str) -> float:
            if v is None:
                return math.nan
            if isinstance(v, bool) or not isinstance(v, numbers.Real):
                raise ValueError(f"a parameter's value and stderr must be numbers or null; "
                                 f"got {v!r}")
            problem = non_finite_problem(what, float(v))
            if problem:  # issue 28: NaN or 1e999 (inf) reported as an estimate
                raise ValueError(problem)
            return float(v)

        return cls(number(data.get("value"), "value"), number(data.get("stderr"), "stderr"),
                   str(data.get("unit", "-")), bool(data.get("fixed", False)))


@dataclass(frozen=True, repr=False)
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

    def to_dict(self, series: bool = False, command: Sequence[str] | None = None
                ) -> dict[str, Any]:
        """Return the estimate in the result schema ``driveid-result/1`` (JSON-ready).

        Parameters
        ----------
        series : bool
            Include long arrays of ``data_used`` (time series, peak lists); otherwise only
            scalars and arrays of at most 16 values are kept.
        command : sequence of str, optional
            The command line that produced the estimate (``sys.argv``); ``null`` if None.

        Returns
        -------
        dict
            Keys ``driveid``, ``schema``, ``command``, ``inputs``, ``method``,
            ``parameters``, ``covariance``, ``diagnostics``, ``warnings``, ``data_used``.
        """
        from driveid import __version__

        covariance = None
        if self.covariance is not None:
            covariance = {"names": list(self.covariance["names"]),
                          "matrix": to_jsonable(self.covariance["matrix"])}
        data_used = {k: v for k, v in self.data_used.items() if series or _is_short(v)}
        return {
            "driveid": __version__,
            "schema": SCHEMA,
            "command": None if command is None else [str(a) for a in command],
            "inputs": to_jsonable([dict(i) for i in self.inputs]),
            "method": self.method,
            "parameters": {name: par.to_dict() for name, par in self.params.items()},
            "covariance": covariance,
            "diagnostics": to_jsonable(dict(self.diagnostics)),
            "warnings": list(self.warnings),
            "data_used": to_jsonable(data_used),
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> Estimate:
        """Return the estimate written by :meth:`to_dict` (a round trip up to JSON types).

        Parameters
        ----------
        data : mapping
            A ``driveid-result/1`` dict (e.g. ``json.load`` of a ``--json`` output).

        Returns
        -------
        Estimate
            Parameters, covariance (matrix as ndarray), inputs, diagnostics, warnings and
            the ``data_used`` that was written.

        Raises
        ------
        ValueError
            If ``data`` is not of schema ``driveid-result/1``, or a parameter's value or
            standard error is not a finite number or null.
        """
        import numpy as np

        if not isinstance(data, Mapping):
            raise ValueError(f"a result must be a JSON object; got a {type(data).__name__}")
        schema = data.get("schema")
        if schema != SCHEMA:
            raise ValueError(
                f"not a driveid result of schema {SCHEMA!r}: got schema {schema!r}; read a "
                "file written by --json of this driveid version")
        # issue 28: a list where an object belongs ended in an AttributeError (exit 70)
        if not isinstance(data.get("method"), str):
            raise ValueError(f"'method' must be a string; got {data.get('method')!r}")
        if not isinstance(data.get("parameters"), Mapping):
            raise ValueError("'parameters' must be an object {name: {value, stderr, unit}}; "
                             f"got a {type(data.get('parameters')).__name__}")
        for key in ("data_used", "diagnostics", "covariance"):
            if data.get(key) is not None and not isinstance(data[key], Mapping):
                raise ValueError(f"{key!r} must be an object; got a {type(data[key]).__name__}")
        for key in ("warnings", "inputs"):
            if data.get(key) is not None and not isinstance(data[key], list):
                raise ValueError(f"{key!r} must be a list; got a {type(data[key]).__name__}")
        if any(not isinstance(i, Mapping) for i in data.get("inputs") or ()):
            raise ValueError("every entry of 'inputs' must be an object")
        covariance = data.get("covariance")
        if covariance is not None:
            covariance = {"names": list(covariance["names"]),
                          "matrix": np.array(covariance["matrix"], dtype=float)}
        return cls(
            method=str(data["method"]),
            params={k: _parameter(k, v) for k, v in data["parameters"].items()},
            data_used=dict(data.get("data_used") or {}),
            diagnostics=dict(data.get("diagnostics") or {}),
            warnings=tuple(data.get("warnings") or ()),
            covariance=covariance,
            inputs=tuple(dict(i) for i in data.get("inputs") or ()),
        )

    def to_json(self, series: bool = False, command: Sequence[str] | None = None,
                **kwargs: Any) -> str:
        """Serialise :meth:`to_dict` to a JSON string.

        Parameters
        ----------
        series : bool
            Include long arrays (see :meth:`to_dict`).
        command : sequence of str, optional
            The command line, kept as ``"command"``.
        **kwargs
            Passed to :func:`json.dumps` (e.g. ``indent=2``).

        Returns
        -------
        str
            Standard JSON (NaN written as ``null``).
        """
        return json.dumps(self.to_dict(series=series, command=command), **kwargs)

    def with_inputs(self, records: Sequence[Any]) -> Estimate:
        """Return a copy whose ``inputs`` describe ``records`` (from their ``meta``).

        Parameters
        ----------
        records : sequence of Record
            The records the estimate was computed from, in order.

        Returns
        -------
        Estimate
            The same estimate with provenance filled in.
        """
        return dataclasses.replace(self, inputs=tuple(inputs_of(records)))

    def with_warnings(self, *messages: str) -> Estimate:
        """Return a copy with ``messages`` appended to the warnings (duplicates dropped).

        Parameters
        ----------
        *messages : str
            Reasons to trust the estimate less.

        Returns
        -------
        Estimate
            The same estimate with more warnings.
        """
        new = tuple(m for m in dict.fromkeys(messages) if m not in self.warnings)
        return dataclasses.replace(self, warnings=self.warnings + new) if new else self

    def table(self) -> str:
        """Return a plain-text table: name, value ± standard error, unit."""
        rows = [("parameter", "value", "std. error", "unit")]
        for name, par in self.params.items():
            error = "(given)" if par.fixed else f"{par.stderr:.3g}"
            rows.append((name, f"{par.value:.6g}", error, par.unit))
        widths = [max(len(r[i]) for r in rows) for i in range(4)]
        lines = [
            "  ".join(cell.ljust(w) for cell, w in zip(row, widths, strict=True)) for row in rows
        ]
        lines.insert(1, "  ".join("-" * w for w in widths))
        return "\n".join(lines)


    def __repr__(self) -> str:
        """Short and readable: method, parameters with standard errors, warning count."""
        lines = [f"<Estimate {self.method}: {len(self.params)} parameters, "
                 f"{len(self.warnings)} warning(s)>"]
        lines += ["  " + line for line in self.table().splitlines()]
        return "\n".join(lines)

    def _repr_html_(self) -> str:
        """HTML table for notebooks: value, standard error, 95 % interval, unit."""
        from html import escape

        rows = []
        for name, par in self.params.items():
            if par.fixed:
                err, interval = "fixed (given)", ""
            else:
                low, high = self.interval(name)
                err = f"{par.stderr:.3g}"
                digits = _digits(par.value, par.stderr)
                interval = (f"[{low:.{digits}g}, {high:.{digits}g}]" if math.isfinite(low)
                            else "")
            rows.append(f"<tr><td>{escape(name)}</td><td>{par.value:.6g}</td>"
                        f"<td>{escape(err)}</td><td>{escape(interval)}</td>"
                        f"<td>{escape(par.unit)}</td></tr>")
        warn = "".join(f"<li>{escape(w)}</li>" for w in self.warnings)
        return (f"<div><strong>{escape(self.method)}</strong>"
                "<table><thead><tr><th>parameter</th><th>value</th><th>std. error</th>"
                "<th>95 % interval</th><th>unit</th></tr></thead><tbody>"
                + "".join(rows) + "</tbody></table>"
                + (f"<p>warnings:</p><ul>{warn}</ul>" if warn else "") + "</div>")

    def interval(self, name: str, level: float = 0.95) -> tuple[float, float]:
        """Return the two-sided normal confidence interval of a parameter [its unit].

        Parameters
        ----------
        name : str
            Parameter name.
        level : float
            Coverage in (0, 1), e.g. 0.95.

        Returns
        -------
        tuple of float
            ``(value - z·stderr, value + z·stderr)``; ``(nan, nan)`` for a fixed parameter or
            one without a standard error.

        Raises
        ------
        ParameterError
            If ``level`` is not in (0, 1).

        Examples
        --------
        >>> est = Estimate("demo", {"K": Parameter(16.0, 0.5, "N·m/rad")})
        >>> [round(v, 3) for v in est.interval("K")]
        [15.02, 16.98]
        """
        from statistics import NormalDist

        from driveid.errors import ParameterError

        if not 0.0 < level < 1.0:
            raise ParameterError(f"level must lie in (0, 1), e.g. 0.95; got {level}")
        par = self[name]
        if par.fixed or not math.isfinite(par.stderr):
            return (math.nan, math.nan)
        z = NormalDist().inv_cdf(0.5 + level / 2.0)
        return (par.value - z * par.stderr, par.value + z * par.stderr)

    def to_pandas(self) -> Any:
        """Return the parameters as a DataFrame (one row each: value, stderr, unit, fixed).

        Returns
        -------
        pandas.DataFrame
            Indexed by parameter name; ``attrs`` holds the rest of :meth:`to_dict`
            (method, inputs, covariance, diagnostics, warnings), so
            :meth:`from_pandas` round-trips it.
        """
        import pandas as pd

        data = self.to_dict()
        frame = pd.DataFrame.from_dict(data.pop("parameters"), orient="index")
        frame.index.name = "parameter"
        frame.attrs.update(data)
        return frame

    @classmethod
    def from_pandas(cls, frame: Any) -> Estimate:
        """Rebuild an estimate from :meth:`to_pandas` (inverse of it).

        Parameters
        ----------
        frame : pandas.DataFrame
            As returned by :meth:`to_pandas`.

        Returns
        -------
        Estimate
            The same parameters, method, covariance, diagnostics, warnings and inputs.
        """
        params = {}
        for name, row in frame.iterrows():
            params[str(name)] = {k: (None if _is_missing(v) else v) for k, v in row.items()}
        return cls.from_dict({**frame.attrs, "parameters": params})


def non_finite_problem(what: str, number: float) -> str | None:
    """Return why a parameter's number read from a result file is refused, or None.

    Parameters
    ----------
    what : {"value", "stderr"}
        Which number of the parameter.
    number : float
        The number as read (JSON ``NaN`` is nan, ``1e999`` and ``Infinity`` are inf).

    Returns
    -------
    str or None
        The reason for a ``NaN`` or infinite value or an infinite standard error; None
        for a finite number or a ``NaN`` standard error (missing, as null).
    """
    if math.isfinite(number) or (what == "stderr" and math.isnan(number)):
        return None
    return (f"a parameter's {'standard error' if what == 'stderr' else 'value'} must be a "
            f"finite number or null (driveid writes a missing number as null); got {number!r}")


def _parameter(name: str, data: Any) -> Parameter:
    """:meth:`Parameter.from_dict`, its refusal naming the parameter."""
    try:
        return Parameter.from_dict(data)
    except ValueError as exc:
        raise ValueError(f"parameter {name!r}: {exc}") from None


def _digits(value: float, stderr: float) -> int:
    """Significant digits that keep an interval's two bounds apart (two beyond the error)."""
    if not (math.isfinite(stderr) and stderr > 0 and value != 0):
        return 6
    return max(3, min(15, int(math.floor(math.log10(abs(value) / stderr))) + 3))


def _is_missing(value: Any) -> bool:
    try:
        return bool(value != value) or value is None
    except (TypeError, ValueError):
        return False


def inputs_of(records: Sequence[Any]) -> list[dict[str, Any]]:
    """Return the provenance entries of records for :attr:`Estimate.inputs`.

    Parameters
    ----------
    records : sequence of Record
        Records read by :func:`driveid.io.read_record` (or made in memory: path ``None``).

    Returns
    -------
    list of dict
        One ``{"path", "sha256", "rows", "columns", "window", "units", "units_in_file"}``
        per record (and ``reading``, the reading options that differ from the defaults, and
        ``notes``, the choices the reading made: a column by convention, a unit assumed);
        ``columns`` maps record column -> file column, ``window`` is the time span used
        [s], ``units`` the SI units after conversion.
    """
    out = []
    for record in records:
        meta = dict(record.meta)
        window = [float(record.t[0]), float(record.t[-1])]  # the span used, after any crop
        out.append({
            "path": meta.get("source"),
            "sha256": meta.get("sha256"),
            "rows": meta.get("rows", record.n),
            "columns": dict(meta.get("columns_used") or {c: c for c in record.columns}),
            "window": [float(w) for w in window],
            "units": {c: record.units[c] for c in record.columns if c in record.units},
            "units_in_file": dict(meta.get("units_in_file") or {}),
        })
        if meta.get("reading"):  # the reading options, so validate/report read it alike
            out[-1]["reading"] = dict(meta["reading"])
        if meta.get("notes"):  # columns chosen by convention, units assumed
            out[-1]["notes"] = list(meta["notes"])
    return out


def _is_short(value: Any) -> bool:
    return _n_values(value) <= _SHORT


def _n_values(value: Any) -> int:
    if isinstance(value, Mapping):
        return sum(_n_values(v) for v in value.values())
    if isinstance(value, (list, tuple)):
        return sum(_n_values(v) for v in value)
    size = getattr(value, "size", None)
    return int(size) if isinstance(size, (int,)) or hasattr(value, "shape") else 1


def _finite_or_none(value: float) -> float | None:
    value = float(value)
    return value if math.isfinite(value) else None
