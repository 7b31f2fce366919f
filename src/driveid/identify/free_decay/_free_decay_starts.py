r"""Start values of the free-decay output-error fit that do not hinge on the peak estimator.

The whole-record fit (:mod:`driveid.identify.free_decay.output_error`) is a local search; its start
used to come only from the least-squares log decrement of the record's peaks, which fails
on coarse records (5-20 samples per period, 0.01 rad encoder steps, a start mid-swing,
long Coulomb tails). Two more strategies work on the samples themselves:

* ``"exponential"``: the spectral peak ``ω_d`` (:func:`driveid.signal.envelope.dominant_frequency`)
  and a damped sinusoid ``e + e^{-σ τ}(a cos ω τ + b sin ω τ)`` fitted by variable projection
  over the first periods: viscous damping ``ζ = σ/√(σ² + ω²)``, no Coulomb friction;
* ``"linear envelope"``: ``e + (a + a'τ) cos ω τ + (b + b'τ) sin ω τ``: an envelope that
  falls linearly, which is Coulomb friction (thesis 2.139-2.143 with ζ = 0: each half
  cycle loses ``2 θk``, so ``dA/dt = -2 θk ω/π``).

Each gives ``(ω0, ζ⁺ = ζ⁻, θk_mean, θk_delta = -e)`` and the release: the last velocity zero
of the fitted curve at or before the first moving sample (the same mid-swing model as
``_free_response``). The caller fits from every start and keeps the lowest residual.
Not in the thesis (which reads peaks by hand, §2.2.5).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.optimize import least_squares, minimize_scalar

from driveid.errors import IdentificationError
from driveid.identify.free_decay._free_response import GLOBAL_NAMES
from driveid.identify.free_decay.logdec import estimate_log_decrement
from driveid.io.record import Record
from driveid.signal.envelope import dominant_frequency, noise_std

__all__ = ["peak_start", "sample_starts"]

#: Periods of the record the start curves are fitted to [-].
_PERIODS = 20


def _linear_fit(basis: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    coef, *_ = np.linalg.lstsq(basis, y, rcond=None)
    return coef, y - basis @ coef


def _exp_basis(tau, sigma, omega):
    env = np.exp(-sigma * tau)
    return np.column_stack([np.ones_like(tau), env * np.cos(omega * tau),
                            env * np.sin(omega * tau)])


def _lin_basis(tau, omega):
    c, s = np.cos(omega * tau), np.sin(omega * tau)
    return np.column_stack([np.ones_like(tau), c, s, tau * c, tau * s])


def _motion_start(t: np.ndarray, x: np.ndarray) -> int:
    """Index of the first sample that moves away from a held start (0: moving at once)."""
    head = x[: max(5, min(50, x.size // 20))]
    level = float(np.median(head))
    steps = np.abs(np.diff(x))
    quantum = float(np.min(steps[steps > 0])) if np.any(steps > 0) else 0.0
    tol = max(5.0 * noise_std(x), 2.0 * quantum, 1e-12 * float(np.ptp(x)))
    moved = np.nonzero(np.abs(x - level) > tol)[0]
    return int(moved[0]) if moved.size else 0


def _release(curve, t0: float, omega: float) -> float:
    """Time of the last velocity zero of ``curve`` in ``(t0 - 0.95π/ω, t0 + 0.05π/ω)``.

    The window stops short of the zero half a period before a release at ``t0`` (the same
    data, one invisible half cycle earlier).
    """
    grid = t0 + np.linspace(-0.95, 0.05, 2001) * math.pi / omega
    v = np.gradient(curve(grid), grid)
    change = np.nonzero(np.sign(v[1:]) != np.sign(v[:-1]))[0]
    if not change.size:
        return t0
    i = int(change[-1])
    if grid[i] > t0:  # the zero at the first sample itself (released there)
        return t0
    frac = v[i] / (v[i] - v[i + 1]) if v[i] != v[i + 1] else 0.0
    return float(grid[i] + frac * (grid[i + 1] - grid[i]))


def _one_record(t: np.ndarray, x: np.ndarray) -> dict[str, dict]:
    """Fit the two start curves to one record; return ``{strategy: start}``."""
    i0 = _motion_start(t, x)
    held = i0 > 3
    tt, xx = t[i0:], x[i0:]
    if tt.size < 16:
        return {}
    dt = float(np.median(np.diff(tt)))
    grid = np.arange(tt[0], tt[-1], dt)
    uniform = np.interp(grid, tt, xx)
    omega = dominant_frequency(uniform, 1.0 / dt)
    if not omega > 0:
        return {}
    keep = tt - tt[0] <= _PERIODS * 2 * math.pi / omega
    if np.sum(keep) < 16:
        keep[:16] = True
    tau, y = tt[keep] - tt[0], xx[keep]
    out: dict[str, dict] = {}

    def exp_resid(q):
        return _linear_fit(_exp_basis(tau, q[0], q[1]), y)[1]

    try:
        sol = least_squares(exp_resid, [0.01 * omega, omega],
                            bounds=([-0.2 * omega, 0.5 * omega], [2.0 * omega, 2.0 * omega]),
                            x_scale=[0.01 * omega, 0.01 * omega], max_nfev=200)
        sigma, om = (float(v) for v in sol.x)
        coef, _ = _linear_fit(_exp_basis(tau, sigma, om), y)
        zeta = float(np.clip(sigma / math.hypot(sigma, om), 1e-4, 0.9))

        def exp_curve(tq, coef=coef, sigma=sigma, om=om):
            return _exp_basis(tq - tt[0], sigma, om) @ coef

        out["exponential"] = {"omega_d": om, "zeta": zeta, "theta_k": 0.0,
                              "center": float(coef[0]), "curve": exp_curve}
    except (ValueError, np.linalg.LinAlgError):
        pass

    def lin_cost(om):
        return float(np.sum(_linear_fit(_lin_basis(tau, om), y)[1] ** 2))

    res = minimize_scalar(lin_cost, bounds=(0.9 * omega, 1.1 * omega), method="bounded",
                          options={"xatol": 1e-6 * omega})
    om = float(res.x)
    coef, _ = _linear_fit(_lin_basis(tau, om), y)
    amp0 = math.hypot(coef[1], coef[2])
    if amp0 > 0:
        # slope of the amplitude along the phasor's own direction
        slope = (coef[1] * coef[3] + coef[2] * coef[4]) / amp0
        theta_k = max(-slope * math.pi / (2.0 * om), 0.0)

        def lin_curve(tq, coef=coef, om=om):
            return _lin_basis(tq - tt[0], om) @ coef

        out["linear envelope"] = {"omega_d": om, "zeta": 1e-4, "theta_k": theta_k,
                                  "center": float(coef[0]), "curve": lin_curve}
    for start in out.values():
        if held:  # released from rest at the last held sample
            start["release"] = (float(np.median(x[:i0])), float(t[i0 - 1]))
            start["mid_swing"] = False
        else:
            t_r = _release(start["curve"], float(tt[0]), start["omega_d"])
            start["release"] = (float(start["curve"](np.array([t_r]))[0]), t_r)
            start["mid_swing"] = bool(t_r < tt[0] - 0.25 * dt)
    return out


def peak_start(records, x_ref, mass, stiffness, max_samples):
    """Start values from the least-squares log decrement; release per record, mid-swing test.

    Parameters
    ----------
    records : sequence of Record
        The free decays.
    x_ref : float
        Spring zero [m or rad].
    mass, stiffness : float or None
        Known J [kg or kg·m²] or K [N/m or N·m/rad].
    max_samples : int
        Samples the peak search is decimated to [-].

    Returns
    -------
    (ndarray, list, list of bool)
        ``glob``, ``(x_r, t_r)`` per record, mid-swing flags.
    """
    step = math.ceil(sum(r.n for r in records) / max_samples)
    shifted = [Record(t=r.t[::step], x=np.asarray(r.x, float)[::step] - float(x_ref),
                      meta=r.meta, max_jitter=r.max_jitter) for r in records]
    try:
        start = estimate_log_decrement(shifted, mass=mass, stiffness=stiffness)
    except IdentificationError as exc:
        raise IdentificationError(
            f"output error needs start values from the peak estimator, which failed: {exc}"
        ) from None
    glob = [start.value(n) for n in GLOBAL_NAMES]
    glob[1:3] = [float(np.clip(z, -0.9, 0.9)) for z in glob[1:3]]
    glob[0] = max(glob[0], 1e-9)
    releases, mid_swing = [], []
    for rec, x, pt, px in zip(shifted, [v.x for v in shifted], start.data_used["peak_t"],
                              start.data_used["peak_x"], strict=True):
        noise = max(float(np.std(np.diff(x[:8]))), 1e-9 * float(np.ptp(x)))
        moving = (pt[0] - rec.t[0] > 3 * rec.dt) and abs(x[0] - px[0]) > 20 * noise
        if moving:  # the previous velocity zero lies before the first sample
            s0 = 1 if px[0] > x[0] else -1
            zeta = glob[1] if s0 > 0 else glob[2]
            rho = math.exp(-math.pi * zeta / math.sqrt(1 - zeta * zeta))
            e = -(s0 * glob[3] + glob[4])
            x_r = e - (px[0] - e) / rho
            t_r = pt[0] - math.pi / (glob[0] * math.sqrt(1 - zeta * zeta))
        else:
            x_r, t_r = float(px[0]), float(pt[0])
        releases.append((x_r, t_r))
        mid_swing.append(bool(moving))
    return np.array(glob), releases, mid_swing


def sample_starts(times, values) -> list[tuple[str, np.ndarray, list, list[bool]]]:
    """Start values of the free-decay fit from the samples, one set per strategy.

    Parameters
    ----------
    times : sequence of ndarray, shape (n_r,)
        Sample times of each record [s], increasing (any spacing).
    values : sequence of ndarray, shape (n_r,)
        Positions relative to the spring zero [m or rad].

    Returns
    -------
    list of (str, ndarray, list, list of bool)
        ``(strategy, glob, releases, mid_swing)`` with ``glob`` =
        ``(ω0, ζ⁺, ζ⁻, θk_mean, θk_delta)``, ``releases`` a ``(x_r, t_r)`` per record;
        only strategies that worked on every record.
    """
    per_record = [_one_record(np.asarray(t, float), np.asarray(x, float))
                  for t, x in zip(times, values, strict=True)]
    out = []
    for name in ("exponential", "linear envelope"):
        if not all(name in r for r in per_record):
            continue
        starts = [r[name] for r in per_record]
        zeta = float(np.median([s["zeta"] for s in starts]))
        omega0 = float(np.median([s["omega_d"] for s in starts])) / math.sqrt(1 - zeta**2)
        theta_k = float(np.median([s["theta_k"] for s in starts]))
        theta_delta = -float(np.median([s["center"] for s in starts]))
        glob = np.array([omega0, zeta, zeta, theta_k, theta_delta])
        out.append((name, glob, [s["release"] for s in starts],
                    [s["mid_swing"] for s in starts]))
    return out
