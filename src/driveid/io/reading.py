"""From a table of file columns to a validated :class:`Record` in SI units.

One pipeline serves every format (:mod:`driveid.io.tables`), the Python API
(:func:`read_record`, :meth:`Record.from_dataframe`) and every command (the shared record
options of :mod:`driveid.commands._record_options`):

1. choose the columns: by name (case-insensitive, with aliases such as ``time``/``Zeit``
   for ``t`` and ``position``/``pos``/``Weg`` for ``x``), by 0-based index, or ``VAR:INDEX``
   for a column of a matrix variable;
2. time from the file, or ``t = t0 + k/fs`` for files without a time column;
3. scale (``--scale u=200``, ``--scale v=0.02/60``; numbers and ``+ - * / ( )`` only, or a
   scalar variable of the file) and units (``--unit x=mm``; header units) converted to SI;
4. the window ``(t0, t1)`` [s] kept;
5. provenance in ``meta``: ``source``, ``sha256``, ``rows``, ``columns``, ``columns_used``,
   ``window``, ``units`` (SI), ``units_in_file``, ``format``.
"""

from __future__ import annotations

import ast
import hashlib
import math
import operator
import re
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from driveid.errors import FileFormatError
from driveid.io.tables import Table, read_table
from driveid.io.units import split_header, to_si

__all__ = ["read_record", "record_from_table", "parse_scale", "COLUMN_ALIASES",
           "OPTION_OF_COLUMN", "file_sha256", "choose_columns"]

#: Record column -> names (lower case) found automatically in a file.
COLUMN_ALIASES: dict[str, tuple[str, ...]] = {
    "t": ("t", "time", "zeit", "timestamp", "times", "time_s", "t_s", "sec", "seconds"),
    "x": ("x", "position", "pos", "weg", "theta", "q", "angle", "winkel", "displacement",
          "disp", "lage", "posistion"),
    "v": ("v", "velocity", "vel", "speed", "omega", "geschwindigkeit", "drehzahl"),
    "u": ("u", "force", "torque", "tau", "f", "kraft", "moment", "drehmoment", "load"),
}
#: Record column -> the CLI option that chooses it.
OPTION_OF_COLUMN = {"t": "--time", "x": "--position", "v": "--velocity", "u": "--force"}
_WORDS = {"t": "time", "x": "position", "v": "velocity", "u": "force"}
# provenance of an earlier reading, stale in a file driveid wrote from a read record
_PROVENANCE = ("source", "sha256", "rows", "columns", "columns_used", "window", "format",
               "units_in_file", "scale", "fs_given", "window_requested", "resampled")


def file_sha256(path: str | Path) -> str:
    """Return the SHA-256 of a file's bytes (hex), for provenance.

    Parameters
    ----------
    path : str or Path
        The file.

    Returns
    -------
    str
        64 hexadecimal digits.
    """
    digest = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def read_record(
    path: str | Path,
    *,
    columns: Mapping[str, str | int] | None = None,
    fs: float | None = None,
    window: tuple[float | None, float | None] | None = None,
    max_jitter: float | None = 0.01,
    scale: Mapping[str, float | str] | None = None,
    units: Mapping[str, str] | None = None,
    counts_per_rev: float | None = None,
    counts_per_metre: float | None = None,
    record_type: Callable[..., Any],
) -> Any:
    """Read a record from any supported file, in SI units, with its provenance.

    Parameters
    ----------
    path : str or Path
        The file (CSV and other delimited text, JSON, MATLAB .mat v5/v7.3, .npz, Parquet,
        HDF5, TDMS; see :mod:`driveid.io.tables`).
    columns : mapping, optional
        Record column (``t``, ``x``, ``v``, ``u``) -> file column: a name, a 0-based index,
        or ``VAR:INDEX`` (column INDEX of matrix VAR; MATLAB's ``data(:, 2)`` is
        ``data:1``). Columns not named are found by name and alias; ``"none"`` ignores a
        quantity (e.g. a velocity column in another unit).
    fs : float, optional
        Sample rate [Hz] for a file without a time column (``t = k/fs``).
    window : tuple of (float or None, float or None), optional
        Keep samples with ``t0 <= t <= t1`` [s]; ``None`` keeps that end.
    max_jitter : float or None
        Largest relative deviation of a sampling interval from the median [-]; ``None``
        accepts any increasing timeline (analyses that need uniform sampling then resample
        with a warning, :meth:`Record.resampled_uniform`).
    scale : mapping, optional
        Record column -> factor: a number, an expression such as ``"0.02/60"``, or the name
        of a scalar variable of the file (EMPS: ``{"u": "gtau"}``). The scaled values are
        taken as SI (or as the unit given in ``units``).
    units : mapping, optional
        Record column -> unit, stating or overriding the file's unit (``{"x": "mm"}``).
    counts_per_rev : float, optional
        Encoder counts per revolution [1/rev], for positions in ``counts``.
    counts_per_metre : float, optional
        Encoder counts per metre [1/m], for positions in ``counts``.
    record_type : type
        :class:`driveid.io.Record` (passed in, so that this module stays below
        ``record.py`` in the import order; :func:`driveid.io.read_record` passes it).

    Returns
    -------
    Record
        The validated record; ``meta`` holds ``source``, ``sha256``, ``rows``, ``columns``,
        ``columns_used``, ``window``, ``units`` (SI) and ``units_in_file``.

    Raises
    ------
    FileNotFoundError
        If the file does not exist.
    FileFormatError
        If the file cannot be parsed, a column or unit is unknown, or time is missing; the
        message names the option that fixes it.
    RecordError
        If the data break a rule of :class:`Record`.

    Examples
    --------
    >>> rec = read_record("trace.csv", columns={"x": "Weg"}, units={"x": "mm"},
    ...                   window=(2.0, 10.0), max_jitter=None)  # doctest: +SKIP
    """
    path = Path(path)
    table = read_table(path)
    return record_from_table(
        table, source=str(path), sha256=file_sha256(path), columns=columns, fs=fs,
        window=window, max_jitter=max_jitter, scale=scale, units=units,
        counts_per_rev=counts_per_rev, counts_per_metre=counts_per_metre,
        record_type=record_type, owned=True)


def choose_columns(table: Table, columns: Mapping[str, str | int] | None = None, *,
                   source: str = "") -> dict[str, str]:
    """Return record column -> file column name, from explicit choices and aliases.

    Parameters
    ----------
    table : Table
        The columns of a file.
    columns : mapping, optional
        Explicit choices (name, 0-based index or ``VAR:INDEX``); ``"none"`` ignores that
        quantity even where a column is named like it.
    source : str
        File name for messages.

    Returns
    -------
    dict
        Found columns only (``t`` may be missing; ``x`` is required later).

    Raises
    ------
    FileFormatError
        If an explicit choice names no column of the file.
    """
    mapping = dict(columns or {})
    unknown = set(mapping) - set(COLUMN_ALIASES)
    if unknown:
        raise FileFormatError(
            f"columns mapping has unknown record column(s) {sorted(unknown)}; map only t, x, "
            "v, u (time, position, velocity, force)")
    chosen: dict[str, str] = {}
    ignored = {col for col, spec in mapping.items() if str(spec).strip().lower() == "none"}
    for col, spec in mapping.items():
        if spec is not None and str(spec).strip() != "" and col not in ignored:
            chosen[col] = _resolve(table, spec, col, source)
    for col in COLUMN_ALIASES:
        if col not in chosen and col not in ignored:
            name = _by_alias(table, col, set(chosen.values()))
            if name is not None:
                chosen[col] = name
    return chosen


def _resolve(table: Table, spec: str | int, col: str, source: str) -> str:
    names = list(table.columns)
    text = str(spec).strip()
    if isinstance(spec, int) or re.fullmatch(r"\d+", text):
        index = int(text)
        if index < len(names):
            return names[index]
    else:
        if text in table.columns:
            return text
        lowered = {n.lower(): n for n in names}
        for candidate in (text, split_header(text)[0]):
            if candidate.lower() in lowered:
                return lowered[candidate.lower()]
    raise FileFormatError(
        f"{source or 'the file'} has no column {text!r} for the {_WORDS[col]} "
        f"({OPTION_OF_COLUMN[col]}); columns found: {_listing(names)}; choose one by name, "
        "0-based index, or VAR:INDEX for a column of a matrix (driveid inspect FILE lists "
        "them)")


def _listing(names: list[str], limit: int = 30) -> str:
    shown = ", ".join(f"[{i}] {n}" for i, n in enumerate(names[:limit]))
    return shown + (f" ... ({len(names)} in all)" if len(names) > limit else "")


def _by_alias(table: Table, col: str, taken: set[str]) -> str | None:
    aliases = COLUMN_ALIASES[col]
    exact, token = None, None
    for name in table.columns:
        if name in taken:
            continue
        leaf = re.split(r"[./]", name)[-1].lower()
        if leaf in aliases and exact is None:
            exact = name
        first = re.split(r"[\s_&]+", leaf)[0]
        if first in aliases and token is None and first != leaf:
            token = name
    return exact if exact is not None else token


_OPS = {ast.Add: operator.add, ast.Sub: operator.sub, ast.Mult: operator.mul,
        ast.Div: operator.truediv}


def parse_scale(text: str | float, scalars: Mapping[str, float] | None = None) -> float:
    """Return the value of a scale factor: a number or a safe arithmetic expression.

    Parameters
    ----------
    text : str or float
        ``"200"``, ``"0.02/60"``, ``"2*pi"`` is refused (no names except the file's scalar
        variables), ``"gtau"`` for a scalar variable of the file.
    scalars : mapping, optional
        Scalar variables of the file that may be named [their own units].

    Returns
    -------
    float
        The factor; finite and non-zero.

    Raises
    ------
    FileFormatError
        If the text is not numbers and ``+ - * / ( )`` (and scalar names of the file).

    Examples
    --------
    >>> parse_scale("0.02/60") == 0.02 / 60, parse_scale("-(1.5e3 + 500)")
    (True, -2000.0)
    """
    if isinstance(text, (int, float)) and not isinstance(text, bool):
        value = float(text)
    else:
        scalars = dict(scalars or {})
        try:
            tree = ast.parse(str(text).strip(), mode="eval")
            value = float(_evaluate(tree.body, scalars))
        except (SyntaxError, ValueError, ZeroDivisionError, KeyError, TypeError) as exc:
            names = f"; scalar variables of the file: {sorted(scalars)}" if scalars else ""
            raise FileFormatError(
                f"scale {text!r} is not a number or an expression of numbers with + - * / "
                f"and parentheses, e.g. 0.02/60{names} ({exc})") from None
    if not (math.isfinite(value) and value != 0.0):
        raise FileFormatError(f"a scale must be finite and non-zero; got {text!r}")
    return value


def _evaluate(node: ast.AST, scalars: Mapping[str, float]) -> float:
    if isinstance(node, ast.Constant) and isinstance(node.value, (int, float)) and not \
            isinstance(node.value, bool):
        return float(node.value)
    if isinstance(node, ast.BinOp) and type(node.op) in _OPS:
        return _OPS[type(node.op)](_evaluate(node.left, scalars), _evaluate(node.right, scalars))
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.USub, ast.UAdd)):
        value = _evaluate(node.operand, scalars)
        return -value if isinstance(node.op, ast.USub) else value
    if isinstance(node, ast.Name) and node.id in scalars:
        return float(scalars[node.id])
    raise ValueError(f"not allowed: {ast.dump(node)[:40]}")


def record_from_table(
    table: Table,
    *,
    source: str = "",
    sha256: str | None = None,
    columns: Mapping[str, str | int] | None = None,
    fs: float | None = None,
    window: tuple[float | None, float | None] | None = None,
    max_jitter: float | None = 0.01,
    scale: Mapping[str, float | str] | None = None,
    units: Mapping[str, str] | None = None,
    counts_per_rev: float | None = None,
    counts_per_metre: float | None = None,
    record_type: Callable[..., Any],
    owned: bool = False,
) -> Any:
    """Build a record from a :class:`~driveid.io.tables.Table` (the reading pipeline).

    Parameters
    ----------
    table : Table
        Columns read from a file or a DataFrame.
    source : str
        Path or name, kept as ``meta["source"]``.
    sha256 : str, optional
        Hash of the file's bytes, kept as ``meta["sha256"]``.
    columns, fs, window, max_jitter, scale, units, counts_per_rev, counts_per_metre
        As in :func:`read_record` [Hz, s, -, -, -, 1/rev, 1/m].
    record_type : type
        :class:`driveid.io.Record` (passed in, so that this module stays below
        ``record.py`` in the import order).
    owned : bool
        True when the table's columns belong to this call alone (a table just read from a
        file): columns already in SI units are then frozen and wrapped by the record
        without a copy (8 B a sample each). False leaves a caller's arrays writeable and
        lets the record copy them.

    Returns
    -------
    Record
        The validated record in SI units with provenance in ``meta``.

    Raises
    ------
    FileFormatError
        Unknown column, unit or scale; no time and no sample rate.
    RecordError
        If the data break a rule of :class:`Record`.
    """
    name = Path(source).name if source else "the data"
    chosen = choose_columns(table, columns, source=name)
    explicit_time = columns is not None and columns.get("t") not in (None, "")
    if fs is not None:
        if explicit_time:
            raise FileFormatError(
                f"{name}: give the time column (--time) or the sample rate (--fs), not both")
        if not (math.isfinite(fs) and fs > 0):
            raise FileFormatError(f"fs must be a positive sample rate [Hz]; got {fs}")
        chosen.pop("t", None)
    if "x" not in chosen:
        raise FileFormatError(
            f"{name} has no position column found by name (x, position, pos, ...); columns "
            f"found: {_listing(list(table.columns))}; choose it with --position COL "
            "(Python: columns={'x': COL}) by name, 0-based index or VAR:INDEX")
    scales = dict(scale or {})
    overrides = dict(units or {})
    for option, given in (("scale", scales), ("units", overrides)):
        unknown = set(given) - set(COLUMN_ALIASES)
        if unknown:
            raise FileFormatError(
                f"{option} names unknown record column(s) {sorted(unknown)}; use t, x, v or u")
    arrays = {col: _numeric(table.columns[fname], fname, name) for col, fname in chosen.items()}
    rate = fs if fs is not None else table.fs
    if "t" not in arrays:
        if rate is None:
            raise FileFormatError(
                f"{name} has no time column found by name (t, time, Zeit, ...); columns found: "
                f"{_listing(list(table.columns))}; choose it with --time COL, or give the "
                "sample rate with --fs HZ (Python: columns={'t': COL} or fs=HZ)")
        n = arrays["x"].size
        arrays["t"] = table.t0 + np.arange(n) / rate
    arrays = _trim_missing(arrays, name)
    file_meta = {k: v for k, v in table.meta.items() if k not in _PROVENANCE}
    from driveid.io.consistency import check_meta_units

    meta_units = file_meta.pop("units", {}) or {}
    # a header saying 't [ms]' under a meta line saying 's' is an error, never a silent pick
    check_meta_units({col: table.units[fname] for col, fname in chosen.items()
                      if fname and table.units.get(fname)}, meta_units, name)
    meta_units = dict(meta_units)
    in_file: dict[str, str] = {}
    si: dict[str, str] = {}
    applied_scale: dict[str, float] = {}
    for col in ("t", "x", "v", "u"):
        if col not in arrays:
            continue
        fname = chosen.get(col)
        file_unit = table.units.get(fname) if fname else None
        file_unit = file_unit or meta_units.get(col) or ("s" if col == "t" and fname is None
                                                         else None)
        if file_unit:
            in_file[col] = file_unit
        stated = overrides.get(col)
        if col in scales:
            factor = parse_scale(scales[col], table.scalars)
            applied_scale[col] = factor
            arrays[col] = arrays[col] * factor
            if stated is None:
                continue  # the scaled values are SI; their unit follows the position's
            unit = stated
        else:
            unit = stated or file_unit
        if unit is None:
            continue
        si_unit, factor = to_si(col, unit, source=name, counts_per_rev=counts_per_rev,
                                counts_per_metre=counts_per_metre)
        if factor != 1.0:  # x * 1.0 == x: no 8 B/sample copy of a column already in SI
            arrays[col] = arrays[col] * factor
        si[col] = si_unit
    _complete_units(si, applied_scale)
    _check_consistent(si, in_file, name)
    t_all = arrays["t"]
    arrays = _crop(arrays, window, name)
    meta = {**file_meta, "units": si, "units_in_file": in_file, "source": source,
            "rows": int(table.rows), "columns": list(table.columns),
            "columns_used": dict(chosen), "format": table.format,
            "window": [float(arrays["t"][0]), float(arrays["t"][-1])]}
    if sha256 is not None:
        meta["sha256"] = sha256
    if applied_scale:
        meta["scale"] = applied_scale
    if "t" not in chosen:
        meta["fs_given"] = float(rate)
    if window is not None and window != (None, None) and t_all.size:
        meta["window_requested"] = [None if w is None else float(w) for w in window]
    given = {id(c) for c in table.columns.values()}
    for arr in arrays.values():
        if (arr.dtype == np.float64 and arr.base is None and arr.flags.writeable
                and (owned or id(arr) not in given)):
            arr.setflags(write=False)  # ours alone: the Record may keep it without a copy
    return record_type(t=arrays["t"], x=arrays["x"], v=arrays.get("v"), u=arrays.get("u"),
                       meta=meta, max_jitter=max_jitter)


def _numeric(values: np.ndarray, fname: str, source: str) -> np.ndarray:
    try:
        return np.asarray(values, dtype=float)
    except (TypeError, ValueError):
        raise FileFormatError(
            f"{source}: column {fname!r} is not numeric (e.g. {values[0]!r}); choose a "
            "numeric column with --time/--position/--velocity/--force") from None


def _trim_missing(arrays: dict[str, np.ndarray], source: str) -> dict[str, np.ndarray]:
    """Drop incomplete rows at the start and end (exports often pad the last rows)."""
    lengths = {a.size for a in arrays.values()}
    if len(lengths) != 1:
        sizes = {c: a.size for c, a in arrays.items()}
        raise FileFormatError(
            f"{source}: the chosen columns have different lengths {sizes}; choose columns of "
            "one table (or one matrix) with --time/--position/--velocity/--force")
    ok = None
    for a in arrays.values():  # one boolean mask (1 B a sample), not one per column
        ok = np.isfinite(a) if ok is None else np.logical_and(ok, np.isfinite(a), out=ok)
    if not ok.any():
        return arrays  # Record explains non-finite data
    first, last = int(np.argmax(ok)), int(ok.size - np.argmax(ok[::-1]))
    if first == 0 and last == ok.size:
        return arrays  # complete: keep the columns themselves (a Record may wrap them)
    return {c: a[first:last] for c, a in arrays.items()}


def _complete_units(si: dict[str, str], scaled: Mapping[str, float]) -> None:
    """Scaled columns without a stated unit are SI: rotational or translational like x."""
    translational = si.get("x", "rad") == "m"
    for col in scaled:
        if col in si:
            continue
        si[col] = {"t": "s", "x": "m" if translational else "rad",
                   "v": "m/s" if translational else "rad/s",
                   "u": "N" if translational else "N·m"}[col]


def _check_consistent(si: Mapping[str, str], in_file: Mapping[str, str], source: str) -> None:
    x_unit, v_unit = si.get("x"), si.get("v")
    if x_unit and v_unit and v_unit.split("/")[0] != x_unit:
        raise FileFormatError(
            f"{source}: position is in {in_file.get('x', x_unit)} ({x_unit}) but velocity in "
            f"{in_file.get('v', v_unit)} ({v_unit}); give the transmission as a scale, e.g. "
            "--scale v=0.02/60 for rpm of a 20 mm/rev screw (then m/s), or choose the "
            "velocity column of the same axis with --velocity COL, or ignore it with "
            "--velocity none")


def _crop(arrays: dict[str, np.ndarray], window: tuple[float | None, float | None] | None,
          source: str) -> dict[str, np.ndarray]:
    if window is None or tuple(window) == (None, None):
        return arrays
    t0, t1 = window
    t = arrays["t"]
    lo = -np.inf if t0 is None else float(t0)
    hi = np.inf if t1 is None else float(t1)
    if not lo < hi:
        raise FileFormatError(
            f"window start {t0} s must be before its end {t1} s (--t-start, --t-end or "
            "FILE@T0:T1)")
    keep = (t >= lo) & (t <= hi)
    if keep.sum() < 2:
        raise FileFormatError(
            f"{source}: the window {t0}..{t1} s holds {int(keep.sum())} sample(s); the record "
            f"spans {t[0]:.6g}..{t[-1]:.6g} s; choose --t-start/--t-end inside it")
    return {c: a[keep] for c, a in arrays.items()}
