"""``driveid simulate free-decay`` and ``driveid identify logdec``."""

from __future__ import annotations

import click

from driveid.commands import clean_errors
from driveid.commands._checks import (
    SEED,
    FilePath,
    PositiveFloat,
    bootstrap_options,
    parse_quantisation,
)
from driveid.commands._output import emit, noise_words, output_options
from driveid.commands._record_options import record_options

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
@click.option("--counts-per-rev", type=PositiveFloat(min=1.0), default=None,
              help="Rotary encoder quantisation [counts/rev].")
@click.option("--counts-per-metre", type=PositiveFloat(min=1.0), default=None,
              help="Linear encoder quantisation [counts/m].")
@click.option("--units", type=click.Choice(["rad", "m"]), default="rad", show_default=True,
              help="Rotational (rad, N·m) or translational (m, N) record.")
@click.option("--seed", type=SEED, default=None, help="Seed of the noise generator.")
@click.option("--out", "out", type=FilePath(), required=True,
              help="Record file to write (.csv, .npz or .mat).")
@click.option("--overwrite", is_flag=True, help="Overwrite an existing output file.")
@click.option("--force", "force_alias", is_flag=True, hidden=True,
              help="Old name of --overwrite.")
@clean_errors
def free_decay_command(J, K, c_mean, c_delta, fk_mean, fk_delta, fs_mean, fs_delta, x0,
                       duration, fs, noise, counts_per_rev, counts_per_metre, units, seed, out,
                       overwrite, force_alias):
    """Simulate an exact free decay with asymmetric friction and write it as a record."""
    from driveid.io import write_record
    from driveid.sim import OscillatorParams, measure, simulate_free_decay

    params = OscillatorParams(J=J, K=K, c_mean=c_mean, c_delta=c_delta, fk_mean=fk_mean,
                              fk_delta=fk_delta, fs_mean=fs_mean, fs_delta=fs_delta)
    from driveid.errors import RecordError, SimulationError

    try:
        result = simulate_free_decay(params, x0=x0, duration=duration, fs=fs)
        record = result.record
    except RecordError as exc:  # the record refuses inf (J = 1e-300: issue 28)
        raise SimulationError(
            f"the simulated decay is not finite ({exc}); J = {J:g}, K = {K:g}: check the "
            "values and their SI units (J in kg·m² or kg, K in N·m/rad or N/m)") from None
    _active_warnings(params, record.x, x0)
    if units == "m":
        record = record.replace(meta={"units": {"x": "m", "u": "N", "v": "m/s"}})
    record = measure(record, noise_std=noise, counts_per_rev=counts_per_rev,
                     counts_per_unit=counts_per_metre, rng=seed)
    path = write_record(record, out, overwrite=overwrite or force_alias)
    stuck = f", stuck at t = {result.stuck_at:.4g} s" if result.stuck_at is not None else ""
    click.echo(f"wrote {path} ({record.n} samples, {result.n_reversals} reversals{stuck})")


def _active_warnings(params, x, x0) -> None:
    """Say so when the simulated body is not passive (issue 28: a growing decay was silent)."""
    import numpy as np

    from driveid.errors import SimulationError

    if not np.all(np.isfinite(x)):
        raise SimulationError(
            f"the simulated decay overflows (J = {params.J:g}, K = {params.K:g}, c_mean = "
            f"{params.c_mean:g}): check the values and their SI units (J in kg·m² or kg, K "
            "in N·m/rad or N/m)")
    notes = []
    if params.c_mean - abs(params.c_delta) < 0:
        notes.append(f"its viscous friction is negative in one direction at least (c_mean - "
                     f"|c_delta| = {params.c_mean - abs(params.c_delta):g}), which feeds "
                     "energy in")
    if abs(params.fk_delta) > params.fk_mean:
        notes.append(f"|fk_delta| = {abs(params.fk_delta):g} exceeds fk_mean = "
                     f"{params.fk_mean:g}, so friction pushes the body in one direction")
    if notes:
        click.echo(f"warning: the simulated body is not passive: {'; '.join(notes)}; the "
                   f"response reaches |x| = {float(np.max(np.abs(x))):.3g} from x0 = {x0:g} "
                   "(a self-excited system; no real free decay does this)", err=True)


@click.command("logdec")
@click.argument("files", nargs=-1, required=True, metavar="FILE[@T0:T1]...")
@click.option("--mass", "--J", "mass", type=float, default=None,
              help="Known mass or inertia J [kg or kg·m²].")
@click.option("--stiffness", "--K", "stiffness", type=float, default=None,
              help="Known stiffness K [N/m or N·m/rad].")
@click.option("--method", type=click.Choice(["oe", "peaks", "lsq", "thesis", "thesis-printed"]),
              default="oe", show_default=True,
              help="oe: whole-record output-error fit of every sample (near the Cramér-Rao "
                   "bound); peaks (alias lsq): least-squares log decrement of all peaks and "
                   "times; thesis: corrected closed forms (2.169)-(2.175); thesis-printed: as "
                   "printed. Several FILES are fitted jointly by oe and peaks.")
@click.option("--x-ref", type=float, default=0.0, show_default=True,
              help="Position of the spring's zero [m or rad] (oe; a constant offset is not "
                   "identifiable from a free decay).")
@click.option("--drift", is_flag=True, help="Fit a slow linear drift of the position (oe).")
@bootstrap_options(25)
@click.option("--check-window", is_flag=True,
              help="Refit without the last 20 % of each window and warn when a parameter "
                   "moves by more than 3 standard errors.")
@record_options
@output_options
@clean_errors
def logdec_command(files, mass, stiffness, method, x_ref, drift, quantisation, bootstrap, seed,
                   check_window, record_opts, output_opts):
    """Identify asymmetric viscous and kinetic friction from free-decay FILES.

    Each FILE may carry its own window, e.g. run.csv@2:30 [s].
    """
    raw = record_opts.read_all(files)
    if method in ("thesis", "thesis-printed") and len(raw) > 1:
        raise click.UsageError("the thesis formulas take one file; use --method oe or peaks")
    if method == "oe":
        # the whole-record fit takes any increasing timeline: no resampling
        records = raw
        q = parse_quantisation(quantisation)

        def fit(recs):
            from driveid.commands._progress import progress_bar
            from driveid.identify.free_decay.output_error import estimate_output_error

            with progress_bar(bootstrap, "bootstrap refits (encoder records)",
                              quiet=output_opts.quiet) as bar:
                return estimate_output_error(
                    recs, mass=mass, stiffness=stiffness, x_ref=x_ref, drift=drift,
                    quantisation=q, bootstrap=bootstrap, rng=seed,
                    progress=lambda done, total: bar.update(1))

        def figure():
            from driveid.validate import compare

            return compare(records[0], est, index=0).plot()
    else:
        records = [r.resampled_uniform(purpose="peak refinement") for r in raw]

        def fit(recs):
            from driveid.identify.free_decay.logdec import (
                estimate_log_decrement,
                estimate_log_decrement_thesis,
            )

            if method in ("lsq", "peaks"):
                return estimate_log_decrement(recs, mass=mass, stiffness=stiffness)
            return estimate_log_decrement_thesis(recs[0], corrected=(method == "thesis"),
                                                 mass=mass, stiffness=stiffness)

        def figure():
            from driveid.commands._output import plot_of

            return plot_of(est, records)

    est = fit(records)
    if check_window:
        from driveid.identify.core._plausibility import check_refit_stability

        shorter = [r.crop(None, r.t[0] + 0.8 * r.duration) for r in records]
        est = check_refit_stability(est, fit(shorter),
                                    change="the last 20 % of the window dropped")
    counts = (f"samples: {est.diagnostics.get('n_samples')}" if method == "oe"
              else f"peaks: {est.diagnostics.get('n_peaks')}")
    if method == "oe" and "structure" in est.diagnostics:
        # which structure and noise model were chosen, and why (issue 24)
        noise = est.diagnostics["noise_model"]
        counts += (f"   structure: {est.diagnostics['structure']}   noise: "
                   f"{noise_words(noise)}")
    est = est.with_warnings(*_applied_force_notes(records))
    emit(est, output_opts, records=records, figure=figure,
         header=f"method: {est.method}   {counts}")


def _applied_force_notes(records) -> list[str]:
    """Say when a record's force column is not zero: a free decay is unforced.

    A constant load was ignored without a word (fifth hostile campaign); it shifts the rest
    position by u0/K and reads as a kinetic asymmetry (the estimate is fk_delta - u0).
    """
    import numpy as np

    out = []
    for i, rec in enumerate(records):
        u = None if rec.u is None else np.asarray(rec.u, float)
        if u is None or not np.any(u):
            continue
        name = f"record {i + 1}" if len(records) > 1 else "the record"
        unit = rec.units.get("u", "")
        mean, spread = float(np.mean(u)), float(np.std(u))
        if spread <= 0.05 * abs(mean):
            out.append(f"{name}'s force column holds a constant load of {mean:.4g} {unit}: "
                       "a free-decay fit ignores u, and a constant load shifts the rest "
                       "position by u0/K, so fk_delta reads as fk_delta - u0; drop the load, "
                       "or ignore the column with --force none if it is not a load")
        else:
            out.append(f"{name}'s force column is not zero (up to {np.max(np.abs(u)):.4g} "
                       f"{unit}): a free-decay fit assumes no applied force and ignores u; a "
                       "driven record is fitted by identify forced or identify idim")
    return out
