"""Raw column reading of measured traces in the formats drive engineers bring.

:func:`read_table` turns a file into a :class:`Table`: named one-dimensional numeric columns
(a matrix variable ``data`` of a .mat, .npz, JSON or HDF5 file becomes the columns
``data:0``, ``data:1`` ... along its shorter axis, 0-based), the unit of each column as
stated in the file, scalars, and the driveid metadata of files driveid wrote. It knows
nothing of records: choosing columns, converting units and validating is
:func:`driveid.io.read_record`'s work.

Formats (chosen by suffix):

- delimited text (``.csv .txt .dat .tsv .asc .prn``), read with :func:`pandas.read_csv`:
  delimiter sniffed among ``,`` ``;`` tab and whitespace, decimal comma detected, thousands
  grouping (``"1,234.5"`` quoted, ``1.234,5``), BOM, UTF-16 (Excel "Unicode text"),
  preamble/metadata lines before the header skipped (the header is the line just above the
  first run of numeric rows), comment lines (``#``), trailing empty columns, units in the
  header in every spelling of :func:`driveid.io.units.split_header`;
- JSON (``.json``): an object of equal-length arrays, an array of row objects, or a 2-D
  array of rows under a key (columns ``KEY:INDEX``); nested objects give dotted names
  (``data.disp``); units beside the data (``{"units": {"disp": "in"}}``, ``"disp_unit"``,
  or ``{"disp": {"values": [...], "unit": "in"}}``);
- MATLAB ``.mat`` v4-v7.2 (scipy) and v7.3 (HDF5 via h5py; datasets stored transposed);
  structs give dotted names (``logsout.time``);
- ``.npz`` (numpy), Parquet (``.parquet``, pandas + pyarrow), HDF5 (``.h5 .hdf5``: datasets,
  compound tables, pandas fixed-format frames), TDMS (``.tdms``, National Instruments, via
  npTDMS, imported only when needed).
"""

from __future__ import annotations

import csv
import re
from pathlib import Path
from typing import Any

import numpy as np

from driveid.errors import FileFormatError
from driveid.io.container_tables import CONTAINER_READERS
from driveid.io.table_type import Table, table_from_dataframe, unique_name
from driveid.io.units import known_unit as _known_unit
from driveid.io.units import normalise_unit, split_header

__all__ = ["Table", "read_table", "table_from_dataframe", "refuse_non_file", "READABLE_SUFFIXES"]

_TEXT = (".csv", ".txt", ".dat", ".tsv", ".asc", ".prn")
#: File suffixes :func:`read_table` reads.
READABLE_SUFFIXES = (*_TEXT, ".json", ".mat", ".npz", ".parquet", ".pq", ".h5", ".hdf5",
                     ".hdf", ".tdms")
_SAMPLE_LINES = 400


def refuse_non_file(path: Path) -> None:
    """Raise the error for a record path that is no regular file (missing, folder, device).

    Parameters
    ----------
    path : Path
        The path a user named as a record file.

    Raises
    ------
    IsADirectoryError
        A folder (the message names a file in it and the fleet's pattern form).
    FileFormatError
        A device, pipe or socket.
    FileNotFoundError
        Nothing there.
    """
    if path.is_dir():  # issue 28: a folder was reported as 'no such record file'
        raise IsADirectoryError(
            f"{path} is a folder, not a record file; name a file in it (e.g. {path}/run.csv), "
            "or quote a pattern for fleet identify ('DIR/**/*.csv')")
    if path.exists():
        raise FileFormatError(f"{path} is not a regular file (a device, pipe or socket); "
                              "name a record file (.csv, .npz, .mat ...)")
    raise FileNotFoundError(f"no such record file: {path}")


def read_table(path: str | Path) -> Table:
    """Read the numeric columns of a file in any supported format.

    Parameters
    ----------
    path : str or Path
        The file; its suffix chooses the reader (:data:`READABLE_SUFFIXES`).

    Returns
    -------
    Table
        Columns, units, scalars and metadata found.

    Raises
    ------
    FileNotFoundError
        If the file does not exist.
    IsADirectoryError
        If ``path`` is a folder.
    FileFormatError
        If ``path`` is no regular file, the suffix is unknown or the content cannot be
        parsed; the message says which formats and options would work.
    """
    path = Path(path)
    if not path.is_file():
        refuse_non_file(path)
    suffix = path.suffix.lower()
    readers = CONTAINER_READERS
    if suffix in _TEXT:
        table = _read_text(path)
    elif suffix in readers:
        table = readers[suffix](path)
    else:
        raise FileFormatError(
            f"cannot read {path.name}: unknown suffix {path.suffix!r}; driveid reads "
            f"{', '.join(READABLE_SUFFIXES)}; export the trace as CSV (one column per "
            "quantity, units in the header such as 'x [mm]') or rename a text file to .csv")
    if not table.columns:
        raise FileFormatError(
            f"{path.name}: found no numeric column ({table.format}); driveid needs at least "
            "a position column, and a time column or --fs HZ")
    return table


# -- delimited text -----------------------------------------------------------------------
_CANDIDATES = ((";", ","), (";", "."), ("\t", ","), ("\t", "."), (",", "."), (None, "."),
               (None, ","))
_COMMENT = ("#", "%", "//")
_RATE = re.compile(r"(sampl\w*\s*(rate|freq\w*)|fs|abtastrate)\W+([0-9.eE+-]+)\s*(k?hz)?",
                   re.IGNORECASE)


def _utf16(path: Path) -> str | None:
    """Return the UTF-16 codec of an Excel "Unicode text" export, or None.

    A BOM names it; without one, NUL bytes in every other position of the head do (ASCII
    text in UTF-16-LE). It read as cp1252 before: "no block of numeric rows".
    """
    with open(path, "rb") as fh:
        head = fh.read(4096)
    if head[:2] in (b"\xff\xfe", b"\xfe\xff"):
        return "utf-16"
    if len(head) >= 64:
        odd, even = head[1::2], head[0::2]
        if odd.count(0) > 0.9 * len(odd) and even.count(0) < 0.1 * len(even):
            return "utf-16-le"
        if even.count(0) > 0.9 * len(even) and odd.count(0) < 0.1 * len(odd):
            return "utf-16-be"
    return None


def _lines(path: Path) -> tuple[list[str], str]:
    wide = _utf16(path)
    for encoding in ((wide,) if wide else ("utf-8-sig", "cp1252", "latin-1")):
        try:
            with open(path, encoding=encoding) as fh:
                lines = []
                for line in fh:
                    lines.append(line.rstrip("\r\n"))
                    if len(lines) >= _SAMPLE_LINES:
                        break
            return lines, encoding
        except UnicodeDecodeError:
            continue
    raise FileFormatError(f"{path.name}: not a text file")  # pragma: no cover (latin-1)


def _fields(line: str, sep: str | None) -> list[str]:
    if sep is None:
        parts = line.split()
    elif '"' in line:  # a quoted field may hold the delimiter ("572,845.832" in a , file)
        try:
            parts = [f.strip() for f in next(csv.reader([line], delimiter=sep))]
        except csv.Error:  # a field over the csv limit: the plain split, as before
            parts = [f.strip().strip('"') for f in line.split(sep)]
    else:
        parts = [f.strip() for f in line.split(sep)]
    while parts and not parts[-1]:
        parts.pop()  # trailing empty columns (a delimiter at the end of every row)
    return parts


# an ISO time zone (Z, +01:00, +0200) is allowed: a DST switch inside a log (issue 28)
_TIMESTAMP = re.compile(
    r"^(\d{4}-\d\d-\d\d[ T])?\d{1,2}:\d\d:\d\d([.,]\d+)?(Z|[+-]\d\d:?\d\d)?$")


#: Cells that loggers and spreadsheets write for a missing value; they read as NaN, so the
#: record's finiteness check names them instead of the block search stopping there.
_MISSING = {"nan", "na", "n/a", "#n/a", "-", "--", "null", "none", "#value!", "#div/0!"}


#: A number with thousands grouping, by decimal mark: 572,845.832 and 572.845,832.
_GROUPED = {".": re.compile(r"^[+-]?\d{1,3}(,\d{3})+(\.\d*)?$"),
            ",": re.compile(r"^[+-]?\d{1,3}(\.\d{3})+(,\d*)?$")}


#: A Fortran double-precision exponent (1.000000D-03, 5,0d+02 with a decimal comma).
_FORTRAN = re.compile(r"^([+-]?(?:\d+[.,]?\d*|[.,]\d+))[dD]([+-]?\d+)$")


def _plain(part: str, decimal: str) -> str:
    """Return the field as Python reads a float: no grouping, a decimal point, an E."""
    if _GROUPED[decimal].match(part):
        part = part.replace("," if decimal == "." else ".", "")
    part = _FORTRAN.sub(r"\1e\2", part)
    return part.replace(",", ".") if decimal == "," else part


def _fortran_column(cells: Any, decimal: str) -> np.ndarray | None:
    """Read a column of Fortran ``D`` exponents, or None when it has none."""
    import pandas as pd

    text = pd.Series(cells).astype(str).str.strip()
    found = text.str.match(_FORTRAN.pattern)
    if not found.any():
        return None
    # vectorised, not _plain per cell: 0.25 against 0.87 s for a 200 000-row column
    text = text.str.replace(_FORTRAN.pattern, r"\1e\2", regex=True)
    if decimal == ",":
        text = text.str.replace(",", ".", regex=False)
    return pd.to_numeric(text, errors="coerce").to_numpy(dtype=float)


def _numeric(parts: list[str], decimal: str, missing_only: bool = False) -> bool:
    """Tell whether a line's fields are numbers, timestamps or missing-value marks.

    A line of missing marks alone counts only inside a block (``missing_only``).
    """
    if not parts:
        return False
    found = False
    for part in parts:
        if not part:
            continue
        try:
            float(_plain(part, decimal))
        except ValueError:
            if part.lower() in _MISSING:
                continue
            if not _TIMESTAMP.match(part):
                return False
        found = True
    return found or missing_only


def _header_fields(line: str, sep: str | None, name: str = "") -> list[str]:
    """Split a header line, honouring quotes (``"Position, mm"`` is one field).

    ``name`` (the file's) starts the message of the error a too-long field raises.
    """
    if sep is None:
        return _fields(line, sep)
    try:
        parts = [f.strip() for f in next(csv.reader([line], delimiter=sep))]
    except csv.Error:  # a field over csv.field_size_limit() (a 1 MB column name, issue 28)
        raise FileFormatError(
            f"{name}: a header line holds a field longer than the csv field limit of "
            f"{csv.field_size_limit()} characters; column names are short words such as "
            "'x [mm]': fix or delete that line") from None
    while parts and not parts[-1]:
        parts.pop()
    return parts


def _is_unit_row(parts: list[str]) -> bool:
    """Tell whether a line holds units under the names (``s,mm,N``), as LabVIEW exports."""
    known = 0
    for part in parts:
        text = part.strip().strip("[]()")
        if not text:
            continue
        if _known_unit(text):
            known += 1
        elif text.lower() not in _OTHER_UNITS:
            return False
    return known > 0


def _unit_row_with_a_typo(parts: list[str], above: list[str], sep: str | None,
                          name: str) -> bool:
    """Tell a units row with one unknown unit (``s,parsec,N*m``) under a header of names.

    Taken as the header, its units were listed as the columns ("no position column ...
    [1] parsec"); as a units row, the reader names the unit it does not know.
    """
    texts = [p.strip().strip("[]()") for p in parts if p.strip()]
    known = sum(1 for p in texts if _known_unit(p) or p.lower() in _OTHER_UNITS)
    if known < 2 or len(texts) - known != 1:
        return False
    header = next((line for line in reversed(above) if line.strip()), None)
    if header is None or _is_comment(header):
        return False
    names = _header_fields(header, sep, name)
    return len(names) == len(parts) and not any(_known_unit(n) for n in names)


# units of quantities that are no record column, seen in unit rows beside known ones
# (Maxon EPOS: 'ms;rpm;%' - a torque in % of the rated torque)
_OTHER_UNITS = {"%", "-", "°c", "degc", "k", "bar", "pa", "kpa", "mpa", "hz", "khz", "w",
                "kw", "ohm", "Ω", "digits", "inc", "g", "m/s²", "m/s^2", "rad/s²", "rad/s^2"}


def _seconds(values: Any) -> np.ndarray | None:
    """Timestamps (``2024-05-01 12:00:00.125`` or ``12:00:00.125``) as seconds from the first."""
    import pandas as pd

    text = pd.Series(values).astype(str).str.strip().str.replace(",", ".", regex=False)
    if not text.str.match(_TIMESTAMP.pattern).all():
        return None
    try:
        if text.str.contains("-").any():
            # utc: mixed offsets (+01:00 then +02:00 across a DST switch) on one clock
            stamps = pd.to_datetime(text, format="mixed", utc=True)
            return (stamps - stamps.iloc[0]).dt.total_seconds().to_numpy(dtype=float)
        deltas = pd.to_timedelta(text)
        seconds = (deltas - deltas.iloc[0]).dt.total_seconds().to_numpy(dtype=float)
        # a clock time without a date wraps at midnight (23:59:59 -> 00:00:00): a step back
        # of more than half a day is the next day (the time was read as going back 86390 s)
        days = np.concatenate([[0.0], np.cumsum(np.diff(seconds) < -43200.0)])
        return seconds + 86400.0 * days
    except (ValueError, TypeError):
        return None


def _is_comment(line: str) -> bool:
    return line.lstrip().startswith(_COMMENT)


def _sniff(lines: list[str]) -> tuple[str | None, str, int, int]:
    """Delimiter, decimal mark, index of the first data line and number of fields."""
    best: tuple[int, int, str | None, str, int] | None = None
    for rank, (sep, decimal) in enumerate(_CANDIDATES):
        start, widths, rows, commas = None, [], [], False
        for i, line in enumerate(lines):
            if not line.strip() or _is_comment(line):
                continue
            parts = _fields(line, sep)
            if _numeric(parts, decimal, missing_only=start is not None):
                if start is None:
                    start = i
                widths.append(len(parts))
                rows.append(i)
                commas = commas or any("," in p for p in parts)
            else:
                start, widths, rows, commas = None, [], [], False
        if start is None or (decimal == "," and not commas):
            continue
        if len(widths) > 8 and widths[0] > max(widths[1:]):
            # one wide row of values above a long, narrower block: a metadata pair
            # ('trigger_start_deg, sample_rate, duration_sec' / '90, 1000, 5'), not data
            start, widths = rows[1], widths[1:]
        width = max(widths)  # rows may end early: a sparse last column (events, marks)
        key = (width, -rank)
        if best is None or key > best[:2]:
            best = (width, -rank, sep, decimal, start)
    if best is None:
        raise FileFormatError(
            "found no block of numeric rows with the same number of fields (non-numeric data "
            "below the header?); driveid reads "
            "delimited text (',' ';' tab or spaces, '.' or ',' as decimal mark) with a "
            "header line of names above the data")
    width, _, sep, decimal, start = best
    return sep, decimal, start, width


def _read_text(path: Path) -> Table:
    import pandas as pd

    lines, encoding = _lines(path)
    try:
        sep, decimal, start, width = _sniff(lines)
    except FileFormatError as exc:
        raise FileFormatError(f"{path.name}: {exc}") from None
    meta: dict[str, Any] = {}
    notes: dict[str, str] = {}
    header: list[str] | None = None
    for line in lines[:start]:
        body = line.strip()
        if body.startswith("#") and body.lstrip("#").strip().startswith("meta:"):
            from driveid.io.consistency import load_json

            # bounded nesting, no NaN, a message that never echoes the line (issue 12)
            meta = load_json(body.lstrip("#").strip()[5:], f"{path.name}: '# meta:' line")
            if not isinstance(meta, dict):
                raise FileFormatError(
                    f"{path.name}: the '# meta:' line must hold a JSON object such as "
                    f"{{\"units\": {{\"t\": \"s\"}}}}; got a {type(meta).__name__}; fix or "
                    "delete that line")
    fs = None
    for line in lines[:start]:
        match = _RATE.search(line)
        if match:
            fs = float(match.group(3)) * (1e3 if (match.group(4) or "").lower() == "khz" else 1)
    unit_row: list[str] | None = None
    used: set[int] = set()
    pair = _metadata_pair(lines[:start], sep, decimal)
    for index in range(start - 1, -1 if not pair else start - 1, -1):  # a pair: no header
        line = lines[index]
        if not line.strip():
            continue
        text = line.lstrip()
        if _is_comment(text):
            text = text.lstrip("#%/ ")
            if text.startswith("meta:") or len(_header_fields(text, sep, path.name)) != width:
                continue
        parts = _header_fields(text, sep, path.name)
        if sep is None and len(parts) != width:
            parts = [p for p in re.split(r"\t|\s{2,}", text.strip()) if p]
        label, parts = _row_label(parts, width)
        if label == "other":
            continue  # 'Description', 'Data type' ... lines of an instrument header block
        if label == "unit" and unit_row is None:
            unit_row = parts + [""] * (width - len(parts))
            used.add(index)
            continue
        if label == "name":
            header = parts + [""] * (width - len(parts))
            used.add(index)
            break
        if len(parts) > width:
            parts = parts[:width]  # named columns that stay empty in every row
        if unit_row is None and len(parts) <= width and (
                _is_unit_row(parts) or _unit_row_with_a_typo(parts, lines[:index], sep,
                                                             path.name)):
            unit_row = parts + [""] * (width - len(parts))
            used.add(index)
            continue
        if len(parts) == width:
            header = parts
            used.add(index)
        elif parts and not _numeric(parts, decimal):
            _refuse_ragged(path.name, lines, start, sep, len(parts), width)
        break
    if header is None and unit_row is not None:
        header, unit_row = unit_row, None  # a header whose names all look like units
    grouped = any(_GROUPED[decimal].match(part) for line in lines[start:]
                  for part in _fields(line, sep))
    thousands = ("," if decimal == "." else ".") if grouped else None
    try:
        frame = pd.read_csv(path, sep=r"\s+" if sep is None else sep, decimal=decimal,
                            header=None, skiprows=start, comment="#", encoding=encoding,
                            engine="python" if sep is None else "c", skip_blank_lines=True,
                            usecols=range(width), names=list(range(width)),
                            thousands=thousands)
    except (ValueError, pd.errors.ParserError) as exc:
        raise FileFormatError(
            f"{path.name}: rows below the header cannot be parsed ({exc}); every row must "
            f"have the {width} fields of the first data row") from None
    for key, value in pair.items():
        notes[key] = value
        if fs is None and re.fullmatch(r"(sampl\w*[ _]?(rate|freq\w*)|fs|rate)(_hz)?", key,
                                       re.IGNORECASE):
            fs = float(value.replace(",", ".") if decimal == "," else value)
    for index, line in enumerate(lines[:start]):
        body = line.strip()
        if index in used or not body or (body.startswith("#") and "meta:" in body):
            continue
        parts = re.split(r"\s*[:;,=\t]\s*", body.lstrip("#%/ "), maxsplit=1)
        key, value = (parts + [""])[:2]
        if key and value and len(notes) < 50:
            notes[key.strip()] = value.strip()
    found = header is not None
    if header is None:
        header = [str(i) for i in range(width)]
    columns: dict[str, np.ndarray] = {}
    units: dict[str, str] = {}
    repeated: dict[str, list[str]] = {}
    for i, text in enumerate(header):
        name, unit = split_header(text)
        if unit_row is not None and unit_row[i].strip().strip("[]()"):
            unit = normalise_unit(unit_row[i].strip().strip("[]()"))
        unique = unique_name(name or str(i), columns)
        if unique != (name or str(i)):
            repeated.setdefault(name, [name]).append(unique)
        name = unique
        values = pd.to_numeric(frame[i], errors="coerce").to_numpy(dtype=float)
        if not pd.api.types.is_numeric_dtype(frame[i]) and np.isnan(values).any():
            fortran = _fortran_column(frame[i], decimal)
            if fortran is not None:
                values = fortran
        if np.isnan(values).all() and frame[i].notna().any():
            stamps = _seconds(frame[i].dropna())
            if stamps is not None and stamps.size == values.size:
                values, unit = stamps, "s"
        columns[name] = values
        if unit:
            units[name] = unit
    sep_name = {None: "whitespace", "\t": "tab"}.get(sep, repr(sep))
    where = f"header at line {start}" if found else "no header: columns named by index"
    return Table(columns=columns, units=units, meta=meta, fs=fs, notes=notes,
                 format=f"text ({sep_name}, decimal {decimal!r}, {where}"
                        f"{', units row' if unit_row else ''})", repeated=repeated)


def _refuse_ragged(name: str, lines: list[str], start: int, sep: str | None, named: int,
                   width: int) -> None:
    """Refuse rows wider than a header whose width most data rows share.

    Without this the widest row sets the width, the header no longer matches it and the
    file reads as headerless ("no time column"), which names the wrong problem.
    """
    rows = [(start + 1 + i, len(_fields(line, sep))) for i, line in enumerate(lines[start:])
            if line.strip() and not _is_comment(line)]  # (1-based line, fields)
    if named not in (width_ for _, width_ in rows):
        return  # every row is wider: unnamed columns, read by index as before
    wide = [number for number, width_ in rows if width_ > named]
    raise FileFormatError(
        f"{name}: the header names {named} columns but line {wide[0]}"
        f"{f' (and {len(wide) - 1} more of the first {len(lines)} lines)' if len(wide) > 1 else ''}"
        f" has up to {width} fields; delete the extra fields of those rows, or name every "
        "column in the header")


#: First fields that label a header line rather than name a column (instrument exports:
#: NI DIAdem/SignalExpress ``Channel name``/``Unit`` lines, DEWESoft, HBM catman).
_NAME_LABELS = ("channel name", "channel names", "channel", "channels", "name", "names",
                "kanal", "kanalname", "signal", "signal name", "variable", "quantity")
_UNIT_LABELS = ("unit", "units", "unit string", "einheit", "einheiten", "dimension")
_OTHER_LABELS = ("description", "comment", "comments", "data type", "datatype", "type",
                 "channel type", "display type", "group name", "group", "beschreibung",
                 "kommentar", "minimum", "maximum", "min", "max", "wf_increment",
                 "wf_start_offset", "wf_samples", "sample rate", "samples", "x dimension",
                 "delta x", "x0", "t0", "dt", "date", "time stamp", "start time", "offset")


def _row_label(parts: list[str], width: int) -> tuple[str | None, list[str]]:
    """Split a leading ``Channel name`` / ``Unit`` label off a header line.

    Returns ``("name" | "unit" | "other" | None, fields)``: with a label and one field more
    than the data rows, the label is dropped; with as many fields, the label's column gets
    no name (or no unit) from this line. ``"other"``: another labelled line of the header
    block (``Description``, ``Data type``), skipped.
    """
    if not parts or len(parts) not in (width, width + 1):
        return None, parts
    first = parts[0].strip().rstrip(":").strip().lower()
    kind = "name" if first in _NAME_LABELS else "unit" if first in _UNIT_LABELS else (
        "other" if first in _OTHER_LABELS and len(parts) == width + 1 else None)
    if kind is None:
        return None, parts
    rest = parts[1:] if len(parts) == width + 1 else [""] + parts[1:]
    if not any(p.strip() for p in rest):
        return None, parts
    return kind, rest


def _metadata_pair(preamble: list[str], sep: str | None, decimal: str) -> dict[str, str]:
    """``{name: value}`` from a line of names followed by a line of as many numbers."""
    body = [line for line in preamble if line.strip() and not _is_comment(line)]
    if len(body) < 2:
        return {}
    # a one-column data block fits any delimiter: split the pair by its own
    for split in dict.fromkeys((sep, ",", ";", "\t", None)):
        names, values = _fields(body[-2], split), _fields(body[-1], split)
        if (len(names) == len(values) and not _numeric(names, decimal)
                and _numeric(values, decimal)):
            return {n.strip(): v.strip() for n, v in zip(names, values, strict=True)
                    if n.strip()}
    return {}
