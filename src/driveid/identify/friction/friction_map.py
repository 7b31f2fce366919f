"""Steady-velocity friction maps: Coulomb + viscous (and Stribeck) fits per direction.

At a constant velocity the inertia term vanishes and the applied force equals friction, so
averaging force and velocity over steady segments samples the static friction map
``F(v)``. Each direction is its own branch (DESIGN.md: asymmetric friction
``C = c_mean + c_delta·sgn(v)``, ``F_k = fk_mean·sgn(v) + fk_delta``), fitted on
magnitudes ``|F| = Fc + Fv·|v|`` by weighted least squares with the segment standard
errors as weights. Stribeck maps — Armstrong-Hélouvry's Lorentzian (2.3) and Bo &
Pavelescu's exponential (2.5) — are fitted per branch by nonlinear least squares and
compared by AIC/BIC; a Stribeck velocity outside the measured speed range is reported as
unidentifiable rather than as a number with a huge interval.

The loader :func:`read_tro2021_steady_state` reads the EPOS exports of the screw-drive data
of Mablekos-Alexiou, da Cruz & Bergeles (IEEE T-RO 37(4), 2021).
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from scipy import optimize
from scipy.stats import chi2
from scipy.stats import t as student_t

from driveid.errors import FileFormatError, IdentificationError, ParameterError, RecordError
from driveid.identify.core._noise import fit_lines, fit_noise_model
from driveid.identify.core.estimate import Estimate, Parameter
from driveid.io.record import Record
from driveid.models.friction import (
    STATIC_MAPS,
    BoPavelescuParams,
    CoulombViscousParams,
    HessSoomParams,
    LorentzianParams,
    bo_pavelescu_friction,
    coulomb_viscous_friction,
    hess_soom_friction,
    lorentzian_friction,
)
from driveid.signal.differentiate import differentiate
from driveid.signal.steady import (
    SteadySegment,
    find_steady_segments,
    n_effective,
    segment_mean,
)

__all__ = [
    "FrictionMap",
    "BRANCH_MAPS",
    "steady_points",
    "binned_points",
    "estimate_friction_map",
    "read_tro2021_steady_state",
    "TRO2021_NOMINAL_TORQUE",
]

#: Nominal motor torque of the TRO 2021 drives [N·m]: EPOS torque is in % of it.
TRO2021_NOMINAL_TORQUE = 9.84e-3


def _lorentzian(s: np.ndarray, fc: float, fs: float, vs: float, fv: float) -> np.ndarray:
    return lorentzian_friction(s, LorentzianParams(mu_k=fc, mu_s=fs, nu=fv, v_s=vs))


def _bo_pavelescu(s: np.ndarray, fc: float, fs: float, vs: float, fv: float,
                  delta: float) -> np.ndarray:
    return bo_pavelescu_friction(
        s, BoPavelescuParams(mu_k=fc, mu_s=fs, nu=fv, v_s=vs, delta=delta))


def _hess_soom(s: np.ndarray, fs: float, vs: float, fv: float) -> np.ndarray:
    # (2.2) with unit eta, W, E, l: c_S = v, so c1 = 1/vs² and c2 = viscous coefficient —
    # the Lorentzian (2.3) without kinetic friction, as (2.4) states
    return hess_soom_friction(
        s, HessSoomParams(mu_s=fs, c1=1.0 / vs**2, c2=fv, eta=1.0, W=1.0, E=1.0, l=1.0))


def _coulomb_viscous(s: np.ndarray, fc: float, fv: float) -> np.ndarray:
    return coulomb_viscous_friction(
        s, CoulombViscousParams(fk_mean=fc, fk_delta=0.0, c_mean=fv, c_delta=0.0))


#: Branch maps fitted on speed magnitude: name -> (function of (|v|, ``*params``), parameter
#: names, thesis equation). Functions wrap :data:`driveid.models.friction.STATIC_MAPS`.
BRANCH_MAPS: dict[str, tuple[Callable[..., np.ndarray], tuple[str, ...], str]] = {
    "coulomb_viscous": (_coulomb_viscous, ("Fc", "Fv"), "(2.155)"),
    "lorentzian": (_lorentzian, ("Fc", "Fs", "vs", "Fv"), "(2.3)"),
    "bo_pavelescu": (_bo_pavelescu, ("Fc", "Fs", "vs", "Fv", "delta"), "(2.5)"),
    "hess_soom": (_hess_soom, ("Fs", "vs", "Fv"), "(2.2) via (2.4)"),
}
assert set(BRANCH_MAPS) <= set(STATIC_MAPS)


@dataclass(frozen=True)
class FrictionMap:
    """Result of :func:`estimate_friction_map`.

    Attributes
    ----------
    estimate : Estimate
        Coulomb + viscous fit: ``Fc_plus``, ``Fv_plus``, ``Fc_minus``, ``Fv_minus``
        (magnitudes, positive for a dissipative drive) and the DESIGN.md combinations
        ``fk_mean``, ``fk_delta``, ``c_mean``, ``c_delta``.
    fits : dict of str to Estimate
        Every requested map, with branch parameters ``<name>_plus``/``<name>_minus``;
        unidentifiable parameters have value ``nan`` and a warning.
    comparison : list of dict
        One row per model and branch: ``model``, ``branch``, ``k``, ``n``, ``rss``,
        ``aic``, ``bic`` (Gaussian likelihood with unknown scale), ``identifiable`` (no
        flagged parameter) and ``best_aic`` (lowest AIC among identifiable fits).
    points : list of SteadySegment
        The steady points used.
    """

    estimate: Estimate
    fits: dict[str, Estimate]
    comparison: list[dict[str, Any]]
    points: list[SteadySegment] = field(default_factory=list)

    def to_dict(self) -> dict[str, Any]:
        """Return a JSON-ready dict of all fits, the comparison and the points."""
        return {
            "estimate": self.estimate.to_dict(),
            "fits": {k: v.to_dict() for k, v in self.fits.items()},
            "comparison": self.comparison,
            "points": [
                {"velocity": p.velocity, "velocity_stderr": p.velocity_stderr,
                 "force": p.force, "force_stderr": p.force_stderr, "n": p.n}
                for p in self.points
            ],
        }


def steady_points(
    record: Record,
    *,
    window: int = 25,
    rel_tol: float = 0.02,
    noise_factor: float = 3.0,
    min_samples: int = 50,
    cutoff_hz: float | None = None,
) -> list[SteadySegment]:
    """Detect steady-velocity segments of a record and average force and velocity.

    Parameters
    ----------
    record : Record
        Force ``u`` [N or N·m] and velocity ``v`` [m/s or rad/s] (or position ``x``,
        differentiated after a zero-phase low-pass at ``cutoff_hz``).
    window, rel_tol, noise_factor, min_samples
        Passed to :func:`driveid.signal.steady.find_steady_segments`.
    cutoff_hz : float, optional
        Low-pass cut-off before differentiating ``x`` [Hz]; default ``fs/20``.

    Returns
    -------
    list of SteadySegment
        One point per steady segment whose mean speed exceeds twice its standard error
        (standstill segments carry static, not kinetic, friction and are dropped).

    Raises
    ------
    RecordError
        If the record has no force column.
    """
    if record.u is None:
        raise RecordError(
            "a friction map needs the applied force or torque u; got a record with columns "
            f"{list(record.columns)}"
        )
    if record.v is not None:
        v = np.asarray(record.v, dtype=float)
    else:
        # the low-pass and the differences assume one interval: an uneven clock is put on
        # the median grid first, with a warning saying so
        record = record.resampled_uniform(
            purpose="differentiating the position for the friction map")
        fc = record.fs / 20.0 if cutoff_hz is None else cutoff_hz
        _, v, _ = differentiate(record.x, record.fs, cutoff_hz=fc)
    u = np.asarray(record.u, dtype=float)
    settings = {"window": window, "rel_tol": rel_tol, "noise_factor": noise_factor,
                "min_samples": min_samples}
    # steady means force and speed both steady: a speed that merely changes slowly inside
    # a window (the tail of an approach with time constant J/c) or that spans a step of the
    # force is not on the friction map
    points = []
    for a, b in find_steady_segments(v, **settings):
        vm, vs = _plateau_mean(v[a:b])
        fm, fs = _plateau_mean(u[a:b])
        if abs(vm) > 2 * vs:
            points.append(SteadySegment(a, b, vm, vs, fm, fs, b - a))
    return _settled(points, v, rel_tol)


def _plateau_mean(y: np.ndarray) -> tuple[float, float]:
    """Mean of one plateau [unit] and its standard error from an AR(p) noise model [unit].

    ``sqrt(S(0)/n)`` with the long-run variance ``S(0)`` of an AR model (Burg, order by BIC)
    of the demeaned samples (issue 24), after sinusoidal lines that stand out of the noise
    spectrum (mains hum, :func:`~driveid.identify.core._noise.fit_lines`) are fitted
    with the mean: a line of an integer period makes the AR model seasonal, with a pole
    near zero frequency. The lag-1 (AR(1)) effective count of
    :func:`~driveid.signal.steady.segment_mean` reads a 25 Hz low-pass or a 50 Hz line as
    slow noise. On 300 plateaus of 750 pure-noise samples at 500 Hz, scatter over mean
    error bar: white 0.95, AR(1) 0.9 1.00, AR(1) 0.97 1.07, 25 Hz low-pass 1.04, 50 Hz mains
    0.96 (0.53 with the AR model alone, 0.3 with the lag-1 count). 1/f-like noise stays
    under-estimated (its slowest part is a plateau's offset).
    """
    y = np.asarray(y, float)
    mean = float(np.mean(y))
    if not np.ptp(y) > 0:  # a noise-free (simulated) plateau: nothing to model
        return segment_mean(y)
    lines, residual = fit_lines(y)
    try:
        model = fit_noise_model(residual, n_params=1 + 2 * len(lines))
    except IdentificationError:  # too few samples for a noise model
        return segment_mean(y)
    n_eff = model.n_eff
    if not n_eff > 0:
        return segment_mean(y)
    # the lines are at Fourier frequencies k/n, orthogonal to the constant: they leave the
    # mean as it is and take their power out of the noise model
    return mean, math.sqrt(model.variance / min(n_eff, y.size))


def _drift(v: np.ndarray) -> float:
    """Least-squares change of ``v`` over the piece where it is significant, else 0."""
    n = v.size
    if n < 3:
        return 0.0
    i = np.arange(n) - 0.5 * (n - 1)
    slope = float(i @ (v - v.mean())) / float(i @ i)
    resid = v - v.mean() - slope * i
    # the residual's correlation (a filtered, differentiated position) widens the trend's
    # standard error as 1/sqrt(n_eff)
    se = float(np.std(resid)) * math.sqrt(12.0 / n_effective(resid))
    return slope * n if abs(slope * n) > 4.0 * se else 0.0


def _settled(points: list[SteadySegment], v: np.ndarray,
             rel_tol: float) -> list[SteadySegment]:
    """Drop pieces that are the approach to the next one at the same force.

    Under a constant force a settled axis has one speed; a piece at that force whose speed
    still drifts towards the next piece's (an exponential with time constant J/c looks level
    inside a short window) is the transient, not a point of the map. Pieces at one force with
    flat, different speeds stay: a speed-controlled test on the falling part of a Stribeck
    curve gives those.
    """
    out: list[SteadySegment] = []
    for p in points:
        if out:
            q = out[-1]
            tol = max(rel_tol * max(abs(p.force), abs(q.force)),
                      4.0 * math.hypot(p.force_stderr, q.force_stderr))
            drift = _drift(v[q.start:q.stop])
            if (abs(p.force - q.force) <= tol and drift != 0.0
                    and np.sign(drift) == np.sign(p.velocity - q.velocity)):
                out[-1] = p
                continue
        out.append(p)
    return out


def binned_points(
    record: Record,
    *,
    inertia: float,
    bins: int = 20,
    cutoff_hz: float | None = None,
    min_fraction: float = 0.05,
    min_per_bin: int = 20,
) -> list[SteadySegment]:
    """Friction points from non-steady motion: ``F − J·a`` binned by velocity per direction.

    Parameters
    ----------
    record : Record
        Position ``x`` [m or rad] (velocity ``v`` if present) and force ``u`` [N or N·m]
        of a sinusoidal, triangular or any other test with a range of speeds.
    inertia : float
        Known or estimated inertia J [kg or kg·m²] (e.g. from ``estimate_idim``); >= 0.
    bins : int
        Velocity bins per direction [-], equal-count (quantiles of the speed); >= 3.
    cutoff_hz : float, optional
        Zero-phase low-pass before differentiating [Hz]; default ``fs/20``.
    min_fraction : float
        Speeds below this fraction of the top speed are left out [-] (near reversals the
        friction is in its presliding/stiction regime, not on the map).
    min_per_bin : int
        Fewest samples per bin [-].

    Returns
    -------
    list of SteadySegment
        One point per bin (``start = stop = -1``): mean velocity and mean ``F − J·a``
        with standard errors ``std/√n_eff`` (AR(1) effective sample count).

    Raises
    ------
    RecordError
        If the record has no force.
    ParameterError
        If ``inertia`` or ``bins`` is out of range.
    IdentificationError
        If neither direction has ``bins * min_per_bin`` moving samples (too many bins for
        the record); the message gives the most bins it can fill.

    Notes
    -----
    The equation of motion (2.155) with ``K = 0`` gives the friction as ``u − J·a``; at
    every speed the map is the average over the samples at that speed, so plateaus are
    not needed. An error ``δJ`` in the inertia adds ``δJ·a`` to each point; it averages
    out where a bin holds accelerating and decelerating samples alike (sinusoids and
    triangles do).
    """
    if record.u is None:
        raise RecordError("a friction map needs the applied force or torque u; got a record "
                          f"with columns {list(record.columns)}")
    if not (math.isfinite(inertia) and inertia >= 0):
        raise ParameterError(f"inertia must be >= 0 [kg or kg·m²]; got {inertia}")
    if int(bins) != bins or bins < 3:
        raise ParameterError(f"bins must be an integer >= 3; got {bins}")
    record = record.resampled_uniform(
        purpose="differentiating the position for the friction map")
    fc = record.fs / 20.0 if cutoff_hz is None else cutoff_hz
    _, v_x, a = differentiate(record.x, record.fs, cutoff_hz=fc)
    v = np.asarray(record.v, float) if record.v is not None else v_x
    force = np.asarray(record.u, float) - inertia * a
    top = float(np.max(np.abs(v)))
    points = []
    counts = []
    for sign in (1.0, -1.0):
        sel = np.flatnonzero(sign * v > min_fraction * top)
        counts.append(int(sel.size))
        if sel.size < bins * min_per_bin:
            continue
        order = sel[np.argsort(np.abs(v[sel]))]
        for chunk in np.array_split(order, int(bins)):
            idx = np.sort(chunk)
            vm, vs = segment_mean(v[idx])
            fm, fse = segment_mean(force[idx])
            points.append(SteadySegment(-1, -1, vm, vs, fm, fse, int(idx.size)))
    if not points:  # issue 28: reported as 'no steady-velocity segments found'
        most = max(counts) // min_per_bin
        fix = (f"give at most bins={most} (CLI: --bins)" if most >= 3 else
               "record more motion (a longer run or more cycles)")
        raise IdentificationError(
            f"bins={bins} velocity bins of at least {min_per_bin} samples need "
            f"{bins * min_per_bin} moving samples in one direction; the record has "
            f"{counts[0]} (+) and {counts[1]} (-) above {min_fraction:g} of the top speed: "
            f"{fix}")
    return points


def estimate_friction_map(
    data: Record | Sequence[Record] | Sequence[SteadySegment],
    *,
    models: Sequence[str] = ("coulomb_viscous", "lorentzian", "bo_pavelescu", "hess_soom"),
    min_speeds: int = 3,
    velocity_unit: str | None = None,
    force_unit: str | None = None,
    min_speed: float = 0.0,
    max_speed: float = math.inf,
    **steady_kw: Any,
) -> FrictionMap:
    """Fit steady-velocity friction maps with separate + and − branches.

    Parameters
    ----------
    data : Record, sequence of Record, or sequence of SteadySegment
        One record with several constant-speed plateaus, a set of constant-speed runs
        (one record each), or ready-made steady points.
    models : sequence of str
        Keys of :data:`BRANCH_MAPS`; ``"coulomb_viscous"`` is always fitted.
    min_speeds : int
        Fewest steady points per direction for the Coulomb + viscous fit [-]; >= 3 so
        that the residual scatter can be assessed. Stribeck maps need one more point than
        they have parameters and are skipped (with a warning) otherwise.
    velocity_unit, force_unit : str, optional
        Units for the result; default from the records (``x`` unit + "/s", ``u`` unit).
    min_speed, max_speed : float
        Keep only points whose speed lies in ``[min_speed, max_speed]`` [m/s or rad/s].
    **steady_kw
        Passed to :func:`steady_points`.

    Returns
    -------
    FrictionMap
        Fits, AIC/BIC comparison and the points.

    Raises
    ------
    IdentificationError
        If no steady segment is found, motion is in one direction only, or a direction
        has fewer than ``min_speeds`` distinct steady speeds; the message says which
        experiment to add.
    ParameterError
        If a model name is unknown or ``min_speeds < 3``.

    Notes
    -----
    Branch fits weight each point by ``1/σ_F`` and scale the parameter covariance by the
    reduced χ² when it exceeds 1 (scatter beyond the segment noise, e.g. position-dependent
    friction, must widen the intervals). AIC = n ln(RSS/n) + 2k, BIC = n ln(RSS/n) + k ln n
    with the weighted RSS.

    Examples
    --------
    >>> import numpy as np
    >>> from driveid.signal.steady import SteadySegment
    >>> v = np.array([-3.0, -2.0, -1.0, 1.0, 2.0, 3.0])
    >>> f = np.where(v > 0, 2.0 + 0.5 * v, -1.5 + 0.8 * v)
    >>> pts = [SteadySegment(0, 100, vi, 0.01, fi, 0.01, 100) for vi, fi in zip(v, f)]
    >>> fm = estimate_friction_map(pts, models=("coulomb_viscous",))
    >>> round(fm.estimate.value("Fc_plus"), 3), round(fm.estimate.value("Fc_minus"), 3)
    (2.0, 1.5)
    """
    unknown = [m for m in models if m not in BRANCH_MAPS]
    if unknown:
        raise ParameterError(f"unknown friction map(s) {unknown}; use {sorted(BRANCH_MAPS)}")
    if int(min_speeds) != min_speeds or min_speeds < 3:
        raise ParameterError(f"min_speeds must be an integer >= 3; got {min_speeds}")
    if not (0 <= min_speed <= max_speed):
        raise ParameterError(f"need 0 <= min_speed <= max_speed [m/s or rad/s]; got "
                             f"{min_speed}, {max_speed}")
    points, vu, fu = _collect(data, steady_kw)
    points = [p for p in points if min_speed <= abs(p.velocity) <= max_speed]
    vu = velocity_unit or vu
    fu = force_unit or fu
    if not points:
        raise IdentificationError(
            "no steady-velocity segments found; run the drive at constant speeds (each "
            "plateau at least min_samples long) in both directions, or loosen rel_tol; got 0 "
            "segments"
        )
    plus = [p for p in points if p.velocity > 0]
    minus = [p for p in points if p.velocity < 0]
    if not plus or not minus:
        have = "positive" if plus else "negative"
        raise IdentificationError(
            f"steady segments in one direction only ({have}); add constant-speed runs in the "
            f"other direction to separate Coulomb friction from an offset; got {len(plus)} "
            f"positive and {len(minus)} negative segments"
        )
    for name, branch in (("positive", plus), ("negative", minus)):
        n_speeds = _distinct_speeds(branch)
        if n_speeds < min_speeds:
            raise IdentificationError(
                f"the {name} direction has too few distinct steady speeds for a Coulomb + "
                f"viscous fit (need {min_speeds}); add constant-speed runs at more speeds, "
                f"spread over the working range; got {n_speeds}"
            )
    fits: dict[str, Estimate] = {}
    comparison: list[dict[str, Any]] = []
    wanted = ["coulomb_viscous"] + [m for m in models if m != "coulomb_viscous"]
    for model in wanted:
        fits[model] = _fit_model(model, plus, minus, vu, fu, comparison)
    for branch in ("plus", "minus"):
        rows = [r for r in comparison
                if r["branch"] == branch and r["identifiable"] and math.isfinite(r["aic"])]
        best = min(rows, key=lambda r: r["aic"])["model"] if rows else None
        for r in comparison:
            if r["branch"] == branch:
                r["best_aic"] = r["model"] == best
    return FrictionMap(estimate=_combine(fits["coulomb_viscous"], fu, vu), fits=fits,
                       comparison=comparison, points=points)


def _collect(data: Any, steady_kw: dict[str, Any]) -> tuple[list[SteadySegment], str, str]:
    if isinstance(data, Record):
        data = [data]
    data = list(data)
    if data and all(isinstance(d, SteadySegment) for d in data):
        return data, "m/s", "N"
    points: list[SteadySegment] = []
    vu, fu = "", ""
    for d in data:
        if not isinstance(d, Record):
            raise ParameterError(
                "data must be a Record, a sequence of Records or of SteadySegments; got an "
                f"item of type {type(d).__name__}"
            )
        points += steady_points(d, **steady_kw)
        # velocity is dx/dt: Record fills a missing v unit with rad/s even for x in m
        vu = vu or d.units.get("x", "m") + "/s"
        fu = fu or d.units.get("u", "N")
    return points, vu or "m/s", fu or "N"


def _distinct_speeds(points: list[SteadySegment]) -> int:
    s = np.sort(np.abs([p.velocity for p in points]))
    if s.size == 0:
        return 0
    return 1 + int(np.count_nonzero(np.diff(s) > 0.02 * s[1:]))


def _units(name: str, vu: str, fu: str) -> str:
    if name in ("Fc", "Fs"):
        return fu
    if name == "Fv":
        return f"{fu}/({vu})"
    if name == "vs":
        return vu
    return "-"


#: χ² p-value below which the plateau means scatter about a branch's map more than their
#: error bars allow: warned, and the error bars widened (issue 24, :func:`_scatter_warning`).
SCATTER_P = 0.01


def _fit_branch(model: str, pts: list[SteadySegment]) -> dict[str, Any]:
    func, names, _ = BRANCH_MAPS[model]
    s = np.abs([p.velocity for p in pts])
    f = np.abs([p.force for p in pts])
    sig = np.array([p.force_stderr for p in pts])
    sig = np.where(np.isfinite(sig) & (sig > 0), sig, np.nanmedian(sig[sig > 0])
                   if np.any(sig > 0) else 1.0)
    n, k = s.size, len(names)
    if n <= k:
        return {"skipped": f"{n} points for {k} parameters; add steady runs at more speeds"}
    if model == "coulomb_viscous":
        A = np.column_stack([np.ones(n), s]) / sig[:, None]
        theta, *_ = np.linalg.lstsq(A, f / sig, rcond=None)
        r = f / sig - A @ theta
        jac = A
    else:
        theta, r, jac = _fit_nonlinear(func, names, s, f, sig)
    rss = float(r @ r)
    dof = n - k
    chi2_red = rss / dof
    scatter_p = float(chi2.sf(rss, dof))
    try:
        cov = np.linalg.inv(jac.T @ jac) * max(1.0, chi2_red)
        se = np.sqrt(np.abs(np.diag(cov)))
    except np.linalg.LinAlgError:
        se = np.full(k, np.inf)
    if scatter_p < SCATTER_P:
        # the error bars then rest on the scatter of n - k points (3 on the benchmark's
        # staircase): Student's t, not the normal, gives its 95 % interval; the factor
        # puts that width on ±1.96 standard errors (1/f-like noise: coverage 0.70-0.80
        # with the scatter alone, bench_noise_coverage_fits.py; docs/validation.md)
        se = se * float(student_t.ppf(0.975, dof)) / 1.959964
    rss_n = max(rss / n, 1e-300)
    return {
        "theta": dict(zip(names, map(float, theta), strict=True)),
        "stderr": dict(zip(names, map(float, se), strict=True)),
        "rss": rss, "n": n, "k": k, "chi2_red": chi2_red, "scatter_p": scatter_p,
        "aic": n * math.log(rss_n) + 2 * k,
        "bic": n * math.log(rss_n) + k * math.log(n),
        "speed_range": (float(s.min()), float(s.max())),
    }


def _fit_nonlinear(func: Callable[..., np.ndarray], names: tuple[str, ...], s: np.ndarray,
                   f: np.ndarray, sig: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    # free parameters: Fs enters as Fc + dS with dS >= 0 (the models require mu_s >= mu_k);
    # levels and viscous coefficients are >= 0, vs > 0, delta in [0.3, 5]
    has_fc = "Fc" in names
    i_min = int(np.argmin(s))
    hi_half = s >= np.median(s)
    fc0 = float(np.mean(f[hi_half]))
    start = {"Fc": max(fc0, 0.0), "Fs": max(f[i_min] - fc0, 0.0) if has_fc else f[i_min],
             "vs": max(float(np.median(s)) / 2, 1.5 * s[i_min]), "Fv": 0.0, "delta": 2.0}
    lower = {"Fc": 0.0, "Fs": 0.0, "vs": 1e-3 * s.min(), "Fv": 0.0, "delta": 0.3}
    upper = {"Fc": np.inf, "Fs": np.inf, "vs": 1e3 * s.max(), "Fv": np.inf, "delta": 5.0}
    x0 = [start[n] for n in names]
    lo = [lower[n] for n in names]
    hi = [upper[n] for n in names]
    if s.max() < 1e-12:  # the start must lie 1e-12 inside bounds that scale with the speed
        raise IdentificationError(  # (issue 28: speeds of 1e-20 ended in scipy's error, exit 70)
            "the speeds of the friction map are too small for the Stribeck fit; check the "
            "position's unit (--unit x=UNIT) or rescale it (--scale x=F); got at most "
            f"{float(s.max()):.3g} m/s or rad/s")
    x0 = np.clip(x0, np.array(lo) + 1e-12, np.array(hi) - 1e-12)
    i_fs = names.index("Fs")
    i_fc = names.index("Fc") if has_fc else None
    # d(model params)/d(free params): identity except Fs = Fc + dS
    T = np.eye(len(names))
    if i_fc is not None:
        T[i_fs, i_fc] = 1.0

    def to_model(x: np.ndarray) -> np.ndarray:
        return T @ x

    def resid(x: np.ndarray) -> np.ndarray:
        return (func(s, *to_model(x)) - f) / sig

    sol = optimize.least_squares(resid, x0, bounds=(lo, hi), x_scale="jac")
    # Jacobian with respect to the model parameters: J_free = J_model @ T
    jac = sol.jac @ np.linalg.inv(T)
    return to_model(sol.x), -sol.fun, jac


def _scatter_warning(model: str, branch: str, res: dict[str, Any]) -> list[str]:
    """Warn where the plateau means scatter about the map more than their error bars allow.

    χ² of the weighted branch fit against its degrees of freedom, p < 0.01 (issue 24). On
    the benchmark's staircase (bench_noise_coverage_fits.py, 40 records each) it fired on
    95 % of 1/f-like records and on 91 % of those whose intervals missed, against 5 %
    (white, AR(1) 0.97) and 10 % (25 Hz low-pass) where the intervals are honest; before,
    the map's 0.70-0.80 coverage under 1/f-like noise came without a word.
    """
    dof = res["n"] - res["k"]
    if dof < 1 or not math.isfinite(res["chi2_red"]):
        return []
    p = res["scatter_p"]
    if p >= SCATTER_P:
        return []
    return [f"{model} {branch}: the plateau means scatter about the fitted map "
            f"{math.sqrt(res['chi2_red']):.3g} times more than their error bars allow (χ² "
            f"p = {p:.2g}): slow drift between plateaus (1/f-like noise, temperature) or a "
            "shape this model lacks; the error bars are widened by that factor and by "
            f"Student's t with {dof} degrees of freedom, and may still be short: repeat "
            "the staircase in another order, or compare another model"]


def _fit_model(model: str, plus: list[SteadySegment], minus: list[SteadySegment], vu: str,
               fu: str, comparison: list[dict[str, Any]]) -> Estimate:
    params: dict[str, Parameter] = {}
    warn: list[str] = []
    diag: dict[str, Any] = {"equation": BRANCH_MAPS[model][2]}
    for branch, pts in (("plus", plus), ("minus", minus)):
        res = _fit_branch(model, pts)
        if "skipped" in res:
            warn.append(f"{model} {branch} branch skipped: {res['skipped']}")
            comparison.append({"model": model, "branch": branch, "k": len(BRANCH_MAPS[model][1]),
                               "n": len(pts), "rss": math.nan, "aic": math.nan,
                               "bic": math.nan, "identifiable": False})
            continue
        lo_s, hi_s = res["speed_range"]
        warn.extend(_scatter_warning(model, branch, res))
        flagged = set()
        vs = res["theta"].get("vs")
        if vs is not None and not lo_s <= vs <= hi_s:
            flagged |= {"vs", "Fs"} | ({"delta"} if model == "bo_pavelescu" else set())
            where = "below the slowest" if vs < lo_s else "above the fastest"
            warn.append(
                f"{model} {branch}: Stribeck velocity unidentifiable (fit {vs:.3g} {vu} is "
                f"{where} measured speed, {lo_s:.3g}…{hi_s:.3g} {vu}); add steady runs at "
                f"{'slower' if vs < lo_s else 'faster'} speeds"
            )
        for name, val in res["theta"].items():
            se = res["stderr"][name]
            # shape parameters need a tighter bound: a Stribeck velocity known to a factor
            # of 2 says nothing about where the transition is
            limit = 0.5 if name in ("vs", "delta") else 1.0
            if name in flagged or (math.isfinite(se) and se <= limit * abs(val)):
                continue
            if model == "coulomb_viscous" and math.isfinite(se):
                # a linear fit's value stays meaningful: it is just consistent with zero
                warn.append(f"{model} {branch}: {name} = {val:.3g} ± {se:.3g} is not "
                            "significantly different from 0")
                continue
            flagged.add(name)
            warn.append(f"{model} {branch}: {name} unidentifiable (standard error "
                        f"{se:.3g} exceeds {limit:g}·|value| = {limit * abs(val):.3g})")
        if "vs" in flagged:
            # without a Stribeck velocity the static level and shape exponent mean nothing
            flagged |= {"Fs", "delta"} & set(res["theta"])
        for name, val in res["theta"].items():
            se = res["stderr"][name]
            if name in flagged:
                params[f"{name}_{branch}"] = Parameter(math.nan, math.nan, _units(name, vu, fu))
                diag[f"{name}_{branch}_raw"] = val
            else:
                params[f"{name}_{branch}"] = Parameter(val, se, _units(name, vu, fu))
        for key in ("rss", "aic", "bic", "chi2_red", "n"):
            diag[f"{key}_{branch}"] = res[key]
        comparison.append({"model": model, "branch": branch, "k": res["k"], "n": res["n"],
                           "rss": res["rss"], "aic": res["aic"], "bic": res["bic"],
                           "identifiable": not flagged})
    return Estimate(method=f"friction-map-{model}", params=params, diagnostics=diag,
                    warnings=tuple(warn))


def _combine(cv: Estimate, fu: str, vu: str) -> Estimate:
    params = dict(cv.params)
    for mean, delta, key in (("fk_mean", "fk_delta", "Fc"), ("c_mean", "c_delta", "Fv")):
        p, m = cv.params.get(f"{key}_plus"), cv.params.get(f"{key}_minus")
        if p is None or m is None:
            continue
        se = 0.5 * math.hypot(p.stderr, m.stderr)
        params[mean] = Parameter(0.5 * (p.value + m.value), se, p.unit)
        params[delta] = Parameter(0.5 * (p.value - m.value), se, p.unit)
    return Estimate(method="friction-map-coulomb-viscous", params=params,
                    diagnostics=dict(cv.diagnostics), warnings=cv.warnings)


def read_tro2021_steady_state(folder: str | Path) -> list[Record]:
    """Read the steady-state EPOS exports of one TRO 2021 screw drive.

    Parameters
    ----------
    folder : str or Path
        A folder of ``<rpm>.csv`` / ``n<rpm>.csv`` files, e.g.
        ``screw_drive_friction_TRO2021/driveNo1/steady_state/0.096kg``.

    Returns
    -------
    list of Record
        One record per file, sorted by signed set-point: ``t`` [s], ``v`` motor velocity
        [rad/s], ``u`` motor torque [N·m], ``x`` the integrated velocity [rad] (the files
        carry no position). Signs follow the authors' ``getEposData.m``: both channels
        negated, so files without ``n`` have positive velocity. ``meta`` holds
        ``set_point_rpm`` and ``source``.

    Raises
    ------
    FileNotFoundError
        If the folder does not exist.
    FileFormatError
        If it has no CSV files or a file lacks the ``ms;rpm;%`` units line.

    Notes
    -----
    Torque [N·m] = −torque[%]·9.84e-3/100 (nominal torque of the EPOS set-up). Rows
    carrying a hand-written note (``-1200,,was -8.9`` in three driveNo3 files) are dropped.
    """
    from scipy.integrate import cumulative_trapezoid

    folder = Path(folder)
    if not folder.is_dir():
        raise FileNotFoundError(f"no such folder: {folder}")
    files = sorted(folder.glob("*.csv"))
    if not files:
        raise FileFormatError(f"{folder} holds no .csv files; point at a steady_state/<load> "
                              "folder of the TRO 2021 data")
    records = []
    for path in files:
        lines = path.read_text(encoding="latin-1").splitlines()
        try:
            i = next(k for k, line in enumerate(lines) if line.startswith("ms;"))
        except StopIteration:
            raise FileFormatError(
                f"{path.name}: no units line 'ms;rpm;%'; not an EPOS recorder export"
            ) from None
        rows = []
        for line in lines[i + 1:]:
            if not line.strip() or "was" in line:
                continue
            try:
                rows.append([float(c.split(",")[0]) for c in line.split(";")[:3]])
            except ValueError:
                raise FileFormatError(f"{path.name}: non-numeric row {line!r}") from None
        a = np.array(rows)
        t = a[:, 0] / 1000.0
        w = -a[:, 1] * np.pi / 30.0
        tau = -a[:, 2] * TRO2021_NOMINAL_TORQUE / 100.0
        stem = path.stem
        rpm = -float(stem[1:]) if stem.startswith("n") else float(stem)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            x = cumulative_trapezoid(w, t, initial=0.0)
        records.append(Record(
            t=t, x=x, u=tau, v=w,
            meta={"units": {"x": "rad", "u": "N·m", "v": "rad/s"}, "source": str(path),
                  "set_point_rpm": rpm},
        ))
    records.sort(key=lambda r: r.meta["set_point_rpm"])
    return records
