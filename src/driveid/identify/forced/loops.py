"""Force–displacement loops: presliding stiffness, backlash gap and contact stiffness.

A slow cyclic test (sinusoidal or triangular) plotted as force against displacement is a
hysteresis loop. Two shapes are analysed:

* **Presliding** (thesis §2.1.1.3, Eqs. 2.13–2.20): after each reversal the friction
  force follows the Dahl branch (2.17) with exponent 1,
  ``F(x) = s·Fc − (s·Fc − F_r)·exp(−σ0·|x − x_r|/Fc)``, from the reversal point
  ``(x_r, F_r)`` in the direction ``s``; its initial slope ``σ0·(1 − s·F_r/Fc)`` is
  ``σ0`` at a virgin contact and ``2σ0`` after full saturation. LuGre (2.23)–(2.26)
  reduces to it at speeds far below the Stribeck velocity with ``Fc`` the static level
  ``fs``. :func:`estimate_presliding_loop` fits ``σ0`` and ``Fc`` to all branches.
* **Backlash** (thesis §2.1.2, Eq. 2.27, dead zone + stiffness): after a reversal the
  force unloads along the contact stiffness, stays near zero while the gap is crossed,
  then loads along the stiffness on the other side until the far body slides at its
  friction level. :func:`estimate_backlash_loop` measures per reversal the gap crossed,
  the contact stiffness and the sliding levels.

The applied force is taken as the friction/contact force: the test must be slow enough
that inertia is negligible (check ``J·a`` against the force). Both analyses use force
against displacement in sample order, never the time step, so an uneven clock does not
bias them; only the optional low-pass on the force resamples to the median interval (with
a warning).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from scipy import optimize

from driveid.errors import IdentificationError, ParameterError, RecordError
from driveid.identify.core._plausibility import (
    GAP_HINT,
    check_plausibility,
    few_repeats_warning,
    held_at_zero,
)
from driveid.identify.core.estimate import Estimate, Parameter
from driveid.io.record import Record
from driveid.signal.differentiate import zero_phase_lowpass

__all__ = ["loop_branches", "estimate_presliding_loop", "estimate_backlash_loop"]


def _check(record: Record) -> tuple[np.ndarray, np.ndarray]:
    if record.u is None:
        raise RecordError("a force–displacement loop needs the applied force u; read the "
                          "record with a force column (CLI: --force NAME); got none")
    return np.asarray(record.x, float), np.asarray(record.u, float)


def loop_branches(x: np.ndarray, *, smooth: int = 5) -> list[tuple[int, int, int]]:
    """Split a cyclic displacement into monotonic branches between reversals.

    Parameters
    ----------
    x : array_like, shape (n,)
        Displacement [m or rad].
    smooth : int
        Moving-average length used to find reversals [samples]; >= 1.

    Returns
    -------
    list of (int, int, int)
        ``(start, stop, direction)`` half-open ranges, direction +1 or −1.

    Raises
    ------
    IdentificationError
        If fewer than two reversals are found.

    Examples
    --------
    >>> import numpy as np
    >>> x = np.sin(np.linspace(0, 4 * np.pi, 400))
    >>> [d for *_, d in loop_branches(x)]
    [-1, 1, -1]
    """
    x = np.asarray(x, float)
    k = max(1, int(smooth))
    xs = np.convolve(x, np.ones(k) / k, mode="same") if k > 1 else x
    # a reversal is an extremum the displacement then leaves by more than 10 % of the swing
    return _branches_from_extrema(xs, float(np.ptp(xs)))


def _branches_from_extrema(xs: np.ndarray, amp: float) -> list[tuple[int, int, int]]:
    idx = [0]
    direction = 0
    cand = 0
    for i in range(1, xs.size):
        if direction == 0:
            if abs(xs[i] - xs[0]) > 0.1 * amp:
                direction = 1 if xs[i] > xs[0] else -1
                cand = i
            continue
        if (xs[i] - xs[cand]) * direction > 0:
            cand = i
        elif abs(xs[i] - xs[cand]) > 0.1 * amp:
            idx.append(cand)
            direction = -direction
            cand = i
    if len(idx) < 3:
        raise IdentificationError(
            "a loop needs at least two reversals of the displacement; record two or more "
            f"full cycles; got {len(idx) - 1}")
    out = []
    for a, b in zip(idx[1:-1], idx[2:], strict=True):
        out.append((int(a), int(b), 1 if xs[b] > xs[a] else -1))
    return out


def _run_next_to(sel: np.ndarray, *, last: bool) -> np.ndarray:
    if sel.size == 0:
        return sel
    breaks = np.flatnonzero(np.diff(sel) > 1)
    if last:
        return sel[breaks[-1] + 1:] if breaks.size else sel
    return sel[:breaks[0] + 1] if breaks.size else sel


def _force_halves(u: np.ndarray, smooth: int) -> list[tuple[int, int, int]]:
    k = max(1, int(smooth))
    us = np.convolve(u, np.ones(k) / k, mode="same") if k > 1 else u
    amp = float(np.max(np.abs(us)))
    # zero crossings with hysteresis of 5 % of the amplitude, so noise does not chatter
    sign, out, start = 0, [], 0
    for i, val in enumerate(us):
        new = 1 if val > 0.05 * amp else (-1 if val < -0.05 * amp else sign)
        if new != sign:
            if sign != 0:
                j = start + int(np.flatnonzero(np.diff(np.sign(us[start:i + 1])) != 0)[-1]) + 1 \
                    if np.any(np.diff(np.sign(us[start:i + 1])) != 0) else i
                out.append((start, j, sign))
                start = j
            else:
                start = i
            sign = new
    out.append((start, u.size, sign))
    return [h for h in out[1:-1] if h[2] != 0] if len(out) > 2 else []


def estimate_presliding_loop(record: Record, *, smooth: int = 5) -> Estimate:
    """Presliding stiffness σ0 and sliding level from a force–displacement loop.

    Parameters
    ----------
    record : Record
        Slow cyclic test: displacement ``x`` [m or rad] and force ``u`` [N or N·m].
    smooth : int
        Moving-average length used to find reversals [samples].

    Returns
    -------
    Estimate
        ``sigma0`` [N/m or N·m/rad], ``fc`` (level the branches saturate towards, the
        static level ``fs`` for LuGre) [N or N·m]; standard errors from the spread of
        per-branch fits (``std/√n``) over ≥ 3 branches, else a warning.

    Raises
    ------
    RecordError
        If the record has no force.
    IdentificationError
        If fewer than two reversals, or the fit does not converge.

    Notes
    -----
    Dahl's model (2.17) with exponent 1 integrates along a branch to the exponential in
    the module docstring; ``σ0`` and ``Fc`` are fitted by nonlinear least squares on all
    branches together (the reversal point of each branch is its first sample).
    """
    x, u = _check(record)
    branches = loop_branches(x, smooth=smooth)
    fc0 = float(np.percentile(np.abs(u), 98))
    span = float(np.median([abs(x[b - 1] - x[a]) for a, b, _ in branches]))
    if not (math.isfinite(fc0) and fc0 > 0.0):
        # the Dahl fit works on log σ0 and log Fc from these starts (exit 70 before)
        raise IdentificationError(
            "the force is zero on 98 % of the record (its 98th percentile |u| is "
            f"{fc0:.3g}), so there is no presliding loop to fit; give the record of the slow "
            "cyclic test with its force or torque column (--force COLUMN)")
    if not (math.isfinite(span) and span > 0.0):
        raise IdentificationError(
            "the position does not move along the loop's branches (median branch span "
            f"{span:.3g}), so no presliding stiffness can be read; check the position column "
            "(--position COLUMN) and its resolution")
    s0 = 3.0 * fc0 / span

    def fit(rows: list[tuple[int, int, int]]) -> np.ndarray:
        def resid(th: np.ndarray) -> np.ndarray:
            # a trial step may wander far in log space: exp of more than 700 overflows
            sig, fc = math.exp(min(th[0], 700.0)), math.exp(min(th[1], 700.0))
            out = []
            for a, b, s in rows:
                dx = np.abs(x[a:b] - x[a])
                model = s * fc - (s * fc - u[a]) * np.exp(-sig * dx / fc)
                out.append((u[a:b] - model) / fc0)
            return np.concatenate(out)

        sol = optimize.least_squares(resid, [math.log(s0), math.log(fc0)], method="lm")
        if not sol.success:
            raise IdentificationError("the Dahl branch fit did not converge; check that the "
                                      f"test is a presliding loop; got status {sol.status}")
        return np.exp(sol.x)

    sig, fc = fit(branches)
    per = np.array([fit([br]) for br in branches]) if len(branches) >= 3 else None
    warnings = []
    if per is not None:
        se = per.std(axis=0, ddof=1) / math.sqrt(len(branches))
        warnings += few_repeats_warning(len(branches), "branches")
    else:
        se = np.full(2, math.nan)
        warnings.append("fewer than 3 branches: no standard errors; record more cycles")
    xu, fu = record.units.get("x", "rad"), record.units.get("u", "N·m")
    if fc > 2.0 * float(np.max(np.abs(u))):
        warnings.append(f"the branches do not approach saturation (fitted level {fc:.3g} "
                        f"above 2× the largest force): sigma0 is the slope, the level is "
                        "poorly determined")
    return check_plausibility(Estimate(
        method="loop-presliding-dahl",
        params={"sigma0": Parameter(float(sig), float(se[0]), f"{fu}/{xu}"),
                "fc": Parameter(float(fc), float(se[1]), fu)},
        data_used={"branches": branches},
        diagnostics={"n_branches": len(branches), "equation": "(2.17) exponent 1"},
        warnings=tuple(warnings),
    ))


def estimate_backlash_loop(record: Record, *, threshold: float | None = None,
                           smooth: int = 5, lowpass_hz: float | None = None) -> Estimate:
    """Backlash gap, contact stiffness and sliding levels from a force–displacement loop.

    Parameters
    ----------
    record : Record
        Slow cyclic test of a body driven through backlash: displacement ``x`` of the
        driving side [m or rad] and the force ``u`` [N or N·m].
    threshold : float, optional
        Force scale of the analysis [N or N·m] (kept for the CLI; the contact lines use
        20–70 % of the sliding level); must lie below the sliding level.
    smooth : int
        Moving-average length used to find reversals [samples].
    lowpass_hz : float, optional
        Zero-phase low-pass on the force before the analysis [Hz]; default none.

    Returns
    -------
    Estimate
        ``gap`` (total gap crossed after each reversal) [m or rad], ``gap_plus`` =
        ``gap_minus`` = gap/2 (the split needs a reference position of the driven body;
        a warning says so), ``K`` contact stiffness [N/m or N·m/rad], ``f_plus``,
        ``f_minus`` sliding levels (magnitudes) [N or N·m], ``fk_mean``, ``fk_delta``.
        Standard errors: spread over reversals (``std/√n``).

    Raises
    ------
    RecordError
        If the record has no force.
    IdentificationError
        If fewer than two reversals, or no reversal shows a dead zone.

    Notes
    -----
    Dead zone + stiffness (2.27): after a reversal the force unloads along the contact
    line ``F = K·(x − x_a)`` and loads on the other side along ``F = K·(x − x_b)``; both
    are fitted between 20 % and 70 % of the sliding level (where the driven body sticks)
    and the gap is the distance ``|x_b − x_a|`` between their zero-force intercepts.
    ``K`` is the mean of the two slopes. The gap is bounded, ``gap >= 0``: a negative mean
    (presliding friction or a preload read as a dead zone) is held at 0, reported in
    ``diagnostics["at_bound"]`` with its one-sided 95 % upper limit, and warned.
    """
    if lowpass_hz is not None:
        # the filter needs one interval; the loop itself uses the sample order only
        record = record.resampled_uniform(purpose="the low-pass on the force (--lowpass-hz)")
    x, u = _check(record)
    if lowpass_hz is not None:
        u = zero_phase_lowpass(u, record.fs, lowpass_hz)
    halves = _force_halves(u, smooth)
    levels: dict[int, list[float]] = {1: [], -1: []}
    for a, b, s in halves:
        fu = np.sort(u[a:b] * s)
        levels[s].append(float(np.median(fu[fu.size // 2:])))
    f_plus = float(np.median(levels[1])) if levels[1] else math.nan
    f_minus = float(np.median(levels[-1])) if levels[-1] else math.nan
    both = [f for f in (f_plus, f_minus) if math.isfinite(f)]
    f_slide = min(both) if both else math.nan
    if not f_slide > 0:
        found = (f"{len(halves)} half cycles of the force" if halves else
                 "it never passes ±5 % of its peak both ways")
        raise IdentificationError(
            f"no force level found: the force does not reverse with the motion ({found}); "
            "a backlash loop needs a slow cyclic test whose force pushes both ways; check "
            "the force column (--force COLUMN)")
    thr = 0.2 * f_slide if threshold is None else float(threshold)
    if not (math.isfinite(thr) and 0 < thr < 0.7 * f_slide):
        raise ParameterError(f"threshold must be in (0, 0.7 × force level "
                             f"{0.7 * f_slide:.3g}); got {thr}")
    gaps, stiff = [], []
    for (a, c, _), (_, b, s) in zip(halves[:-1], halves[1:], strict=True):
        # unloading on the old side before the force crosses zero at c, loading after it
        fu = u[a:b] * s
        xx = (x[a:b] - x[c]) * s
        k0 = c - a
        lines = []
        for lo, hi, part in ((-0.7, -thr / f_slide, slice(0, k0)),
                             (thr / f_slide, 0.7, slice(k0, None))):
            idx = np.arange(fu.size)[part]
            sel = idx[(fu[part] > lo * f_slide) & (fu[part] < hi * f_slide)]
            # the contiguous run next to the crossing: last unloading, first loading
            sel = _run_next_to(sel, last=part.stop is not None)
            if sel.size < 3 or np.ptp(xx[sel]) <= 0:
                break
            k, icpt = np.polyfit(xx[sel], fu[sel], 1)
            if not k > 0:
                break
            lines.append((float(k), float(-icpt / k)))
        if len(lines) < 2:
            continue
        (k1, x1), (k2, x2) = lines
        stiff.append(0.5 * (k1 + k2))
        gaps.append(x2 - x1)
    if len(gaps) < 1:
        raise IdentificationError(
            "no force reversal shows contact lines on both sides; record slow full cycles "
            f"that load the contact well past {thr:.3g} both ways; got 0 of "
            f"{max(len(halves) - 1, 0)} reversals")
    g = np.array(gaps)
    k = np.array(stiff)
    n = g.size
    warnings = ["gap_plus and gap_minus are gap/2: the split of the gap needs the position "
                "of the driven body, which a force–displacement loop does not give"]
    if n < 3:
        warnings.append("fewer than 3 reversals: no standard errors; record more cycles")
    else:
        warnings += few_repeats_warning(n, "reversals")

    def se(v: np.ndarray) -> float:
        return float(v.std(ddof=1) / math.sqrt(v.size)) if v.size >= 3 else math.nan

    def se_levels(v: list[float]) -> float:
        return se(np.array(v)) if len(v) >= 3 else math.nan

    xu, fu_unit = record.units.get("x", "rad"), record.units.get("u", "N·m")
    gap = float(g.mean())
    diagnostics: dict[str, Any] = {"n_reversals": n, "threshold": thr, "equation": "(2.27)"}
    if gap < 0:
        # gap >= 0: the mean of the reversals' gaps held at its bound
        entry, message = held_at_zero("gap", gap, se(g), xu, GAP_HINT)
        half, _ = held_at_zero("gap/2", gap / 2, se(g) / 2, xu, GAP_HINT)
        diagnostics["at_bound"] = {"gap": entry, "gap_plus": half, "gap_minus": half}
        warnings.append(message)
        gap = 0.0
    params: dict[str, Any] = {
        "gap": Parameter(gap, se(g), xu),
        "gap_plus": Parameter(gap / 2, se(g) / 2, xu),
        "gap_minus": Parameter(gap / 2, se(g) / 2, xu),
        "K": Parameter(float(k.mean()), se(k), f"{fu_unit}/{xu}"),
        "f_plus": Parameter(f_plus, se_levels(levels[1]), fu_unit),
        "f_minus": Parameter(f_minus, se_levels(levels[-1]), fu_unit),
    }
    lp, lm = params["f_plus"], params["f_minus"]
    s_lev = 0.5 * math.hypot(lp.stderr, lm.stderr)
    params["fk_mean"] = Parameter(0.5 * (f_plus + f_minus), s_lev, fu_unit)
    params["fk_delta"] = Parameter(0.5 * (f_plus - f_minus), s_lev, fu_unit)
    return check_plausibility(Estimate(
        method="loop-backlash-deadzone",
        params=params,
        data_used={"halves": halves, "gaps": g, "stiffness": k},
        diagnostics=diagnostics,
        warnings=tuple(warnings),
    ))


