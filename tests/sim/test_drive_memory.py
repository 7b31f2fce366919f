"""Frictional memory (thesis Eq. 2.12) in the event-located drive kernel (issue 25 item 4).

Truth is independent of the kernel: the memoryless map of :mod:`driveid.models.friction`
(a lag of a constant is the constant), :func:`driveid.models.friction_memory.lagged_friction`
on the simulated velocity, and a stick–slip reference written here with scipy's
``solve_ivp`` by the method of steps (exact stick, breakaway in closed form, the delayed
velocity read from the dense output of the earlier steps).
"""

import bisect
import dataclasses
import functools
import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from driveid.errors import ConfigError, ParameterError
from driveid.models.friction import LorentzianParams, lorentzian_friction
from driveid.models.friction_memory import lagged_friction
from driveid.sim.drive import BodyParams, DriveParams, simulate_drive

# a forward-slipping body: kinetic 0.1, static 0.3 N·m, Stribeck velocity 0.2 rad/s
SLIP = dict(J=0.01, c_mean=0.05, fk_mean=0.1, fs_mean=0.3, stribeck="lorentzian", v_s=0.2)


def test_steady_slip_is_the_memoryless_map():
    """At constant velocity the lagged velocity is the velocity: the map balances u."""
    u = 0.25
    b = BodyParams(**SLIP, memory=0.05)
    r = simulate_drive(DriveParams(bodies=(b,)), duration=4.0, fs=200.0, torque=[u],
                       v0=[3.0])
    v = float(r.v[0, -1])
    f = lorentzian_friction(v, LorentzianParams(mu_k=0.1, mu_s=0.3, nu=0.05, v_s=0.2))
    # J v' = u - F(v(t - 0.05)) settles as exp(-t F'/J) (F'/J ~ 5/s, the lag slows it by
    # ~25 %): after 4 s the offset of the 3 rad/s start is < 1e-6 of u; a map read at the
    # wrong speed or the wrong branch is off by > 1e-2
    assert float(f) == pytest.approx(u, rel=1e-5)


def test_friction_follows_the_lagged_map_on_the_simulated_velocity():
    """A body kept sliding through a velocity sweep traces Eq. 2.12's hysteresis loop."""
    lag, fs, omega = 0.02, 20000.0, 2 * math.pi * 2.0
    lor = LorentzianParams(mu_k=0.1, mu_s=0.3, nu=0.0, v_s=0.2)
    # viscous damping above the map's steepest fall (0.65 N·m·s/rad): open loop, the
    # velocity stays near the sweep instead of drifting off to a stick
    b = BodyParams(**{**SLIP, "c_mean": 1.0}, memory=lag)
    t = np.arange(int(1.5 * fs) + 1) / fs
    target = 0.3 + 0.25 * np.sin(omega * t)  # stays above 0.05 rad/s: no stick
    u = (b.J * 0.25 * omega * np.cos(omega * t) + lorentzian_friction(target, lor)
         + b.c_mean * target)  # the memoryless feed-forward: the lag changes the motion
    r = simulate_drive(DriveParams(bodies=(b,)), duration=t[-1], fs=fs, torque=u[None],
                       v0=[0.3])
    v = r.v[0]
    assert v.min() > 0.01  # slipping throughout (the kernel would stick at v = 0)
    # friction in the simulation from the equation of motion: u - J v' - c v, with v' by
    # central differences (error dt²/6 |v'''| ~ 1e-9 rad/s² here)
    f_sim = u[1:-1] - b.J * (v[2:] - v[:-2]) * (fs / 2) - b.c_mean * v[1:-1]
    # before t = 0 the kernel's history is the initial velocity; lag_signal holds the
    # first sample: the same; the lag is 400 whole samples, so the shift is exact
    f_ref = lagged_friction(v, 1.0 / fs, lag=lag,
                            friction=functools.partial(lorentzian_friction, params=lor))
    # the lagged velocity kinks at t = lag (the history leaves the constant v0): there the
    # difference quotient of v, not the kernel, errs by dt·(jump of v'')/4 ~ 1e-5 N·m
    smooth = np.abs(t[1:-1] - lag) > 1.5 / fs
    err = np.max(np.abs(f_sim - f_ref[1:-1])[smooth])
    loop = np.max(np.abs(f_ref - lorentzian_friction(v, lor)))
    # measured 4.4e-8 N·m (the kernel's Hermite read of its grid history against the
    # samples, and the difference quotient); 1e-6 is 5e-6 of the 0.2 N·m Stribeck excess,
    # while the hysteresis (memoryless map against the lagged one) is 0.028 N·m wide
    assert loop > 0.02
    assert err < 1e-6, err


def _memory_reference(J, K, V, c, fk, fs, v_s, lag, t_eval):
    """Spring pulled at speed V (u = K V t, ground spring K), Lorentzian map with memory.

    Method of steps: each slip phase is integrated by solve_ivp (DOP853) in pieces of one
    lag from its breakaway, so the delayed velocity always comes from pieces already done
    (their dense output) or from rest (0); stick is exact and the breakaway closed-form.
    """
    starts, ends, sols = [], [], []  # slip pieces; the velocity is 0 outside them

    def v_hist(tau):
        j = bisect.bisect_right(starts, tau) - 1
        if j < 0 or tau > ends[j]:
            return 0.0
        return float(sols[j](tau)[1])

    x_out = np.full_like(t_eval, np.nan)
    t, x, stuck_since = 0.0, 0.0, 0.0
    end = t_eval[-1]
    while t < end:
        tb = min((fs / K + x) / V, end)  # K (V t - x) reaches the static level fs
        assert tb - stuck_since >= lag  # the reference's lag reads 0 from the rest
        x_out[(t_eval >= t) & (t_eval <= tb)] = x
        t, v = tb, 0.0
        while t < end:
            def rhs(tt, y):
                vd = v_hist(tt - lag)
                fric = fk + (fs - fk) / (1.0 + (vd / v_s) ** 2) + c * y[1]
                return [y[1], (K * (V * tt - y[0]) - fric) / J]

            def vzero(tt, y):
                return y[1]
            vzero.terminal, vzero.direction = True, -1
            t1 = min(t + lag, end)
            sol = solve_ivp(rhs, (t, t1), [x, v], method="DOP853", events=vzero,
                            dense_output=True, rtol=1e-12, atol=1e-14)
            t_stop = sol.t_events[0][0] if sol.t_events[0].size else t1
            starts.append(t)
            ends.append(t_stop)
            sols.append(sol.sol)
            sel = (t_eval >= t) & (t_eval <= t_stop)
            x_out[sel] = sol.sol(t_eval[sel])[0]
            x, v = (float(z) for z in sol.sol(t_stop))
            t = t_stop
            if t_stop < t1:  # velocity zero: the force is inside the band, it sticks
                assert abs(K * (V * t - x)) <= fs
                v, stuck_since = 0.0, t
                break
    return x_out


def test_stick_slip_with_memory_against_a_method_of_steps_reference():
    J, K, V, c, fk, fs, v_s, lag = 0.01, 10.0, 0.05, 0.01, 0.1, 0.3, 0.05, 0.02
    b = BodyParams(J=J, K=K, c_mean=c, fk_mean=fk, fs_mean=fs, stribeck="lorentzian",
                   v_s=v_s, memory=lag)
    rate = 1000.0
    t = np.arange(int(4.0 * rate) + 1) / rate
    drive = DriveParams(bodies=(b,))
    r = simulate_drive(drive, duration=4.0, fs=rate, torque=K * V * t[None])
    ref = _memory_reference(J, K, V, c, fk, fs, v_s, lag, t)
    assert r.n_mode_switches >= 6  # several stick-slip cycles
    err = np.max(np.abs(r.x[0] - ref))
    plain = simulate_drive(DriveParams(bodies=(dataclasses.replace(b, memory=0.0),)),
                           duration=4.0, fs=rate, torque=K * V * t[None])
    # the memory moves the motion by 0.038 rad (measured): the reference would see a kernel
    # that ignored it
    assert np.max(np.abs(plain.x[0] - ref)) > 1e-2
    # measured 6.7e-11 rad at the default step (h = 5e-4 s) on a 0.19 rad travel; 1e-9
    # leaves a factor 15 for platform round-off, while a lag one grid step off moves the
    # motion by 2e-4 rad (measured)
    assert err < 1e-9, err
    fine = simulate_drive(drive, duration=4.0, fs=rate, torque=K * V * t[None],
                          max_step=1e-4)
    err_fine = np.max(np.abs(fine.x[0] - ref))
    # a 5x finer step: measured 1.35e-12 rad, 50x less (RK4's h**4 would give 625x; the
    # lagged velocity's kinks one lag after each breakaway and stick, and the reference's
    # own rtol 1e-12, cost the rest); 10x is asked, an O(h) defect would give 5x
    assert err_fine < err / 10, (err, err_fine)


def test_vanishing_memory_tends_to_the_memoryless_run():
    """A lag far below the step reads the current velocity (linear blend to now)."""
    runs = [simulate_drive(DriveParams(bodies=(BodyParams(**SLIP, memory=lag),)), duration=1.0,
                           fs=1000.0, torque=[0.375], x0=[0.0]) for lag in (0.0, 1e-8, 1e-9)]
    d8, d9 = (np.max(np.abs(r.x - runs[0].x)) for r in runs[1:])
    # to first order the friction moves by F'(v)·v'·lag: the deviation from the memoryless
    # run is proportional to the lag (measured 7.1e-8 and 7.1e-9 rad); 10 % on the ratio
    # leaves room for round-off (1e-16 rad on ~1 rad) and the second order
    assert 0 < d9 < 1e-7
    assert d8 / d9 == pytest.approx(10.0, rel=0.1)


def test_strides_are_off_with_memory():
    """rtol asks for strides; a memory body takes every grid step (its history is on it)."""
    b = BodyParams(J=0.01, K=1.0, c_mean=0.02, fk_mean=0.05, fs_mean=0.1,
                   stribeck="lorentzian", v_s=0.1, memory=0.01)
    kw = dict(duration=1.0, x0=[0.5])
    a = simulate_drive(DriveParams(bodies=(b,)), **kw)
    s = simulate_drive(DriveParams(bodies=(b,)), rtol=1e-6, **kw)
    np.testing.assert_array_equal(a.x, s.x)


def test_memory_needs_a_stribeck_map_and_one_run():
    with pytest.raises(ParameterError, match="memory.*stribeck"):
        BodyParams(J=1.0, fk_mean=0.1, memory=0.01)
    with pytest.raises(ParameterError, match="memory must be >= 0"):
        BodyParams(**SLIP, memory=-0.01)
    with pytest.raises(ParameterError, match="memory"):
        BodyParams(**SLIP, memory=math.nan)
    with pytest.raises(ParameterError, match="controller callback"):
        simulate_drive(DriveParams(bodies=(BodyParams(**SLIP, memory=0.01),)), duration=0.1,
                       control_rate=100.0, controller=lambda t, x, v: 0.0)


def test_toml_body_takes_the_memory():
    from driveid.sim.config import parse_drive_config

    params, _ = parse_drive_config({"body": [{
        "J": 0.01, "fk_mean": 0.1, "fs_mean": 0.3, "stribeck": "lorentzian", "v_s": 0.2,
        "memory": 0.02}]})
    assert params.bodies[0].memory == 0.02
    with pytest.raises(ConfigError, match=r"body\[1\]\.memory"):
        parse_drive_config({"body": [{"J": 1.0, "fk_mean": 0.1, "memory": 0.02}]})
