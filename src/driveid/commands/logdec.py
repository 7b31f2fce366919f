"""``driveid simulate free-decay`` and ``driveid identify logdec``."""

from __future__ import annotations

import json
from pathlib import Path

import click

from driveid.commands import clean_errors
from driveid.identify.logdec import estimate_log_decrement, estimate_log_decrement_thesis
from driveid.io import read_record, write_record
from driveid.sim import OscillatorParams, measure, simulate_free_decay

__all__ = ["free_decay_command", "logdec_command"]


@click.command("free-decay")
@click.option("--J", "J", type=float, default=1.0, show_default=True,
              help="Mass [kg] or inertia [kg·m²].")
@click.option("--K", "K", type=float, default=16.0, show_default=True,
              help="Stiffness [N/m or N·m/rad].")
@click.option("--c-mean", type=float, default=0.3, show_default=True,
              help="Mean viscous friction [N·s/m or N·m·s/rad].")
@click.option("--c-delta", type=float, default=0.1, show_default=True,
              help="Viscous asymmetry (signed) [N·s/m or N·m·s/rad].")
@click.option("--fk-mean", type=float, default=0.07, show_default=True,
              help="Mean kinetic friction [N or N·m].")
@click.option("--fk-delta", type=float, default=0.03, show_default=True,
              help="Kinetic asymmetry (signed) [N or N·m].")
@click.option("--fs-mean", type=float, default=None,
              help="Mean static friction [N or N·m]; default: the kinetic value.")
@click.option("--fs-delta", type=float, default=None,
              help="Static asymmetry [N or N·m]; default: the kinetic value.")
@click.option("--x0", type=float, default=10.0, show_default=True,
              help="Initial displacement [m or rad], released at rest.")
@click.option("--duration", type=float, default=30.0, show_default=True, help="Duration [s].")
@click.option("--rate", "fs", type=float, default=1000.0, show_default=True,
              help="Sampling rate [Hz].")
@click.option("--noise", type=float, default=0.0, show_default=True,
              help="Gaussian position noise, standard deviation [m or rad].")
@click.option("--counts-per-rev", type=float, default=None,
              help="Rotary encoder quantisation [counts/rev].")
@click.option("--counts-per-metre", type=float, default=None,
              help="Linear encoder quantisation [counts/m].")
@click.option("--units", type=click.Choice(["rad", "m"]), default="rad", show_default=True,
              help="Rotational (rad, N·m) or translational (m, N) record.")
@click.option("--seed", type=int, default=None, help="Seed of the noise generator.")
@click.option("--out", "out", type=click.Path(dir_okay=False, path_type=Path), required=True,
              help="Record file to write (.csv, .npz or .mat).")
@click.option("--force", is_flag=True, help="Overwrite an existing output file.")
@clean_errors
def free_decay_command(J, K, c_mean, c_delta, fk_mean, fk_delta, fs_mean, fs_delta, x0,
                       duration, fs, noise, counts_per_rev, counts_per_metre, units, seed, out,
                       force):
    """Simulate an exact free decay with asymmetric friction and write it as a record."""
    params = OscillatorParams(J=J, K=K, c_mean=c_mean, c_delta=c_delta, fk_mean=fk_mean,
                              fk_delta=fk_delta, fs_mean=fs_mean, fs_delta=fs_delta)
    result = simulate_free_decay(params, x0=x0, duration=duration, fs=fs)
    record = result.record
    if units == "m":
        record = record.replace(meta={"units": {"x": "m", "u": "N", "v": "m/s"}})
    record = measure(record, noise_std=noise, counts_per_rev=counts_per_rev,
                     counts_per_unit=counts_per_metre, rng=seed)
    path = write_record(record, out, overwrite=force)
    stuck = f", stuck at t = {result.stuck_at:.4g} s" if result.stuck_at is not None else ""
    click.echo(f"wrote {path} ({record.n} samples, {result.n_reversals} reversals{stuck})")


@click.command("logdec")
@click.argument("files", nargs=-1, required=True,
                type=click.Path(exists=True, dir_okay=False, path_type=Path))
@click.option("--mass", "--J", "mass", type=float, default=None,
              help="Known mass or inertia J [kg or kg·m²].")
@click.option("--stiffness", "--K", "stiffness", type=float, default=None,
              help="Known stiffness K [N/m or N·m/rad].")
@click.option("--method", type=click.Choice(["lsq", "thesis", "thesis-printed"]),
              default="lsq", show_default=True,
              help="lsq: all peaks and times (several FILES are fitted jointly); thesis: "
                   "corrected closed forms (2.169)-(2.175); thesis-printed: as printed.")
@click.option("--json", "as_json", is_flag=True, help="Print the estimate as JSON.")
@click.option("--figure", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Save a figure of the record, its peaks and the fitted envelope (PNG).")
@click.option("--force", is_flag=True, help="Overwrite an existing figure file.")
@clean_errors
def logdec_command(files, mass, stiffness, method, as_json, figure, force):
    """Identify asymmetric viscous and kinetic friction from free-decay FILES."""
    records = [read_record(f) for f in files]
    if method == "lsq":
        est = estimate_log_decrement(records, mass=mass, stiffness=stiffness)
    else:
        if len(records) > 1:
            raise click.UsageError("the thesis formulas take one file; use --method lsq")
        est = estimate_log_decrement_thesis(records[0], corrected=(method == "thesis"),
                                            mass=mass, stiffness=stiffness)
    if figure is not None:
        from driveid.report.figures import save_figure

        save_figure(est.plot(record=records), figure, overwrite=force)
    if as_json:
        click.echo(json.dumps(est.to_dict(), indent=2))
    else:
        click.echo(f"method: {est.method}   peaks: {est.diagnostics.get('n_peaks')}")
        click.echo(est.table())
        if figure is not None:
            click.echo(f"figure: {figure}")
