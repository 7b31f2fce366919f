"""One least-squares stage of the drive fit: the stacked residual, its solver, the starts.

Split from :mod:`driveid.identify.drive.drive_fit`, which drives the stages (growing horizon,
whole record, pieces) and builds the result; the objective, its smoothness and the weights
are described there. Here: :class:`_Fit` (the weighted, prewhitened residual of all records
and channels and its Jacobian), :func:`_stage` (one fit of shared parameters and per-record
initial states, weighted twice and then with the noise model) and :func:`_solve` (scipy's
trust-region reflective solver with fresh-trust-region restarts and the stopping rule of
:data:`COST_TOL`).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.optimize import OptimizeResult, least_squares
from threadpoolctl import threadpool_limits

from driveid.errors import IdentificationError, ParameterError
from driveid.identify.drive._drive_covariance import _channel_noise
from driveid.identify.drive._drive_encoder import _quanta
from driveid.identify.drive._drive_model import (
    DriveProblem,
    DriveRecord,
    channel_index,
    get_value,
    lower_bound,
)
from driveid.sim.drive_types import DriveParams

__all__: list[str] = []


#: An accepted step that lowers the cost (half the sum of squared weighted residuals, in
#: units of the noise variance) by less than this ends a solve. Near a kinked minimum the
#: trust region shrinks fourfold a step and each step gains about a quarter of the last, so
#: what is left is about a third of it: the parameters are within ~0.03 standard errors of
#: where the solver would stop. scipy's own ftol needs a step the linear model predicted
#: well, which a kink denies; its xtol went on 5-8 Jacobians longer for a Δχ² of 1e-6
#: (docs/drive-fit.md, "time per fit").
COST_TOL = 1e-3


#: A fresh trust region (restart) that lowers the cost by less than this ends the fit
#: (Δχ² 0.02: within ~0.14 standard errors along the weakest direction).
RESTART_GAIN = 1e-2
#: Least inertia a fit may reach, as a fraction of its start value [-]. A body's inertia
#: sets its damping and contact rates, and with them the RK4 step, without bound: in the
#: three-body open-loop benchmark (seed 6) the unmeasured middle body's J fell from its
#: start 2.3e-3 to 1e-9 kg·m² in a 0.1 s head (8e5 times the start's steps; 2-6 s a 0.1 s
#: trial run). At 1e-4 a trial costs at most ~700 times the start's steps; a floor of 1e-2
#: made that fit fast but sent seed 3, whose path passes below 1e-2, 19.7 times the noise
#: off (docs/drive-fit.md).
INERTIA_FLOOR = 1e-4
#: Most RK4 steps a trial drive may take, as a multiple of the user's start drive's on the
#: same record [-]. A costlier trial is answered with a non-finite residual, which scipy's
#: trust region rejects (it shrinks the region and tries again): the slow path of the
#: three-body benchmark's seed 6 spent 2-6 s on each such 0.1 s trial (docs/drive-fit.md).
TRIAL_STEP_RATIO = 50.0


class _Converged(Exception):
    """Raised by :meth:`_Fit.jacobian` when the last accepted step gained under COST_TOL."""

    def __init__(self, z: np.ndarray, cost: float) -> None:
        super().__init__()
        self.z, self.cost = z, cost


def _noise_fitter():
    """Return ``fit_noise_model`` of the shared noise module, or None (white noise)."""
    try:
        from driveid.identify.core._noise import fit_noise_model
    except ImportError:  # until the shared noise module is there: white noise
        return None
    return fit_noise_model


def _initial_state(record: DriveRecord, params: DriveParams) -> tuple[np.ndarray, np.ndarray]:
    """Start values of the initial state from the first samples of the record."""
    nb = params.n_bodies
    x0, v0 = np.full(nb, np.nan), np.full(nb, np.nan)
    head = max(2, min(20, record.t.size // 50))
    dt = 1.0 / record.fs
    for name, y in record.channels.items():
        kind, body = channel_index(name)
        if body >= nb:
            continue
        if kind == "x":
            x0[body] = float(np.mean(y[:3]))
            if np.isnan(v0[body]):
                tt = np.arange(head) * dt
                coef, res, *_ = np.polyfit(tt, y[:head], 1, full=True)
                se = math.sqrt(float(res[0]) / (head - 2) / np.sum((tt - tt.mean()) ** 2)) \
                    if res.size else 0.0
                # a slope within noise is a start at rest (the common case): a noisy
                # nonzero start velocity lets a stuck body slide, a poor local minimum
                v0[body] = float(coef[0]) if abs(coef[0]) > 3.0 * se else 0.0
        else:
            v0[body] = float(y[0])
    known = np.flatnonzero(np.isfinite(x0))
    for i in range(nb):  # an unmeasured body starts where its nearest measured one does
        if np.isnan(x0[i]):
            x0[i] = x0[known[np.argmin(np.abs(known - i))]] if known.size else 0.0
        if np.isnan(v0[i]):
            v0[i] = 0.0
    locked = np.array([b.locked for b in params.bodies])
    v0[locked] = 0.0
    return x0, v0


def _scale(name: str, value: float, base: DriveParams) -> float:
    """Typical size of a parameter for scaling (its start, or a related one where 0)."""
    if value != 0.0:
        return abs(value)
    owner, field_name = name.rsplit(".", 1)
    partner = {"c_delta": "c_mean", "fk_delta": "fk_mean", "fs_delta": "fs_mean",
               "v_s_delta": "v_s",
               "gap_minus": "gap_plus", "gap_plus": "gap_minus"}.get(field_name)
    if partner is not None:
        try:
            other = abs(get_value(base, np.zeros(base.n_bodies), np.zeros(base.n_bodies),
                                  f"{owner}.{partner}"))
        except ParameterError:
            other = 0.0
        if other > 0:
            return 0.1 * other if field_name.endswith("delta") else other
    # lengths and times that are often 0 at the start: a millimetre (milliradian), a
    # millisecond (a loop's delay, a friction memory)
    return 1e-3 if field_name in ("gap_plus", "gap_minus", "delay", "memory") else 1.0


class _Fit:
    """The stacked, weighted (and prewhitened) residual of all records and channels."""

    def __init__(self, problems, index, records, sigma):
        self.problems, self.index, self.records = problems, index, records
        self.sigma = sigma  # per record: array (n_channels,)
        self.filters: list | None = None  # per record: list of noise models per channel
        self.prior: np.ndarray | None = None  # shared z held loosely (growing horizon)
        self.quanta: list | None = None  # per record: (step, noise sd) or None per channel
        self._local: dict[bytes, list] = {}  # the last local Jacobian, by z
        self.stop_gain: float | None = None  # see COST_TOL
        self._cost_at: tuple[bytes, float] | None = None  # the last residual's z and cost
        self._jac_cost: float | None = None  # the cost where the last Jacobian was taken
        self.n_residuals = 0
        self.step_caps: list[float] | None = None  # per record: most RK4 steps of a trial
        self._size: int | None = None  # the residual's length

    def _too_costly(self, z: np.ndarray) -> bool:
        """Whether a trial drive at ``z`` takes more RK4 steps than ``step_caps`` allow."""
        if self.step_caps is None or self._size is None:
            return False
        from driveid.sim.drive_cost import estimate_drive_cost

        for prob, idx, cap in zip(self.problems, self.index, self.step_caps, strict=True):
            try:
                params = prob.build(z[idx])[0]
            except ParameterError:
                return False  # outputs() says what is wrong with it
            if estimate_drive_cost(params, duration=prob.duration, fs=prob.fs).n_steps > cap:
                prob.n_refused += 1
                return True
        return False

    def _whiten(self, r: int, c: int, values: np.ndarray) -> np.ndarray:
        if self.filters is None:
            return values
        return self.filters[r][c].whiten(values)

    def _measured(self, r: int, c: int, y: np.ndarray, jac: np.ndarray | None = None):
        """Return the expected encoder reading of a simulated channel (and its Jacobian)."""
        if self.quanta is None or self.quanta[r][c] is None:
            return y, jac
        q, sd = self.quanta[r][c]
        k = np.arange(1, 6)[:, None]
        damp = (-1.0) ** k * np.exp(-2.0 * (np.pi * k * sd / q) ** 2)
        phase = 2.0 * np.pi * k * y[None, :] / q
        mean = y + np.sum(q / (np.pi * k) * damp * np.sin(phase), axis=0)
        if jac is None:
            return mean, None
        slope = 1.0 + np.sum(2.0 * damp * np.cos(phase), axis=0)
        return mean, jac * slope[:, None]

    def raw_residuals(self, z: np.ndarray) -> list[np.ndarray]:
        """Model minus data per record, shape (n_channels, n), unweighted."""
        out = []
        for r, (prob, idx, rec) in enumerate(zip(self.problems, self.index, self.records,
                                                 strict=True)):
            y = prob.outputs([z[idx]])[0]
            model = np.array([self._measured(r, c, y[c])[0] for c in range(y.shape[0])])
            out.append(model - np.array([rec.channels[c] for c in prob.channels]))
        return out

    def residual(self, z: np.ndarray) -> np.ndarray:
        if self._too_costly(z):
            return np.full(self._size, np.nan)  # the trust region shrinks, no simulation
        parts = []
        for r, res in enumerate(self.raw_residuals(z)):
            for c in range(res.shape[0]):
                parts.append(self._whiten(r, c, res[c] / self.sigma[r][c]))
        if self.prior is not None:
            parts.append(z[:self.prior.size] - self.prior)
        out = np.concatenate(parts)
        self._size = out.size
        self._cost_at = (z.tobytes(), 0.5 * float(out @ out))
        self.n_residuals += 1
        return out

    def jacobian(self, z: np.ndarray, local: bool = False) -> np.ndarray:
        """Weighted (and prewhitened) Jacobian; ``local``: the covariance's small-step one."""
        blocks = []
        key = z.tobytes()
        if not local and self.stop_gain is not None and self._cost_at is not None \
                and self._cost_at[0] == key:
            # the solver asks for a Jacobian after each accepted step, at the point whose
            # residual it has just taken: stop here when that step gained too little
            cost = self._cost_at[1]
            if self._jac_cost is not None and self._jac_cost - cost < self.stop_gain:
                raise _Converged(z.copy(), cost)
            self._jac_cost = cost
        if local and key not in self._local:
            self._local = {key: [prob.local_jacobian(z[idx]) for prob, idx
                                 in zip(self.problems, self.index, strict=True)]}
        for r, (prob, idx) in enumerate(zip(self.problems, self.index, strict=True)):
            y, jac = self._local[key][r] if local else prob.value_and_jacobian(z[idx])
            for c in range(jac.shape[0]):
                full = np.zeros((jac.shape[1], z.size))
                full[:, idx] = self._measured(r, c, y[c], jac[c])[1] / self.sigma[r][c]
                blocks.append(self._whiten(r, c, full))
        if self.prior is not None:
            blocks.append(np.eye(self.prior.size, z.size))
        return np.vstack(blocks)


def _horizons(recs, first: float | None) -> list[float]:
    """Fractions of the records fitted before the whole: first, 2·first, 4·first ... [-]."""
    if not first:
        return []
    total = min(float(r.t[-1] - r.t[0]) for r in recs)
    # a head is never shorter than 20 samples (_head): shorter horizons would fit the same
    # head again, about 50 times over for a segment of 1e-15 s
    out, h = [], max(float(first), total * 20.0 / min(r.t.size for r in recs))
    while h < 0.7 * total:
        out.append(h / total)
        h *= 2.0
    return out


def _head(rec: DriveRecord, fraction: float) -> DriveRecord:
    n = max(int(round(fraction * rec.t.size)), 20)
    return DriveRecord(t=rec.t[:n], u=None if rec.u is None else rec.u[:n],
                       channels={c: y[:n] for c, y in rec.channels.items()}, meta=rec.meta)


def _states_of(st: dict, theta: np.ndarray, n_shared: int) -> list:
    """Return the fitted initial states of a stage, per record (the next stage's start)."""
    out = []
    for prob, idx, (sx, sv) in zip(st["problems"], st["index"], st["states0"], strict=True):
        sx, sv = sx.copy(), sv.copy()
        for name, j in zip(prob.names[n_shared:], idx[n_shared:], strict=True):
            body = int(name[4:name.index(".")]) - 1
            (sx if name.endswith(".x0") else sv)[body] = theta[j]
        out.append((sx, sv))
    return out


def _stage(recs, base, start, names, free_states, x0, v0, input_body, use_u, torque,
           parallel, max_nfev, noise_model, starts=None, hold=False, progress=None) -> dict:
    """One least-squares fit of shared parameters and per-record states (weighted twice)."""
    nb = start.n_bodies
    zero = np.zeros(nb)
    shared_values = np.array([get_value(base, zero, zero, n) for n in names])
    scale_shared = np.array([_scale(n, v, base) for n, v in zip(names, shared_values,
                                                                 strict=True)])
    # global vector: shared parameters, then each record's free states
    z0 = list(shared_values / scale_shared)
    all_names = list(names)
    problems, index, states0 = [], [], []
    built: dict = {}  # trial drives, shared by the records' problems (see DriveProblem)
    for r, rec in enumerate(recs):
        sx, sv = _initial_state(rec, base) if starts is None else starts[r]
        if x0 is not None:
            sx = np.broadcast_to(np.asarray(x0, float), (nb,)).copy()
        if v0 is not None:
            sv = np.broadcast_to(np.asarray(v0, float), (nb,)).copy()
        states0.append((sx, sv))
        idx = list(range(len(names)))
        local = list(names)
        scale = list(scale_shared)
        for n in free_states:
            value = get_value(base, sx, sv, n)
            s = _state_scale(n, rec)
            idx.append(len(all_names))
            all_names.append(n if len(recs) == 1 else f"{n}@{r + 1}")
            local.append(n)
            scale.append(s)
            z0.append(value / s)
        problems.append(DriveProblem(base, sx, sv, local, np.array(scale), rec,
                                     input_body if use_u else None, torque=torque,
                                     parallel=parallel, progress=progress, built=built))
        index.append(np.array(idx))
    z0 = np.array(z0)
    scale_all = np.concatenate([scale_shared] + [p.scale[len(names):] for p in problems])
    lower = np.array([lower_bound(n.split("@")[0]) for n in all_names]) / scale_all
    upper = np.full(z0.size, np.inf)
    # a fixed static band must hold the kinetic one: bound fk_mean by it
    for j, n in enumerate(names):
        if n.endswith(".fk_mean"):
            b = start.bodies[int(n[4:n.index(".")]) - 1]
            if f"{n[:-8]}.fs_mean" not in names and not _follows(b):
                upper[j] = b.fs_mean / scale_all[j]
    # a Stribeck velocity far below its start is below what the record resolves, and the
    # slope of its map would shrink the RK4 step without bound: keep it above 1 % of it
    # (and above a fixed |v_s_delta|, so both branches keep a positive one); an inertia
    # likewise, above INERTIA_FLOOR of the user's start (not this stage's)
    for j, n in enumerate(names):
        if n.endswith(".v_s"):
            b = start.bodies[int(n[4:n.index(".")]) - 1]
            held = 0.0 if f"{n}_delta" in names else 1.01 * abs(b.v_s_delta) / scale_all[j]
            lower[j] = max(lower[j], 0.01 * z0[j], held)
        elif n.endswith(".J"):
            lower[j] = max(lower[j], INERTIA_FLOOR * get_value(start, zero, zero, n)
                           / scale_all[j])
    z0 = np.clip(z0, lower + 1e-9 * np.abs(z0 + 1e-3), upper)

    sigma = [np.array([_channel_noise(rec.channels[c]) for c in p.channels])
             for p, rec in zip(problems, recs, strict=True)]
    fit = _Fit(problems, index, recs, sigma)
    fit.step_caps = [TRIAL_STEP_RATIO * _steps(start, p) for p in problems]
    if hold:
        # a prior of one start value's size on each shared parameter: a parameter the
        # short horizon does not excite (a gap never closed yet) stays at its start
        # instead of wandering off; an excited one is set by the data (weights 1/σ
        # over hundreds of samples)
        fit.prior = z0[:len(names)].copy()
    with threadpool_limits(limits=1):
        sol = _solve(fit, z0, lower, upper, max_nfev)
        # weights from the first fit's residuals: each channel by its own noise level
        raw = fit.raw_residuals(sol.x)
        fit.sigma = _pooled_sigma(problems, raw)
        fit.quanta = _quanta(recs, fit, sol.x)
        sol = _solve(fit, sol.x, lower, upper, max_nfev)
        if fit.quanta is not None:  # the encoder noise again, from the nearer positions
            fit.quanta = _quanta(recs, fit, sol.x)
        noise_info = None
        fitter = _noise_fitter() if noise_model else None
        if fitter is not None:
            raw = fit.raw_residuals(sol.x)
            fit.sigma = _pooled_sigma(problems, raw)
            fit.filters = [[fitter(res[c] / fit.sigma[r][c]) for c in range(res.shape[0])]
                           for r, res in enumerate(raw)]
            noise_info = {f"{p.channels[c]}" + ("" if len(recs) == 1 else f"@{r + 1}"):
                          fit.filters[r][c].to_dict()
                          for r, p in enumerate(problems) for c in range(len(p.channels))}
            sol = _solve(fit, sol.x, lower, upper, max_nfev)
    return {"sol": sol, "fit": fit, "problems": problems, "index": index,
            "all_names": all_names, "scale_all": scale_all, "states0": states0,
            "lower": lower, "upper": upper, "noise_info": noise_info}


def _steps(params: DriveParams, prob: DriveProblem) -> float:
    """RK4 steps of one simulation of ``params`` over ``prob``'s record [-].

    At least one a sample: a start the closed form runs takes none.
    """
    from driveid.sim.drive import estimate_drive_cost

    cost = estimate_drive_cost(params, duration=prob.duration, fs=prob.fs)
    return float(max(cost.n_steps, cost.n_samples - 1))


def _pooled_sigma(problems, raw) -> list[np.ndarray]:
    """Return the residual rms of each channel name over all records.

    Pooled: a short stuck piece alone would fit its quantised samples exactly and get an
    infinite weight.
    """
    sums: dict[str, list[float]] = {}
    for prob, res in zip(problems, raw, strict=True):
        for c, ch in enumerate(prob.channels):
            acc = sums.setdefault(ch, [0.0, 0.0])
            acc[0] += float(res[c] @ res[c])
            acc[1] += res.shape[1]
    rms = {ch: math.sqrt(a / n) if a > 0 else 1e-12 for ch, (a, n) in sums.items()}
    return [np.array([rms[ch] for ch in prob.channels]) for prob in problems]


def _follows(b) -> bool:
    return abs(b.fs_mean - b.fk_mean - b.ripple_amplitude) <= 1e-12 * max(1.0, b.fk_mean)


def _state_scale(name: str, rec: DriveRecord) -> float:
    spans = [float(np.ptp(y)) for c, y in rec.channels.items() if c[0] == name[-2]]
    if name.endswith(".x0"):
        return max(spans + [1e-3]) or 1.0
    if not spans:  # velocity scale from the positions' rate
        spans = [float(np.ptp(np.diff(y))) * rec.fs for c, y in rec.channels.items()
                 if c[0] == "x"]
    return max(spans + [1e-3]) or 1.0


def _solve(fit: _Fit, z0, lower, upper, max_nfev, restarts: int = 4):
    lo = np.where(np.isfinite(lower), lower, -np.inf)
    fit.stop_gain = COST_TOL
    try:
        sol = None
        for _ in range(restarts):
            # a fresh trust region: where the event pattern changes near the optimum the
            # linear model fails for a step, the region collapses and the solver stops
            # short of the minimum; a restart from there goes on
            fit._jac_cost = None
            before = fit.n_residuals
            try:
                new = least_squares(fit.residual, z0 if sol is None else sol.x,
                                    jac=fit.jacobian, bounds=(lo, upper), method="trf",
                                    x_scale="jac", max_nfev=max_nfev, xtol=1e-10,
                                    ftol=1e-10, gtol=1e-10)
            except _Converged as stop:
                new = OptimizeResult(x=stop.z, cost=stop.cost, nfev=fit.n_residuals - before,
                                     status=3, success=True,
                                     message=f"a step lowered the cost by under {COST_TOL:g}")
            done = sol is not None and new.cost > sol.cost - RESTART_GAIN
            if sol is not None:
                new.nfev += sol.nfev
                if new.cost > sol.cost:
                    new = sol
            sol = new
            if done or sol.status in (1, 2):  # gtol or ftol: converged
                break
        return sol
    except ValueError as exc:  # non-finite residual or Jacobian
        raise IdentificationError(f"the drive fit failed ({exc}); start nearer the truth "
                                  "or estimate fewer parameters") from None
    finally:
        fit.stop_gain = None
