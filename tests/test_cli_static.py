"""Command-line tests of breakaway, loop, static-stiffness, step, forced, envelope, idim and
friction-map (commands invoked directly with CliRunner; registration is the integrator's)."""

import json

import numpy as np
import pytest
from click.testing import CliRunner

from driveid.commands.forced import envelope_command, forced_command
from driveid.commands.friction import friction_map_command, idim_command
from driveid.commands.static import (
    breakaway_command,
    loop_command,
    static_stiffness_command,
    step_command,
)
from driveid.io import read_record, write_record
from driveid.io.record import Record


def _run(cmd, args):
    res = CliRunner().invoke(cmd, [str(a) for a in args])
    return res


def _ramps(tmp_path):
    from driveid.sim import BodyParams, DriveParams, simulate_drive

    paths = []
    rng = np.random.default_rng(0)
    body = BodyParams(J=1e-3, c_mean=1e-3, fk_mean=0.04, fs_mean=0.05)
    for k, sign in enumerate((1, -1)):
        t = np.arange(5001) / 1000.0
        u = sign * np.where(t < 0.5, 0.0, 0.02 * (t - 0.5))
        res = simulate_drive(DriveParams(bodies=(body,)), duration=5.0, fs=1000.0,
                             torque=u[None, :])
        rec = Record(t=t, x=res.x[0], u=u + 1e-4 * rng.standard_normal(t.size),
                     meta={"units": {"x": "rad", "u": "N·m"}})
        paths.append(write_record(rec, tmp_path / f"ramp{k}.csv"))
    return paths


def test_breakaway_command(tmp_path):
    paths = _ramps(tmp_path)
    fig = tmp_path / "b.png"
    res = _run(breakaway_command, [*paths, "--v-break", "0.05", "--json", "--figure", fig])
    assert res.exit_code == 0, res.output
    out = json.loads(res.stdout)
    # simulated static friction 0.05 N·m: within 2 %
    assert out["parameters"]["fs_plus"]["value"] == pytest.approx(0.05, rel=0.02)
    assert fig.is_file()
    res = _run(breakaway_command, [*paths, "--v-break", "0.05", "--figure", fig])
    assert res.exit_code == 2 and "error:" in res.output  # no overwrite without --overwrite
    res = _run(breakaway_command, [paths[0], "--v-break", "-1"])
    assert res.exit_code == 2 and res.output.startswith("error: --v-break must be")


def test_loop_command_presliding_and_backlash(tmp_path):
    t = np.arange(8001) / 2000.0
    force = 6.0 * np.sin(2 * np.pi * t)
    # Dahl branches with sigma0 = 1e5 N/m and level 10 N, built branch by branch
    x = np.zeros_like(t)
    fr, xr, s = 0.0, 0.0, 1
    for i in range(1, t.size):
        s_new = 1 if force[i] > force[i - 1] else -1
        if s_new != s:
            fr, xr, s = force[i - 1], x[i - 1], s_new
        x[i] = xr - s * 10.0 / 1e5 * np.log((s * 10.0 - force[i]) / (s * 10.0 - fr))
    rec = Record(t=t, x=x, u=force, meta={"units": {"x": "m", "u": "N"}})
    path = write_record(rec, tmp_path / "loop.csv")
    res = _run(loop_command, [path, "--kind", "presliding", "--json", "--figure",
                              tmp_path / "l.png"])
    assert res.exit_code == 0, res.output
    # exact Dahl data: σ0 to 1 %
    assert json.loads(res.stdout)["parameters"]["sigma0"]["value"] == pytest.approx(1e5, rel=0.01)
    # a dead zone of 2 mm with 1e4 N/m contact, displacement controlled, sliding at 20 N
    xs = 0.01 * np.sin(2 * np.pi * 0.5 * t)
    f = np.zeros_like(t)
    pos = 0.0  # driven body position
    for i, xi in enumerate(xs):
        d = xi - pos
        if d > 1e-3:
            f[i] = min(1e4 * (d - 1e-3), 20.0)
            pos = max(pos, xi - 1e-3 - 20.0 / 1e4)
        elif d < -1e-3:
            f[i] = max(1e4 * (d + 1e-3), -20.0)
            pos = min(pos, xi + 1e-3 + 20.0 / 1e4)
    rec2 = Record(t=t, x=xs, u=f + 0.01 * np.random.default_rng(1).standard_normal(t.size),
                  meta={"units": {"x": "m", "u": "N"}})
    path2 = write_record(rec2, tmp_path / "bl.csv")
    res = _run(loop_command, [path2, "--kind", "backlash", "--json"])
    assert res.exit_code == 0, res.output
    out = json.loads(res.stdout)
    assert out["parameters"]["gap"]["value"] == pytest.approx(2e-3, rel=0.05)


def test_static_stiffness_and_step_commands(tmp_path):
    loads = np.array([-3.0, -2.0, -1.0, -0.5, 0.5, 1.0, 2.0, 3.0])
    defl = 0.002 * np.sign(loads) + loads / 500.0
    rec = Record(t=np.arange(8.0), x=defl, u=loads, meta={"units": {"x": "rad", "u": "N·m"}})
    path = write_record(rec, tmp_path / "static.csv")
    res = _run(static_stiffness_command, [path, "--backlash", "--json"])
    assert res.exit_code == 0, res.output
    out = json.loads(res.stdout)
    assert out["parameters"]["K"]["value"] == pytest.approx(500.0, rel=1e-6)
    assert out["parameters"]["gap"]["value"] == pytest.approx(0.004, rel=1e-6)
    res = _run(static_stiffness_command, [path, "--json"])
    assert res.exit_code == 0, res.output
    # a square-wave speed command and an underdamped second-order response
    zeta, w0 = 0.2, 20.0
    t = np.arange(8000) / 1000.0
    cmd = np.where((t % 2.0) < 1.0, 1.0, 0.0) + 0.5
    from scipy import signal

    sys2 = signal.lti([w0**2], [1, 2 * zeta * w0, w0**2])
    _, y, _ = signal.lsim(sys2, cmd, t)
    rec = Record(t=t, x=np.cumsum(y) / 1000.0, v=y, u=cmd,
                 meta={"units": {"x": "rad", "u": "N·m", "v": "rad/s"}})
    path = write_record(rec, tmp_path / "step.csv")
    res = _run(step_command, [path, "--t-start", "1.0", "--json"])
    assert res.exit_code == 0, res.output
    assert json.loads(res.stdout)["parameters"]["zeta"]["value"] == pytest.approx(zeta, rel=0.05)


def test_idim_command_campaign_and_aliases(tmp_path):
    paths = []
    for k, sign in enumerate((1.0, -1.0)):
        t = np.arange(8000) / 1000.0
        w = 2 * np.pi * 0.5
        x = sign * (0.2 * t + 0.02 * np.sin(w * t))
        v, a = sign * (0.2 + 0.02 * w * np.cos(w * t)), -sign * 0.02 * w**2 * np.sin(w * t)
        g = 0.5 * np.sin(x * 10)
        u = 4.0 * a + 10.0 * v + 1.0 * np.sign(v) + g
        u = u + 0.01 * np.random.default_rng(k).standard_normal(t.size)
        rec = Record(t=t, x=x, u=u, meta={"units": {"x": "m", "u": "N"}})
        paths.append(write_record(rec, tmp_path / f"run{k}.csv"))
    res = _run(idim_command, [*paths, "--offset", "0", "--regressor", "sin(10*x)",
                              "--cutoff-hz", "20", "--json"])
    assert res.exit_code == 0, res.output
    out = json.loads(res.stdout)
    assert out["parameters"]["M"]["value"] == pytest.approx(4.0, rel=0.02)
    assert out["parameters"]["Fc"]["value"] == pytest.approx(1.0, rel=0.03)
    assert out["parameters"]["k[sin(10*x)]"]["value"] == pytest.approx(0.5, rel=0.03)
    # the old --force-column spelling still names the force column
    res = _run(idim_command, [paths[0], "--force-column", "u", "--offset", "0",
                              "--regressor", "sin(10*x)", "--cutoff-hz", "20"])
    assert res.exit_code == 0, res.output
    res = _run(idim_command, [paths[0], "--regressor", "__import__('os')"])
    assert res.exit_code == 2 and res.output.startswith("error: expression")
    res = _run(idim_command, [paths[0], "--cutoff-hz", "20"])
    assert res.exit_code == 2 and "--offset 0" in res.output


def test_friction_map_command_binned(tmp_path):
    t = np.arange(20000) / 1000.0
    w = 2 * np.pi * 0.5
    x = 0.1 * np.sin(w * t)
    v, a = 0.1 * w * np.cos(w * t), -0.1 * w**2 * np.sin(w * t)
    u = 3.0 * a + np.where(v > 0, 2.0 + 8.0 * v, -1.5 + 6.0 * v)
    u = u + 0.05 * np.random.default_rng(0).standard_normal(t.size)
    path = write_record(Record(t=t, x=x, u=u, meta={"units": {"x": "m", "u": "N"}}),
                        tmp_path / "sine.csv")
    res = _run(friction_map_command, [path, "--inertia", "3", "--models", "coulomb_viscous",
                                      "--min-speed", "0.02", "--json"])
    assert res.exit_code == 0, res.output
    out = json.loads(res.stdout)
    assert out["parameters"]["Fc_plus"]["value"] == pytest.approx(2.0, rel=0.03)
    res = _run(friction_map_command, [path, "--models", "coulomb_viscous"])
    assert res.exit_code == 2 and "error:" in res.output  # a sine has no plateaus


def test_forced_and_envelope_commands(tmp_path):
    from driveid.sim import OscillatorParams, simulate_free_decay

    J, C, K = 1.0, 0.4, 16.0
    paths = []
    for k, om in enumerate((2.0, 4.0, 6.0)):
        t = np.arange(30000) / 1000.0
        h = 1.0 / (K - J * om**2 + 1j * C * om)
        x = np.abs(h) * np.sin(om * t + np.angle(h))
        rec = Record(t=t, x=x, u=np.sin(om * t), meta={"units": {"x": "rad", "u": "N·m"}})
        paths.append(write_record(rec, tmp_path / f"f{k}.csv"))
    res = _run(forced_command, [*paths, "--json"])
    assert res.exit_code == 0, res.output
    assert json.loads(res.stdout)["parameters"]["K"]["value"] == pytest.approx(K, rel=0.02)
    fig_path = tmp_path / "forced.png"
    res = _run(forced_command, [*paths, "--figure", str(fig_path)])
    assert res.exit_code == 0, res.output
    assert fig_path.stat().st_size > 0
    # the figure's run markers are the measured dynamic stiffness, which for this exact linear
    # response lies on the model K - Jω² and at C (2 % as the K check above)
    from driveid.identify.forced.forced import estimate_forced_response
    from driveid.report.forced_figures import plot_forced

    fig = plot_forced(estimate_forced_response([read_record(p) for p in paths]))
    left, right = fig.axes
    w = left.lines[0].get_xdata()
    assert left.lines[0].get_ydata() == pytest.approx(K - J * w**2, rel=0.02, abs=0.02 * K)
    assert right.lines[0].get_ydata() == pytest.approx(C, rel=0.02)
    decay = simulate_free_decay(OscillatorParams(J=1.0, K=16.0, c_mean=0.3, fk_mean=0.05),
                                x0=10.0, duration=20.0, fs=1000.0)
    path = write_record(decay.record, tmp_path / "decay.csv")
    res = _run(envelope_command, [path, "--mass", "1", "--json"])
    assert res.exit_code == 0, res.output
    assert "c_mean" in json.loads(res.stdout)["parameters"]
