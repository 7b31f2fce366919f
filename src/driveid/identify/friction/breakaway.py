"""Breakaway (static) friction by gross sliding, from force ramps in one or several records.

A slow force ramp from rest first deforms the contact (presliding, creep: thesis §2.1.1.3,
Eqs. 2.13–2.14), then the body breaks away into gross sliding. Displacement-based
criteria fire at the creep onset and return too low a breakaway force; here breakaway is
the applied force at the first sample where the velocity — the displacement rate over a
window — exceeds a threshold stated in physical units, ``v_break`` [m/s or rad/s]. The
creep onset (displacement from rest above ``x_creep``) is reported separately. Ramps may be
spread over several files; with the dwell time at rest before each ramp the rise of static
friction with dwell time (thesis 2.6–2.11) follows from
:func:`driveid.identify.friction.static_tests.estimate_rising_friction`.

Sign convention (DESIGN.md): static friction ``fs_mean + fs_delta·sgn(applied force)``;
``fs_plus``/``fs_minus`` are magnitudes.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from driveid.errors import IdentificationError, ParameterError, RecordError
from driveid.identify.core._plausibility import check_plausibility, few_repeats_warning
from driveid.identify.core.estimate import Estimate, Parameter
from driveid.io.record import Record
from driveid.signal.steady import noise_level

__all__ = ["estimate_breakaway_sliding", "rising_friction_from_breakaways"]


def _rate(x: np.ndarray, t: np.ndarray, window: int) -> np.ndarray:
    # displacement over the window divided by its actual duration (the timestamps, so an
    # uneven clock needs no resampling), attributed to its end sample
    rate = np.zeros_like(x)
    rate[window:] = (x[window:] - x[:-window]) / (t[window:] - t[:-window])
    return rate


def estimate_breakaway_sliding(
    records: Record | Sequence[Record],
    *,
    v_break: float,
    window: float | None = None,
    x_creep: float | None = None,
    min_force: float = 0.0,
) -> Estimate:
    """Breakaway force per direction by gross sliding, with the creep onset apart.

    Parameters
    ----------
    records : Record or sequence of Record
        Position ``x`` [m or rad] and a slowly ramped applied force ``u`` [N or N·m]; each
        run of one sign of ``u`` starting from rest is one ramp. Ramps of both signs may
        sit in different files.
    v_break : float
        Gross-sliding threshold on the displacement rate [m/s or rad/s]; > 0. Choose it
        far above the creep rate and the rate noise (``position quantum / window``) and
        well below the sliding speeds.
    window : float, optional
        Duration over which the displacement rate is taken [s]; default 10 samples.
    x_creep : float, optional
        Displacement from rest that marks the creep (presliding) onset [m or rad];
        default 5 position-noise deviations at the start of the ramp (at least 2
        position quanta).
    min_force : float
        Ramps whose peak force stays below this are ignored [N or N·m]; >= 0.

    Returns
    -------
    Estimate
        ``fs_plus``, ``fs_minus`` (magnitudes) [N or N·m], ``fs_mean``, ``fs_delta`` of
        the directions found, ``creep_plus``/``creep_minus`` (force at the creep onset)
        [N or N·m], left out with a warning where no ramp of that direction moved more
        than ``x_creep`` before gross sliding. Standard errors: the spread over repeated
        ramps (``std/√n``); with one ramp the force change over one sample and the rate
        window, with a warning that it is a resolution, not a statistical error.
        ``data_used["ramps"]``: one dict per ramp with ``record``, ``direction``,
        ``index``, ``force``, ``creep_force``, ``x_creep`` (the threshold used) and
        ``dwell`` (time at rest before the ramp [s]).

    Raises
    ------
    ParameterError
        If ``v_break``, ``window``, ``x_creep`` or ``min_force`` is out of range.
    RecordError
        If a record has no force.
    IdentificationError
        If no ramp reaches gross sliding; the message says what to change.

    Notes
    -----
    The force is read at the first sample where the rate over ``window`` exceeds
    ``v_break`` in the direction of the force, minus half the window (the rate belongs to
    the middle of its window). For a rigid body with static friction ``Fs`` and kinetic
    ``Fk < Fs`` the velocity grows as ``(Fs − Fk)/J·t`` after breakaway, so the force
    error is about ``ramp rate × (J·v_break/(Fs − Fk) + window/2)``.
    """
    recs = [records] if isinstance(records, Record) else list(records)
    if not (math.isfinite(v_break) and v_break > 0):
        raise ParameterError(f"v_break must be a positive speed [m/s or rad/s]; got {v_break}")
    if not (math.isfinite(min_force) and min_force >= 0):
        raise ParameterError(f"min_force must be >= 0 [N or N·m]; got {min_force}")
    if x_creep is not None and not (math.isfinite(x_creep) and x_creep > 0):
        raise ParameterError(f"x_creep must be a positive displacement; got {x_creep}")
    ramps: list[dict[str, Any]] = []
    for k, rec in enumerate(recs):
        if rec.u is None:
            raise RecordError("breakaway needs the applied force u; read the record with a "
                              f"force column (CLI: --force NAME); record {k} has none")
        ramps += _ramps(rec, k, v_break, window, x_creep, min_force)
    plus = [r for r in ramps if r["direction"] > 0]
    minus = [r for r in ramps if r["direction"] < 0]
    if not ramps:
        raise IdentificationError(
            f"no force ramp reaches gross sliding (rate > v_break = {v_break:g}); "
            + _v_break_advice(recs[0], v_break, window) + "; got 0 ramps")
    first = recs[0]
    xu, fu = first.units.get("x", "rad"), first.units.get("u", "N·m")
    params: dict[str, Parameter] = {}
    warnings = []
    stats = {}
    for tag, rows in (("plus", plus), ("minus", minus)):
        if not rows:
            warnings.append(f"no ramp in the {tag} direction reaches sliding; fs_{tag} not "
                            "identified; add a ramp of that sign")
            continue
        f = np.array([r["force"] for r in rows])
        c = np.array([r["creep_force"] for r in rows])
        if f.size > 1:
            fse = float(f.std(ddof=1) / math.sqrt(f.size))
            n_c = int(np.sum(np.isfinite(c)))
            cse = float(np.nanstd(c, ddof=1) / math.sqrt(n_c)) if n_c > 1 else math.nan
        else:
            fse, cse = rows[0]["resolution"], rows[0]["resolution"]
            warnings.append(f"one {tag} ramp: the standard error of fs_{tag} is the force "
                            "resolution (force step over the rate window), not a "
                            "statistical error; repeat the ramp for one")
        if f.size > 1:
            warnings += few_repeats_warning(int(f.size), f"{tag} ramps")
        stats[tag] = (float(f.mean()), fse)
        params[f"fs_{tag}"] = Parameter(float(f.mean()), fse, fu)
        if np.any(np.isfinite(c)):
            params[f"creep_{tag}"] = Parameter(float(np.nanmean(c)), cse, fu)
        else:  # a NaN with an error bar said nothing (before 2026-11-28)
            xc = min(r["x_creep"] for r in rows)
            warnings.append(
                f"no {tag} ramp moved more than x_creep = {xc:.3g} {xu} from rest before "
                f"gross sliding, so the creep onset is not resolved and creep_{tag} is not "
                "reported: the contact shows no presliding at this position resolution "
                "(a smaller x_creep, CLI --x-creep, looks for a smaller one)")
    if "plus" in stats and "minus" in stats:
        (fp, ep), (fm, em) = stats["plus"], stats["minus"]
        se = 0.5 * math.hypot(ep, em)
        params["fs_mean"] = Parameter(0.5 * (fp + fm), se, fu)
        params["fs_delta"] = Parameter(0.5 * (fp - fm), se, fu)
    return check_plausibility(Estimate(
        method="breakaway-gross-sliding",
        params=params,
        data_used={"ramps": ramps},
        diagnostics={"n_plus": len(plus), "n_minus": len(minus), "v_break": v_break,
                     "v_break_unit": f"{xu}/s", "n_records": len(recs)},
        warnings=tuple(warnings),
    ))


def _ramps(rec: Record, k: int, v_break: float, window: float | None,
           x_creep: float | None, min_force: float) -> list[dict[str, Any]]:
    x, u, fs = np.asarray(rec.x, float), np.asarray(rec.u, float), rec.fs
    w = 10 if window is None else max(1, round(window * fs))
    if window is not None and not (math.isfinite(window) and window > 0):
        raise ParameterError(f"window must be a positive duration [s]; got {window}")
    rate = _rate(x, np.asarray(rec.t, float), w)
    steps = np.abs(np.diff(x))
    quantum = float(steps[steps > 0].min()) if np.any(steps > 0) else 0.0
    du = float(np.median(np.abs(np.diff(u))))
    sgn = np.sign(u)
    edges = np.flatnonzero(np.diff(sgn) != 0) + 1
    bounds = np.concatenate([[0], edges, [u.size]])
    out = []
    for a, b in zip(bounds[:-1], bounds[1:], strict=True):
        s = int(sgn[a])
        if s == 0 or b - a < w + 2 or float(np.max(np.abs(u[a:b]))) < min_force:
            continue
        # the ramp must start from rest: the rate at its start below the threshold
        if abs(rate[min(a + w, b - 1)]) > v_break:
            continue
        hit = np.flatnonzero(s * rate[a + w:b] > v_break)
        if hit.size == 0:
            continue
        i_b = a + w + int(hit[0]) - w // 2
        rest_x = x[a:a + max(w + 2, min(200, (i_b - a) // 4))]
        xc = x_creep if x_creep is not None else max(
            5.0 * noise_level(rest_x) if rest_x.size > 2 else 0.0, 2.0 * quantum, 1e-15)
        creep = np.flatnonzero(np.abs(x[a:i_b + 1] - x[a]) > xc)
        i_c = a + int(creep[0]) if creep.size else -1
        rest = np.flatnonzero(np.abs(rate[:a]) > v_break)
        t_rest = rec.t[rest[-1]] if rest.size else rec.t[0]
        out.append({"record": k, "direction": s, "index": int(i_b),
                    "time": float(rec.t[i_b]), "force": float(abs(u[i_b])),
                    "creep_force": float(abs(u[i_c])) if i_c >= 0 else math.nan,
                    "creep_index": int(i_c), "x_creep": float(xc),
                    "dwell": float(rec.t[a] - t_rest),
                    "resolution": float(du * max(1.0, w / 2) / math.sqrt(3.0))})
    return out


def rising_friction_from_breakaways(estimate: Estimate) -> Estimate:
    """Fit the rise of static friction with dwell time (2.6) to the ramps of an estimate.

    Parameters
    ----------
    estimate : Estimate
        Result of :func:`estimate_breakaway_sliding` whose ramps have distinct dwell
        times at rest [s] (at least 5 ramps of one direction).

    Returns
    -------
    Estimate
        ``fs_inf``, ``fk`` [N or N·m], ``gamma`` [s^kappa], ``kappa`` [-], see
        :func:`driveid.identify.friction.static_tests.estimate_rising_friction`; the direction with
        more ramps is used.

    Raises
    ------
    IdentificationError
        If fewer than 5 ramps of one direction or the dwell times do not span the rise.
    """
    from driveid.identify.friction.static_tests import estimate_rising_friction

    ramps = list(estimate.data_used.get("ramps", ()))
    plus = [r for r in ramps if r["direction"] > 0]
    minus = [r for r in ramps if r["direction"] < 0]
    rows = plus if len(plus) >= len(minus) else minus
    if len(rows) < 5:
        raise IdentificationError("rising static friction needs at least 5 ramps of one "
                                  "direction after different dwell times; got "
                                  f"{len(rows)}")
    unit = next(iter(estimate.params.values())).unit if estimate.params else "N"
    return estimate_rising_friction(np.array([r["dwell"] for r in rows]),
                                    np.array([r["force"] for r in rows]), unit=unit)


def _v_break_advice(rec: Record, v_break: float, window: float | None) -> str:
    """Say which way v_break is off: below the noise's rate, above every motion, or fine.

    "lower v_break" was the advice for v_break = 1e-12 too, where the noise alone exceeds
    it everywhere and no ramp starts from rest (fifth hostile campaign).
    """
    x = np.asarray(rec.x, float)
    lag = 10 if window is None else max(1, round(window * rec.fs))  # as _ramps
    if x.size <= lag + 1:
        return f"the rate window ({lag / rec.fs:g} s) is longer than the record: shorten it"
    rates = np.abs(x[lag:] - x[:-lag]) / (lag / rec.fs)
    floor, top = (float(np.percentile(rates, q)) for q in (1, 99.5))
    if v_break <= floor:
        return (f"v_break is below the rate of the record's slowest 1 % ({floor:.3g}: at "
                "rest, its noise): raise it above that")
    if v_break >= top:
        return (f"v_break is above the record's fastest motion ({top:.3g}): lower it, or apply "
                "a ramp that ends in sliding")
    return "apply a slow ramp from rest that ends in sliding, or lower v_break"
