"""Validation of an identified lumped drive (``identify drive``) on drive records.

:func:`compare_drive` re-simulates the drive of a ``drive-oe`` result (its model TOML, the
identified values in place) with the record's own input torque or under the result's PD
loop, and compares every measured channel (``x1``, ``v2`` ...) with it: fit [%], residual
rms and the Ljung-Box whiteness of the residual, as :func:`driveid.validate.compare` does
for one-body models.

Initial state: a record the fit used starts from its fitted state (``bodyI.x0`` /
``bodyI.v0``, ``@r`` for the r-th record of a multi-record fit); a held-out record from
its first samples (the first position of each measured body, the mean slope of its first
five samples as velocity, and the model's initial state for bodies not measured).
"""

from __future__ import annotations

import math
import tomllib
from typing import Any

import numpy as np

from driveid.errors import IdentificationError
from driveid.identify.core.estimate import Estimate
from driveid.identify.drive._drive_model import DriveProblem, DriveRecord, channel_index
from driveid.sim.config import parse_drive_config
from driveid.validate import Comparison, fit_percent, whiteness

__all__ = ["compare_drive", "drive_of"]


def compare_drive(record: DriveRecord, estimate: Estimate, *, index: int | None = None,
                  lags: int = 20) -> dict[str, Comparison]:
    """Compare a drive record's channels with the identified drive simulated on it.

    Parameters
    ----------
    record : DriveRecord
        Measured channels [m or rad, m/s or rad/s] and, open loop, the input u [N or N·m].
    estimate : Estimate
        A ``drive-oe`` result (``identify drive --json``).
    index : int, optional
        Position of ``record`` among the estimate's records (its fitted initial state is
        used); None for a held-out record (initial state from its first samples).
    lags : int
        Autocorrelation lags of the whiteness test [-].

    Returns
    -------
    dict of str to Comparison
        One per measured channel that the drive simulates.

    Raises
    ------
    IdentificationError
        If the result carries no model, the record has none of its channels, or the model
        diverges on the record.
    """
    params, run = drive_of(estimate)
    nb = params.n_bodies
    channels = [c for c in record.channels if channel_index(c)[1] < nb]
    if not channels:
        raise IdentificationError(
            f"the record has no channel of this {nb}-body drive (x1 ... x{nb}); got "
            f"{sorted(record.channels)}")
    x0 = np.array(run.x0 if run.x0 is not None else [0.0] * nb, float)
    v0 = np.array(run.v0 if run.v0 is not None else [0.0] * nb, float)
    fitted = index is not None
    if fitted:
        n_rec = int(estimate.diagnostics.get("n_records", 1))
        for i in range(nb):
            for what, target in (("x0", x0), ("v0", v0)):
                key = f"body{i + 1}.{what}" + (f"@{index + 1}" if n_rec > 1 else "")
                if key in estimate.params:
                    target[i] = estimate.value(key)
    else:
        _first_state(record, x0, v0, nb)
    body = estimate.diagnostics.get("input_body")
    record = DriveRecord(t=record.t, channels={c: record.channels[c] for c in channels},
                         u=record.u, meta=record.meta)
    problem = DriveProblem(params, x0, v0, [], np.empty(0), record,
                           None if body is None else int(body) - 1, torque=run.torque,
                           parallel=False)
    try:
        (simulated,) = problem.outputs([np.empty(0)])
    except IdentificationError as exc:
        raise IdentificationError(f"the identified drive cannot be simulated on this record "
                                  f"({exc})") from None
    out = {}
    for row, name in enumerate(problem.channels):
        y, y_hat = record.channels[name], simulated[row]
        resid = y - y_hat
        fit = fit_percent(y, resid)
        white = whiteness(resid, lags)
        notes = []
        if not white["white"]:
            notes.append(f"{name}: residuals are not white (Ljung-Box p = "
                         f"{white['p_value']:.2g}): the drive model misses an effect of this "
                         "record, or the noise is coloured")
        if math.isfinite(fit) and fit < 90.0:
            notes.append(f"{name}: fit is only {fit:.1f} %: the model does not describe "
                         "this record")
        unit = run.units if name.startswith("x") else f"{run.units}/s"
        model: dict[str, Any] = {"kind": "drive", "channel": name, "x0": x0.tolist(),
                                 "v0": v0.tolist(), "initial_state":
                                 "fitted" if fitted else "from the record's first samples"}
        out[name] = Comparison(t=np.asarray(record.t, float), y=np.asarray(y, float),
                               y_hat=y_hat, fit=fit,
                               residual_rms=float(math.sqrt(np.mean(resid**2))),
                               whiteness=white, held_out=not fitted, warnings=tuple(notes),
                               unit=unit, model=model)
    return out


def drive_of(estimate: Estimate):
    """Return the drive and run options of a ``drive-oe`` result's ``model_toml``.

    Parameters
    ----------
    estimate : Estimate
        An ``identify drive`` result.

    Returns
    -------
    params : DriveParams
        The identified drive.
    run : RunOptions
        Its ``[run]`` table (initial state, torques, units).

    Raises
    ------
    IdentificationError
        If the result has no readable model (not a drive result, or edited by hand).
    """
    from driveid.errors import ConfigError

    toml = estimate.diagnostics.get("model_toml")
    if estimate.method != "drive-oe" or not isinstance(toml, str):
        raise IdentificationError(
            "a drive validation takes an 'identify drive' result: method drive-oe with the "
            f"drive as TOML text in diagnostics.model_toml; got method {estimate.method!r} "
            f"and a model_toml of type {type(toml).__name__}")
    try:
        return parse_drive_config(tomllib.loads(toml), source="the result's model_toml")
    except (tomllib.TOMLDecodeError, ConfigError) as exc:
        raise IdentificationError(f"the result's model_toml is not a drive ({exc}); write "
                                  "the result again with identify drive --json") from None


def _first_state(record: DriveRecord, x0: np.ndarray, v0: np.ndarray, nb: int) -> None:
    """Fill x0, v0 of the measured bodies from the record's first five samples."""
    head = slice(0, min(5, record.t.size))
    for name, values in record.channels.items():
        kind, i = channel_index(name)
        if i >= nb:
            continue
        if kind == "x":
            x0[i] = float(values[0])
            if f"v{i + 1}" not in record.channels:
                v0[i] = float(np.polyfit(record.t[head] - record.t[0], values[head], 1)[0])
        else:
            v0[i] = float(values[0])
