"""Figures of the instantaneous methods: Hilbert (FREEVIB/FORCEVIB) and Morlet wavelet."""

from __future__ import annotations

from typing import Any

import numpy as np

from driveid.report._pyplot import pyplot

__all__ = ["plot_hilbert", "plot_wavelet"]


def plot_hilbert(estimate: Any, *, record: Any = None) -> Any:
    """Four panels: omega0(t), zeta(t), backbone (omega0 vs A) and damping curve.

    Parameters
    ----------
    estimate : Estimate
        Result of :func:`driveid.identify.hilbert.estimate_hilbert`.
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
    ax = axes[1, 0]
    ax.plot(d["backbone"]["amplitude"], d["backbone"]["omega0"], lw=1)
    ax.set_xlabel(f"amplitude A [{xunit}]")
    ax.set_ylabel("ω0 [rad/s]")
    ax.set_title("backbone", fontsize=9)
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
    """Scalogram with ridges, and per-mode omega0(t) and zeta(t).

    Parameters
    ----------
    estimate : Estimate
        Result of :func:`driveid.identify.wavelet.estimate_wavelet`.
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
    fig, axes = plt.subplots(3, 1, figsize=(9, 9), height_ratios=[2, 1, 1])
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
    for a in axes[1:]:
        a.set_xlabel("time t [s]")
        a.grid(True, alpha=0.3)
        a.legend(fontsize=8)
    fig.suptitle(f"{estimate.method}: ω_c = {d['omega_c']:.3g}")
    fig.tight_layout()
    return fig
