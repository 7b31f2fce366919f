"""Figures of friction identification: steady-velocity maps and IDIM force fits."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from driveid.report._pyplot import pyplot

__all__ = ["plot_friction_map", "plot_idim"]

_COLORS = {"coulomb_viscous": "C0", "lorentzian": "C1", "bo_pavelescu": "C2",
           "hess_soom": "C3"}


def plot_friction_map(result: Any, *, ax: Any = None) -> Any:
    """Draw steady points with error bars and every fitted map on both branches.

    Parameters
    ----------
    result : FrictionMap
        Result of :func:`driveid.identify.friction.friction_map.estimate_friction_map`.
    ax : matplotlib Axes, optional
        Where to draw; a new figure when omitted.

    Returns
    -------
    matplotlib.figure.Figure
        Friction force [N or N·m] against velocity [m/s or rad/s]; maps with an
        unidentifiable parameter on a branch are not drawn on that branch.
    """
    from driveid.identify.friction.friction_map import BRANCH_MAPS

    plt = pyplot()
    if ax is None:
        fig, ax = plt.subplots(figsize=(7, 4.5))
    else:
        fig = ax.figure
    pts = result.points
    binned = bool(pts) and all(p.start < 0 for p in pts)
    v = np.array([p.velocity for p in pts])
    f = np.array([p.force for p in pts])
    ax.errorbar(v, f, xerr=[p.velocity_stderr for p in pts],
                yerr=[p.force_stderr for p in pts], fmt="k.", ms=4, lw=0.8,
                label="velocity bins of F − J·a" if binned else "steady segments")
    vmax = float(np.max(np.abs(v))) if v.size else 1.0
    for model, est in result.fits.items():
        func, names, eq = BRANCH_MAPS[model]
        first = True
        for branch, sign in (("plus", 1.0), ("minus", -1.0)):
            values = [est.params.get(f"{n}_{branch}") for n in names]
            if any(p is None or not math.isfinite(p.value) for p in values):
                continue
            s = np.linspace(1e-3 * vmax, 1.05 * vmax, 300)
            try:
                mag = func(s, *[p.value for p in values])
            except ValueError:  # parameters outside the model's valid range
                continue
            ax.plot(sign * s, sign * mag, color=_COLORS.get(model), lw=1.2,
                    label=f"{model} {eq}" if first else None)
            first = False
    units = result.estimate.params.get("Fc_plus")
    fu = units.unit if units is not None else ""
    vu = result.estimate.params.get("Fv_plus")
    vel_unit = vu.unit.split("/(")[-1].rstrip(")") if vu is not None else ""
    ax.axhline(0.0, color="0.7", lw=0.6)
    ax.axvline(0.0, color="0.7", lw=0.6)
    ax.set_xlabel(f"velocity [{vel_unit}]")
    ax.set_ylabel(f"friction [{fu}]")
    ax.set_title("friction map from binned motion (+ and − branches)" if binned
                 else "steady-velocity friction map (+ and − branches)")
    ax.legend(fontsize=8)
    fig.tight_layout()
    return fig


def plot_idim(estimate: Any, validation: Any = None) -> Any:
    """Draw measured and IDIM-predicted force, and the cross-test if given.

    Parameters
    ----------
    estimate : Estimate
        Result of :func:`driveid.identify.friction.idim.estimate_idim`.
    validation : IdimValidation, optional
        Result of :func:`driveid.identify.friction.idim.validate_idim`.

    Returns
    -------
    matplotlib.figure.Figure
        One panel per record: force [N or N·m] against time [s] with the relative error.
    """
    plt = pyplot()
    n = 1 if validation is None else 2
    fig, axes = plt.subplots(n, 1, figsize=(8, 3.2 * n), squeeze=False)
    force_unit = estimate.diagnostics.get("force_unit", "")
    d = estimate.data_used
    rel = estimate.diagnostics.get("relative_error_pct", math.nan)
    panels = [(d["t"], d["force"], d["predicted"], f"estimation: relative error {rel:.3g} %")]
    if validation is not None:
        panels.append((validation.t, validation.measured, validation.predicted,
                       f"cross-test: relative error {validation.relative_error:.3g} %"))
    for ax, (t, meas, pred, title) in zip(axes[:, 0], panels, strict=True):
        ax.plot(t, meas, "k-", lw=0.8, label="measured")
        ax.plot(t, pred, "C1--", lw=0.8, label="IDIM prediction")
        ax.plot(t, meas - pred, "C3-", lw=0.6, label="error")
        ax.set_ylabel(f"force [{force_unit}]")
        ax.set_title(title, fontsize=9)
        ax.legend(fontsize=8, loc="upper right")
    axes[-1, 0].set_xlabel("time [s]")
    fig.tight_layout()
    return fig
