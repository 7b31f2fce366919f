"""``driveid identify auto``: classify the test shape and identify with what applies."""

from __future__ import annotations

import click

from driveid.commands import clean_errors
from driveid.commands._output import emit, output_options
from driveid.commands._record_options import record_options

__all__ = ["auto_command"]


@click.command("auto")
@click.argument("files", nargs=-1, required=True, metavar="FILE[@T0:T1]...")
@click.option("--mass", "--J", "mass", type=float, default=None,
              help="Known mass or inertia J [kg or kg·m²] (free decays).")
@click.option("--stiffness", "--K", "stiffness", type=float, default=None,
              help="Known stiffness K [N/m or N·m/rad].")
@record_options
@output_options
@clean_errors
def auto_command(files, mass, stiffness, record_opts, output_opts):
    """Recognise the test in FILES and identify with what applies.

    Prints the test shape with its evidence, the method chosen and why, the other methods'
    values, and the next test that would identify what these records cannot.
    """
    from driveid.identify.auto import identify_auto

    records = record_opts.read_all(files)
    if not output_opts.quiet:
        click.echo("reading done; classifying and fitting", err=True)
    def say(name):  # each candidate as it starts: a 5e6-row record was a minute of silence
        click.echo(f"fitting: {name} ({sum(r.n for r in records):,} samples)", err=True)

    est = identify_auto(records, mass=mass, stiffness=stiffness,
                        progress=None if output_opts.quiet else say)
    auto = est.diagnostics["auto"]
    lines = [f"test shape: {auto['shape']} ({'; '.join(auto['evidence'])})",
             f"method: {est.method} - {auto['reason']}"]
    others = [c for c in auto["candidates"] if c["name"] != auto["chosen"]]
    for c in others:
        if c["ok"]:
            values = ", ".join(f"{k} {v[0]:.4g}" for k, v in list(c["parameters"].items())[:6])
            lines.append(f"also {c['name']}: {values}")
        else:
            lines.append(f"also {c['name']}: failed ({c['error'][:160]})")
    lines.append(f"next test: {auto['next_test']}")
    emit(est, output_opts, records=records, header="\n".join(lines))
