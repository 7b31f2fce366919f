"""``driveid identify friction-map`` and ``driveid identify idim``."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import click

from driveid.commands import clean_errors
from driveid.commands._output import cli_text, emit, noise_words, output_options
from driveid.commands._record_options import record_options, split_window_spec

__all__ = ["friction_map_command", "idim_command"]


def _scale(value: str | None) -> float | str | None:
    if value is None:
        return None
    try:
        return float(value)
    except ValueError:
        return value


def _legacy(record_opts: Any, force_column: str | None, force_scale: str | None,
            units: str | None) -> Any:
    """Fold the older --force-column/--force-scale/--units options into the record options."""
    columns = dict(record_opts.columns)
    if force_column and "u" not in columns:
        columns["u"] = force_column
    scale = dict(record_opts.scale)
    if force_scale is not None:
        scale.setdefault("u", _scale(force_scale))
    unit_map = dict(record_opts.units)
    if units == "m":
        unit_map = {"x": "m", "u": "N", "v": "m/s", **unit_map}
    elif units == "rad":
        unit_map = {"x": "rad", "u": "N·m", "v": "rad/s", **unit_map}
    return dataclasses.replace(record_opts, columns=columns, scale=scale, units=unit_map)


_legacy_options = [
    click.option("--force-column", default=None, hidden=True,
                 help="Old name of --force (the force/torque column)."),
    click.option("--force-scale", default=None,
                 help="Factor on the force column: a number or the name of a scalar "
                      "variable in FILE (EMPS: gtau); same as --scale u=F."),
    click.option("--units", type=click.Choice(["m", "rad"]), default=None,
                 help="Translational (m, N) or rotational (rad, N·m); default from FILE."),
]


def _with_legacy(func: Any) -> Any:
    for option in reversed(_legacy_options):
        func = option(func)
    return func


@click.command("idim")
@click.argument("files", nargs=-1, required=True, metavar="FILE[@T0:T1]...")
@click.option("--validate", "validate_file", default=None,
              help="Record for the cross-test (same θ, its observation matrix).")
@click.option("--model", type=click.Choice(["symmetric", "asymmetric"]), default="symmetric",
              show_default=True, help="Coulomb + viscous + offset, or ± branches, no offset.")
@click.option("--cutoff-hz", type=float, default=None,
              help="Zero-phase Butterworth cut-off on the position [Hz] (default: 100 Hz, "
                   "or fs/10 of the slowest record when that is lower).")
@click.option("--decimate", type=int, default=10, show_default=True,
              help="Decimation factor of observation matrix and force [-]: rows are "
                   "means of this many samples (EMPS: 10); 1 uses every sample, more precise "
                   "under coloured force noise.")
@click.option("--offset", type=float, default=None,
              help="Known force offset [N or N·m], e.g. 0: runs in one direction become "
                   "identifiable.")
@click.option("--load", "load_column", default=None,
              help="Column of FILE holding a known load force [N or N·m] to subtract.")
@click.option("--load-expr", default=None,
              help="Known load as an expression of t x v a u, e.g. '1.47*sin(x)'.")
@click.option("--regressor", "regressors", multiple=True,
              help="Extra regressor with an unknown coefficient, an expression of t x v a u "
                   "with sin cos tanh sign abs exp sqrt, e.g. 'sin(x)'; repeatable.")
@click.option("--weights", default=None,
              help="'auto' (inverse residual variance per record) or one number per FILE, "
                   "comma-separated.")
@click.option("--min-speed", type=float, default=None,
              help="Drop rows slower than this [m/s or rad/s] (standstill rows always are).")
@click.option("--no-sensitivity", is_flag=True,
              help="Skip the estimates at the two neighbouring cut-offs.")
@click.option("--noise", type=click.Choice(["ar", "white"]), default="ar", show_default=True,
              help="Force-noise model: 'ar' fits AR(p) residuals and refits by generalised "
                   "least squares (honest error bars on coloured noise); 'white' is ordinary "
                   "least squares with white-noise error bars (the EMPS recipe).")
@click.option("--position-noise-std", type=float, default=None,
              help="White noise sd on the position [m or rad] (an encoder's count/sqrt(12)); "
                   "the inertia is corrected for it (errors in variables). Default: "
                   "estimated from the position's fourth differences; 0 turns it off.")
@click.option("--simulate", is_flag=True,
              help="Also simulate the closed loop (EMPS .mat files: reads qg, kp, kv, gtau "
                   "and pulses_N) and report position and force errors.")
@_with_legacy
@record_options
@output_options
@clean_errors
def idim_command(files, validate_file, model, cutoff_hz, decimate, offset, load_column,
                 load_expr, regressors, weights, min_speed, no_sensitivity, noise,
                 position_noise_std, simulate, force_column, force_scale, units, record_opts,
                 output_opts):
    """Identify inertia, Coulomb and viscous friction by inverse-model least squares.

    Several FILES are fitted in one least-squares problem (each filtered on its own).
    """
    from driveid.errors import ParameterError
    from driveid.identify.friction.idim import estimate_idim, validate_idim
    from driveid.report.friction_figures import plot_idim

    opts = _legacy(record_opts, force_column, force_scale, units)
    records = opts.read_all(files)
    if load_column and load_expr:
        raise ParameterError("give the load as a column (--load) or an expression "
                             f"(--load-expr), not both; got {load_column!r} and {load_expr!r}")
    load: Any = load_expr
    if load_column:
        load_opts = dataclasses.replace(
            opts, columns={**opts.columns, "u": load_column},
            scale={k: v for k, v in opts.scale.items() if k != "u"})
        load = [r.u for r in load_opts.read_all(files)]
    if cutoff_hz is None:  # the default follows the record: 100 Hz refused a 64.5 Hz log
        slowest = min(r.fs for r in records)
        cutoff_hz = min(100.0, slowest / 10.0)
        if cutoff_hz < 100.0:
            click.echo(f"note: --cutoff-hz {cutoff_hz:.4g} Hz (fs/10 of the {slowest:.4g} Hz "
                       "record; 100 Hz by default); give --cutoff-hz to choose", err=True)
    w: Any = None
    if weights:
        w = "auto" if weights.strip() == "auto" else _numbers(weights, "--weights")
    est = estimate_idim(records, model=model, cutoff_hz=cutoff_hz, decimate=decimate,
                        offset=offset, load=load, regressors=regressors, weights=w,
                        min_speed=min_speed, sensitivity=not no_sensitivity, noise=noise,
                        position_noise_std=position_noise_std)
    extra: dict[str, Any] = {}
    val = None
    if validate_file is not None:
        val = validate_idim(est, opts.read(validate_file))
        extra["validation"] = val.to_dict()
    if simulate:
        pairs = list(zip(files, records, strict=True))
        if validate_file is not None:
            pairs.append((validate_file, opts.read(validate_file)))
        extra["simulation"] = {split_window_spec(f)[0].name: _simulate_emps(
            est, rec, split_window_spec(f)[0]) for f, rec in pairs}
    if extra:
        est = dataclasses.replace(est, diagnostics={**est.diagnostics, **extra})
    d = est.diagnostics
    noise_line = (f"noise: {noise_words(d['noise_model'])}   error bars: "
                  f"{d['adequacy']['covariance']}")
    shown = emit(est, output_opts, records=records, figure=lambda: plot_idim(est, val),
                 header=f"method: {est.method}   N = {d['n']}   cond = {d['cond']:.4g}   "
                        f"relative error = {d['relative_error_pct']:.4g} %\n{noise_line}")
    if output_opts.as_json:
        return
    # the adequacy notes a warning did not already say (the velocity cross-correlation,
    # the slow-noise excess): before, they reached --json only
    for note in d["adequacy"]["notes"]:
        if note not in shown.warnings and not note.startswith("force residuals are coloured"):
            click.echo(f"note: {cli_text(note)}", err=True)
    if val is not None:
        click.echo(f"cross-test on {split_window_spec(validate_file)[0].name}: relative "
                   f"error {val.relative_error:.4g} %   cond = {val.cond:.4g}")
    for name, res in extra.get("simulation", {}).items():
        click.echo(f"direct simulation of {name}: position error "
                   f"{res['position_error_pct']:.4g} %   force error "
                   f"{res['force_error_pct']:.4g} %")


def _numbers(text: str, option: str) -> list[float]:
    try:
        return [float(p) for p in text.split(",") if p.strip()]
    except ValueError:
        raise click.BadParameter(f"{option} takes 'auto' or numbers separated by commas; "
                                 f"got {text!r}") from None


def _simulate_emps(est: Any, record: Any, path: Path) -> dict[str, float]:
    from driveid.errors import FileFormatError
    from driveid.identify.friction.idim import simulate_idim_model

    if path.suffix.lower() != ".mat":
        raise FileFormatError(f"--simulate reads the EMPS loop variables from a .mat file; "
                              f"got {path.name}")
    from scipy.io import loadmat

    d = loadmat(path)
    missing = [k for k in ("qg", "kp", "kv", "gtau") if k not in d]
    if missing:
        raise FileFormatError(f"--simulate needs the EMPS variables qg, kp, kv, gtau; "
                              f"{path.name} lacks {missing}")
    pulses = d["pulses_N"].ravel().astype(float) if "pulses_N" in d else None
    sim = simulate_idim_model(est, record, q_ref=d["qg"].ravel(), kp=float(d["kp"].item()),
                              kv=float(d["kv"].item()), gtau=float(d["gtau"].item()),
                              input_offset=pulses)
    return {"position_error_pct": sim.position_error_pct,
            "force_error_pct": sim.force_error_pct}


@click.command("friction-map")
@click.argument("files", nargs=-1, required=True, metavar="FILE[@T0:T1]|FOLDER...")
@click.option("--models", default="coulomb_viscous,lorentzian,bo_pavelescu,hess_soom",
              show_default=True, help="Comma-separated maps to fit.")
@click.option("--rel-tol", type=float, default=0.02, show_default=True,
              help="Steady-segment tolerance relative to the speed [-].")
@click.option("--min-samples", type=int, default=50, show_default=True,
              help="Shortest steady segment [samples].")
@click.option("--min-speed", type=float, default=None,
              help="Ignore steady points slower than this [m/s or rad/s].")
@click.option("--max-speed", type=float, default=None,
              help="Ignore steady points faster than this [m/s or rad/s].")
@click.option("--inertia", type=float, default=None,
              help="Known inertia J [kg or kg·m²]: bin F − J·a by velocity instead of "
                   "looking for steady plateaus (sinusoidal or triangular tests).")
@click.option("--bins", type=int, default=20, show_default=True,
              help="With --inertia: velocity bins per direction [-].")
@click.option("--cutoff-hz", type=float, default=None,
              help="Low-pass before differentiating the position [Hz] (default fs/20).")
@_with_legacy
@record_options
@output_options
@clean_errors
def friction_map_command(files, models, rel_tol, min_samples, min_speed, max_speed, inertia,
                         bins, cutoff_hz, force_column, force_scale, units, record_opts,
                         output_opts):
    """Fit friction maps with + and − branches from steady plateaus or binned motion.

    FILES are records (each may carry a window, run.csv@2:30), or folders of TRO 2021
    EPOS exports (e.g. screw_drive_friction_TRO2021/driveNo1/steady_state/0.096kg).
    """
    from driveid.identify.friction.friction_map import (
        BRANCH_MAPS,
        binned_points,
        estimate_friction_map,
        read_tro2021_steady_state,
        steady_points,
    )
    from driveid.report.friction_figures import plot_friction_map

    names = tuple(m.strip() for m in models.split(",") if m.strip())
    if not names:  # issue 28: an empty list fitted Coulomb + viscous alone, without a word
        raise click.BadParameter(
            f"--models names no map; give one or more of {', '.join(sorted(BRANCH_MAPS))}, "
            "comma-separated, or leave the option out for the default four")
    opts = _legacy(record_opts, force_column, force_scale, units)
    records = []
    for f in files:
        path = Path(f)
        if path.is_dir():
            records += read_tro2021_steady_state(path)
        else:
            records.append(opts.read(f, position=False))  # speed-only logs will do
    points = []
    for rec in records:
        if inertia is not None:
            points += binned_points(rec, inertia=inertia, bins=bins, cutoff_hz=cutoff_hz)
        else:
            points += steady_points(rec, rel_tol=rel_tol, min_samples=min_samples,
                                    cutoff_hz=cutoff_hz)
    vu = records[0].units.get("x", "m") + "/s" if records else None
    fu = records[0].units.get("u", "N") if records else None
    result = estimate_friction_map(
        points, models=names, velocity_unit=vu, force_unit=fu,
        min_speed=0.0 if min_speed is None else min_speed,
        max_speed=float("inf") if max_speed is None else max_speed)
    est = result.estimate
    warnings = tuple(dict.fromkeys(w for e in result.fits.values() for w in e.warnings))
    est = dataclasses.replace(est, warnings=warnings, diagnostics={
        **est.diagnostics, "n_points": len(result.points), "comparison": result.comparison,
        "fits": {k: v.to_dict() for k, v in result.fits.items() if k != "coulomb_viscous"},
        "source": "binned F - J·a" if inertia is not None else "steady segments"})
    emit(est, output_opts, records=records, figure=lambda: plot_friction_map(result),
         header=f"points: {len(result.points)}")
    if output_opts.as_json:
        return
    click.echo("")
    click.echo("model             branch  k   AIC       BIC       identifiable")
    for row in result.comparison:
        best = "  <- best AIC" if row.get("best_aic") else ""
        click.echo(f"{row['model']:<17} {row['branch']:<7} {row['k']:<3} {row['aic']:<9.4g} "
                   f"{row['bic']:<9.4g} {str(row['identifiable']):<5}{best}")
    for model, fit in result.fits.items():
        if model == "coulomb_viscous":
            continue
        click.echo(f"\n{model}:")
        click.echo(fit.table())
