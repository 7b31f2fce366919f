"""``driveid identify forced`` and ``driveid identify envelope``: thin wrappers."""

from __future__ import annotations

import click

from driveid.commands import clean_errors
from driveid.commands._output import emit, output_options, plot_of
from driveid.commands._record_options import record_options

__all__ = ["forced_command", "envelope_command"]


@click.command("forced")
@click.argument("files", nargs=-1, required=True, metavar="FILE[@T0:T1]...")
@click.option("--omega", type=float, multiple=True,
              help="Excitation frequency [rad/s]: once for all FILES or once per FILE "
                   "(default: estimated from each run's force).")
@click.option("--K", "K_known", type=float, default=None,
              help="Known stiffness K [N/m or N·m/rad].")
@click.option("--friction/--no-friction", default=False, show_default=True,
              help="Also fit asymmetric describing-function friction c_mean, c_delta, "
                   "fk_mean, fk_delta (runs at several amplitudes: a frequency × amplitude "
                   "grid).")
@click.option("--x-ref", "x_ref", type=float, default=None,
              help="Spring zero in the files' x [rad or m] (with --friction): needed for "
                   "fk_delta when the drive has a spring.")
@click.option("--pho", is_flag=True, default=False,
              help="Runs under delayed PD feedback (forced PHO): P, D and the delay come "
                   "from the files' metadata.")
@record_options
@output_options
@clean_errors
def forced_command(files, omega, K_known, friction, x_ref, pho, record_opts, output_opts):
    """J, C, K (and friction) from steady sinusoidal runs (one FILE per frequency/amplitude).

    With --friction, parameters the runs do not determine (the asymmetry without a spring
    or feedback, fk_delta without --x-ref on a spring) are shown as nan (JSON null) and
    listed in the diagnostics under not_identified.
    """
    from driveid.identify.forced.forced import estimate_forced_pho, estimate_forced_response

    if x_ref is not None and not friction:
        raise click.UsageError("--x-ref is used by the friction fit only; add --friction")
    records = record_opts.read_all(files)
    om = None if not omega else (omega[0] if len(omega) == 1 else list(omega))
    if pho:
        est = estimate_forced_pho(records, omega=om, K_known=K_known, friction=friction,
                                  x_ref=x_ref)
    else:
        est = estimate_forced_response(records, omega=om, K_known=K_known,
                                       friction=friction, x_ref=x_ref)
    emit(est, output_opts, records=records, figure=lambda: plot_of(est, records),
         header=f"method: {est.method}   runs: {len(records)}")


@click.command("envelope")
@click.argument("file", metavar="FILE[@T0:T1]")
@click.option("--mass", "--J", "mass", type=float, default=None,
              help="Known mass or inertia J [kg or kg·m²].")
@click.option("--min-snr", type=float, default=10.0, show_default=True,
              help="Smallest accepted signal-to-noise ratio of the decay [-].")
@record_options
@output_options
@clean_errors
def envelope_command(file, mass, min_snr, record_opts, output_opts):
    """Viscous and Coulomb damping from the Hilbert envelope of a free decay in FILE."""
    import math

    import numpy as np

    from driveid.identify.free_decay.hilbert import estimate_envelope_damping

    record = record_opts.read(file)
    est = estimate_envelope_damping(record, mass=mass, min_snr=min_snr)
    if record.u is not None and np.any(record.u):  # issue 28: a forced run gave nan silently
        est = est.with_warnings(
            f"the record has a force or torque input (max |u| = "
            f"{float(np.max(np.abs(record.u))):.3g}): the envelope method reads a free decay; "
            "for a driven run use driveid identify forced or idim")
    missing = [n for n, p in est.params.items() if not p.fixed and math.isfinite(p.value)
               and not math.isfinite(p.stderr)]
    if missing:
        est = est.with_warnings(f"{', '.join(missing)} came out without a standard error (too "
                                "few envelope samples to judge the scatter); treat the value "
                                "as unverified")
    emit(est, output_opts, records=[record], figure=lambda: plot_of(est, record),
         header=f"method: {est.method}")
