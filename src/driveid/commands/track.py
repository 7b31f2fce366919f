"""``driveid track FILE``: follow drifting inertia and friction through a long record."""

from __future__ import annotations

import dataclasses

import click

from driveid.commands import clean_errors
from driveid.commands._output import emit, output_options
from driveid.commands._record_options import record_options
from driveid.identify.friction.online import chunks_of, track_friction

__all__ = ["track_command"]


@click.command("track")
@click.argument("file", metavar="FILE[@T0:T1]")
@click.option("--drift-time", type=float, default=600.0, show_default=True,
              help="Expected drift time constant [s]; memory = drift time / 10.")
@click.option("--memory", type=float, default=None,
              help="Memory of the exponential window [s] (overrides --drift-time).")
@click.option("--v-min", type=float, default=None,
              help="Skip samples slower than this [rad/s or m/s] (default 5 % of rms).")
@click.option("--stiffness", is_flag=True, help="Also track a stiffness K (spring in u).")
@click.option("--every", "output_every", type=float, default=10.0, show_default=True,
              help="Output interval [s].")
@record_options
@output_options
@clean_errors
def track_command(file, drift_time, memory, v_min, stiffness, output_every, record_opts,
                  output_opts):
    """Track J, c_mean, c_delta, fk_mean, fk_delta of FILE (t, x, u[, v]) over time.

    Recursive least squares with exponential forgetting on the inverse model
    J a + c_mean v + c_delta |v| + fk_mean sgn v + fk_delta = u. The table shows the
    final values; --json holds one array per parameter (and "<name>_stderr") with the
    time stamps "t" under "data_used"; --figure draws the trajectories with ±2σ bands.
    """
    record = record_opts.read(file)
    if record.u is None:
        raise click.UsageError("FILE has no command column u; name it with --force COL")
    units = "m" if record.units.get("x") == "m" else "rad"
    result = track_friction(chunks_of(record, max(int(10 * record.fs), 5)), fs=record.fs,
                            drift_time=drift_time, memory=memory, v_min=v_min,
                            stiffness=stiffness, output_every=output_every, units=units)
    est = result.to_estimate()
    if not stiffness:
        est = est.with_warnings(*_spring_left_out(record, est))
    opts = dataclasses.replace(output_opts, series=True) if output_opts.as_json else output_opts
    emit(est, opts, records=[record], figure=result.plot,
         header=(f"method: {est.method}   memory (lag): {result.memory:.4g} s   "
                 f"outputs: {result.t.size}   samples used: {result.n_used}/"
                 f"{result.n_samples}"))


def _spring_left_out(record, est) -> list[str]:
    """Warn when the motion cannot tell inertia from a spring the model lacks.

    The tracker has no spring unless --stiffness. Under one excitation frequency ``a`` is
    ``-ω² x``: a spring K is absorbed into J as ``J - K/ω²`` and no residual shows it (a
    1 Hz sine on a K = 16 record gave J 42 % low and no word, fifth hostile campaign).
    """
    import numpy as np

    x = np.asarray(record.x, float)
    a = np.gradient(np.gradient(x, record.t), record.t)
    keep = np.isfinite(a)
    if keep.sum() < 10 or np.std(x[keep]) == 0 or np.std(a[keep]) == 0:
        return []
    corr = float(np.corrcoef(x[keep], a[keep])[0, 1])
    if corr > -0.95:
        return []
    omega2 = -float(np.polyfit(x[keep], a[keep], 1)[0])
    return [f"the acceleration follows the position (a ≈ -{omega2:.3g} x, correlation "
            f"{corr:.2f}): one excitation frequency cannot tell the inertia from a spring, so "
            f"a spring K the model lacks reads as J - K/{omega2:.3g}; if the axis has one, "
            "track it with --stiffness on a record of two or more frequencies"]
