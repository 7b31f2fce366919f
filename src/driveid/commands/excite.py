"""``driveid excite KIND``: write an excitation signal as a CSV file with columns ``t,u``."""

from __future__ import annotations

import json

import click
import numpy as np

from driveid.commands import clean_errors
from driveid.commands._checks import SEED, FilePath
from driveid.io.safe_write import atomic_write_text
from driveid.signal import excitation as _ex

#: Time to format and write one CSV row, measured on the shared 2-core machine [s].
_CSV_SECONDS_PER_ROW = 1.5e-6
#: A write estimated longer than this [s] is announced first.
_ANNOUNCE_SECONDS = 10.0

__all__ = ["excite_command"]


def _need(kind: str, **values: object) -> None:
    missing = [f"--{k.replace('_', '-')}" for k, v in values.items() if v is None]
    if missing:
        raise click.UsageError(f"excite {kind} needs {', '.join(missing)}")


@click.command("excite")
@click.argument("kind", type=click.Choice(list(_ex.KINDS)))
@click.option("--f-min", type=float, default=None,
              help="Lowest frequency [Hz] (chirp, multisine, random).")
@click.option("--f-max", type=float, default=None,
              help="Highest frequency [Hz] (chirp, multisine, random).")
@click.option("--frequency", type=float, default=None, help="Frequency [Hz] (square, sine).")
@click.option("--f-clock", type=float, default=None, help="Bit rate [Hz] (prbs).")
@click.option("--duration", type=float, default=None,
              help="Record length [s] (all but ramp).")
@click.option("--fs", type=float, default=1000.0, show_default=True,
              help="Sampling rate [Hz].")
@click.option("--amplitude", type=float, required=True,
              help="Peak (or step half-height, ramp plateau) [N·m or N].")
@click.option("--bias", type=float, default=0.0, show_default=True,
              help="DC bias [N·m or N] (square, sine).")
@click.option("--method", type=click.Choice(["linear", "logarithmic"]), default="linear",
              show_default=True, help="Chirp frequency law.")
@click.option("--period", type=float, default=None,
              help="Multisine period [s] (default: the duration).")
@click.option("--order", type=int, default=None, help="PRBS register length (2..24).")
@click.option("--seed", type=SEED, default=None, help="Seed (random).")
@click.option("--ramp-time", type=float, default=None, help="Ramp duration [s] (ramp).")
@click.option("--dwell-time", type=float, default=0.0, show_default=True,
              help="Plateau duration [s] (ramp).")
@click.option("--cycles", type=int, default=1, show_default=True,
              help="Number of ± cycles (ramp).")
@click.option("--units", type=click.Choice(["N·m", "N"]), default="N·m", show_default=True,
              help="Unit of u written in the header.")
@click.option("--out", type=FilePath(), required=True,
              help="CSV file to write (columns t,u).")
@click.option("--overwrite", is_flag=True, help="Replace an existing --out file.")
@clean_errors
def excite_command(kind, f_min, f_max, frequency, f_clock, duration, fs, amplitude, bias,
                   method, period, order, seed, ramp_time, dwell_time, cycles, units, out,
                   overwrite):
    """Generate an excitation signal KIND and write it as CSV (t [s], u [N·m or N]).

    KIND: chirp, multisine (Schroeder phases), prbs, random (band-limited noise),
    square (DC-biased), ramp (ramps with dwell), sine.

    Example: driveid excite multisine --f-min 1 --f-max 20 --duration 10 --fs 1000
    --amplitude 0.5 --out u.csv
    """
    if kind != "ramp":
        _need(kind, duration=duration)
    if kind in ("chirp", "multisine", "random"):
        _need(kind, f_min=f_min, f_max=f_max)
    common = {"duration": duration, "fs": fs, "amplitude": amplitude}
    if kind == "chirp":
        sig = _ex.chirp(f_min=f_min, f_max=f_max, method=method, **common)
    elif kind == "multisine":
        sig = _ex.multisine(f_min=f_min, f_max=f_max, period=period, **common)
    elif kind == "random":
        sig = _ex.filtered_random(f_min=f_min, f_max=f_max, seed=seed, **common)
    elif kind == "prbs":
        _need(kind, f_clock=f_clock)
        sig = _ex.prbs(f_clock=f_clock, order=order, **common)
    elif kind in ("square", "sine"):
        _need(kind, frequency=frequency)
        make = _ex.square_wave if kind == "square" else _ex.sine
        sig = make(frequency=frequency, bias=bias, **common)
    else:
        _need(kind, ramp_time=ramp_time)
        sig = _ex.ramps_with_dwell(amplitude=amplitude, ramp_time=ramp_time,
                                   dwell_time=dwell_time, fs=fs, n_cycles=cycles)
    seconds = sig.t.size * _CSV_SECONDS_PER_ROW
    if seconds > _ANNOUNCE_SECONDS:  # issue 28: 1e8 rows were written for minutes unannounced
        click.echo(f"writing {sig.t.size:.3g} rows of CSV to {out}: about {seconds:.3g} s",
                   err=True)
    settings = {k: (v.tolist() if isinstance(v, np.ndarray) else v)
                for k, v in sig.settings.items() if k != "frequencies"}
    meta = {"kind": sig.kind, "settings": settings, "crest_factor": sig.crest_factor,
            "band_hz": list(sig.band)}
    rows = "\n".join(f"{t:.10g},{u:.17g}" for t, u in zip(sig.t, sig.u, strict=True))
    text = (f"# driveid excitation: {json.dumps(meta)}\n"
            f"t [s],u [{units}]\n{rows}\n")
    atomic_write_text(out, text, overwrite=overwrite)
    lo, hi = sig.amplitude_limits
    click.echo(f"wrote {out} ({sig.t.size} samples, {sig.kind}, u in [{lo:.6g}, {hi:.6g}] "
               f"{units}, crest factor {sig.crest_factor:.3f})")
