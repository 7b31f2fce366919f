"""``driveid identify hilbert`` and ``driveid identify wavelet``."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import click
import numpy as np

from driveid.commands import clean_errors
from driveid.identify.hilbert import estimate_hilbert
from driveid.identify.wavelet import estimate_wavelet
from driveid.io import read_record

__all__ = ["hilbert_command", "wavelet_command"]

_SERIES = ("t", "omega0", "zeta", "amplitude")


def _series(data: Any) -> dict[str, Any]:
    out = {key: np.asarray(data[key]).tolist() for key in _SERIES}
    out["window"] = list(data["window"])
    return out


def _save(fig: Any, figure: Path, force: bool) -> None:
    from driveid.report.figures import save_figure

    save_figure(fig, figure, overwrite=force)


_FILE = click.argument("file", type=click.Path(exists=True, dir_okay=False, path_type=Path))
_JSON = click.option("--json", "as_json", is_flag=True,
                     help="Print the summary and the time series as JSON.")
_FIGURE = click.option("--figure", type=click.Path(dir_okay=False, path_type=Path),
                       default=None, help="Save a figure (PNG).")
_FORCE = click.option("--force", is_flag=True, help="Overwrite an existing figure file.")


@click.command("hilbert")
@_FILE
@click.option("--mass", "--J", "mass", type=float, default=None,
              help="Known mass or inertia J [kg or kg·m²] (FORCEVIB estimates it if omitted).")
@_JSON
@_FIGURE
@_FORCE
@clean_errors
def hilbert_command(file: Path, mass: float | None, as_json: bool, figure: Path | None,
             force: bool) -> None:
    """Instantaneous ω0(t), ζ(t), backbone and damping curve by the Hilbert transform."""
    record = read_record(file)
    est = estimate_hilbert(record, mass=mass)
    if figure is not None:
        from driveid.report.instantaneous_figures import plot_hilbert

        _save(plot_hilbert(est, record=record), figure, force)
    if as_json:
        out = est.to_dict()
        out["series"] = _series(est.data_used)
        click.echo(json.dumps(out, indent=2))
    else:
        w0, w1 = est.data_used["window"]
        click.echo(f"method: {est.method}   valid window: {w0:.4g}-{w1:.4g} s")
        click.echo(est.table())
        if figure is not None:
            click.echo(f"figure: {figure}")


@click.command("wavelet")
@_FILE
@click.option("--modes", type=int, default=1, show_default=True,
              help="Number of modes to identify.")
@click.option("--omega-c", type=float, default=None,
              help="Wavelet centre frequency [-] (default: chosen from the mode spacing).")
@_JSON
@_FIGURE
@_FORCE
@clean_errors
def wavelet_command(file: Path, modes: int, omega_c: float | None, as_json: bool,
             figure: Path | None, force: bool) -> None:
    """Modal ω0 and ζ of a free decay by the Morlet wavelet transform (one or more modes)."""
    record = read_record(file)
    est = estimate_wavelet(record, modes=modes, omega_c=omega_c)
    if figure is not None:
        from driveid.report.instantaneous_figures import plot_wavelet

        _save(plot_wavelet(est, record=record), figure, force)
    if as_json:
        out: dict[str, Any] = {"method": est.method, "modes": []}
        for k, m in enumerate(est.data_used["modes"], start=1):
            suffix = "" if modes == 1 else f"_{k}"
            out["modes"].append({
                "omega0": est["omega0" + suffix].to_dict(),
                "zeta": est["zeta" + suffix].to_dict(),
                "series": _series(m),
            })
        if modes == 1:
            out["omega0"], out["zeta"] = out["modes"][0]["omega0"], out["modes"][0]["zeta"]
        out["diagnostics"] = est.to_dict()["diagnostics"]
        click.echo(json.dumps(out, indent=2))
    else:
        click.echo(f"method: {est.method}   omega_c: {est.data_used['omega_c']:.3g}")
        click.echo(est.table())
        for k, m in enumerate(est.data_used["modes"], start=1):
            w0, w1 = m["window"]
            click.echo(f"mode {k}: valid window {w0:.4g}-{w1:.4g} s")
        if figure is not None:
            click.echo(f"figure: {figure}")

