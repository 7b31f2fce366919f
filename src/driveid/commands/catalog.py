"""``driveid catalog add | list | export``: the catalogue of identifications."""

from __future__ import annotations

import json
from pathlib import Path

import click

from driveid.commands import clean_errors
from driveid.commands._checks import FilePath
from driveid.errors import ConfigError, FileFormatError
from driveid.io.consistency import load_json

__all__ = ["catalog_group", "catalog_option", "open_catalog", "check_catalog_names_a_file"]

_CATALOG_HELP = ("Catalogue: a SQLite file, sqlite:///FILE or postgresql://user@host/db "
                 "[default: ./driveid-catalog.sqlite in the working directory].")


def catalog_option(func):
    """Add ``--catalog FILE|URL`` to a command."""
    return click.option("--catalog", "catalog", default=None, metavar="FILE|URL",
                        help=_CATALOG_HELP)(func)


def open_catalog(catalog, *, create=True):
    """Open the catalogue, saying which extra to install when SQLAlchemy is missing."""
    try:
        from driveid.catalog import Catalog
    except ImportError as exc:
        raise ConfigError(f"the catalogue needs the fleet extra ({exc.name} is missing); "
                          "pip install 'driveid[fleet]'") from None
    check_catalog_names_a_file(catalog)
    return Catalog(catalog, create=create)


def check_catalog_names_a_file(catalog) -> None:
    """Refuse ``--catalog sqlite://`` and the like: an in-memory catalogue ends with the command.

    Parameters
    ----------
    catalog : str, Path or None
        The ``--catalog`` value (None: the default file).

    Raises
    ------
    ConfigError
        If it names a SQLite database without a file ('added as entry 1', nothing kept).
    """
    text = "" if catalog is None else str(catalog).strip()
    if text.startswith("sqlite") and text.split("://", 1)[-1].strip("/") in ("", ":memory:"):
        raise ConfigError(f"--catalog {text!r} names no file (SQLite would keep the catalogue "
                          "in memory and lose it when the command ends); name a file, e.g. "
                          "--catalog plant.sqlite or sqlite:///plant.sqlite")


@click.group("catalog")
def catalog_group():
    """Catalogue of identifications (SQLite/PostgreSQL).

    Add results, list them (failures included), export them.
    """


@catalog_group.command("add")
@click.argument("results", nargs=-1, required=True,
                type=click.Path(exists=True, dir_okay=False, path_type=Path))
@click.option("--machine", required=True, help="Machine the record was measured on.")
@click.option("--axis", required=True, help="Axis of that machine.")
@click.option("--machine-type", default=None, help="Machine type (for the blueprint).")
@click.option("--time", "measured_at", default=None,
              help="Measurement time, ISO 8601 (2026-03-01T08:30Z) [default: now, UTC].")
@catalog_option
@clean_errors
def catalog_add_command(results, machine, axis, machine_type, measured_at, catalog):
    """Add RESULTS (JSON from 'driveid identify ... --json') to the catalogue.

    The same inputs with the same method are added once: a second add reports the
    existing entry.
    """
    with open_catalog(catalog) as cat:
        for path in results:
            try:  # nesting thousands deep was a RecursionError (exit 70)
                result = load_json(path.read_bytes(), str(path), constants=True)
            except FileFormatError as exc:
                raise FileFormatError(f"{exc}; pass the output of 'driveid identify ... "
                                      "--json'") from None
            try:
                out = cat.add_result(result, machine=machine, axis=axis,
                                     measured_at=measured_at, machine_type=machine_type)
            except FileFormatError as exc:  # name the file: several may be added at once
                raise FileFormatError(f"{path}: {exc}") from None
            state = "added" if out.created else "already catalogued"
            click.echo(f"{path}: {state} as entry {out.entry_id}")


@catalog_group.command("list")
@click.option("--machine", default=None, help="Only this machine.")
@click.option("--axis", default=None, help="Only this axis.")
@click.option("--machine-type", default=None, help="Only this machine type.")
@click.option("--status", type=click.Choice(["ok", "failed"]), default=None,
              help="Only successes or failures.")
@click.option("--json", "as_json", is_flag=True, help="Print the entries as JSON.")
@catalog_option
@clean_errors
def catalog_list_command(machine, axis, machine_type, status, as_json, catalog):
    """List catalogued identifications, failures included with their error."""
    with open_catalog(catalog, create=False) as cat:
        found = cat.entries(machine=machine, axis=axis, machine_type=machine_type,
                            status=status)
    if as_json:
        click.echo(json.dumps([e.to_dict() for e in found], indent=2))
        return
    rows = [("id", "machine", "axis", "measured at (UTC)", "method", "status", "result")]
    for e in found:
        if e.status == "ok":
            estimated = sorted((n, p) for n, p in e.parameters.items() if not p.fixed)
            shown = ", ".join(f"{n}={p.value:.4g}±{p.stderr:.2g}" for n, p in estimated[:4])
        else:
            shown = e.error or ""
        rows.append((str(e.id), e.machine, e.axis, e.measured_at.isoformat(sep=" "),
                     e.method, e.status, shown))
    widths = [max(len(r[i]) for r in rows) for i in range(6)]
    for row in rows:
        click.echo("  ".join(c.ljust(w) for c, w in zip(row[:6], widths, strict=True))
                   + "  " + row[6])
    n_failed = sum(e.status == "failed" for e in found)
    click.echo(f"{len(found)} entries, {n_failed} failed")


@catalog_group.command("export")
@click.option("--csv", "csv_path", default=None,
              type=FilePath(), help="Write a CSV file.")
@click.option("--parquet", "parquet_path", default=None,
              type=FilePath(), help="Write a Parquet file.")
@click.option("--overwrite", is_flag=True, help="Replace an existing output file.")
@catalog_option
@clean_errors
def catalog_export_command(csv_path, parquet_path, overwrite, catalog):
    """Export the catalogue, one row per entry and parameter (failures: one row each)."""
    from driveid.io import ensure_writable

    if (csv_path is None) == (parquet_path is None):
        raise click.UsageError("give exactly one of --csv FILE or --parquet FILE")
    target = csv_path or parquet_path
    ensure_writable(target, overwrite=overwrite)
    with open_catalog(catalog, create=False) as cat:
        frame = cat.to_frame()
    from driveid.io.safe_write import atomic_save

    if csv_path is not None:
        atomic_save(csv_path, lambda fh: frame.to_csv(fh, index=False, mode="wb"),
                    overwrite=overwrite)
    else:
        atomic_save(parquet_path, lambda fh: frame.to_parquet(fh, index=False),
                    overwrite=overwrite)
    click.echo(f"wrote {target} ({len(frame)} rows, {frame['entry_id'].nunique()} entries)")
