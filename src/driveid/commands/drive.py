"""``driveid simulate drive``: simulate a lumped drive from a TOML file or a preset."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import click
import numpy as np

from driveid._json import to_jsonable
from driveid.commands import clean_errors
from driveid.commands._checks import FilePath, PositiveFloat
from driveid.errors import ConfigError
from driveid.io import ensure_writable
from driveid.sim.config import RunOptions, parse_drive_config, read_toml, simulate_config
from driveid.sim.drive import (
    DEFAULT_MAX_STEPS,
    DriveResult,
    check_drive_cost,
    estimate_drive_cost,
)
from driveid.sim.presets import PRESETS, preset, preset_units

__all__ = ["drive_command", "write_drive_csv"]

#: A run estimated longer than this [s] is announced (steps, step, samples, time) first.
_ANNOUNCE_SECONDS = 10.0

_UNITS = {"rad": ("rad", "rad/s", "N·m"), "m": ("m", "m/s", "N")}


def _csv_path(path) -> Path:
    path = Path(path)
    if path.suffix.lower() != ".csv":
        raise ConfigError(f"the drive record is written as CSV; name the file *.csv; "
                          f"got {path.name!r}")
    return path


def write_drive_csv(result: DriveResult, path: str | Path, *, units: str = "rad",
                    overwrite: bool = False, meta: dict | None = None) -> Path:
    """Write every body's position and velocity and the command as one CSV file.

    Parameters
    ----------
    result : DriveResult
        The simulated drive.
    path : str or Path
        Destination ``.csv`` file.
    units : {"rad", "m"}
        Rotational (rad, rad/s, N·m) or translational (m, m/s, N) labels.
    overwrite : bool
        Replace an existing file.
    meta : dict, optional
        Written as JSON on the ``# meta:`` line.

    Returns
    -------
    Path
        The written file. Columns ``t [s], x1 [rad], v1 [rad/s], x2 ..., command [N·m]``,
        bodies counted from 1; :func:`driveid.io.read_record` reads one body with e.g.
        ``columns={"x": "x2", "v": "v2", "u": "command"}`` (CLI: ``--position x2
        --velocity v2 --force command``).

    Raises
    ------
    OverwriteError
        If the file exists and ``overwrite`` is False.
    ConfigError
        If ``path`` does not end in ``.csv``.
    """
    path = _csv_path(path)
    ensure_writable(path, overwrite=overwrite)
    xu, vu, uu = _UNITS[units]
    names, columns = ["t [s]"], [result.t]
    for i in range(result.x.shape[0]):
        names += [f"x{i + 1} [{xu}]", f"v{i + 1} [{vu}]"]
        columns += [result.x[i], result.v[i]]
    names.append(f"command [{uu}]")
    columns.append(result.command)
    keep = np.all(np.isfinite(np.vstack(columns)), axis=0)  # rows after an abort are NaN
    from driveid.io.safe_write import atomic_open

    with atomic_open(path, "w", newline="\n", overwrite=overwrite) as fh:
        fh.write("# driveid record\n")
        fh.write(f"# meta: {json.dumps(to_jsonable(meta or {}))}\n")
        fh.write(",".join(names) + "\n")
        np.savetxt(fh, np.column_stack(columns)[keep], delimiter=",", fmt="%.17g")
    return path


@click.command("drive")
@click.argument("config", required=False,
                type=FilePath())
@click.option("--preset", "preset_name", type=click.Choice(sorted(PRESETS)), default=None,
              help="Simulate a preset instead of a CONFIG file (released from x0 = 1 rad "
                   "or 0.1 m).")
@click.option("--duration", type=float, default=None,
              help="Duration [s]; overrides the [run] table.")
@click.option("--out", "out", type=FilePath(), required=True,
              help="CSV file to write: t, x1, v1, x2, v2 ..., command.")
@click.option("--max-steps", type=PositiveFloat(max=1e18), default=float(DEFAULT_MAX_STEPS),
              show_default=True,
              help="Budget of RK4 steps: a longer run (a stiff contact or shaft needs a short "
                   "step) is refused before it starts.")
@click.option("--overwrite", is_flag=True, help="Overwrite an existing output file.")
@click.option("--force", "force_alias", is_flag=True, hidden=True,
              help="Old name of --overwrite.")
@clean_errors
def drive_command(config, preset_name, duration, max_steps, out, overwrite, force_alias):
    """Simulate the lumped drive described by CONFIG (TOML) or --preset; write a CSV record."""
    if (config is None) == (preset_name is None):
        raise click.UsageError("give either a CONFIG.toml file or --preset NAME (not both)")
    if config is not None:
        doc = read_toml(config, "drive config")  # once: parsed, and asked for a preset
        params, options = parse_drive_config(doc, source=Path(config).name)
        source = str(config)
        options = _start_a_resting_run(doc, params, options)
    else:
        params = preset(preset_name)
        units = preset_units(preset_name)
        options = RunOptions(units=units, x0=_release(units, params.n_bodies))
        source = f"preset {preset_name}"
    if duration is not None:
        try:
            options = dataclasses.replace(options, duration=duration)
        except ValueError as exc:
            raise ConfigError(f"--duration: {exc}") from None
    force = overwrite or force_alias
    ensure_writable(_csv_path(out), overwrite=force)  # fail before a long simulation
    max_steps = math.ceil(max_steps)
    cost = estimate_drive_cost(params, duration=options.duration, fs=options.fs,
                               method=options.method)
    check_drive_cost(cost, duration=options.duration, max_steps=max_steps)
    if cost.seconds > _ANNOUNCE_SECONDS:  # long but feasible: say so before the silence
        why = (f"the step resolves {cost.stiffest}" if cost.step < 0.999 / options.fs
               else "one step per output sample")
        click.echo(f"simulating {cost.n_steps:.3g} RK4 steps of {cost.step:.2g} s "
                   f"({cost.n_samples:.3g} samples; {why}): about "
                   f"{cost.seconds:.3g} s on one core", err=True)
    result = simulate_config(params, options, max_steps=max_steps)
    meta = {"source": "driveid simulate drive", "config": source,
            "run": dataclasses.asdict(options)}
    path = write_drive_csv(result, out, units=options.units, overwrite=True, meta=meta)
    kept = int(np.isfinite(result.x[0]).sum())
    click.echo(f"wrote {path} ({kept} sample{'s' if kept != 1 else ''}, {params.n_bodies} "
               f"bod{'y' if params.n_bodies == 1 else 'ies'}, "
               f"{result.n_impacts} impacts, {result.n_mode_switches} mode switches)")
    from driveid.io.record import MIN_SAMPLES

    if kept < MIN_SAMPLES:  # issue 28: a 1-sample file every reader then refused
        click.echo(f"warning: {path.name} holds {kept} sample{'s' if kept != 1 else ''}; "
                   f"driveid reads records of {MIN_SAMPLES} or more: lengthen [run] duration "
                   "(--duration) or raise [run] fs", err=True)
    active = [f"body {i + 1} (c_mean - |c_delta| = {b.c_mean - abs(b.c_delta):g})"
              for i, b in enumerate(params.bodies) if b.c_mean - abs(b.c_delta) < 0]
    if active:  # issue 28: a run that grew to 3e34 was silent
        finite = np.asarray(result.x, float)
        finite = finite[np.isfinite(finite)]
        reach = float(np.max(np.abs(finite))) if finite.size else math.inf
        click.echo(f"warning: negative viscous friction on {', '.join(active)} feeds energy "
                   f"in: the motion reaches |x| = {reach:.3g} (a self-excited drive; check "
                   "the config's signs)", err=True)
    _warn_unstable_loop(params, result)
    if result.aborted:
        click.echo(f"aborted: {result.abort_reason}")


def _warn_unstable_loop(params, result) -> None:
    """Warn when the delayed-PD loop diverges: its error grows tenfold over the run.

    A stable loop holds the feedback body near its reference; P = 5000 with a 50 ms delay
    (or P < 0) reached |x| = 8e176 with nothing on stderr (fifth hostile campaign).
    """
    fb = params.feedback
    if fb is None or result.aborted:  # an abort is said on its own line
        return
    err = np.asarray(result.x[fb.body], float) - fb.reference
    fifth = err.size // 5
    if fifth < 2:
        return
    first = float(np.nanmax(np.abs(err[:fifth]), initial=0.0))
    last = np.abs(err[-fifth:])
    reach = float(np.max(last)) if np.all(np.isfinite(last)) else math.inf
    if reach > 10.0 * first:
        fix = ("P < 0 pushes the body away from the reference: give P > 0" if fb.P < 0 else
               "lower P or the delay, or raise D (the delay adds a negative damping of about "
               "P·delay)")
        click.echo(f"warning: the feedback loop is unstable: body {fb.body + 1}'s distance "
                   f"from the reference grows from {abs(float(err[0])):.3g} at the start to "
                   f"{reach:.3g} (P = {fb.P:g}, D = {fb.D:g}, delay = {fb.delay:g} s); {fix}",
                   err=True)


def _release(units: str, n_bodies: int) -> tuple[float, ...]:
    """Return the release of a preset run [rad or m]: 1 rad or 0.1 m for every body."""
    return (1.0 if units == "rad" else 0.1,) * n_bodies


def _start_a_resting_run(doc, params, options):
    """Release a preset named in a TOML as ``--preset`` does, or warn that nothing moves.

    ``preset = "testbed-a"`` alone wrote a record of zeros, while the example TOML calls it
    equivalent to ``--preset testbed-a`` (released from 1 rad; fifth hostile campaign).
    ``identify drive`` keeps a missing x0 free (estimated), so this is the command's choice.
    """
    if options.x0 is not None or options.v0 is not None or options.torque is not None:
        return options
    if params.feedback is not None and params.feedback.reference != 0.0:
        return options
    if "preset" in doc:
        x0 = _release(options.units, params.n_bodies)
        click.echo(f"note: [run] sets no x0, v0 or torque: released from x0 = {x0[0]:g} "
                   f"{options.units}, as --preset does", err=True)
        return dataclasses.replace(options, x0=x0)
    click.echo("warning: [run] sets no x0, v0 or torque and nothing else moves the drive: "
               "the record will be at rest; set [run] x0 = [...] (initial positions) or "
               "torque = [...]", err=True)
    return options
