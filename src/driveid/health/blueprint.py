"""Blueprint of a machine type: nominal value, tolerance band and correlations per parameter.

Made from catalogued identifications of healthy axes of one type (de Marchi 1998, §6.1:
"a methodology for machine tool classification", "monitor the general health"). For each
parameter it holds

* ``nominal`` — the median over axes of each axis's mean;
* ``spread`` — the standard deviation of single healthy identifications about ``nominal``
  (axis-to-axis manufacturing spread and month-to-month scatter together);
* ``repeatability`` — the pooled within-axis standard deviation (how much one healthy axis
  scatters from one measurement to the next, measurement noise included);
* ``se_ref`` — the median standard error of those identifications, the measurement noise
  already inside ``spread`` and ``repeatability`` (:mod:`driveid.health.drift` adds only a
  new measurement's *excess* variance over it);
* ``band`` — ``nominal ± 3·spread``, for people; and the between-axis correlation matrix.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from driveid._json import to_jsonable
from driveid.errors import ConfigError, FileFormatError, ParameterError
from driveid.io.consistency import load_json

__all__ = ["BLUEPRINT_SCHEMA", "PHYSICAL_PARAMETERS", "Blueprint", "BlueprintParameter",
           "make_blueprint", "read_blueprint", "write_blueprint"]

BLUEPRINT_SCHEMA = "driveid-blueprint/1"
#: Monitored by default when present: the physical parameters (the derived ω0, ζ and
#: θk = fk/K repeat them, and testing them too would only spend false-alarm budget).
PHYSICAL_PARAMETERS = ("J", "K", "c_mean", "c_delta", "fk_mean", "fk_delta", "fs_mean",
                       "fs_delta", "gap_plus", "gap_minus", "M", "Fv", "Fc")


@dataclass(frozen=True)
class BlueprintParameter:
    """Healthy statistics of one parameter of a machine type.

    Attributes
    ----------
    nominal : float
        Median over axes of the axis means [unit].
    spread : float
        Standard deviation of single healthy identifications about ``nominal`` [unit].
    repeatability : float
        Pooled within-axis standard deviation [unit]; nan with one entry per axis.
    se_ref : float
        Median standard error of the healthy identifications [unit].
    unit : str
        SI unit.
    n_axes, n_entries : int
        Axes and identifications it was made from.
    """

    nominal: float
    spread: float
    repeatability: float
    se_ref: float
    unit: str
    n_axes: int
    n_entries: int

    @property
    def band(self) -> tuple[float, float]:
        """Tolerance band ``nominal ± 3·spread`` [unit]."""
        return (self.nominal - 3 * self.spread, self.nominal + 3 * self.spread)


@dataclass(frozen=True)
class Blueprint:
    """What a healthy axis of one machine type looks like.

    Attributes
    ----------
    machine_type : str
        The type.
    parameters : mapping of str to BlueprintParameter
        Per-parameter statistics.
    monitored : tuple of str
        Parameters the health check tests.
    correlation : mapping
        ``{"names": [...], "matrix": ndarray}``, between-axis correlation of axis means.
    source : mapping
        How it was made (catalogue, selection rule, counts).
    """

    machine_type: str
    parameters: Mapping[str, BlueprintParameter]
    monitored: tuple[str, ...]
    correlation: Mapping[str, Any] = field(default_factory=dict)
    source: Mapping[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        """Return the JSON-ready blueprint (schema ``driveid-blueprint/1``)."""
        return to_jsonable({
            "schema": BLUEPRINT_SCHEMA, "machine_type": self.machine_type,
            "monitored": list(self.monitored),
            "parameters": {n: {"nominal": p.nominal, "spread": p.spread,
                               "repeatability": p.repeatability, "se_ref": p.se_ref,
                               "unit": p.unit, "band": list(p.band), "n_axes": p.n_axes,
                               "n_entries": p.n_entries}
                           for n, p in self.parameters.items()},
            "correlation": dict(self.correlation), "source": dict(self.source)})


def make_blueprint(entries: Sequence[Any], *, machine_type: str, first: int | None = 3,
                   parameters: Sequence[str] | None = None, min_axes: int = 5,
                   source: Mapping[str, Any] | None = None) -> Blueprint:
    """Make a blueprint from healthy identifications of one machine type.

    Parameters
    ----------
    entries : sequence of CatalogEntry
        Identifications (failures are ignored), e.g. ``Catalog.entries(machine_type=T)``.
    machine_type : str
        The type they belong to.
    first : int or None
        Use only each axis's first ``first`` successful identifications (commissioning,
        assumed healthy); ``None`` uses all given.
    parameters : sequence of str, optional
        Parameters to monitor; default the physical ones present and estimated
        (:data:`PHYSICAL_PARAMETERS`, not fixed), else every estimated one.
    min_axes : int
        Fewest axes for a blueprint (a spread from fewer axes is not a spread).
    source : mapping, optional
        Provenance stored in the blueprint.

    Returns
    -------
    Blueprint
        Nominal, spread, repeatability, reference standard error and correlations.

    Raises
    ------
    ConfigError
        If fewer than ``min_axes`` axes have successful identifications, or a named
        parameter is absent.
    ParameterError
        If ``min_axes`` < 2 or ``first`` < 1.
    """
    # issue 28: min_axes 0 ended in a StopIteration (exit 70); first -1 dropped the last entry
    if isinstance(min_axes, bool) or not isinstance(min_axes, int) or min_axes < 2:
        raise ParameterError(f"min_axes must be an integer >= 2 (a spread needs two axes or "
                             f"more; CLI --min-axes); got {min_axes!r}")
    if first is not None and (isinstance(first, bool) or not isinstance(first, int)
                              or first < 1):
        raise ParameterError(f"first must be an integer >= 1, or None for every entry (CLI "
                             f"--first N, 0 for all); got {first!r}")
    by_axis: dict[tuple[str, str], list[Any]] = {}
    for e in sorted((e for e in entries if e.status == "ok"), key=lambda e: e.measured_at):
        by_axis.setdefault((e.machine, e.axis), []).append(e)
    if first is not None:
        by_axis = {k: v[:first] for k, v in by_axis.items()}
    if len(by_axis) < min_axes:
        raise ConfigError(
            f"a blueprint of {machine_type!r} needs healthy identifications of at least "
            f"{min_axes} axes; got {len(by_axis)}: add more (driveid catalog add/fleet) or "
            "check --machine-type")
    estimated = _estimated_names(by_axis)
    if parameters is None:
        monitored = tuple(n for n in PHYSICAL_PARAMETERS if n in estimated) or tuple(estimated)
    else:
        missing = [n for n in parameters if n not in estimated]
        if missing:
            raise ConfigError(f"parameters {missing} are not estimated in every entry; "
                              f"choose from {sorted(estimated)}")
        monitored = tuple(parameters)
    stats: dict[str, BlueprintParameter] = {}
    axis_means: dict[str, list[float]] = {}
    for name in estimated:
        values, errors, means, resid = [], [], [], []
        unit = "-"
        for rows in by_axis.values():
            v = np.array([e.parameters[name].value for e in rows], float)
            values.extend(v)
            errors.extend(e.parameters[name].stderr for e in rows)
            unit = rows[0].parameters[name].unit
            means.append(float(np.mean(v)))
            if v.size > 1:
                resid.extend(v - v.mean())
        axis_means[name] = means
        nominal = float(np.median(means))
        spread = float(np.sqrt(np.mean((np.array(values) - nominal) ** 2)))
        dof = len(resid) - sum(1 for r in by_axis.values() if len(r) > 1)
        repeat = float(np.sqrt(np.sum(np.square(resid)) / dof)) if dof > 0 else math.nan
        finite = [s for s in errors if math.isfinite(s)]
        stats[name] = BlueprintParameter(
            nominal=nominal, spread=spread, repeatability=repeat,
            se_ref=float(np.median(finite)) if finite else math.nan, unit=unit,
            n_axes=len(by_axis), n_entries=len(values))
    names = list(monitored)
    matrix = np.corrcoef(np.array([axis_means[n] for n in names])) if len(names) > 1 \
        else np.ones((1, 1))
    return Blueprint(
        machine_type=machine_type, parameters=stats, monitored=monitored,
        correlation={"names": names, "matrix": np.atleast_2d(matrix)},
        source={"first": first, "n_axes": len(by_axis),
                "n_entries": sum(len(v) for v in by_axis.values()), **dict(source or {})})


def _estimated_names(by_axis: Mapping[Any, list[Any]]) -> list[str]:
    common: set[str] | None = None
    for rows in by_axis.values():
        for e in rows:
            names = {n for n, p in e.parameters.items()
                     if not p.fixed and math.isfinite(p.value)
                     and not (p.stderr == 0.0)}  # stderr 0: a given value (older results)
            common = names if common is None else common & names
    order = list(next(iter(by_axis.values()))[0].parameters)
    return [n for n in order if n in (common or set())]


def write_blueprint(blueprint: Blueprint, path: str | Path, *, overwrite: bool = False) -> Path:
    """Write a blueprint as JSON.

    Parameters
    ----------
    blueprint : Blueprint
        The blueprint.
    path : str or Path
        Destination ``.json`` file.
    overwrite : bool
        Replace an existing file.

    Returns
    -------
    Path
        The file written.
    """
    from driveid.io.safe_write import atomic_write_text

    return atomic_write_text(path, json.dumps(blueprint.to_dict(), indent=2),
                             overwrite=overwrite)


def read_blueprint(path: str | Path) -> Blueprint:
    """Read a blueprint written by :func:`write_blueprint`.

    Parameters
    ----------
    path : str or Path
        The JSON file.

    Returns
    -------
    Blueprint
        The blueprint.

    Raises
    ------
    FileFormatError
        If the file is not a ``driveid-blueprint/1`` JSON.
    """
    path = Path(path)
    try:  # nesting thousands deep was a RecursionError (exit 70)
        data = load_json(path.read_bytes(), str(path), constants=True)
    except FileFormatError as exc:
        raise FileFormatError(f"{exc}; pass a blueprint written by 'driveid blueprint "
                              "make'") from None
    if not isinstance(data, dict) or data.get("schema") != BLUEPRINT_SCHEMA:
        raise FileFormatError(
            f"{path} is not a blueprint (schema {BLUEPRINT_SCHEMA}); make one with "
            "'driveid blueprint make'")
    try:  # an edited or foreign file: one line, not a TypeError deep in the health check
        return _blueprint_of(data)
    except (KeyError, TypeError, ValueError, AttributeError) as exc:
        what = f"missing {exc}" if isinstance(exc, KeyError) else str(exc)
        raise FileFormatError(
            f"{path} is not a usable blueprint ({what}); make it again with 'driveid "
            "blueprint make'") from None


def _number(p: Mapping, key: str, *, positive: bool = False, optional: bool = False) -> float:
    value = p.get(key) if optional else p[key]
    if optional and (value is None or (isinstance(value, float) and math.isnan(value))):
        return math.nan
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ValueError(f"'{key}' must be a number; got {value!r}")
    value = float(value)
    # the health check squares spreads and z-scores: keep them far from overflow
    if not (math.isfinite(value) and abs(value) < 1e150) or (positive and value <= 0):
        raise ValueError(f"'{key}' must be a finite number{' > 0' if positive else ''} of "
                         f"reasonable size; got {value!r}")
    return value


def _blueprint_of(data: dict) -> Blueprint:
    for key, kind in (("parameters", Mapping), ("monitored", list)):
        if not isinstance(data[key], kind):
            raise ValueError(f"'{key}' must be a JSON {'object' if kind is Mapping else 'list'}"
                             f"; got {type(data[key]).__name__}")
    params = {}
    for n, p in data["parameters"].items():
        if not isinstance(p, Mapping):
            raise ValueError(f"parameter '{n}' must be an object; got {p!r}")
        params[str(n)] = BlueprintParameter(
            nominal=_number(p, "nominal"), spread=_number(p, "spread", positive=True),
            repeatability=_number(p, "repeatability", optional=True),
            se_ref=_number(p, "se_ref", optional=True), unit=str(p.get("unit", "-")),
            n_axes=int(p.get("n_axes", 0)), n_entries=int(p.get("n_entries", 0)))
    monitored = tuple(str(n) for n in data["monitored"])
    if not monitored:
        raise ValueError("it monitors no parameter ('monitored' is empty)")
    unknown = [n for n in monitored if n not in params]
    if unknown:
        raise ValueError(f"'monitored' names {unknown}, which 'parameters' lacks")
    corr = data.get("correlation") or {}
    if corr and not isinstance(corr, Mapping):
        raise ValueError(f"'correlation' must be an object {{names, matrix}}; got "
                         f"{type(corr).__name__}")
    if corr:
        names = [str(n) for n in corr["names"]]
        matrix = np.array(corr["matrix"], float)
        if matrix.shape != (len(names), len(names)) or not np.all(np.isfinite(matrix)):
            raise ValueError(f"the correlation matrix must be {len(names)} x {len(names)} "
                             f"finite numbers; got shape {matrix.shape}")
        corr = {"names": names, "matrix": matrix}
    return Blueprint(machine_type=str(data["machine_type"]), parameters=params,
                     monitored=monitored, correlation=corr, source=data.get("source", {}))
