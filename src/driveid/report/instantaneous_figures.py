"""Figures of the instantaneous methods: Hilbert (FREEVIB/FORCEVIB) and Morlet wavelet."""

from __future__ import annotations

from typing import Any

import numpy as np

from driveid.report._pyplot import pyplot

__all__ = ["plot_hilbert", "plot_wavelet", "plot_backbone"]


def plot_backbone(estimate: Any, *, record: Any = None, mode: int = 0, ax: Any = None) -> Any:
    """Backbone ``K_eff(A)`` (or ``omega0(A)`` per unit inertia) with its band and fit.

    Parameters
    ----------
    estimate : Estimate
        Result of :func:`~driveid.identify.free_decay.hilbert.estimate_hilbert` or
        :func:`~driveid.identify.free_decay.wavelet.estimate_wavelet`.
    record : Record, optional
        Supplies the units of ``x`` and ``u`` for the axes.
    mode : int
        Mode of a several-mode wavelet estimate (0 = lowest) [-].
    ax : matplotlib.axes.Axes, optional
        Draw into this axes; a new one-panel figure otherwise.

    Returns
    -------
    matplotlib.figure.Figure
        The figure holding the axes.

    Notes
    -----
    Light line: the instantaneous samples; markers: the bin means; band: +-2 standard
    errors of the bins; dashed: the fit ``K0 + K2 A²``. The title gives the verdict and the
    p-value of ``K2 = 0`` (:mod:`driveid.identify.free_decay.backbone`).
    """
    d = estimate.data_used
    src = d["modes"][mode] if "modes" in d else d
    xunit = record.units.get("x", "rad") if record is not None else "rad"
    if ax is None:
        fig, ax = pyplot().subplots(figsize=(6, 4.5))
    else:
        fig = ax.figure
    bb, fit = src.get("backbone"), src.get("backbone_fit", {})
    if bb is None:
        ax.plot(src["amplitude"], src["omega0"] ** 2, lw=0.8, color="0.6")
        ax.set_title(f"backbone: {fit.get('verdict', 'undetermined')} (too few periods)",
                     fontsize=9)
        ax.set_xlabel(f"amplitude A [{xunit}]")
        ax.set_ylabel("ω0² [rad²/s²]")
        return fig
    scale = bb["stiffness"][-1] / bb["omega0"][-1] ** 2  # J, or 1 per unit inertia
    unit = fit["unit_K0"]
    label = "K_eff/J = ω0²" if fit["mass_normalised"] else "K_eff = J ω0²"
    ax.plot(src["amplitude"], scale * np.asarray(src["omega0"]) ** 2, lw=0.6, color="0.7",
            label="instantaneous")
    amp, k, err = (np.asarray(bb[key]) for key in ("amplitude", "stiffness",
                                                    "stiffness_stderr"))
    ax.fill_between(amp, k - 2 * err, k + 2 * err, color="C0", alpha=0.25, label="±2 s.e.")
    ax.plot(amp, k, "o-", color="C0", ms=4, lw=1, label="bins")
    grid = np.linspace(amp.min(), amp.max(), 100)
    ax.plot(grid, fit["K0"] + fit["K2"] * grid**2, "k--", lw=0.8, label="K0 + K2 A²")
    ax.set_xlabel(f"amplitude A [{xunit}]")
    ax.set_ylabel(f"{label} [{unit}]")
    ax.set_title(f"backbone: {fit['verdict']} (p = {fit['p_value']:.2g}, ΔK/K = "
                 f"{fit['change']:+.2%})", fontsize=9)
    ax.legend(fontsize=7)
    ax.grid(True, alpha=0.3)
    return fig


def plot_hilbert(estimate: Any, *, record: Any = None) -> Any:
    """Four panels: omega0(t), zeta(t), backbone (omega0 vs A) and damping curve.

    Parameters
    ----------
    estimate : Estimate
        Result of :func:`driveid.identify.free_decay.hilbert.estimate_hilbert`.
    record : Record, optional
        Supplies the unit of ``x`` for the axes.

    Returns
    -------
    matplotlib.figure.Figure
        The figure.
    """
    plt = pyplot()
    d = estimate.data_used
    xunit = record.units.get("x", "rad") if record is not None else "rad"
    uunit = record.units.get("u", "N·m") if record is not None else "N·m"
    funit = f"{xunit}/s²" if d["damping_curve"]["mass_normalised"] else uunit
    fig, axes = plt.subplots(2, 2, figsize=(10, 7))
    ax = axes[0, 0]
    ax.plot(d["t"], d["omega0"], lw=1)
    ax.axhline(estimate.value("omega0"), color="k", ls="--", lw=0.8, label="summary")
    ax.set_xlabel("time t [s]")
    ax.set_ylabel("ω0(t) [rad/s]")
    ax.legend(fontsize=8)
    ax = axes[0, 1]
    ax.plot(d["t"], d["zeta"], lw=1)
    ax.axhline(estimate.value("zeta"), color="k", ls="--", lw=0.8)
    ax.set_xlabel("time t [s]")
    ax.set_ylabel("ζ(t) [-]")
    plot_backbone(estimate, record=record, ax=axes[1, 0])
    ax = axes[1, 1]
    ax.plot(d["damping_curve"]["amplitude"], d["damping_curve"]["force"], lw=1)
    ax.set_xlabel(f"amplitude A [{xunit}]")
    ax.set_ylabel(f"damping force 2Jhω A [{funit}]")
    ax.set_title("damping curve", fontsize=9)
    for a in axes.flat:
        a.grid(True, alpha=0.3)
    w0, w1 = d["window"]
    fig.suptitle(f"{estimate.method}: valid window {w0:.3g}-{w1:.3g} s")
    fig.tight_layout()
    return fig


def plot_wavelet(estimate: Any, *, record: Any = None) -> Any:
    """Scalogram with ridges, per-mode omega0(t) and zeta(t), and the first mode's backbone.

    Parameters
    ----------
    estimate : Estimate
        Result of :func:`driveid.identify.free_decay.wavelet.estimate_wavelet`.
    record : Record, optional
        Supplies the unit of ``x`` for the colour bar.

    Returns
    -------
    matplotlib.figure.Figure
        The figure.
    """
    plt = pyplot()
    d = estimate.data_used
    xunit = record.units.get("x", "rad") if record is not None else "rad"
    sc = d["scalogram"]
    fig, axes = plt.subplots(4, 1, figsize=(9, 12), height_ratios=[2, 1, 1, 1.4])
    ax = axes[0]
    amp = np.asarray(sc["amplitude"])
    mesh = ax.pcolormesh(sc["t"], np.asarray(sc["omegas"]) / (2 * np.pi), amp,
                         shading="auto", cmap="viridis")
    fig.colorbar(mesh, ax=ax, label=f"amplitude 2|W|/√a [{xunit}]")
    for k, m in enumerate(d["modes"], start=1):
        ax.plot(m["t"], np.asarray(m["ridge"]) / (2 * np.pi), "r-", lw=1,
                label="ridges" if k == 1 else None)
        axes[1].plot(m["t"], m["omega0"], lw=1, label=f"mode {k}")
        axes[2].plot(m["t"], m["zeta"], lw=1, label=f"mode {k}")
    ax.set_yscale("log")
    ax.set_xlabel("time t [s]")
    ax.set_ylabel("frequency [Hz]")
    ax.legend(fontsize=8, loc="upper right")
    axes[1].set_ylabel("ω0(t) [rad/s]")
    axes[2].set_ylabel("ζ(t) [-]")
    for a in axes[1:3]:
        a.set_xlabel("time t [s]")
        a.grid(True, alpha=0.3)
        a.legend(fontsize=8)
    plot_backbone(estimate, record=record, ax=axes[3])
    fig.suptitle(f"{estimate.method}: ω_c = {d['omega_c']:.3g}")
    fig.tight_layout()
    return fig
