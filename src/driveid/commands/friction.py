"""``driveid identify friction-map`` and ``driveid identify idim``."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import click

from driveid.commands import clean_errors

__all__ = ["friction_map_command", "idim_command"]


def _scale(value: str | None) -> float | str | None:
    if value is None:
        return None
    try:
        return float(value)
    except ValueError:
        return value


def _read(path: Path, position: str | None, force_column: str | None,
          force_scale: str | None, velocity: str | None, units: str | None) -> Any:
    from driveid.io import read_record

    columns = {k: v for k, v in (("x", position), ("u", force_column), ("v", velocity)) if v}
    scale = {"u": _scale(force_scale)} if force_scale is not None else None
    unit_map = None
    if units == "m":
        unit_map = {"x": "m", "u": "N", "v": "m/s"}
    elif units == "rad":
        unit_map = {"x": "rad", "u": "N·m", "v": "rad/s"}
    return read_record(path, columns=columns or None, scale=scale, units=unit_map)


_column_options = [
    click.option("--position", default=None, help="Name of the position variable in FILE."),
    click.option("--force-column", default=None,
                 help="Name of the force/torque variable in FILE."),
    click.option("--force-scale", default=None,
                 help="Factor on the force column: a number or the name of a scalar "
                      "variable in FILE (EMPS: gtau)."),
    click.option("--units", type=click.Choice(["m", "rad"]), default=None,
                 help="Translational (m, N) or rotational (rad, N·m); default from FILE."),
]


def _with_columns(func: Callable[..., Any]) -> Callable[..., Any]:
    for option in reversed(_column_options):
        func = option(func)
    return func


@click.command("idim")
@click.argument("file", type=click.Path(exists=True, dir_okay=False, path_type=Path))
@click.option("--validate", "validate_file", default=None,
              type=click.Path(exists=True, dir_okay=False, path_type=Path),
              help="Second record for the cross-test (same θ, its observation matrix).")
@click.option("--model", type=click.Choice(["symmetric", "asymmetric"]), default="symmetric",
              show_default=True, help="Coulomb + viscous + offset, or ± branches, no offset.")
@_with_columns
@click.option("--cutoff-hz", type=float, default=100.0, show_default=True,
              help="Zero-phase Butterworth cut-off on the position [Hz].")
@click.option("--decimate", type=int, default=10, show_default=True,
              help="Decimation factor of observation matrix and force [-].")
@click.option("--simulate", is_flag=True,
              help="Also simulate the closed loop (EMPS .mat files: reads qg, kp, kv, gtau "
                   "and pulses_N) and report position and force errors.")
@click.option("--json", "as_json", is_flag=True, help="Print the estimate as JSON.")
@click.option("--figure", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Save measured vs predicted force (PNG).")
@click.option("--force", is_flag=True, help="Overwrite an existing figure file.")
@clean_errors
def idim_command(file, validate_file, model, position, force_column, force_scale, units,
                 cutoff_hz, decimate, simulate, as_json, figure, force):
    """Identify inertia, Coulomb and viscous friction by inverse-model least squares."""
    from driveid.identify.idim import estimate_idim, validate_idim

    record = _read(file, position, force_column, force_scale, None, units)
    est = estimate_idim(record, model=model, cutoff_hz=cutoff_hz, decimate=decimate)
    val = None
    if validate_file is not None:
        val = validate_idim(est, _read(validate_file, position, force_column, force_scale,
                                       None, units))
    sims = {}
    if simulate:
        pairs = [(file, record)]
        if validate_file is not None:
            pairs.append((validate_file, _read(validate_file, position, force_column,
                                               force_scale, None, units)))
        for path, rec in pairs:
            sims[path.name] = _simulate_emps(est, rec, path)
    if figure is not None:
        from driveid.report.figures import save_figure
        from driveid.report.friction_figures import plot_idim

        save_figure(plot_idim(est, val), figure, overwrite=force)
    if as_json:
        out = est.to_dict()
        if val is not None:
            out["validation"] = val.to_dict()
        if sims:
            out["simulation"] = sims
        click.echo(json.dumps(out, indent=2))
        return
    d = est.diagnostics
    click.echo(f"method: {est.method}   N = {d['n']}   cond = {d['cond']:.4g}   "
               f"relative error = {d['relative_error_pct']:.4g} %")
    click.echo(est.table())
    if val is not None:
        click.echo(f"cross-test on {validate_file.name}: relative error "
                   f"{val.relative_error:.4g} %   cond = {val.cond:.4g}")
    for name, res in sims.items():
        click.echo(f"direct simulation of {name}: position error "
                   f"{res['position_error_pct']:.4g} %   force error "
                   f"{res['force_error_pct']:.4g} %")
    for w in est.warnings:
        click.echo(f"warning: {w}")
    if figure is not None:
        click.echo(f"figure: {figure}")


def _simulate_emps(est: Any, record: Any, path: Path) -> dict[str, float]:
    from driveid.errors import FileFormatError
    from driveid.identify.idim import simulate_idim_model

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
@click.argument("files", nargs=-1, required=True,
                type=click.Path(exists=True, path_type=Path))
@_with_columns
@click.option("--velocity", default=None, help="Name of the velocity variable in FILE.")
@click.option("--models", default="coulomb_viscous,lorentzian,bo_pavelescu,hess_soom",
              show_default=True, help="Comma-separated maps to fit.")
@click.option("--rel-tol", type=float, default=0.02, show_default=True,
              help="Steady-segment tolerance relative to the speed [-].")
@click.option("--min-samples", type=int, default=50, show_default=True,
              help="Shortest steady segment [samples].")
@click.option("--json", "as_json", is_flag=True, help="Print all fits as JSON.")
@click.option("--figure", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Save friction vs velocity with the fitted maps (PNG).")
@click.option("--force", is_flag=True, help="Overwrite an existing figure file.")
@clean_errors
def friction_map_command(files, position, force_column, force_scale, units, velocity, models,
                         rel_tol, min_samples, as_json, figure, force):
    """Fit steady-velocity friction maps with + and − branches.

    FILES are records with constant-speed plateaus (one or several), or folders of TRO 2021
    EPOS exports (e.g. screw_drive_friction_TRO2021/driveNo1/steady_state/0.096kg).
    """
    from driveid.identify.friction_map import estimate_friction_map, read_tro2021_steady_state

    records = []
    for f in files:
        if f.is_dir():
            records += read_tro2021_steady_state(f)
        else:
            records.append(_read(f, position, force_column, force_scale, velocity, units))
    names = tuple(m.strip() for m in models.split(",") if m.strip())
    result = estimate_friction_map(records, models=names, rel_tol=rel_tol,
                                   min_samples=min_samples)
    if figure is not None:
        from driveid.report.figures import save_figure
        from driveid.report.friction_figures import plot_friction_map

        save_figure(plot_friction_map(result), figure, overwrite=force)
    if as_json:
        click.echo(json.dumps(result.to_dict(), indent=2, default=float))
        return
    click.echo(f"steady points: {len(result.points)}")
    click.echo(result.estimate.table())
    click.echo("")
    click.echo("model             branch  k   AIC       BIC       identifiable")
    for row in result.comparison:
        best = "  <- best AIC" if row.get("best_aic") else ""
        click.echo(f"{row['model']:<17} {row['branch']:<7} {row['k']:<3} {row['aic']:<9.4g} "
                   f"{row['bic']:<9.4g} {str(row['identifiable']):<5}{best}")
    for model, est in result.fits.items():
        if model == "coulomb_viscous":
            continue
        click.echo(f"\n{model}:")
        click.echo(est.table())
    warnings = [w for est in result.fits.values() for w in est.warnings]
    for w in warnings:
        click.echo(f"warning: {w}")
    if figure is not None:
        click.echo(f"figure: {figure}")
