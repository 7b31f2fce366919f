"""``driveid validate RESULT.json FILE...``: simulate an identified model on records."""

from __future__ import annotations

import json
import math
from pathlib import Path

import click

from driveid.commands import clean_errors
from driveid.commands._checks import FilePath
from driveid.commands._output import cli_text
from driveid.commands._record_options import RecordOptions, record_options
from driveid.errors import FileFormatError, IdentificationError

__all__ = ["validate_command"]

SCHEMA = "driveid-validate/1"


def _load_estimate(path: Path):
    from driveid.identify.core.estimate import Estimate
    from driveid.io.consistency import load_json

    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise FileFormatError(f"cannot read the result file {path}: {exc.strerror}") from None
    try:  # nesting thousands deep was a RecursionError (exit 70)
        data = load_json(raw, str(path), constants=True)
    except FileFormatError as exc:
        raise FileFormatError(f"{exc}; pass the file written by an identify command's "
                              "--json") from None
    if not isinstance(data, dict) or "parameters" not in data:
        raise FileFormatError(
            f"{path} has no 'parameters': pass the JSON written by an identify command's "
            "--json (schema driveid-result/1)")
    try:
        return Estimate.from_dict(data)
    except (ValueError, KeyError, TypeError) as exc:
        raise FileFormatError(
            f"{path} is not a driveid result ({exc}); pass the JSON written by an identify "
            "command's --json") from None


def _index_of(record, estimate, position: int, n_files: int):
    """Which of the estimate's records this file is (by content hash), or None (held out)."""
    digest = record.meta.get("sha256")
    hashes = [i.get("sha256") for i in estimate.inputs]
    if digest and digest in hashes:
        return hashes.index(digest)
    releases = estimate.data_used.get("release_x")
    n_fitted = len(releases) if releases is not None else \
        estimate.diagnostics.get("n_records")
    if not any(hashes) and n_fitted == n_files:
        return position  # an estimate of the same files, in the same order, without hashes
    return None


def _stored_reading(path: Path, estimate, position: int, n_files: int) -> dict | None:
    """Return the reading options stored in the result for this file, or None."""
    from driveid.io.reading import file_sha256

    inputs = [dict(i) for i in estimate.inputs]
    if not any(i.get("reading") for i in inputs):
        return None
    try:
        digest = file_sha256(path)
    except OSError:
        digest = None
    for item in inputs:
        if digest and item.get("sha256") == digest:
            return dict(item.get("reading") or {})
    for item in inputs:
        if item.get("path") and Path(str(item["path"])).name == path.name:
            return dict(item.get("reading") or {})
    if len(inputs) == n_files:
        return dict(inputs[position].get("reading") or {})
    readings = {json.dumps(i.get("reading") or {}, sort_keys=True) for i in inputs}
    return json.loads(readings.pop()) if len(readings) == 1 else None


def _read_as_estimated(files, estimate, record_opts: RecordOptions, result: Path) -> list:
    """Read FILEs with the reading options stored in the result, unless options are given."""
    import dataclasses

    from driveid.commands._record_options import reading_as_cli, split_window_spec
    from driveid.io.consistency import warn_duplicates

    if not dataclasses.replace(record_opts, window=(None, None)).is_default():
        return record_opts.read_all(files)  # options given: they win
    records = []
    for k, spec in enumerate(files):
        path, _ = split_window_spec(spec)
        reading = _stored_reading(path, estimate, k, len(files))
        opts = record_opts
        if reading:  # the stored reading, in the window asked for (--t-start, FILE@T0:T1)
            opts = dataclasses.replace(RecordOptions.from_reading(reading),
                                       window=record_opts.window)
            click.echo(f"note: {path.name}: read with the options stored in {result.name}: "
                       f"{reading_as_cli(reading)}", err=True)
        records.append(opts.read(spec))
    warn_duplicates(records)
    return records


@click.command("validate")
@click.argument("result", type=click.Path(exists=True, dir_okay=False, path_type=Path))
@click.argument("files", nargs=-1, required=True, metavar="FILE[@T0:T1]...")
@click.option("--lags", type=click.IntRange(1, 1000), default=20, show_default=True,
              help="Autocorrelation lags of the Ljung–Box whiteness test.")
@click.option("--inertia", type=float, default=None,
              help="Inertia J [kg·m² or kg] of a friction-map model (default: fitted to "
                   "each record).")
@click.option("--json", "as_json", is_flag=True, help="Print the result as JSON.")
@click.option("--figure", type=FilePath(), default=None,
              help="Write an overlay/residual figure (PNG, PDF or SVG).")
@click.option("--overwrite", is_flag=True, help="Replace an existing figure.")
@record_options
@clean_errors
def validate_command(result, files, lags, inertia, as_json, figure, overwrite, record_opts):
    """Simulate the model identified in RESULT.json on FILEs: fit %, residual whiteness.

    RESULT.json is the --json of a free-decay (logdec, output error), PHO, forced, IDIM,
    friction-map or drive (identify drive: every measured channel, FILE:x1 ...)
    identification. Each FILE is simulated with its own input u and initial
    state: a PHO run in its PD loop (gains P, D and release x0 from the file's meta line),
    a forced, IDIM or friction-map run driven by its u. A FILE the estimate was not
    computed from is held out, and its residual rms is the prediction error. Without
    reading options, each FILE is read with the options stored in RESULT.json (its
    columns, units, scales, --max-jitter), as the identification read it.
    """
    from driveid.validate import compare

    estimate = _load_estimate(result)
    if estimate.method == "drive-oe":  # every measured channel of every file (issue 25)
        labels, comparisons = _compare_drive(files, estimate, record_opts, lags)
    else:
        records = _read_as_estimated(files, estimate, record_opts, result)
        comparisons = []
        for k, record in enumerate(records):
            index = _index_of(record, estimate, k, len(records))
            comparisons.append(compare(record, estimate, index=index, lags=lags,
                                       inertia=inertia))
        labels = [str(f) for f in files]
    if figure is not None:
        import matplotlib.pyplot as plt

        from driveid.report.figures import save_figure

        # at most 4 records side by side; more wrap into further rows of 3 panels
        cols = min(len(comparisons), 4)
        groups = -(-len(comparisons) // cols)
        fig, axes = plt.subplots(3 * groups, cols, figsize=(6 * cols, 6.5 * groups),
                                 constrained_layout=True, squeeze=False)
        for k in range(groups * cols):
            panel = axes[3 * (k // cols):3 * (k // cols) + 3, k % cols]
            if k >= len(comparisons):
                for ax in panel:
                    ax.set_axis_off()
                continue
            comparisons[k].plot(ax=panel)
            panel[0].set_title(labels[k], fontsize="small")
        save_figure(fig, figure, overwrite=overwrite)
    for spec, c in zip(labels, comparisons, strict=True):
        for message in c.warnings:
            click.echo(f"warning: {spec}: {cli_text(message)}", err=True)
    fits = [c.fit for c in comparisons]
    n_total = sum(c.t.size for c in comparisons)
    rms = math.sqrt(sum(c.residual_rms**2 * c.t.size for c in comparisons) / n_total)
    held = [c for c in comparisons if c.held_out]
    prediction = math.sqrt(sum(c.residual_rms**2 * c.t.size for c in held)
                           / sum(c.t.size for c in held)) if held else None
    if as_json:
        out = {
            "schema": SCHEMA,
            "method": estimate.method,
            "kind": comparisons[0].model.get("kind"),
            "result": str(result),
            "fit": min(fits),
            "residual_rms": rms,
            "prediction_error": prediction,
            "whiteness": {"white": all(c.whiteness["white"] for c in comparisons),
                          "p_value": min(c.whiteness["p_value"] for c in comparisons),
                          "white_through_noise_model": all(
                              _white_cell(c.whiteness) != "NO" for c in comparisons),
                          "test": "ljung-box", "lags": lags},
            "records": [dict(c.to_dict(), path=spec)
                        for spec, c in zip(labels, comparisons, strict=True)],
        }
        click.echo(json.dumps(out, indent=2))
        return
    if not comparisons:
        raise IdentificationError("no record to validate")
    click.echo(f"model: {comparisons[0].model.get('kind')} ({estimate.method}), simulated "
               "with each record's input and initial state")
    rows = [("file", "fit %", "residual rms", "Ljung–Box p", "white", "held out")]
    for spec, c in zip(labels, comparisons, strict=True):
        rows.append((spec, f"{c.fit:.3f}", f"{c.residual_rms:.3g}",
                     f"{c.whiteness['p_value']:.3g}", _white_cell(c.whiteness),
                     "yes" if c.held_out else "no"))
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    for n, row in enumerate(rows):
        click.echo("  ".join(cell.ljust(w) for cell, w in zip(row, widths, strict=True)))
        if n == 0:
            click.echo("  ".join("-" * w for w in widths))


def _compare_drive(files, estimate, record_opts, lags):
    """Read each FILE as the drive fit did and compare every channel (``FILE:x1`` ...)."""
    from driveid.commands._record_options import split_window_spec
    from driveid.commands.identify_drive import read_drive_records
    from driveid.io.reading import file_sha256
    from driveid.validate_drive import compare_drive, drive_of

    params, _ = drive_of(estimate)
    inputs = [dict(i) for i in estimate.inputs]
    hashes = [i.get("sha256") for i in inputs]
    labels, comparisons = [], []
    for k, spec in enumerate(files):
        path, window = split_window_spec(spec)
        digest = file_sha256(path) if path.is_file() else None
        index = hashes.index(digest) if digest and digest in hashes else None
        stored = inputs[index if index is not None else min(k, len(inputs) - 1)] \
            if inputs else {}
        columns = dict(stored.get("columns") or {})
        (record,) = read_drive_records(
            [spec], record_opts,
            channels={c: f for c, f in columns.items() if c[:1] in "xv" and c[1:].isdigit()},
            input_column=columns.get("u"), n_bodies=params.n_bodies)
        if index is not None and window != (None, None):
            index = None  # a window of a fitted file starts elsewhere: its state is fitted anew
        for name, c in compare_drive(record, estimate, index=index, lags=lags).items():
            labels.append(f"{spec}:{name}")
            comparisons.append(c)
    return labels, comparisons


def _white_cell(white):
    """Return the table's white cell: yes, NO, or "after AR(p)" (coloured as expected)."""
    if white["white"]:
        return "yes"
    pre = white.get("prewhitened")
    return f"after {pre['noise_model']}" if pre and pre["white"] else "NO"
