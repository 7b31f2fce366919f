"""Compiled kernels of the stiff drive path (:mod:`driveid.sim._smooth`).

Right-hand side, analytic Jacobian, contact switching and the 2-stage Radau IIA integrator
with a delay history; the packed parameter arrays are laid out by ``_pack`` in ``_smooth.py``.
"""

import math

import numpy as np
from numba import njit

from driveid.sim._kernels import _interp as _interp_inline
from driveid.sim.lugre import _solve_inplace

_A11, _A12, _A21, _A22 = 5.0 / 12.0, -1.0 / 12.0, 0.75, 0.25
_C1 = 1.0 / 3.0
_G0, _E1, _E2 = 0.5, -0.75, 0.25
_OK, _TOO_MANY_STEPS, _STEP_TOO_SMALL, _ABORTED = 0, 1, 2, 3
_MAX_NEWTON = 10
_MAX_STEPS = 50_000_000
# body parameter columns
(_J, _K, _CM, _CD, _FKD, _LG, _S0, _S1, _S2, _FC, _FS, _VS) = range(12)
_N_AUX = 5  # command, raw command, input power, friction power, contact power


@njit(cache=True)
def _interp(arr, row, tau, fs):
    """``_kernels._interp`` as one compiled function, not inlined at each call site."""
    return _interp_inline(arr, row, tau, fs)


@njit(cache=True)
def _delayed(td, hist_t, hist_y, n_hist, x0b, v0b):
    """Feedback-body position and velocity at ``td`` from the accepted-step history."""
    if td <= 0.0 or n_hist < 2:
        return x0b, v0b
    # first index with hist_t >= td (np.searchsorted's 'left'), by bisection: searchsorted
    # compiles numba's generic sort comparators, seconds of compile for one lookup
    lo = 0
    hi = n_hist
    while lo < hi:
        mid = (lo + hi) // 2
        if hist_t[mid] < td:
            lo = mid + 1
        else:
            hi = mid
    k = min(max(lo - 1, 0), n_hist - 2)
    h = hist_t[k + 1] - hist_t[k]
    s = (td - hist_t[k]) / h
    s2 = s * s
    s3 = s2 * s
    h00 = 2 * s3 - 3 * s2 + 1
    h10 = (s3 - 2 * s2 + s) * h
    h01 = -2 * s3 + 3 * s2
    h11 = (s3 - s2) * h
    x = h00 * hist_y[0, k] + h10 * hist_y[1, k] + h01 * hist_y[0, k + 1] + h11 * hist_y[1, k + 1]
    v = h00 * hist_y[1, k] + h10 * hist_y[2, k] + h01 * hist_y[1, k + 1] + h11 * hist_y[2, k + 1]
    return x, v


@njit(cache=True, inline="always")
def _contact_force(lp, rel, vrel):
    """Backlash link force (pushes body j+1 forward) in the link's mode ``lp[6]``."""
    if lp[6] > 0.0:
        return lp[1] * (rel - lp[3]) + lp[2] * vrel
    if lp[6] < 0.0:
        return lp[1] * (rel + lp[4]) + lp[2] * vrel
    return 0.0


@njit(cache=True, inline="always")
def _contact_gaps(lp, rel, vrel):
    """Contact functions (gp, gm), positive while that side must be in contact.

    With tension allowed the penetration alone; without, contact also ends where the force
    ``k d ± c d'`` reaches zero (as ``_kernels._contact_gaps`` of ``simulate_drive``).
    """
    dp = rel - lp[3]
    dm = -lp[4] - rel
    if lp[5] != 0.0:
        return dp, dm
    return min(dp, lp[1] * dp + lp[2] * vrel), min(dm, lp[1] * dm - lp[2] * vrel)


@njit(cache=True)
def _link_phi(lpar, xb, vb, phi):
    """Event functions of the links: >= 0 while each link's mode holds."""
    for j in range(lpar.shape[0]):
        phi[j] = 1.0
        if lpar[j, 0] != 2.0:
            continue
        gp, gm = _contact_gaps(lpar[j], xb[j] - xb[j + 1], vb[j] - vb[j + 1])
        m = lpar[j, 6]
        if m == 0.0:
            phi[j] = -max(gp, gm)
        elif m > 0.0:
            phi[j] = gp
        else:
            phi[j] = gm


@njit(cache=True)
def _switch_links(lpar, xb, vb, release):
    """Set every link mode from the state; returns the number of contact closures.

    ``release[0]`` accumulates the energy a no-tension contact still stores when it opens
    (lost, as in ``simulate_drive``).
    """
    closures = 0
    for j in range(lpar.shape[0]):
        if lpar[j, 0] != 2.0:
            continue
        gp, gm = _contact_gaps(lpar[j], xb[j] - xb[j + 1], vb[j] - vb[j + 1])
        m = lpar[j, 6]
        if (m > 0.0 and gp <= 0.0) or (m < 0.0 and gm <= 0.0):
            rel = xb[j] - xb[j + 1]
            d = rel - lpar[j, 3] if m > 0.0 else -lpar[j, 4] - rel
            if d > 0.0:
                release[0] += 0.5 * lpar[j, 1] * d * d
            m = 0.0
        if m == 0.0:
            if gp > 0.0:
                m = 1.0
                closures += 1
            elif gm > 0.0:
                m = -1.0
                closures += 1
        lpar[j, 6] = m
    return closures


@njit(cache=True)
def _bodies_state(y, lay, xfix, xb, vb):
    """Positions and velocities of all bodies (locked ones at their fixed position)."""
    for i in range(xb.shape[0]):
        if lay[0, i] >= 0:
            xb[i] = y[lay[0, i]]
            vb[i] = y[lay[1, i]]
        else:
            xb[i] = xfix[i]
            vb[i] = 0.0


@njit(cache=True)
def _hermite(s, h, y0, f0, y1, f1, out):
    """Cubic Hermite interpolant of a step at the fraction ``s`` of its length ``h``."""
    h00 = (1.0 + 2.0 * s) * (1.0 - s) ** 2
    h10 = s * (1.0 - s) ** 2
    h01 = s * s * (3.0 - 2.0 * s)
    h11 = s * s * (s - 1.0)
    for i in range(y0.shape[0]):
        out[i] = h00 * y0[i] + h10 * h * f0[i] + h01 * y1[i] + h11 * h * f1[i]


@njit(cache=True)
def _rhs(t, y, md, hist_t, hist_y, n_hist, x0b, v0b, sc, dy, aux):
    """State derivative ``dy`` of the dynamic states; ``aux`` gets command and powers.

    md = (lay, xfix, bpar, lpar, fpar, mpar, inp, fs_in), the model; sc = (xb, vb, force),
    scratch arrays.

    lay rows: position, velocity, bristle index per body (-1: not in the state); lay[3, 0]:
    index of the motor current (-1: none).
    """
    lay, xfix, bpar, lpar, fpar, mpar, inp, fs_in = md
    xb, vb, force = sc
    nb = bpar.shape[0]
    _bodies_state(y, lay, xfix, xb, vb)
    has_motor = mpar[0] != 0.0
    mb = int(mpar[10])
    p_in = 0.0
    for i in range(nb):
        ext = _interp(inp, i, t, fs_in)
        force[i] = -bpar[i, _K] * xb[i]
        if has_motor and i == mb:
            continue  # this row is the amplifier command, not a torque
        force[i] += ext
        p_in += ext * vb[i]
    u = 0.0
    raw = 0.0
    if fpar[0] != 0.0:
        b = int(fpar[1])
        if fpar[4] == 0.0:
            xd, vd = xb[b], vb[b]
        else:
            xd, vd = _delayed(t - fpar[4], hist_t, hist_y, n_hist, x0b, v0b)
        raw = fpar[2] * (_interp(inp, nb, t, fs_in) - xd) - fpar[3] * vd
        u = min(max(raw, -fpar[5]), fpar[5])
    act = -1
    torque = 0.0
    if has_motor:
        u += _interp(inp, mb, t, fs_in)
        act = mb
        ic = int(lay[3, 0])
        km, kemf, rm, lm, ka, wc, vlim, ilim = (mpar[2], mpar[3], mpar[4], mpar[5], mpar[6],
                                                 mpar[7], mpar[8], mpar[9])
        if mpar[1] == 0.0:  # voltage mode
            volt = min(max(ka * u, -vlim), vlim)
            if ic >= 0:
                cur = y[ic]
                di = (volt - rm * cur - kemf * vb[mb]) / lm
                if (cur >= ilim and di > 0.0) or (cur <= -ilim and di < 0.0):
                    di = 0.0  # anti-windup clamp of the current limit
                dy[ic] = di
            else:
                cur = min(max((volt - kemf * vb[mb]) / rm, -ilim), ilim)
        else:
            demand = min(max(ka * u, -ilim), ilim)
            if ic >= 0:
                cur = y[ic]
                dy[ic] = wc * (demand - cur)
            else:
                cur = demand
        torque = km * cur
    elif fpar[0] != 0.0:
        act = int(fpar[1])
        torque = u
    if act >= 0:
        force[act] += torque
        p_in += torque * vb[act]
    p_fric = 0.0
    p_contact = 0.0
    for j in range(nb - 1):
        typ = lpar[j, 0]
        if typ == 0.0:
            continue
        rel = xb[j] - xb[j + 1]
        vrel = vb[j] - vb[j + 1]
        if typ == 1.0:
            f = lpar[j, 1] * rel + lpar[j, 2] * vrel
            p_fric += lpar[j, 2] * vrel * vrel
        else:
            f = _contact_force(lpar[j], rel, vrel)
            p_contact += f * vrel
        force[j] -= f
        force[j + 1] += f
    for i in range(nb):
        if lay[0, i] < 0:
            continue
        v = vb[i]
        sg = 1.0 if v > 0.0 else (-1.0 if v < 0.0 else 0.0)
        fric = (bpar[i, _CM] + bpar[i, _CD] * sg) * v + bpar[i, _FKD]
        if bpar[i, _LG] != 0.0:
            s0 = bpar[i, _S0]
            fc = bpar[i, _FC]
            g = fc + (bpar[i, _FS] - fc) * math.exp(-((v / bpar[i, _VS]) ** 2))
            z = y[lay[2, i]]
            zd = v - s0 * abs(v) * z / g
            fric += s0 * z + bpar[i, _S1] * zd + bpar[i, _S2] * v
            dy[lay[2, i]] = zd
        p_fric += fric * v
        dy[lay[0, i]] = v
        dy[lay[1, i]] = (force[i] - fric) / bpar[i, _J]
    aux[0] = u
    aux[1] = raw
    aux[2] = p_in
    aux[3] = p_fric
    aux[4] = p_contact


@njit(cache=True)
def _add(jac, row, col, value):
    """Add to a Jacobian entry; a negative index is a state that does not exist.

    A plain call (LLVM inlines it): numba's IR inlining at its 22 call sites cost compile time.
    """
    if row >= 0 and col >= 0:
        jac[row, col] += value


@njit(cache=True)
def _jac(t, y, md, hist_t, hist_y, n_hist, x0b, v0b, sc, jac):
    """Analytic Jacobian of ``_rhs`` (same ``md``, ``sc``) at ``y`` into ``jac``.

    Kinks (``|v|``, ``sgn(v) v``, saturations) take the one-sided derivative of ``_rhs``'s
    branch; the delayed PD command depends on the history only (no state derivative).
    """
    lay, xfix, bpar, lpar, fpar, mpar, inp, fs_in = md
    xb, vb, force = sc
    n = y.shape[0]
    nb = bpar.shape[0]
    for i in range(n):
        for j in range(n):
            jac[i, j] = 0.0
    _bodies_state(y, lay, xfix, xb, vb)
    for i in range(nb):
        px, pv, pz = lay[0, i], lay[1, i], lay[2, i]
        if px < 0:
            continue
        inv_j = 1.0 / bpar[i, _J]
        jac[px, pv] = 1.0
        jac[pv, px] -= bpar[i, _K] * inv_j
        v = vb[i]
        sg = 1.0 if v > 0.0 else (-1.0 if v < 0.0 else 0.0)
        dfdv = bpar[i, _CM] + bpar[i, _CD] * sg
        if bpar[i, _LG] != 0.0:
            s0, s1, fc = bpar[i, _S0], bpar[i, _S1], bpar[i, _FC]
            fs_, vs = bpar[i, _FS], bpar[i, _VS]
            e = math.exp(-((v / vs) ** 2))
            g = fc + (fs_ - fc) * e
            dg = -2.0 * v / (vs * vs) * (fs_ - fc) * e
            z = y[pz]
            dzd_dv = 1.0 - s0 * z * (sg * g - abs(v) * dg) / (g * g)
            dzd_dz = -s0 * abs(v) / g
            dfdv += s1 * dzd_dv + bpar[i, _S2]
            jac[pv, pz] -= (s0 + s1 * dzd_dz) * inv_j
            jac[pz, pv] = dzd_dv
            jac[pz, pz] = dzd_dz
        jac[pv, pv] -= dfdv * inv_j
    for j in range(nb - 1):
        typ = lpar[j, 0]
        if typ == 0.0 or (typ == 2.0 and lpar[j, 6] == 0.0):
            continue
        k, c = lpar[j, 1], lpar[j, 2]
        for side in range(2):  # f pushes j + 1 forward, j back
            b = j + side
            sb = 2.0 * side - 1.0
            pvb = lay[1, b]
            if pvb < 0:
                continue
            w = sb / bpar[b, _J]
            _add(jac, pvb, lay[0, j], w * k)
            _add(jac, pvb, lay[0, j + 1], -w * k)
            _add(jac, pvb, lay[1, j], w * c)
            _add(jac, pvb, lay[1, j + 1], -w * c)
    # actuator: du/dx_b and du/dv_b of the PD command (instantaneous feedback only)
    dudx = 0.0
    dudv = 0.0
    fb = -1
    u = 0.0
    if fpar[0] != 0.0:
        fb = int(fpar[1])
        if fpar[4] == 0.0:
            raw = fpar[2] * (_interp(inp, nb, t, fs_in) - xb[fb]) - fpar[3] * vb[fb]
            u = min(max(raw, -fpar[5]), fpar[5])
            if abs(raw) < fpar[5]:
                dudx = -fpar[2]
                dudv = -fpar[3]
        else:
            xd, vd = _delayed(t - fpar[4], hist_t, hist_y, n_hist, x0b, v0b)
            raw = fpar[2] * (_interp(inp, nb, t, fs_in) - xd) - fpar[3] * vd
            u = min(max(raw, -fpar[5]), fpar[5])
    if mpar[0] == 0.0:
        if fb >= 0:
            w = 1.0 / bpar[fb, _J]
            _add(jac, lay[1, fb], lay[0, fb], dudx * w)
            _add(jac, lay[1, fb], lay[1, fb], dudv * w)
        return
    mb = int(mpar[10])
    u += _interp(inp, mb, t, fs_in)
    ic = int(lay[3, 0])
    km, kemf, rm, lm, ka, wc, vlim, ilim = (mpar[2], mpar[3], mpar[4], mpar[5], mpar[6],
                                             mpar[7], mpar[8], mpar[9])
    pvm = lay[1, mb]
    wm = km / bpar[mb, _J]
    pxf = lay[0, fb] if fb >= 0 else -1
    pvf = lay[1, fb] if fb >= 0 else -1
    if mpar[1] == 0.0:  # voltage mode
        dvdu = ka if abs(ka * u) < vlim else 0.0
        volt = min(max(ka * u, -vlim), vlim)
        if ic >= 0:
            cur = y[ic]
            di = (volt - rm * cur - kemf * vb[mb]) / lm
            if not ((cur >= ilim and di > 0.0) or (cur <= -ilim and di < 0.0)):
                jac[ic, ic] = -rm / lm
                _add(jac, ic, pvm, -kemf / lm)
                _add(jac, ic, pxf, dvdu * dudx / lm)
                _add(jac, ic, pvf, dvdu * dudv / lm)
            _add(jac, pvm, ic, wm)
        else:
            if abs((volt - kemf * vb[mb]) / rm) < ilim:
                _add(jac, pvm, pvm, -wm * kemf / rm)
                _add(jac, pvm, pxf, wm * dvdu * dudx / rm)
                _add(jac, pvm, pvf, wm * dvdu * dudv / rm)
    else:
        dddu = ka if abs(ka * u) < ilim else 0.0
        if ic >= 0:
            jac[ic, ic] = -wc
            _add(jac, ic, pxf, wc * dddu * dudx)
            _add(jac, ic, pvf, wc * dddu * dudv)
            _add(jac, pvm, ic, wm)
        else:
            _add(jac, pvm, pxf, wm * dddu * dudx)
            _add(jac, pvm, pvf, wm * dddu * dudv)


@njit(cache=True)
def _filtered_error(h, g, k1, f1, jac, m, err, y0, y1, atol, rtol):
    """Scaled RMS of the embedded error ``(I - h g0 J)^-1 h (g0 g + e1 k1 + e2 f1)``."""
    n = y0.shape[0]
    for i in range(n):
        err[i] = h * (_G0 * g[i] + _E1 * k1[i] + _E2 * f1[i])
        for j in range(n):
            m[i, j] = (1.0 if i == j else 0.0) - h * _G0 * jac[i, j]
    _solve_inplace(m, err, n)
    en = 0.0
    for i in range(n):
        w = atol[i] + rtol * max(abs(y0[i]), abs(y1[i]))
        en += (err[i] / w) ** 2
    return math.sqrt(en / n)


@njit(cache=True)
def _push(hist_t, hist_y, n_hist, t, y, dy, ix, iv):
    """Append (t, x, v, a) of the state entries ``ix``, ``iv`` to the delay history.

    The capacity doubles when full; entries from ``n_hist`` on are never read.
    """
    if n_hist == hist_t.shape[0]:
        nt = np.empty(2 * n_hist)
        nyy = np.empty((3, 2 * n_hist))
        # element loops: a slice assignment compiles numba's shape-error message formatting
        for i in range(n_hist):
            nt[i] = hist_t[i]
            for r in range(3):
                nyy[r, i] = hist_y[r, i]
        hist_t, hist_y = nt, nyy
    hist_t[n_hist] = t
    hist_y[0, n_hist] = y[ix]
    hist_y[1, n_hist] = y[iv]
    hist_y[2, n_hist] = dy[iv]
    return hist_t, hist_y, n_hist + 1


@njit(cache=True)
def _smooth_kernel(y_init, lay, xfix, bpar, lpar, fpar, mpar, inp, fs_in, atol, rtol, h_cap,
                   t_end, fs, n_out, max_steps):
    """Adaptive 2-stage Radau IIA on the chain; samples at ``i/fs``.

    Returns (out[n + 6, n_out] — states, command, input work, friction work, contact work,
    raw command, contact release loss —, counts[2], status, abort_time, abort_value, n_acc,
    n_rej).
    """
    n = y_init.shape[0]
    nb = bpar.shape[0]
    nl = nb - 1
    # np.empty only, filled here: np.full, np.zeros and np.ones each compile their own code
    out = np.empty((n + 6, n_out))
    for i in range(n + 6):
        for k in range(n_out):
            out[i, k] = np.nan
    release = np.empty(1)
    xb = np.empty(nb)
    vb = np.empty(nb)
    force = np.empty(nb)
    aux = np.empty(_N_AUX)
    aux_b = np.empty(_N_AUX)
    aux_c = np.empty(_N_AUX)
    y0 = y_init.copy()
    f0 = np.empty(n)
    f1 = np.empty(n)
    k1 = np.empty(n)
    fp = np.empty(n)
    tmp = np.empty(n)
    tmp2 = np.empty(n)
    y1 = np.empty(n)
    err = np.empty(n)
    j1 = np.empty((n, n))
    j2 = np.empty((n, n))
    big = np.empty((2 * n, 2 * n))
    rhs2 = np.empty(2 * n)
    zst = np.empty(2 * n)
    m1 = np.empty((n, n))
    e0 = np.empty(3)  # input, friction, contact work at the step start
    e1 = np.empty(3)
    ebuf = np.empty(3)
    p0 = np.empty(3)
    p1 = np.empty(3)
    for i in range(3):
        e0[i] = 0.0
    counts = np.empty(2, dtype=np.int64)
    counts[0] = 0
    counts[1] = 0
    has_fb = fpar[0] != 0.0
    fbb = int(fpar[1]) if has_fb else 0
    ixb = lay[0, fbb]
    ivb = lay[1, fbb]
    use_hist = has_fb and fpar[4] > 0.0  # a delayed PD reads the history
    hist_t = np.empty(1024 if use_hist else 2)
    hist_y = np.empty((3, hist_t.shape[0]))
    n_hist = np.int64(0)  # not the literal 0: that would compile the callees twice
    x0b = y0[ixb] if has_fb else 0.0
    v0b = y0[ivb] if has_fb else 0.0

    lpar = lpar.copy()  # column 6 holds the contact modes, changed at events
    md = (lay, xfix, bpar, lpar, fpar, mpar, inp, fs_in)
    sc = (xb, vb, force)
    phi = np.empty(max(nl, 1))
    t = 0.0
    _bodies_state(y0, lay, xfix, xb, vb)
    for _r in range(2):  # contacts already closed at t = 0
        _switch_links(lpar, xb, vb, release)
    release[0] = 0.0  # contacts open at t = 0 are not a loss
    _rhs(t, y0, md, hist_t, hist_y, n_hist, x0b, v0b, sc, f0, aux)
    for i in range(3):
        p0[i] = aux[2 + i]
    if use_hist:
        hist_t, hist_y, n_hist = _push(hist_t, hist_y, n_hist, 0.0, y0, f0, ixb, ivb)
    for i in range(n):
        out[i, 0] = y0[i]
    out[n, 0] = aux[0]
    out[n + 4, 0] = aux[1]
    out[n + 5, 0] = 0.0
    for i in range(3):
        out[n + 1 + i, 0] = 0.0
    vsign = np.empty(nb)
    for i in range(nb):
        vsign[i] = 1.0 if vb[i] > 0.0 else (-1.0 if vb[i] < 0.0 else 0.0)
    # loop state starts typed (np.int64, np.bool_), not as literals: type inference then
    # settles in 2 passes over the kernel instead of 4
    targeted = np.bool_(False)  # the step was shortened to end just past a contact event
    margin = 1e-12 * max(t_end, 1.0)

    newton_tol = max(10.0 * 2.2e-16 / rtol, min(0.03, math.sqrt(rtol)))
    h = min(1e-5, t_end, h_cap)
    next_out = np.int64(1)
    n_acc = np.int64(0)
    n_rej = np.int64(0)
    prev_rejected = np.bool_(False)
    first = np.bool_(True)
    h_min = 1e-14 * max(t_end, 1.0)
    while t < t_end and next_out < n_out:
        if n_acc + n_rej >= max_steps:
            return out, counts, _TOO_MANY_STEPS, t, 0.0, n_acc, n_rej
        if h < h_min:
            return out, counts, _STEP_TOO_SMALL, t, 0.0, n_acc, n_rej
        if t + h > t_end:
            h = t_end - t
        for i in range(n):
            zst[i] = _C1 * h * f0[i]
            zst[n + i] = h * f0[i]
        converged = False
        dn_prev = 0.0
        for it in range(_MAX_NEWTON):
            for i in range(n):
                tmp[i] = y0[i] + zst[i]
                tmp2[i] = y0[i] + zst[n + i]
            _rhs(t + _C1 * h, tmp, md, hist_t, hist_y, n_hist, x0b, v0b, sc, k1, aux)
            _rhs(t + h, tmp2, md, hist_t, hist_y, n_hist, x0b, v0b, sc, f1, aux)
            _jac(t + _C1 * h, tmp, md, hist_t, hist_y, n_hist, x0b, v0b, sc, j1)
            _jac(t + h, tmp2, md, hist_t, hist_y, n_hist, x0b, v0b, sc, j2)
            for i in range(n):
                rhs2[i] = -(zst[i] - h * (_A11 * k1[i] + _A12 * f1[i]))
                rhs2[n + i] = -(zst[n + i] - h * (_A21 * k1[i] + _A22 * f1[i]))
                for j in range(n):
                    eye = 1.0 if i == j else 0.0
                    big[i, j] = eye - h * _A11 * j1[i, j]
                    big[i, n + j] = -h * _A12 * j2[i, j]
                    big[n + i, j] = -h * _A21 * j1[i, j]
                    big[n + i, n + j] = eye - h * _A22 * j2[i, j]
            if not _solve_inplace(big, rhs2, 2 * n):
                break
            dn = 0.0
            for i in range(2 * n):
                zst[i] += rhs2[i]
                w = atol[i % n] + rtol * abs(y0[i % n])
                dn += (rhs2[i] / w) ** 2
            dn = math.sqrt(dn / (2 * n))
            if not math.isfinite(dn):
                break
            if it > 0 and dn > 2.0 * dn_prev:
                break
            if dn < newton_tol:
                converged = True
                break
            dn_prev = dn
        if not converged:
            h *= 0.5
            n_rej += 1
            prev_rejected = True
            continue
        for i in range(n):
            tmp[i] = y0[i] + zst[i]
            y1[i] = y0[i] + zst[n + i]
        _rhs(t + _C1 * h, tmp, md, hist_t, hist_y, n_hist, x0b, v0b, sc, k1, aux_b)
        _rhs(t + h, y1, md, hist_t, hist_y, n_hist, x0b, v0b, sc, f1, aux)
        # embedded error filtered by (I - h g0 J(y0)) for the stiff components
        _jac(t, y0, md, hist_t, hist_y, n_hist, x0b, v0b, sc, j1)
        en = _filtered_error(h, f0, k1, f1, j1, m1, err, y0, y1, atol, rtol)
        if en > 1.0 and (first or prev_rejected):
            # second filtering (Hairer & Wanner IV.8): damps the stiff part once more
            for i in range(n):
                tmp2[i] = y0[i] + err[i]
            _rhs(t, tmp2, md, hist_t, hist_y, n_hist, x0b, v0b, sc, fp, aux_c)
            en = _filtered_error(h, fp, k1, f1, j1, m1, err, y0, y1, atol, rtol)
        fac = 0.9 * (1.0 / max(en, 1e-10)) ** (1.0 / 3.0)
        if en > 1.0:
            h *= max(0.1, fac)
            n_rej += 1
            prev_rejected = True
            continue
        # contact events: the modes were fixed over the step; if one must switch inside it,
        # find the crossing on the step's Hermite interpolant and redo the step to just past
        _bodies_state(y1, lay, xfix, xb, vb)
        _link_phi(lpar, xb, vb, phi)
        violated = np.bool_(False)
        for j in range(nl):
            if phi[j] < 0.0:
                violated = True
        if violated and not targeted:
            s_hit = 1.0
            for j in range(nl):
                if phi[j] >= 0.0:
                    continue
                lo = 0.0
                hi = 1.0
                for _it in range(60):
                    mid = 0.5 * (lo + hi)
                    _hermite(mid, h, y0, f0, y1, f1, tmp2)
                    _bodies_state(tmp2, lay, xfix, xb, vb)
                    _link_phi(lpar, xb, vb, phi)
                    if phi[j] < 0.0:
                        hi = mid
                    else:
                        lo = mid
                _bodies_state(y1, lay, xfix, xb, vb)
                _link_phi(lpar, xb, vb, phi)
                s_hit = min(s_hit, hi)
            # overshoot a little: the solution's root is not exactly the interpolant's
            h_hit = s_hit * h + max(margin, 1e-6 * h)
            if h_hit < h:
                h = h_hit
                targeted = True
                continue
        targeted = False
        # accepted: Radau quadrature (weights b = A[1]) of the powers
        t1 = t + h
        for i in range(3):
            p1[i] = aux[2 + i]
            e1[i] = e0[i] + h * (_A21 * aux_b[2 + i] + _A22 * aux[2 + i])
        aborted = abs(aux[1]) > fpar[6]
        while next_out < n_out:
            ts = next_out / fs
            if ts > t1 * (1.0 + 1e-14):
                break
            s = min(max((ts - t) / h, 0.0), 1.0)
            _hermite(s, h, y0, f0, y1, f1, tmp2)
            _hermite(s, h, e0, p0, e1, p1, ebuf)
            for i in range(n):
                out[i, next_out] = tmp2[i]
            for i in range(3):
                out[n + 1 + i, next_out] = ebuf[i]
            _rhs(ts, tmp2, md, hist_t, hist_y, n_hist, x0b, v0b, sc, fp, aux_b)
            out[n, next_out] = aux_b[0]
            out[n + 4, next_out] = aux_b[1]
            out[n + 5, next_out] = release[0]  # this step's switches come after
            next_out += 1
        if aborted:
            return out, counts, _ABORTED, t1, aux[1], n_acc, n_rej
        # velocity reversals, then contact switches at the step end
        _bodies_state(y1, lay, xfix, xb, vb)
        for i in range(nb):
            sg = 1.0 if vb[i] > 0.0 else (-1.0 if vb[i] < 0.0 else 0.0)
            if sg != 0.0:
                if vsign[i] != 0.0 and sg != vsign[i]:
                    counts[0] += 1
                vsign[i] = sg
        if violated:
            counts[1] += _switch_links(lpar, xb, vb, release)
        if use_hist:
            hist_t, hist_y, n_hist = _push(hist_t, hist_y, n_hist, t1, y1, f1, ixb, ivb)
        if violated:
            # new modes: right-hand derivative at t1 (the history keeps both sides, a
            # repeated time, so that each interval is interpolated with its own mode)
            _rhs(t1, y1, md, hist_t, hist_y, n_hist, x0b, v0b, sc, f1, aux)
            for i in range(3):
                p1[i] = aux[2 + i]
            if use_hist:
                hist_t, hist_y, n_hist = _push(hist_t, hist_y, n_hist, t1, y1, f1, ixb, ivb)
        t = t1
        for i in range(n):
            y0[i] = y1[i]
            f0[i] = f1[i]
        for i in range(3):
            e0[i] = e1[i]
            p0[i] = p1[i]
        n_acc += 1
        grow = min(5.0, fac)
        if prev_rejected:
            grow = min(1.0, grow)
        h = min(h * grow, h_cap)
        prev_rejected = False
        first = False
    return out, counts, _OK, t, 0.0, n_acc, n_rej
