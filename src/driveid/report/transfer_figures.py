"""Figure of a transfer or two-mass estimate: Bode plot over the data's FRF, coherence, fit."""

from __future__ import annotations

from typing import Any

import numpy as np

from driveid.report._pyplot import pyplot

__all__ = ["plot_transfer"]


def plot_transfer(estimate: Any) -> Any:
    """Draw the identified model's Bode plot over the record's H1 FRF and coherence.

    Left column: magnitude [output unit per input unit] and phase [deg] against frequency
    [Hz] — the data's H1 estimate (points, shaded by coherence) and the model sampled with
    its zero-order hold (line), with the resonances ``omega0_i`` marked. Right column: the
    ordinary coherence γ² [-] and the measured output over the model output in time [s].

    Parameters
    ----------
    estimate : Estimate
        From :func:`driveid.identify.forced.transfer.estimate_transfer` (in memory: the FRF and
        time series are dropped from JSON unless ``--series``).

    Returns
    -------
    matplotlib.figure.Figure
        The figure.
    """
    plt = pyplot()
    du = estimate.data_used
    units = du.get("units", {})
    out = du.get("output", "v")
    gain_unit = f"{units.get(out, '')}/{units.get('u', '')}"
    fig, axes = plt.subplots(2, 2, figsize=(11, 7), layout="constrained")
    (mag, coh), (pha, tim) = axes
    if "f" in du:
        f = np.asarray(du["f"], float)
        gamma2 = np.asarray(du["coherence"], float)
        colours = plt.get_cmap("viridis")(np.clip(gamma2, 0, 1))
        fm = np.asarray(du.get("model_f", f), float)
        mag_m = np.asarray(du.get("model_magnitude_dense", du["model_magnitude"]), float)
        pha_m = np.asarray(du.get("model_phase_dense", np.unwrap(du["model_phase"])), float)
        mag.scatter(f, np.asarray(du["frf_magnitude"]), s=10, c=colours,
                    label="data H1 (colour: coherence, yellow = 1)")
        mag.plot(fm, mag_m, "r-", lw=1.2, label="model (ZOH)")
        # each data phase shifted by whole turns to lie nearest the model's (unwrapped) phase
        near = np.interp(f, fm, pha_m)
        phase = np.asarray(du["frf_phase"], float)
        phase = phase + 2 * np.pi * np.round((near - phase) / (2 * np.pi))
        pha.scatter(f, np.degrees(phase), s=10, c=colours)
        pha.plot(fm, np.degrees(pha_m), "r-", lw=1.2)
        coh.semilogx(f, gamma2, ".-", ms=3, lw=0.8)
        for ax in (mag, pha):
            ax.set_xscale("log")
        mag.set_yscale("log")
    else:
        mag.text(0.5, 0.5, du.get("frf_note", "no FRF in this result (use --series)"),
                 ha="center", va="center", transform=mag.transAxes, wrap=True)
    for name, par in estimate.params.items():
        if name.startswith("omega0_"):
            for ax in (mag, pha, coh):
                ax.axvline(par.value / (2 * np.pi), color="grey", ls=":", lw=0.8)
    mag.set_ylabel(f"|G| [{gain_unit}]")
    mag.legend(fontsize=8)
    pha.set_ylabel("phase [deg]")
    pha.set_xlabel("frequency [Hz]")
    coh.set_ylabel("coherence γ² [-]")
    coh.set_ylim(0, 1.05)
    coh.set_xlabel("frequency [Hz]")
    if "t" in du and "y_model" in du:
        t = np.asarray(du["t"], float)
        tim.plot(t, np.asarray(du["y"]), lw=0.7, label="measured")
        tim.plot(t, np.asarray(du["y_model"]), lw=0.9, label="model")
        tim.legend(fontsize=8)
    tim.set_xlabel("time t [s]")
    tim.set_ylabel(f"output [{units.get(out, '')}]")
    for ax in axes.ravel():
        ax.grid(True, alpha=0.3, which="both")
    res = ", ".join(f"ω0 = {p.value:.4g} rad/s" for n, p in estimate.params.items()
                    if n.startswith("omega0_"))
    fit = estimate.diagnostics.get("fit_percent")
    fig.suptitle(f"{estimate.method}: {res or 'no resonance'}"
                 + (f"; fit {fit:.1f} %" if fit is not None else ""))
    return fig
