"""Online tracking (EW recursive least squares) of drifting friction."""

import math

import numba
import numpy as np
import pytest

from driveid.errors import ParameterError, RecordError
from driveid.identify.friction.online import chunks_of, forgetting_factor, track_friction
from driveid.io.record import Record

# Truth of the drifting drive (rotational, SI): Coulomb friction rises by 30 % with time
# constant TAU, viscous friction drifts linearly by +50 % over the two hours.
J, C0, CD, FK0, FKD, TAU, HOURS = 0.0115, 0.002, 0.0004, 0.10, 0.01, 1200.0, 2.0


def fk_true(t):
    return FK0 * (1.0 + 0.3 * (1.0 - np.exp(-t / TAU)))


def c_true(t):
    return C0 * (1.0 + 0.5 * t / (HOURS * 3600.0))


@numba.njit(cache=False)
def _accel(t, x, v, tau, c0, fk0, hours):
    xr = 1.0 * math.sin(2 * math.pi * 0.5 * t) + 0.3 * math.sin(2 * math.pi * 1.3 * t)
    vr = (math.pi * math.cos(2 * math.pi * 0.5 * t)
          + 0.78 * math.pi * math.cos(2 * math.pi * 1.3 * t))
    u = 20.0 * (xr - x) + 1.0 * (vr - v)
    fk = fk0 * (1.0 + 0.3 * (1.0 - math.exp(-t / tau)))
    c = c0 * (1.0 + 0.5 * t / (hours * 3600.0))
    f = c * v + 0.0004 * abs(v) + fk * math.tanh(v / 0.01) + 0.01
    return (u - f) / 0.0115, u


@numba.njit(cache=False)
def _integrate(t0, n, fs, sub, state, noise, tau, c0, fk0, hours):
    """RK4 of J a = u - c v - cd|v| - fk tanh(v/0.01) - fkd under PD tracking of a
    two-sine reference; returns t, x, v and the measured command u (noisy) sampled at
    the same instants. tanh(v/0.01) = sgn v to 1e-6 above the tracker's v_min."""
    h = 1.0 / (fs * sub)
    out = np.empty((4, n))
    x, v = state[0], state[1]
    for k in range(n):
        for s in range(sub):
            t = t0 + (k * sub + s) * h
            a1, u = _accel(t, x, v, tau, c0, fk0, hours)
            if s == 0:
                out[0, k] = t
                out[1, k] = x
                out[2, k] = v
                out[3, k] = u
            a2, _ = _accel(t + h / 2, x + h / 2 * v, v + h / 2 * a1, tau, c0, fk0, hours)
            a3, _ = _accel(t + h / 2, x + h / 2 * (v + h / 2 * a1), v + h / 2 * a2,
                           tau, c0, fk0, hours)
            a4, _ = _accel(t + h, x + h * (v + h / 2 * a2), v + h * a3, tau, c0, fk0, hours)
            x += h * (v + h / 6 * (a1 + a2 + a3))
            v += h / 6 * (a1 + 2 * a2 + 2 * a3 + a4)
    state[0], state[1] = x, v
    out[3] += noise
    return out


def drift_chunks(*, hours=HOURS, fs=100.0, chunk_s=60.0, noise_std=0.02, seed=0):
    """Generator of 60 s chunks of the first `hours` of the run (bounded memory)."""
    rng = np.random.default_rng(seed)
    state = np.zeros(2)
    n = int(chunk_s * fs)
    for i in range(int(hours * 3600 / chunk_s)):
        noise = noise_std * rng.standard_normal(n)
        out = _integrate(i * chunk_s, n, fs, 4, state, noise, TAU, C0, FK0, HOURS)
        yield {"t": out[0], "x": out[1], "v": out[2], "u": out[3]}


@pytest.mark.slow
def test_tracks_two_hour_drift_within_bands():
    # Acceptance (issue 17): 2-hour run, fk_mean +30 % with τ = 1200 s, c_mean +50 %.
    # Memory by the documented rule T_mem = τ/10 = 120 s; the estimate lags by about
    # T_mem, so it is compared with the truth T_mem earlier (the stated lag).
    res = track_friction(drift_chunks(), drift_time=TAU, output_every=30.0)
    assert res.lag == pytest.approx(120.0)
    t = res.t
    late = t > 3 * res.memory          # after the start-up of the window
    cover = {}
    for name, truth in (("fk_mean", fk_true), ("c_mean", c_true)):
        val, se = res.trajectory(name)
        inside = np.abs(val - truth(t - res.lag)) <= 2 * se
        cover[name] = inside[late].mean()
    # issue 17 asks for >= 90 % inside the ±2σ bands
    assert cover["fk_mean"] >= 0.9, cover
    assert cover["c_mean"] >= 0.9, cover
    val, se = res.trajectory("J")
    assert np.median(np.abs(val[late] / J - 1)) < 0.01    # constant J: within 1 %
    val, _ = res.trajectory("fk_delta")
    assert np.median(val[late]) == pytest.approx(FKD, rel=0.1)


def test_forgetting_rule_and_record_input():
    assert forgetting_factor(fs=100.0, drift_time=100.0) == pytest.approx(math.exp(-1e-3))
    t = np.arange(60000) / 100
    v = np.cos(t) + 0.5 * np.cos(2.3 * t)
    a = -np.sin(t) - 1.15 * np.sin(2.3 * t)
    x = np.sin(t) + 0.5 / 2.3 * np.sin(2.3 * t)
    u = 0.02 * a + 0.003 * v + 0.08 * np.sign(v) + 0.5 * x
    res = track_friction(Record(t=t, x=x, u=u, v=v), memory=100.0, stiffness=True)
    est = res.to_estimate()
    # noise-free, a and v by central differences of the given v at 100 Hz: truncation
    # error ~ (ω dt)²/6 ≈ 1e-4 relative on a; sign errors only within v_min of reversals
    assert est.value("K") == pytest.approx(0.5, rel=1e-3)
    assert est.value("fk_mean") == pytest.approx(0.08, rel=1e-3)
    assert est.value("J") == pytest.approx(0.02, rel=1e-2)
    d = res.to_dict()
    assert set(d["parameters"]) == {"J", "c_mean", "c_delta", "fk_mean", "fk_delta", "K"}
    assert len(d["t"]) == len(d["parameters"]["J"]["value"])
    # the same record split differently gives the same result (carry across chunks)
    res2 = track_friction(chunks_of(Record(t=t, x=x, u=u, v=v), 777), fs=100.0,
                          memory=100.0, stiffness=True)
    assert res2.values[-1] == pytest.approx(res.values[-1], rel=1e-9)


def test_errors():
    with pytest.raises(ParameterError, match="drift_time"):
        forgetting_factor(fs=1.0, drift_time=-1.0)
    t = np.arange(100) / 100
    with pytest.raises(RecordError, match="command u"):
        track_friction(Record(t=t, x=t))
    with pytest.raises(RecordError, match="moving"):
        track_friction(Record(t=t, x=np.zeros(100), u=np.zeros(100)), v_min=1.0)


def test_track_command_json_and_figure(tmp_path):
    import json

    from click.testing import CliRunner

    from driveid.commands.track import track_command
    from driveid.io import write_record

    t = np.arange(30000) / 100
    v = np.cos(t) + 0.5 * np.cos(2.3 * t)
    a = -np.sin(t) - 1.15 * np.sin(2.3 * t)
    x = np.sin(t) + 0.5 / 2.3 * np.sin(2.3 * t)
    u = 0.02 * a + 0.003 * v + 0.08 * np.sign(v)
    path = write_record(Record(t=t, x=x, u=u, v=v), tmp_path / "run.csv")
    fig = tmp_path / "track.png"
    res = CliRunner().invoke(track_command, [str(path), "--memory", "60", "--json",
                                             "--figure", str(fig)])
    assert res.exit_code == 0, res.output
    out = json.loads(res.stdout)
    assert out["method"] == "rls-forgetting"
    du = out["data_used"]
    assert len(du["t"]) == len(du["fk_mean"]) == len(du["fk_mean_stderr"]) > 10
    assert du["fk_mean"][-1] == pytest.approx(0.08, rel=1e-3)
    assert fig.exists()
    res = CliRunner().invoke(track_command, [str(tmp_path / "missing.csv")])
    assert res.exit_code == 2 and "error" in res.output
