import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.linalg import expm

from driveid.errors import ParameterError
from driveid.sim import OscillatorParams, measure, simulate_free_decay


def _expm_response(J, C, K, F, x0, v0, t):
    """Independent truth for a linear segment: matrix exponential of [x, v, 1]."""
    A = np.array([[0, 1, 0], [-K / J, -C / J, F / J], [0, 0, 0]], float)
    return np.array([expm(A * tk) @ [x0, v0, 1.0] for tk in t])[:, :2]


@pytest.mark.parametrize("C", [0.8, 8.0, 20.0])  # under-, critically (ζ = 1) and over-damped
def test_linear_cases_match_matrix_exponential(C):
    p = OscillatorParams(J=1.0, K=16.0, c_mean=C)
    t = np.linspace(0, 3, 301)
    sim = simulate_free_decay(p, x0=0.3, v0=-2.0, duration=3.0, t=t)
    ref = _expm_response(1.0, C, 16.0, 0.0, 0.3, -2.0, t)
    # closed form vs expm: both at round-off, 1e-12 leaves room for expm's own error
    np.testing.assert_allclose(sim.record.x, ref[:, 0], atol=1e-12)
    np.testing.assert_allclose(sim.record.v, ref[:, 1], atol=1e-11)


def test_near_critical_damping_keeps_accuracy():
    # ζ = 1 ± 1e-9: the Taylor branch of the unified kernel must agree with expm
    for C in (8.0 * (1 - 1e-9), 8.0 * (1 + 1e-9)):
        t = np.linspace(0, 2, 81)
        sim = simulate_free_decay(OscillatorParams(J=1.0, K=16.0, c_mean=C), x0=1.0,
                                  v0=0.5, duration=2.0, t=t)
        ref = _expm_response(1.0, C, 16.0, 0.0, 1.0, 0.5, t)
        np.testing.assert_allclose(sim.record.x, ref[:, 0], atol=1e-12)


def test_springless_coulomb_viscous_stops_at_closed_form_time():
    # K = 0 (thesis 2.149): J v' = -C v - fk  =>  v = 0 at t* = (J/C) ln(1 + C v0 / fk)
    J, C, fk, v0 = 2.0, 0.5, 0.2, 1.0
    sim = simulate_free_decay(OscillatorParams(J=J, K=0.0, c_mean=C, fk_mean=fk), x0=0.0,
                              v0=v0, duration=10.0)
    t_stop = J / C * math.log(1 + C * v0 / fk)
    assert sim.stuck_at == pytest.approx(t_stop, rel=1e-13)  # closed form vs closed form
    x_stop = J / C * (v0 - fk / C * math.log(1 + C * v0 / fk))
    assert sim.record.x[-1] == pytest.approx(x_stop, rel=1e-12)


def test_asymmetric_stick_slip_matches_fine_event_integration():
    p = OscillatorParams(J=1.0, K=16.0, c_mean=0.3, c_delta=0.1, fk_mean=0.07,
                         fk_delta=0.03, fs_mean=0.105, fs_delta=0.03)
    sim = simulate_free_decay(p, x0=1.0, duration=25.0)

    def rhs(t, z, s):
        return [z[1], -(p.damping(s) * z[1] + p.K * z[0] + p.kinetic(s))]

    def zero_velocity(t, z, s):
        return z[1]

    t0, z, s = 0.0, [1.0, 0.0], -1
    for k in range(1, 9):
        sol = solve_ivp(rhs, (t0, t0 + 1.0), z, args=(s,), method="DOP853", rtol=1e-13,
                        atol=1e-15, events=zero_velocity)
        te, ye = sol.t_events[0], sol.y_events[0]
        keep = te > t0 + 1e-6
        t0, z, s = te[keep][0], [ye[keep][0][0], 0.0], -s
        # DOP853 at rtol 1e-13 is the reference; 1e-9 is the bound
        assert abs(t0 - sim.reversal_t[k]) < 1e-9
        assert abs(z[0] - sim.reversal_x[k]) < 1e-9
    # true sticking: at rest the applied force lies inside the static band, and stays
    assert sim.stuck_at is not None
    x_end = sim.reversal_x[-1]
    assert abs(-p.K * x_end - p.fs_delta) <= p.fs_mean
    after = sim.record.t >= sim.stuck_at
    assert np.ptp(sim.record.x[after]) == 0.0 and np.all(sim.record.v[after] == 0.0)
    x_prev = sim.reversal_x[-2]
    assert abs(-p.K * x_prev - p.fs_delta) > p.fs_mean


def test_energy_balance_of_symmetric_coulomb_viscous_decay():
    # dissipated = Coulomb work + viscous work: integrate both along the exact trajectory
    p = OscillatorParams(J=1.0, K=16.0, c_mean=0.3, fk_mean=0.07)
    t = np.linspace(0, 10, 200_001)
    sim = simulate_free_decay(p, x0=1.0, duration=10.0, t=t)
    x, v = sim.record.x, sim.record.v
    energy = 0.5 * p.J * v**2 + 0.5 * p.K * x**2
    power = p.c_mean * v**2 + p.fk_mean * np.abs(v)
    dissipated = np.concatenate([[0], np.cumsum(0.5 * (power[1:] + power[:-1]) * np.diff(t))])
    # trapezoid at dt = 5e-5 s: error ~ (ω dt)² ≈ 4e-8 of the energy
    np.testing.assert_allclose(energy + dissipated, energy[0], rtol=1e-6)


def test_measurement_model():
    sim = simulate_free_decay(OscillatorParams(J=1.0, K=16.0, c_mean=0.3), x0=1.0,
                              duration=2.0)
    q = measure(sim.record, counts_per_rev=8000)
    quantum = 2 * math.pi / 8000
    np.testing.assert_allclose(q.x / quantum, np.round(q.x / quantum), atol=1e-9)
    assert np.max(np.abs(q.x - sim.record.x)) <= quantum / 2 + 1e-15
    noisy = measure(sim.record, noise_std=1e-3, rng=0)
    # 2001 samples: the sample std is within 5 % of the true one with overwhelming odds
    assert np.std(noisy.x - sim.record.x) == pytest.approx(1e-3, rel=0.05)
    assert q.v is None


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"J": 0.0, "K": 1.0}, "J must be positive"),
        ({"J": 1.0, "K": -1.0}, "K must be >= 0"),
        ({"J": 1.0, "K": 1.0, "fk_mean": -0.1}, "fk_mean must be >= 0"),
        ({"J": 1.0, "K": 1.0, "fk_mean": 0.2, "fs_mean": 0.1}, "static friction must hold"),
        ({"J": float("nan"), "K": 1.0}, "finite"),
    ],
)
def test_bad_parameters(kwargs, match):
    with pytest.raises(ParameterError, match=match):
        OscillatorParams(**kwargs)


def test_bad_simulation_arguments():
    p = OscillatorParams(J=1.0, K=1.0)
    with pytest.raises(ParameterError, match="duration must be positive"):
        simulate_free_decay(p, x0=1.0, duration=0.0)
    with pytest.raises(ParameterError, match="fs must be positive"):
        simulate_free_decay(p, x0=1.0, duration=1.0, fs=0.0)
    with pytest.raises(ParameterError, match="counts_per_rev must be positive"):
        measure(simulate_free_decay(p, x0=1.0, duration=1.0).record, counts_per_rev=0)
