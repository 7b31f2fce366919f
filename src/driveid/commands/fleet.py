"""``driveid fleet identify`` (records on Dask into the catalogue), ``fleet simulate``."""

from __future__ import annotations

from pathlib import Path

import click

from driveid.commands import clean_errors
from driveid.commands._checks import SEED, BoundedInt
from driveid.commands._record_options import record_options
from driveid.commands.catalog import catalog_option, check_catalog_names_a_file
from driveid.errors import ConfigError

__all__ = ["fleet_group"]


@click.group("fleet")
def fleet_group():
    """Identify many records on Dask; simulated fleets."""


@fleet_group.command("identify")
@click.argument("patterns", nargs=-1, required=True)
@click.option("--method", type=click.Choice(["output-error", "logdec", "auto"]),
              default="output-error", show_default=True,
              help="Estimator run on every record: output-error, the whole-record fit that "
                   "'identify logdec' runs (near the Cramér-Rao bound); logdec, the peak log "
                   "decrement ('identify logdec --method peaks'); auto, what 'identify auto' "
                   "chooses for each record's test shape.")
@click.option("--mass", "--J", "mass", type=float, default=None,
              help="Known mass or inertia J [kg or kg·m²].")
@click.option("--stiffness", "--K", "stiffness", type=float, default=None,
              help="Known stiffness K [N/m or N·m/rad].")
@click.option("--machine-from-path", "path_pattern", default="{machine}/{axis}/{time}",
              show_default=True,
              help="How machine, axis and time are read from each path's last components: "
                   "placeholders {machine} {axis} {time} (ISO 8601 file name, else the file's "
                   "modification time) {type} and {*}.")
@click.option("--machine-type", default=None, help="Machine type of every record.")
@click.option("--workers", type=int, default=2, show_default=True,
              help="Worker processes of the local Dask cluster.")
@click.option("--scheduler", default=None, metavar="tcp://HOST:PORT",
              help="Use an existing Dask scheduler instead of a local cluster.")
@click.option("--scheduler-timeout", type=float, default=10.0, show_default=True,
              metavar="SECONDS",
              help="How long to try reaching --scheduler before giving up [s].")
@click.option("--batch-size", type=BoundedInt(10_000, min=1), default=None,
              help="Records per Dask task (default: batches that shrink as the work runs out, "
                   "at most 32 records, the last ones single records).")
@click.option("--quiet", is_flag=True, help="No progress bar.")
@catalog_option
@record_options
@clean_errors
def fleet_identify_command(patterns, method, mass, stiffness, path_pattern, machine_type,
                           workers, scheduler, scheduler_timeout, batch_size, quiet, catalog,
                           record_opts):
    """Identify every record matching PATTERNS ('traces/**/*.csv') into the catalogue.

    Dask tasks of a batch of records each, read inside the task; the catalogue is written
    from a thread as results arrive. A bad file becomes a catalogued failure
    with its error; records already catalogued (same SHA-256) are skipped, so an
    interrupted run resumes where it stopped.
    """
    try:
        import distributed  # noqa: F401

        from driveid.fleet import identify_many
    except ImportError as exc:
        raise ConfigError(f"fleet runs need the fleet extra ({exc.name} is missing); "
                          "pip install 'driveid[fleet]'") from None
    check_catalog_names_a_file(catalog)
    options = {k: v for k, v in (("mass", mass), ("stiffness", stiffness)) if v is not None}
    summary = identify_many(list(patterns), method=method, method_options=options,
                            record_options=record_opts, catalog=catalog, scheduler=scheduler,
                            n_workers=workers, path_pattern=path_pattern,
                            machine_type=machine_type, progress=not quiet,
                            batch_size=batch_size, scheduler_timeout=scheduler_timeout)
    click.echo(f"{summary.n_found} records: {summary.n_ok} identified, {summary.n_failed} "
               f"failed, {summary.n_skipped} already catalogued; "
               f"{summary.records_per_second:.3g} records/s on {summary.n_workers} workers")


@fleet_group.command("simulate")
@click.argument("out_dir", type=click.Path(file_okay=False, path_type=Path))
@click.option("--axes", "n_axes", type=int, default=200, show_default=True, help="Axes.")
@click.option("--months", "n_months", type=int, default=12, show_default=True,
              help="Monthly measurements per axis.")
@click.option("--faulty", "faulty_fraction", type=float, default=0.1, show_default=True,
              help="Fraction of axes with an injected fault.")
@click.option("--seed", type=SEED, default=0, show_default=True, help="Random seed.")
@click.option("--max-records", type=click.IntRange(min=1), default=100_000, show_default=True,
              help="Most records (axes x months) written without this override.")
@click.option("--overwrite", is_flag=True, help="Replace an existing simulated fleet.")
@clean_errors
def fleet_simulate_command(out_dir, n_axes, n_months, faulty_fraction, seed, max_records,
                           overwrite):
    """Write a simulated fleet of free decays with known faults to OUT_DIR (and truth.csv)."""
    from driveid.sim.fleet import RECORD_BYTES, simulate_fleet

    n = n_axes * n_months
    if 10_000 < n <= max_records:  # long but within the budget: say so first
        click.echo(f"simulating {n} records ({n_axes} axes x {n_months} months), about "
                   f"{n * RECORD_BYTES / 1e9:.2g} GB and {n * 0.02 / 60:.2g} min here",
                   err=True)
    truth = simulate_fleet(out_dir, n_axes=n_axes, n_months=n_months,
                           faulty_fraction=faulty_fraction, seed=seed, overwrite=overwrite,
                           max_records=max_records)
    n_faulty = len({(r["machine"], r["axis"]) for r in truth.rows if r["fault"] != "none"})
    click.echo(f"wrote {len(truth.rows)} records of {n_axes} axes ({n_faulty} faulty) to "
               f"{out_dir}; truth in {out_dir / 'truth.csv'}")
