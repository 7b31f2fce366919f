"""Controller callback, restitution contact, batch API and the smooth-integrator hooks."""

import math
import sys
import types

import numpy as np
import pytest

from driveid.errors import ParameterError, SimulationError
from driveid.models.dynamic_friction import LuGreParams
from driveid.sim import OscillatorParams, simulate_free_decay
from driveid.sim.batch import simulate_drive_batch
from driveid.sim.drive import (
    BacklashLink,
    BodyParams,
    DriveParams,
    PDFeedback,
    ShaftLink,
    simulate_drive,
)


def _w3_plant(feedback=None, scale=None):
    s = np.ones(7) if scale is None else scale
    bodies = (BodyParams(J=0.0115 * s[0], c_mean=1e-3 * s[1], fk_mean=0.02 * s[2]),
              BodyParams(J=0.0035 * s[3]),
              BodyParams(J=0.016 * s[4], c_mean=2e-3, fk_mean=0.05 * s[5]))
    links = (BacklashLink(gap_plus=0.01, gap_minus=0.01, k=1e4, c=2.0),
             ShaftLink(k=50.0 * s[6], c=0.05))
    return DriveParams(bodies=bodies, links=links, feedback=feedback)


def _balance(res):
    e = res.energy
    return e["initial"] + e["input"] - e["kinetic"] - e["potential"] - e["dissipated"]


# ------------------------------------------------------------------ controller callback
@pytest.mark.parametrize("control_rate", [1000.0, 100.0])
def test_constant_callback_matches_constant_torque_run(control_rate):
    plant = _w3_plant()
    t = np.arange(2001) / 1000.0
    ref = simulate_drive(plant, duration=2.0, torque=[0.3, 0.0, 0.0], v0=[0.0, 0.0, 0.0])
    res = simulate_drive(plant, duration=2.0, controller=lambda t, x, v: 0.3,
                         control_rate=control_rate)
    assert res.n_impacts >= 1 and res.n_mode_switches >= 1
    # same RK4 grid, restarted at every control tick: only round-off differs
    np.testing.assert_allclose(res.x, ref.x, rtol=0, atol=1e-12)
    np.testing.assert_allclose(res.v, ref.v, rtol=0, atol=1e-11)
    assert (res.n_impacts, res.n_mode_switches) == (ref.n_impacts, ref.n_mode_switches)
    np.testing.assert_array_equal(res.command, 0.3 + 0 * t)
    # acceptance 1e-6 relative (RK4 at the default step closes it to ~3e-9); the restarts
    # per control period change it by round-off only
    assert np.max(np.abs(_balance(res))) < 1e-6 * np.max(np.abs(res.energy["input"]))
    np.testing.assert_allclose(_balance(res), _balance(ref), rtol=0, atol=1e-13)


def test_callback_pd_converges_to_continuous_pd_at_first_order():
    # J x'' = P (r - x) - D x' is the exact oscillator K = P, c = D, u0 = P r
    J, P, D, r = 1.0, 16.0, 0.8, 0.5
    exact = simulate_free_decay(OscillatorParams(J=J, K=P, c_mean=D), x0=0.0, u0=P * r,
                                duration=3.0).record.x
    plant = DriveParams(bodies=(BodyParams(J=J),))
    errors = []
    for rate in (250.0, 500.0, 1000.0, 2000.0):
        res = simulate_drive(plant, duration=3.0, controller=lambda t, x, v: P * (r - x[0])
                             - D * v[0], control_rate=rate)
        errors.append(np.max(np.abs(res.x[0] - exact)))
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    # zero-order hold = a delay of T/2 to first order: error O(T), observed order ~1.00
    assert np.all(np.abs(orders - 1.0) < 0.05), orders
    assert errors[-1] < 2e-3  # 2 kHz: a few 1e-4 rad on a 0.5 rad step


def test_callback_delay_and_vector_torque():
    J, u, rate, d = 0.5, 2.0, 100.0, 3
    plant = DriveParams(bodies=(BodyParams(J=J), BodyParams(J=1.0)), links=(None,))
    res = simulate_drive(plant, duration=0.2, fs=1000.0, controller=lambda t, x, v: [u, -u],
                         control_rate=rate, controller_delay=d)
    t0 = d / rate  # the command is zero for the first d control periods
    tt = np.clip(res.t - t0, 0.0, None)
    # free bodies under a piecewise constant torque: RK4 is exact on parabolas
    np.testing.assert_allclose(res.x[0], u * tt ** 2 / (2 * J), atol=1e-13)
    np.testing.assert_allclose(res.x[1], -u * tt ** 2 / 2, atol=1e-13)
    assert res.command.shape == (2, res.t.size)
    assert np.all(res.command[0][res.t < t0] == 0) and np.all(res.command[0][res.t >= t0] == u)
    assert np.all(res.body_record(1).u[res.t >= t0] == -u)


def test_fast_controller_and_saturation_abort():
    plant = DriveParams(bodies=(BodyParams(J=1.0),))
    # control at 10 kHz, output at 1 kHz: a constant command is exact on the output grid
    res = simulate_drive(plant, duration=0.5, controller=lambda t, x, v: 5.0,
                         control_rate=10000.0, saturation=1.5)
    np.testing.assert_allclose(res.x[0], 1.5 * res.t ** 2 / 2, atol=1e-13)  # exact parabola
    assert np.all(res.command == 1.5)
    # a sampled torque ramp (1 kHz) under a 10 kHz controller: x = t³/6 + 0.25 t², exact
    res = simulate_drive(plant, duration=0.5, torque=np.arange(501) / 1000.0,
                         controller=lambda t, x, v: 0.5, control_rate=10000.0)
    np.testing.assert_allclose(res.x[0], res.t ** 3 / 6 + 0.25 * res.t ** 2, atol=1e-13)
    res = simulate_drive(plant, duration=0.5, controller=lambda t, x, v: 100.0 * t,
                         control_rate=100.0, abort_limit=20.0)
    assert res.aborted and res.abort_time == pytest.approx(0.21)  # first tick with 100 t > 20
    assert "abort_limit=20" in res.abort_reason and np.isnan(res.x[0, -1])
    assert np.all(np.isfinite(res.x[0, res.t < 0.21]))


def test_controller_errors():
    plant = DriveParams(bodies=(BodyParams(J=1.0),))
    pd = DriveParams(bodies=(BodyParams(J=1.0),), feedback=PDFeedback(P=1.0, D=0.1))
    ok = dict(duration=0.1, controller=lambda t, x, v: 0.0, control_rate=1000.0)
    with pytest.raises(ParameterError, match="either params.feedback or a controller"):
        simulate_drive(pd, **ok)
    with pytest.raises(ParameterError, match="must be an integer"):
        simulate_drive(plant, **ok | dict(control_rate=300.0))
    with pytest.raises(ParameterError, match="control_rate must be a positive"):
        simulate_drive(plant, **ok | dict(control_rate=None))
    with pytest.raises(ParameterError, match="control_rate needs a controller"):
        simulate_drive(plant, duration=0.1, control_rate=100.0)
    with pytest.raises(ParameterError, match="controller_delay must be a whole"):
        simulate_drive(plant, **ok | dict(controller_delay=0.5))
    with pytest.raises(ParameterError, match=r"scalar or shape \(1,\)"):
        simulate_drive(plant, **ok | dict(controller=lambda t, x, v: [1.0, 2.0]))
    with pytest.raises(SimulationError, match="non-finite torque"):
        simulate_drive(plant, **ok | dict(controller=lambda t, x, v: math.nan))


# ------------------------------------------------------------------ restitution contact
@pytest.mark.parametrize("e, locked", [(0.5, False), (0.8, True), (1.0, False)])
def test_restitution_ball_drop_is_exact(e, locked):
    """Body 1 pushed by F from rest into a gap against body 2 (free at rest, or a wall)."""
    m1, m2, F, g = 0.0115, 0.0035, 0.4, 0.01
    link = BacklashLink(gap_plus=g, gap_minus=1.0, k=1e4, c=2.0, contact="restitution",
                        restitution=e)
    plant = DriveParams(bodies=(BodyParams(J=m1), BodyParams(J=m2, locked=locked)),
                        links=(link,))
    fs, duration = 20000.0, 0.2
    res = simulate_drive(plant, duration=duration, fs=fs, torque=[F, 0.0])
    a = F / m1
    # closed form: impact k at t_k with approach speed e^k v1; between impacts body 1 is a
    # parabola, body 2 a line; each impact maps velocities by Newton's law
    t_hit, v1 = math.sqrt(2 * g / a), math.sqrt(2 * g * a)
    w1, w2 = (1.0, 0.0) if locked else (m2 / (m1 + m2), m1 / (m1 + m2))
    x_ref, v_ref = np.full((2, res.t.size), np.nan), np.full((2, res.t.size), np.nan)
    tk, xs, vs, n_hits, losses = 0.0, [0.0, 0.0], [0.0, 0.0], 0, []
    mu = m1 if locked else m1 * m2 / (m1 + m2)
    while True:
        dt = t_hit if n_hits == 0 else 2 * (e ** n_hits) * v1 / a
        if n_hits and e ** n_hits * v1 <= link.rest_velocity or tk + dt > 0.6 * duration:
            break
        seg = (res.t >= tk) & (res.t < tk + dt)
        s = res.t[seg] - tk
        x_ref[0, seg], v_ref[0, seg] = xs[0] + vs[0] * s + a * s * s / 2, vs[0] + a * s
        x_ref[1, seg], v_ref[1, seg] = xs[1] + vs[1] * s, vs[1] + 0 * s
        xs = [xs[0] + vs[0] * dt + a * dt * dt / 2, xs[1] + vs[1] * dt]
        vs[0] += a * dt
        vrel = vs[0] - vs[1]
        vs = [vs[0] - (1 + e) * w1 * vrel, vs[1] + (1 + e) * w2 * vrel]
        tk += dt
        losses.append((tk, 0.5 * mu * (1 - e * e) * vrel ** 2))
        n_hits += 1
    known = np.isfinite(x_ref[0])
    assert n_hits >= 3 and known.sum() > 1000
    # RK4 is exact on parabolas and the impact time is located to ~1e-15 h: round-off only
    np.testing.assert_allclose(res.x[:, known], x_ref[:, known], rtol=0, atol=1e-12)
    np.testing.assert_allclose(res.v[:, known], v_ref[:, known], rtol=0, atol=1e-10)
    # restitution recovered from the sampled relative velocity just after the first impact
    i = np.flatnonzero(res.t > math.sqrt(2 * g / a))[0]
    vrel_after = (res.v[0, i] - res.v[1, i]) - a * (res.t[i] - math.sqrt(2 * g / a))
    assert -vrel_after / v1 == pytest.approx(e, rel=1e-12, abs=1e-13)  # round-off
    if not locked:  # momentum = impulse of F at every sample, through every impact
        np.testing.assert_allclose(m1 * res.v[0] + m2 * res.v[1], F * res.t, rtol=1e-12,
                                   atol=1e-15)
    j = np.flatnonzero(known)[-1]
    loss = sum(q for t_imp, q in losses if t_imp <= res.t[j])
    assert res.energy["impact"][j] == pytest.approx(loss, rel=1e-12)  # round-off
    scale = np.max(np.abs(res.energy["input"]))
    # the impact loss closes the books; flight is exact, the resting contact after a Zeno
    # sequence is RK4 on the compliant contact (~2e-12 here)
    assert np.max(np.abs(_balance(res))) < 1e-10 * scale
    if locked:
        assert np.all(res.x[1] == 0.0)


def test_restitution_zeno_ends_in_resting_contact():
    m1, m2, F, g, e = 0.0115, 0.0035, 0.4, 0.01, 0.5
    link = BacklashLink(gap_plus=g, gap_minus=1.0, k=1e4, c=2.0, contact="restitution",
                        restitution=e)
    plant = DriveParams(bodies=(BodyParams(J=m1), BodyParams(J=m2)), links=(link,))
    res = simulate_drive(plant, duration=0.5, torque=[F, 0.0])
    v1 = math.sqrt(2 * g * F / m1)
    # impacts faster than rest_velocity (e^k v1 > 1e-4), then one compliant closure
    n_fast = math.floor(math.log(link.rest_velocity / v1) / math.log(e)) + 1
    assert res.n_impacts == n_fast + 1
    late = res.t > 0.3
    # pressed together by F: one rigid body (compliant contact: k δ = F m2/(m1+m2))
    np.testing.assert_allclose(res.v[0, late], res.v[1, late], atol=1e-9)
    delta = res.x[0, late] - res.x[1, late] - g
    np.testing.assert_allclose(delta, F * m2 / (m1 + m2) / link.k, rtol=1e-6)
    np.testing.assert_allclose(m1 * res.v[0] + m2 * res.v[1], F * res.t, rtol=1e-12)
    assert np.max(np.abs(_balance(res))) < 1e-9 * np.max(res.energy["input"])


@pytest.mark.parametrize("e", [0.0, 0.5])
def test_restitution_in_the_w3_drive_closes_the_energy_balance(e):
    bodies = (BodyParams(J=0.0115, c_mean=1e-3, fk_mean=0.02), BodyParams(J=0.0035),
              BodyParams(J=0.016, c_mean=2e-3, fk_mean=0.05))
    links = (BacklashLink(gap_plus=0.01, gap_minus=0.01, k=1e4, c=2.0, contact="restitution",
                          restitution=e), ShaftLink(k=50.0, c=0.05))
    plant = DriveParams(bodies=bodies, links=links,
                        feedback=PDFeedback(P=5.0, D=0.3, delay=0.01, reference=1.0))
    res = simulate_drive(plant, duration=2.0)
    assert res.n_impacts >= 5 and res.energy["impact"][-1] > 0
    # acceptance 1e-6 relative; impacts are exact, the rest is RK4 (~5e-9 here)
    assert np.max(np.abs(_balance(res))) < 1e-6 * np.max(np.abs(res.energy["input"]))
    assert abs(res.x[0, -1] - 1.0) < 0.02  # settles near the reference like the W3 drive


def test_restitution_link_errors():
    with pytest.raises(ParameterError, match=r"restitution must be in \[0, 1\]"):
        BacklashLink(gap_plus=0.0, gap_minus=0.0, k=1.0, contact="restitution", restitution=1.5)
    with pytest.raises(ParameterError, match="restitution must be in"):
        BacklashLink(gap_plus=0.0, gap_minus=0.0, k=1.0, contact="restitution")
    with pytest.raises(ParameterError, match="cannot pull"):
        BacklashLink(gap_plus=0.0, gap_minus=0.0, k=1.0, contact="restitution",
                     restitution=0.5, allow_tension=True)
    with pytest.raises(ParameterError, match='needs contact="restitution"'):
        BacklashLink(gap_plus=0.0, gap_minus=0.0, k=1.0, restitution=0.5)
    with pytest.raises(ParameterError, match="contact must be"):
        BacklashLink(gap_plus=0.0, gap_minus=0.0, k=1.0, contact="plastic")


# ------------------------------------------------------------------ batch
@pytest.mark.parametrize("parallel", [False, True])
def test_batch_equals_single_runs(parallel):
    rng = np.random.default_rng(3)
    fb = PDFeedback(P=5.0, D=0.3, delay=0.01, reference=1.0)
    plants = [_w3_plant(fb, rng.uniform(0.7, 1.3, 7)) for _ in range(4)]
    plants.append(_w3_plant(None))  # feedback may differ inside a batch
    x0 = np.zeros((5, 3))
    x0[:, 2] = rng.uniform(-0.1, 0.1, 5)
    batch = simulate_drive_batch(plants, duration=1.0, x0=x0, parallel=parallel)
    for p, b, x in zip(plants, batch, x0, strict=True):
        one = simulate_drive(p, duration=1.0, x0=x)
        # the same compiled kernel on the same inputs: round-off at most
        np.testing.assert_allclose(b.x, one.x, rtol=0, atol=1e-12)
        np.testing.assert_allclose(b.command, one.command, rtol=0, atol=1e-10)
        assert (b.n_impacts, b.n_mode_switches) == (one.n_impacts, one.n_mode_switches)
        np.testing.assert_allclose(b.energy["dissipated"], one.energy["dissipated"], atol=1e-12)


def test_batch_errors():
    one = DriveParams(bodies=(BodyParams(J=1.0),))
    two = DriveParams(bodies=(BodyParams(J=1.0), BodyParams(J=1.0)), links=(None,))
    with pytest.raises(ParameterError, match="drive 1 has 2"):
        simulate_drive_batch([one, two], duration=1.0)
    with pytest.raises(ParameterError, match="non-empty sequence"):
        simulate_drive_batch([], duration=1.0)
    with pytest.raises(ParameterError, match=r"x0 and v0 must have shape \(1,\) or \(2, 1\)"):
        simulate_drive_batch([one, one], duration=1.0, x0=[1.0, 2.0, 3.0])


# ------------------------------------------------------------------ hooks for the smooth path
LUGRE = LuGreParams(sigma0=1e5, sigma1=0.5, sigma2=0.4, fc=1.0, fs=1.5, vs=1e-3)


def test_lugre_body_validation():
    assert BodyParams(J=1.0, lugre=LUGRE).lugre is LUGRE
    with pytest.raises(ParameterError, match="choose one friction model"):
        BodyParams(J=1.0, fk_mean=0.1, lugre=LUGRE)
    with pytest.raises(ParameterError, match="choose one friction model"):
        BodyParams(J=1.0, fs_mean=0.2, lugre=LUGRE)
    with pytest.raises(ParameterError, match="lugre must be a LuGreParams"):
        BodyParams(J=1.0, lugre={"sigma0": 1e5})
    with pytest.raises(ParameterError, match="motor must be a driveid.models.motor"):
        DriveParams(bodies=(BodyParams(J=1.0),), motor="dc")


def test_smooth_models_delegate_to_simulate_smooth(monkeypatch):
    calls = []
    fake = types.ModuleType("driveid.sim._smooth")
    fake.simulate_smooth = lambda params, **kw: calls.append((params, kw)) or "smooth"
    monkeypatch.setitem(sys.modules, "driveid.sim._smooth", fake)
    plant = DriveParams(bodies=(BodyParams(J=1.0, K=2.0, lugre=LUGRE),))
    out = simulate_drive(plant, duration=1.0, fs=500.0, x0=[0.1], torque=[0.2])
    assert out == "smooth" and calls[0][0] is plant
    assert calls[0][1] == dict(duration=1.0, fs=500.0, x0=[0.1], v0=None, torque=[0.2],
                               reference=None)
    with pytest.raises(ParameterError, match="smooth integrator"):
        simulate_drive(plant, duration=1.0, method="exact")
    with pytest.raises(ParameterError, match="smooth integrator"):
        simulate_drive(plant, duration=1.0, controller=lambda t, x, v: 0.0, control_rate=1e3)


def test_restitution_keys_in_toml_config():
    from driveid.errors import ConfigError
    from driveid.sim.config import parse_drive_config

    link = {"type": "backlash", "gap_plus": 0.01, "gap_minus": 0.01, "k": 1e4,
            "contact": "restitution", "restitution": 0.4, "rest_velocity": 1e-3}
    cfg = {"body": [{"J": 1.0}, {"J": 2.0}], "link": [link]}
    params, _ = parse_drive_config(cfg)
    ln = params.links[0]
    assert (ln.contact, ln.restitution, ln.rest_velocity) == ("restitution", 0.4, 1e-3)
    with pytest.raises(ConfigError, match=r"link\[1\]\.restitution"):
        parse_drive_config(cfg | {"link": [link | {"restitution": 2.0}]})
