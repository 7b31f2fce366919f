"""Figures of records and estimates (matplotlib); every axis carries its unit."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from driveid.report._pyplot import pyplot

__all__ = ["plot_estimate", "plot_log_decrement", "pyplot", "save_figure"]


def plot_estimate(estimate: Any, *, record: Any = None, ax: Any = None) -> Any:
    """Draw an estimate over its record; dispatches on ``estimate.method``.

    Parameters
    ----------
    estimate : Estimate
        Result of an identification.
    record : Record or sequence of Record, optional
        The data the estimate came from.
    ax : matplotlib Axes, optional
        Where to draw; a new figure when omitted.

    Returns
    -------
    matplotlib.figure.Figure
        The figure drawn on.
    """
    method = estimate.method
    if method == "output-error":
        from driveid.validate import compare

        records = [record] if hasattr(record, "t") else list(record or [])
        if not records:
            raise ValueError("an output-error figure overlays the model on its record; pass "
                             "record=")
        return compare(records[0], estimate, index=0).plot()
    if method.startswith("logdec"):
        return plot_log_decrement(estimate, record=record, ax=ax)
    if method in ("hilbert-freevib", "hilbert-forcevib"):
        from driveid.report.instantaneous_figures import plot_hilbert

        return plot_hilbert(estimate, record=record)
    if method.startswith("wavelet"):
        from driveid.report.instantaneous_figures import plot_wavelet

        return plot_wavelet(estimate, record=record)
    if method == "pho-campaign":
        from driveid.report.pho_figures import plot_pho_campaign

        return plot_pho_campaign(estimate)
    if method == "pho-output-error":
        from driveid.report.pho_figures import plot_pho_fit

        return plot_pho_fit(estimate, record)
    if method.startswith("idim"):
        from driveid.report.friction_figures import plot_idim

        return plot_idim(estimate)
    if method in ("contour-idim", "contour-ballbar"):
        from driveid.report.contour_figures import plot_contour_estimate

        return plot_contour_estimate(estimate)
    if method in ("forced-response", "forced-pho", "forced-friction", "describing-function"):
        from driveid.report.forced_figures import plot_forced

        return plot_forced(estimate)
    if method in ("transfer-oe", "two-mass-oe"):
        from driveid.report.transfer_figures import plot_transfer

        return plot_transfer(estimate)
    raise NotImplementedError(
        f"no figure for method {method!r}; friction maps are drawn by "
        "driveid.report.friction_figures.plot_friction_map(result)"
    )


def plot_log_decrement(estimate: Any, *, record: Any = None, ax: Any = None) -> Any:
    """Draw record(s) with their peaks, the fitted peak sequence and its envelopes.

    Parameters
    ----------
    estimate : Estimate
        A ``logdec-*`` estimate.
    record : Record or sequence of Record, optional
        The records behind the estimate, drawn as lines.
    ax : matplotlib Axes, optional
        Where to draw.

    Returns
    -------
    matplotlib.figure.Figure
        The figure.
    """
    plt = pyplot()
    if ax is None:
        fig, ax = plt.subplots(figsize=(9, 4.5), constrained_layout=True)
    else:
        fig = ax.figure
    records = [] if record is None else ([record] if hasattr(record, "t") else list(record))
    peak_t = estimate.data_used["peak_t"]
    peak_x = estimate.data_used["peak_x"]
    fits = estimate.data_used.get("peak_fit")
    if not isinstance(peak_t, list):
        peak_t, peak_x = [peak_t], [peak_x]
        fits = None if fits is None else [fits]
    xunit = records[0].units.get("x", "") if records else ""
    for k, (tp, xp) in enumerate(zip(peak_t, peak_x, strict=True)):
        color = f"C{k}"
        if k < len(records):
            rec = records[k]
            ax.plot(rec.t, rec.x, color=color, lw=0.8, label=f"record {k + 1}")
        ax.plot(tp, xp, "o", color=color, ms=4, mfc="none",
                label="measured peaks" if k == 0 else None)
        if fits is not None:
            fit = np.asarray(fits[k])
            upper = _is_maximum(np.asarray(xp))
            for mask, name in ((upper, "upper"), (~upper, "lower")):
                ax.plot(tp[mask], fit[mask], "--", color="k", lw=0.9,
                        label="fitted envelope" if (k == 0 and name == "upper") else None)
    p = estimate.params
    if "theta_k_mean" in p:
        for s in (1, -1):
            eq = -(p["theta_k_mean"].value * s + p["theta_k_delta"].value)
            ax.axhline(eq, color="grey", lw=0.6, ls=":")
    ax.set_xlabel("time t [s]")
    ax.set_ylabel(f"position x [{xunit}]" if xunit else "position x")
    ax.set_title(f"{estimate.method}: ω0 = {p['omega0'].value:.5g} rad/s")
    ax.legend(loc="upper right", fontsize=8)
    ax.grid(True, alpha=0.3)
    return fig


def _is_maximum(peaks: np.ndarray) -> np.ndarray:
    """Which of alternating extrema are maxima, by comparison with their neighbours.

    Splitting by the median of the values (as before) joins maxima and minima into one
    diagonal line when the record's equilibrium is offset from zero, as on measured records.
    """
    n = peaks.size
    if n < 2:
        return np.ones(n, dtype=bool)
    first_is_max = peaks[0] > peaks[1]
    return (np.arange(n) % 2 == 0) == first_is_max


def save_figure(fig: Any, path: str | Path, *, overwrite: bool = False) -> Path:
    """Save a figure as PNG (or the format of the suffix), refusing to overwrite.

    Parameters
    ----------
    fig : matplotlib.figure.Figure
        The figure.
    path : str or Path
        Destination file.
    overwrite : bool
        Replace an existing file.

    Returns
    -------
    Path
        The written file.

    Notes
    -----
    Written atomically (:func:`driveid.io.safe_write.atomic_save`): a symbolic link at
    ``path`` is never followed (refused, or with ``overwrite`` the link itself replaced),
    and an interrupted save leaves no partial image.
    """
    from driveid.io.safe_write import atomic_save

    path = Path(path)
    fmt = path.suffix.lstrip(".").lower() or "png"
    supported = fig.canvas.get_supported_filetypes()
    if fmt not in supported:
        from driveid.errors import FileFormatError

        pyplot().close(fig)
        raise FileFormatError(
            f"cannot write a figure as {path.name}: unknown image suffix {path.suffix!r}; "
            f"use one of {', '.join('.' + k for k in sorted(supported))}")
    try:
        atomic_save(path, lambda fh: fig.savefig(fh, format=fmt, dpi=120),
                    overwrite=overwrite)
    finally:
        pyplot().close(fig)
    return path
