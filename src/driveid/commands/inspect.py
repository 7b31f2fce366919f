"""``driveid inspect FILE``: show what driveid reads from a trace before trusting an estimate."""

from __future__ import annotations

import dataclasses
import json

import click
import numpy as np

from driveid._json import to_jsonable
from driveid.commands import clean_errors
from driveid.commands._record_options import RecordOptions, record_options

__all__ = ["inspect_command", "describe_reading"]

_WORDS = {"t": "time", "x": "position", "v": "velocity", "u": "force"}


def describe_reading(spec: str, record_opts: RecordOptions) -> dict:
    """Read a file as an identify command would and describe the reading.

    A file without a position column (a force-only logger, a speed-only drive log) is
    described too: what it holds, and that identify commands need a position.

    Parameters
    ----------
    spec : str
        ``PATH`` or ``PATH@T0:T1`` [s].
    record_opts : RecordOptions
        The shared record options (columns, fs, window, scale, units ...).

    Returns
    -------
    dict
        ``path``, ``format``, ``rows`` (in the file), ``samples`` (kept), ``fs`` [Hz],
        ``jitter`` [-], ``max_jitter``, ``accepted``, ``window`` [s], ``columns`` (every
        column found: ``index``, ``name``, ``unit``), ``chosen`` (record column -> file
        column), ``units_in_file``, ``units`` (SI), ``notes`` (preamble lines such as
        ``Device: ...``), ``reading_notes`` (columns chosen by convention, units assumed),
        ``position`` (``"column"``, ``"integrated velocity"`` or ``None``), and per chosen
        quantity ``t``, ``x``, ``v``, ``u``: ``{"column", "min", "max", "unit",
        "unit_in_file"}`` in SI.
    """
    from driveid.commands._record_options import split_window_spec
    from driveid.io.reading import convert_table, file_sha256
    from driveid.io.tables import read_table

    path, window = split_window_spec(spec)
    if window == (None, None):
        window = record_opts.window
    lenient = dataclasses.replace(record_opts, max_jitter=None)
    table = read_table(path)
    kwargs = lenient.read_kwargs(window)
    arrays, meta = convert_table(table, source=str(path), sha256=file_sha256(path),
                                 require=(), **kwargs)
    position: str | None = "column" if "x" in arrays else None
    if "x" in arrays or "v" in arrays:
        record = lenient.read(spec, position=False, notes=False)
        meta = dict(record.meta)
        values = {c: np.asarray(getattr(record, c)) for c in record.columns}
        units = {c: record.units[c] for c in record.columns}
        t = record.t
        if "derived" in meta:
            position = "integrated velocity"
    else:
        values = arrays
        units = {**meta["units"], "t": "s"}
        t = arrays["t"]
    dt = np.diff(t)
    nominal = float(np.median(dt)) if dt.size else float("nan")
    jitter = float(np.max(np.abs(dt - nominal)) / nominal) if dt.size else 0.0
    limit = record_opts.max_jitter
    out = {
        "path": meta["source"],
        "sha256": meta.get("sha256"),
        "format": meta.get("format"),
        "rows": meta.get("rows"),
        "samples": int(t.size),
        "fs": float(round(1.0 / nominal, 9)) if dt.size else None,
        "jitter": jitter,
        "max_jitter": limit,
        "accepted": limit is None or jitter <= limit,
        "window": meta.get("window"),
        "columns": [{"index": i, "name": name, "unit": table.units.get(name)}
                    for i, name in enumerate(table.columns)],
        "chosen": dict(meta.get("columns_used", {})),
        "units_in_file": dict(meta.get("units_in_file", {})),
        "units": units,
        "scale": dict(meta.get("scale", {})),
        "notes": dict(table.notes),
        "reading_notes": list(meta.get("notes", [])),
        "position": position,
    }
    if "fs_given" in meta:
        out["chosen"]["t"] = f"k/fs with fs = {meta['fs_given']:g} Hz"
    for col, vals in values.items():
        default = "derived" if col != "x" or position == "column" else "integrated velocity"
        out[col] = {"column": out["chosen"].get(col, default), "min": float(vals.min()),
                    "max": float(vals.max()), "unit": units.get(col, ""),
                    "unit_in_file": out["units_in_file"].get(col)}
    return out


@click.command("inspect")
@click.argument("file", metavar="FILE[@T0:T1]")
@record_options
@click.option("--json", "as_json", is_flag=True, help="Print the description as JSON.")
@clean_errors
def inspect_command(file, record_opts, as_json):
    """Show what is read from FILE: columns found and chosen, units, rate, jitter, ranges.

    Takes the same record options as the identify commands, so a user can check the
    reading before trusting an estimate.
    """
    info = describe_reading(file, record_opts)
    if as_json:
        click.echo(json.dumps(to_jsonable(info), indent=2))
        return
    click.echo(f"file: {info['path']}  ({info['format']})")
    click.echo(f"rows: {info['rows']} in the file, {info['samples']} kept; window "
               f"{info['window'][0]:.6g}..{info['window'][1]:.6g} s")
    verdict = "accepted" if info["accepted"] else (
        f"refused by --max-jitter {info['max_jitter']} (give --max-jitter none, or a larger "
        "fraction)")
    click.echo(f"sample rate: {info['fs']:.6g} Hz; jitter {100 * info['jitter']:.3g} % "
               f"({verdict})")
    click.echo("columns found: " + ", ".join(
        f"[{c['index']}] {c['name']}" + (f" [{c['unit']}]" if c["unit"] else "")
        for c in info["columns"]))
    click.echo(f"{'quantity':<9} {'column':<24} {'unit in file':<13} {'unit':<6} "
               f"{'min':>12} {'max':>12}")
    for col in ("t", "x", "v", "u"):
        if col in info:
            q = info[col]
            click.echo(f"{_WORDS[col]:<9} {str(q['column'])[:24]:<24} "
                       f"{q['unit_in_file'] or '(none)':<13} {q['unit']:<6} "
                       f"{q['min']:>12.6g} {q['max']:>12.6g}")
    for key, value in list(info["notes"].items())[:10]:
        click.echo(f"preamble: {key}: {value}")
    for note in info["reading_notes"]:
        click.echo(f"note: {note}")
    if info["position"] is None:
        click.echo("position: none in this file; commands that need a position (the "
                   "identify commands) refuse it; choose one with --position COL if it is "
                   "named otherwise")
    elif info["position"] == "integrated velocity":
        click.echo("position: none in this file; commands that use only the velocity read "
                   "it, with the position integrated from the velocity")
    if info["scale"]:
        click.echo("scaled: " + ", ".join(f"{k} x {v:g}" for k, v in info["scale"].items()))
