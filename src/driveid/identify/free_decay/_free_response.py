r"""The exact piecewise free response and its analytic Jacobian, for whole-record fits.

Used by :mod:`driveid.identify.free_decay.output_error` (the fit) and :mod:`driveid.identify.crlb`
(the Fisher information). ``identify`` never imports ``sim``: this is the same closed form as
:func:`driveid.sim.simulate_free_decay` for a release from rest, written for derivatives.

Model (de Marchi 1998, Eqs. 2.139-2.143, 2.156, 2.168)
-----------------------------------------------------
Before the release time ``t_r`` the body is held at ``x_r``. Half cycle ``k = 1..N`` runs
in direction ``s_k = s_1·(-1)^(k-1)`` (``s_1 = -sgn(x_r + θk_delta)``, the side the spring
pulls to) from rest at ``(T_{k-1}, x_{k-1})`` about ``e_k = -(s_k θk_mean + θk_delta)``:

.. math::

    x(t) = e_k + (x_{k-1} - e_k)\, g(τ),\quad
    g(τ) = e^{-στ}\big[\cos ω_d τ + (σ/ω_d)\sin ω_d τ\big],\quad τ = t - T_{k-1},

with ``σ = ζ_s ω0``, ``ω_d = ω0 sqrt(1 - ζ_s²)``. It ends at the velocity zero
``T_k = T_{k-1} + π/ω_d`` and ``x_k = e_k - ρ_s (x_{k-1} - e_k)``, ``ρ_s = e^{-πσ/ω_d}``.
After ``N`` half cycles the body is stuck at ``x_N``. A record that starts mid-swing is
the same model with ``t_r`` before the first sample (the previous velocity zero): a
one-to-one reparametrisation of the position and velocity at the first sample.

Derivatives are propagated forward through the recursion (``dX``, ``dT`` carry
``∂x_{k-1}/∂q`` and ``∂T_{k-1}/∂q``), so the Jacobian is exact to round-off.

:func:`second_mode` is the term the ``+ second mode`` structure adds
(:mod:`driveid.identify.free_decay._free_decay_structures`): a damped oscillation released
with the first, ``e^{-σ₂τ}(a cos ω₂τ + b sin ω₂τ)``, with its derivatives.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["GLOBAL_NAMES", "first_direction", "kinetic_stop_count", "response", "second_mode"]

#: Order of the shared unknowns; each record adds ``x_r``, ``t_r`` (and a drift slope).
GLOBAL_NAMES = ("omega0", "zeta_plus", "zeta_minus", "theta_k_mean", "theta_k_delta")


def first_direction(x_r: float, theta_k_delta: float) -> int:
    """Direction of the first half cycle after a release from rest at ``x_r`` [-].

    Parameters
    ----------
    x_r : float
        Release position [m or rad].
    theta_k_delta : float
        ``fk_delta/K`` [m or rad].

    Returns
    -------
    int
        +1 or -1: the spring force ``-K x_r`` against the friction offset.
    """
    return 1 if x_r + theta_k_delta < 0 else -1


def kinetic_stop_count(glob, x_r: float, t_r: float, t_end: float,
                       max_half_cycles: int = 100_000, *,
                       zeta_amp: float = 0.0) -> tuple[int, bool]:
    """Half cycles until a reversal falls inside the kinetic band, or until ``t_end``.

    Parameters
    ----------
    glob : sequence of float
        ``(omega0 [rad/s], zeta_plus, zeta_minus [-], theta_k_mean, theta_k_delta [m or rad])``.
    x_r, t_r : float
        Release position [m or rad] and time [s].
    t_end : float
        Last sample time [s].
    max_half_cycles : int
        Safety bound [-].
    zeta_amp : float
        Amplitude-dependent damping ``q`` [1/(m or rad)] as in :func:`response`.

    Returns
    -------
    n : int
        Largest number of half cycles the kinetic friction allows (static friction can
        only stop the body earlier, thesis 2.137-2.138) [-].
    inside : bool
        True if the stop happens before ``t_end`` (the count matters), False if the record
        ends while the body still moves.
    """
    omega0, zp, zm, tkm, tkd = (float(v) for v in glob)
    x, t, s = x_r, t_r, first_direction(x_r, tkd)
    for k in range(1, max_half_cycles + 1):
        zeta = zp if s > 0 else zm
        e = -(s * tkm + tkd)
        if zeta_amp:
            zeta = min(max(zeta + zeta_amp * abs(x - e), 0.0), 0.999)
        wd = omega0 * math.sqrt(1.0 - zeta * zeta)
        x = e - math.exp(-math.pi * zeta / math.sqrt(1.0 - zeta * zeta)) * (x - e)
        t += math.pi / wd
        if abs(x + tkd) <= tkm:
            return k, t < t_end
        if t >= t_end:
            return k, False
        s = -s
    return max_half_cycles, False


#: Most Jacobian rows handed to a ``sink`` at once (a 7-column block: 7 MB).
SINK_ROWS = 1 << 17


def response(t: np.ndarray, glob, x_r: float, t_r: float, n_half: int, *,
             jacobian: bool = True, sink=None, zeta_amp: float = 0.0):
    """Exact free response sampled at ``t`` and its Jacobian.

    Parameters
    ----------
    t : ndarray, shape (n,)
        Increasing sample times [s].
    glob : sequence of float
        ``(omega0 [rad/s], zeta_plus, zeta_minus [-], theta_k_mean, theta_k_delta
        [m or rad])``; |ζ| < 1.
    x_r, t_r : float
        Release position [m or rad] and time [s] (at rest).
    n_half : int
        Half cycles before the body sticks [-]; >= 1.
    jacobian : bool
        Also return the derivatives.
    sink : callable, optional
        Instead of returning the Jacobian, call ``sink(lo, hi, x_rows, jac_rows)`` for
        consecutive row ranges ``[lo, hi)`` of at most :data:`SINK_ROWS` rows, with
        ``x_rows = x[lo:hi]`` (final) and ``jac_rows`` an ``(hi - lo, 7)`` array or a
        read-only broadcast view, valid only during the call. Memory is then O(SINK_ROWS) for the
        derivatives instead of 56 B a sample (issue 12: normal equations built blockwise).
    zeta_amp : float
        Amplitude-dependent damping ``q`` [1/(m or rad)]: half cycle ``k`` uses
        ``ζ_k = ζ_s + q |x_{k-1} - e_k|``, the equivalent linearisation of quadratic
        (aerodynamic) damping ``c₂|x'|x'`` (``q = 4 c₂/(3π J)``, Krylov–Bogoliubov); only
        without ``jacobian`` (the structure test differentiates numerically).

    Returns
    -------
    x : ndarray, shape (n,)
        Position [m or rad].
    jac : ndarray, shape (n, 7) or None
        ``∂x/∂(omega0, zeta_plus, zeta_minus, theta_k_mean, theta_k_delta, x_r, t_r)``;
        None without ``jacobian`` or with a ``sink``.
    reversals : ndarray, shape (m, 2)
        Time [s] and position of the release and of every velocity zero reached.
    """
    omega0, zp, zm, tkm, tkd = (float(v) for v in glob)
    n = t.size
    x = np.empty(n)
    jacobian = jacobian or sink is not None
    if zeta_amp and jacobian:
        raise ValueError("response: zeta_amp has no analytic Jacobian; pass jacobian=False")
    # with a sink the derivatives go to it block by block: no n x 7 array
    jac = np.zeros((n, 7)) if jacobian and sink is None else None

    def constant_rows(lo, hi, row):
        for a in range(lo, hi, SINK_ROWS):
            b = min(a + SINK_ROWS, hi)
            sink(a, b, x[a:b], np.broadcast_to(row, (b - a, 7)))

    X, T = float(x_r), float(t_r)
    dX = np.zeros(7)
    dX[5] = 1.0
    dT = np.zeros(7)
    dT[6] = 1.0
    i0 = int(np.searchsorted(t, T, "left"))
    x[:i0] = X  # held before the release
    if sink is not None:
        constant_rows(0, i0, dX.copy())
    elif jacobian:
        jac[:i0] = dX
    s = first_direction(X, tkd)
    reversals = [(T, X)]
    for _k in range(int(n_half)):
        zeta, iz = (zp, 1) if s > 0 else (zm, 2)
        e = -(s * tkm + tkd)
        A = X - e
        if zeta_amp:
            zeta = min(max(zeta + zeta_amp * abs(A), 0.0), 0.999)
        root = math.sqrt(1.0 - zeta * zeta)
        sigma, wd = zeta * omega0, omega0 * root
        T_end = T + math.pi / wd
        i1 = int(np.searchsorted(t, T_end, "left"))
        # one block without a sink (as before); blocks of SINK_ROWS rows with one
        for a0 in range(i0, i1, SINK_ROWS if sink is not None else max(i1 - i0, 1)):
            a1 = min(a0 + SINK_ROWS, i1) if sink is not None else i1
            tau = t[a0:a1] - T
            E = np.exp(-sigma * tau)
            C, S = np.cos(wd * tau), np.sin(wd * tau)
            g = E * (C + (sigma / wd) * S)
            x[a0:a1] = e + A * g
            if jacobian:
                d_sigma = np.zeros(7)
                d_sigma[0], d_sigma[iz] = zeta, omega0
                d_wd = np.zeros(7)
                d_wd[0], d_wd[iz] = root, -omega0 * zeta / root
                de = np.zeros(7)
                de[3], de[4] = -s, -1.0
                g_tau = -(omega0 * omega0 / wd) * E * S
                g_sigma = -tau * g + E * S / wd
                g_wd = E * (-tau * S + sigma * tau * C / wd - sigma * S / (wd * wd))
                # one (m x 5) @ (5 x 7) product instead of five outer products
                basis = np.column_stack([1.0 - g, g, A * g_sigma, A * g_wd, -A * g_tau])
                rows = basis @ np.vstack([de, dX, d_sigma, d_wd, dT])
                if sink is not None:
                    sink(a0, a1, x[a0:a1], rows)
                else:
                    jac[a0:a1] = rows
        rho = math.exp(-math.pi * zeta / root)
        if jacobian:
            de = np.zeros(7)
            de[3], de[4] = -s, -1.0
            d_rho = np.zeros(7)
            d_rho[iz] = -rho * math.pi / root**3
            d_wd = np.zeros(7)
            d_wd[0], d_wd[iz] = root, -omega0 * zeta / root
            dX = de - rho * (dX - de) - A * d_rho
            dT = dT - (math.pi / (wd * wd)) * d_wd
        X = e - rho * A
        T, i0, s = T_end, i1, -s
        reversals.append((T, X))
        if i0 >= n:
            break
    if i0 < n:  # stuck for good
        x[i0:] = X
        if sink is not None:
            constant_rows(i0, n, dX.copy())
        elif jacobian:
            jac[i0:] = dX
    return x, jac, np.array(reversals)


def second_mode(t: np.ndarray, t_r: float, omega: float, sigma: float, a: float,
                b: float) -> np.ndarray:
    """Return ``e^{-σ₂τ}(a cos ω₂τ + b sin ω₂τ)``, ``τ = t - t_r``, zero before the release.

    The second mode of a two-degree-of-freedom decay, released with the first (its own
    amplitude and phase per record).

    Parameters
    ----------
    t : ndarray, shape (n,)
        Sample times [s].
    t_r : float
        Release time [s].
    omega : float
        Damped frequency ω₂ [rad/s].
    sigma : float
        Decay rate σ₂ [1/s]; the damping ratio is ``σ₂/√(ω₂² + σ₂²)``.
    a, b : float
        Cosine and sine amplitudes at the release [m or rad].

    Returns
    -------
    ndarray, shape (n,)
        The mode's displacement [m or rad].
    """
    tau = np.asarray(t, float) - t_r
    after = tau >= 0.0
    out = np.zeros(tau.size)
    ta = tau[after]
    out[after] = np.exp(-sigma * ta) * (a * np.cos(omega * ta) + b * np.sin(omega * ta))
    return out


def _second_mode_columns(t, t_r, omega, sigma, a, b):
    """∂/∂(ω₂, σ₂, a, b, t_r) of :func:`second_mode`, shape (n, 5)."""
    tau = np.asarray(t, float) - t_r
    after = tau >= 0.0
    cols = np.zeros((tau.size, 5))
    ta = tau[after]
    e = np.exp(-sigma * ta)
    c, s = np.cos(omega * ta), np.sin(omega * ta)
    term = e * (a * c + b * s)
    slope = e * (b * c - a * s)  # ∂/∂(ωτ) of the bracket, times e
    cols[after, 0] = ta * slope
    cols[after, 1] = -ta * term
    cols[after, 2] = e * c
    cols[after, 3] = e * s
    cols[after, 4] = sigma * term - omega * slope  # -d/dτ
    return cols
