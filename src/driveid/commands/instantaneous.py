"""``driveid identify hilbert`` and ``driveid identify wavelet``."""

from __future__ import annotations

import click

from driveid.commands import clean_errors
from driveid.commands._checks import FilePath
from driveid.commands._output import emit, output_options
from driveid.commands._record_options import record_options

__all__ = ["hilbert_command", "wavelet_command"]

_FILE = click.argument("file", metavar="FILE[@T0:T1]")
_CHECK = click.option("--check-window", is_flag=True,
                      help="Refit without the last 20 % of the window and warn when a "
                           "parameter moves by more than 3 standard errors.")


_BACKBONE = click.option(
    "--backbone-figure", "backbone_figure", default=None,
    type=FilePath(),
    help="Write the backbone K_eff(A) = J ω0(A)² with its ±2 s.e. band, fit K0 + K2 A² and "
         "verdict (PNG, PDF or SVG; --overwrite replaces a file).")


def _write_backbone(est, record, path, output_opts):
    """Write the backbone figure to ``path`` when asked."""
    if path is None:
        return
    from driveid.report.figures import save_figure
    from driveid.report.instantaneous_figures import plot_backbone

    save_figure(plot_backbone(est, record=record), path, overwrite=output_opts.overwrite)


def _checked(est, fit, record, check_window):
    """Return ``est``, compared with a refit on the first 80 % of the record if asked."""
    if not check_window:
        return est
    from driveid.identify.core._plausibility import check_refit_stability

    shorter = record.crop(None, record.t[0] + 0.8 * record.duration)
    return check_refit_stability(est, fit(shorter),
                                 change="the last 20 % of the window dropped")


@click.command("hilbert")
@_FILE
@click.option("--mass", "--J", "mass", type=float, default=None,
              help="Known mass or inertia J [kg or kg·m²] (FORCEVIB estimates it if omitted).")
@_CHECK
@_BACKBONE
@record_options
@output_options
@clean_errors
def hilbert_command(file, mass, check_window, backbone_figure, record_opts, output_opts):
    """Instantaneous ω0(t), ζ(t), backbone and damping curve by the Hilbert transform.

    --json gives the backbone fit K_eff = K0 + K2 A² and its verdict (hardening, softening,
    constant) under data_used.backbone_fit; --json --series adds the time series t,
    omega0, zeta, amplitude and the binned backbone under "data_used".
    """
    from driveid.identify.free_decay.hilbert import estimate_hilbert

    record = record_opts.read(file).resampled_uniform(purpose="the Hilbert transform")
    est = _checked(estimate_hilbert(record, mass=mass),
                   lambda rec: estimate_hilbert(rec, mass=mass), record, check_window)

    def figure():
        from driveid.report.instantaneous_figures import plot_hilbert

        return plot_hilbert(est, record=record)

    w0, w1 = est.data_used["window"]
    est = emit(est, output_opts, records=[record], figure=figure,
               header=f"method: {est.method}   valid window: {w0:.4g}-{w1:.4g} s   "
                      f"backbone: {est.data_used['backbone_fit']['verdict']}")
    _write_backbone(est, record, backbone_figure, output_opts)


@click.command("wavelet")
@_FILE
@click.option("--modes", type=int, default=1, show_default=True,
              help="Number of modes to identify.")
@click.option("--omega-c", type=float, default=None,
              help="Wavelet centre frequency [-] (default: chosen from the mode spacing).")
@click.option("--mass", "--J", "mass", type=float, default=None,
              help="Inertia J [kg or kg·m²] of the mode, to give the backbone as a stiffness "
                   "K_eff = J ω0² (per unit inertia without it).")
@_CHECK
@_BACKBONE
@record_options
@output_options
@clean_errors
def wavelet_command(file, modes, omega_c, mass, check_window, backbone_figure, record_opts,
                    output_opts):
    """Modal ω0 and ζ of a free decay by the Morlet wavelet transform (one or more modes).

    With several modes the parameters are omega0_1, zeta_1, omega0_2 ...; --json gives each
    mode's backbone fit and verdict (data_used.backbone_fit for one mode, diagnostics
    backbone_verdict_k for several); --json --series adds each mode's time series under
    "data_used". --backbone-figure draws the first mode's backbone.
    """
    from driveid.identify.free_decay.wavelet import estimate_wavelet

    record = record_opts.read(file).resampled_uniform(purpose="the wavelet transform")
    def fit(rec):
        return estimate_wavelet(rec, modes=modes, omega_c=omega_c, mass=mass)

    est = _checked(fit(record), fit, record, check_window)

    def figure():
        from driveid.report.instantaneous_figures import plot_wavelet

        return plot_wavelet(est, record=record)

    windows = "; ".join(f"mode {k}: valid window {m['window'][0]:.4g}-{m['window'][1]:.4g} s"
                        for k, m in enumerate(est.data_used["modes"], start=1))
    est = emit(est, output_opts, records=[record], figure=figure,
               header=f"method: {est.method}   omega_c: {est.data_used['omega_c']:.3g}   "
                      f"{windows}")
    _write_backbone(est, record, backbone_figure, output_opts)
