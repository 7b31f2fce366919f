"""Velocity-binned friction maps from sinusoidal motion (no plateaus), closed-form truth."""

import numpy as np
import pytest

from driveid.errors import ParameterError, RecordError
from driveid.identify.friction.friction_map import binned_points, estimate_friction_map
from driveid.io.record import Record


def _sine_test(seed: int = 0) -> Record:
    # x = A sin(ωt): the force is the exact inverse model with asymmetric friction
    t = np.arange(20000) / 1000.0
    w = 2 * np.pi * 0.5
    x = 0.1 * np.sin(w * t)
    v, a = 0.1 * w * np.cos(w * t), -0.1 * w**2 * np.sin(w * t)
    fric = np.where(v > 0, 2.0 + 8.0 * v, -1.5 + 6.0 * v)
    u = 3.0 * a + fric + 0.05 * np.random.default_rng(seed).standard_normal(t.size)
    return Record(t=t, x=x, u=u, meta={"units": {"x": "m", "u": "N"}})


def test_binned_map_recovers_branches():
    pts = binned_points(_sine_test(), inertia=3.0, bins=15)
    assert len(pts) == 30
    fm = estimate_friction_map(pts, models=("coulomb_viscous",))
    # sinusoid: filtering at fs/20 = 50 Hz leaves a 0.5 Hz motion exact to ~1e-6; the 3 %
    # bound covers the first bins, whose speeds still carry the filter's edge effects
    assert fm.estimate.value("Fc_plus") == pytest.approx(2.0, rel=0.03)
    assert fm.estimate.value("Fv_plus") == pytest.approx(8.0, rel=0.03)
    assert fm.estimate.value("Fc_minus") == pytest.approx(1.5, rel=0.03)
    assert fm.estimate.value("Fv_minus") == pytest.approx(6.0, rel=0.03)


def test_binned_map_errors():
    rec = _sine_test()
    with pytest.raises(ParameterError, match="inertia must be"):
        binned_points(rec, inertia=-1.0)
    with pytest.raises(ParameterError, match="bins must be"):
        binned_points(rec, inertia=1.0, bins=2)
    with pytest.raises(RecordError, match="needs the applied force"):
        binned_points(Record(t=rec.t, x=rec.x), inertia=1.0)
