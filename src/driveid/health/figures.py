"""Figure of an axis's health: each parameter's history with intervals, band and CUSUM."""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["plot_axis_health"]

_COLOURS = {"healthy": "tab:green", "watch": "tab:orange", "degraded": "tab:red"}


def plot_axis_health(health: Any, blueprint: Any = None) -> Any:
    """Draw one row per monitored parameter: values ± 2 s.e., blueprint band, CUSUM.

    Parameters
    ----------
    health : AxisHealth
        From :func:`driveid.health.assess_axis`.
    blueprint : Blueprint, optional
        Draws the nominal value and the ``nominal ± 3·spread`` band.

    Returns
    -------
    matplotlib.figure.Figure
        The figure.
    """
    import matplotlib.pyplot as plt

    names = list(health.parameters)
    fig, axes = plt.subplots(len(names), 2, figsize=(10, 2.2 * len(names) + 0.6),
                             squeeze=False, sharex=True)
    for row, name in enumerate(names):
        ph = health.parameters[name]
        t = ph.times.astype("datetime64[s]").astype(object)
        ax, ax_c = axes[row]
        colours = [_COLOURS[v] for v in ph.verdicts]
        ax.errorbar(t, ph.values, yerr=2 * np.nan_to_num(ph.stderr), fmt="none",
                    ecolor="0.5", capsize=2)
        ax.scatter(t, ph.values, c=colours, s=18, zorder=3)
        if blueprint is not None and name in blueprint.parameters:
            bp = blueprint.parameters[name]
            ax.axhline(bp.nominal, color="0.3", lw=0.8)
            ax.axhspan(*bp.band, color="0.9", zorder=0)
        if np.isfinite(ph.baseline):
            ax.axhline(ph.baseline, color="tab:blue", lw=0.8, ls="--")
        ax.set_ylabel(f"{name} [{ph.unit}]")
        ax_c.plot(t, ph.cusum_up, "-o", ms=3, label="S⁺")
        ax_c.plot(t, ph.cusum_down, "-s", ms=3, label="S⁻")
        ax_c.axhline(health.thresholds["cusum"], color="tab:red", lw=0.8)
        ax_c.axhline(health.thresholds["cusum_watch"], color="tab:orange", lw=0.8, ls="--")
        ax_c.set_ylabel("CUSUM [-]")
        if row == 0:
            ax_c.legend(fontsize=7, loc="upper left")
    axes[-1][0].set_xlabel("measured at (UTC)")
    axes[-1][1].set_xlabel("measured at (UTC)")
    fig.suptitle(f"{health.machine}/{health.axis}: "
                 + (health.reasons[0] if health.reasons else health.verdict), fontsize=9)
    fig.autofmt_xdate()
    fig.tight_layout()
    return fig
