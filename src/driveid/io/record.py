"""The :class:`Record`: one experiment's time series, validated at construction."""

from __future__ import annotations

import functools
import warnings
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

import numpy as np

from driveid.errors import RecordError, RecordWarning
from driveid.signal.repair import _interval_blocks, check_timeline, find_corrupted_bursts

__all__ = ["Record", "MIN_SAMPLES", "DEFAULT_UNITS", "needs_uniform_sampling", "record_from_table",
           "resample_linearly"]

#: Fewest samples a record may have [-].
MIN_SAMPLES = 8

#: Units assumed for columns whose unit is not given (the thesis's rotational test bed).
DEFAULT_UNITS = MappingProxyType({"t": "s", "x": "rad", "u": "N·m", "v": "rad/s"})

_COLUMNS = ("t", "x", "u", "v")


@dataclass(frozen=True, eq=False)
class Record:
    """One experiment's time series: time, position, optional force/torque and velocity.

    Parameters
    ----------
    t : array_like, shape (n,)
        Sample times [s], increasing and uniform within ``max_jitter``; n >= 8.
    x : array_like, shape (n,)
        Position [m or rad].
    u : array_like, shape (n,), optional
        Applied force or torque [N or N·m].
    v : array_like, shape (n,), optional
        Velocity [m/s or rad/s].
    meta : mapping, optional
        Free metadata: ``units`` (column -> unit string), ``source``, ``plant``, feedback
        ``P``, ``D``, ``delay``, ``x0_sign`` ... Must be JSON-serialisable to be saved.
    max_jitter : float or None
        Largest relative deviation of a sampling interval from the median [-]; ``None``
        accepts a non-uniform (but increasing) timeline.

    Raises
    ------
    RecordError
        Non-finite values, unsorted or duplicated time, too few samples, columns of unequal
        length, or non-uniform sampling beyond ``max_jitter``.

    Warns
    -----
    RecordWarning
        When a single wrong timestamp was repaired by interpolation (App. B.3.1), or when a
        burst of corrupted samples was found (see :attr:`corrupted`; analyses refuse it).

    Examples
    --------
    >>> rec = Record(t=np.arange(10) * 1e-3, x=np.zeros(10))
    >>> rec.fs, rec.n, rec.units["x"]
    (1000.0, 10, 'rad')
    """

    t: np.ndarray
    x: np.ndarray
    u: np.ndarray | None = None
    v: np.ndarray | None = None
    meta: Mapping[str, Any] = field(default_factory=dict)
    max_jitter: float | None = 0.01

    def __post_init__(self) -> None:
        arrays = {}
        for name in _COLUMNS:
            value = getattr(self, name)
            if value is None:
                if name in ("t", "x"):
                    raise RecordError(f"column {name!r} is required; got None")
                continue
            try:
                if (isinstance(value, np.ndarray) and value.dtype == np.float64
                        and not value.flags.writeable and value.base is None):
                    # read-only and owning its data (the reading pipeline's columns): nobody
                    # can change it, so wrap it instead of copying (10 M samples: -80 MB each)
                    arr = value
                else:
                    arr = np.array(value, dtype=float)
            except (TypeError, ValueError) as exc:
                raise RecordError(
                    f"column {name!r} must be numeric; got {type(value).__name__}: {exc}"
                ) from None
            arr = np.squeeze(arr) if arr.ndim == 2 and 1 in arr.shape else arr
            if arr.ndim != 1:
                raise RecordError(
                    f"column {name!r} must be one-dimensional; got shape {arr.shape}"
                )
            arrays[name] = arr
        n = arrays["t"].size
        for name, arr in arrays.items():
            if arr.size != n:
                raise RecordError(
                    f"column {name!r} has {arr.size} samples but 't' has {n}; "
                    "all columns must have one value per sample"
                )
            if np.isfinite(arr).all():
                continue
            bad = np.flatnonzero(~np.isfinite(arr))
            if bad.size:
                # the file's own column where it was read from one (x1 of a drive record)
                label = dict(self.meta.get("columns_used") or {}).get(name, name)
                raise RecordError(
                    f"column {label!r} has {bad.size} non-finite value(s) (NaN or inf), the "
                    f"first at sample {bad[0]}; drop or interpolate those samples before "
                    "analysis"
                )
        if n < MIN_SAMPLES:
            raise RecordError(
                f"a record needs at least {MIN_SAMPLES} samples; got {n}. Record for longer "
                "or at a higher sampling rate"
            )
        check = check_timeline(arrays["t"], max_jitter=self.max_jitter)
        if check.problem:
            raise RecordError(check.problem)
        if check.repaired:
            warnings.warn(
                f"repaired {len(check.repaired)} wrong timestamp(s) by linear interpolation at "
                f"sample(s) {list(check.repaired)[:10]} (thesis App. B.3.1)",
                RecordWarning,
                stacklevel=3,
            )
        arrays["t"] = check.t
        # the median interval, once: 10 M samples made every ``dt`` a 160 MB, 0.3 s pass
        object.__setattr__(self, "_dt", float(np.median(np.diff(check.t),
                                                        overwrite_input=True)))
        for name, arr in arrays.items():
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)
        meta = dict(self.meta)
        given = dict(meta.get("units", {}))
        units = dict(DEFAULT_UNITS)
        if given.get("x") == "m":  # translational: defaults follow the position unit
            units.update({"u": "N", "v": "m/s"})
        units.update(given)
        meta["units"] = units
        if check.repaired:
            meta["repaired_timestamps"] = list(check.repaired)
        object.__setattr__(self, "meta", MappingProxyType(meta))
        # only position: a force may legitimately step (pulses, Coulomb switching)
        bursts = find_corrupted_bursts(arrays["x"])
        object.__setattr__(self, "_corrupted", tuple(sorted(set(bursts))))
        if bursts:
            spans = ", ".join(f"{self.t[i0]:.4g}-{self.t[i1 - 1]:.4g} s" for i0, i1 in bursts[:5])
            warnings.warn(
                f"found {len(bursts)} burst(s) of corrupted samples ({spans}); analyses refuse "
                "them: crop the record around them (Record.crop) or repeat the experiment",
                RecordWarning,
                stacklevel=3,
            )

    # -- derived properties ---------------------------------------------------------------
    @property
    def n(self) -> int:
        """Number of samples [-]."""
        return int(self.t.size)

    @property
    def dt(self) -> float:
        """Median sampling interval [s]."""
        return self._dt  # type: ignore[attr-defined]

    @property
    def fs(self) -> float:
        """Sampling rate [Hz] (from the median interval)."""
        return float(round(1.0 / self.dt, 9))

    @property
    def duration(self) -> float:
        """Time span ``t[-1] - t[0]`` [s]."""
        return float(self.t[-1] - self.t[0])

    @property
    def units(self) -> Mapping[str, str]:
        """Column -> unit string."""
        return self.meta["units"]

    @property
    def corrupted(self) -> tuple[tuple[int, int], ...]:
        """Half-open index ranges of corrupted bursts found at construction."""
        return self._corrupted  # type: ignore[attr-defined]

    # -- derived records ------------------------------------------------------------------
    def crop(self, t_start: float | None = None, t_stop: float | None = None) -> Record:
        """Return the samples with ``t_start <= t <= t_stop`` as a new record.

        Parameters
        ----------
        t_start, t_stop : float, optional
            Window limits [s]; ``None`` keeps that end.

        Returns
        -------
        Record
            The cropped record (metadata kept).
        """
        lo = -np.inf if t_start is None else t_start
        hi = np.inf if t_stop is None else t_stop
        keep = (self.t >= lo) & (self.t <= hi)
        return self.replace(**{name: getattr(self, name)[keep] for name in self.columns})

    def replace(self, **changes: Any) -> Record:
        """Return a copy with some columns, ``meta`` entries or ``max_jitter`` replaced.

        Parameters
        ----------
        **changes
            ``t``, ``x``, ``u``, ``v``, ``max_jitter`` or ``meta`` (merged into the old meta).

        Returns
        -------
        Record
            The new, re-validated record.
        """
        unknown = set(changes) - set(_COLUMNS) - {"meta", "max_jitter"}
        if unknown:
            raise TypeError(f"Record.replace got unknown field(s) {sorted(unknown)}")
        fields = {name: getattr(self, name) for name in _COLUMNS}
        fields["max_jitter"] = self.max_jitter
        meta = dict(self.meta)
        meta.update(changes.pop("meta", {}))
        fields.update(changes)
        return Record(meta=meta, **fields)

    @classmethod
    def from_dataframe(
        cls,
        df: Any,
        *,
        time: str | int | None = None,
        position: str | int | None = None,
        velocity: str | int | None = None,
        force: str | int | None = None,
        fs: float | None = None,
        window: tuple[float | None, float | None] | None = None,
        max_jitter: float | None = 0.01,
        scale: Mapping[str, float | str] | None = None,
        units: Mapping[str, str] | None = None,
        counts_per_rev: float | None = None,
        counts_per_metre: float | None = None,
        source: str = "dataframe",
    ) -> Record:
        """Build a record from a :class:`pandas.DataFrame`, as :func:`read_record` reads files.

        Parameters
        ----------
        df : pandas.DataFrame
            One column per quantity; headers may carry units (``"x [mm]"``).
        time, position, velocity, force : str or int, optional
            Column name or 0-based index; found by name and alias when omitted.
        fs : float, optional
            Sample rate [Hz] when there is no time column.
        window : tuple of (float or None, float or None), optional
            Keep ``t0 <= t <= t1`` [s].
        max_jitter : float or None
            As for :class:`Record` [-].
        scale : mapping, optional
            Record column -> factor (number or expression such as ``"0.02/60"``).
        units : mapping, optional
            Record column -> unit, stating or overriding the header's.
        counts_per_rev : float, optional
            Encoder counts per revolution [1/rev] for positions in counts.
        counts_per_metre : float, optional
            Encoder counts per metre [1/m] for positions in counts.
        source : str
            Name kept as ``meta["source"]``.

        Returns
        -------
        Record
            The validated record in SI units.

        Examples
        --------
        >>> import pandas as pd
        >>> df = pd.DataFrame({"time [ms]": np.arange(10.0), "pos [mm]": np.arange(10.0)})
        >>> rec = Record.from_dataframe(df)
        >>> rec.fs, round(float(rec.x[-1]), 12), rec.units["x"]
        (1000.0, 0.009, 'm')
        """
        from driveid.io.tables import table_from_dataframe

        columns = {col: spec for col, spec in
                   (("t", time), ("x", position), ("v", velocity), ("u", force))
                   if spec is not None}
        return record_from_table(
            table_from_dataframe(df, source=source), source=source, columns=columns, fs=fs,
            window=window, max_jitter=max_jitter, scale=scale, units=units,
            counts_per_rev=counts_per_rev, counts_per_metre=counts_per_metre, owned=True)

    def jitter(self) -> float:
        """Largest relative deviation of a sampling interval from the median [-]."""
        nominal = self.dt
        # in blocks of intervals: O(block) memory whatever the record's length
        worst = max(float(np.max(np.abs(dt - nominal))) for _, dt in _interval_blocks(self.t))
        return worst / nominal

    def resampled_uniform(self, *, purpose: str = "this analysis",
                          tolerance: float = 0.01) -> Record:
        """Return the record on a uniform timeline, resampled if its jitter exceeds tolerance.

        Parameters
        ----------
        purpose : str
            What needs uniform sampling, named in the warning (e.g. ``"the Hilbert
            transform"``).
        tolerance : float
            Largest relative interval deviation accepted as uniform [-].

        Returns
        -------
        Record
            ``self`` when uniform enough; otherwise a copy linearly interpolated onto
            ``t0 + k·dt`` with the median interval ``dt`` (``meta["resampled"]`` says so).

        Warns
        -----
        RecordWarning
            When resampling, naming the jitter and the new rate.
        """
        jitter = self.jitter()
        if jitter <= tolerance:
            return self
        t, columns = resample_linearly(
            self.t, {name: getattr(self, name) for name in self.columns if name != "t"},
            dt=self.dt, jitter=jitter, purpose=purpose, stacklevel=3)
        return self.replace(t=t, **columns, max_jitter=tolerance,
                            meta={"resampled": {"from_jitter": jitter, "fs": 1 / self.dt}})

    @property
    def columns(self) -> tuple[str, ...]:
        """Names of the columns present, in the order t, x, u, v."""
        return tuple(name for name in _COLUMNS if getattr(self, name) is not None)

    def __repr__(self) -> str:
        cols = ", ".join(self.columns)
        return f"Record(n={self.n}, fs={self.fs:g} Hz, duration={self.duration:g} s, [{cols}])"


def resample_linearly(t: np.ndarray, columns: Mapping[str, np.ndarray], *, dt: float,
                      jitter: float, purpose: str | None, source: str = "",
                      stacklevel: int = 2) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Interpolate columns linearly onto ``t[0] + k·dt`` and warn (unless ``purpose`` is None).

    Parameters
    ----------
    t : ndarray
        Increasing time [s].
    columns : mapping of str to ndarray
        Signals sampled at ``t`` [any unit].
    dt : float
        The uniform interval, the median of the record's [s].
    jitter : float
        The record's largest relative interval deviation, named in the warning [-].
    purpose : str or None
        What needs uniform sampling, named in the warning; None: no warning.
    source : str
        Prefix of the warning (e.g. ``"trace.csv: "``).
    stacklevel : int
        Of the warning, as for :func:`warnings.warn`.

    Returns
    -------
    (ndarray, dict)
        The uniform time [s] (within ``t[0] .. t[-1]``) and the columns on it.
    """
    grid = t[0] + dt * np.arange(int(np.floor((t[-1] - t[0]) / dt + 1e-9)) + 1)
    grid = grid[grid <= t[-1]]
    if purpose is not None:
        warnings.warn(
            f"{source}sampling is not uniform (worst interval {100 * jitter:.3g} % off the "
            f"median); {purpose} needs uniform sampling, so the record was resampled linearly "
            f"to {1 / dt:.6g} Hz; record at a steady rate, or check the timestamps",
            RecordWarning, stacklevel=stacklevel + 1)
    return grid, {name: np.interp(grid, t, values) for name, values in columns.items()}


def needs_uniform_sampling(purpose: str) -> Callable[[Callable[..., Any]], Callable[..., Any]]:
    """Decorate an analysis whose first argument is a Record that must be uniformly sampled.

    A record read with ``max_jitter=None`` (CLI ``--max-jitter none``) is resampled by
    :meth:`Record.resampled_uniform` before the analysis sees it, with a warning naming
    ``purpose``; a uniform record passes unchanged.

    Parameters
    ----------
    purpose : str
        What needs uniform sampling, e.g. ``"the Hilbert transform"``.

    Returns
    -------
    callable
        The decorator.
    """

    def decorate(func: Callable[..., Any]) -> Callable[..., Any]:
        @functools.wraps(func)
        def wrapper(*args: Any, **kwargs: Any) -> Any:
            if args and isinstance(args[0], Record):
                args = (args[0].resampled_uniform(purpose=purpose), *args[1:])
            elif isinstance(kwargs.get("record"), Record):
                kwargs["record"] = kwargs["record"].resampled_uniform(purpose=purpose)
            return func(*args, **kwargs)

        return wrapper

    return decorate


def record_from_table(table: Any, **kwargs: Any) -> Record:
    """Build a :class:`Record` from a table of file columns (the reading pipeline).

    Parameters
    ----------
    table : driveid.io.tables.Table
        Columns read from a file or a DataFrame.
    **kwargs
        ``source``, ``sha256``, ``columns``, ``fs`` [Hz], ``window`` [s], ``max_jitter``,
        ``scale``, ``units``, ``counts_per_rev``, ``counts_per_metre``, as in
        :func:`driveid.io.read_record`.

    Returns
    -------
    Record
        The validated record in SI units with provenance in ``meta``.
    """
    from driveid.io import reading

    return reading.record_from_table(table, record_type=Record, **kwargs)
