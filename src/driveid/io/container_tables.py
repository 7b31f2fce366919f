"""Readers of structured containers into a :class:`~driveid.io.table_type.Table`.

JSON, MATLAB ``.mat`` (v4-v7.3), ``.npz``, HDF5, Parquet and TDMS: a matrix variable
``data`` becomes the columns ``data:0``, ``data:1`` … along its shorter axis; structs and
nested objects give dotted names. Called by :func:`driveid.io.tables.read_table`.
"""

from __future__ import annotations

import json
import zipfile
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from driveid.errors import FileFormatError
from driveid.io.table_type import Table, table_from_dataframe, unique_name
from driveid.io.units import split_header

__all__ = ["CONTAINER_READERS"]


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
            key = unique_name(base, self.columns)
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
    except RecursionError:  # issue 28, campaign 4: was an internal error
        raise FileFormatError(
            f"{path.name}: JSON nested thousands of levels deep, which no record needs (a "
            "record is columns of numbers, or rows of them); export the data again") from None
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
    try:
        return _hdf5_table(path, matlab)
    except RuntimeError as exc:  # a soft link that loops (issue 28, campaign 4)
        raise FileFormatError(
            f"{path.name}: its HDF5 links cannot be followed ({exc}); save the datasets "
            "without soft or external links that point back at each other") from None


def _hdf5_table(path: Path, matlab: bool) -> Table:
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


#: Suffix -> reader of a structured container.
CONTAINER_READERS = {".json": _read_json, ".mat": _read_mat, ".npz": _read_npz,
                     ".parquet": _read_parquet, ".pq": _read_parquet, ".h5": _read_hdf5,
                     ".hdf5": _read_hdf5, ".hdf": _read_hdf5, ".tdms": _read_tdms}
