"""``driveid report RESULT.json [RESULT.json ...] -o report.html``: results into one HTML page."""

from __future__ import annotations

from pathlib import Path

import click

from driveid.commands import clean_errors
from driveid.commands._checks import FilePath

__all__ = ["report_command"]


@click.command("report")
@click.argument("results", nargs=-1, required=True, metavar="RESULT.json...",
                type=click.Path(exists=True, dir_okay=False, path_type=Path))
@click.option("-o", "--out", "out", required=True,
              type=FilePath(),
              help="HTML file to write (one self-contained file).")
@click.option("--title", default=None, help="Page title (default: the methods).")
@click.option("--overwrite", is_flag=True, help="Replace an existing output file.")
@clean_errors
def report_command(results, out, title, overwrite):
    """Write a self-contained HTML report of results saved with an identify command's --json.

    Several RESULT files are also compared side by side (e.g. the + and - runs of an axis).
    The page shows the inputs with their SHA-256, the parameters with 95 % intervals, the
    warnings and the command line that made each result; it opens offline in any browser.
    """
    from driveid.io.safe_write import check_destination
    from driveid.report.html import load_results, write_report

    check_destination(out, overwrite=overwrite)
    data = load_results(results)
    # each result shows the command line stored in it (the one that estimated it)
    path = write_report(data, out, title=title, overwrite=overwrite)
    click.echo(f"wrote {path} ({len(data)} result{'s' if len(data) > 1 else ''})")
