"""Figures of loop and breakaway tests: fitted loops over the data, ramps with breakaway."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from driveid.report._pyplot import pyplot

__all__ = ["plot_loop", "plot_breakaway"]


def plot_loop(estimate: Any, record: Any, *, ax: Any = None) -> Any:
    """Overlay the fitted loop on the measured force–displacement loop.

    Parameters
    ----------
    estimate : Estimate
        Result of :func:`driveid.identify.forced.loops.estimate_presliding_loop` (Dahl branches
        drawn from every reversal) or :func:`driveid.identify.forced.loops.estimate_backlash_loop`
        (dead zone + contact lines).
    record : Record
        The loop test: displacement [m or rad], force [N or N·m].
    ax : matplotlib Axes, optional
        Where to draw; a new figure when omitted.

    Returns
    -------
    matplotlib.figure.Figure
        Force [N or N·m] against displacement [m or rad].
    """
    plt = pyplot()
    if ax is None:
        fig, ax = plt.subplots(figsize=(6.5, 4.5))
    else:
        fig = ax.figure
    x, u = np.asarray(record.x, float), np.asarray(record.u, float)
    xu, fu = record.units.get("x", "rad"), record.units.get("u", "N·m")
    ax.plot(x, u, "k-", lw=0.6, label="measured")
    if estimate.method == "loop-presliding-dahl":
        sig, fc = estimate.value("sigma0"), estimate.value("fc")
        first = True
        for a, b, s in estimate.data_used["branches"]:
            dx = np.abs(x[a:b] - x[a])
            model = s * fc - (s * fc - u[a]) * np.exp(-sig * dx / fc)
            ax.plot(x[a:b], model, "C1--", lw=1.0,
                    label=f"Dahl (2.17): σ0 = {sig:.4g} {fu}/{xu}" if first else None)
            first = False
    else:
        gap, k = estimate.value("gap"), estimate.value("K")
        fp, fm = estimate.value("f_plus"), estimate.value("f_minus")
        xc = 0.5 * (float(np.max(x)) + float(np.min(x)))
        for side, level in ((1, fp), (-1, fm)):
            if not math.isfinite(level):
                continue
            edge = xc + side * gap / 2
            xs = np.array([edge, edge + side * level / k])
            ax.plot(xs, side * np.array([0.0, level]), "C1-", lw=1.5)
        ax.plot([xc - gap / 2, xc + gap / 2], [0, 0], "C1-", lw=1.5,
                label=f"dead zone {gap:.4g} {xu}, K = {k:.4g} {fu}/{xu} (2.27)")
    ax.set_xlabel(f"displacement [{xu}]")
    ax.set_ylabel(f"force [{fu}]")
    ax.legend(fontsize=8)
    fig.tight_layout()
    return fig


def plot_breakaway(estimate: Any, records: Sequence[Any], *, ax: Any = None) -> Any:
    """Draw every ramp's force against time with the creep onset and breakaway marked.

    Parameters
    ----------
    estimate : Estimate
        Result of :func:`driveid.identify.friction.breakaway.estimate_breakaway_sliding`.
    records : sequence of Record
        The records it was estimated from [s, N or N·m].
    ax : matplotlib Axes, optional
        Where to draw; a new figure when omitted.

    Returns
    -------
    matplotlib.figure.Figure
        Force [N or N·m] against time [s].
    """
    plt = pyplot()
    if ax is None:
        fig, ax = plt.subplots(figsize=(7, 4))
    else:
        fig = ax.figure
    fu = records[0].units.get("u", "N·m") if records else ""
    for k, rec in enumerate(records):
        ax.plot(rec.t, rec.u, lw=0.7, color=f"C{k % 10}")
    for i, r in enumerate(estimate.data_used.get("ramps", ())):
        rec = records[r["record"]]
        ax.plot(rec.t[r["index"]], rec.u[r["index"]], "kv", ms=6,
                label="breakaway (gross sliding)" if i == 0 else None)
        if r["creep_index"] >= 0:
            ax.plot(rec.t[r["creep_index"]], rec.u[r["creep_index"]], "o", mfc="none",
                    color="C3", label="creep onset" if i == 0 else None)
    ax.set_xlabel("time [s]")
    ax.set_ylabel(f"force [{fu}]")
    ax.legend(fontsize=8)
    fig.tight_layout()
    return fig
