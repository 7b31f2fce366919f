"""Friction maps, breakaway and loops on records whose clock is uneven (issue 24).

Truth: closed forms sampled at the uneven instants themselves; the estimators either use the
timestamps (breakaway rates, loops) or resample with a warning (friction map), and must
land where the same physics sampled uniformly lands.
"""

import numpy as np
import pytest

from driveid.errors import RecordWarning
from driveid.identify.forced.loops import estimate_backlash_loop
from driveid.identify.friction.breakaway import estimate_breakaway_sliding
from driveid.identify.friction.friction_map import binned_points, estimate_friction_map
from driveid.io.record import Record

from .test_loops import backlash_test  # noqa: F401  (fixture)


def _uneven_times(n: int, dt: float, seed: int) -> np.ndarray:
    # mostly dt, 15 % early (dt/2), 10 % stalls of 1.5-6.5 dt: a scheduler-driven logger
    rng = np.random.default_rng(seed)
    steps = np.full(n - 1, dt)
    r = rng.random(n - 1)
    steps[r < 0.15] = 0.5 * dt
    stall = r > 0.9
    steps[stall] = dt * rng.uniform(1.5, 6.5, int(stall.sum()))
    return np.concatenate([[0.0], np.cumsum(steps)])


def _sine_map(t: np.ndarray) -> Record:
    w = 2 * np.pi * 0.5
    x = 0.1 * np.sin(w * t)
    v, a = 0.1 * w * np.cos(w * t), -0.1 * w**2 * np.sin(w * t)
    fric = np.where(v > 0, 2.0 + 8.0 * v, -1.5 + 6.0 * v)
    u = 3.0 * a + fric + 0.05 * np.random.default_rng(0).standard_normal(t.size)
    return Record(t=t, x=x, u=u, meta={"units": {"x": "m", "u": "N"}}, max_jitter=None)


def test_friction_map_resamples_an_uneven_clock_with_a_warning():
    rec = _sine_map(_uneven_times(16000, 1e-3, 1))
    with pytest.warns(RecordWarning, match="friction map.*resampled linearly"):
        pts = binned_points(rec, inertia=3.0, bins=15)
    fm = estimate_friction_map(pts, models=("coulomb_viscous",))
    # the uniform record gives these within 3 % (test_friction_map_binned); linear
    # interpolation across stalls of up to 6.5 ms costs little at 0.5 Hz: same 3 %
    assert fm.estimate.value("Fc_plus") == pytest.approx(2.0, rel=0.03)
    assert fm.estimate.value("Fv_plus") == pytest.approx(8.0, rel=0.03)
    assert fm.estimate.value("Fv_minus") == pytest.approx(6.0, rel=0.03)


def _creep_ramp(t: np.ndarray, sign: float) -> Record:
    # force ramps from rest; the body sticks until u reaches 0.05, then slides at a speed
    # growing with the excess force (closed form, no simulator): x = ∫ 20 (|u| - 0.05)⁺ dt
    u = sign * 0.02 * np.clip(t - 0.5, 0.0, None)
    excess = np.clip(np.abs(u) - 0.05, 0.0, None)
    # exact integral of 20 * 0.02 (t - t_b) from the breakaway time t_b = 3 s
    x = sign * 20 * 0.02 * 0.5 * np.clip(t - 3.0, 0.0, None) ** 2
    assert np.all(excess[t < 3.0] == 0)
    return Record(t=t, x=x, u=u + 1e-6 * sign, meta={"units": {"x": "rad", "u": "N·m"}},
                  max_jitter=None)


def test_breakaway_rate_uses_the_timestamps():
    t = _uneven_times(5000, 1e-3, 2)
    t = t[t < 4.0]
    recs = [_creep_ramp(t, s) for s in (1.0, -1.0)]
    est = estimate_breakaway_sliding(recs, v_break=0.02)
    # rate 0.02 rad/s is reached at t_b + 0.02/0.4 = 3.05 s, force 0.02·2.55 = 0.051; the
    # 10-sample window lags by ~5 samples (~7 ms at this clock): 1 % covers it
    assert est.value("fs_plus") == pytest.approx(0.051, rel=0.01)
    assert est.value("fs_minus") == pytest.approx(0.051, rel=0.01)


def test_backlash_loop_ignores_the_clock(backlash_test):  # noqa: F811
    # the loop is force against displacement in sample order: keeping every other sample
    # and jittering the instants gives the same gap and stiffness
    rec = backlash_test
    keep = np.sort(np.random.default_rng(4).choice(rec.n, rec.n // 2, replace=False))
    uneven = Record(t=rec.t[keep], x=rec.x[keep], u=rec.u[keep], meta=rec.meta,
                    max_jitter=None)
    assert uneven.jitter() > 1.0
    a, b = estimate_backlash_loop(rec), estimate_backlash_loop(uneven)
    # half the samples on the contact lines: within 3 combined standard errors
    for name in ("gap", "K"):
        err = 3 * np.hypot(a.stderr(name), b.stderr(name))
        assert abs(a.value(name) - b.value(name)) < err, (name, a.value(name), b.value(name))
