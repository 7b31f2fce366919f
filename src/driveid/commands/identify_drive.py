"""``driveid identify drive`` and ``driveid identify subsystems``: the whole lumped drive."""

from __future__ import annotations

import math
import re

import click

from driveid.commands import clean_errors
from driveid.commands._checks import FilePath, NonNegativeFloat, PositiveFloat
from driveid.commands._output import emit, output_options
from driveid.commands._record_options import record_options, split_window_spec
from driveid.identify.drive._drive_model import DEFAULT_FIT_STEPS

__all__ = ["drive_command", "subsystems_command", "read_drive_records"]

_CHANNEL = re.compile(r"^[xv][1-9][0-9]*$")


def _pairs(values, option: str) -> dict[str, str]:
    out = {}
    for item in values:
        key, sep, column = item.partition("=")
        if not sep or not _CHANNEL.match(key.strip()) or not column.strip():
            raise click.UsageError(f"{option} takes CHANNEL=COLUMN with CHANNEL like x1, v2; "
                                   f"got {item!r}")
        out[key.strip()] = column.strip()
    return out


def read_drive_records(files, record_opts, *, channels: dict[str, str] | None = None,
                       input_column: str | None = None, n_bodies: int):
    """Read drive records, ``PATH@T0:T1`` windows and the reading options applied.

    See :func:`driveid.identify.drive.records.read_drive_record`; ``files`` are ``PATH`` or
    ``PATH@T0:T1`` each and ``record_opts`` the shared :class:`RecordOptions`.
    """
    from driveid.identify.drive.records import read_drive_record as read

    specs = [split_window_spec(spec) for spec in files]
    return [read(path, read_kwargs=record_opts.read_kwargs(None if window == (None, None)
                                                            else window),
                 time_column=record_opts.columns.get("t"), channels=channels,
                 input_column=input_column, n_bodies=n_bodies)
            for path, window in specs]


def _piece_option(text: str) -> float | None:
    """``--pieces``: None for auto, else the piece length [s] (0: never)."""
    if text.strip().lower() == "auto":
        return None
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value >= 0):
        raise click.UsageError(f"--pieces takes a length in seconds >= 0 (0: never) or auto; "
                               f"got {text}")
    return value


def _pieces_line(info: dict) -> str:
    """Return the fit's stages in plain words (one line under the header)."""
    retry = info.get("short_horizon_retry")
    again = "" if not retry else (
        f" (ended {retry['residual_to_noise']:.3g} times the noise, so fitted again from "
        f"{retry['segment']:g} s heads: {retry['retried_residual_to_noise']:.3g} times, "
        + ("kept)" if retry["kept"] else "not kept)"))
    paths = info.get("paths")
    if paths:
        again += (f" from {len(paths['segments'])} first horizons ("
                  + ", ".join(f"{seg:g} s" for seg in paths["segments"])
                  + f"), the lowest cost kept ({paths['segments'][paths['kept']]:g} s: "
                  + ", ".join(f"{c:.4g}" for c in paths["cost_to_noise"])
                  + " times the noise's squared residual)")
    rest = info.get("start_at_rest")
    if rest:
        again += (f"; start velocities held at 0 changed the squared residual over the "
                  f"noise by {rest['delta_chi2']:+.3g} (motion at the start shows above "
                  f"{rest['limit']:.3g}"
                  + (f"; {rest['first_delta_chi2']:+.3g} from the first horizon, so fitted "
                     "from the others too" if "first_delta_chi2" in rest else "")
                  + "): the start at " + ("rest was kept" if rest["at_rest"] else
                                          "rest was refused"))
    if not info["done"]:
        return "fit: the whole record" + again + (
            "" if info["whole_record_white"] else
            " (its residual is not white: see the warnings)")
    why = ("over a whole record an open-loop drive with backlash or a poor residual is so "
           "sensitive that its error bars would be far too short")
    halved = info.get("halved_from")
    if halved:
        why += (f"; {halved['length']:g} s pieces left {halved['not_white']} of "
                f"{halved['channels']} channels not white, so they were halved")
    ridge = info.get("ridge_restarts") or {}
    if ridge.get("tried"):
        why += (f"; their fit stalled at {ridge['cost_to_noise']:.3g} times the noise's "
                f"squared residual (the median piece) and was restarted {ridge['tried']} "
                f"times along its principal axis of uncertainty ({ridge['taken']} kept, now "
                f"{ridge['final_cost_to_noise']:.3g} times)")
    return (f"fit: the whole record{again}, then {info['n_pieces']} pieces of "
            f"{info['length']:g} s "
            f"with their own initial states ({why}); values and error bars are the "
            "pieces' fit's")


@click.command("drive")
@click.argument("config", type=FilePath())
@click.argument("files", nargs=-1, required=True, metavar="FILE[@T0:T1]...")
@click.option("--estimate", "estimate", required=True,
              help="Parameters to estimate, comma-separated, named as in the TOML "
                   "(bodies and links from 1): body1.J,body1.fk_mean,link1.gap_plus,...")
@click.option("--channel", "channel", multiple=True, metavar="CHANNEL=COLUMN",
              help="Read channel x1, v2 ... from another column (repeatable).")
@click.option("--input", "input_column", default=None,
              help="Column of the input torque/force u (default: command or u).")
@click.option("--input-body", type=int, default=None,
              help="Body (from 1) the input acts on (default: [feedback] body, else 1).")
@click.option("--segment", type=NonNegativeFloat(), default=0.5, show_default=True,
              help="First fit the first SECONDS of each record, then twice as long, and so "
                   "on to the whole records [s] (0: whole records only).")
@click.option("--pieces", default="auto", show_default=True, metavar="SECONDS|auto",
              help="Open loop: re-fit the records cut into pieces of this length [s], each "
                   "with its own initial state, from the whole-record fit, and report that "
                   "fit's error bars; auto: 0.5 s pieces for a drive with backlash or a "
                   "whole-record residual that is not white or above the noise; 0: never.")
@click.option("--paths", type=click.IntRange(1, 3), default=None,
              help="Whole-record fits from first horizons of --segment, a fifth and a half "
                   "of it, the lowest-cost kept [default: 3 for a drive with backlash under "
                   "[feedback], else 1].")
@click.option("--rest-test/--no-rest-test", default=True, show_default=True,
              help="Where start velocities are estimated, fit them held at 0 too and keep "
                   "that start at rest unless the record shows motion (a likelihood-ratio "
                   "test); [run] v0 in the TOML gives them instead.")
@click.option("--white", is_flag=True, help="White noise only (no AR noise model).")
@click.option("--max-steps", type=PositiveFloat(max=1e18), default=float(DEFAULT_FIT_STEPS),
              show_default=True,
              help="Budget of RK4 steps of the whole fit, estimated before it starts.")
@click.option("--model-out", type=FilePath(), default=None,
              help="Write the identified drive as TOML (simulate drive re-runs it).")
@record_options
@output_options
@clean_errors
def drive_command(config, files, estimate, channel, input_column, input_body, segment, pieces,
                  paths, rest_test, white, max_steps, model_out, record_opts, output_opts):
    """Fit the lumped drive of CONFIG (TOML) to motor and load records."""
    from driveid.identify.drive.drive_fit import estimate_drive
    from driveid.io.safe_write import atomic_write_text
    from driveid.sim.config import load_drive_config

    params, run = load_drive_config(config)
    names = [n.strip() for n in estimate.split(",") if n.strip()]
    piece_length = _piece_option(pieces)
    if input_body is not None and not 1 <= input_body <= params.n_bodies:
        raise click.UsageError(f"--input-body counts bodies from 1 to {params.n_bodies} (the "
                               f"drive of {config.name if hasattr(config, 'name') else config})"
                               f"; got {input_body}")
    if model_out is not None:
        from driveid.io import ensure_writable

        ensure_writable(model_out, overwrite=output_opts.overwrite)
    records = read_drive_records(files, record_opts, channels=_pairs(channel, "--channel"),
                                 input_column=input_column, n_bodies=params.n_bodies)
    from driveid.commands._progress import progress_bar

    def advance(done, expected):
        # the fit's length is estimated before it starts: the bar grows past the estimate
        bar.total = max(expected, done)
        bar.update(done - bar.n)

    with progress_bar(1, "drive fit: simulations (expected count estimated)",
                      quiet=output_opts.quiet, unit="sim") as bar:
        est = estimate_drive(records, params, estimate=names, x0=run.x0, v0=run.v0,
                             input_body=None if input_body is None else input_body - 1,
                             torque=run.torque, units=run.units, noise_model=not white,
                             segment=segment or None, max_steps=max_steps,
                             pieces=piece_length, paths=paths, test_rest=rest_test,
                             progress=advance)
    if model_out is not None:
        atomic_write_text(model_out, est.diagnostics["model_toml"],
                          overwrite=output_opts.overwrite)
    emit(est, output_opts, records=records,
         header=f"method: {est.method}   samples: {est.diagnostics['n_samples']}   "
                f"simulations: {est.diagnostics['n_simulations']}\n"
                + _pieces_line(est.diagnostics["pieces"]))
    if model_out is not None and not output_opts.as_json:
        click.echo(f"wrote {model_out}")


@click.command("subsystems")
@click.argument("manifest", type=FilePath())
@output_options
@clean_errors
def subsystems_command(manifest, output_opts):
    """Fit sections A, A+B, A+B+C; each part as their difference."""
    from driveid.identify.drive.subsystems import estimate_subsystems

    result = estimate_subsystems(manifest)
    emit(result, output_opts, header="sections fitted in sequence; parts as differences "
                                     "(thesis §4.1, Table 5.2)")
    if not output_opts.as_json:
        click.echo("")
        click.echo(result.diagnostics["table"])
