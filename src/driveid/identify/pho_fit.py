r"""Whole-record output-error fit of a PHO campaign: the delayed-PD closed loop fitted jointly.

The peak analysis (:func:`driveid.identify.pho.estimate_pho_records`) reduces each (P, D)
setting to a handful of features (σ±, ω_d, θk from the peaks) and combines them through the
exact delayed-PD theory of :mod:`driveid.identify.pho`. On quantised records the peak
values carry rounding errors that follow the signal, and the features' error bars do not
describe them: the issue-13 measurement found 40-50 % coverage of the 95 % intervals of
J, c_mean and fk_mean on asymmetric encoder campaigns. This module instead fits **every
sample of every run** at once.

The model
---------
Each run is de Marchi (1998) Eq. (2.180) with the asymmetric friction of (2.155),

.. math::

    J x'' + (\bar c + Δc\,s)\,x' + K x + \bar f_k s + Δf_k
        = -P\,x(t - Δ) - D\,x'(t - Δ), \qquad s = \operatorname{sgn} x',

released at ``t = 0`` from rest at ``x0`` (held there before, so the delayed command reads
``x0`` for ``t < Δ``) and sticking whenever the body stops with the applied force inside
the static band (static = kinetic friction, as in the presets). It is integrated by the
event-located drive simulator (:func:`driveid.sim.drive.simulate_drive`, one body, the same
RK4 step for every evaluation of a fit so that the model is a smooth function of the
parameters between stick events). The unknowns are shared by all runs: ``J``, ``c_mean``,
``c_delta``, ``K`` (or known), ``fk_mean``, ``fk_delta`` and the loop delay (or known);
the per-run inputs are the gains ``meta["P"]``, ``meta["D"]``, ``meta["saturation"]`` if
any, and the release ``meta["x0"]``; a run without it (a hand-written manifest) gets its
release fitted as one more unknown, started from its first sample (``fit_release=True``
fits every run's: a holding loop may leave the axis off the commanded ``x0``).

Unweighted least squares over all samples (Levenberg–Marquardt with Marquardt scaling;
the Jacobian by forward differences of the simulator, relative step 1e-6: central
differences with steps from 1e-5 to 1e-7 agree to ~1e-8 on the test bed, so the model is
smooth at that scale). Start values: the peak analysis.

Error bars of the campaign fit
------------------------------
White noise: ``s²(JᵀJ)⁻¹`` with ``s² = RSS/(n - p)``. Encoder records (every run on one
grid, :func:`driveid.identify.output_error.detect_quantum`, or ``quantisation=`` the step):
a parametric bootstrap, as for free decays — the fitted response, plus any noise beyond the
rounding, re-quantised on a grid of random phase per run, ``bootstrap`` times. Each
replicate is refitted by one Gauss–Newton step from the fit with its Jacobian
(``refit=False``, the default: the rounding moves the estimate by far less than the
curvature scale of the model, so the step is the refit to first order) or by a full fit
(``refit=True``, about ``0.6·bootstrap`` times the fit's cost; its standard errors agreed
with the step's to 3 %). The covariance of the replicates, widened by
``t_{B-1,0.975}/1.96`` for their number
(:func:`~driveid.identify.output_error.replicate_covariance`), is the estimate's.

Measured (``benchmarks/bench_pho_coverage.py``, docs/pho-fit.md): on 200 quantised
asymmetric campaigns each of the test bed (8000 counts/rev) and the pendulum cart (10 µm),
delay estimated, the 95 % intervals covered the truth in 92-96.5 % for every field, with
bias < 0.1 se and scatter/se 0.97-1.03; the peak analysis's covered 27.5-100 %.

Limits
------
One rigid body: a drive with backlash or compliance between the motor and the load (the
``testbed`` preset) has no single J; fit its motor alone or use the peaks. Static friction
is taken equal to kinetic.
Relative to the thesis: the thesis identifies from peaks (§2.2.7); the whole-record fit is
our extension, with the thesis's model unchanged.

References
----------
.. [1] J. A. de Marchi, "Modeling of dynamic friction, impact backlash and elastic compliance
       nonlinearities in machine tools", PhD thesis, RPI, 1998, §2.2.7, Eqs. (2.155), (2.180).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from driveid.errors import DriveIdError, IdentificationError, ParameterError, RecordError
from driveid.identify._plausibility import plausibility_checked
from driveid.identify.estimate import Estimate, Parameter
from driveid.identify.output_error import detect_quantum, replicate_covariance
from driveid.identify.pho import _gains, estimate_pho_records
from driveid.io.record import Record

__all__ = ["FIELDS", "estimate_pho_output_error"]

#: Parameters of the fit, in the order of the internal vector.
FIELDS = ("J", "c_mean", "c_delta", "K", "fk_mean", "fk_delta", "delay")
#: Relative forward-difference step of the Jacobian (model smooth to ~1e-13 between events).
_FD_STEP = 1e-6
#: Most Levenberg–Marquardt iterations of a fit.
_MAX_ITER = 40


class _Campaign:
    """The runs of a campaign and the simulated closed loop for a parameter vector."""

    def __init__(self, records: Sequence[Record], fit_release: bool | None):
        self.runs = []
        self.fitted_release = []
        for k, rec in enumerate(records):
            P, D = _gains(rec, k)
            t = np.asarray(rec.t, float)
            dt = float(np.median(np.diff(t)))
            index = np.round(t / dt).astype(int)
            if np.any(np.abs(t - index * dt) > 1e-6 * dt) or index[0] < 0:
                raise RecordError(
                    f"record {k} is not uniformly sampled from the release at t = 0; the PHO "
                    "whole-record fit simulates on the sample grid - resample the record or "
                    "use --method peaks")
            x0 = rec.meta.get("x0")
            if x0 is None:
                if index[0] != 0:
                    raise RecordError(
                        f"record {k} has no meta['x0'] and does not start at the release "
                        "(t = 0); give the run's release position x0 (manifest entry)")
                x0 = float(rec.x[0])
            if fit_release or (fit_release is None and rec.meta.get("x0") is None):
                self.fitted_release.append(k)
            sat = rec.meta.get("saturation")
            self.runs.append({"P": P, "D": D, "x0": float(x0), "dt": dt, "index": index,
                              "saturation": math.inf if sat is None else float(sat)})
        self.y = [np.asarray(r.x, float) for r in records]
        self.target = np.concatenate(self.y)
        self.edges = np.cumsum([0] + [v.size for v in self.y])
        self.n = self.target.size
        self.max_step = None
        self.nfev = 0

    def set_step(self, theta: np.ndarray) -> None:
        """Fix the RK4 step for the whole fit (the simulator's default at ``theta``)."""
        J, c, cd, K = theta[:4]
        rate = max(math.sqrt((K + abs(r["P"])) / J) for r in self.runs)
        rate = max(rate, max((abs(c) + abs(cd) + abs(r["D"])) / J for r in self.runs))
        self.max_step = min(0.2 / rate, min(r["dt"] for r in self.runs))
        if theta[6] > 0:
            self.max_step = min(self.max_step, float(theta[6]))

    def run(self, theta: np.ndarray, k: int) -> np.ndarray:
        """Return the simulated position of run ``k`` at its samples [rad or m]."""
        from driveid.sim.drive import BodyParams, DriveParams, PDFeedback, simulate_drive

        J, c, cd, K, fkm, fkd, delay = (float(v) for v in theta[:7])
        r = self.runs[k]
        x0 = float(theta[7 + k])
        body = BodyParams(J=J, K=K, c_mean=c, c_delta=cd, fk_mean=fkm, fk_delta=fkd)
        fb = PDFeedback(P=r["P"], D=r["D"], delay=delay, saturation=r["saturation"])
        n_out = int(r["index"][-1])
        res = simulate_drive(DriveParams(bodies=(body,), feedback=fb), duration=n_out * r["dt"],
                             fs=1.0 / r["dt"], x0=[x0], max_step=self.max_step)
        x = np.asarray(res.x[0], float)
        if x.size <= n_out:
            raise IdentificationError("simulated run shorter than its record")
        return x[r["index"]]

    def model(self, theta: np.ndarray) -> np.ndarray:
        """All runs' simulated positions, concatenated [rad or m]; nan if not simulable."""
        self.nfev += 1
        try:
            return np.concatenate([self.run(theta, k) for k in range(len(self.runs))])
        except DriveIdError:
            return np.full(self.n, np.nan)

    def jacobian(self, theta, free, f0, scale):
        """Forward-difference Jacobian (n, len(free)) of the model at ``theta``.

        A release ``theta[7 + k]`` moves run ``k`` only, so only that run is simulated.
        """
        jac = np.zeros((self.n, len(free)))
        for j, i in enumerate(free):
            h = _FD_STEP * max(abs(theta[i]), scale[i])
            up = theta.copy()
            up[i] += h
            if i < 7:
                jac[:, j] = (self.model(up) - f0) / h
            else:
                part = slice(self.edges[i - 7], self.edges[i - 6])
                try:
                    jac[part, j] = (self.run(up, i - 7) - f0[part]) / h
                except DriveIdError:
                    jac[part, j] = np.nan
        return jac


def _fit(problem, theta0, free, lower, upper, scale, target=None):
    """Levenberg–Marquardt over the ``free`` entries of ``theta``.

    Returns ``(theta, f, jac, rss, iterations)``; stops when an iteration lowers χ² by less
    than 1e-4 (in units of the current s²) or the step is below 1e-9 of the scale.
    """
    y = problem.target if target is None else target
    theta = theta0.copy()
    f = problem.model(theta)
    if not np.all(np.isfinite(f)):
        raise IdentificationError(
            "the start values cannot be simulated; the peak analysis gave an unphysical "
            "start (check the gains and the units of the records)")
    r = y - f
    rss = float(r @ r)
    dof = max(problem.n - len(free), 1)
    jac = problem.jacobian(theta, free, f, scale)
    lam = 1e-3
    it = 0
    while it < _MAX_ITER:
        it += 1
        A = jac.T @ jac
        g = jac.T @ r
        d = np.diag(A).copy()
        d[d <= 0] = 1.0
        accepted = False
        for _ in range(12):
            try:
                step = np.linalg.solve(A + lam * np.diag(d), g)
            except np.linalg.LinAlgError:
                lam *= 10.0
                continue
            trial = theta.copy()
            trial[free] = np.clip(theta[free] + step, lower[free], upper[free])
            f_t = problem.model(trial)
            r_t = y - f_t
            rss_t = float(r_t @ r_t) if np.all(np.isfinite(f_t)) else math.inf
            if rss_t <= rss:
                accepted = True
                break
            lam *= 4.0
        if not accepted:
            break
        gain = (rss - rss_t) / max(rss / dof, 1e-300)
        small = np.all(np.abs(trial[free] - theta[free]) <= 1e-9 * scale[free])
        theta, f, r, rss = trial, f_t, r_t, rss_t
        lam = max(lam / 3.0, 1e-9)
        if gain < 1e-4 or small:
            break
        jac = problem.jacobian(theta, free, f, scale)
    jac = problem.jacobian(theta, free, f, scale)
    return theta, f, jac, rss, it


def _bootstrap(problem, theta, f, jac, free, s2, quantum, replicates, rng, refit, lower,
               upper, scale, progress):
    """Covariance of the estimates from the fitted response re-quantised on random grids."""
    gen = np.random.default_rng(rng)
    extra = math.sqrt(max(s2 - quantum**2 / 12.0, 0.0))
    bounds = np.cumsum([0] + [v.size for v in problem.y])
    solve = np.linalg.pinv(jac)
    out = []
    for b in range(replicates):
        y_b = np.empty_like(f)
        for k in range(len(problem.y)):  # each run its own grid phase
            part = f[bounds[k]:bounds[k + 1]]
            if extra > 0:
                part = part + gen.normal(0.0, extra, part.size)
            phase = gen.uniform(0.0, quantum)
            y_b[bounds[k]:bounds[k + 1]] = quantum * np.round((part - phase) / quantum) + phase
        if refit:
            try:
                est = _fit(problem, theta, free, lower, upper, scale, target=y_b)[0][free]
            except IdentificationError:
                est = None
        else:
            est = theta[free] + solve @ (y_b - f)
        if est is not None and np.all(np.isfinite(est)):
            out.append(est)
        if progress is not None:
            progress(b + 1, replicates)
    if len(out) < max(10, replicates // 2):
        raise IdentificationError(
            f"only {len(out)} of {replicates} bootstrap refits converged; the error bars of "
            "this quantised campaign cannot be trusted (record more cycles or a finer encoder)")
    return replicate_covariance(out)


def _units(units: str) -> dict[str, str]:
    if units == "m":
        return {"J": "kg", "c_mean": "N·s/m", "c_delta": "N·s/m", "K": "N/m", "fk_mean": "N",
                "fk_delta": "N", "delay": "s"}
    if units == "rad":
        return {"J": "kg·m²", "c_mean": "N·m·s/rad", "c_delta": "N·m·s/rad", "K": "N·m/rad",
                "fk_mean": "N·m", "fk_delta": "N·m", "delay": "s"}
    raise ParameterError(f"units must be 'rad' (rotational) or 'm' (linear); got {units!r}")


@plausibility_checked
def estimate_pho_output_error(
    records: Sequence[Record],
    *,
    delay: float | None = None,
    K_known: float | None = None,
    units: str | None = None,
    quantisation: float | str | None = "auto",
    bootstrap: int = 50,
    refit: bool = False,
    rng: np.random.Generator | int | None = None,
    start: Estimate | None = None,
    fit_release: bool | None = None,
    progress: Callable[[int, int], Any] | None = None,
) -> Estimate:
    """Fit the delayed-PD closed loop with asymmetric friction to every sample of a campaign.

    Parameters
    ----------
    records : sequence of Record
        The accepted runs [rad or m] from the release at ``t = 0``, uniformly sampled, each
        with ``meta["P"]`` [N·m/rad or N/m], ``meta["D"]`` [N·m·s/rad or N·s/m] and
        ``meta["x0"]`` [rad or m] (else the first sample is the release); at least two
        (P, D) settings.
    delay : float, optional
        Loop delay Δ [s], known; estimated with the rest when None.
    K_known : float, optional
        Known stiffness [N·m/rad or N/m], >= 0 (e.g. 0 for a drive without a spring);
        estimated (bounded at 0, the simulator's range) when None.
    units : {"rad", "m"}, optional
        Default: the records' position unit.
    quantisation : float, "auto" or None
        Encoder step [rad or m]; ``"auto"`` detects it; ``None`` treats the records as
        unquantised (white-noise error bars).
    bootstrap : int
        Bootstrap replicates for quantised records [-]; >= 25.
    refit : bool
        Refit each replicate fully instead of one Gauss–Newton step (module notes).
    rng : Generator or int, optional
        Random generator or seed of the bootstrap.
    start : Estimate, optional
        Start values (``J``, ``c_mean``, ``c_delta``, ``K``, ``fk_mean``, ``fk_delta``,
        ``delay``); default the peak analysis of the same records.
    fit_release : bool, optional
        Fit each run's release position too (one unknown per run [rad or m]); default only
        for runs without ``meta["x0"]`` (whose first, possibly rounded sample starts the
        fit). The loop that held the axis may leave it off the commanded ``x0``.
    progress : callable, optional
        Called as ``progress(done, total)`` after each bootstrap replicate.

    Returns
    -------
    Estimate
        Method ``"pho-output-error"``: ``J``, ``c_mean``, ``c_delta``, ``K``, ``fk_mean``,
        ``fk_delta``, ``delay`` (given ones ``fixed``), ``covariance`` of the estimated
        ones; ``data_used`` holds per run ``P``, ``D``, ``x0``, ``run_samples`` and,
        concatenated over the runs, the fitted ``fit_x`` and the ``residual`` [rad or m];
        diagnostics ``n_samples``, ``noise_std``, ``quantum``, ``bootstrap``, ``nfev``.

    Raises
    ------
    IdentificationError
        If the peak analysis cannot give start values, or the campaign does not determine
        the unknowns (singular Jacobian).
    ParameterError
        For a missing gain, ``bootstrap < 25``, a bad ``delay``, ``K_known`` or
        ``quantisation``.
    RecordError
        For a record not sampled uniformly from its release.
    """
    records = list(records)
    if not records:
        raise IdentificationError(
            "no records: a PHO campaign needs runs at two or more (P, D) settings")
    for k, rec in enumerate(records):
        if not isinstance(rec, Record):
            raise ParameterError(f"records[{k}] must be a Record; got {type(rec).__name__}")
    if not (isinstance(bootstrap, int) and bootstrap >= 25):
        raise ParameterError(f"bootstrap must be an integer >= 25 replicates; got {bootstrap!r}")
    if delay is not None and not (math.isfinite(delay) and delay >= 0):
        raise ParameterError(f"delay must be finite and >= 0 [s], or None; got {delay!r}")
    if K_known is not None and not (math.isfinite(K_known) and K_known >= 0):
        raise ParameterError(
            f"K_known must be >= 0 [N·m/rad or N/m] (the simulated loop has no negative "
            f"spring) or None; got {K_known!r}")
    if units is None:
        units = records[0].units.get("x", "rad")
    unit = _units(units)
    if quantisation == "auto":
        found = [detect_quantum(np.asarray(r.x, float)) for r in records]
        quantum = min(found) if all(q is not None for q in found) else None
    elif quantisation is None:
        quantum = None
    elif isinstance(quantisation, (int, float)) and quantisation > 0:
        quantum = float(quantisation)
    else:
        raise ParameterError(
            f"quantisation must be 'auto', None or the encoder step > 0 [rad or m]; got "
            f"{quantisation!r}")
    problem = _Campaign(records, fit_release)
    if start is None:
        start = estimate_pho_records(records, delay=delay, K_known=K_known, units=units)
    theta0 = np.array([start.value(n) if n in start else 0.0 for n in FIELDS]
                      + [r["x0"] for r in problem.runs], float)
    if delay is not None:
        theta0[6] = delay
    if K_known is not None:
        theta0[3] = K_known
    free = [i for i, n in enumerate(FIELDS)
            if not ((n == "K" and K_known is not None) or (n == "delay" and delay is not None))]
    n_phys = len(free)
    free += [7 + k for k in problem.fitted_release]
    # scales for steps and stopping: an asymmetry or K may be 0, so borrow its partner's
    gains = np.array([r["P"] for r in problem.runs])
    scale = np.abs(theta0).copy()
    scale[2] = max(scale[2], 0.1 * scale[1], 1e-12)
    scale[3] = max(scale[3], 0.1 * float(np.median(np.abs(gains))))
    scale[5] = max(scale[5], 0.1 * scale[4], 1e-12)
    scale[6] = max(scale[6], 1e-3)
    scale[7:] = max(float(np.max(np.abs(theta0[7:]))), 1e-12)
    scale = np.maximum(scale, 1e-12)
    lower = np.concatenate([[1e-9 * scale[0], -np.inf, -np.inf, 0.0, 0.0, -np.inf, 0.0],
                            np.full(len(problem.runs), -np.inf)])
    upper = np.full(lower.size, np.inf)
    theta0 = np.clip(theta0, lower, upper)
    problem.set_step(theta0)
    theta, f, jac, rss, iterations = _fit(problem, theta0, free, lower, upper, scale)
    dof = problem.n - len(free)
    if dof <= 0:
        raise IdentificationError(f"{problem.n} samples cannot determine {len(free)} unknowns")
    s2 = rss / dof
    if not (np.all(np.isfinite(jac)) and np.all(np.isfinite(theta))):
        raise IdentificationError(
            "the fitted closed loop cannot be simulated near its optimum (non-finite "
            "Jacobian); check the gains and units of the records, or use the peak analysis")
    cond = float(np.linalg.cond(jac / scale[free]))
    if not math.isfinite(cond) or cond > 1e12:
        raise IdentificationError(
            "the runs do not separate the unknowns (singular Jacobian); add runs with widely "
            f"different P, or give the delay or K; got condition number {cond:.3g}")
    if quantum is not None:
        cov = _bootstrap(problem, theta, f, jac, free, s2, quantum, bootstrap, rng, refit,
                         lower, upper, scale, progress)
    else:
        cov = s2 * np.linalg.inv(jac.T @ jac)
    se = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    release_se = np.full(len(problem.runs), np.nan)
    for j, i in enumerate(free[n_phys:], start=n_phys):
        release_se[i - 7] = se[j]
    params = {}
    for i, name in enumerate(FIELDS):
        if i in free:
            params[name] = Parameter(float(theta[i]), float(se[free.index(i)]), unit[name])
        else:
            params[name] = Parameter(float(theta[i]), math.nan, unit[name], fixed=True)
    warnings = [f"{FIELDS[i]} = {theta[i]:.4g} sits on its bound {lower[i]:g}: the fit wants "
                "it lower than the simulator allows; its error bar is not reliable"
                for i in free if theta[i] <= lower[i] and lower[i] > -np.inf]
    if iterations >= _MAX_ITER:
        warnings.append(f"the fit stopped after {_MAX_ITER} iterations without converging; "
                        "check the start values (the peak analysis)")
    residual = problem.target - f
    return Estimate(
        method="pho-output-error",
        params=params,
        covariance={"names": [FIELDS[i] for i in free[:n_phys]],
                    "matrix": cov[:n_phys, :n_phys]},
        warnings=tuple(warnings),
        data_used={
            "P": np.array([r["P"] for r in problem.runs]),
            "D": np.array([r["D"] for r in problem.runs]),
            "x0": theta[7:].copy(),
            "x0_se": release_se,
            "run_samples": np.array([v.size for v in problem.y]),
            "fit_x": f,
            "residual": residual,
        },
        diagnostics={
            "n_samples": problem.n,
            "n_runs": len(problem.runs),
            "n_records": len(records),
            "residual_rms": math.sqrt(float(residual @ residual) / problem.n),
            "noise_std": math.sqrt(s2),
            "quantum": quantum,
            "bootstrap": bootstrap if quantum is not None else 0,
            "refit": bool(refit),
            "iterations": iterations,
            "condition": cond,
            "nfev": problem.nfev,
        },
    )
