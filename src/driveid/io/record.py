"""The :class:`Record`: one experiment's time series, validated at construction."""

from __future__ import annotations

import warnings
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

import numpy as np

from driveid.errors import RecordError, RecordWarning
from driveid.signal.repair import check_timeline, find_corrupted_bursts

__all__ = ["Record", "MIN_SAMPLES", "DEFAULT_UNITS"]

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
            bad = np.flatnonzero(~np.isfinite(arr))
            if bad.size:
                raise RecordError(
                    f"column {name!r} has {bad.size} non-finite value(s) (NaN or inf), the first "
                    f"at sample {bad[0]}; drop or interpolate those samples before analysis"
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
        return float(np.median(np.diff(self.t)))

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

    @property
    def columns(self) -> tuple[str, ...]:
        """Names of the columns present, in the order t, x, u, v."""
        return tuple(name for name in _COLUMNS if getattr(self, name) is not None)

    def __repr__(self) -> str:
        cols = ", ".join(self.columns)
        return f"Record(n={self.n}, fs={self.fs:g} Hz, duration={self.duration:g} s, [{cols}])"
