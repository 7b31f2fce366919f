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

import hashlib
import math
import re
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from driveid.errors import FileFormatError
from driveid.io.registers import decode_sign_magnitude, sign_magnitude_suspect
from driveid.io.scale_expressions import parse_scale
from driveid.io.tables import Table, read_table
from driveid.io.units import split_header, to_si

__all__ = ["read_record", "record_from_table", "convert_table", "parse_scale",
           "COLUMN_ALIASES", "OPTION_OF_COLUMN", "file_sha256", "choose_columns",
           "decode_sign_magnitude"]

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
               "units_in_file", "scale", "fs_given", "window_requested", "resampled",
               "notes", "reading", "derived")


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
    sign_magnitude: Mapping[str, int] | None = None,
    position: bool = True,
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
    sign_magnitude : mapping, optional
        Record column -> register width [bits] of a column stored as sign-magnitude
        integers (``{"x": 16}``); such a column read without it is flagged by a warning.
    position : bool
        False accepts a file without a position column when it has a velocity (the
        position is then the integrated velocity, ``meta["derived"]``).
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
        sign_magnitude=sign_magnitude, position=position, record_type=record_type,
        owned=True)


def choose_columns(table: Table, columns: Mapping[str, str | int] | None = None, *,
                   source: str = "") -> dict[str, str]:
    """Return record column -> file column name, from explicit choices and conventions.

    Parameters
    ----------
    table : Table
        The columns of a file.
    columns : mapping, optional
        Explicit choices (full name, 0-based index or ``VAR:INDEX``); ``"none"`` ignores
        that quantity even where a column is named like it.
    source : str
        File name for messages.

    Returns
    -------
    dict
        Found columns only (``t`` may be missing; ``x`` is required later).

    Raises
    ------
    FileFormatError
        If an explicit choice names no column, or a name fits several columns (all such
        problems of the file in one message, the candidates listed).
    """
    chosen, _, problems = _choose(table, columns, source=source)
    if problems:
        raise FileFormatError(_joined(source or "the file", problems))
    return chosen


def _choose(table: Table, columns: Mapping[str, str | int] | None, source: str = ""
            ) -> tuple[dict[str, str], list[str], list[str]]:
    """Return the chosen columns, the notes showing each non-obvious choice, the problems."""
    from driveid.io.columns import parse_column_name, rank_candidates

    mapping = dict(columns or {})
    unknown = set(mapping) - set(COLUMN_ALIASES)
    if unknown:
        raise FileFormatError(
            f"columns mapping has unknown record column(s) {sorted(unknown)}; map only t, x, "
            "v, u (time, position, velocity, force)")
    chosen: dict[str, str] = {}
    notes: list[str] = []
    problems: list[str] = []
    ignored = {col for col, spec in mapping.items() if str(spec).strip().lower() == "none"}
    for col, spec in mapping.items():
        if spec is not None and str(spec).strip() != "" and col not in ignored:
            name, problem = _resolve(table, spec, col)
            if problem:
                problems.append(problem)
            else:
                chosen[col] = name
    joint = next((parse_column_name(chosen[c]).joint for c in ("x", "v", "u")
                  if c in chosen and parse_column_name(chosen[c]).quantity), None)
    for col in ("x", "v", "u", "t"):  # position first: velocity and force follow its joint
        if col in chosen or col in ignored or str(mapping.get(col) or "").strip():
            continue  # chosen, ignored, or asked for (and then reported if not found)
        free = [n for n in table.columns if n not in chosen.values()]
        top, passed = rank_candidates(free, col, joint=None if col == "t" else joint)
        if len(top) > 1:
            listed = ", ".join(repr(c.name) for c in top)
            if col in ("v", "u"):  # optional: left out, and said so
                notes.append(
                    f"{len(top)} columns could be the {_WORDS[col]}: {listed}; none is used: "
                    f"choose one with {OPTION_OF_COLUMN[col]} COL")
                continue
            problems.append(
                f"{len(top)} columns could be the {_WORDS[col]}: {listed}; choose one with "
                f"{OPTION_OF_COLUMN[col]} COL (full name or 0-based index)")
            continue
        if not top:
            top = _by_unit(table, free, col)  # a nameless column with a telling unit
            if len(top) > 1:
                problems.append(
                    f"{len(top)} columns are in units of a {_WORDS[col]}: "
                    f"{', '.join(repr(c.name) for c in top)}; choose one with "
                    f"{OPTION_OF_COLUMN[col]} COL")
                continue
            if top:
                chosen[col] = top[0].name
                notes.append(
                    f"read column {top[0].name!r} as the {_WORDS[col]} (its unit "
                    f"{table.units[top[0].name]}); {OPTION_OF_COLUMN[col]} COL chooses another")
            continue
        pick = top[0]
        twin = _repeated_header(table, pick.name, col, source)
        if twin:
            problems.append(twin)
            continue
        chosen[col] = pick.name
        if col != "t" and joint is None and pick.joint is not None and pick.convention:
            joint = pick.joint
        why = []
        if pick.convention:  # q, dq, qd, tau, a joint number: shown, never silent
            why.append("robot/servo naming convention")
        if pick.role != "plain":
            why.append(pick.role_words)
        if passed:
            why.append("passed over: " + ", ".join(
                f"{c.name!r} ({c.role_words})" for c in passed[:6]))
        if why:
            notes.append(
                f"read column {pick.name!r} as the {_WORDS[col]} ({'; '.join(why) or 'name'})"
                f"; {OPTION_OF_COLUMN[col]} COL chooses another"
                + ("" if col in ("t", "x") else f", {OPTION_OF_COLUMN[col]} none ignores it"))
        if col == "v" and pick.name.lower().startswith("qd"):
            notes.append(
                f"{pick.name!r} is read as joint velocity (q-dot); if it is the desired "
                "position, give --velocity none")
    return chosen, notes, problems


def _repeated_header(table: Table, name: str, col: str, source: str = "") -> str | None:
    """Check a column found by its name against the other columns of the same header.

    A header the file repeats (``x``, read as ``x`` and ``x.1``) is no unique name: with
    the same values in every such column, the first is read and a
    :class:`~driveid.errors.RecordWarning` says so; with different values, the returned
    problem asks for a choice by index (issue 28).
    """
    header = next((h for h, names in table.repeated.items() if name in names), None)
    if header is None:
        return None
    names = list(table.columns)
    twins = table.repeated[header]
    where = ", ".join(f"[{names.index(n)}] {n!r}" for n in twins)
    first = table.columns[twins[0]]
    if all(np.array_equal(first, table.columns[n], equal_nan=True) for n in twins[1:]):
        import warnings

        from driveid.errors import RecordWarning

        warnings.warn(
            f"{source + ': ' if source else ''}the header {header!r} names {len(twins)} "
            f"columns ({where}) with the same "
            f"values; read [{names.index(name)}] {name!r} as the {_WORDS[col]}; "
            f"rename the copies in the file, or choose one with {OPTION_OF_COLUMN[col]} INDEX",
            RecordWarning, stacklevel=5)
        return None
    return (f"the header {header!r} names {len(twins)} columns with different values "
            f"({where}), so the {_WORDS[col]} is ambiguous; choose one with "
            f"{OPTION_OF_COLUMN[col]} INDEX (0-based), or rename the columns in the file")


def _check_time_precision(t: np.ndarray, dtype: str | None, fname: str, source: str) -> None:
    """Refuse a time column stored in a float type too narrow for its sampling interval.

    float16 keeps 11 bits: at 6 s its steps are 4 ms, so a 1 kHz clock repeats its stamps
    and the record reads as "not increasing" (issue 28). Refused where the type's
    resolution near the column's end exceeds a tenth of the mean sampling interval.
    """
    if dtype is None or t.size < 2:
        return
    span = abs(float(t[-1]) - float(t[0]))
    step = span / (t.size - 1)
    top = float(np.max(np.abs(t)))
    resolution = float(np.finfo(dtype).eps) * top
    if resolution > 0.1 * step:
        raise FileFormatError(
            f"{source}: the time column {fname!r} is stored as {dtype}, whose precision near "
            f"its end ({top:.3g} s) is about {resolution:.2g} s, too coarse for a sampling "
            f"interval of {step:.2g} s (time stamps repeat or jump); export the time column "
            "as float64 (double), or give the sample rate with --fs HZ and --time none "
            "(Python: fs=HZ, columns={'t': 'none'})")


def _by_unit(table: Table, free: list[str], col: str) -> list[Any]:
    """Columns whose name says nothing but whose unit belongs to one quantity only."""
    from driveid.io.columns import parse_column_name
    from driveid.io.units import UNIT_CONVERSIONS

    out = []
    for name in free:
        parsed = parse_column_name(name)
        if parsed.quantity is None and table.units.get(name) in UNIT_CONVERSIONS[col]:
            out.append(parsed)
    return out


def _joined(source: str, problems: list[str]) -> str:
    """One message for every column and unit problem of a file."""
    if len(problems) == 1:
        return f"{source}: {problems[0]}"
    return f"{source}: {len(problems)} problems: " + " ".join(
        f"({k}) {p}" for k, p in enumerate(problems, 1))


def _resolve(table: Table, spec: str | int, col: str) -> tuple[str, str | None]:
    from driveid.io.columns import matching_names

    names = list(table.columns)
    text = str(spec).strip()
    if isinstance(spec, int) or re.fullmatch(r"\d+", text):
        index = int(text)
        if text in table.columns and index >= len(names):
            return text, None
        if index < len(names):
            return names[index], None
    else:
        found = matching_names(names, text, table.repeated)
        if not found:
            base = split_header(text)[0]
            if base != text:  # the header with its unit: 'x [mm]'
                found = matching_names(names, base, table.repeated)
        if len(found) == 1:
            return found[0], None
        if found:
            where = ", ".join(f"[{names.index(n)}] {n!r}" for n in found)
            return "", (
                f"{text!r} for the {_WORDS[col]} ({OPTION_OF_COLUMN[col]}) fits "
                f"{len(found)} columns: {where}; give the full name or the 0-based index")
    return "", (
        f"no column {text!r} for the {_WORDS[col]} ({OPTION_OF_COLUMN[col]}); columns "
        f"found: {_listing(names)}; choose one by full name, 0-based index, or VAR:INDEX "
        "for a column of a matrix (driveid inspect FILE lists them)")


def _listing(names: list[str], limit: int = 30) -> str:
    shown = ", ".join(f"[{i}] {n}" for i, n in enumerate(names[:limit]))
    return shown + (f" ... ({len(names)} in all)" if len(names) > limit else "")


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
    sign_magnitude: Mapping[str, int] | None = None,
    position: bool = True,
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
    sign_magnitude : mapping, optional
        Record column -> register width [bits] of a column stored as a sign-magnitude
        integer (the top bit is the sign): decoded before scaling.
    position : bool
        False accepts a record without a position column when it has a velocity: the
        position is then the velocity integrated from 0 (``meta["derived"]``), for
        analyses that use no position.
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
        The validated record in SI units with provenance in ``meta``; ``meta["notes"]``
        shows every choice that was not stated in the file or the options (a column chosen
        by convention, a unit assumed).

    Raises
    ------
    FileFormatError
        Unknown column, unit or scale; no time and no sample rate (every such problem of
        the file in one message).
    RecordError
        If the data break a rule of :class:`Record`.
    """
    arrays, meta = convert_table(
        table, source=source, sha256=sha256, columns=columns, fs=fs, window=window,
        max_jitter=max_jitter, scale=scale, units=units, counts_per_rev=counts_per_rev,
        counts_per_metre=counts_per_metre, sign_magnitude=sign_magnitude,
        require=("x", "v") if not position else ("x",))
    if "x" not in arrays:
        v = arrays["v"]
        dt = np.diff(arrays["t"])
        x = np.concatenate(([0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) * dt)))
        arrays["x"] = x
        meta["units"]["x"] = meta["units"].get("v", "rad/s").split("/")[0]
        meta["derived"] = {"x": "velocity integrated from 0 (no position column)"}
        meta["notes"].append("no position column: the position is the velocity integrated "
                             "from 0, for analyses that use no position")
    given = {id(c) for c in table.columns.values()}
    for arr in arrays.values():
        if (arr.dtype == np.float64 and arr.base is None and arr.flags.writeable
                and (owned or id(arr) not in given)):
            arr.setflags(write=False)  # ours alone: the Record may keep it without a copy
    return record_type(t=arrays["t"], x=arrays["x"], v=arrays.get("v"), u=arrays.get("u"),
                       meta=meta, max_jitter=max_jitter)


def convert_table(
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
    sign_magnitude: Mapping[str, int] | None = None,
    require: tuple[str, ...] = ("x",),
) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
    """Choose, decode, scale, convert and crop the columns of a table, without a Record.

    The steps of :func:`record_from_table` before the :class:`Record` is built; ``driveid
    inspect`` uses it directly so that a force-only or speed-only file can be described.

    Parameters
    ----------
    table : Table
        Columns read from a file or a DataFrame.
    source, sha256, columns, fs, window, max_jitter, scale, units, counts_per_rev
        As in :func:`record_from_table` [-, -, -, Hz, s, -].
    counts_per_metre, sign_magnitude
        As in :func:`record_from_table` [1/m, bits].
    require : tuple of str
        Record columns of which at least one must be found (``("x",)``: a position;
        ``()``: any column will do).

    Returns
    -------
    tuple of (dict, dict)
        Record column -> values in SI units, shape (n,) each (``t`` always), and the
        ``meta`` of the record (provenance, ``units``, ``notes``, ``reading``).

    Raises
    ------
    FileFormatError
        Every column and unit problem of the file, in one message.
    """
    name = Path(source).name if source else "the data"
    chosen, notes, problems = _choose(table, columns, source=name)
    # already reported: no second 'not found' for them
    unresolved = {c for c in COLUMN_ALIASES if any(
        f"the {_WORDS[c]} ({OPTION_OF_COLUMN[c]})" in p or f"could be the {_WORDS[c]}:" in p
        or f"so the {_WORDS[c]} is ambiguous" in p for p in problems)}
    explicit_time = columns is not None and str(columns.get("t") or "").strip().lower() not in (
        "", "none")
    if fs is not None:
        if explicit_time:
            raise FileFormatError(
                f"{name}: give the time column (--time) or the sample rate (--fs), not both")
        if not (math.isfinite(fs) and fs > 0):
            raise FileFormatError(f"fs must be a positive sample rate [Hz]; got {fs}")
        found = chosen.pop("t", None)
        if found:  # issue 28: the file's own clock was dropped without a word
            import warnings

            from driveid.errors import RecordWarning

            warnings.warn(
                f"{name}: the file has a time column {found!r}, which --fs {fs:g} Hz (Python: "
                "fs=) replaces by k/fs; leave --fs out to use the column, or pass --time none "
                "to say that it is no clock", RecordWarning, stacklevel=4)
    ignored = {c for c, spec in dict(columns or {}).items()
               if str(spec).strip().lower() == "none"}
    if require and not any(c in chosen or c in unresolved for c in require) and not any(
            c in dict(columns or {}) and c not in ignored for c in require):
        words = " or ".join(_WORDS[c] for c in require)
        problems.append(
            f"no {words} column found by name (x, position, pos, q ...); columns found: "
            f"{_listing(list(table.columns))}; choose it with --position COL (Python: "
            "columns={'x': COL}) by full name, 0-based index or VAR:INDEX"
            + ("; driveid inspect FILE describes a file without one" if require == ("x",)
               else ""))
    scales = dict(scale or {})
    overrides = dict(units or {})
    signs = dict(sign_magnitude or {})
    for option, given in (("scale", scales), ("units", overrides),
                          ("sign_magnitude", signs)):
        unknown = set(given) - set(COLUMN_ALIASES)
        if unknown:
            raise FileFormatError(
                f"{option} names unknown record column(s) {sorted(unknown)}; use t, x, v or u")
    rate = fs if fs is not None else table.fs
    if "t" not in chosen and "t" not in unresolved and rate is None:
        problems.append(
            "no time column found by name (t, time, Zeit, ...); choose it with --time COL, "
            "or give the sample rate with --fs HZ (Python: columns={'t': COL} or fs=HZ)")
    arrays: dict[str, np.ndarray] = {}
    for col, fname in chosen.items():
        try:
            arrays[col] = _numeric(table.columns[fname], fname, name)
        except FileFormatError as exc:
            problems.append(str(exc).removeprefix(f"{name}: "))
    from driveid.io.consistency import check_meta_units

    file_meta = {k: v for k, v in table.meta.items() if k not in _PROVENANCE}
    meta_units = file_meta.pop("units", {}) or {}
    # a header saying 't [ms]' under a meta line saying 's' is an error, never a silent pick
    check_meta_units({col: table.units[fname] for col, fname in chosen.items()
                      if fname and table.units.get(fname)}, meta_units, name)
    meta_units = dict(meta_units)
    in_file: dict[str, str] = {}
    si: dict[str, str] = {}
    applied_scale: dict[str, float] = {}
    unitless: list[str] = []
    for col in ("t", "x", "v", "u"):
        if col not in arrays:
            continue
        fname = chosen[col]
        if col in signs:
            try:
                arrays[col] = decode_sign_magnitude(arrays[col], signs[col])
            except FileFormatError as exc:
                problems.append(f"column {fname!r} ({OPTION_OF_COLUMN[col]}): {exc}")
                continue
        else:
            bits = sign_magnitude_suspect(arrays[col])
            if bits:
                import warnings

                from driveid.errors import RecordWarning

                warnings.warn(
                    f"{name}: column {fname!r} looks like a {bits}-bit sign-magnitude "
                    f"register (small values next to values just above {2 ** (bits - 1)}): "
                    f"decode it with --sign-magnitude {col}:{bits} (Python: "
                    f"sign_magnitude={{'{col}': {bits}}}), or check the export",
                    RecordWarning, stacklevel=4)
        file_unit = table.units.get(fname) or meta_units.get(col)
        if file_unit:
            in_file[col] = file_unit
        stated = overrides.get(col)
        if col in scales:
            try:
                factor = parse_scale(scales[col], table.scalars)
            except FileFormatError as exc:
                problems.append(str(exc))
                continue
            applied_scale[col] = factor
            arrays[col] = arrays[col] * factor
            if stated is None:
                continue  # the scaled values are SI; their unit follows the position's
            unit = stated
        else:
            unit = stated or file_unit
        if unit is None:
            unitless.append(col)
            continue
        try:
            si_unit, factor = to_si(col, unit, counts_per_rev=counts_per_rev,
                                    counts_per_metre=counts_per_metre)
        except FileFormatError as exc:
            problems.append(f"{_WORDS[col]} {fname!r}: {exc}")
            continue
        if factor != 1.0:  # x * 1.0 == x: no 8 B/sample copy of a column already in SI
            arrays[col] = arrays[col] * factor
        si[col] = si_unit
    if problems:
        raise FileFormatError(_joined(name, problems))
    if "t" not in arrays:
        n = next(iter(arrays.values())).size if arrays else table.rows
        arrays["t"] = table.t0 + np.arange(n) / rate
    arrays = _trim_missing(arrays, name)
    if arrays["t"].size == 0:  # issue 28: empty arrays (.npz, .mat) ended in an IndexError
        raise FileFormatError(
            f"{name}: the columns chosen hold no samples (empty arrays): export the data "
            "again, or choose other columns (--time/--position)")
    if "t" in chosen:
        _check_time_precision(arrays["t"], table.precision.get(chosen["t"]), chosen["t"], name)
    _complete_units(si, applied_scale)
    translational = si.get("x", "").startswith("m") or (
        "x" not in si and si.get("v", "").startswith("m/"))
    for col in unitless:
        assumed = {"t": "s", "x": "m" if translational else "rad",
                   "v": "m/s" if translational else "rad/s",
                   "u": "N" if translational else "N·m"}[col]
        other = {"t": "ms", "x": "m" if assumed == "rad" else "mm",
                 "v": "m/s" if assumed == "rad/s" else "mm/s",
                 "u": "N" if assumed == "N·m" else "kN"}[col]
        notes.append(f"the {_WORDS[col]} column {chosen[col]!r} states no unit: read as "
                     f"{assumed}; give --unit {col}={other} (or the right unit) if it is "
                     "another")
    _check_consistent(si, in_file, name)
    t_all = arrays["t"]
    arrays = _crop(arrays, window, name)
    meta = {**file_meta, "units": si, "units_in_file": in_file, "source": source,
            "rows": int(table.rows), "columns": list(table.columns),
            "columns_used": dict(chosen), "format": table.format,
            "window": [float(arrays["t"][0]), float(arrays["t"][-1])],
            "notes": notes}
    reading = _reading_options(columns, fs, max_jitter, scale, units, counts_per_rev,
                               counts_per_metre, sign_magnitude)
    if reading:
        meta["reading"] = reading
    if sha256 is not None:
        meta["sha256"] = sha256
    if applied_scale:
        meta["scale"] = applied_scale
    if "t" not in chosen:
        meta["fs_given"] = float(rate)
    if window is not None and window != (None, None) and t_all.size:
        meta["window_requested"] = [None if w is None else float(w) for w in window]
    return arrays, meta


def _reading_options(columns, fs, max_jitter, scale, units, counts_per_rev, counts_per_metre,
                     sign_magnitude) -> dict[str, Any]:
    """Return the options of this reading that differ from the defaults (to read it again)."""
    out: dict[str, Any] = {}
    if columns:
        out["columns"] = {k: v if isinstance(v, int) else str(v) for k, v in columns.items()}
    if fs is not None:
        out["fs"] = float(fs)
    if max_jitter != 0.01:
        out["max_jitter"] = max_jitter
    if scale:
        out["scale"] = {k: v if isinstance(v, (int, float)) else str(v)
                        for k, v in scale.items()}
    if units:
        out["units"] = dict(units)
    for key, value in (("counts_per_rev", counts_per_rev),
                       ("counts_per_metre", counts_per_metre)):
        if value is not None:
            out[key] = float(value)
    if sign_magnitude:
        out["sign_magnitude"] = {k: int(v) for k, v in sign_magnitude.items()}
    return out


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
    x_unit, v_unit, u_unit = si.get("x"), si.get("v"), si.get("u")
    if x_unit in ("m", "rad") and u_unit in ("N", "N·m") and \
            (x_unit == "m") != (u_unit == "N"):
        # x [mm] beside u [N·m] was read as a force in N (fifth hostile campaign)
        rotary = x_unit == "rad"
        raise FileFormatError(
            f"{source}: position is in {in_file.get('x', x_unit)} ({x_unit}) but the "
            f"{'force' if rotary else 'torque'} in {in_file.get('u', u_unit)} ({u_unit}): "
            f"one body moves either in rad with N·m or in m with N; give the transmission "
            f"as a scale, e.g. --scale u=2*3.14159/0.02 --unit u=N for the torque of a 20 "
            "mm/rev screw, choose the force column of the same axis with --force COL, or "
            "ignore it with --force none")
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
