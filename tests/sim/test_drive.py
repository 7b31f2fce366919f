import math

import numpy as np
import pytest

from driveid.errors import ParameterError, SimulationError
from driveid.models.backlash import ImpactParams, contact_duration, restitution
from driveid.sim import OscillatorParams, simulate_free_decay
from driveid.sim.batch import simulate_free_decay_batch
from driveid.sim.drive import (
    BacklashLink,
    BodyParams,
    DriveParams,
    PDFeedback,
    ShaftLink,
    simulate_drive,
)

W1 = dict(J=1.0, K=16.0, c_mean=0.3, c_delta=0.1, fk_mean=0.07, fk_delta=0.03, fs_mean=0.105)


def _one_body(**kw):
    return DriveParams(bodies=(BodyParams(**kw),))


def _w3(**fb):
    bodies = (BodyParams(J=0.0115, c_mean=1e-3, fk_mean=0.02), BodyParams(J=0.0035),
              BodyParams(J=0.016, c_mean=2e-3, fk_mean=0.05))
    links = (BacklashLink(gap_plus=0.01, gap_minus=0.01, k=1e4, c=2.0), ShaftLink(k=50.0, c=0.05))
    kw = dict(P=5.0, D=0.3, delay=0.01, reference=1.0) | fb
    return DriveParams(bodies=bodies, links=links, feedback=PDFeedback(**kw))


# ------------------------------------------------------------------ one body vs exact
@pytest.mark.parametrize("c_delta, v0", [(0.0, 0.0), (0.1, 0.0), (-0.1, 2.0)])
def test_rk4_linear_friction_matches_exact_oscillator(c_delta, v0):
    osc = OscillatorParams(J=1.0, K=16.0, c_mean=0.3, c_delta=c_delta)
    exact = simulate_free_decay(osc, x0=1.0, v0=v0, duration=20.0)
    res = simulate_drive(_one_body(J=1.0, K=16.0, c_mean=0.3, c_delta=c_delta), x0=[1.0],
                         v0=[v0], duration=20.0, method="rk4")
    # acceptance: 1e-9; RK4 at h = 1 ms (h*omega0 = 4e-3) and located reversals give ~3e-11
    np.testing.assert_allclose(res.x[0], exact.record.x, rtol=0, atol=1e-9)
    np.testing.assert_allclose(res.v[0], exact.record.v, rtol=0, atol=1e-9)


def test_rk4_stiction_w1_matches_exact_oscillator():
    exact = simulate_free_decay(OscillatorParams(**W1), x0=1.0, duration=20.0)
    res = simulate_drive(_one_body(**W1), x0=[1.0], duration=20.0, method="rk4")
    # same integrator accuracy as the linear case: stick and breakaway are event-located
    np.testing.assert_allclose(res.x[0], exact.record.x, rtol=0, atol=1e-9)
    assert exact.stuck_at is not None and np.all(res.v[0][res.t > exact.stuck_at + 1e-3] == 0)
    # n_reversals counts the start at rest; ours counts 22 reversals + the final stick
    assert res.n_mode_switches == exact.n_reversals - 1


def test_exact_path_and_constant_torque():
    exact = simulate_free_decay(OscillatorParams(**W1), x0=1.0, u0=0.2, duration=20.0)
    for method in ("exact", "rk4"):
        res = simulate_drive(_one_body(**W1), x0=[1.0], torque=[0.2], duration=20.0,
                             method=method)
        # exact path: round-off (the one-sample transition matrix accumulates ~1e-14)
        tol = 1e-12 if method == "exact" else 1e-9
        np.testing.assert_allclose(res.x[0], exact.record.x, rtol=0, atol=tol)
        e = res.energy
        balance = e["initial"] + e["input"] - e["kinetic"] - e["potential"] - e["dissipated"]
        assert np.max(np.abs(balance)) < 1e-6 * e["initial"]  # acceptance: 1e-6 relative


def test_batch_matches_exact_oscillator_per_set():
    rng = np.random.default_rng(1)
    n = 40
    draw = {k: v * rng.uniform(0.7, 1.3, n) for k, v in W1.items()}
    # draw the ratio fs/fk = 1.5 ± 30 % so that static friction stays >= kinetic
    draw["fs_mean"] = 1.5 * rng.uniform(0.7, 1.3, n) * draw["fk_mean"]
    batch = simulate_free_decay_batch(**draw, x0=1.0, duration=20.0)
    worst = 0.0
    for i in range(0, n, 5):
        p = OscillatorParams(**{k: float(v[i]) for k, v in draw.items()})
        ref = simulate_free_decay(p, x0=1.0, duration=20.0)
        worst = max(worst, np.max(np.abs(batch.x[i] - ref.record.x)))
        if ref.stuck_at is None:
            assert np.isnan(batch.stuck_at[i])
        else:
            assert batch.stuck_at[i] == pytest.approx(ref.stuck_at, abs=1e-12)
    assert worst < 1e-12  # both are closed forms; only round-off differs


# ------------------------------------------------------------------ locks, energy, contact
def test_locked_body_never_moves():
    bodies = (BodyParams(J=0.01, fk_mean=0.01), BodyParams(J=0.004, locked=True),
              BodyParams(J=0.02, c_mean=1e-3))
    links = (BacklashLink(gap_plus=0.01, gap_minus=0.02, k=1e4, c=1.0), ShaftLink(k=50.0))
    t = np.arange(2001) / 1000.0
    torque = np.vstack([0.5 * np.sin(20 * t), 3.0 + 0 * t, 0 * t])
    res = simulate_drive(DriveParams(bodies=bodies, links=links), duration=2.0,
                         x0=[0.0, 0.3, 0.1], v0=[1.0, 0.0, 0.0], torque=torque)
    assert np.all(res.x[1] == 0.3) and np.all(res.v[1] == 0.0)  # exactly, not approximately
    assert res.n_impacts > 0  # the motor did hit the locked arm


@pytest.mark.parametrize("allow_tension", [False, True])
def test_energy_balance_closes_with_friction_contact_and_shaft(allow_tension):
    bodies = (BodyParams(J=0.0115, c_mean=1e-3, fk_mean=0.02, fs_mean=0.03),
              BodyParams(J=0.0035, K=2.0),
              BodyParams(J=0.016, c_mean=2e-3, c_delta=5e-4, fk_mean=0.05, fk_delta=0.01))
    links = (BacklashLink(gap_plus=0.01, gap_minus=0.015, k=1e4, c=2.0,
                          allow_tension=allow_tension), ShaftLink(k=50.0, c=0.05))
    t = np.arange(3001) / 1000.0
    torque = np.vstack([0.3 * np.sin(6 * t), 0 * t, 0.05 * np.cos(3 * t)])
    res = simulate_drive(DriveParams(bodies=bodies, links=links), duration=3.0,
                         x0=[0.005, 0.0, -0.02], v0=[1.0, 0.0, -0.5], torque=torque,
                         max_step=2e-5)
    e = res.energy
    scale = e["initial"] + np.max(np.abs(e["input"]))
    balance = e["initial"] + e["input"] - e["kinetic"] - e["potential"] - e["dissipated"]
    assert res.n_impacts >= 5 and res.n_mode_switches >= 5
    # acceptance 1e-6 relative; RK4 at h*omega_contact = 0.04 closes it to ~1e-10
    assert np.max(np.abs(balance)) < 1e-6 * scale
    assert np.all(np.diff(e["dissipated"]) > -1e-9 * scale)  # dissipation never decreases


@pytest.mark.parametrize("allow_tension", [False, True])
def test_ball_drop_restitution_and_contact_duration(allow_tension):
    m1, m2, k, c, gap, vc = 0.0115, 0.0035, 1e4, 2.0, 0.01, 0.8
    imp = ImpactParams(m1=m1, m2=m2, k=k, c=c)
    drive = DriveParams(bodies=(BodyParams(J=m1), BodyParams(J=m2)),
                        links=(BacklashLink(gap_plus=gap, gap_minus=1.0, k=k, c=c,
                                            allow_tension=allow_tension),))
    duration = 0.02
    res = simulate_drive(drive, duration=duration, fs=1000.0, v0=[vc, 0.0], max_step=1e-6)
    v_rel = res.v[0, -1] - res.v[1, -1]
    e = float(restitution(imp.zeta, allow_tension))
    assert res.n_impacts == 1
    # free flight is exact; the contact is RK4 at h*omega_d = 2e-3: ~1e-12 relative
    assert -v_rel / vc == pytest.approx(e, rel=1e-9)
    # momentum is conserved through the contact
    assert m1 * res.v[0, -1] + m2 * res.v[1, -1] == pytest.approx(m1 * vc, rel=1e-12)
    # contact end from the final separation: delta(t) = delta_end + v_rel (t - t_end), with
    # delta_end = (vc/omega_d) e^{-zeta omega0 t_c} sin(omega_d t_c) (2.62) at release
    t_c = float(contact_duration(imp.zeta, imp.omega0, allow_tension))
    d_end = vc / imp.omega_d * math.exp(-imp.zeta * imp.omega0 * t_c) * math.sin(imp.omega_d * t_c)
    delta_final = res.x[0, -1] - res.x[1, -1] - gap
    t_end = duration - (delta_final - d_end) / v_rel
    t_start = gap / vc
    assert t_end - t_start == pytest.approx(t_c, rel=1e-7)  # 1e-7: sub-nanosecond on 1.6 ms


# ------------------------------------------------------------------ feedback
def test_pd_without_delay_is_the_exact_oscillator():
    # J x'' = P (r - x) - D x'  <=>  oscillator K = P, c = D, u0 = P r
    P, D, r = 16.0, 0.8, 0.5
    drive = DriveParams(bodies=(BodyParams(J=1.0),), feedback=PDFeedback(P=P, D=D, reference=r))
    res = simulate_drive(drive, duration=5.0)
    exact = simulate_free_decay(OscillatorParams(J=1.0, K=P, c_mean=D), x0=0.0, u0=P * r,
                                duration=5.0)
    np.testing.assert_allclose(res.x[0], exact.record.x, atol=1e-9)  # RK4 at h*omega = 0.2/... s
    np.testing.assert_allclose(res.command, P * (r - exact.record.x) - D * exact.record.v,
                               atol=1e-8)


def test_delay_holds_the_initial_command_then_converges():
    P, D, delay, r, J = 5.0, 0.3, 0.01, 1.0, 0.02
    drive = DriveParams(bodies=(BodyParams(J=J),),
                        feedback=PDFeedback(P=P, D=D, delay=delay, reference=r))
    res = simulate_drive(drive, duration=1.0, fs=10000.0)
    early = res.t <= delay
    # before t = delay the loop sees only the initial state: constant torque P r
    np.testing.assert_allclose(res.x[0][early], P * r * res.t[early] ** 2 / (2 * J), atol=1e-12)
    fine = simulate_drive(drive, duration=1.0, fs=10000.0, max_step=1e-5)
    # a 10x finer run: RK4 with Hermite-interpolated history converges at ~4th order
    assert np.max(np.abs(res.x[0] - fine.x[0])) < 1e-6


def test_saturation_and_abort():
    res = simulate_drive(_w3(saturation=2.0), duration=1.0)
    assert np.max(np.abs(res.command)) <= 2.0 and not res.aborted
    res = simulate_drive(_w3(P=50.0, abort_limit=20.0), duration=1.0)
    assert res.aborted and res.abort_time == pytest.approx(0.0)
    assert "abort_limit=20" in res.abort_reason
    assert np.all(np.isnan(res.x[:, 1:]))


def test_w3_three_body_drive_settles_near_the_reference():
    res = simulate_drive(_w3(), duration=5.0)
    fine = simulate_drive(_w3(), duration=5.0, max_step=1e-5)
    assert res.n_impacts >= 2 and not res.aborted
    # default step (h*omega = 0.2) against a 10x finer run of our own
    assert np.max(np.abs(res.x - fine.x)) < 1e-5
    # motor friction 0.02 N·m over P = 5: the motor rests within 4 mrad (+ loop) of r = 1
    assert abs(res.x[0, -1] - 1.0) < 0.02
    assert res.body_record(2).x.size == res.t.size


# ------------------------------------------------------------------ error paths
@pytest.mark.parametrize("kwargs, match", [
    (dict(J=0.0), "J must be positive"),
    (dict(J=1.0, K=-1.0), "K must be >= 0"),
    (dict(J=1.0, fk_mean=-0.1), "fk_mean must be >= 0"),
    (dict(J=1.0, fk_mean=0.1, fs_mean=0.05), "static friction must hold"),
    (dict(J=float("nan")), "finite"),
])
def test_body_params_errors(kwargs, match):
    with pytest.raises(ParameterError, match=match):
        BodyParams(**kwargs)


def test_link_feedback_and_drive_errors():
    with pytest.raises(ParameterError, match="BacklashLink.k must be positive"):
        BacklashLink(gap_plus=0.01, gap_minus=0.01, k=0.0)
    with pytest.raises(ParameterError, match="BacklashLink.gap_minus must be >= 0"):
        BacklashLink(gap_plus=0.01, gap_minus=-0.01, k=1.0)
    with pytest.raises(ParameterError, match="ShaftLink.c must be >= 0"):
        ShaftLink(k=1.0, c=-1.0)
    with pytest.raises(ParameterError, match="delay must be >= 0"):
        PDFeedback(P=1.0, D=0.0, delay=-1.0)
    with pytest.raises(ParameterError, match="saturation must be positive"):
        PDFeedback(P=1.0, D=0.0, saturation=0.0)
    b = BodyParams(J=1.0)
    with pytest.raises(ParameterError, match="len\\(bodies\\) - 1 = 1 links"):
        DriveParams(bodies=(b, b))
    with pytest.raises(ParameterError, match="must index a body"):
        DriveParams(bodies=(b,), feedback=PDFeedback(P=1.0, D=0.0, body=3))
    with pytest.raises(ParameterError, match="must not be locked"):
        DriveParams(bodies=(BodyParams(J=1.0, locked=True),), feedback=PDFeedback(P=1, D=0))


def test_simulate_drive_errors():
    d = _one_body(J=1.0, K=1.0)
    with pytest.raises(ParameterError, match="duration must be positive"):
        simulate_drive(d, duration=0.0)
    with pytest.raises(ParameterError, match="fs must be positive"):
        simulate_drive(d, duration=1.0, fs=-1.0)
    with pytest.raises(ParameterError, match="torque must be a scalar or broadcast"):
        simulate_drive(d, duration=1.0, torque=np.zeros((2, 7)))
    with pytest.raises(ParameterError, match="locked bodies must start at rest"):
        simulate_drive(_one_body(J=1.0, locked=True), duration=1.0, v0=[1.0])
    with pytest.raises(ParameterError, match='method="exact" needs one unlocked body'):
        simulate_drive(_w3(), duration=1.0, method="exact")
    with pytest.raises(ParameterError, match="method must be"):
        simulate_drive(d, duration=1.0, method="euler")
    with pytest.raises(ParameterError, match="params must be a DriveParams"):
        simulate_drive(BodyParams(J=1.0), duration=1.0)
    # a 2 s step holds two reversals of a 1.57 s-period oscillator with friction: the
    # chattering guard (a body without friction has no reversal events)
    with pytest.raises(SimulationError, match="max_events_per_step=1"):
        simulate_drive(_one_body(J=1.0, K=16.0, fk_mean=0.01), x0=[1.0], duration=10.0,
                       fs=0.5, max_step=2.0, max_events_per_step=1, method="rk4")


def test_batch_errors():
    with pytest.raises(ParameterError, match="K must be positive"):
        simulate_free_decay_batch(J=1.0, K=[1.0, 0.0], x0=1.0, duration=1.0)
    with pytest.raises(ParameterError, match="broadcast"):
        simulate_free_decay_batch(J=[1.0, 2.0], K=[1.0, 2.0, 3.0], x0=1.0, duration=1.0)
    with pytest.raises(ParameterError, match="x0 must be finite"):
        simulate_free_decay_batch(J=1.0, K=1.0, x0=np.nan, duration=1.0)
    with pytest.raises(SimulationError, match="max_reversals=3"):
        simulate_free_decay_batch(J=1.0, K=16.0, x0=1.0, duration=10.0, max_reversals=3)
