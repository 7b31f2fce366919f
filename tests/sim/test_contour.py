"""The circle-test simulator against closed forms (issue 27, acceptance (a)).

Truth: for linear axes (a mass with viscous damping, no friction, no backlash) under the
sampled PID with feed-forward, the table's steady response to the circle's sinusoidal
references is the closed-loop frequency response at ω = feed/radius. Both axes alike, the
steady radius is ``R |G|`` exactly at the samples for the sampled-data loop (zero-order hold,
``G`` of the ZOH-discretised plant and the discrete PID), and ``R |G_c(jω)|`` within O(ωT)
for the continuous transfer function.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from driveid.errors import ConfigError, ParameterError
from driveid.sim.contour import (
    AxisCompensation,
    circle_reference,
    closed_loop_gain,
    simulate_contour,
)
from driveid.sim.contour_config import (
    CirclePath,
    ControllerParams,
    load_contour_config,
    parse_contour_config,
)

EXAMPLE = "examples/drive_configs/contour_xy.toml"


def closed_loop_discrete(J, c, kp, kd, ki, kv, ka, rate, omega):
    return closed_loop_gain(J, c, ControllerParams(kp=kp, kd=kd, ki=ki, kv=kv, ka=ka,
                                                   rate=rate), omega)


def closed_loop_continuous(J, c, kp, kd, ki, kv, ka, omega):
    s = 1j * omega
    return (kp + ki / s + (kd + kv) * s + ka * s**2) / (J * s**2 + c * s + kp + ki / s + kd * s)


LINEAR = {"J": 50.0, "c": 100.0, "kp": 2e5, "kd": 6e3, "ki": 1e6, "kv": 0.0, "ka": 0.0}


def _linear_config(rate, radius=0.01, feed=0.3, **gains):
    g = {**LINEAR, **gains}
    axis = {"body": [{"J": g["J"], "c_mean": g["c"]}],
            "controller": {"kp": g["kp"], "kd": g["kd"], "ki": g["ki"], "kv": g["kv"],
                           "ka": g["ka"], "rate": rate}}
    return g, parse_contour_config({"x": axis, "y": axis, "path": {
        "radius": radius, "feed": feed, "revolutions": 6.0, "fs": rate, "ramp": 0.02}})


def _steady_radius(res):
    m = res.metrics
    idx = np.flatnonzero(m["steady"])
    # the start transient decays with the slowest closed-loop pole (about 6 1/s here): over
    # the last fifth of six turns it is below 2e-4 of the radius error
    tail = idx[4 * idx.size // 5:]
    return m["radial"][tail]


@pytest.mark.parametrize("feed,radius", [(0.3, 0.01), (0.15, 0.02)])
def test_linear_axes_radius_is_closed_loop_gain(feed, radius):
    g, cfg = _linear_config(2000.0, radius=radius, feed=feed)
    omega = feed / radius
    G = closed_loop_discrete(g["J"], g["c"], g["kp"], g["kd"], g["ki"], g["kv"], g["ka"],
                             2000.0, omega)
    dr = _steady_radius(simulate_contour(cfg))
    expected = radius * (abs(G) - 1.0)
    assert abs(expected) > 1e-4 * radius  # the test sees a real radius error
    # the RK4 kernel is exact to ~1e-10 of the radius; the left-over start transient
    # stays below 2e-4 of the deviation, so 1e-3 is a tight closed-form check
    assert np.max(np.abs(dr - expected)) < 1e-3 * abs(expected)
    # the continuous transfer function differs by the hold's half-sample delay, O(ωT)
    Gc = closed_loop_continuous(g["J"], g["c"], g["kp"], g["kd"], g["ki"], g["kv"], g["ka"],
                                omega)
    assert abs(np.mean(dr) - radius * (abs(Gc) - 1.0)) < 3 * omega / 2000.0 * radius


def test_sampled_gain_tends_to_the_continuous_transfer_function():
    # independent of the code under test: the test's own continuous closed form, and the
    # sampled loop's deviation from it shrinks like the hold's delay, O(ωT)
    g = LINEAR
    Gc = closed_loop_continuous(g["J"], g["c"], g["kp"], g["kd"], g["ki"], 0.0, 0.0, 30.0)
    errors = [abs(closed_loop_discrete(g["J"], g["c"], g["kp"], g["kd"], g["ki"], 0.0, 0.0,
                                       rate, 30.0) - Gc) for rate in (1e3, 1e4, 1e5)]
    assert errors[2] < errors[1] / 5 < errors[0] / 25  # first order: 10x per decade
    assert errors[2] < 30.0 / 1e5  # |ΔG| ~ ωT/2


def test_feed_forward_cancels_the_radius_error():
    # ka = J and kv = c make G = 1 in continuous time; the sampled loop leaves O((ωT)²)
    g, cfg = _linear_config(2000.0, kv=100.0, ka=50.0)
    dr = _steady_radius(simulate_contour(cfg))
    G = closed_loop_discrete(g["J"], g["c"], g["kp"], g["kd"], g["ki"], 100.0, 50.0, 2000.0,
                             30.0)
    assert np.max(np.abs(dr - 0.01 * (abs(G) - 1))) < 1e-3 * 0.01 * abs(abs(G) - 1) + 1e-12
    assert np.max(np.abs(dr)) < 0.01 * (30.0 / 2000.0)  # far below the uncompensated error


def test_reference_is_the_circle_with_its_derivatives():
    path = CirclePath(radius=0.05, feed=0.1, ramp=0.05, revolutions=1.0)
    t = np.linspace(0, path.duration, 20001)
    ref = circle_reference(path, t)
    assert np.allclose(np.hypot(ref["p1"], ref["p2"]), 0.05, rtol=0, atol=1e-15)
    # finite differences agree with the closed-form velocity and acceleration (h = 1.6e-4 s)
    h = t[1] - t[0]
    # away from the ends of the ramps, where the raised cosine's jerk steps (a central
    # difference across a jerk step errs by ~h·jerk/4, 8e-3 m/s² here)
    smooth = np.ones(t.size, bool)
    smooth[[0, -1]] = False
    for edge in (path.ramp, path.ramp + path.constant_feed):
        smooth &= np.abs(t - edge) > 3 * h
    for k in ("1", "2"):
        assert np.allclose(np.gradient(ref["p" + k], h)[smooth], ref["v" + k][smooth],
                           rtol=0, atol=1e-6)
        assert np.allclose(np.gradient(ref["v" + k], h)[smooth], ref["a" + k][smooth],
                           rtol=0, atol=1e-4)  # h²/6 times the 4th derivative in the ramps: ~5e-5
    speed = np.hypot(ref["v1"], ref["v2"])
    steady = (t > path.ramp) & (t < path.ramp + path.constant_feed)
    assert np.allclose(speed[steady], 0.1, atol=1e-12)
    assert speed[0] == 0.0 and speed[-1] < 1e-12


def test_friction_makes_four_outward_glitches_and_compensation_removes_them():
    cfg = load_contour_config(EXAMPLE)
    res = simulate_contour(cfg)
    glitches = res.metrics["glitches"]
    assert [g["axis"] for g in glitches] == ["y", "x", "y", "x"]
    # each glitch peaks just after its reversal (90, 180, 270, 360 deg; within 10 deg)
    for g, where in zip(glitches, (90.0, 180.0, 270.0, 0.0), strict=True):
        assert abs((g["where_deg"] - where + 180) % 360 - 180) < 10
        assert g["height"] > 5e-6  # outward, micrometres (fk/kp ~ 15 µm)
    comp = {"x": AxisCompensation(fk_mean=59.0, fk_delta=6.0, c_mean=270.0, gap=12e-6),
            "y": AxisCompensation(fk_mean=43.0, fk_delta=-3.0, c_mean=195.0, gap=8e-6)}
    better = simulate_contour(cfg, compensation=comp)
    # the true model compensated: the glitches shrink by more than 10x
    assert better.metrics["peak"] < res.metrics["peak"] / 10


def test_columns_and_noise_are_seeded():
    cfg = load_contour_config(EXAMPLE)
    path = CirclePath(radius=0.01, feed=0.05, revolutions=0.3, fs=2000.0)
    res = simulate_contour(type(cfg)(axes=cfg.axes, path=path, noise=cfg.noise))
    a, b = res.columns(cfg.noise), res.columns(cfg.noise)
    assert list(a) == ["t", "x_ref", "y_ref", "x", "y", "x_motor", "y_motor", "u_x", "u_y"]
    assert np.array_equal(a["x"], b["x"])
    assert 0.5e-7 < np.std(a["x"] - res.position["x"]) < 2e-7  # the configured 1e-7 m


def test_config_errors_name_the_key():
    axis = {"body": [{"J": 50.0}], "controller": {"kp": 1e6, "kd": 1e4}}
    with pytest.raises(ConfigError, match="y.controller: missing kd"):
        parse_contour_config({"x": axis, "y": {"body": [{"J": 1.0}],
                                               "controller": {"kp": 1.0}},
                              "path": {"radius": 0.1, "feed": 0.1}})
    with pytest.raises(ConfigError, match="path: missing radius"):
        parse_contour_config({"x": axis, "y": axis, "path": {"feed": 0.1}})
    with pytest.raises(ConfigError, match="plane 'xy' needs the axes"):
        parse_contour_config({"x": axis, "path": {"radius": 0.1, "feed": 0.1}})
    with pytest.raises(ConfigError, match="direction"):
        parse_contour_config({"x": axis, "y": axis, "path": {"radius": 0.1, "feed": 0.1,
                                                             "direction": "up"}})
    with pytest.raises(ConfigError, match=r"x: body\[1\].J"):
        parse_contour_config({"x": {"body": [{"J": -1.0}], "controller": axis["controller"]},
                              "y": axis, "path": {"radius": 0.1, "feed": 0.1}})


def test_rate_mismatch_and_unknown_compensation_axis_are_refused():
    axis = {"body": [{"J": 50.0}], "controller": {"kp": 1e6, "kd": 1e4, "rate": 1500.0}}
    cfg = parse_contour_config({"x": axis, "y": axis, "path": {
        "radius": 0.01, "feed": 0.05, "fs": 1000.0, "revolutions": 0.1}})
    with pytest.raises(ParameterError, match="must be an integer"):
        simulate_contour(cfg)
    with pytest.raises(ParameterError, match="compensation names axes"):
        simulate_contour(cfg, compensation={"z": AxisCompensation()})
    assert math.isfinite(cfg.path.duration)


def test_third_axis_off_the_plane_holds_still():
    axis = {"body": [{"J": 50.0, "c_mean": 100.0, "fk_mean": 20.0}],
            "controller": {"kp": 2e6, "kd": 1.5e4, "ki": 3e7, "rate": 1000.0}}
    cfg = parse_contour_config({"x": axis, "y": axis, "z": axis, "path": {
        "radius": 0.02, "feed": 0.05, "revolutions": 0.3, "fs": 1000.0, "plane": "yz"}})
    res = simulate_contour(cfg)
    assert list(res.columns())[:4] == ["t", "x_ref", "y_ref", "z_ref"]
    assert np.all(res.reference["x"] == 0.0)
    # the off-plane axis only sees its own start: it never leaves the origin (friction holds
    # it exactly; nothing drives it)
    assert np.max(np.abs(res.position["x"])) == 0.0
    # the plane's first axis (y) starts at R cos 45°, its second (z) at R sin 45°
    assert res.reference["y"][0] == pytest.approx(0.02 * math.cos(math.pi / 4), abs=1e-15)
    assert res.reference["z"][0] == pytest.approx(0.02 * math.sin(math.pi / 4), abs=1e-15)
