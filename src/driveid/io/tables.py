"""Raw column reading of measured traces in the formats drive engineers bring.

:func:`read_table` turns a file into a :class:`Table`: named one-dimensional numeric columns
(a matrix variable ``data`` of a .mat, .npz, JSON or HDF5 file becomes the columns
``data:0``, ``data:1`` ... along its shorter axis, 0-based), the unit of each column as
stated in the file, scalars, and the driveid metadata of files driveid wrote. It knows
nothing of records: choosing columns, converting units and validating is
:func:`driveid.io.read_record`'s work.

Formats (chosen by suffix):

- delimited text (``.csv .txt .dat .tsv .asc .prn``), read with :func:`pandas.read_csv`:
  delimiter sniffed among ``,`` ``;`` tab and whitespace, decimal comma detected, BOM,
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
import json
import re
import zipfile
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from driveid.errors import FileFormatError
from driveid.io.units import known_unit as _known_unit
from driveid.io.units import normalise_unit, split_header

__all__ = ["Table", "read_table", "table_from_dataframe", "refuse_non_file", "READABLE_SUFFIXES"]

_TEXT = (".csv", ".txt", ".dat", ".tsv", ".asc", ".prn")
#: File suffixes :func:`read_table` reads.
READABLE_SUFFIXES = (*_TEXT, ".json", ".mat", ".npz", ".parquet", ".pq", ".h5", ".hdf5",
                     ".hdf", ".tdms")
_SAMPLE_LINES = 400


@dataclass
class Table:
    """Numeric columns of one file, before any choice of record columns or units.

    Attributes
    ----------
    columns : dict of str to ndarray
        Column name -> values, shape (n,), in file order.
    units : dict of str to str
        Column name -> unit as stated in the file (canonical spelling).
    scalars : dict of str to float
        Scalar variables of the file (gains such as ``gtau``) [their own units].
    meta : dict
        Metadata stored by driveid in files it wrote (``# meta:`` line, ``meta`` array).
    fs : float or None
        Sample rate stated by the file itself [Hz] (TDMS ``wf_increment``, a preamble line).
    t0 : float
        Time of the first sample when ``fs`` is used [s].
    format : str
        What was read, e.g. ``"csv (';', decimal ',')"`` or ``"mat v7.3"``.
    notes : dict
        Preamble metadata found above the header (key -> text).
    repeated : dict of str to list of str
        A header name the file repeats -> the column names it was given (``pos``,
        ``pos.1`` ...): asking for that name is ambiguous.
    precision : dict of str to str
        Column name -> the narrow float type it was stored in (``"float16"``,
        ``"float32"``); columns read as float64 (all text) are not listed.
    """

    columns: dict[str, np.ndarray]
    units: dict[str, str] = field(default_factory=dict)
    scalars: dict[str, float] = field(default_factory=dict)
    meta: dict[str, Any] = field(default_factory=dict)
    fs: float | None = None
    t0: float = 0.0
    format: str = ""
    notes: dict[str, str] = field(default_factory=dict)
    repeated: dict[str, list[str]] = field(default_factory=dict)
    precision: dict[str, str] = field(default_factory=dict)

    @property
    def rows(self) -> int:
        """Number of samples of the longest column [-]."""
        return max((c.size for c in self.columns.values()), default=0)


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
    readers = {".json": _read_json, ".mat": _read_mat, ".npz": _read_npz,
               ".parquet": _read_parquet, ".pq": _read_parquet, ".h5": _read_hdf5,
               ".hdf5": _read_hdf5, ".hdf": _read_hdf5, ".tdms": _read_tdms}
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


def table_from_dataframe(df: Any, *, source: str = "dataframe") -> Table:
    """Return the numeric columns of a :class:`pandas.DataFrame` as a :class:`Table`.

    Parameters
    ----------
    df : pandas.DataFrame
        One column per quantity; headers may carry units (``"x [mm]"``).
    source : str
        Name for messages.

    Returns
    -------
    Table
        Columns under their names without unit, units from the headers.
    """
    columns: dict[str, np.ndarray] = {}
    units: dict[str, str] = {}
    repeated: dict[str, list[str]] = {}
    precision: dict[str, str] = {}
    for header in df.columns:
        name, unit = split_header(str(header))
        unique = _unique(name, columns)
        if unique != name:
            repeated.setdefault(name, [name]).append(unique)
        name = unique
        values = df[header].to_numpy()
        if values.dtype.kind in "biuf":
            columns[name] = values.astype(float)
            if values.dtype.kind == "f" and values.dtype.itemsize < 8:
                precision[name] = values.dtype.name
        else:
            columns[name] = values  # checked when chosen: a text column may go unused
        if unit:
            units[name] = unit
    return Table(columns=columns, units=units, format=source, repeated=repeated,
                 precision=precision)


# -- delimited text -----------------------------------------------------------------------
_CANDIDATES = ((";", ","), (";", "."), ("\t", ","), ("\t", "."), (",", "."), (None, "."),
               (None, ","))
_COMMENT = ("#", "%", "//")
_RATE = re.compile(r"(sampl\w*\s*(rate|freq\w*)|fs|abtastrate)\W+([0-9.eE+-]+)\s*(k?hz)?",
                   re.IGNORECASE)


def _lines(path: Path) -> tuple[list[str], str]:
    for encoding in ("utf-8-sig", "cp1252", "latin-1"):
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
    parts = line.split() if sep is None else [f.strip().strip('"') for f in line.split(sep)]
    while parts and not parts[-1]:
        parts.pop()  # trailing empty columns (a delimiter at the end of every row)
    return parts


_TIMESTAMP = re.compile(r"^(\d{4}-\d\d-\d\d[ T])?\d{1,2}:\d\d:\d\d([.,]\d+)?Z?$")


def _numeric(parts: list[str], decimal: str) -> bool:
    if not parts:
        return False
    for part in parts:
        if not part:
            continue
        try:
            float(part.replace(",", ".") if decimal == "," else part)
        except ValueError:
            if not _TIMESTAMP.match(part):
                return False
    return True


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
            stamps = pd.to_datetime(text, format="mixed")
            return (stamps - stamps.iloc[0]).dt.total_seconds().to_numpy(dtype=float)
        deltas = pd.to_timedelta(text)
        return (deltas - deltas.iloc[0]).dt.total_seconds().to_numpy(dtype=float)
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
            if _numeric(parts, decimal):
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
        if unit_row is None and len(parts) <= width and _is_unit_row(parts):
            unit_row = parts + [""] * (width - len(parts))
            used.add(index)
            continue
        if len(parts) == width:
            header = parts
            used.add(index)
        break
    if header is None and unit_row is not None:
        header, unit_row = unit_row, None  # a header whose names all look like units
    try:
        frame = pd.read_csv(path, sep=r"\s+" if sep is None else sep, decimal=decimal,
                            header=None, skiprows=start, comment="#", encoding=encoding,
                            engine="python" if sep is None else "c", skip_blank_lines=True,
                            usecols=range(width), names=list(range(width)))
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
        unique = _unique(name or str(i), columns)
        if unique != (name or str(i)):
            repeated.setdefault(name, [name]).append(unique)
        name = unique
        values = pd.to_numeric(frame[i], errors="coerce").to_numpy(dtype=float)
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


# -- structured containers ----------------------------------------------------------------
def _unique(name: str, taken: Mapping[str, Any]) -> str:
    if name not in taken:
        return name
    k = 1
    while f"{name}.{k}" in taken:
        k += 1
    return f"{name}.{k}"


class _Collector:
    """Flatten nested containers into named columns, matrices as ``NAME:INDEX``."""

    def __init__(self) -> None:
        self.columns: dict[str, np.ndarray] = {}
        self.units: dict[str, str] = {}
        self.scalars: dict[str, float] = {}
        self.precision: dict[str, str] = {}

    def array(self, name: str, value: Any, unit: str | None = None,
              transposed: bool = False) -> None:
        arr = np.asarray(value)
        if arr.dtype.names:  # compound (HDF5 table, structured array)
            for sub in arr.dtype.names:
                self.array(f"{name}.{sub}" if name else sub, arr[sub])
            return
        if arr.dtype.kind not in "biuf":
            return
        if transposed:
            arr = arr.T
        if arr.ndim != 1:
            arr = np.squeeze(arr)  # (a 1-D array stays itself, not a view)
        base, split_unit = split_header(name) if name else (name, None)
        unit = unit or split_unit
        if arr.ndim == 0:
            self.scalars[base] = float(arr)
        elif arr.ndim == 1:
            # a fresh float column (np.load, h5py) is kept, not copied (8 B a sample)
            key = _unique(base, self.columns)
            self.columns[key] = arr.astype(float, copy=False)
            if unit:
                self.units[base] = unit
            if arr.dtype.kind == "f" and arr.dtype.itemsize < 8:
                self.precision[key] = arr.dtype.name
        elif arr.ndim == 2:
            if arr.shape[0] < arr.shape[1]:
                arr = arr.T  # samples along the longer axis
            for i in range(arr.shape[1]):
                self.columns[f"{base}:{i}"] = arr[:, i].astype(float)
                if unit:
                    self.units[f"{base}:{i}"] = unit
                if arr.dtype.kind == "f" and arr.dtype.itemsize < 8:
                    self.precision[f"{base}:{i}"] = arr.dtype.name

    def nested(self, prefix: str, node: Any) -> None:
        join = (lambda k: f"{prefix}.{k}") if prefix else (lambda k: str(k))
        if isinstance(node, Mapping):
            values = next((node[k] for k in ("values", "data", "value") if k in node), None)
            unit = next((node[k] for k in ("unit", "units") if isinstance(node.get(k), str)),
                        None)
            if values is not None and unit is not None and prefix:
                self.array(prefix, _as_array(values), unit=split_header(f"x [{unit}]")[1])
                return
            side_units = node.get("units") if isinstance(node.get("units"), Mapping) else {}
            for key, value in node.items():
                if key == "units" and side_units:
                    continue
                if isinstance(value, str):
                    if str(key).lower().endswith(("_unit", "_units")):
                        side_units = {**side_units, str(key).rsplit("_", 1)[0]: value}
                    continue
                self.nested(join(key), value)
            for key, unit in side_units.items():
                name = join(key)
                if isinstance(unit, str) and unit.strip():
                    canon = split_header(f"x [{unit}]")[1]
                    for col in self.columns:
                        if col == name or col.startswith(f"{name}:"):
                            self.units[col] = canon
        elif isinstance(node, list) and node and all(isinstance(r, Mapping) for r in node):
            keys = list(dict.fromkeys(k for r in node for k in r))
            for key in keys:
                self.nested(join(key), [r.get(key, np.nan) for r in node])
        else:
            arr = _as_array(node)
            if arr is not None:
                self.array(prefix, arr)

    def table(self, **kwargs: Any) -> Table:
        units = {k: v for k, v in self.units.items() if k in self.columns}
        return Table(columns=self.columns, units=units, scalars=self.scalars,
                     precision=self.precision, **kwargs)


def _as_array(value: Any) -> np.ndarray | None:
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return np.asarray(float(value))
    if isinstance(value, np.ndarray):
        return value
    if isinstance(value, list):
        try:
            arr = np.asarray([np.nan if v is None else v for v in value] if value and not
                             isinstance(value[0], list) else value, dtype=float)
        except (TypeError, ValueError):
            return None
        return arr
    return None


def _read_json(path: Path) -> Table:
    try:
        with open(path, encoding="utf-8-sig") as fh:
            obj = json.load(fh)
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise FileFormatError(f"{path.name}: not valid JSON ({exc})") from None
    collector = _Collector()
    meta = {}
    if isinstance(obj, Mapping) and isinstance(obj.get("meta"), Mapping):
        meta = dict(obj["meta"])
        obj = {k: v for k, v in obj.items() if k != "meta"}
    rows_of_numbers = isinstance(obj, list) and not all(isinstance(r, Mapping) for r in obj)
    collector.nested("data" if rows_of_numbers else "", obj)  # a bare matrix: data:INDEX
    return collector.table(meta=meta, format="json")


def _read_npz(path: Path) -> Table:
    collector = _Collector()
    meta: dict[str, Any] = {}
    try:
        with np.load(path, allow_pickle=False) as npz:
            for key in npz.files:
                if key == "meta":
                    meta = json.loads(str(npz["meta"]))
                else:
                    collector.array(key, _npz_array(npz, key))
    except (ValueError, OSError, EOFError, zipfile.BadZipFile) as exc:
        raise FileFormatError(f"{path.name}: cannot read as .npz ({exc})") from None
    return collector.table(meta=meta, format="npz")


def _npz_array(npz: Any, key: str) -> Any:
    """Read one array of an open .npz into an array that owns its memory.

    ``npz[key]`` returns a view (``base`` set), which a :class:`Record` must copy: 8 B a
    sample more at the peak. Plain numeric arrays are read straight into ``np.empty`` in
    1 MB pieces instead; anything else (object arrays, format 3.0 headers, scalars, raw
    bytes) goes through numpy's own reader and its checks.
    """
    fmt = np.lib.format
    names = npz.zip.namelist()
    member = key if key in names else f"{key}.npy"
    if member not in names:
        return npz[key]
    with npz.zip.open(member) as fh:
        try:
            version = fmt.read_magic(fh)
        except ValueError:
            return npz[key]
        header = {(1, 0): fmt.read_array_header_1_0, (2, 0): fmt.read_array_header_2_0}
        if version not in header:
            return npz[key]
        shape, fortran, dtype = header[version](fh)
        if dtype.hasobject or dtype.itemsize == 0 or len(shape) == 0 or 0 in shape:
            return npz[key]
        arr = np.empty(shape, dtype, order="F" if fortran else "C")
        flat = memoryview(arr.T if fortran else arr).cast("B")
        done = 0
        while done < flat.nbytes:
            got = fh.readinto(flat[done:done + (1 << 20)])
            if not got:
                raise ValueError(f"array {key!r} is truncated ({done} of {flat.nbytes} bytes)")
            done += got
    return arr


def _read_mat(path: Path) -> Table:
    with open(path, "rb") as fh:
        head = fh.read(128)
    if b"MATLAB 7.3" in head or head.startswith(b"\x89HDF"):
        return _read_hdf5(path, matlab=True)
    from scipy.io import loadmat
    from scipy.io.matlab import MatReadError

    try:
        raw = loadmat(path, simplify_cells=True)
    except NotImplementedError:
        return _read_hdf5(path, matlab=True)
    except (ValueError, TypeError, OSError, IndexError, EOFError, KeyError, MatReadError):
        # scipy raises IndexError/KeyError on a garbled header: a damaged file, not a bug
        raise FileFormatError(_not_mat(path, head)) from None
    collector = _Collector()
    meta: dict[str, Any] = {}
    for key, value in raw.items():
        if key.startswith("__"):
            continue
        if key == "driveid_meta":
            meta = json.loads(str(np.asarray(value).ravel()[0]))
            continue
        if isinstance(value, dict):
            collector.nested(key, value)
        else:
            collector.array(key, value)
    return collector.table(meta=meta, format="mat v5")


def _not_mat(path: Path, head: bytes) -> str:
    """Say why a ``.mat`` file scipy cannot read is none (text, no header) or damaged."""
    fix = "save it in MATLAB with save(FILE, '-v7') or '-v7.3'"
    if not head:
        return f"{path.name} is empty, not a MATLAB .mat file; {fix}"
    try:
        start = head.decode("utf-8")
    except UnicodeDecodeError:  # also a multi-byte character cut at byte 128: not text
        start = None
    if start is not None and all(c.isprintable() or c in "\r\n\t" for c in start):
        # issue 28: said '(IndexError)'
        return (f"{path.name} is text, not a MATLAB .mat file (a .mat file is binary with a "
                "'MATLAB 5.0 MAT-file' header); if it holds delimited columns, rename it to "
                f".csv; otherwise {fix}")
    if head[126:128] not in (b"IM", b"MI"):
        return (f"{path.name} is not a MATLAB .mat file: it has no MAT-file header (another "
                f"format named .mat?); {fix}")
    return (f"{path.name} has a MATLAB .mat header but its contents cannot be read (damaged "
            f"or cut short); {fix}")


def _read_hdf5(path: Path, matlab: bool = False) -> Table:
    import h5py

    collector = _Collector()
    meta: dict[str, Any] = {}
    try:
        fh = h5py.File(path, "r")
    except OSError as exc:
        raise FileFormatError(f"{path.name}: cannot read as HDF5 ({exc})") from None
    with fh:
        if not matlab and _pandas_frames(fh, collector):
            return collector.table(format="hdf5 (pandas fixed format)")

        def visit(name: str, obj: Any) -> None:
            if not isinstance(obj, h5py.Dataset) or name.startswith("#refs#"):
                return
            if matlab and obj.attrs.get("MATLAB_class", b"") in (b"char", b"cell"):
                if name == "driveid_meta":
                    meta.update(json.loads(bytes(np.asarray(obj[()], dtype=np.uint16)
                                                 .ravel().astype(np.uint8)).decode()))
                return
            unit = obj.attrs.get("unit", obj.attrs.get("units"))
            if isinstance(unit, bytes):
                unit = unit.decode()
            label = name.replace("/", ".") if matlab else name
            collector.array(label, obj[()], unit=split_header(f"x [{unit}]")[1]
                            if isinstance(unit, str) and unit else None, transposed=matlab)

        fh.visititems(visit)
    return collector.table(meta=meta, format="mat v7.3 (HDF5)" if matlab else "hdf5")


def _pandas_frames(fh: Any, collector: _Collector) -> bool:
    found = False
    for group in fh.values():
        if not hasattr(group, "attrs") or group.attrs.get("pandas_type") not in (b"frame",
                                                                                 "frame"):
            continue
        k = 0
        while f"block{k}_items" in group:
            items = [i.decode() if isinstance(i, bytes) else str(i)
                     for i in group[f"block{k}_items"][()]]
            values = group[f"block{k}_values"][()]
            for j, item in enumerate(items):
                collector.array(item, values[:, j])
            k += 1
        found = found or k > 0
    return found


def _read_parquet(path: Path) -> Table:
    import pandas as pd

    try:
        frame = pd.read_parquet(path)
    except ImportError as exc:
        raise FileFormatError(
            f"{path.name}: reading Parquet needs pyarrow ({exc}); pip install pyarrow, or "
            "export the trace as CSV") from None
    except (ValueError, OSError) as exc:
        raise FileFormatError(f"{path.name}: cannot read as Parquet ({exc})") from None
    table = table_from_dataframe(frame, source="parquet")
    meta_text = (frame.attrs or {}).get("driveid_meta")
    if isinstance(meta_text, str):
        table.meta = json.loads(meta_text)
    return table


def _read_tdms(path: Path) -> Table:
    try:
        from nptdms import TdmsFile
    except ImportError:
        raise FileFormatError(
            f"{path.name}: reading TDMS needs the optional package npTDMS (pip install "
            "npTDMS); or export the trace from LabVIEW/DIAdem as CSV") from None
    try:
        tdms = TdmsFile.read(path)
    except (ValueError, OSError, KeyError) as exc:
        raise FileFormatError(f"{path.name}: cannot read as TDMS ({exc})") from None
    collector = _Collector()
    fs = None
    t0 = 0.0
    for group in tdms.groups():
        for channel in group.channels():
            data = channel[:]
            if data.dtype.kind not in "biuf":
                continue
            props = channel.properties
            unit = props.get("unit_string") or None
            name = channel.name if channel.name not in collector.columns else (
                f"{group.name}/{channel.name}")
            collector.array(name, data, unit=split_header(f"x [{unit}]")[1] if unit else None)
            increment = props.get("wf_increment")
            if fs is None and increment:
                fs = 1.0 / float(increment)
                t0 = float(props.get("wf_start_offset", 0.0) or 0.0)
    return collector.table(fs=fs, t0=t0, format="tdms")
