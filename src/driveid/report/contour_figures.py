"""The ball-bar figure: radial deviation of a circle test on a polar plot, magnified.

As ISO 230-4 plots a ball-bar run: the nominal circle is drawn at a fixed display radius and
the radial deviation ``Δr`` [m] is added to it magnified, so micrometres become visible on a
circle of centimetres; quadrant glitches are marked where they peak.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from driveid.report._pyplot import pyplot

__all__ = ["plot_ball_bar", "plot_contour_estimate"]


def plot_ball_bar(curves: Sequence[tuple[str, np.ndarray, np.ndarray]], *,
                  glitches: Sequence[dict] = (), ax: Any = None,
                  scale: float | None = None) -> Any:
    """Draw radial deviations on a polar plot around a nominal circle.

    Parameters
    ----------
    curves : sequence of (str, ndarray, ndarray)
        ``(label, angle, radial)``: angle [rad] shape (n,), radial deviation [m] shape (n,).
    glitches : sequence of dict
        Glitches to mark (``where_deg`` [deg], ``height`` [m], ``axis``), e.g.
        ``contour_metrics(...)["glitches"]`` of the first curve.
    ax : matplotlib polar Axes, optional
        Where to draw; a new figure when omitted.
    scale : float, optional
        Full scale of the deviation [m]: the ring spans ``-scale .. +scale`` around the
        nominal circle; default the largest ``|Δr|`` of all curves.

    Returns
    -------
    matplotlib.figure.Figure
        The figure.
    """
    plt = pyplot()
    if ax is None:
        fig = plt.figure(figsize=(6.2, 6.2), constrained_layout=True)
        ax = fig.add_subplot(projection="polar")
    else:
        fig = ax.figure
    if scale is None:
        scale = max(float(np.nanmax(np.abs(dr))) for _, _, dr in curves) or 1e-6
    base = 2.0  # the nominal circle sits at 2 display units; ±scale spans ±1
    theta = np.linspace(0, 2 * math.pi, 361)
    ax.plot(theta, np.full_like(theta, base), color="grey", lw=0.8, ls="--",
            label="nominal circle")
    for k, (label, angle, dr) in enumerate(curves):
        ax.plot(angle, base + np.asarray(dr) / scale, lw=1.6 if k == 0 else 1.0,
                ls="-" if k != 1 else "--", color=f"C{k}", label=label)
    for g in glitches:
        a = math.radians(g["where_deg"])
        ax.plot([a], [base + g["height"] / scale], "v" if g["height"] > 0 else "^",
                color="crimson", ms=7)
        ax.annotate(f"{g['axis']} {g['height'] * 1e6:+.1f} µm", (a, base + g["height"] / scale),
                    textcoords="offset points", xytext=(6, 6), fontsize=8, color="crimson")
    ax.set_ylim(0, base + 1.3)
    ticks = [base - 1, base, base + 1]
    ax.set_yticks(ticks)
    ax.set_yticklabels([f"{-scale * 1e6:.1f} µm", "0", f"+{scale * 1e6:.1f} µm"], fontsize=8)
    ax.set_title("radial deviation Δr [µm], magnified (ball-bar plot)", fontsize=10)
    ax.legend(loc="lower left", bbox_to_anchor=(-0.1, -0.12), fontsize=8)
    return fig


def plot_contour_estimate(estimate: Any, ax: Any = None) -> Any:
    """Ball-bar figure of a ``contour-idim`` estimate: measured, simulated, compensated.

    Parameters
    ----------
    estimate : Estimate
        From :func:`driveid.identify.contour.circle.estimate_contour` with its series
        (``radial_measured``, ``angle`` and, where computed, ``radial_simulated`` and the
        compensation preview ``radial_model_with``).
    ax : matplotlib polar Axes, optional
        Where to draw.

    Returns
    -------
    matplotlib.figure.Figure
        The figure.

    Raises
    ------
    ValueError
        If the estimate carries no radial deviation series (a JSON written without
        ``--series``).
    """
    data = estimate.data_used
    if "radial_measured" not in data:
        raise ValueError("the contour estimate carries no radial-deviation series; write it "
                         "with --series (or pass the Estimate itself)")
    angle = np.asarray(data["angle"])
    steady = np.asarray(data.get("steady", np.ones(angle.size)), bool)

    def part(values: Any) -> np.ndarray:  # the constant-feed part (ramps left out)
        values = np.asarray(values)
        n = min(values.size, steady.size)
        return values[:n][steady[:n]]

    curves = [("measured (uncompensated)", part(angle), part(data["radial_measured"]))]
    if "radial_simulated" in data:
        curves.append(("identified model", part(angle), part(data["radial_simulated"])))
    if "radial_model_with" in data:
        curves.append(("identified model, compensated", part(data["angle_model_with"]),
                       part(data["radial_model_with"])))
    measured = estimate.diagnostics.get("measured", {})
    return plot_ball_bar(curves, ax=ax, glitches=measured.get("glitches", ()))
