"""Reading a drive record: the channels of each body and the input from one table.

Channels are named as ``driveid simulate drive`` writes them (``x1``, ``v1``, ``x2`` ... and
``command`` or ``u``); other column names are mapped with ``channels``.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

from driveid.errors import FileFormatError
from driveid.identify.drive._drive_model import DriveRecord

__all__ = ["read_drive_record"]


def read_drive_record(path: str | Path, *, read_kwargs: Mapping[str, Any] | None = None,
                       time_column: str | int | None = None,
                       channels: dict[str, str] | None = None,
                       input_column: str | None = None, n_bodies: int) -> DriveRecord:
    """Read one drive record: channels ``x1``, ``v1`` ... of each body and the input.

    Parameters
    ----------
    path : str or Path
        The table (CSV and the other formats :func:`driveid.io.read_table` reads).
    read_kwargs : mapping, optional
        Keywords of :func:`driveid.io.read_record` (window [s], scale, units, jitter, encoder
        counts); ``columns`` is set here.
    time_column : str or int, optional
        Time column when it is not found by name.
    channels : dict of str to str, optional
        Channel (``x2``) -> file column, for columns not named as ``simulate drive`` writes.
    input_column : str, optional
        File column of the input torque or force (default ``command`` or ``u`` if present).
    n_bodies : int
        Bodies of the drive (channels of other bodies are ignored).

    Returns
    -------
    DriveRecord
        Time [s], the channels [m or rad, m/s or rad/s] and the input [N or N·m].

    Raises
    ------
    FileFormatError
        If the file has no channel of the drive.
    """
    from driveid.io import read_record
    from driveid.io.tables import read_table

    path = Path(path)
    channels = dict(channels or {})
    kwargs = dict(read_kwargs or {})
    table = read_table(path)
    names = set(table.columns)
    mapping = {}
    for i in range(1, n_bodies + 1):
        for kind in ("x", "v"):
            ch = f"{kind}{i}"
            column = channels.get(ch, ch if ch in names else None)
            if column is not None:
                mapping[ch] = column
    ucol = input_column or next((c for c in ("command", "u") if c in names), None)
    bodies = sorted({int(ch[1:]) for ch in mapping})
    if not any(ch.startswith("x") for ch in mapping):
        raise FileFormatError(f"{path.name}: no position channel of the drive (x1 ... "
                              f"x{n_bodies}); name one with --channel x1=COLUMN; got "
                              f"columns {sorted(names)}")
    chans, t, u, meta = {}, None, None, {}
    for i in bodies:
        cols = {}
        if time_column is not None:
            cols["t"] = time_column
        x_col = mapping.get(f"x{i}")
        if x_col is None:
            continue  # a velocity alone is read with its body's position only
        cols["x"] = x_col
        if f"v{i}" in mapping:
            cols["v"] = mapping[f"v{i}"]
        if ucol is not None:
            cols["u"] = ucol
        rec = read_record(path, **{**kwargs, "columns": cols})
        t, meta = rec.t, dict(rec.meta)
        chans[f"x{i}"] = rec.x
        if rec.v is not None and "v" in cols:
            chans[f"v{i}"] = rec.v
        if rec.u is not None and ucol is not None:
            u = rec.u
    return DriveRecord(t=t, channels=chans, u=u, meta=meta)
