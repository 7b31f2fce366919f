"""Figure of a PHO campaign: what each run alone implies, against the campaign's estimate."""

from __future__ import annotations

from typing import Any

import numpy as np

from driveid.report._pyplot import pyplot

__all__ = ["plot_pho_campaign", "plot_pho_fit"]

_PANELS = (("c_mean", "viscous c_mean"), ("K", "stiffness K"), ("fk_mean", "kinetic fk_mean"),
           ("fk_delta", "kinetic asymmetry fk_delta"))


def plot_pho_campaign(estimate: Any) -> Any:
    """Per-run values of C, K and kinetic friction against P, with the campaign's ±2 s.e. band.

    A trend with P (rather than scatter about the band) means the model misses something:
    a wrong delay, an unmodelled spring or friction that depends on speed.

    Parameters
    ----------
    estimate : Estimate
        Result of :func:`driveid.identify.pho.peaks.estimate_pho_campaign` or
        :func:`driveid.identify.pho.peaks.estimate_pho_records`.

    Returns
    -------
    matplotlib.figure.Figure
        Four panels against the proportional gain P [N·m/rad or N/m].
    """
    plt = pyplot()
    data, params = estimate.data_used, estimate.params
    fig, axes = plt.subplots(2, 2, figsize=(9, 6), sharex=True)
    P = np.asarray(data["P"])
    for ax, (name, label) in zip(axes.flat, _PANELS, strict=True):
        per_run = data.get(f"{name}_per_run")
        if per_run is None or name not in params:
            ax.set_visible(False)
            continue
        par = params[name]
        ax.axhspan(par.value - 2 * par.stderr, par.value + 2 * par.stderr, color="C0",
                   alpha=0.2, label="campaign ±2 s.e.")
        ax.axhline(par.value, color="C0")
        ax.plot(P, per_run, "o", color="C1", label="each run alone")
        ax.set_ylabel(f"{label} [{par.unit}]")
        ax.grid(True, alpha=0.3)
        ax.ticklabel_format(axis="y", useOffset=False)
    for ax in axes[1]:
        ax.set_xlabel("P [N·m/rad or N/m]")
    axes[0, 0].legend(fontsize=8)
    J = params["J"]
    fig.suptitle(f"PHO campaign: J = {J.value:.6g} ± {J.stderr:.2g} {J.unit}, "
                 f"delay = {params['delay'].value * 1e3:.4g} ms")
    fig.tight_layout()
    return fig


def plot_pho_fit(estimate: Any, records: Any) -> Any:
    """Each PHO run with the fitted closed loop (top) and the residuals (bottom).

    Parameters
    ----------
    estimate : Estimate
        From :func:`driveid.identify.pho.pho_fit.estimate_pho_output_error` (its ``data_used``
        holds ``run_samples``, ``fit_x`` [m or rad] and ``residual`` [m or rad]).
    records : sequence of Record
        The runs it was fitted to, in the same order [s; m or rad].

    Returns
    -------
    matplotlib.figure.Figure
    """
    records = [records] if hasattr(records, "t") else list(records or [])
    if not records:
        raise ValueError("a PHO fit figure overlays the fit on its runs; pass the records")
    plt = pyplot()
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(9, 6), sharex=True,
                                      gridspec_kw={"height_ratios": [2, 1]})
    edges = np.cumsum([0, *estimate.data_used["run_samples"]])
    fit, resid = estimate.data_used["fit_x"], estimate.data_used["residual"]
    for k, rec in enumerate(records):
        part = slice(edges[k], edges[k + 1])
        top.plot(rec.t, rec.x, ".", ms=1.5, color=f"C{k % 10}")
        top.plot(rec.t, fit[part], "-", lw=0.8, color=f"C{k % 10}")
        bottom.plot(rec.t, resid[part], ".", ms=1.0, color=f"C{k % 10}")
    unit = records[0].units.get("x", "")
    top.set_ylabel(f"x [{unit}]")
    top.set_title("PHO runs (dots) and the fitted delayed-PD loop (lines)")
    bottom.set_ylabel(f"residual [{unit}]")
    bottom.set_xlabel("t [s]")
    fig.tight_layout()
    return fig
