"""Figure of a forced-response or forced-PHO estimate: the dynamic stiffness and its model."""

from __future__ import annotations

from typing import Any

import numpy as np

from driveid.report._pyplot import pyplot

__all__ = ["plot_forced"]


def plot_forced(estimate: Any) -> Any:
    """Draw the measured dynamic stiffness of each run against the identified model.

    Left: ``Re(H - z)`` [N·m/rad or N/m] against ω [rad/s] with the line ``K - Jω²``.
    Right: the equivalent damping ``Im(H - z)/ω`` [N·m·s/rad or N·s/m] against the velocity
    amplitude ``ωA`` [rad/s or m/s] with the model ``c_mean + 4 fk_mean/(π ωA)`` (the
    describing function, :mod:`driveid.identify.forced.forced_friction`) or the constant C.
    ``H = R e^{jρ}`` is each run's dynamic stiffness (de Marchi 1998, Eq. 2.179) and
    ``z = (P + jωD) e^{-jωΔ}`` the delayed PD loop (zero for the open drive).

    Parameters
    ----------
    estimate : Estimate
        From :func:`~driveid.identify.forced.forced.estimate_forced_response`,
        :func:`~driveid.identify.forced.forced.estimate_forced_pho` or
        :func:`~driveid.identify.forced.forced_friction.estimate_forced_friction`.

    Returns
    -------
    matplotlib.figure.Figure
    """
    plt = pyplot()
    du = estimate.data_used
    w = np.asarray(du["omega"], float)
    H = np.asarray(du["amplitude_ratio"], float) * np.exp(1j * np.asarray(du["phase_lag"]))
    delay = estimate.value("delay") if "delay" in estimate else float(du.get("delay", 0.0))
    P = np.broadcast_to(np.asarray(du.get("P", 0.0), float), w.shape)
    D = np.broadcast_to(np.asarray(du.get("D", 0.0), float), w.shape)
    z = (P + 1j * w * D) * np.exp(-1j * w * delay)
    V = w * np.asarray(du["displacement_amplitude"], float)
    J, K, c = estimate.value("J"), estimate.value("K"), estimate.value("c_mean")
    fk = estimate.value("fk_mean") if "fk_mean" in estimate else 0.0

    fig, (left, right) = plt.subplots(1, 2, figsize=(10, 4), layout="constrained")
    order = np.argsort(w)
    left.plot(w, (H - z).real, "o", label="runs: Re(H - z)")
    left.plot(w[order], K - J * w[order] ** 2, "-", label="model K - Jω²")
    left.set_xlabel("ω [rad/s]")
    left.set_ylabel("in-phase dynamic stiffness [N·m/rad or N/m]")
    left.legend()
    right.plot(V, (H - z).imag / w, "o", label="runs: Im(H - z)/ω")
    v = np.linspace(V.min(), V.max(), 100)
    model = c + 4.0 * fk / (np.pi * v)
    label = "model c_mean + 4 fk_mean/(πωA)" if fk else "model C"
    right.plot(v, model, "-", label=label)
    right.set_xlabel("velocity amplitude ωA [rad/s or m/s]")
    right.set_ylabel("equivalent damping [N·m·s/rad or N·s/m]")
    right.legend()
    fig.suptitle(f"{estimate.method}: J = {J:.4g}, K = {K:.4g}, C = {c:.4g}")
    return fig
