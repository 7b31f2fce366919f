"""Friction ripple periodic in position, lazy result bookkeeping, reused batch buffers, and
the import order of driveid.sim (types at the bottom, engines, simulate_drive, batch)."""

import ast
import math
from pathlib import Path

import numpy as np
import pytest

from driveid.errors import ParameterError
from driveid.sim import simulate_free_decay_batch
from driveid.sim.drive import BodyParams, DriveParams, simulate_drive

RIPPLE = dict(ripple_amplitude=0.05, ripple_period=0.25, ripple_phase=0.3)


def test_ripple_at_constant_speed_matches_the_closed_form():
    # feeding forward exactly the friction of the closed form, c v0 + fk + A sin(2π v0 t/P + φ),
    # keeps the body at v0: any other friction law would make it speed up or slow down
    J, c, fk, v0, fs = 2.0, 0.1, 0.2, 1.5, 10_000.0
    body = BodyParams(J=J, c_mean=c, fk_mean=fk, **RIPPLE)
    t = np.arange(int(1.0 * fs) + 1) / fs
    phase = 2 * math.pi * v0 * t / RIPPLE["ripple_period"] + RIPPLE["ripple_phase"]
    torque = (c * v0 + fk + RIPPLE["ripple_amplitude"] * np.sin(phase))[None, :]
    res = simulate_drive(DriveParams(bodies=(body,)), duration=1.0, fs=fs, v0=[v0],
                         torque=torque, method="rk4")
    # the kernel interpolates the sampled torque linearly: error <= A (Ω/fs)²/8 = 9e-8 N·m
    # with Ω = 2π v0/P = 38 rad/s, alternating in sign, so |Δv| <= 9e-8/(J Ω) ~ 1e-9 m/s
    assert np.max(np.abs(res.v[0] - v0)) < 1e-7
    assert np.max(np.abs(res.x[0] - v0 * t)) < 1e-7


def test_ripple_work_gives_the_speed_along_the_slide():
    # a free slide (no spring, no viscous term) loses exactly the friction work:
    # ½ J v² = ½ J v0² - fk Δx - A P/(2π) [cos φ - cos(2π x/P + φ)]
    J, fk, v0 = 1.0, 0.2, 2.0
    a, p, phi = 0.1, 0.3, 0.7
    body = BodyParams(J=J, fk_mean=fk, ripple_amplitude=a, ripple_period=p, ripple_phase=phi)
    res = simulate_drive(DriveParams(bodies=(body,)), duration=12.0, fs=1000.0, v0=[v0])
    x, v = res.x[0], res.v[0]
    work = fk * x + a * p / (2 * math.pi) * (math.cos(phi) - np.cos(2 * math.pi * x / p + phi))
    moving = v > 0
    assert moving.any() and not moving[-1]  # it slid, then stuck
    # RK4 at h = 1 ms on a ripple of Ω = 2π v/P <= 42 rad/s: local error ~ (Ω h)^5/120 ~ 1e-9
    assert np.max(np.abs(0.5 * J * v[moving] ** 2 - (0.5 * J * v0**2 - work[moving]))) < 1e-6
    stop = x[-1]  # where the speed of the closed form reaches zero
    assert 0.5 * J * v0**2 == pytest.approx(fk * stop + a * p / (2 * math.pi) * (
        math.cos(phi) - math.cos(2 * math.pi * stop / p + phi)), abs=1e-6)
    e = res.energy  # the balance, computed on first access, books the ripple as dissipated
    assert np.max(np.abs(e["initial"] + e["input"] - e["kinetic"] - e["potential"]
                         - e["dissipated"])) < 1e-9


def test_ripple_rules():
    body = BodyParams(J=1.0, fk_mean=0.2, **RIPPLE)
    assert body.fs_mean == pytest.approx(0.25)  # the static default holds the kinetic peak
    assert body.has_ripple and not BodyParams(J=1.0).has_ripple
    with pytest.raises(ParameterError, match="ripple_amplitude must be in"):
        BodyParams(J=1.0, fk_mean=0.01, **RIPPLE)
    with pytest.raises(ParameterError, match="ripple_period"):
        BodyParams(J=1.0, fk_mean=0.2, ripple_amplitude=0.05)
    with pytest.raises(ParameterError, match="static friction must hold"):
        BodyParams(J=1.0, fk_mean=0.2, fs_mean=0.2, **RIPPLE)
    spring = DriveParams(bodies=(BodyParams(J=1.0, K=16.0, fk_mean=0.2, **RIPPLE),))
    with pytest.raises(ParameterError, match="ripple"):
        simulate_drive(spring, duration=1.0, x0=[1.0], method="exact")
    # "auto" falls back to RK4 for a rippled body and still conserves energy
    res = simulate_drive(spring, duration=3.0, x0=[1.0])
    e = res.energy
    assert np.max(np.abs(e["initial"] + e["input"] - e["kinetic"] - e["potential"]
                         - e["dissipated"])) < 1e-9


def test_constant_input_runs_equal_sampled_ones():
    # a constant torque goes to the kernel as one column; the result must not change
    drive = DriveParams(bodies=(BodyParams(J=1.0, K=16.0, c_mean=0.3, fk_mean=0.07),))
    one = simulate_drive(drive, duration=2.0, x0=[1.0], torque=[0.1], method="rk4")
    grid = simulate_drive(drive, duration=2.0, x0=[1.0], torque=np.full((1, 2001), 0.1),
                          method="rk4")
    assert np.array_equal(one.x, grid.x) and np.array_equal(one.v, grid.v)


@pytest.mark.parametrize("rtol", [None, 1e-9])
def test_energy_integrals_are_integrated_only_when_read(rtol):
    # simulate_drive runs the kernel on positions and velocities; reading result.energy runs
    # it again with the three energy integrals. They do not feed back, so the trajectory of
    # both runs must be the same to the bit (also with strides, whose estimate skips them).
    from driveid.sim.drive import _prepare, _run_kernel

    from .test_drive import _w3

    drive = _w3()
    run = _prepare(drive, 2.0, 1000.0, None, None, None, None, 2.5e-5, 200, rtol)
    fast, full = _run_kernel(run, 200), _run_kernel(run, 200, energy=True)
    assert fast[3] is None and full[3].shape == (6, 2001)
    assert np.array_equal(fast[0], full[0]) and np.array_equal(fast[1], full[1])
    assert np.array_equal(fast[2], full[2]) and np.array_equal(fast[4], full[4])
    res = simulate_drive(drive, duration=2.0, max_step=2.5e-5, rtol=rtol)
    e = res.energy  # the second run, with the integrals: the balance closes
    residual = e["initial"] + e["input"] - e["kinetic"] - e["potential"] - e["dissipated"]
    # 1.7e-9 of the input work (RK4 at h = 25 us; the contact release is booked as
    # dissipated): a hundred times that margin, far below any bookkeeping slip (~1e-2)
    assert np.max(np.abs(residual)) < 2e-7 * np.max(np.abs(e["input"]))


def test_free_decay_batch_writes_into_the_callers_buffer():
    kw = dict(J=1.0, K=16.0, c_mean=[0.3, 0.4], fk_mean=0.07, x0=1.0, duration=2.0)
    fresh = simulate_free_decay_batch(**kw, return_velocity=True)
    buf, vbuf = np.full((2, 2001), np.nan), np.full((2, 2001), np.nan)
    again = simulate_free_decay_batch(**kw, return_velocity=True, out=buf, v_out=vbuf)
    assert again.x is buf and again.v is vbuf
    assert np.array_equal(buf, fresh.x) and np.array_equal(vbuf, fresh.v)
    with pytest.raises(ParameterError, match="out must be a writeable"):
        simulate_free_decay_batch(**kw, out=np.empty((2, 2000)))


def _sim_imports(path: Path) -> set[str]:
    """driveid.sim modules imported anywhere in a file (also inside functions)."""
    found = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.ImportFrom) and node.module:
            if node.module == "driveid.sim":
                found |= {f"driveid.sim.{a.name}" for a in node.names}
            elif node.module.startswith("driveid.sim."):
                found.add(node.module)
        elif isinstance(node, ast.Import):
            found |= {a.name for a in node.names if a.name.startswith("driveid.sim.")}
    return found


def test_the_simulator_has_no_import_circle():
    root = Path(__file__).resolve().parents[2] / "src" / "driveid" / "sim"
    graph = {f"driveid.sim.{p.stem}": _sim_imports(p) for p in root.glob("*.py")
             if p.stem != "__init__"}
    state: dict[str, int] = {}

    def visit(node, trail):
        if state.get(node) == 1:
            raise AssertionError("import circle: " + " -> ".join(trail + [node]))
        if state.get(node) == 2 or node not in graph:
            return
        state[node] = 1
        for nxt in sorted(graph[node]):
            visit(nxt, trail + [node])
        state[node] = 2

    for module in graph:
        visit(module, [])
    assert "driveid.sim.drive" not in graph["driveid.sim.drive_types"]
    assert "driveid.sim.drive" not in graph["driveid.sim._smooth"]


def test_ripple_from_a_config_table():
    from driveid.sim.config import parse_drive_config

    params, _ = parse_drive_config({"body": [{"J": 1.0, "fk_mean": 0.2, **RIPPLE}]})
    body = params.bodies[0]
    assert (body.ripple_amplitude, body.ripple_period, body.ripple_phase) == (0.05, 0.25, 0.3)
