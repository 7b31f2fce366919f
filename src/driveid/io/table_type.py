"""The :class:`Table` every reader of :mod:`driveid.io.tables` returns.

A file's numeric columns, their units as stated, scalars and the file's own metadata,
before any choice of record columns or units; :func:`table_from_dataframe` builds one from
a pandas DataFrame.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from driveid.io.units import split_header

__all__ = ["Table", "table_from_dataframe", "unique_name"]


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


def unique_name(name: str, taken: Mapping[str, Any]) -> str:
    """Return ``name``, or ``name.1``, ``name.2`` … where ``taken`` has it (pandas' way).

    Parameters
    ----------
    name : str
        A column name as the file gives it.
    taken : mapping
        The names already given.

    Returns
    -------
    str
        A name not in ``taken``.
    """
    if name not in taken:
        return name
    k = 1
    while f"{name}.{k}" in taken:
        k += 1
    return f"{name}.{k}"


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
        unique = unique_name(name, columns)
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
