"""Campaign model, bounded Levenberg–Marquardt fit and static-band scan of the PHO fit.

Helpers of :mod:`driveid.identify.pho.pho_fit` (the public function and its notes live there).

The parameter vector ``theta`` holds ``J, c_mean, c_delta, K, fk_mean, fk_delta, delay``
(:data:`FIELDS`), then the static band's excesses over the kinetic band ``e_plus, e_minus``
(both >= 0: ``fs_delta + fs_mean = fk_delta + fk_mean + e_plus`` and
``fs_delta - fs_mean = fk_delta - fk_mean - e_minus``, so static >= kinetic in each direction
by construction, thesis 2.137, 2.155a), then one release position per run.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from scipy.signal import lfilter

from driveid.errors import DriveIdError, IdentificationError, RecordError
from driveid.identify.core._noise import NoiseModel
from driveid.identify.free_decay._quantised import replicate_covariance
from driveid.identify.pho.peaks import _gains
from driveid.io.record import Record

__all__: list[str] = []

#: Parameters of the fit, in the order of the internal vector.
FIELDS = ("J", "c_mean", "c_delta", "K", "fk_mean", "fk_delta", "delay")
#: Entries of ``theta`` before the per-run releases: FIELDS, then e_plus, e_minus.
N_PHYS = 9
#: Indices of the static band's excesses in ``theta``.
BAND = (7, 8)
#: Relative forward-difference step of the Jacobian (model smooth to ~1e-13 between events).
_FD_STEP = 1e-6
#: Most Levenberg–Marquardt iterations of a fit.
MAX_ITER = 40


def band_from_excess(theta: np.ndarray) -> tuple[float, float]:
    """Return ``(fs_mean, fs_delta)`` of ``theta`` [N·m or N]."""
    fkm, fkd, ep, em = (float(v) for v in (theta[4], theta[5], theta[7], theta[8]))
    return fkm + 0.5 * (ep + em), fkd + 0.5 * (ep - em)


def band_jacobian() -> np.ndarray:
    """d(fs_mean, fs_delta)/d(fk_mean, fk_delta, e_plus, e_minus), shape (2, 4)."""
    return np.array([[1.0, 0.0, 0.5, 0.5], [0.0, 1.0, 0.5, -0.5]])


class Campaign:
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
        self.segments = [v.size for v in self.y]
        self.edges = np.cumsum([0] + self.segments)
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
        fs_mean, fs_delta = band_from_excess(theta)
        r = self.runs[k]
        x0 = float(theta[N_PHYS + k])
        body = BodyParams(J=J, K=K, c_mean=c, c_delta=cd, fk_mean=fkm, fk_delta=fkd,
                          fs_mean=fs_mean, fs_delta=fs_delta)
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

        A release ``theta[N_PHYS + k]`` moves run ``k`` only, so only that run is simulated.
        """
        jac = np.zeros((self.n, len(free)))
        for j, i in enumerate(free):
            h = _FD_STEP * max(abs(theta[i]), scale[i])
            up = theta.copy()
            up[i] += h
            if i < N_PHYS:
                jac[:, j] = (self.model(up) - f0) / h
            else:
                part = slice(self.edges[i - N_PHYS], self.edges[i - N_PHYS + 1])
                try:
                    jac[part, j] = (self.run(up, i - N_PHYS) - f0[part]) / h
                except DriveIdError:
                    jac[part, j] = np.nan
        return jac

    def end_forces(self, theta: np.ndarray, quantum: float | None,
                   noise_std: float = 0.0) -> np.ndarray:
        """Return the applied force ``-(P + K) x_end`` of each run that ends at rest [N·m or N].

        A run ends at rest when its last tenth (at least 20 samples) spans no more than ten
        sample-to-sample noise deviations, eight ``noise_std`` (coloured noise wanders
        further than its differences say) or 2.5 encoder steps; the delayed command then
        reads ``x_end`` and the D term is 0.
        """
        out = []
        q = 0.0 if quantum is None else float(quantum)
        for r, y in zip(self.runs, self.y, strict=True):
            tail = y[-max(20, y.size // 10):]
            tol = max(2.5 * q, 8.0 * noise_std,
                      10.0 * float(np.std(np.diff(tail))) / math.sqrt(2.0))
            if np.ptp(tail) <= tol:
                force = -(r["P"] + float(theta[3])) * float(np.mean(tail))
                out.append(float(np.clip(force, -r["saturation"], r["saturation"])))
        return np.array(out)


def project(theta: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
    """Clip to the box and to ``c_mean ± c_delta >= 0``, ``fk_mean ± fk_delta >= 0``."""
    theta = np.clip(theta, lower, upper)
    for mean, delta in ((1, 2), (4, 5)):
        plus = max(theta[mean] + theta[delta], 0.0)
        minus = max(theta[mean] - theta[delta], 0.0)
        theta[mean], theta[delta] = 0.5 * (plus + minus), 0.5 * (plus - minus)
    return theta


def at_bounds(theta: np.ndarray, free: Sequence[int], lower: np.ndarray,
              tol: float = 1e-9) -> list[str]:
    """Name the constraints active at ``theta`` (``"c_mean - c_delta = 0"``, ``"K = 0"``)."""
    names = []
    scale = {1: abs(theta[1]) + abs(theta[2]), 4: abs(theta[4]) + abs(theta[5])}
    for mean, delta, label in ((1, 2, "c"), (4, 5, "fk")):
        if mean in free and delta in free:
            s = max(scale[mean], 1e-300)
            if theta[mean] + theta[delta] <= tol * s:
                names.append(f"{label}_mean + {label}_delta = 0")
            if theta[mean] - theta[delta] <= tol * s:
                names.append(f"{label}_mean - {label}_delta = 0")
    if 0 in free and theta[0] <= lower[0] * (1 + 1e-9):
        names.append("J at its lower bound")
    if 3 in free and theta[3] <= 0.0:
        names.append("K = 0")
    return names


def fit(problem, theta0, free, lower, upper, scale, target=None,
        noise: NoiseModel | None = None):
    """Bounded Levenberg–Marquardt over the ``free`` entries of ``theta``.

    With a noise model the residuals and the Jacobian are prewhitened (prediction error).
    Returns ``(theta, f, jac, cost, iterations)``, ``jac`` not whitened, ``cost`` the
    (prewhitened) residual sum of squares; stops when an iteration lowers it by less than
    1e-4 of the current s², or the step is below 1e-9 of the scale.
    """
    y = problem.target if target is None else target
    seg = problem.segments

    def whiten(a):
        return a if noise is None else noise.whiten(a, seg)

    theta = project(theta0.copy(), lower, upper)
    f = problem.model(theta)
    if not np.all(np.isfinite(f)):
        raise IdentificationError(
            "the start values cannot be simulated; the peak analysis gave an unphysical "
            "start (check the gains and the units of the records)")
    r = whiten(y - f)
    rss = float(r @ r)
    dof = max(r.size - len(free), 1)
    jac = problem.jacobian(theta, free, f, scale)
    lam = 1e-3
    it = 0
    while it < MAX_ITER:
        it += 1
        jw = whiten(jac)
        A = jw.T @ jw
        g = jw.T @ r
        d = np.diag(A).copy()
        d[d <= 0] = 1.0
        accepted = False
        for _ in range(12):
            try:
                step = _bounded_step(A + lam * np.diag(d), g, theta[free], lower[free],
                                     upper[free])
            except np.linalg.LinAlgError:
                lam *= 10.0
                continue
            trial = theta.copy()
            trial[free] = theta[free] + step
            trial = project(trial, lower, upper)
            f_t = problem.model(trial)
            r_t = whiten(y - f_t) if np.all(np.isfinite(f_t)) else None
            rss_t = float(r_t @ r_t) if r_t is not None else math.inf
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


def _bounded_step(M: np.ndarray, g: np.ndarray, x: np.ndarray, lo: np.ndarray,
                  hi: np.ndarray) -> np.ndarray:
    """Solve ``M step = g`` with the entries held that sit on a bound and would leave it.

    Projecting the free step instead (K pushed below 0 and clipped back) leaves the other
    parameters the step they took for K's move, and the fit crept: 40 iterations each
    lowering the cost by 0.1-0.2 s² on a quantised test-bed campaign (2026-11-28).
    """
    step = np.linalg.solve(M, g)
    held = ((x <= lo) & (step < 0)) | ((x >= hi) & (step > 0))
    if held.any() and not held.all():
        keep = ~held
        step = np.zeros_like(step)
        step[keep] = np.linalg.solve(M[np.ix_(keep, keep)], g[keep])
    return step


def scan_band(problem, theta, s2, quantum):
    """Profile the static band edge by edge with the other parameters held.

    Returns ``(theta, brackets)``: ``theta`` with ``e_plus, e_minus`` at the middle of the
    range whose residual sum of squares is within ``3.84 s²`` of the scan's least (the edge
    is bracketed, not measured, where a run ends stuck inside the band: the model does not
    change across that range), or 10 % of fk above its low end when the largest excess
    tried still fits;
    ``brackets`` the ``(lo, hi)`` of each excess [N·m or N] (``hi`` = inf when open), and
    the least residual sum of squares of the last edge's scan.
    """
    fkm = max(float(theta[4]), 1e-12)
    forces = problem.end_forces(theta, quantum, math.sqrt(max(s2, 0.0)))
    plus_edge = theta[5] + theta[4]
    minus_edge = theta[5] - theta[4]
    need_plus = max([0.0] + [F - plus_edge for F in forces])
    need_minus = max([0.0] + [minus_edge - F for F in forces])
    theta = theta.copy()
    # while one edge is scanned the other sits 10 % of fk inside what the rest positions
    # demand, not on the boundary where a run flips between stopping and reversing
    theta[7], theta[8] = need_plus + 0.1 * fkm, need_minus + 0.1 * fkm
    brackets = []
    for i, need in ((7, need_plus), (8, need_minus)):
        # relative grid: the rest positions say at least `need`; 45 % of fk above the
        # kinetic band is beyond the lubricated contacts of thesis §2.1.1.2
        grid = np.unique(np.concatenate([need + fkm * np.arange(0.0, 0.46, 0.03),
                                         [need * 0.5, need * 0.8]]))
        grid = grid[grid >= 0.0]
        costs = []
        for e in grid:
            trial = theta.copy()
            trial[i] = e
            f = problem.model(trial)
            r = problem.target - f
            costs.append(float(r @ r) if np.all(np.isfinite(f)) else math.inf)
        costs = np.array(costs)
        best = int(np.argmin(costs))
        ok = costs <= costs[best] + 3.84 * s2
        lo_i = hi_i = best
        while lo_i > 0 and ok[lo_i - 1]:
            lo_i -= 1
        while hi_i < grid.size - 1 and ok[hi_i + 1]:
            hi_i += 1
        lo, hi = float(grid[lo_i]), float(grid[hi_i])
        open_top = hi_i == grid.size - 1
        # an edge the runs bound from one side only is put 10 % of fk beyond the least the
        # data demand (the least itself is where some run flips: a fragile start)
        theta[i] = min(lo + 0.1 * fkm, hi) if open_top else 0.5 * (lo + hi)
        brackets.append((lo, math.inf if open_top else hi))
    return theta, brackets, float(costs[best])


def bootstrap_covariance(problem, theta, f, jac, free, s2, quantum, replicates, rng, refit,
                         lower, upper, scale, progress, noise: NoiseModel | None):
    """Covariance of the estimates from the fitted response re-quantised on random grids.

    Noise beyond the rounding (variance ``s² - q²/12``) is added to each replicate, coloured
    by ``noise`` where that is an AR model.
    """
    gen = np.random.default_rng(rng)
    extra = max(s2 - quantum**2 / 12.0, 0.0)
    bounds = problem.edges
    solve = np.linalg.pinv(jac)
    coloured = noise is not None and not noise.is_white and noise.innovation_variance > 0
    a = np.concatenate([[1.0], -np.asarray(noise.ar, float)]) if coloured else None
    shape = math.sqrt(noise.innovation_variance / noise.variance) if coloured else 1.0
    out = []
    for b in range(replicates):
        y_b = np.empty_like(f)
        for k in range(len(problem.y)):  # each run its own grid phase
            part = f[bounds[k]:bounds[k + 1]]
            if extra > 0:
                if coloured:
                    burn = 10 * noise.order + 200
                    w = gen.normal(0.0, math.sqrt(extra) * shape, part.size + burn)
                    part = part + lfilter([1.0], a, w)[burn:]
                else:
                    part = part + gen.normal(0.0, math.sqrt(extra), part.size)
            phase = gen.uniform(0.0, quantum)
            y_b[bounds[k]:bounds[k + 1]] = quantum * np.round((part - phase) / quantum) + phase
        if refit:
            try:
                est = fit(problem, theta, free, lower, upper, scale, target=y_b)[0][free]
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
