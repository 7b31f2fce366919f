r"""Subsystem separation: sections A, A+B, A+B+C fitted in sequence, parts as differences.

The thesis identifies its test bed in three sections (§4.1, §5.1, Table 5.2): body A alone,
A with B attached, then A+B+C, each as one lumped body under the delayed PD loop, and obtains
the inertia, viscous and kinetic friction (and stiffness) of B and C as differences of
successive section estimates. Here each section is fitted by :func:`driveid.identify.
drive_fit.estimate_drive` (whole-record output error, growing horizon) and each part is

.. math:: p_{B} = p_{A+B} - p_{A}, \qquad \operatorname{Var} p_B = \operatorname{Var}
   p_{A+B} + \operatorname{Var} p_A

(the sections are separate experiments, so their errors are independent).

Manifest (TOML; files relative to it)::

    [[section]]
    name = "A"                  # part added by this section
    config = "a.toml"           # the section's drive (one body; start values)
    files = ["a1.csv", "a2.csv"]
    estimate = ["body1.J", "body1.c_mean", "body1.fk_mean"]   # optional (this default)
    [section.published]         # optional: published cumulative values, shown beside
    J = 0.0115355

References
----------
.. [1] J. A. de Marchi, "Modeling of dynamic friction, impact backlash and elastic
       compliance nonlinearities in machine tools", PhD thesis, RPI, 1998, §4.1, §5.1,
       Table 5.2.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from driveid.errors import ConfigError
from driveid.identify.core.estimate import Estimate, Parameter

__all__ = ["estimate_subsystems", "subsystem_differences"]

_QUANTITIES = ("J", "c_mean", "fk_mean", "K")
_DEFAULT = ["body1.J", "body1.c_mean", "body1.fk_mean"]
_SECTION_KEYS = {"name", "config", "files", "estimate", "published"}


def subsystem_differences(sections: list[tuple[str, Estimate]]) -> Estimate:
    """Each part's parameters as the difference of successive section estimates.

    Parameters
    ----------
    sections : list of (str, Estimate)
        Part name added by each section (``"A"``, ``"B"``, ``"C"``) and the section's
        one-body estimate (parameters ``body1.J`` [kg·m²], ``body1.c_mean`` [N·m·s/rad],
        ``body1.fk_mean`` [N·m], ``body1.K`` [N·m/rad]), in order of assembly.

    Returns
    -------
    Estimate
        Method ``"subsystems"``: ``A+B.J`` (cumulative section values) and ``B.J`` (parts)
        with standard errors ``sqrt(se_k² + se_{k-1}²)`` (independent experiments).

    Examples
    --------
    >>> a = Estimate("x", {"body1.J": Parameter(1.0, 0.01, "kg·m²")})
    >>> ab = Estimate("x", {"body1.J": Parameter(1.5, 0.02, "kg·m²")})
    >>> d = subsystem_differences([("A", a), ("B", ab)])
    >>> round(d.value("B.J"), 3), round(d.stderr("B.J"), 4)
    (0.5, 0.0224)
    """
    params: dict[str, Parameter] = {}
    label = ""
    previous: Estimate | None = None
    for name, est in sections:
        label = name if not label else f"{label}+{name}"
        for q in _QUANTITIES:
            key = f"body1.{q}"
            if key not in est:
                continue
            cur = est[key]
            params[f"{label}.{q}"] = cur
            if previous is None:
                params[f"{name}.{q}"] = cur
            elif key in previous:
                prev = previous[key]
                if cur.fixed and prev.fixed:
                    se, fixed = math.nan, True
                else:
                    se = math.sqrt(np.nansum([0.0 if cur.fixed else cur.stderr ** 2,
                                              0.0 if prev.fixed else prev.stderr ** 2]))
                    fixed = False
                params[f"{name}.{q}"] = Parameter(cur.value - prev.value, se, cur.unit,
                                                  fixed=fixed)
        previous = est
    return Estimate(method="subsystems", params=params)


def estimate_subsystems(manifest: str | Path) -> Estimate:
    """Fit the sections of a subsystem manifest in sequence and separate the parts.

    Parameters
    ----------
    manifest : str or Path
        TOML manifest (see the module docstring): ``[[section]]`` tables with ``name``,
        ``config``, ``files``, optional ``estimate`` and ``published``.

    Returns
    -------
    Estimate
        Method ``"subsystems"``: cumulative section values (``A+B.J`` …) and parts
        (``B.J`` …) with standard errors; ``diagnostics["table"]`` a plain-text table like
        Table 5.2 (published beside identified where given), ``diagnostics["sections"]``
        each section's full result.

    Raises
    ------
    ConfigError
        If the manifest cannot be read, a key is unknown or a section lacks its files.
    """
    from driveid.identify.drive.drive_fit import estimate_drive
    from driveid.identify.drive.records import read_drive_record
    from driveid.sim.config import load_drive_config, read_toml

    path = Path(manifest)
    doc = read_toml(path, "manifest")
    tables = doc.get("section")
    if not isinstance(tables, list) or len(tables) < 2:
        raise ConfigError(f"{path.name}: needs two or more [[section]] tables (A, then A+B "
                          f"...); got {0 if not isinstance(tables, list) else len(tables)}")
    sections, published, results = [], [], {}
    for i, table in enumerate(tables):  # every section checked before the first fit
        _check_section(table, f"{path.name}: section[{i + 1}]")
    names = [str(t["name"]) for t in tables]
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:  # a part is named after its section: a second "A" overwrote the first
        raise ConfigError(f"{path.name}: section names must differ (each part is named after "
                          f"its section); {twice} appear more than once")
    for table in tables:
        files = table["files"]
        params, run = load_drive_config(path.parent / table["config"])
        records = [read_drive_record(path.parent / f, read_kwargs={"max_jitter": None},
                                     n_bodies=params.n_bodies) for f in files]
        est = estimate_drive(records, params, estimate=_names(table.get("estimate", _DEFAULT)),
                             x0=run.x0, v0=run.v0, torque=run.torque, units=run.units)
        sections.append((str(table["name"]), est))
        published.append(dict(table.get("published", {})))
        results[str(table["name"])] = est.to_dict()
    out = subsystem_differences(sections)
    warnings = [f"{name}: {w}" for name, est in sections for w in est.warnings]
    table = _table(sections, published, out)
    return Estimate(method="subsystems", params=out.params, warnings=tuple(warnings),
                    diagnostics={"table": table, "sections": results})


def _names(estimate) -> list[str]:
    """Return a section's ``estimate``: a list of names, or one comma-separated string."""
    if isinstance(estimate, str):  # read one character at a time before
        return [n.strip() for n in estimate.split(",") if n.strip()]
    return list(estimate)


def _check_section(table, where: str) -> None:
    """Refuse a malformed [[section]] in one line, before any fit runs."""
    if not isinstance(table, dict):
        raise ConfigError(f"{where}: must be a [[section]] table; got {table!r}")
    unknown = sorted(set(table) - _SECTION_KEYS)
    if unknown:
        raise ConfigError(f"{where}: unknown key(s) {unknown}; allowed {sorted(_SECTION_KEYS)}")
    missing = [k for k in ("name", "config", "files") if k not in table]
    if missing:
        raise ConfigError(f"{where}: missing {missing}; add them")
    files = table["files"]
    if not isinstance(files, list) or not files:
        raise ConfigError(f"{where}.files: must be a non-empty list of files; got {files!r}")
    estimate = table.get("estimate", [])
    if not isinstance(estimate, (str, list)) or (isinstance(estimate, list) and not all(
            isinstance(n, str) for n in estimate)):
        raise ConfigError(f"{where}.estimate: must be a list of parameter names (e.g. "
                          f"[\"body1.J\", \"body1.c_mean\"]); got {estimate!r}")
    pub = table.get("published", {})
    if not isinstance(pub, dict):
        raise ConfigError(f"{where}.published: must be a table of {list(_QUANTITIES)}; got "
                          f"{pub!r}")
    for key, value in pub.items():
        if key not in _QUANTITIES:
            raise ConfigError(f"{where}.published: unknown quantity {key!r}; give some of "
                              f"{list(_QUANTITIES)} (cumulative values, SI units)")
        if isinstance(value, bool) or not isinstance(value, (int, float)) \
                or not math.isfinite(float(value)):
            raise ConfigError(f"{where}.published.{key}: must be a finite number; got "
                              f"{value!r}")


def _table(sections, published, out: Estimate) -> str:
    rows = [("section", "quantity", "identified", "std. error", "published", "part",
             "part value", "part s.e.")]
    label = ""
    for (name, _), pub in zip(sections, published, strict=True):
        label = name if not label else f"{label}+{name}"
        for q in _QUANTITIES:
            key = f"{label}.{q}"
            if key not in out:
                continue
            p, part = out[key], out[f"{name}.{q}"]
            ref = pub.get(q)
            rows.append((label, q, f"{p.value:.6g}",
                         "(given)" if p.fixed else f"{p.stderr:.2g}",
                         "" if ref is None else f"{ref:.6g}", name, f"{part.value:.6g}",
                         "(given)" if part.fixed else f"{part.stderr:.2g}"))
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    lines = ["  ".join(c.ljust(w) for c, w in zip(r, widths, strict=True)) for r in rows]
    lines.insert(1, "  ".join("-" * w for w in widths))
    return "\n".join(lines)
