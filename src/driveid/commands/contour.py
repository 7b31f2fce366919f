"""``driveid simulate contour`` and ``driveid identify contour``: the circular contour test."""

from __future__ import annotations

import json
from pathlib import Path

import click
import numpy as np

from driveid.commands import clean_errors
from driveid.commands._checks import SEED, FilePath, PositiveFloat
from driveid.commands._output import emit, output_options
from driveid.commands._record_options import record_options
from driveid.errors import ConfigError, FileFormatError

__all__ = ["simulate_contour_command", "identify_contour_command", "write_contour_csv"]

_UNITS = {"t": "s", "u": "N"}


def write_contour_csv(columns: dict, path: str | Path, *, overwrite: bool = False,
                      meta: dict | None = None) -> Path:
    """Write the columns of a circle test as one CSV file (atomic, no silent overwrite).

    Parameters
    ----------
    columns : dict of str to ndarray, shape (n,)
        ``t`` [s], positions [m], commands ``u_<a>`` [N] (``ContourResult.columns``).
    path : str or Path
        Destination ``.csv`` file.
    overwrite : bool
        Replace an existing file.
    meta : dict, optional
        Written as JSON on the ``# meta:`` line.

    Returns
    -------
    Path
        The written file.

    Raises
    ------
    ConfigError
        If ``path`` does not end in ``.csv``.
    OverwriteError
        If the file exists and ``overwrite`` is False.
    """
    from driveid._json import to_jsonable
    from driveid.io import ensure_writable
    from driveid.io.safe_write import atomic_open

    path = Path(path)
    if path.suffix.lower() != ".csv":
        raise ConfigError(f"the circle record is written as CSV; name the file *.csv; got "
                          f"{path.name!r}")
    ensure_writable(path, overwrite=overwrite)
    names = [f"{n} [{_UNITS.get(n, _UNITS['u'] if n.startswith('u_') else 'm')}]"
             for n in columns]
    with atomic_open(path, "w", newline="\n", overwrite=overwrite) as fh:
        fh.write("# driveid record\n")
        fh.write(f"# meta: {json.dumps(to_jsonable(meta or {}))}\n")
        fh.write(",".join(names) + "\n")
        np.savetxt(fh, np.column_stack(list(columns.values())), delimiter=",", fmt="%.17g")
    return path


@click.command("contour")
@click.argument("config", type=FilePath())
@click.option("--out", type=FilePath(), required=True,
              help="CSV file to write: t, x_ref, y_ref, x, y, x_motor, y_motor, u_x, u_y.")
@click.option("--compensate", "compensate", default=None,
              type=FilePath(),
              help="RESULT.json of 'driveid identify contour': add its friction "
                   "feed-forward and backlash compensation (also simulated without, and "
                   "with the friction 20 % low and high).")
@click.option("--seed", type=SEED, default=None,
              help="Seed of the measurement noise; overrides [noise] seed.")
@click.option("--json", "as_json", is_flag=True,
              help="Print the radial error, glitches and reversal spikes as JSON.")
@click.option("--max-periods", type=PositiveFloat(max=1e18), default=1e7, show_default=True,
              help="Budget of control periods (Python controller calls) of a run, all axes.")
@click.option("--overwrite", is_flag=True, help="Overwrite an existing output file.")
@clean_errors
def simulate_contour_command(config, out, compensate, seed, as_json, max_periods, overwrite):
    """Circular contour test (ball bar) of two feed axes under PID control."""
    import dataclasses

    from driveid.identify.contour.circle import compensation_from_estimate
    from driveid.io import ensure_writable
    from driveid.sim.contour import simulate_contour
    from driveid.sim.contour_config import load_contour_config

    cfg = load_contour_config(config)
    if seed is not None:
        cfg = dataclasses.replace(cfg, noise=dataclasses.replace(cfg.noise, seed=seed))
    ensure_writable(out, overwrite=overwrite)  # fail before the simulation
    _announce_contour(cfg, max_periods, runs=1 if compensate is None else 4)
    comp = None
    if compensate is not None:
        from driveid.io.consistency import load_json

        try:
            data = load_json(Path(compensate).read_bytes(), Path(compensate).name,
                             constants=True)
        except OSError as exc:
            raise ConfigError(f"--compensate: cannot read {compensate}: {exc.strerror}; "
                              "check the path") from None
        except FileFormatError as exc:
            raise ConfigError(f"--compensate: {exc}; pass the --json output of 'driveid "
                              "identify contour'") from None
        if not isinstance(data, dict):
            raise ConfigError("--compensate: expected a driveid-result JSON object; got "
                              f"{type(data).__name__}")
        comp = compensation_from_estimate(data, config=cfg)
    result = simulate_contour(cfg, compensation=comp, max_periods=max_periods)
    summary = result.summary()
    if comp is not None:
        table = {"with": summary["radial_error"]}
        for label, factor in (("without", None), ("friction_low", 0.8),
                              ("friction_high", 1.2)):
            other = simulate_contour(cfg, compensation=None if factor is None else
                                     compensation_from_estimate(data, friction=factor,
                                                                config=cfg),
                                     max_periods=max_periods)
            table[label] = other.summary()["radial_error"]
        table["peak_ratio"] = table["without"]["peak"] / max(table["with"]["peak"], 1e-300)
        summary["compensation"] = {"axes": {a: dataclasses.asdict(c) for a, c in comp.items()},
                                   "radial_error": table}
    meta = {"source": "driveid simulate contour", "config": str(config),
            "path": dataclasses.asdict(cfg.path), "compensated": comp is not None}
    path = write_contour_csv(result.columns(cfg.noise), out, overwrite=True, meta=meta)
    if as_json:
        from driveid._json import to_jsonable

        click.echo(json.dumps(to_jsonable(summary), indent=2))
        return
    err = summary["radial_error"]
    click.echo(f"wrote {path} ({result.t.size} samples); radial error rms "
               f"{err['rms'] * 1e6:.3g} µm, peak {err['peak'] * 1e6:.3g} µm")
    for g in summary["glitches"]:
        click.echo(f"  glitch {g['axis']} at {g['where_deg']:6.1f}°: {g['height'] * 1e6:+.3g} "
                   f"µm, width {g['width_deg']:.3g}°")
    if comp is not None:
        tab = summary["compensation"]["radial_error"]
        click.echo(f"  peak without compensation {tab['without']['peak'] * 1e6:.3g} µm, with "
                   f"{tab['with']['peak'] * 1e6:.3g} µm ({tab['peak_ratio']:.3g}x), friction "
                   f"-20 % {tab['friction_low']['peak'] * 1e6:.3g} µm, +20 % "
                   f"{tab['friction_high']['peak'] * 1e6:.3g} µm")


@click.command("contour")
@click.argument("file", metavar="FILE[@T0:T1]")
@click.option("--config", "config", type=FilePath(),
              required=True, help="AXES.toml the test ran on (masses, links, controller, "
                                  "path).")
@click.option("--min-speed", "min_speed", type=float, default=0.2, show_default=True,
              help="Leave out samples slower than this fraction of the feed (reversals).")
@click.option("--no-preview", is_flag=True,
              help="Skip the validation and compensation simulations (faster).")
@record_options
@output_options
@clean_errors
def identify_contour_command(file, config, min_speed, no_preview, record_opts, output_opts):
    """Circle test: each axis's Coulomb, viscous friction and backlash gap."""
    from driveid.commands._record_options import split_window_spec
    from driveid.identify.contour.circle import estimate_contour, read_contour_record
    from driveid.sim.contour_config import load_contour_config

    if record_opts.columns:
        raise click.UsageError("identify contour reads its columns by name (t, x_ref, x, "
                               "x_motor, u_x, ...); drop --position/--velocity/--force")
    cfg = load_contour_config(config)
    path, window = split_window_spec(file)
    kwargs = record_opts.read_kwargs(None if window == (None, None) else window)
    record = read_contour_record(path, cfg.path.axes, **kwargs)
    est = estimate_contour(record, cfg, min_speed_fraction=min_speed,
                           validate=not no_preview, compensation=not no_preview)

    def figure():
        from driveid.report.contour_figures import plot_contour_estimate

        return plot_contour_estimate(est)

    return emit(est, output_opts, figure=figure)


def _announce_contour(cfg, max_periods, *, runs):
    """Refuse over budget, else say what a long run costs and what long ramps do.

    A 1000 s feed ramp on a 3 s circle ran silent for minutes (fifth hostile campaign).
    """
    import math

    from driveid.sim.contour import SECONDS_PER_PERIOD, check_contour_cost

    path = cfg.path
    ramp_turns = path.feed * path.ramp / (2 * math.pi * path.radius)  # both ramps together
    if ramp_turns > path.revolutions:
        click.echo(f"warning: the feed ramps ([path] ramp = {path.ramp:g} s each) travel "
                   f"{ramp_turns:.3g} revolutions, more than the {path.revolutions:g} at "
                   "constant feed: most of the record is ramp; shorten [path] ramp", err=True)
    rate = min(a.controller.rate for a in cfg.axes.values())
    if path.constant_feed * rate < 100:
        # a 1e4 m/s feed or a 1 nm radius: the circle passes between two control periods
        # and the result read as a 9.7 km radial error (fifth hostile campaign)
        click.echo(f"warning: the circle at constant feed lasts {path.constant_feed:.3g} s, "
                   f"{path.constant_feed * rate:.3g} control periods at {rate:g} Hz: no "
                   "controller follows it and the radial error measures that; lower [path] "
                   "feed or raise radius (a ball bar runs hundreds of periods a turn)", err=True)
    seconds = runs * check_contour_cost(cfg, max_periods) * SECONDS_PER_PERIOD
    if seconds > 10.0:
        click.echo(f"note: simulate contour: {path.duration:.4g} s of path, about "
                   f"{seconds:.3g} s on one core (an estimate)", err=True)
