"""Read and write :class:`Record` files: CSV (with units in the header), NPZ and MATLAB .mat.

CSV layout written by driveid::

    # driveid record
    # meta: {"plant": "testbed-a", "P": 1.5, ...}
    t [s],x [rad],u [N·m]
    0.0,0.1,0.0
    ...

Reading accepts far more than driveid writes: every format of :mod:`driveid.io.tables`,
column choice, header units in every spelling (converted to SI, :mod:`driveid.io.units`),
windows and scales; the pipeline is :mod:`driveid.io.reading`. An unknown unit is an
error, never ignored.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from driveid._json import to_jsonable
from driveid.errors import FileFormatError
from driveid.io.record import Record
from driveid.io.safe_write import atomic_open, atomic_save, check_destination
from driveid.io.units import UNIT_CONVERSIONS

__all__ = ["read_record", "write_record", "ensure_writable", "SUFFIXES", "UNIT_CONVERSIONS"]

#: File suffixes understood by :func:`read_record` and :func:`write_record`.
SUFFIXES = (".csv", ".npz", ".mat")


def ensure_writable(path: str | Path, *, overwrite: bool = False) -> Path:
    """Return ``path`` as a Path after checking that writing it loses nothing.

    A symbolic link at ``path`` (even a dangling one) counts as an existing file and is
    never followed; see :mod:`driveid.io.safe_write`.

    Parameters
    ----------
    path : str or Path
        Destination file.
    overwrite : bool
        Allow replacing an existing file (or the link itself, never its target).

    Returns
    -------
    Path
        The destination, with its parent folder created.

    Raises
    ------
    OverwriteError
        If something exists at ``path`` and ``overwrite`` is False.
    IsADirectoryError
        If ``path`` is a folder.
    """
    path = check_destination(path, overwrite=overwrite)
    path.parent.mkdir(parents=True, exist_ok=True)
    return path


def write_record(record: Record, path: str | Path, *, overwrite: bool = False) -> Path:
    """Write a record as CSV, NPZ or MATLAB .mat, chosen by the file suffix.

    The file is written under a temporary name in the same folder and renamed when
    complete (:func:`driveid.io.safe_write.atomic_open`): an interrupted write leaves no
    partial file, and a symbolic link at ``path`` is replaced (with ``overwrite``), never
    written through.

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
    check_destination(path, overwrite=overwrite)
    meta_json = json.dumps(to_jsonable(dict(record.meta)))
    columns = record.columns
    if suffix == ".csv":
        header = ",".join(f"{c} [{record.units.get(c, '')}]" for c in columns)
        data = np.column_stack([getattr(record, c) for c in columns])
        with atomic_open(path, "w", overwrite=overwrite, newline="\n") as fh:
            fh.write("# driveid record\n")
            fh.write(f"# meta: {meta_json}\n")
            fh.write(header + "\n")
            np.savetxt(fh, data, delimiter=",", fmt="%.17g")
    elif suffix == ".npz":
        arrays = {c: getattr(record, c) for c in columns}
        atomic_save(path, lambda fh: np.savez(fh, meta=np.array(meta_json), **arrays),
                    overwrite=overwrite)
    else:
        from scipy.io import savemat

        arrays = {c: np.asarray(getattr(record, c)).reshape(-1, 1) for c in columns}
        atomic_save(path, lambda fh: savemat(fh, {**arrays, "driveid_meta": meta_json}),
                    overwrite=overwrite)
    return path


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
) -> Record:
    """Read a record from any supported file (see :func:`driveid.io.reading.read_record`).

    Parameters
    ----------
    path : str or Path
        The file: delimited text, JSON, .mat (v5, v7.3), .npz, Parquet, HDF5 or TDMS.
    columns : mapping, optional
        Record column -> file column (name, 0-based index or ``VAR:INDEX``).
    fs : float, optional
        Sample rate [Hz] for files without a time column.
    window : tuple of (float or None, float or None), optional
        Keep ``t0 <= t <= t1`` [s].
    max_jitter : float or None
        Largest relative deviation of a sampling interval [-]; ``None`` accepts any
        increasing timeline.
    scale : mapping, optional
        Record column -> factor (number, expression such as ``"0.02/60"``, or a scalar
        variable of the file).
    units : mapping, optional
        Record column -> unit, stating or overriding the file's.
    counts_per_rev : float, optional
        Encoder counts per revolution [1/rev], for positions in counts.
    counts_per_metre : float, optional
        Encoder counts per metre [1/m], for positions in counts.
    sign_magnitude : mapping, optional
        Record column -> register width [bits] of a sign-magnitude integer column.
    position : bool
        False accepts a speed-only file (position integrated from the velocity).

    Returns
    -------
    Record
        The validated record in SI units, provenance in ``meta``; ``meta["notes"]`` shows
        each column chosen by convention and each unit assumed.

    Raises
    ------
    FileNotFoundError
        If the file does not exist.
    FileFormatError
        If the file cannot be parsed or a column, unit or scale is unknown.
    RecordError
        If the data break a rule of :class:`Record`.
    """
    from driveid.io.reading import read_record as _read

    return _read(path, columns=columns, fs=fs, window=window, max_jitter=max_jitter,
                 scale=scale, units=units, counts_per_rev=counts_per_rev,
                 counts_per_metre=counts_per_metre, sign_magnitude=sign_magnitude,
                 position=position, record_type=Record)
