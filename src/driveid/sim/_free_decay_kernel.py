"""Compiled (numba) exact free decay of the 1-DOF oscillator with stiction; private.

:func:`free_decay_batch_kernel` evaluates the piecewise closed form for many parameter sets
(the Monte-Carlo path of :func:`driveid.sim.batch.simulate_free_decay_batch`); the caller
validates everything (float64 / int64 arrays).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from driveid.sim import _compile_notice

_compile_notice.install()


@njit(cache=True)
def _kernels_cs(tau, sigma, w0sq):
    """C and S kernels of ``y'' + 2σy' + ω0²y = 0`` (cos/sin, cosh/sinh, 1/τ; series near ζ=1)."""
    w2 = w0sq - sigma * sigma
    z = w2 * tau * tau
    if abs(z) < 1e-3:
        c = 1 - z / 2 * (1 - z / 12 * (1 - z / 30 * (1 - z / 56)))
        s = tau * (1 - z / 6 * (1 - z / 20 * (1 - z / 42 * (1 - z / 72))))
    elif w2 > 0:
        r = math.sqrt(w2)
        c = math.cos(r * tau)
        s = math.sin(r * tau) / r
    else:
        r = math.sqrt(-w2)
        c = math.cosh(r * tau)
        s = math.sinh(r * tau) / r
    return c, s


@njit(cache=True)
def _propagate(tau, y0, v0, sigma, w0sq):
    c, s = _kernels_cs(tau, sigma, w0sq)
    e = math.exp(-sigma * tau)
    return e * (y0 * c + (v0 + sigma * y0) * s), e * (v0 * c - (sigma * v0 + w0sq * y0) * s)


@njit(cache=True)
def _time_to_rest(y0, v0, sigma, w0sq):
    den = sigma * v0 + w0sq * y0
    w2 = w0sq - sigma * sigma
    if v0 == 0.0:
        return math.pi / math.sqrt(w2) if w2 > 0 else math.inf
    if w2 > 0:
        root = math.sqrt(w2)
        theta = math.atan2(root * v0, den) % math.pi
        return (theta if theta > 0 else math.pi) / root
    if den == 0.0:
        return math.inf
    g = v0 / den
    if g <= 0:
        return math.inf
    if w2 == 0.0:
        return g
    root = math.sqrt(-w2)
    if root * g >= 1.0:
        return math.inf
    return math.atanh(root * g) / root


@njit(cache=True)
def free_decay_batch_kernel(par, x0, v0, u0, fs, n_out, max_segments, want_v, x, v):
    """Exact free decays; par rows: J, K, c_mean, c_delta, fk_mean, fk_delta, fs_lo, fs_hi.

    Fills the caller's x, shape (n_sets, n_out), and v (the same, or any shape unfilled
    when ``want_v`` is False: half the memory traffic); returns (stuck_at, n_reversals, ok).
    Reusing x and v across calls saves the page faults of fresh output (most of the time of
    a large batch).
    """
    n = par.shape[0]
    stuck_at = np.full(n, np.nan)
    n_rev = np.zeros(n, dtype=np.int64)
    ok = np.ones(n, dtype=np.bool_)
    dt = 1.0 / fs
    t_last = (n_out - 1) * dt
    for r in range(n):
        J, K, cm, cd, fkm, fkd, lo, hi = (par[r, 0], par[r, 1], par[r, 2], par[r, 3],
                                          par[r, 4], par[r, 5], par[r, 6], par[r, 7])
        w0sq = K / J
        t_now = 0.0
        x_now = x0[r]
        v_now = v0[r]
        k = 0  # next output sample
        done = False
        for _seg in range(max_segments):
            if v_now == 0.0:
                f = u0[r] - K * x_now
                if lo <= f <= hi:
                    stuck_at[r] = t_now
                    while k < n_out:
                        x[r, k] = x_now
                        if want_v:
                            v[r, k] = 0.0
                        k += 1
                    done = True
                    break
                d = 1.0 if f > 0.5 * (lo + hi) else -1.0
            else:
                d = 1.0 if v_now > 0 else -1.0
            sigma = (cm + cd * d) / (2.0 * J)
            x_eq = (u0[r] - fkm * d - fkd) / K
            y0 = x_now - x_eq
            tau = _time_to_rest(y0, v_now, sigma, w0sq)
            t_end = t_now + tau
            if k < n_out and k * dt < t_end:
                # first sample in closed form, then the exact one-sample transition matrix
                yk, vk = _propagate(k * dt - t_now, y0, v_now, sigma, w0sq)
                a11, a21 = _propagate(dt, 1.0, 0.0, sigma, w0sq)
                a12, a22 = _propagate(dt, 0.0, 1.0, sigma, w0sq)
                while k < n_out and k * dt < t_end:
                    x[r, k] = yk + x_eq
                    if want_v:
                        v[r, k] = vk
                    yk, vk = a11 * yk + a12 * vk, a21 * yk + a22 * vk
                    k += 1
            if not math.isfinite(t_end) or t_end > t_last:
                done = True
                break
            yend, _ = _propagate(tau, y0, v_now, sigma, w0sq)
            x_now = yend + x_eq
            v_now = 0.0
            t_now = t_end
            n_rev[r] += 1
        if not done:
            ok[r] = False
    return stuck_at, n_rev, ok
