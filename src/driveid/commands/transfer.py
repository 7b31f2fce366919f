"""``driveid identify transfer``: a linear drive model from a command column to an output column.

The file is read by the shared reading layer (:func:`driveid.io.read_table`: every format,
column choice by name, index or ``VAR:INDEX``, header units) but the record is built here
from the two chosen columns, because the command needs no position: a speed-only record
(``--output`` a speed, no time column, ``--fs``) is the common case of a drive test.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import click
import numpy as np

from driveid.commands import clean_errors
from driveid.commands._output import emit, output_options
from driveid.commands._record_options import split_window_spec

__all__ = ["transfer_command"]


@dataclass(frozen=True)
class _Signals:
    """A command and one output on a uniform time base, with the reading's provenance."""

    t: np.ndarray
    u: np.ndarray
    v: np.ndarray | None = None
    x: np.ndarray | None = None
    meta: dict[str, Any] = field(default_factory=dict)

    @property
    def n(self) -> int:
        """Samples [-]."""
        return int(self.t.size)

    @property
    def columns(self) -> tuple[str, ...]:
        """Record columns present."""
        return tuple(c for c in ("t", "x", "v", "u") if getattr(self, c) is not None)

    @property
    def units(self) -> dict[str, str]:
        """Record column -> SI unit (the command keeps its file unit if electrical)."""
        return dict(self.meta.get("units", {}))


def _output_unit_problem(source: str, column: str | None, unit: str, out: str) -> str:
    """Name the output column's unit problem in this command's options."""
    from driveid.errors import FileFormatError
    from driveid.io.units import to_si

    other = "x" if out == "v" else "v"
    try:
        to_si(other, unit, source=source)
    except FileFormatError:
        fix = "state its unit with --output-unit UNIT"
    else:
        fix = ("it measures " + ("position: add --output-quantity position" if out == "v" else
                                 "speed: drop --output-quantity position")
               + ", or state its unit with --output-unit UNIT")
    wanted = "speed" if out == "v" else "position"
    return (f"{source}: the output column {column!r} (--output) is in {unit!r}, not a "
            f"{wanted} unit; {fix}")


def _read_signals(spec: str, *, input_col: str, output_col: str, quantity: str,
                  time_col: str | None, fs: float | None,
                  window: tuple[float | None, float | None], units: dict[str, str]
                  ) -> _Signals:
    from driveid.errors import FileFormatError
    from driveid.io.reading import choose_columns, file_sha256
    from driveid.io.tables import read_table
    from driveid.io.units import to_si

    path, own_window = split_window_spec(spec)
    if own_window != (None, None):
        window = own_window
    table = read_table(path)
    out = "v" if quantity == "speed" else "x"
    wanted: dict[str, Any] = {"u": input_col, out: output_col}
    wanted["x" if out == "v" else "v"] = "none"
    if time_col is not None:
        if fs is not None:
            raise click.UsageError("give the time column (--time) or the sample rate (--fs), "
                                   "not both")
        wanted["t"] = time_col
    elif fs is not None:
        wanted["t"] = "none"
    try:
        chosen = choose_columns(table, wanted, source=path.name)
    except FileFormatError as exc:  # name this command's options, not the record options
        text = str(exc)
        for word in ("force (--force)", "velocity (--velocity)", "position (--position)",
                     "time (--time)"):
            text = text.replace(word, {"f": "command (--input)", "t": "time (--time)"}.get(
                word[0], "output (--output)"))
        raise FileFormatError(text) from None
    if chosen["u"] == chosen[out]:  # issue 28: fitted u -> u, exit 0 with a singular fit
        raise FileFormatError(
            f"{path.name}: --input and --output both name column {chosen['u']!r}; the output "
            "is the measured response (speed or position) to the command: name its column "
            "with --output")
    arrays = {"u": np.asarray(table.columns[chosen["u"]], float),
              out: np.asarray(table.columns[chosen[out]], float)}
    rate = fs if fs is not None else table.fs
    if "t" in chosen:
        arrays["t"] = np.asarray(table.columns[chosen["t"]], float)
    elif rate is None:
        raise FileFormatError(
            f"{path.name} has no time column found by name (t, time, ...); give the sample "
            "rate with --fs HZ or the time column with --time COL")
    else:
        arrays["t"] = table.t0 + np.arange(arrays["u"].size) / rate
    si: dict[str, str] = {}
    in_file: dict[str, str] = {}
    for col in ("t", "u", out):
        fname = chosen.get(col)
        unit = units.get(col) or (table.units.get(fname) if fname else None)
        if not unit:
            continue
        in_file[col] = unit
        try:
            si_unit, factor = to_si(col, unit, source=path.name)
        except FileFormatError:
            if col == out:
                raise FileFormatError(_output_unit_problem(path.name, fname, unit, out)) from None
            if col != "u":
                raise
            si_unit, factor = unit, 1.0  # a voltage or current command keeps its unit
        arrays[col] = arrays[col] * factor
        si[col] = si_unit
    lo = -math.inf if window[0] is None else window[0]
    hi = math.inf if window[1] is None else window[1]
    keep = (arrays["t"] >= lo) & (arrays["t"] <= hi)
    if keep.sum() < 2:
        raise FileFormatError(
            f"{path.name}: the window {window[0]}..{window[1]} s holds {int(keep.sum())} "
            f"sample(s); the record spans {arrays['t'][0]:.6g}..{arrays['t'][-1]:.6g} s")
    arrays = {k: a[keep] for k, a in arrays.items()}
    meta = {"source": str(path), "sha256": file_sha256(path), "rows": int(table.rows),
            "columns": list(table.columns), "columns_used": dict(chosen), "units": si,
            "units_in_file": in_file, "format": table.format,
            "window": [float(arrays["t"][0]), float(arrays["t"][-1])]}
    if "t" not in chosen:
        meta["fs_given"] = float(rate)
    return _Signals(t=arrays["t"], u=arrays["u"], meta=meta, **{out: arrays[out]})


def _check_input_unit(unit: str) -> str:
    """Return ``--input-unit`` spelled canonically; refuse a non-force/torque/electrical one."""
    from driveid.io.units import ELECTRICAL_UNITS, UNIT_CONVERSIONS, normalise_unit

    known = [*UNIT_CONVERSIONS["u"], *ELECTRICAL_UNITS]
    if normalise_unit(unit) not in known:
        raise click.BadParameter(
            f"--input-unit {unit!r} is no unit driveid knows for a command; known units: "
            f"{', '.join(known)}; give one of them, or leave the option out to keep the "
            "file's unit")
    return normalise_unit(unit)


def _fixed(fix: tuple[str, ...], free: tuple[str, ...]) -> dict[str, float]:
    from driveid.identify.forced.transfer_models import TWO_MASS_DEFAULT_FIXED, TWO_MASS_PARAMETERS

    fixed = {k: v for k, v in TWO_MASS_DEFAULT_FIXED.items() if k not in free}
    held = ", ".join(TWO_MASS_DEFAULT_FIXED)
    for name in free:
        if name not in TWO_MASS_PARAMETERS:
            raise click.BadParameter(
                f"--free names a two-mass parameter ({', '.join(TWO_MASS_PARAMETERS)}); got "
                f"{name!r}")
        if name not in TWO_MASS_DEFAULT_FIXED:  # issue 28: accepted, and did nothing
            raise click.BadParameter(
                f"--free {name}: {name} is estimated already; --free frees only a parameter "
                f"held by default ({held}): drop --free {name}")
        if any(item.partition("=")[0].strip() == name for item in fix):
            raise click.BadParameter(
                f"--free {name} and --fix {name}=... contradict each other: keep one")
    for item in fix:
        name, sep, text = item.partition("=")
        name = name.strip()
        try:
            value = float(text)
        except ValueError:
            value = math.nan
        if not sep or name not in TWO_MASS_PARAMETERS or not math.isfinite(value):
            raise click.BadParameter(
                f"--fix takes NAME=VALUE with NAME one of {', '.join(TWO_MASS_PARAMETERS)} "
                f"and a finite value in SI units, e.g. --fix J_m=2e-4; got {item!r}")
        fixed[name] = value
    return fixed


@click.command("transfer")
@click.argument("file", metavar="FILE[@T0:T1]")
@click.option("--input", "input_col", required=True,
              help="Command column (voltage, current, torque): name, 0-based index or "
                   "VAR:INDEX.")
@click.option("--output", "output_col", required=True,
              help="Output column (speed, or position with --output-quantity position).")
@click.option("--output-quantity", type=click.Choice(["speed", "position"]), default="speed",
              show_default=True, help="What the output column measures.")
@click.option("--time", "time_col", default=None,
              help="Time column (default: found by name; none with --fs).")
@click.option("--fs", type=float, default=None, help="Sample rate [Hz] for files without time.")
@click.option("--t-start", type=float, default=None, help="Keep samples from this time on [s].")
@click.option("--t-end", type=float, default=None, help="Keep samples up to this time [s].")
@click.option("--input-unit", default=None,
              help="State or override the command's unit (N·m, N, V, A ...).")
@click.option("--output-unit", default=None, help="State or override the output's unit "
              "(rad/s, rpm, rad, mm ...).")
@click.option("--structure", type=click.Choice(["tf", "two-mass"]), default="tf",
              show_default=True, help="Transfer function, or the two-mass grey box (J_m, J_l, "
              "k, c, c_m, c_l, gain).")
@click.option("--order", type=int, default=None,
              help="Poles of the transfer function (default: chosen by BIC up to "
                   "--max-order).")
@click.option("--max-order", type=int, default=4, show_default=True,
              help="Highest order tried by BIC.")
@click.option("--relative-degree", type=int, default=None,
              help="Poles minus zeros (default 1 for speed, 2 for position).")
@click.option("--output-nonlinearity", type=click.Choice(["abs"]), default=None,
              help="Static sensor map: abs for a speed-magnitude sensor (the model output "
                   "passes through |.|).")
@click.option("--side", type=click.Choice(["motor", "load"]), default="motor",
              show_default=True, help="Two-mass: where the output is measured.")
@click.option("--fix", multiple=True, metavar="NAME=VALUE",
              help="Two-mass: a given parameter in SI units (default gain=1, c_l=0); "
                   "repeatable.")
@click.option("--free", multiple=True, metavar="NAME",
              help="Two-mass: estimate a parameter held by default (gain or c_l).")
@click.option("--period", type=float, default=None,
              help="Period of a periodic command (multisine) [s], for the data FRF.")
@click.option("--white-noise", is_flag=True,
              help="Assume white residuals (no AR noise model).")
@output_options
@clean_errors
def transfer_command(file, input_col, output_col, output_quantity, time_col, fs, t_start, t_end,
                     input_unit, output_unit, structure, order, max_order, relative_degree,
                     output_nonlinearity, side, fix, free, period, white_noise, output_opts):
    """Linear drive model: command to speed or position (TF, two-mass).

    Fitted by output error with exact zero-order-hold simulation, an AR noise model and
    standard errors; resonances as omega0_1, zeta_1, ... The report shows the Bode plot of
    the model over the data's FRF and coherence.
    """
    from driveid.identify.forced.transfer import estimate_transfer

    if structure != "two-mass" and (fix or free):
        raise click.UsageError("--fix/--free are for --structure two-mass")
    if fs is not None and not (math.isfinite(fs) and fs > 0):
        raise click.BadParameter(f"--fs must be a positive sample rate [Hz]; got {fs}")
    if input_unit is not None:
        input_unit = _check_input_unit(input_unit)
    quantity_col = "v" if output_quantity == "speed" else "x"
    units = {k: v for k, v in (("u", input_unit), (quantity_col, output_unit)) if v}
    record = _read_signals(file, input_col=input_col, output_col=output_col,
                           quantity=output_quantity, time_col=time_col, fs=fs,
                           window=(t_start, t_end), units=units)
    if relative_degree is None:
        relative_degree = 1 if output_quantity == "speed" else 2
    est = estimate_transfer(
        record, output=quantity_col, structure=structure, order=order, max_order=max_order,
        relative_degree=relative_degree, output_nonlinearity=output_nonlinearity, side=side,
        fixed=_fixed(fix, free) if structure == "two-mass" else None,
        noise_model=not white_noise, period=period)

    def figure():
        from driveid.report.transfer_figures import plot_transfer

        return plot_transfer(est)

    emit(est, output_opts, records=[record], figure=figure,
         header=f"method: {est.method}   fit: {est.diagnostics['fit_percent']:.2f} %   "
                f"noise: {est.diagnostics['noise_model']['kind']}   "
                f"source: {Path(record.meta['source']).name}")
