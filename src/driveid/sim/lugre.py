r"""Mass on a moving spring with LuGre friction: an adaptive L-stable implicit simulator.

The classic stick–slip rig: a body of mass ``m`` rests on a surface with LuGre friction,
de Marchi (1998) Eqs. (2.23)–(2.26), and is pulled through a spring ``k`` (with parallel
damper ``c``) whose far end moves at ``belt_speed``:

.. math:: \dot x = v, \quad
          m\dot v = k(v_b t - x) + c(v_b - v) - F(z, v), \quad
          \dot z = v - \sigma_0 |v| z / g_F(v),

with :math:`F = \sigma_0 z + \sigma_1 \dot z + \sigma_2 v` (2.24) and
:math:`g_F(v) = F_c + (F_s - F_c)e^{-(v/v_s)^2}` (2.26).

Why a special integrator: while sliding, the bristle state relaxes at the rate
:math:`\sigma_0|v|/g_F` (1e4 1/s for σ0 = 1e5, |v| = 0.1, g_F = 1), and while stuck the
bristle spring and the mass ring at :math:`\sqrt{\sigma_0/m}`; an explicit scheme must
resolve both for the whole run. Worse, explicit schemes at loose tolerances step over the
micro-slip and return stick–slip cycles that are grossly wrong without a warning
(``scipy.integrate.solve_ivp`` RK45 with its defaults: 21 % error on x, 98 % on v over the
20 s W2 run of issue 4; see ``benchmarks/bench_lugre.py``).

The integrator is the 2-stage Radau IIA collocation method (order 3, L-stable,
stiffly accurate), solved by a full Newton iteration on the 6 stage unknowns with the
analytic Jacobian re-evaluated at every iteration (the :math:`|v|` kink at ``v = 0`` can
make a frozen Jacobian stall). The local error is estimated with an embedded order-2
formula filtered by :math:`(I - h\gamma_0 J)^{-1}` as in Hairer & Wanner [2] §IV.8, and the
solution is written at the sample times by cubic Hermite interpolation of each step.

References
----------
.. [1] J. A. de Marchi, "Modeling of dynamic friction, impact backlash and elastic
       compliance nonlinearities in machine tools", PhD thesis, RPI, 1998.
.. [2] E. Hairer, G. Wanner, "Solving Ordinary Differential Equations II: Stiff and
       Differential-Algebraic Problems", 2nd ed., Springer, 1996.
.. [3] C. Canudas de Wit, H. Olsson, K. J. Åström, P. Lischinsky, "A new model for control
       of systems with friction", IEEE Trans. Automatic Control 40(3), 419–425, 1995.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from driveid.errors import ParameterError, SimulationError
from driveid.models.dynamic_friction import LuGreParams, lugre_friction
from driveid.sim import _compile_notice

_compile_notice.install()

__all__ = ["LuGreResult", "simulate_lugre_oscillator"]

# Radau IIA, s = 2: c = (1/3, 1), A = [[5/12, -1/12], [3/4, 1/4]], b = A[1] (stiffly accurate).
_A11, _A12, _A21, _A22 = 5.0 / 12.0, -1.0 / 12.0, 0.75, 0.25
_C1 = 1.0 / 3.0
# Embedded order-2 formula y0 + h(g0 f0 + sum (b_i + e_i) k_i): the order-2 conditions with
# c = (1/3, 1) give e1 = -3 e2 and g0 = 2 e2; e2 = 1/4 puts g0 = 1/2.
_G0, _E1, _E2 = 0.5, -0.75, 0.25

_OK, _TOO_MANY_STEPS, _STEP_TOO_SMALL = 0, 1, 2
_MAX_NEWTON = 10
_MAX_STEPS = 50_000_000


# _rhs and _jac are plain calls, not inline="always": LLVM inlines them into the kernel all
# the same (equal run time), without numba copying their IR to each of the 9 call sites
@njit(cache=True)
def _rhs(t, x, v, z, par, out):
    """Right-hand side; ``par`` = (m, k, c, vb, sigma0, sigma1, sigma2, fc, fs, vs)."""
    m, k, c, vb = par[0], par[1], par[2], par[3]
    s0, s1, s2, fc, fs, vs = par[4], par[5], par[6], par[7], par[8], par[9]
    g = fc + (fs - fc) * math.exp(-((v / vs) ** 2))
    zd = v - s0 * abs(v) * z / g
    friction = s0 * z + s1 * zd + s2 * v
    out[0] = v
    out[1] = (k * (vb * t - x) + c * (vb - v) - friction) / m
    out[2] = zd


@njit(cache=True)
def _jac(v, z, par, jac):
    """Analytic d(rhs)/d(x, v, z); the sign(v) of the |v| kink is taken as 0 at v = 0."""
    m, k, c = par[0], par[1], par[2]
    s0, s1, s2, fc, fs, vs = par[4], par[5], par[6], par[7], par[8], par[9]
    e = math.exp(-((v / vs) ** 2))
    g = fc + (fs - fc) * e
    dg = -2.0 * v / (vs * vs) * (fs - fc) * e
    sgn = 1.0 if v > 0.0 else (-1.0 if v < 0.0 else 0.0)
    dzd_dv = 1.0 - s0 * z * (sgn * g - abs(v) * dg) / (g * g)
    dzd_dz = -s0 * abs(v) / g
    jac[0, 0], jac[0, 1], jac[0, 2] = 0.0, 1.0, 0.0
    jac[1, 0] = -k / m
    jac[1, 1] = -(c + s1 * dzd_dv + s2) / m
    jac[1, 2] = -(s0 + s1 * dzd_dz) / m
    jac[2, 0], jac[2, 1], jac[2, 2] = 0.0, dzd_dv, dzd_dz


@njit(cache=True)
def _solve_inplace(a, b, n):
    """Gaussian elimination with partial pivoting; overwrites ``a``, solution left in ``b``."""
    for col in range(n):
        piv = col
        best = abs(a[col, col])
        for r in range(col + 1, n):
            if abs(a[r, col]) > best:
                best = abs(a[r, col])
                piv = r
        if best == 0.0:
            return False
        if piv != col:
            for j in range(n):
                a[col, j], a[piv, j] = a[piv, j], a[col, j]
            b[col], b[piv] = b[piv], b[col]
        for r in range(col + 1, n):
            f = a[r, col] / a[col, col]
            if f != 0.0:
                for j in range(col, n):
                    a[r, j] -= f * a[col, j]
                b[r] -= f * b[col]
    for r in range(n - 1, -1, -1):
        s = b[r]
        for j in range(r + 1, n):
            s -= a[r, j] * b[j]
        b[r] = s / a[r, r]
    return True


@njit(cache=True)
def _norm(e, y0, y1, atol, rtol):
    """RMS of the error scaled by atol + rtol * max(|y0|, |y1|) over the 3 states."""
    s = 0.0
    for i in range(3):
        w = atol[i] + rtol * max(abs(y0[i]), abs(y1[i]))
        s += (e[i] / w) ** 2
    return math.sqrt(s / 3.0)


@njit(cache=True)
def _lugre_radau_kernel(y_init, par, atol, rtol, t_end, fs, n_out, max_steps):
    """Integrate to ``t_end`` with adaptive Radau IIA (s = 2); samples at ``i/fs``.

    Returns (out[3, n_out], n_accepted, n_rejected, status).
    """
    out = np.full((3, n_out), np.nan)
    y0 = y_init.copy()
    for i in range(3):
        out[i, 0] = y0[i]
    f0 = np.empty(3)
    f1 = np.empty(3)
    k1 = np.empty(3)
    yst = np.empty(3)
    y1 = np.empty(3)
    err = np.empty(3)
    tmp = np.empty(3)
    j1 = np.empty((3, 3))
    j2 = np.empty((3, 3))
    big = np.empty((6, 6))
    rhs6 = np.empty(6)
    zst = np.empty(6)
    m3 = np.empty((3, 3))

    newton_tol = max(10.0 * 2.2e-16 / rtol, min(0.03, math.sqrt(rtol)))
    t = 0.0
    _rhs(t, y0[0], y0[1], y0[2], par, f0)
    h = min(1e-5, t_end)
    # loop state starts typed (np.int64, np.bool_), not as literals: type inference then
    # settles in 2 passes over the kernel instead of 4
    next_out = np.int64(1)
    n_acc = np.int64(0)
    n_rej = np.int64(0)
    prev_rejected = np.bool_(False)
    first = np.bool_(True)
    h_min = 1e-14 * max(t_end, 1.0)
    while t < t_end and next_out < n_out:
        if n_acc + n_rej >= max_steps:
            return out, n_acc, n_rej, _TOO_MANY_STEPS
        if h < h_min:
            return out, n_acc, n_rej, _STEP_TOO_SMALL
        if t + h > t_end:
            h = t_end - t
        # --- Newton on the stage increments Z_i = Y_i - y0 (predictor: explicit Euler) ---
        for i in range(3):
            zst[i] = _C1 * h * f0[i]
            zst[3 + i] = h * f0[i]
        converged = False
        dn_prev = 0.0
        for it in range(_MAX_NEWTON):
            for i in range(3):
                tmp[i] = y0[i] + zst[i]
                yst[i] = y0[i] + zst[3 + i]
            _rhs(t + _C1 * h, tmp[0], tmp[1], tmp[2], par, k1)
            _rhs(t + h, yst[0], yst[1], yst[2], par, f1)
            _jac(tmp[1], tmp[2], par, j1)
            _jac(yst[1], yst[2], par, j2)
            for i in range(3):
                rhs6[i] = -(zst[i] - h * (_A11 * k1[i] + _A12 * f1[i]))
                rhs6[3 + i] = -(zst[3 + i] - h * (_A21 * k1[i] + _A22 * f1[i]))
                for j in range(3):
                    eye = 1.0 if i == j else 0.0
                    big[i, j] = eye - h * _A11 * j1[i, j]
                    big[i, 3 + j] = -h * _A12 * j2[i, j]
                    big[3 + i, j] = -h * _A21 * j1[i, j]
                    big[3 + i, 3 + j] = eye - h * _A22 * j2[i, j]
            if not _solve_inplace(big, rhs6, 6):
                break
            dn = 0.0
            for i in range(6):
                zst[i] += rhs6[i]
                w = atol[i % 3] + rtol * abs(y0[i % 3])
                dn += (rhs6[i] / w) ** 2
            dn = math.sqrt(dn / 6.0)
            if not math.isfinite(dn):
                break
            if it > 0 and dn > 2.0 * dn_prev:
                break  # diverging
            if dn < newton_tol:
                converged = True
                break
            dn_prev = dn
        if not converged:
            h *= 0.5
            n_rej += 1
            prev_rejected = True
            continue
        for i in range(3):
            tmp[i] = y0[i] + zst[i]
            y1[i] = y0[i] + zst[3 + i]
        _rhs(t + _C1 * h, tmp[0], tmp[1], tmp[2], par, k1)
        _rhs(t + h, y1[0], y1[1], y1[2], par, f1)
        # --- embedded error, filtered by (I - h g0 J(y0)) for stiff components ---
        _jac(y0[1], y0[2], par, j1)
        for i in range(3):
            err[i] = h * (_G0 * f0[i] + _E1 * k1[i] + _E2 * f1[i])
            for j in range(3):
                m3[i, j] = (1.0 if i == j else 0.0) - h * _G0 * j1[i, j]
        _solve_inplace(m3, err, 3)
        en = _norm(err, y0, y1, atol, rtol)
        if en > 1.0 and (first or prev_rejected):
            # second filtering (Hairer & Wanner IV.8): damps the stiff part once more
            for i in range(3):
                tmp[i] = y0[i] + err[i]
            _rhs(t, tmp[0], tmp[1], tmp[2], par, yst)
            for i in range(3):
                err[i] = h * (_G0 * yst[i] + _E1 * k1[i] + _E2 * f1[i])
                for j in range(3):
                    m3[i, j] = (1.0 if i == j else 0.0) - h * _G0 * j1[i, j]
            _solve_inplace(m3, err, 3)
            en = _norm(err, y0, y1, atol, rtol)
        # estimate is O(h^3): exponent 1/3
        fac = 0.9 * (1.0 / max(en, 1e-10)) ** (1.0 / 3.0)
        if en > 1.0:
            h *= max(0.1, fac)
            n_rej += 1
            prev_rejected = True
            continue
        # --- accepted: cubic Hermite dense output on [t, t + h] ---
        t1 = t + h
        while next_out < n_out:
            ts = next_out / fs
            if ts > t1 * (1.0 + 1e-14):
                break
            s = (ts - t) / h
            s = min(max(s, 0.0), 1.0)
            h00 = (1.0 + 2.0 * s) * (1.0 - s) ** 2
            h10 = s * (1.0 - s) ** 2
            h01 = s * s * (3.0 - 2.0 * s)
            h11 = s * s * (s - 1.0)
            for i in range(3):
                out[i, next_out] = (h00 * y0[i] + h10 * h * f0[i] + h01 * y1[i]
                                    + h11 * h * f1[i])
            next_out += 1
        t = t1
        for i in range(3):
            y0[i] = y1[i]
            f0[i] = f1[i]
        n_acc += 1
        grow = min(5.0, fac)
        if prev_rejected:
            grow = min(1.0, grow)
        h *= grow
        prev_rejected = False
        first = False
    return out, n_acc, n_rej, _OK


@dataclass(frozen=True)
class LuGreResult:
    """Sampled response of :func:`simulate_lugre_oscillator`.

    Attributes
    ----------
    t : ndarray, shape (n,)
        Sample times ``i / fs`` [s].
    x : ndarray, shape (n,)
        Position of the mass [m].
    v : ndarray, shape (n,)
        Velocity of the mass [m/s].
    z : ndarray, shape (n,)
        Mean bristle deflection [m].
    friction : ndarray, shape (n,)
        LuGre friction force on the mass, opposing motion, Eq. (2.24) [N].
    n_steps : int
        Accepted integrator steps [-].
    n_rejected : int
        Rejected steps (error test or Newton failure) [-].
    """

    t: np.ndarray
    x: np.ndarray
    v: np.ndarray
    z: np.ndarray
    friction: np.ndarray
    n_steps: int
    n_rejected: int


def _real(name: str, value, *, rule: str = "finite", low: float | None = None,
          strict: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)):
        raise ParameterError(f"{name} must be a real number; got {name}={value!r}")
    x = float(value)
    ok = math.isfinite(x) and (low is None or (x > low if strict else x >= low))
    if not ok:
        raise ParameterError(f"{name} must be {rule}; pass a physical value; got {name}={value!r}")
    return x


def simulate_lugre_oscillator(
    params: LuGreParams,
    *,
    m: float,
    k: float,
    c: float = 0.0,
    belt_speed: float,
    duration: float,
    fs: float = 1000.0,
    x0: float = 0.0,
    v0: float = 0.0,
    z0: float = 0.0,
    rtol: float = 1e-6,
) -> LuGreResult:
    r"""Simulate a mass pulled through a spring over a LuGre-friction surface.

    Parameters
    ----------
    params : LuGreParams
        LuGre friction, Eqs. (2.23)–(2.26). Stick–slip rigs often violate the passivity
        bound; build those with ``check_passivity=False``.
    m : float
        Mass [kg]; > 0.
    k : float
        Spring stiffness [N/m]; > 0.
    c : float, optional
        Damper parallel to the spring [N·s/m]; >= 0. Its force is ``c (belt_speed - v)``.
        Default 0.
    belt_speed : float
        Speed of the spring's far end, which sits at ``belt_speed * t`` [m/s]; finite.
    duration : float
        Simulated time [s]; > 0.
    fs : float, optional
        Output sample rate [Hz]; > 0 and at most 1e7 samples in all. Default 1000.
    x0, v0, z0 : float, optional
        Initial position [m], velocity [m/s] and bristle deflection [m]. Default 0.
    rtol : float, optional
        Relative tolerance of the local error [-], in [1e-12, 1e-2]. The absolute
        tolerances are ``rtol`` times the state scales ``F_s/k`` (x), ``v_s`` (v) and
        ``F_s/sigma0`` (z), so a single number suffices. The velocity scale is the
        Stribeck velocity, not the belt speed, because the breakaway is an instability
        that amplifies errors of the micro-slip velocity (~1e-6 m/s in W2); with the belt
        speed as scale the breakaway time is off by 1e-4 relative at rtol = 1e-6. Default
        1e-6, which reproduces an rtol = 1e-10 reference to 2.3e-6 relative (max |x error|
        / max |x|) on the W2 stick–slip run.

    Returns
    -------
    LuGreResult
        Samples of x, v, z and the friction force, and step counts.

    Raises
    ------
    ParameterError
        If ``params`` is not a :class:`LuGreParams` or any number is out of range.
    SimulationError
        If the step size collapses or more than 5e7 steps would be needed.

    Notes
    -----
    State equations in the module docstring. The integrator is 2-stage Radau IIA [2]
    (order 3, L-stable) with full Newton and the analytic Jacobian; the steady sliding
    solution at ``v = belt_speed`` has friction :math:`g_F(v)\,\mathrm{sgn}(v) + \sigma_2 v`
    (:func:`driveid.models.dynamic_friction.lugre_steady_friction`).

    Examples
    --------
    >>> from driveid.models.dynamic_friction import LuGreParams
    >>> p = LuGreParams(sigma0=1e5, sigma1=316.2, sigma2=0.4, fc=1.0, fs=1.5, vs=1e-3,
    ...                 check_passivity=False)
    >>> r = simulate_lugre_oscillator(p, m=1.0, k=2.0, belt_speed=0.1, duration=1.0)
    >>> r.x.shape
    (1001,)
    >>> bool(abs(r.v[-1]) < 1e-3)   # still stuck after 1 s: the spring force is below F_s
    True
    """
    if not isinstance(params, LuGreParams):
        raise ParameterError(
            f"params must be a LuGreParams; build one with LuGreParams(...); got {params!r}"
        )
    m = _real("m", m, rule="finite and > 0 [kg]", low=0.0, strict=True)
    k = _real("k", k, rule="finite and > 0 [N/m]", low=0.0, strict=True)
    c = _real("c", c, rule="finite and >= 0 [N·s/m]", low=0.0)
    vb = _real("belt_speed", belt_speed, rule="finite [m/s]")
    duration = _real("duration", duration, rule="finite and > 0 [s]", low=0.0, strict=True)
    fs = _real("fs", fs, rule="finite and > 0 [Hz]", low=0.0, strict=True)
    x0 = _real("x0", x0, rule="finite [m]")
    v0 = _real("v0", v0, rule="finite [m/s]")
    z0 = _real("z0", z0, rule="finite [m]")
    rtol = _real("rtol", rtol, rule="finite and in [1e-12, 1e-2] [-]", low=0.0, strict=True)
    if not 1e-12 <= rtol <= 1e-2:
        raise ParameterError(
            f"rtol must be in [1e-12, 1e-2]: tighter is below round-off, looser is not a "
            f"LuGre answer; got rtol={rtol!r}"
        )
    n_out = int(math.floor(duration * fs * (1.0 + 1e-12))) + 1
    if n_out > 10_000_000:
        raise ParameterError(
            f"duration * fs must give at most 1e7 samples; lower fs or duration; got "
            f"{n_out} samples (duration={duration!r}, fs={fs!r})"
        )
    p = params
    par = np.array([m, k, c, vb, p.sigma0, p.sigma1, p.sigma2, p.fc, p.fs, p.vs], float)
    scales = np.array([p.fs / k, p.vs, p.fs / p.sigma0])
    atol = rtol * scales
    t_end = (n_out - 1) / fs
    out, n_acc, n_rej, status = _lugre_radau_kernel(
        np.array([x0, v0, z0]), par, atol, rtol, t_end, fs, n_out, _MAX_STEPS
    )
    if status != _OK:
        why = "the step size collapsed"
        if status == _TOO_MANY_STEPS:
            why = f"more than {_MAX_STEPS} steps"
        raise SimulationError(
            f"LuGre integration stopped: {why}; loosen rtol or shorten duration; "
            f"got rtol={rtol!r}, duration={duration!r}"
        )
    t = np.arange(n_out) / fs
    x, v, z = out[0], out[1], out[2]
    return LuGreResult(t=t, x=x, v=v, z=z, friction=lugre_friction(z, v, p),
                       n_steps=int(n_acc), n_rejected=int(n_rej))
