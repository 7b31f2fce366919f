"""A simulated plant: N axes × M monthly free-decay measurements with known injected faults.

Every axis is one ``J x'' + C(x') x' + K x + F_k(x') = 0`` oscillator (thesis 2.136, 2.155),
simulated exactly (:func:`driveid.sim.simulate_free_decay`) and measured with noise and
encoder quantisation (:func:`driveid.sim.measure`). Axes of one machine type differ by a
manufacturing spread; months differ by a small environmental scatter (temperature,
lubricant); a fraction of axes develops one of three faults from a known month on, growing
linearly with time:

* ``friction`` — kinetic friction ``fk_mean`` rising (wear, lubricant breakdown);
* ``backlash`` — a growing gap. The 1-DOF free decay has no gap, so it is represented by
  its two effects on a decay: the impact losses at each reversal, which are Coulomb-like
  (a constant energy per half cycle: extra ``fk_mean``), and the dead zone, which lowers the
  mean stiffness (a smaller ``K``);
* ``coupling`` — a loosening coupling: stiffness ``K`` falling.

The truth (each axis's parameters every month, its fault and onset) is written beside the
records so that detection can be scored (``benchmarks/bench_fleet.py``).
"""

from __future__ import annotations

import csv
import datetime as dt
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from driveid.errors import OverwriteError, ParameterError
from driveid.io import write_record
from driveid.io.consistency import check_count, check_disk
from driveid.sim.oscillator import OscillatorParams, measure, simulate_free_decay

__all__ = ["FAULTS", "FleetSpec", "FleetTruth", "MAX_FLEET_RECORDS", "simulate_fleet",
           "read_fleet_truth"]

#: Fault kinds and their growth per month after onset, as fractions of the axis's own value.
FAULTS: dict[str, dict[str, float]] = {
    "friction": {"fk_mean": +0.06},
    "backlash": {"fk_mean": +0.03, "K": -0.01},
    "coupling": {"K": -0.025},
}


@dataclass(frozen=True, kw_only=True)
class FleetSpec:
    """The machine type and the measurement campaign of a simulated fleet.

    Attributes
    ----------
    nominal : mapping
        Nominal ``J`` [kg·m²], ``K`` [N·m/rad], ``c_mean``, ``c_delta`` [N·m·s/rad],
        ``fk_mean``, ``fk_delta`` [N·m] of the machine type.
    spread : mapping
        Manufacturing spread per parameter, standard deviation as a fraction of nominal
        (``c_delta`` and ``fk_delta``: absolute [N·m·s/rad, N·m]).
    monthly : mapping
        Month-to-month environmental scatter, same convention.
    faults : mapping
        Fault kind -> parameter -> growth per month (fraction), default :data:`FAULTS`.
    x0 : float
        Initial displacement of every free decay [rad].
    duration, fs : float
        Record length [s] and sampling rate [Hz].
    noise_std : float
        Position noise [rad].
    counts_per_rev : float
        Encoder resolution [counts/rev].
    onset_months : tuple of int
        Range (first, last) of fault onset months, 0-based.
    """

    nominal: Mapping[str, float] = field(default_factory=lambda: {
        "J": 1.0, "K": (2 * math.pi * 2.0) ** 2, "c_mean": 0.5, "c_delta": 0.05,
        "fk_mean": 0.3, "fk_delta": 0.05})
    spread: Mapping[str, float] = field(default_factory=lambda: {
        "K": 0.04, "c_mean": 0.10, "c_delta": 0.02, "fk_mean": 0.08, "fk_delta": 0.02})
    monthly: Mapping[str, float] = field(default_factory=lambda: {
        "K": 0.003, "c_mean": 0.02, "c_delta": 0.005, "fk_mean": 0.02, "fk_delta": 0.005})
    faults: Mapping[str, Mapping[str, float]] = field(default_factory=lambda: dict(FAULTS))
    x0: float = 0.1
    duration: float = 6.0
    fs: float = 200.0
    noise_std: float = 2e-5
    counts_per_rev: float = 2.0**16
    onset_months: tuple[int, int] = (3, 8)


@dataclass(frozen=True)
class FleetTruth:
    """What was simulated.

    Attributes
    ----------
    root : Path
        Folder of the fleet: ``<machine>/<axis>/<YYYY-MM-DD>.csv`` and ``truth.csv``.
    rows : list of dict
        One per axis-month: ``machine, axis, month, date, path, fault, onset_month,
        faulty`` and the true ``J, K, c_mean, c_delta, fk_mean, fk_delta``.
    """

    root: Path
    rows: list[dict[str, Any]]

    def axes(self) -> dict[tuple[str, str], dict[str, Any]]:
        """Return ``(machine, axis) -> {"fault", "onset_month"}``."""
        return {(r["machine"], r["axis"]): {"fault": r["fault"], "onset_month": r["onset_month"]}
                for r in self.rows}


_ABSOLUTE = ("c_delta", "fk_delta")
_AXIS_NAMES = ("x", "y", "z", "a", "b", "c")
#: Most records a simulated fleet writes without an explicit override: 1e5 records are
#: ~5 GB and ~30 minutes here (2.5 s for 121 records of 1601 samples) [-].
MAX_FLEET_RECORDS = 100_000
#: Bytes of one record's CSV file (measured: 5.9 MB for 121 records, with margin) [B].
RECORD_BYTES = 60_000


def simulate_fleet(root: str | Path, *, n_axes: int = 200, n_months: int = 12,
                   faulty_fraction: float = 0.1, axes_per_machine: int = 4,
                   start: str = "2026-01-01", seed: int = 0, spec: FleetSpec | None = None,
                   overwrite: bool = False, max_records: int = MAX_FLEET_RECORDS) -> FleetTruth:
    """Write a simulated fleet of free-decay records and its truth file.

    Parameters
    ----------
    root : str or Path
        Output folder (created).
    n_axes : int
        Number of axes; >= 1.
    n_months : int
        Monthly measurements per axis; >= 1.
    faulty_fraction : float
        Fraction of axes given a fault [-], in [0, 1]; the kinds take turns.
    axes_per_machine : int
        Axes per machine (named x, y, z, a, b, c); 1 to 6.
    start : str
        ISO date of the first measurement; the others follow monthly.
    seed : int
        Seed of every random draw (the fleet is reproducible).
    spec : FleetSpec, optional
        The machine type and campaign (default :class:`FleetSpec`).
    overwrite : bool
        Replace existing records and truth.
    max_records : int
        Most records (axes x months) written without an explicit override [-].

    Returns
    -------
    FleetTruth
        Paths and true parameters of every axis-month.

    Raises
    ------
    ParameterError
        If a count or fraction is out of range, the records exceed ``max_records`` or the
        free disk, or the months run past the calendar (year 9999).
    OverwriteError
        If ``root/truth.csv`` exists and ``overwrite`` is False.
    """
    spec = spec or FleetSpec()
    if n_axes < 1 or n_months < 1 or not 1 <= axes_per_machine <= len(_AXIS_NAMES):
        raise ParameterError(
            f"need n_axes >= 1, n_months >= 1 and 1 <= axes_per_machine <= 6; got "
            f"{n_axes}, {n_months}, {axes_per_machine}")
    if not 0 <= faulty_fraction <= 1:
        raise ParameterError(f"faulty_fraction must be in [0, 1]; got {faulty_fraction}")
    first = dt.date.fromisoformat(start)
    if first.year + (first.month - 1 + n_months) // 12 > 9998:
        raise ParameterError(f"{n_months} months from {start} run past the calendar's year "
                             "9999; ask for fewer months (CLI: --months)")
    check_count(n_axes * n_months, max_records, f"records of the fleet ({n_axes} axes x "
                f"{n_months} months)", override="max_records=N (CLI: --max-records N)")
    check_disk(n_axes * n_months * RECORD_BYTES, root, f"{n_axes * n_months} fleet records",
               override="simulate fewer axes or months (--axes, --months), or write elsewhere")
    root = Path(root)
    if (root / "truth.csv").exists() and not overwrite:
        raise OverwriteError(f"{root / 'truth.csv'} exists; choose another folder or pass "
                             "overwrite=True (CLI: --overwrite)")
    rng = np.random.default_rng(seed)
    n_faulty = int(round(faulty_fraction * n_axes))
    faulty = set(rng.choice(n_axes, size=n_faulty, replace=False).tolist())
    kinds = list(spec.faults)
    rows: list[dict[str, Any]] = []
    fault_count = 0
    for index in range(n_axes):
        machine = f"m{index // axes_per_machine:03d}"
        axis = _AXIS_NAMES[index % axes_per_machine]
        own = {name: _draw(rng, name, value, spec.spread.get(name, 0.0))
               for name, value in spec.nominal.items()}
        fault, onset = "none", None
        if index in faulty:
            fault = kinds[fault_count % len(kinds)]
            fault_count += 1
            onset = int(rng.integers(spec.onset_months[0], spec.onset_months[1] + 1))
        for month in range(n_months):
            params = {name: _draw(rng, name, value, spec.monthly.get(name, 0.0))
                      for name, value in own.items()}
            if onset is not None and month >= onset:
                for name, rate in spec.faults[fault].items():
                    params[name] = params[name] * (1 + rate * (month - onset + 1))
            params["fk_mean"] = max(params["fk_mean"], 0.0)
            date = _add_months(first, month)
            path = root / machine / axis / f"{date.isoformat()}.csv"
            system = OscillatorParams(**params)
            decay = simulate_free_decay(system, x0=spec.x0, duration=spec.duration, fs=spec.fs)
            record = measure(decay.record, noise_std=spec.noise_std,
                             counts_per_rev=spec.counts_per_rev, rng=rng)
            path.parent.mkdir(parents=True, exist_ok=True)
            write_record(record, path, overwrite=overwrite)
            rows.append({"machine": machine, "axis": axis, "month": month,
                         "date": date.isoformat(), "path": str(path.relative_to(root)),
                         "fault": fault, "onset_month": onset,
                         "faulty": onset is not None and month >= onset, **params})
    from driveid.io.safe_write import atomic_open

    with atomic_open(root / "truth.csv", "w", newline="", overwrite=overwrite) as fh:
        writer = csv.DictWriter(fh, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    return FleetTruth(root, rows)


def read_fleet_truth(root: str | Path) -> FleetTruth:
    """Read the truth written by :func:`simulate_fleet`.

    Parameters
    ----------
    root : str or Path
        The fleet's folder.

    Returns
    -------
    FleetTruth
        Rows with numbers and booleans restored.
    """
    root = Path(root)
    rows = []
    with open(root / "truth.csv", encoding="utf-8") as fh:
        for r in csv.DictReader(fh):
            row: dict[str, Any] = dict(r)
            row["month"] = int(r["month"])
            row["onset_month"] = int(r["onset_month"]) if r["onset_month"] else None
            row["faulty"] = r["faulty"] == "True"
            for name in ("J", "K", "c_mean", "c_delta", "fk_mean", "fk_delta"):
                row[name] = float(r[name])
            rows.append(row)
    return FleetTruth(root, rows)


def _draw(rng: np.random.Generator, name: str, value: float, sd: float) -> float:
    if sd == 0:
        return float(value)
    if name in _ABSOLUTE:
        return float(value + sd * rng.standard_normal())
    return float(value * (1 + sd * rng.standard_normal()))


def _add_months(date: dt.date, months: int) -> dt.date:
    total = date.month - 1 + months
    return date.replace(year=date.year + total // 12, month=total % 12 + 1)
