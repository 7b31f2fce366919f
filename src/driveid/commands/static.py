"""``driveid identify breakaway | loop | static-stiffness | step``: quasi-static tests."""

from __future__ import annotations

import click

from driveid.commands import clean_errors
from driveid.commands._output import emit, output_options
from driveid.commands._record_options import record_options

__all__ = ["breakaway_command", "loop_command", "static_stiffness_command", "step_command"]


@click.command("breakaway")
@click.argument("files", nargs=-1, required=True, metavar="FILE[@T0:T1]...")
@click.option("--v-break", type=float, required=True,
              help="Gross-sliding threshold on the displacement rate [m/s or rad/s].")
@click.option("--window", type=float, default=None,
              help="Duration of the displacement-rate window [s] (default 10 samples).")
@click.option("--x-creep", type=float, default=None,
              help="Displacement from rest marking the creep onset [m or rad].")
@click.option("--min-force", type=float, default=0.0, show_default=True,
              help="Ignore ramps whose peak force stays below this [N or N·m].")
@click.option("--dwell-fit", is_flag=True,
              help="Also fit the rise of static friction with the dwell time before each "
                   "ramp (thesis 2.6; needs 5 or more ramps of one direction).")
@record_options
@output_options
@clean_errors
def breakaway_command(files, v_break, window, x_creep, min_force, dwell_fit, record_opts,
                      output_opts):
    """Breakaway force by gross sliding from force ramps in one or several FILES."""
    from driveid.identify.friction.breakaway import (
        estimate_breakaway_sliding,
        rising_friction_from_breakaways,
    )
    from driveid.report.loop_figures import plot_breakaway

    records = record_opts.read_all(files)
    est = estimate_breakaway_sliding(records, v_break=v_break, window=window,
                                     x_creep=x_creep, min_force=min_force)
    rising = None
    if dwell_fit:
        import dataclasses

        rising = rising_friction_from_breakaways(est)
        est = dataclasses.replace(est, diagnostics={
            **est.diagnostics,
            "rising_static_friction": rising.to_dict()["parameters"]})
    emit(est, output_opts, records=records, figure=lambda: plot_breakaway(est, records),
         header=f"method: {est.method}   ramps: +{est.diagnostics['n_plus']} "
                f"-{est.diagnostics['n_minus']}")
    if rising is not None and not output_opts.as_json:
        click.echo("\nrising static friction with dwell time (2.6):")
        click.echo(rising.table())


@click.command("loop")
@click.argument("file", metavar="FILE[@T0:T1]")
@click.option("--kind", type=click.Choice(["presliding", "backlash"]), required=True,
              help="presliding: Dahl/LuGre σ0 (2.13-2.20); backlash: gap and contact "
                   "stiffness (2.27).")
@click.option("--threshold", type=float, default=None,
              help="backlash: force scale of the dead zone [N or N·m] (default 20 % of the "
                   "force level).")
@click.option("--lowpass-hz", type=float, default=None,
              help="backlash: zero-phase low-pass on the force [Hz].")
@record_options
@output_options
@clean_errors
def loop_command(file, kind, threshold, lowpass_hz, record_opts, output_opts):
    """Presliding stiffness or backlash gap from a force–displacement loop in FILE."""
    from driveid.identify.forced.loops import estimate_backlash_loop, estimate_presliding_loop
    from driveid.report.loop_figures import plot_loop

    record = record_opts.read(file)
    if kind == "presliding":
        est = estimate_presliding_loop(record)
    else:
        est = estimate_backlash_loop(record, threshold=threshold, lowpass_hz=lowpass_hz)
    emit(est, output_opts, records=[record], figure=lambda: plot_loop(est, record),
         header=f"method: {est.method}")


@click.command("static-stiffness")
@click.argument("file", metavar="FILE")
@click.option("--backlash", is_flag=True,
              help="Loads of both signs: fit gap + stiffness x = x_c + gap/2·sgn(T) + T/K.")
@click.option("--x-ref", type=float, default=None,
              help="backlash: reference position for gap_plus/gap_minus [m or rad].")
@record_options
@output_options
@clean_errors
def static_stiffness_command(file, backlash, x_ref, record_opts, output_opts):
    """Stiffness (and backlash) from static deflection tests: one row per test in FILE.

    The force column holds the applied loads, the position column the settled
    deflections (pass --fs 1 for a table without a time column).
    """
    from driveid.errors import RecordError
    from driveid.identify.friction.static_tests import (
        estimate_backlash_stiffness,
        estimate_static_stiffness,
    )

    record = record_opts.read(file)
    if record.u is None:
        raise RecordError("static-stiffness needs the loads in a force column (--force "
                          "COL); got none")
    xu, fu = record.units.get("x", "rad"), record.units.get("u", "N·m")
    if backlash:
        est = estimate_backlash_stiffness(record.u, record.x, x_ref=x_ref, load_unit=fu,
                                          position_unit=xu)
    else:
        est = estimate_static_stiffness(record.u, record.x, load_unit=fu, position_unit=xu)
    emit(est, output_opts, records=[record], figure=lambda: _deflection_figure(est, record),
         header=f"method: {est.method}")


def _deflection_figure(est, record):
    from driveid.report._pyplot import pyplot

    plt = pyplot()
    fig, ax = plt.subplots(figsize=(6, 4))
    ax.plot(record.u, record.x, "ko", ms=4, label="tests")
    ax.set_xlabel(f"load [{record.units.get('u', 'N·m')}]")
    ax.set_ylabel(f"deflection [{record.units.get('x', 'rad')}]")
    ax.set_title(f"{est.method}: K = {est.value('K'):.4g} {est['K'].unit}", fontsize=9)
    ax.legend(fontsize=8)
    fig.tight_layout()
    return fig


@click.command("step")
@click.argument("file", metavar="FILE[@T0:T1]")
@click.option("--band", type=float, default=0.02, show_default=True,
              help="Settling band as a fraction of the step [-].")
@click.option("--settle-fraction", type=float, default=0.2, show_default=True,
              help="Final fraction of each half period taken as the settled level [-].")
@record_options
@output_options
@clean_errors
def step_command(file, band, settle_fraction, record_opts, output_opts):
    """ζ and ω0 from the steps of a DC-biased square-wave test in FILE (command in u)."""
    from driveid.identify.friction.static_tests import estimate_step_response

    record = record_opts.read(file, position=False)  # a speed-only drive log will do
    est = estimate_step_response(record, band=band, settle_fraction=settle_fraction)
    emit(est, output_opts, records=[record], figure=lambda: _step_figure(est, record),
         header=f"method: {est.method}   steps: {est.diagnostics['n_steps']}")


def _step_figure(est, record):
    from driveid.report._pyplot import pyplot

    plt = pyplot()
    fig, ax = plt.subplots(figsize=(7, 4))
    y = record.v if record.v is not None else record.x
    ax.plot(record.t, y, "k-", lw=0.7, label="response")
    for i in est.data_used.get("step_index", ()):
        ax.axvline(record.t[i], color="C1", lw=0.5)
    ax.set_xlabel("time [s]")
    ax.set_ylabel("response")
    ax.set_title(f"ζ = {est.value('zeta'):.3g}, ω0 = {est.value('omega0'):.4g} rad/s",
                 fontsize=9)
    fig.tight_layout()
    return fig
