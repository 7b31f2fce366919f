"""Reading a drive record: the channels of each body and the input from one table.

Channels are named as ``driveid simulate drive`` writes them (``x1``, ``v1``, ``x2`` ... and
``command`` or ``u``); other column names are mapped with ``channels``.

The drive fit simulates at one fixed rate, so a record is put on a uniform clock here: a
clock within ``max_jitter`` of uniform (a crystal a little slow, timestamps rounded) is
interpolated onto its median interval without a word; a jittered one that the reading
accepted (``--max-jitter none``) too, with a warning that says what was done (issue 24
item 5: resample and warn; before, the fit refused every clock not uniform to 1e-6).
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from driveid.errors import FileFormatError
from driveid.identify.drive._drive_model import DriveRecord
from driveid.io.record import resample_linearly

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
        Keywords of :func:`driveid.io.read_record` (window [s], scale, units, encoder
        counts); ``columns`` is set here. ``max_jitter`` [-] (default 0.01) is the largest
        relative interval deviation accepted (read_record refuses more) and resampled
        without a warning; with None any increasing clock is accepted and, beyond 1 %,
        resampled with a :class:`~driveid.errors.RecordWarning`.
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
        Time [s] on a uniform clock, the channels [m or rad, m/s or rad/s] and the input
        [N or N·m]; ``meta["resampled"]`` says when the clock was made uniform.

    Raises
    ------
    FileFormatError
        If the file has no channel of the drive, or ``channels`` names one it lacks.

    Warns
    -----
    RecordWarning
        When a clock jittered beyond ``max_jitter`` was resampled.
    """
    from driveid.io import read_record
    from driveid.io.tables import read_table

    path = Path(path)
    channels = dict(channels or {})
    valid = {f"{kind}{i}" for i in range(1, n_bodies + 1) for kind in ("x", "v")}
    unknown = sorted(set(channels) - valid)
    if unknown:  # issue 28: --channel x9=... on a one-body drive was silently ignored
        raise FileFormatError(
            f"channel(s) {unknown} name no body of this {n_bodies}-body drive; name x1 ... "
            f"x{n_bodies} or v1 ... v{n_bodies} (--channel x1=COLUMN)")
    kwargs = dict(read_kwargs or {})
    tolerance = kwargs.get("max_jitter", 0.01)
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
    used, units = {}, {}  # provenance of every channel (result "inputs", issue 28)
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
        read_as = dict(meta.get("columns_used") or {})
        for kind in ("t", "x", "v", "u"):
            name = f"{kind}{i}" if kind in ("x", "v") else kind
            if kind in read_as and (kind != "v" or "v" in cols) and (kind != "u" or ucol):
                used[name] = read_as[kind]
                if kind in rec.units:
                    units[name] = rec.units[kind]
        if rec.v is not None and "v" in cols:
            chans[f"v{i}"] = rec.v
        if rec.u is not None and ucol is not None:
            u = rec.u
    reading = {k: v for k, v in dict(meta.get("reading") or {}).items() if k != "columns"}
    meta = {**{k: v for k, v in meta.items() if k != "reading"}, "columns_used": used,
            "units": units, **({"reading": reading} if reading else {})}
    t, chans, u, meta = _uniform_clock(path, t, chans, u, meta, tolerance)
    return DriveRecord(t=t, channels=chans, u=u, meta=meta)


def _uniform_clock(path: Path, t: np.ndarray, chans: dict[str, np.ndarray],
                   u: np.ndarray | None, meta: dict[str, Any],
                   tolerance: float | None) -> tuple:
    """Interpolate the record onto ``t0 + k·dt`` (median ``dt``) unless it is uniform."""
    steps = np.diff(t)  # positive: read_record refuses a clock that goes back
    dt = float(np.median(steps))
    jitter = float(np.max(np.abs(steps - dt))) / dt
    if jitter <= 1e-6:
        return t, chans, u, meta
    # a clock within the tolerance is put on the grid silently: the simulator needs it exact
    loud = jitter > (0.01 if tolerance is None else tolerance)
    columns = dict(chans) if u is None else {**chans, "u": u}
    grid, columns = resample_linearly(
        t, columns, dt=dt, jitter=jitter, source=f"{path.name}: ", stacklevel=3,
        purpose="the drive fit, which simulates at a fixed rate," if loud else None)
    u = columns.pop("u", None)
    chans = columns
    meta = {**meta, "resampled": {"from_jitter": jitter, "fs": 1 / dt}}
    return grid, chans, u, meta
