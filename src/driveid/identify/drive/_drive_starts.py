"""Start values of a whole-drive fit read from the record (:mod:`driveid.identify.drive.drive_fit`).

Backlash gaps from the contact plateaus of the motor-load position difference; inertias,
viscous and kinetic friction from the sum of all bodies' equations of motion (thesis 2.136,
2.155), in which the link forces cancel.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from driveid.identify.drive._drive_model import DriveRecord, channel_index, get_value
from driveid.sim.drive_types import BacklashLink, DriveParams

__all__ = ["drive_start_values"]


def drive_start_values(records, start: DriveParams, names: Sequence[str], *,
                       input_body: int | None = 0) -> dict[str, float]:
    """Start values of a drive fit read from the record.

    Parameters
    ----------
    records : DriveRecord or sequence of DriveRecord
        The measured runs.
    start : DriveParams
        The drive's structure and the user's start values.
    names : sequence of str
        The parameters to be estimated; only their start values are returned.
    input_body : int or None
        0-based body the record's ``u`` drives (None: closed loop, ``u`` not an input; the
        inverse-model part is then skipped).

    Returns
    -------
    dict of str to float
        Start values for some of ``names``: backlash gaps ``linkJ.gap_plus``,
        ``gap_minus`` [rad or m] from the extremes of the measured ``x_j - x_{j+1}``
        (the deadzone's edges are where the difference turns at reversals); inertias
        ``bodyI.J`` and viscous and kinetic friction ``c_mean``, ``fk_mean`` from the sum of
        all bodies' equations of motion, in which every link force cancels:
        ``u = Σ_i (J_i a_i + c_i v_i + fk_i sgn v_i)`` (thesis 2.136, 2.155), regressed over
        the samples where the measured bodies move (unmeasured bodies follow the nearest
        measured one; velocities and accelerations by Savitzky–Golay differentiation).

    Examples
    --------
    >>> from driveid.sim import BodyParams, DriveParams
    >>> drive_start_values([], DriveParams(bodies=(BodyParams(J=1.0),)), ["body1.J"])
    {}
    """
    recs = [records] if isinstance(records, DriveRecord) else list(records)
    out: dict[str, float] = {}
    wanted = set(names)
    for j, ln in enumerate(start.links):
        if not isinstance(ln, BacklashLink):
            continue
        keys = (f"link{j + 1}.gap_plus", f"link{j + 1}.gap_minus")
        if not wanted & set(keys):
            continue
        diffs = [r.channels[f"x{j + 1}"] - r.channels[f"x{j + 2}"] for r in recs
                 if f"x{j + 1}" in r.channels and f"x{j + 2}" in r.channels]
        if not diffs:
            continue
        d = np.concatenate(diffs)
        hi, lo = float(np.quantile(d, 0.995)), float(np.quantile(d, 0.005))
        # in contact x_j - x_{j+1} sits on a plateau at the gap plus the contact's
        # deflection under the transmitted force; the plateau's median is nearer the gap
        # than its extreme (which holds the largest force)
        if keys[0] in wanted and hi > 0:
            out[keys[0]] = float(np.median(d[d > 0.5 * hi]))
        if keys[1] in wanted and lo < 0:
            out[keys[1]] = -float(np.median(d[d < 0.5 * lo]))
    if input_body is not None:
        out.update(_inverse_model_starts(recs, start, wanted))
    return out


def _inverse_model_starts(recs, start: DriveParams, wanted: set) -> dict[str, float]:
    from scipy.signal import savgol_filter

    nb = start.n_bodies
    movable = [i for i, b in enumerate(start.bodies) if not b.locked]
    rows, rhs = [], []
    cols: list[str] = []
    for i in movable:
        cols += [f"body{i + 1}.J", f"body{i + 1}.c_mean", f"body{i + 1}.fk_mean"]
    for rec in recs:
        if rec.u is None:
            continue
        measured = [channel_index(c)[1] for c in rec.channels if c[0] == "x"]
        if not measured:
            continue
        dt = 1.0 / rec.fs
        window = max(7, int(0.02 * rec.fs) | 1)
        if window >= rec.t.size:
            continue
        va = {}
        for i in measured:
            y = rec.channels[f"x{i + 1}"]
            va[i] = (savgol_filter(y, window, 3, deriv=1, delta=dt),
                     savgol_filter(y, window, 3, deriv=2, delta=dt))
        m = np.asarray(measured)
        block = np.zeros((rec.t.size, len(cols)))
        moving = np.ones(rec.t.size, bool)
        for k, i in enumerate(movable):
            v, a = va[int(m[np.argmin(np.abs(m - i))])]
            block[:, 3 * k] = a
            block[:, 3 * k + 1] = v
            block[:, 3 * k + 2] = np.sign(v)
            moving &= np.abs(v) > 0.05 * np.max(np.abs(v))
        sl = slice(window, rec.t.size - window)
        keep = moving[sl]
        rows.append(block[sl][keep])
        rhs.append(rec.u[sl][keep] - sum(start.bodies[i].fk_delta for i in movable))
    if not rows or sum(r.shape[0] for r in rows) < 10 * len(cols):
        return {}
    a = np.vstack(rows)
    b = np.concatenate(rhs)
    prior = np.array([get_value(start, np.zeros(nb), np.zeros(nb), c) for c in cols])
    # ridge toward the user's start: bodies that move together are not separable here
    norm = np.linalg.norm(a, axis=0) + 1e-300
    lam = 1e-3 * float(np.max(norm)) ** 2
    weight = np.maximum(np.abs(prior), 1e-12)
    an = a * weight
    sol = np.linalg.solve(an.T @ an + lam * np.eye(len(cols)),
                          an.T @ b + lam * prior / weight) * weight
    out = {}
    for name, value, p in zip(cols, sol, prior, strict=True):
        if name in wanted and value > 0 and (p == 0 or 0.2 < value / p < 5.0):
            out[name] = float(value)
    return out
