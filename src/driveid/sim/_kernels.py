"""Compiled (numba) hot loops of the lumped drive simulator; private, see :mod:`driveid.sim.drive`.

Kernels:

* :func:`drive_kernel` — fixed-step RK4 on a chain of bodies with event location (Illinois
  secant on the event functions) for velocity zeros, breakaway, and contact entry/exit
  (Kelvin–Voigt contact, or a Newton restitution impulse at the gap edge), and a PD feedback
  with a pure delay read from a history of past states (cubic Hermite); resumable, so a
  sampled-data controller can run it one control period at a time. With ``rtol`` it strides
  over several grid steps where an embedded error estimate allows (:func:`_integrate`).
  Bodies with frictional memory (Eq. 2.12) keep a ring of their grid-point velocities in the
  same history array (:func:`_lagged_velocity`).

All arrays are float64 / int64; the caller validates everything.

Speed (issue 18, docs/performance.md): the time loop (:func:`_integrate`) is compiled
without reference counting and with its per-step helpers inlined, on separate stage vectors
(an array view or a call with array arguments in the loop costs an atomic reference-count
update or ~100 words of arguments: three quarters of the step time before); the first RK4
stage at a point is computed once and serves every trial step of the event search and the
delay history; the forces at a step's end are computed only while a body is stuck. Each
helper is inlined at one call site only: numba's inlining copies it at every site, and 17
copies of the force evaluation took 90 s to compile (now about 15 s).

One file on purpose: numba's on-disk cache checks only the source file of the function it
caches, so a helper of :func:`_integrate` kept in another module could change and leave a
stale compiled kernel in every user's cache.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numba.core import cpu as _numba_cpu

from driveid.sim import _compile_notice

_compile_notice.install()

# The time loop allocates nothing, so it is compiled without numba's reference counting
# (``_nrt=False``, a private option: ~4x per step, the incref/decref calls dominated). Should a
# numba release drop the option, the kernels compile as usual, only slower. Masses and
# stiffnesses are validated positive, so divisions need no zero check (numpy error model, -5 %
# per step, results identical); reciprocals (``arcp``) change results by round-off only (-7 %
# with fused multiply-adds, now as much without). Not ``contract``: an FMA is fused or not
# depending on the code around it, so the forces of the inlined step and of the separately
# compiled cold paths differed in the last bit, and an event function at a band edge was
# negative for one and not the other (the event loop never ended). The force evaluation
# itself has no division (the delay history multiplies by reciprocals), so ``arcp`` leaves it
# the same everywhere. Not the no-NaN/no-inf flags: outputs start as NaN, the abort limit may
# be inf.
_HOT_LOOP = {"error_model": "numpy", "fastmath": {"arcp"}}
if hasattr(_numba_cpu.CPUTargetOptions, "_nrt"):
    _HOT_LOOP["_nrt"] = False

# body modes (slipping bodies: the sign of their velocity, +-1)
LOCKED = 2
STUCK = 0
FREE = 3  # no friction that depends on the velocity's sign: no velocity-zero events
# Stribeck map of a body (its parameter row, column 11)
STRIBECK_NONE = 0
STRIBECK_LORENTZIAN = 1  # Eq. 2.3 (and Hess-Soom 2.2 through 2.4)
STRIBECK_EXPONENTIAL = 2  # Bo-Pavelescu Eq. 2.5
# body row columns the kernel writes (friction state): when the body stuck [s], and the
# rising fraction of the static excess reached at its last breakaway [-]
COL_STUCK_AT = 17
COL_RISE = 18
# frictional memory (Eq. 2.12): the lag [s], then columns the kernel writes: where the body's
# velocity history starts in ``hist``, its length (a ring) and its last grid step written
COL_MEMORY = 19
COL_RING = 20
COL_RING_LEN = 21
COL_LAST = 22
# link types
LINK_NONE = 0
LINK_SHAFT = 1
LINK_BACKLASH = 2
LINK_IMPACT = 3  # restitution contact; compliant (as LINK_BACKLASH) while resting
# delay history, row 3 of a grid step: 0, EVENT (an event inside), or the column (>= 2) of
# the node of its first event
EVENT = 1.0
# status codes
OK = 0
ABORTED = 1
TOO_MANY_EVENTS = 2


@njit(cache=True, inline="always")
def _interp(arr, row, tau, fs):
    """Linear interpolation of ``arr[row]``, sampled at ``k/fs`` (held beyond the ends)."""
    n = arr.shape[1]
    if n == 1:  # a constant input (one column)
        return arr[row, 0]
    pos = tau * fs
    if pos <= 0.0:
        return arr[row, 0]
    k = int(math.floor(pos))
    if k >= n - 1:
        return arr[row, n - 1]
    w = pos - k
    return arr[row, k] * (1.0 - w) + arr[row, k + 1] * w


@njit(cache=True, inline="always")
def _hermite(s, h):
    """Cubic Hermite weights of (value, slope) at the start and end of an interval.

    ``s`` in [0, 1] is the position inside it, ``h`` its length [s].
    """
    s2 = s * s
    s3 = s2 * s
    return 2 * s3 - 3 * s2 + 1, (s3 - 2 * s2 + s) * h, -2 * s3 + 3 * s2, (s3 - s2) * h


@njit(cache=True, inline="always")
def _ring(delay, h):
    """Slots of the ring of event nodes in the delay history: the grid steps of a delay, + 3."""
    return int(math.ceil(delay / h - 1e-9)) + 3


@njit(cache=True, inline="always")
def _delayed(tau, delay, h, hist, x0, v0, now_x, now_v):
    """Position and velocity of the feedback body at ``tau - delay`` (cubic Hermite).

    hist rows: position, velocity, acceleration and a flag (0, EVENT or a node's column) at
    the grid points ``k h``, then a ring of event nodes, two columns each
    (:func:`drive_kernel`). In a grid step with a node the read uses two Hermite pieces
    split at the event, so the kink the event left in the motion is not smoothed over
    (Hermite across it errs by ~h² times the jump of the acceleration).
    """
    if delay == 0.0:
        return now_x, now_v
    td = tau - delay
    if td <= 0.0:
        return x0, v0
    pos = td * (1.0 / h)
    k = int(math.floor(pos))
    if k >= hist.shape[1] - 1:
        k = hist.shape[1] - 2
    if hist[3, k] > EVENT:  # rare: a separate function keeps the inlined copies small
        return _delayed_at_node(hist, k, pos - k, h)
    h00, h10, h01, h11 = _hermite(pos - k, h)
    x = h00 * hist[0, k] + h10 * hist[1, k] + h01 * hist[0, k + 1] + h11 * hist[1, k + 1]
    v = h00 * hist[1, k] + h10 * hist[2, k] + h01 * hist[1, k + 1] + h11 * hist[2, k + 1]
    return x, v


@njit(cache=True, **_HOT_LOOP)
def _delayed_at_node(hist, k, s, h):
    """Read the delay history like :func:`_delayed`, at fraction ``s`` of node step k.

    Node columns: [offset, x, v before, a before], [v after, a after]. At the event itself
    (to round-off) the piece after it: every read from a step that starts at the kink then
    agrees, and so do the event functions there.
    """
    c = int(hist[3, k])
    sec = s * h
    if sec < hist[0, c] - 1e-9 * h:
        span = hist[0, c]
        xa, va, aa = hist[0, k], hist[1, k], hist[2, k]
        xb, vb, ab = hist[1, c], hist[2, c], hist[3, c]
    else:
        sec -= hist[0, c]
        span = h - hist[0, c]
        xa, va, aa = hist[1, c], hist[0, c + 1], hist[1, c + 1]
        xb, vb, ab = hist[0, k + 1], hist[1, k + 1], hist[2, k + 1]
    h00, h10, h01, h11 = _hermite(sec * (1.0 / span), span)
    return (h00 * xa + h10 * va + h01 * xb + h11 * vb,
            h00 * va + h10 * aa + h01 * vb + h11 * ab)


@njit(cache=True, inline="always")
def _forces(tau, y, nb, modes, par, inp, hist, fs_in, h, x0b, v0b, work):
    """Compute the applied force on every body (but its own friction) and each link force.

    par rows (23 columns, zero-padded): bodies (J, K, c_mean, c_delta, fk_mean, fk_delta,
    fs_lo, fs_hi, ripple amplitude, ripple wavenumber 2π/P, ripple phase, Stribeck map
    code, v_s for v > 0, v_s for v < 0, Stribeck exponent, dwell gamma (0: no rising
    static friction), dwell kappa, then two state columns the kernel writes: the time the
    body stuck and the rising fraction at its last breakaway; the memory lag (0: none),
    then three columns the kernel writes: its velocity ring's first column in ``hist``,
    the ring's length and the last grid step stored), links (type, k, c,
    gap_plus, gap_minus, allow_tension, restitution, rest_velocity), feedback (on, body, P,
    D, delay, sat).
    inp rows: torque of each body, reference. work: applied forces, then link forces.
    Returns the saturated command [N·m].
    """
    nl = nb - 1
    for i in range(nb):
        work[i] = _interp(inp, i, tau, fs_in) - par[i, 1] * y[i]
    cmd = 0.0
    fbr = nb + nl
    if par[fbr, 0] != 0.0:
        b = int(par[fbr, 1])
        xd, vd = _delayed(tau, par[fbr, 4], h, hist, x0b, v0b, y[b], y[nb + b])
        raw = par[fbr, 2] * (_interp(inp, nb, tau, fs_in) - xd) - par[fbr, 3] * vd
        cmd = min(max(raw, -par[fbr, 5]), par[fbr, 5])
        work[b] += cmd
    for j in range(nl):
        r = nb + j
        f = 0.0
        rel = y[j] - y[j + 1]
        vrel = y[nb + j] - y[nb + j + 1]
        if par[r, 0] == LINK_SHAFT:
            f = par[r, 1] * rel + par[r, 2] * vrel
        elif par[r, 0] >= LINK_BACKLASH:
            if modes[r] > 0:
                f = par[r, 1] * (rel - par[r, 3]) + par[r, 2] * vrel
            elif modes[r] < 0:
                f = par[r, 1] * (rel + par[r, 4]) + par[r, 2] * vrel
        work[r] = f
        work[j] -= f
        work[j + 1] += f
    return cmd


@njit(cache=True, inline="always")
def _friction(tau, y, nb, i, m, par, hist, h):
    """Friction force of slipping body i in direction m (its mode) at time tau [N·m or N]."""
    level = par[i, 4]
    if par[i, 8] != 0.0:  # friction ripple periodic in position (drive_types)
        level += par[i, 8] * math.sin(par[i, 9] * y[i] + par[i, 10])
    f = (par[i, 2] + par[i, 3] * m) * y[nb + i] + level * m + par[i, 5]
    if par[i, 11] != STRIBECK_NONE:  # a separate function: Coulomb bodies pay one compare
        f += _stribeck(tau, y[nb + i], i, m, par, hist, h)
    return f


@njit(cache=True, **_HOT_LOOP)
def _stribeck(tau, v, i, m, par, hist, h):
    """Stribeck term of slipping body i in direction m: the static excess times its shape.

    ``(static edge - kinetic level) * rise * g(|v| / v_s)`` with ``g = 1/(1 + r²)``
    (Lorentzian, Eq. 2.3) or ``exp(-r**delta)`` (Bo–Pavelescu, Eq. 2.5), each direction with
    its own edge, kinetic level and v_s; ``rise`` is 1 without dwell (Eq. 2.9 otherwise).
    With frictional memory (Eq. 2.12) ``v`` is the velocity one lag ago
    (:func:`_lagged_velocity`); the direction m stays the current one.
    The same formulas as :mod:`driveid.models.friction` (tests compare them): the kernel
    keeps its own copy because numba's cache checks only this file.
    """
    if par[i, COL_MEMORY] > 0.0:
        v = _lagged_velocity(tau, v, i, par, hist, h)
    r = abs(v) / (par[i, 12] if m > 0 else par[i, 13])
    if par[i, 11] == STRIBECK_LORENTZIAN:
        g = 1.0 / (1.0 + r * r)
    else:
        g = math.exp(-(r ** par[i, 14]))
    edge = par[i, 7] if m > 0 else par[i, 6]
    return (edge - (par[i, 4] * m + par[i, 5])) * par[i, COL_RISE] * g


@njit(cache=True, inline="always")
def _lagged_velocity(tau, v_now, i, par, hist, h):
    """Velocity of body i at ``tau - memory`` [rad/s or m/s] from its history ring.

    Ring rows 0 and 1: velocity and acceleration at the grid points ``k h`` (column
    ``COL_RING + k % COL_RING_LEN``), written up to grid step ``COL_LAST``. Cubic Hermite
    between stored grid points (the delay history's interpolant, :func:`_delayed`); past
    the last one (a lag shorter than the step) linear towards the current velocity, so a
    lag -> 0 tends to the memoryless map; before t = 0 the velocity at t = 0.
    """
    td = tau - par[i, COL_MEMORY]
    base = int(par[i, COL_RING])
    if td <= 0.0:
        return hist[0, base]
    n = int(par[i, COL_RING_LEN])
    last = int(par[i, COL_LAST])
    pos = td * (1.0 / h)
    k = int(math.floor(pos))
    if k >= last:
        t_last = last * h
        v_last = hist[0, base + last % n]
        span = tau - t_last
        if span <= 0.0:
            return v_now
        return v_last + (v_now - v_last) * ((td - t_last) / span)
    ca = base + k % n
    cb = base + (k + 1) % n
    h00, h10, h01, h11 = _hermite(pos - k, h)
    return h00 * hist[0, ca] + h10 * hist[1, ca] + h01 * hist[0, cb] + h11 * hist[1, cb]


@njit(cache=True, **_HOT_LOOP)
def _record_velocities(hist, par, nb, step, y, k1):
    """Store the velocity and acceleration of every memory body at grid step ``step``."""
    for i in range(nb):
        if par[i, COL_MEMORY] > 0.0:
            c = int(par[i, COL_RING]) + step % int(par[i, COL_RING_LEN])
            hist[0, c] = y[nb + i]
            hist[1, c] = k1[nb + i]
            par[i, COL_LAST] = step


@njit(cache=True)
def _memory_rings(par, nb, h, first):
    """Lay out the velocity rings of the memory bodies from column ``first`` of ``hist``.

    Each ring holds the grid steps of the body's lag + 3 (the Hermite read of
    :func:`_lagged_velocity` reaches one step further back than the lag, and one more
    guards round-off). Returns the number of columns they take.
    """
    col = first
    for i in range(nb):
        if par[i, COL_MEMORY] > 0.0:
            n = int(math.ceil(par[i, COL_MEMORY] / h - 1e-9)) + 3
            par[i, COL_RING] = col
            par[i, COL_RING_LEN] = n
            par[i, COL_LAST] = 0.0
            col += n
    return col - first


@njit(cache=True, inline="always")
def _band(dwell, i, par):
    """Return body i's static band (lo, hi) [N·m] after ``dwell`` s stuck, and its rise [-].

    Without dwell parameters the band of the row; with them the kinetic band at zero dwell
    rising to the row's band as ``1 - exp(-dwell**kappa / gamma)`` (Kato/Howe, Eq. 2.6).
    """
    if par[i, 15] == 0.0:
        return par[i, 6], par[i, 7], 1.0
    rise = 1.0 - math.exp(-(dwell ** par[i, 16]) / par[i, 15]) if dwell > 0.0 else 0.0
    klo = par[i, 5] - par[i, 4]
    khi = par[i, 5] + par[i, 4]
    return klo + (par[i, 6] - klo) * rise, khi + (par[i, 7] - khi) * rise, rise


@njit(cache=True, **_HOT_LOOP)
def _acceleration(tau, y, nb, i, modes, par, work, hist, h):
    """Acceleration of body i in its mode, from the forces in ``work`` (computed at y)."""
    m = modes[i]
    if m == LOCKED or m == STUCK:
        return 0.0
    return (work[i] - _friction(tau, y, nb, i, m, par, hist, h)) / par[i, 0]


@njit(cache=True, inline="always")
def _deriv(tau, y, nb, modes, par, inp, hist, fs_in, h, x0b, v0b, work, dy):
    """State derivative: x', v', then input work, dissipation, contact work rates.

    The three energy rates only if the state carries the energy integrals (length 2 nb + 3).
    """
    cmd = _forces(tau, y, nb, modes, par, inp, hist, fs_in, h, x0b, v0b, work)
    nl = nb - 1
    fbr = nb + nl
    fb_body = int(par[fbr, 1]) if par[fbr, 0] != 0.0 else -1
    p_in = 0.0
    p_diss = 0.0
    p_contact = 0.0
    for i in range(nb):
        v = y[nb + i]
        m = modes[i]
        if m == LOCKED or m == STUCK:
            dy[i] = 0.0
            dy[nb + i] = 0.0
            continue
        ext = _interp(inp, i, tau, fs_in)
        if i == fb_body:
            ext += cmd
        fric = _friction(tau, y, nb, i, m, par, hist, h)
        dy[i] = v
        dy[nb + i] = (work[i] - fric) / par[i, 0]
        p_in += ext * v
        p_diss += fric * v
    if dy.shape[0] == 2 * nb:  # no energy integrals: positions and velocities only
        return cmd
    for j in range(nl):
        r = nb + j
        vrel = y[nb + j] - y[nb + j + 1]
        if par[r, 0] == LINK_SHAFT:
            p_diss += par[r, 2] * vrel * vrel
        elif par[r, 0] >= LINK_BACKLASH and modes[r] != 0:
            p_contact += work[r] * vrel
    dy[2 * nb] = p_in
    dy[2 * nb + 1] = p_diss
    dy[2 * nb + 2] = p_contact
    return cmd


@njit(cache=True, inline="always")
def _contact_gaps(y, nb, j, par, r):
    """Penetrations (dp, dm) and contact event functions (gp, gm) of backlash link j.

    g is positive while its + (or -) side is in contact. With tension allowed, contact is the
    penetration alone; without, it also ends where the contact force ``k·δ ± c·δ'`` reaches
    zero (the bodies separate before the gap opens).
    """
    rel = y[j] - y[j + 1]
    vrel = y[nb + j] - y[nb + j + 1]
    dp = rel - par[r, 3]
    dm = -par[r, 4] - rel
    if par[r, 5] != 0.0:
        return dp, dm, dp, dm
    return (dp, dm, min(dp, par[r, 1] * dp + par[r, 2] * vrel),
            min(dm, par[r, 1] * dm - par[r, 2] * vrel))


@njit(cache=True, inline="always")
def _validity(tau, y, nb, modes, par, work, phi):
    """Event functions: >= 0 while the current mode holds, < 0 once it must switch.

    ``work`` must hold the forces at ``y`` (from :func:`_forces`).
    """
    for i in range(nb):
        m = modes[i]
        if m == LOCKED or m == FREE:
            phi[i] = 1.0
        elif m == STUCK:
            f = work[i]
            lo, hi, _ = _band(tau - par[i, COL_STUCK_AT], i, par)
            phi[i] = min(f - lo, hi - f)
        else:
            phi[i] = y[nb + i] * m
    for j in range(nb - 1):
        r = nb + j
        phi[r] = 1.0
        if par[r, 0] < LINK_BACKLASH:
            continue
        dp, dm, gp, gm = _contact_gaps(y, nb, j, par, r)
        if modes[r] == 0:
            phi[r] = -max(gp, gm)
        elif modes[r] > 0:
            phi[r] = gp
        else:
            phi[r] = gm


@njit(cache=True, inline="always")
def _step(tau, y, s, nb, modes, par, inp, hist, fs_in, h, x0b, v0b, work, k1, k2, k3, k4, ys,
          out, phi, any_stuck):
    """One RK4 step of size ``s`` in fixed modes from ``y``; then the event functions at its end.

    ``k1`` is the derivative at ``y``, computed once per start point and reused by every
    trial step of the event search; the forces at the end are needed only when a body is
    stuck (no other event function reads them).

    Inlined into :func:`_integrate` at its one call site, and the three later stages run as a
    loop over one inlined :func:`_deriv`: every inlined copy multiplies numba's compile time
    (17 copies of the force evaluation took ~90 s to compile; the loop costs nothing per step).
    The end forces as a fourth pass of that loop compiled 3 s faster but cost one-body runs
    ~20 % a step, so they keep their own copy.
    """
    ny = y.shape[0]
    for stage in range(3):
        c = s if stage == 2 else 0.5 * s
        src = k1 if stage == 0 else (k2 if stage == 1 else k3)
        dst = k2 if stage == 0 else (k3 if stage == 1 else k4)
        for i in range(ny):
            ys[i] = y[i] + c * src[i]
        _deriv(tau + c, ys, nb, modes, par, inp, hist, fs_in, h, x0b, v0b, work, dst)
    for i in range(ny):
        out[i] = y[i] + s / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i])
    # stuck and locked bodies keep their position exactly
    for i in range(nb):
        if modes[i] == LOCKED or modes[i] == STUCK:
            out[i] = y[i]
            out[nb + i] = 0.0
    if any_stuck:
        _forces(tau + s, out, nb, modes, par, inp, hist, fs_in, h, x0b, v0b, work)
    _validity(tau + s, out, nb, modes, par, work, phi)


@njit(cache=True, **_HOT_LOOP)
def _forces_and_validity(tau, y, nb, modes, par, inp, hist, fs_in, h, x0b, v0b, work, phi):
    """Compute the forces at ``y`` into ``work``, and the event functions (unless phi is empty).

    Not inlined: called only at the start of a run and around events (the cold paths).
    """
    _forces(tau, y, nb, modes, par, inp, hist, fs_in, h, x0b, v0b, work)
    if phi.shape[0] > 0:
        _validity(tau, y, nb, modes, par, work, phi)


@njit(cache=True, **_HOT_LOOP)
def _next_node_kink(hist, scan, step, h, delay):
    """Time of the kink of the next event node at grid step >= ``scan`` (and < ``step``).

    Returns (time [s], the grid step to scan from next); nodes come in time order.
    """
    while scan < step:
        f = hist[3, scan]
        scan += 1
        if f > EVENT:
            return (scan - 1) * h + hist[0, int(f)] + delay, scan
    return math.inf, scan


@njit(cache=True, inline="always")
def _stride_error(k1, k4, nb, s, rtol, pos_scale, vel_scale):
    """Error estimate of the last RK4 step of size ``s`` over its tolerance (> 1: too large).

    The embedded third-order solution ``y + s (k1/6 + k2/3 + k3/3 + k5/6)``, with k5 the
    derivative at the step's end (the next step's first stage, so free), differs from RK4 by
    ``s (k4 - k5)/6``. The tolerance is ``rtol`` times the largest position (velocity)
    magnitude of any body so far; the energy integrals are not checked.
    """
    r = 0.0
    for i in range(2 * nb):
        d = abs(k4[i] - k1[i]) * s / 6.0
        if d > 0.0:
            tol = rtol * (pos_scale if i < nb else vel_scale)
            r = max(r, d / tol) if tol > 0.0 else math.inf
    return r


@njit(cache=True, inline="always")
def _before_kink(hist, k0, m, d_grid):
    """Longest stride from grid point k0, at most m steps, whose delayed reads meet no kink.

    An event in grid step j makes the delayed feedback kink in steps j + d_grid .. j + 1 +
    d_grid; RK4 across a kink loses its order (error ~ step² times the jump), so a stride
    ends before it and the step holding it is one grid step, as without strides.
    """
    first = max(int(math.floor(k0 - d_grid)) - 1, 0)
    last = min(int(math.ceil(k0 + m - d_grid)), k0)
    for j in range(first, last + 1):
        if hist[3, j] != 0.0 and j + 1 + d_grid > k0:
            return max(1, min(m, int(math.floor(j + d_grid - k0))))
    return m


@njit(cache=True, **_HOT_LOOP)
def _fill_history(hist, k0, m, h, x0, v0, a0, x1, v1, a1):
    """Feedback history at the grid points inside an accepted stride of m steps from k0.

    Cubic Hermite of the stride's ends (position from x, v; velocity from v, a; acceleration
    its derivative): the same interpolant a delayed read across the stride would use.
    """
    big = m * h
    if x0 == x1 and v0 == 0.0 and v1 == 0.0 and a0 == 0.0 and a1 == 0.0:  # stuck: at rest
        for j in range(1, m):
            hist[0, k0 + j] = x0
            hist[1, k0 + j] = 0.0
            hist[2, k0 + j] = 0.0
        return
    for j in range(1, m):
        s = j / m
        s2 = s * s
        h00, h10, h01, h11 = _hermite(s, big)
        hist[0, k0 + j] = h00 * x0 + h10 * v0 + h01 * x1 + h11 * v1
        hist[1, k0 + j] = h00 * v0 + h10 * a0 + h01 * v1 + h11 * a1
        hist[2, k0 + j] = ((6 * s2 - 6 * s) * v0 + (3 * s2 - 4 * s + 1) * big * a0
                           + (6 * s - 6 * s2) * v1 + (3 * s2 - 2 * s) * big * a1) / big


@njit(cache=True, inline="always")
def _any_stuck(modes, nb):
    for i in range(nb):
        if modes[i] == STUCK:
            return True
    return False


@njit(cache=True, inline="always")
def _next_event(phi, after):
    """Index of the first event function below zero after index ``after`` (-1: none)."""
    for e in range(after + 1, phi.shape[0]):
        if phi[e] < 0.0:
            return e
    return -1


@njit(cache=True, **_HOT_LOOP)
def _impulse(y, nb, j, modes, par, side, pen, counts, energy_jump):
    """Newton impact on link j: relative velocity -> -e·(relative velocity), momentum kept.

    A locked body has infinite inertia. The (round-off sized) penetration ``pen`` is undone
    about the centre of mass so the link leaves the impact exactly at its gap edge.
    energy_jump[1] accumulates the loss ``½ μ (1 - e²) v_rel²``.
    """
    e = par[nb + j, 6]
    vrel = y[nb + j] - y[nb + j + 1]
    lock1 = modes[j] == LOCKED
    lock2 = modes[j + 1] == LOCKED
    if lock1:
        w1, w2, mu = 0.0, 1.0, par[j + 1, 0]
    elif lock2:
        w1, w2, mu = 1.0, 0.0, par[j, 0]
    else:
        msum = par[j, 0] + par[j + 1, 0]
        w1, w2, mu = par[j + 1, 0] / msum, par[j, 0] / msum, par[j, 0] * par[j + 1, 0] / msum
    y[nb + j] -= (1.0 + e) * w1 * vrel
    y[nb + j + 1] += (1.0 + e) * w2 * vrel
    y[j] -= side * pen * w1
    y[j + 1] += side * pen * w2
    energy_jump[1] += 0.5 * mu * (1.0 - e * e) * vrel * vrel
    for i in (j, j + 1):
        if modes[i] != LOCKED and modes[i] != FREE and y[nb + i] != 0.0:
            new = 1 if y[nb + i] > 0.0 else -1
            if new != modes[i]:
                counts[0] += 1
            modes[i] = new


@njit(cache=True, inline="always")
def _beyond_slip_edge(f, i, m, par):
    """Tell whether force f exceeds body i's slip friction at v = 0+ in direction m."""
    k = par[i, 5] + m * par[i, 4]
    edge = k + par[i, COL_RISE] * ((par[i, 7] if m > 0 else par[i, 6]) - k)
    return (f - edge) * m > 0.0


@njit(cache=True, **_HOT_LOOP)
def _resolve(tau, y, nb, modes, par, work, counts, energy_jump):
    """Switch every mode whose event function is negative (or a body at v = 0).

    ``work`` holds the forces at ``y`` (time ``tau``). A body that sticks records the time
    and one that breaks away the rising fraction of its static band (dwell, Eq. 2.6).
    counts = [mode switches, impacts]; energy_jump[0] accumulates the contact energy lost
    when a no-tension contact opens with residual penetration,
    energy_jump[1] the loss of restitution impacts.
    """
    for i in range(nb):
        m = modes[i]
        if m == LOCKED or m == FREE:
            continue
        f = work[i]
        if m == STUCK:
            lo, hi, rise = _band(tau - par[i, COL_STUCK_AT], i, par)
            if f > hi or f < lo:
                modes[i] = 1 if f > hi else -1
                par[i, COL_RISE] = rise
                counts[0] += 1
        elif y[nb + i] * m <= 0.0:
            y[nb + i] = 0.0
            lo, hi, rise = _band(0.0, i, par)  # no dwell yet
            if lo <= f <= hi:
                new = STUCK
                par[i, COL_STUCK_AT] = tau
            elif f > 0.5 * (lo + hi):
                new = 1
            else:
                new = -1
            if new != STUCK and (new != m or not _beyond_slip_edge(f, i, new, par)):
                # a re-slip without dwell starts from the zero-dwell excess (Eq. 2.9); a
                # body that has just broken away (v = 0, force past its risen edge) keeps
                # the excess it broke away with
                par[i, COL_RISE] = rise
            if new != m:
                counts[0] += 1
            modes[i] = new
    for j in range(nb - 1):
        r = nb + j
        if par[r, 0] < LINK_BACKLASH:
            continue
        dp, dm, gp, gm = _contact_gaps(y, nb, j, par, r)
        m = modes[r]
        if m == 0:
            side = 1 if gp > 0.0 else (-1 if gm > 0.0 else 0)
            if side == 0:
                continue
            approach = side * (y[nb + j] - y[nb + j + 1])
            if par[r, 0] == LINK_IMPACT and approach > par[r, 7]:
                _impulse(y, nb, j, modes, par, side, dp if side > 0 else dm, counts,
                         energy_jump)
                if side * (y[nb + j] - y[nb + j + 1]) >= -par[r, 7]:
                    modes[r] = side  # (nearly) plastic: resting contact at once
            elif (par[r, 0] == LINK_IMPACT and approach < -par[r, 7]
                  and (dp if side > 0 else dm) <= 1e-12):
                continue  # separating at the gap edge after an impulse: stays open
            else:
                modes[r] = side  # slow approach: resting (compliant) contact
            counts[1] += 1
        elif (m > 0 and gp <= 0.0) or (m < 0 and gm <= 0.0):
            d = dp if m > 0 else dm
            if d > 0.0:
                energy_jump[0] += 0.5 * par[r, 1] * d * d
            modes[r] = 0


@njit(cache=True, nogil=True)
def drive_kernel(y0, modes0, par, inp, abort_limit, fs_in, n_out, n_sub, max_events,
                 resume, jump0, rtol, max_stride):
    """Integrate the chain; see :func:`driveid.sim.drive.simulate_drive`.

    ``y0``: positions, velocities, then the three energy integrals (zeros at the start), or
    positions and velocities alone (length 2 nb): the run then skips the energy bookkeeping,
    about a sixth of a step, and leaves energy_out rows 0-2 NaN. ``modes0``: per body
    LOCKED, FREE or 1, then 0 per link; with ``resume`` the modes of a previous call (bodies
    keep STUCK, contacts their side) and ``jump0`` its release and impact losses, so a run
    can continue interval by interval. Returns (x_out, v_out, cmd_out, energy_out, counts,
    status, abort_index, abort_value, modes) where energy_out rows are input work,
    dissipation (bodies, shafts), contact work, contact release loss, energy stored in
    closed contacts, restitution impact loss. ``rtol`` > 0 lets the integrator stride over
    up to ``max_stride`` grid steps at once where its error estimate allows (see
    :func:`_integrate`); 0 takes every grid step.
    """
    nb = (modes0.shape[0] + 1) // 2
    nl = nb - 1
    fbr = nb + nl
    ny = y0.shape[0]
    n_steps = (n_out - 1) * n_sub
    y = y0.copy()
    modes = modes0.copy()
    work = np.zeros(nb + nl)
    k1 = np.zeros(ny)
    k2 = np.zeros(ny)
    k3 = np.zeros(ny)
    k4 = np.zeros(ny)
    ys = np.zeros(ny)
    ytry = np.zeros(ny)
    yend = np.zeros(ny)
    ysave = np.zeros(ny)
    k1save = np.zeros(ny)
    phi0 = np.zeros(nb + nl)
    phiy = np.zeros(nb + nl)
    phi1 = np.zeros(nb + nl)
    counts = np.zeros(2, dtype=np.int64)
    jump = jump0.copy()
    x_out = np.full((nb, n_out), np.nan)
    v_out = np.full((nb, n_out), np.nan)
    cmd_out = np.full(n_out, np.nan)
    e_out = np.full((6, n_out), np.nan)
    has_fb = par[fbr, 0] != 0.0
    fbb = int(par[fbr, 1]) if has_fb else 0
    h = 1.0 / (fs_in * n_sub)
    ring = _ring(par[fbr, 4], h) if has_fb and par[fbr, 4] > 0.0 else 0
    n_fb = (n_steps + 2 if has_fb else 2) + 2 * ring
    # velocity rings of the bodies with frictional memory after the feedback's columns;
    # the history before t = 0 is the initial velocity (a resumed call starts it afresh)
    n_mem = _memory_rings(par, nb, h, n_fb)
    hist = np.zeros((4, n_fb + n_mem))
    for i in range(nb):
        if par[i, COL_MEMORY] > 0.0:
            hist[0, int(par[i, COL_RING])] = y[nb + i]
    status, abort_index, abort_value = _integrate(
        y, modes, par, inp, abort_limit, fs_in, n_sub, max_events, resume, n_steps, rtol,
        max_stride, work, k1, k2, k3, k4, ys, ytry, yend, ysave, k1save, phi0, phiy, phi1,
        counts, jump, x_out, v_out, cmd_out, e_out, hist, y0[fbb], y0[nb + fbb])
    return x_out, v_out, cmd_out, e_out, counts, status, abort_index, abort_value, modes


@njit(cache=True, **_HOT_LOOP)
def _integrate(y, modes, par, inp, abort_limit, fs_in, n_sub, max_events, resume, n_steps,
               rtol, max_stride, work, k1, k2, k3, k4, ys, ytry, yend, ysave, k1save, phi0,
               phiy, phi1, counts, jump, x_out, v_out, cmd_out, e_out, hist, x0b, v0b):
    """Run the time loop of :func:`drive_kernel` on its preallocated arrays.

    Compiled without reference counting (``_nrt=False``: it allocates nothing). The hot
    helpers are inlined, each at one call site (compile time grows with every inlined copy):
    one derivative at each start point, and one RK4 step that serves the full step, every
    trial of the event search and the step to the event, as phases of one loop.
    Returns (status, abort_index, abort_value).
    """
    nb = (modes.shape[0] + 1) // 2
    nl = nb - 1
    fbr = nb + nl
    ny = y.shape[0]
    h = 1.0 / (fs_in * n_sub)
    has_fb = par[fbr, 0] != 0.0
    fbb = int(par[fbr, 1]) if has_fb else 0
    no_phi = phiy[:0]
    status = OK
    abort_index = -1
    abort_value = 0.0
    # initial modes: bodies at rest stick or break away, contacts already closed; friction
    # state: a body at rest sticks from t = 0, one moving has its full static excess
    if not resume:
        for i in range(nb):
            par[i, COL_STUCK_AT] = 0.0
            par[i, COL_RISE] = 1.0
            if modes[i] != LOCKED and modes[i] != FREE:
                modes[i] = -1 if y[nb + i] < 0 else 1
    for _ in range(3):
        _forces_and_validity(0.0, y, nb, modes, par, inp, hist, fs_in, h, x0b, v0b, work,
                             no_phi)
        _resolve(0.0, y, nb, modes, par, work, counts, jump)
    if not resume:
        counts[0] = 0
        counts[1] = 0
    # strides (rtol > 0): up to an output interval, and short of the delay so that every
    # delayed read during a stride falls on history nodes already written
    max_stride = min(max_stride, n_sub)
    if has_fb and par[fbr, 4] > 0.0:
        max_stride = min(max_stride, int(math.ceil(par[fbr, 4] / h - 1e-9)) - 1)
    # frictional memory takes every grid step: its history holds the grid points
    memory = False
    for i in range(nb):
        memory = memory or par[i, COL_MEMORY] > 0.0
    adaptive = rtol > 0.0 and max_stride > 1 and not memory
    pos_scale = 0.0
    vel_scale = 0.0
    m = np.int64(1)  # grid steps in the step being taken
    m_pref = 1
    clean = False  # the step just taken was one RK4 step without events: its estimate holds
    step0 = np.int64(0)
    step = np.int64(0)
    d_grid = par[fbr, 4] / h if has_fb else 0.0  # the delay in grid steps
    delayed = has_fb and par[fbr, 4] > 0.0
    ring = _ring(par[fbr, 4], h) if delayed else 0
    n_grid = n_steps + 2 if has_fb else 2
    if has_fb:
        hist[3, 0] = EVENT  # the delayed read leaves the initial state: a kink
    pending_node = -1  # an event node's column still waiting for its acceleration after
    # the next kink of the delayed feedback: one delay after each event node (and at the
    # delay itself, where the read leaves the initial state); RK4 across a kink in its input
    # loses its order, so a step ends there. Nodes come in time order: a scan of the grid
    # flags up to the current step finds them in turn.
    kink_next = par[fbr, 4] if delayed else math.inf
    kink_scan = np.int64(0)
    nodes_made = 0
    kinks_found = 0
    while True:
        t = step * h
        if has_fb:
            hist[0, step] = y[fbb]
            hist[1, step] = y[nb + fbb]
        # advance from grid point `step` by m grid steps, splitting at every event
        tau = t
        remaining = h
        n_ev = 0
        grid_point = True
        while True:
            # the derivative at (tau, y) in the current modes: the first RK4 stage of every
            # trial step from here, and at a grid point the feedback's acceleration history
            cmd = _deriv(tau, y, nb, modes, par, inp, hist, fs_in, h, x0b, v0b, work, k1)
            if pending_node >= 0:
                hist[1, pending_node + 1] = k1[nb + fbb]
                pending_node = -1
            if grid_point:
                grid_point = False
                rolled_back = False
                if adaptive:
                    for i in range(nb):
                        pos_scale = max(pos_scale, abs(y[i]))
                        vel_scale = max(vel_scale, abs(y[nb + i]))
                    r = _stride_error(k1, k4, nb, m * h, rtol, pos_scale, vel_scale) if clean \
                        else math.inf
                    if m > 1 and r > 1.0:
                        # the stride missed its tolerance: take it again in grid steps
                        rolled_back = True
                        step = step0
                        t = step * h
                        tau = t
                        for i in range(ny):
                            y[i] = ysave[i]
                            k1[i] = k1save[i]
                        m_pref = 1
                        kink_scan = min(kink_scan, step)  # retaken steps may add nodes
                    else:
                        if m > 1 and has_fb:
                            _fill_history(hist, step0, m, h, ysave[fbb], ysave[nb + fbb],
                                          k1save[nb + fbb], y[fbb], y[nb + fbb], k1[nb + fbb])
                        # the estimate grows as the 4th power of the step: double while
                        # 16 r stays below 1/2, halve above 1/2
                        if r * 32.0 <= 1.0:
                            m_pref = 2 * m
                        elif r * 2.0 > 1.0:
                            m_pref = max(1, m // 2)
                        else:
                            m_pref = m
                if not rolled_back:
                    if memory:
                        _record_velocities(hist, par, nb, step, y, k1)
                    if has_fb:
                        hist[2, step] = k1[nb + fbb]
                        xd, vd = _delayed(t, par[fbr, 4], h, hist, x0b, v0b, y[fbb],
                                          y[nb + fbb])
                        raw = (par[fbr, 2] * (_interp(inp, nb, t, fs_in) - xd)
                               - par[fbr, 3] * vd)
                        if abs(raw) > abort_limit:
                            status = ABORTED
                            abort_index = step
                            abort_value = raw
                            break
                    else:
                        cmd = 0.0
                    if step % n_sub == 0:
                        _store(step // n_sub, y, nb, modes, par, cmd, jump, x_out, v_out,
                               cmd_out, e_out)
                    if step == n_steps:
                        break
                m = 1
                if adaptive:
                    m = min(m_pref, max_stride, n_sub - step % n_sub, n_steps - step)
                    if has_fb and m > 1:
                        m = _before_kink(hist, step, m, d_grid)
                    if m > 1:
                        step0 = step
                        for i in range(ny):
                            ysave[i] = y[i]
                            k1save[i] = k1[i]
                remaining = m * h
                clean = False
            stuck = _any_stuck(modes, nb)
            # the step ends at the next kink of the delayed feedback, if one comes first
            s_lim = remaining
            if delayed:
                if kink_next <= tau + 1e-9 * h:
                    kink_next = math.inf
                if kink_next == math.inf and kinks_found < nodes_made:
                    # a separate function: a loop here slowed every step by 40 % (codegen)
                    kink_next, kink_scan = _next_node_kink(hist, kink_scan, step, h,
                                                           par[fbr, 4])
                    if kink_next < math.inf:
                        kinks_found += 1
                if tau + 1e-9 * h < kink_next < tau + remaining - 1e-9 * h:
                    s_lim = kink_next - tau
            # phases: the full step; an Illinois secant on the step length for each
            # event function that went negative; the step to just past the earliest one
            full = True
            final = False
            s = s_lim
            e = -1
            first = -1
            s_first = s_lim
            lo = hi = flo = fhi = 0.0
            side = 0
            it = 0
            while True:
                out = yend if full else ytry
                phi = phi1 if full else phi0
                _step(tau, y, s, nb, modes, par, inp, hist, fs_in, h, x0b, v0b, work,
                      k1, k2, k3, k4, ys, out, phi, stuck)
                if final:
                    break
                if full:
                    e = _next_event(phi1, -1)
                    if e < 0:
                        break
                    if m > 1:  # a stride meets an event: one grid step, located as usual
                        m = 1  # (strides end before kinks, so this step holds none)
                        remaining = s_lim = s = s_first = h
                        continue
                    full = False
                    _forces_and_validity(tau, y, nb, modes, par, inp, hist, fs_in, h, x0b,
                                         v0b, work, phiy)
                else:
                    fm = phi0[e]
                    if fm < 0.0:
                        hi = s
                        fhi = fm
                        if side == -1:
                            flo *= 0.5
                        side = -1
                    else:
                        lo = s
                        flo = fm
                        if side == 1:
                            fhi *= 0.5
                        side = 1
                    it += 1
                    # no early exit on fm == 0: the switch needs a point past the root
                    if not (hi - lo <= 1e-15 * h or it >= 100):
                        s = (lo * (-fhi) + hi * flo) / (flo - fhi) if flo - fhi > 0.0 else lo
                        if not (lo < s < hi):
                            s = 0.5 * (lo + hi)
                        continue
                    if first < 0 or hi < s_first:
                        s_first = hi
                        first = e
                    e = _next_event(phi1, e)
                    if e < 0:
                        final = True
                        s = s_first
                        continue
                # bracket the zero of event function e on [0, s_lim]
                lo = 0.0
                hi = s_lim
                flo = max(phiy[e], 0.0)
                fhi = phi1[e]
                side = 0
                it = 0
                s = (lo * (-fhi) + hi * flo) / (flo - fhi) if flo - fhi > 0.0 else lo
                if not (lo < s < hi):
                    s = 0.5 * (lo + hi)
            if first < 0:
                for i in range(ny):
                    y[i] = yend[i]
                if s_lim < remaining:  # at a kink: go on from it
                    tau += s_lim
                    remaining -= s_lim
                    continue
                clean = n_ev == 0 and s_lim == m * h
                break
            # switch modes just past the event
            for i in range(ny):
                y[i] = ytry[i]
            tau += s_first
            remaining -= s_first
            if first < nb and modes[first] != STUCK:
                y[nb + first] = 0.0
            if delayed and hist[3, step] <= EVENT and 1e-6 * h < tau - t < h - 1e-6 * h:
                # the first event of this grid step becomes a node of the delay history:
                # offset, position, velocity and acceleration before the switch, then after
                # (not within 1e-6 h of a grid point: a piece that short would extrapolate
                # the reads that round-off puts on its wrong side)
                pending_node = n_grid + 2 * (step % ring)
                hist[0, pending_node] = tau - t
                hist[1, pending_node] = y[fbb]
                hist[2, pending_node] = y[nb + fbb]
            for _r in range(3):
                _forces_and_validity(tau, y, nb, modes, par, inp, hist, fs_in, h, x0b, v0b,
                                     work, no_phi)
                if _r == 0 and pending_node >= 0:  # the acceleration before the switch
                    hist[3, pending_node] = _acceleration(tau, y, nb, fbb, modes, par, work,
                                                                    hist, h)
                _resolve(tau, y, nb, modes, par, work, counts, jump)
            n_ev += 1
            if pending_node >= 0:
                hist[0, pending_node + 1] = y[nb + fbb]  # velocity after (impacts change it)
                hist[3, step] = pending_node
                nodes_made += 1
            elif has_fb and hist[3, step] == 0.0:
                hist[3, step] = EVENT  # the delayed feedback will have a kink here
            if n_ev > max_events:
                status = TOO_MANY_EVENTS
                abort_index = step
                break
            if remaining <= 1e-15 * h:
                break
        if status != OK or step == n_steps:
            break
        step += m
    # a resumed call starts its clock at 0 again: the stick times move with it
    for i in range(nb):
        par[i, COL_STUCK_AT] -= step * h
    return status, abort_index, abort_value


@njit(cache=True, **_HOT_LOOP)
def _store(o, y, nb, modes, par, cmd, jump, x_out, v_out, cmd_out, e_out):
    """Store output sample ``o``: positions, velocities, command and the energy rows."""
    for i in range(nb):
        x_out[i, o] = y[i]
        v_out[i, o] = y[nb + i]
    cmd_out[o] = cmd
    if y.shape[0] > 2 * nb:
        e_out[0, o] = y[2 * nb]
        e_out[1, o] = y[2 * nb + 1]
        e_out[2, o] = y[2 * nb + 2]
    e_out[3, o] = jump[0]
    stored = 0.0
    for j in range(nb - 1):
        r = nb + j
        if par[r, 0] >= LINK_BACKLASH and modes[r] != 0:
            rel = y[j] - y[j + 1]
            d = rel - par[r, 3] if modes[r] > 0 else -par[r, 4] - rel
            stored += 0.5 * par[r, 1] * d * d
    e_out[4, o] = stored
    e_out[5, o] = jump[1]
