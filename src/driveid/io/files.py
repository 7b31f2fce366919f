"""Read and write :class:`Record` files: CSV (with units in the header), NPZ and MATLAB .mat.

CSV layout written by driveid::

    # driveid record
    # meta: {"plant": "testbed-a", "P": 1.5, ...}
    t [s],x [rad],u [N·m]
    0.0,0.1,0.0
    ...

Readers also accept a plain header ``t,x`` or ``t,x,u`` (units then default to
:data:`driveid.io.record.DEFAULT_UNITS`), units in brackets or parentheses (``t (s)``), and
the column aliases ``time``, ``position``/``pos``, ``force``/``torque``, ``velocity``/``vel``.
Units in a header are converted to SI at reading (``t [ms]``, ``x [deg]``, ``v [rpm]``,
``u [mN·m]`` ...; see :data:`UNIT_CONVERSIONS`); an unknown unit is an error, never ignored.
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from driveid._json import to_jsonable
from driveid.errors import FileFormatError, OverwriteError
from driveid.io.record import Record

__all__ = ["read_record", "write_record", "ensure_writable", "SUFFIXES", "UNIT_CONVERSIONS"]

#: File suffixes understood by :func:`read_record` and :func:`write_record`.
SUFFIXES = (".csv", ".npz", ".mat")

_ALIASES = {
    "t": "t", "time": "t",
    "x": "x", "position": "x", "pos": "x", "theta": "x", "q": "x",
    "u": "u", "force": "u", "torque": "u", "tau": "u", "f": "u",
    "v": "v", "velocity": "v", "vel": "v", "omega": "v",
}
_HEADER = re.compile(r"^\s*([A-Za-z_][\w]*)\s*(?:[\[(]\s*([^\])]*?)\s*[\])])?\s*$")


def ensure_writable(path: str | Path, *, overwrite: bool = False) -> Path:
    """Return ``path`` as a Path after checking that writing it loses nothing.

    Parameters
    ----------
    path : str or Path
        Destination file.
    overwrite : bool
        Allow replacing an existing file.

    Returns
    -------
    Path
        The destination, with its parent folder created.

    Raises
    ------
    OverwriteError
        If the file exists and ``overwrite`` is False.
    """
    path = Path(path)
    if path.exists() and not overwrite:
        raise OverwriteError(
            f"{path} exists; choose another name, or pass overwrite=True (CLI: --force) to "
            "replace it"
        )
    path.parent.mkdir(parents=True, exist_ok=True)
    return path


def write_record(record: Record, path: str | Path, *, overwrite: bool = False) -> Path:
    """Write a record as CSV, NPZ or MATLAB .mat, chosen by the file suffix.

    Parameters
    ----------
    record : Record
        The record to save.
    path : str or Path
        Destination; suffix ``.csv``, ``.npz`` or ``.mat``.
    overwrite : bool
        Replace an existing file (default: refuse).

    Returns
    -------
    Path
        The written file.

    Raises
    ------
    OverwriteError
        If the file exists and ``overwrite`` is False.
    FileFormatError
        If the suffix is not one of :data:`SUFFIXES`.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in SUFFIXES:
        raise FileFormatError(
            f"cannot write {path.name}: unknown suffix {path.suffix!r}; use one of {SUFFIXES}"
        )
    ensure_writable(path, overwrite=overwrite)
    meta_json = json.dumps(to_jsonable(dict(record.meta)))
    columns = record.columns
    if suffix == ".csv":
        header = ",".join(f"{c} [{record.units.get(c, '')}]" for c in columns)
        data = np.column_stack([getattr(record, c) for c in columns])
        with open(path, "w", encoding="utf-8", newline="\n") as fh:
            fh.write("# driveid record\n")
            fh.write(f"# meta: {meta_json}\n")
            fh.write(header + "\n")
            np.savetxt(fh, data, delimiter=",", fmt="%.17g")
    elif suffix == ".npz":
        arrays = {c: getattr(record, c) for c in columns}
        with open(path, "wb") as fh:
            np.savez(fh, meta=np.array(meta_json), **arrays)
    else:
        from scipy.io import savemat

        arrays = {c: np.asarray(getattr(record, c)).reshape(-1, 1) for c in columns}
        savemat(path, {**arrays, "driveid_meta": meta_json})
    return path


def read_record(
    path: str | Path,
    *,
    columns: Mapping[str, str] | None = None,
    scale: Mapping[str, float | str] | None = None,
    units: Mapping[str, str] | None = None,
    max_jitter: float | None = 0.01,
) -> Record:
    """Read a record from CSV, NPZ or MATLAB .mat.

    Parameters
    ----------
    path : str or Path
        The file.
    columns : mapping, optional
        Record column -> name in the file, e.g. ``{"x": "qm", "u": "vir"}`` for the EMPS
        benchmark. Columns not named are looked up by their own name and aliases.
    scale : mapping, optional
        Record column -> factor applied after reading: a number, or the name of a scalar
        variable in the file (EMPS: ``{"u": "gtau"}``, force = gtau·vir).
    units : mapping, optional
        Record column -> unit string, overriding units read from the file.
    max_jitter : float or None
        Passed to :class:`Record`.

    Returns
    -------
    Record
        The validated record; ``meta["source"]`` names the file.

    Raises
    ------
    FileNotFoundError
        If the file does not exist.
    FileFormatError
        If the file cannot be parsed or lacks time or position.
    RecordError
        If the data break a rule of :class:`Record`.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"no such record file: {path}")
    suffix = path.suffix.lower()
    if suffix == ".csv" or suffix == ".txt":
        data, file_units, meta = _read_csv(path)
    elif suffix == ".npz":
        data, file_units, meta = _read_npz(path)
    elif suffix == ".mat":
        data, file_units, meta = _read_mat(path)
    else:
        raise FileFormatError(
            f"cannot read {path.name}: unknown suffix {path.suffix!r}; use one of {SUFFIXES}"
        )
    picked: dict[str, np.ndarray] = {}
    mapping = dict(columns or {})
    unknown = set(mapping) - {"t", "x", "u", "v"}
    if unknown:
        raise FileFormatError(
            f"columns mapping has unknown record column(s) {sorted(unknown)}; "
            "map only t, x, u, v"
        )
    by_alias = {_ALIASES.get(name.lower(), name): name for name in data}
    for col in ("t", "x", "u", "v"):
        name = mapping.get(col, by_alias.get(col))
        if name is None:
            continue
        if name not in data:
            raise FileFormatError(
                f"{path.name} has no variable {name!r} for column {col!r}; it has "
                f"{sorted(data)}"
            )
        picked[col] = np.asarray(data[name], dtype=float).ravel()
        if name in file_units:
            file_units.setdefault(col, file_units[name])
    for col in ("t", "x"):
        if col not in picked:
            raise FileFormatError(
                f"{path.name} has no {'time' if col == 't' else 'position'} column {col!r}; "
                f"it has {sorted(data)}; name it with columns={{'{col}': NAME}} "
                f"(CLI: --{'time' if col == 't' else 'position'} NAME)"
            )
    for col, factor in (scale or {}).items():
        if col not in picked:
            raise FileFormatError(f"scale names column {col!r}, which was not read")
        if isinstance(factor, str):
            if factor not in data or np.size(data[factor]) != 1:
                raise FileFormatError(
                    f"scale factor {factor!r} for column {col!r} is not a scalar variable of "
                    f"{path.name}"
                )
            factor = float(np.asarray(data[factor]).ravel()[0])
        picked[col] = picked[col] * float(factor)
    meta = dict(meta)
    merged_units = {c: file_units[c] for c in picked if file_units.get(c)}
    merged_units.update(meta.get("units", {}))
    merged_units.update(units or {})
    for col in list(merged_units):
        if col in picked:
            si_unit, factor = _si_unit(col, merged_units[col], path.name)
            picked[col] = picked[col] * factor
            merged_units[col] = si_unit
    meta["units"] = merged_units
    meta["source"] = str(path)
    return Record(**picked, meta=meta, max_jitter=max_jitter)


_DEG = math.pi / 180.0
#: Units a reader converts to SI at the edge: column kind -> unit -> (SI unit, factor).
UNIT_CONVERSIONS: dict[str, dict[str, tuple[str, float]]] = {
    "t": {"s": ("s", 1.0), "ms": ("s", 1e-3), "us": ("s", 1e-6), "µs": ("s", 1e-6),
          "min": ("s", 60.0)},
    "x": {"rad": ("rad", 1.0), "deg": ("rad", _DEG), "°": ("rad", _DEG),
          "rev": ("rad", 2 * math.pi), "m": ("m", 1.0), "mm": ("m", 1e-3), "um": ("m", 1e-6),
          "µm": ("m", 1e-6)},
    "v": {"rad/s": ("rad/s", 1.0), "deg/s": ("rad/s", _DEG), "rpm": ("rad/s", math.pi / 30),
          "rev/s": ("rad/s", 2 * math.pi), "m/s": ("m/s", 1.0), "mm/s": ("m/s", 1e-3)},
    "u": {"N": ("N", 1.0), "kN": ("N", 1e3), "N·m": ("N·m", 1.0), "Nm": ("N·m", 1.0),
          "N*m": ("N·m", 1.0), "N.m": ("N·m", 1.0), "mN·m": ("N·m", 1e-3),
          "mNm": ("N·m", 1e-3)},
}


def _si_unit(column: str, unit: str, source: str) -> tuple[str, float]:
    """SI unit and conversion factor of a column's unit, or a FileFormatError naming it."""
    table = UNIT_CONVERSIONS[column]
    if unit in table:
        return table[unit]
    raise FileFormatError(
        f"{source}: column {column!r} is in {unit!r}, which driveid does not convert; use one "
        f"of {sorted(table)} in the header (e.g. '{column} [{next(iter(table))}]') or convert "
        f"the data to SI first; got {unit!r}"
    )


def _read_csv(path: Path) -> tuple[dict[str, np.ndarray], dict[str, str], dict[str, Any]]:
    meta: dict[str, Any] = {}
    header: str | None = None
    skip = 0
    with open(path, encoding="utf-8-sig") as fh:
        for line in fh:
            skip += 1
            stripped = line.strip()
            if not stripped:
                continue
            if stripped.startswith("#"):
                body = stripped.lstrip("#").strip()
                if body.startswith("meta:"):
                    try:
                        meta = json.loads(body[5:])
                    except json.JSONDecodeError as exc:
                        raise FileFormatError(f"{path.name}: bad meta line: {exc}") from None
                continue
            header = stripped
            break
    if header is None:
        raise FileFormatError(f"{path.name} is empty; expected a header such as 't,x,u'")
    delimiter = ";" if header.count(";") > header.count(",") else ","
    names: list[str] = []
    units: dict[str, str] = {}
    for field_text in header.split(delimiter):
        match = _HEADER.match(field_text)
        if not match:
            raise FileFormatError(
                f"{path.name}: cannot read header field {field_text.strip()!r}; write names "
                "such as 't', 'x' or 't [s]'"
            )
        name, unit = match.group(1), match.group(2)
        if name in names:
            raise FileFormatError(f"{path.name}: column {name!r} appears twice in the header")
        names.append(name)
        if unit:
            units[name] = unit
    try:
        table = np.loadtxt(path, delimiter=delimiter, skiprows=skip, ndmin=2, comments="#")
    except ValueError as exc:
        raise FileFormatError(f"{path.name}: non-numeric data below the header: {exc}") from None
    if table.shape[1] != len(names):
        raise FileFormatError(
            f"{path.name}: header names {len(names)} columns but rows have {table.shape[1]}"
        )
    return {name: table[:, i] for i, name in enumerate(names)}, units, meta


def _read_npz(path: Path) -> tuple[dict[str, np.ndarray], dict[str, str], dict[str, Any]]:
    with np.load(path, allow_pickle=False) as npz:
        data = {k: npz[k] for k in npz.files if k != "meta"}
        meta = json.loads(str(npz["meta"])) if "meta" in npz.files else {}
    return data, {}, meta


def _read_mat(path: Path) -> tuple[dict[str, np.ndarray], dict[str, str], dict[str, Any]]:
    from scipy.io import loadmat

    try:
        raw = loadmat(path)
    except (ValueError, NotImplementedError) as exc:
        raise FileFormatError(
            f"{path.name}: cannot read as MATLAB v4-v7.2 .mat ({exc}); save it with "
            "'-v7' in MATLAB"
        ) from None
    data = {k: v for k, v in raw.items() if not k.startswith("__") and k != "driveid_meta"}
    meta: dict[str, Any] = {}
    if "driveid_meta" in raw:
        meta = json.loads(str(np.asarray(raw["driveid_meta"]).ravel()[0]))
    numeric = {k: v for k, v in data.items() if np.issubdtype(np.asarray(v).dtype, np.number)}
    return numeric, {}, meta
