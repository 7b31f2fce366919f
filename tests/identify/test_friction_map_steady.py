"""Steady plateaus that settle slowly (first-order speed response, τ = 1.4 s)."""

import numpy as np
import pytest

from driveid.identify.friction.friction_map import estimate_friction_map, steady_points
from driveid.io.record import Record
from driveid.signal.steady import find_steady_segments

TAU = 1.4  # s, the servo bench of issue 14


def _first_order_plateaus(fs: float = 100.0, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    t = np.arange(int(40 * fs)) / fs
    levels = np.array([0.0, 10.0, 20.0, 30.0, 40.0])
    target = levels[np.minimum(t // 8, 4).astype(int)]
    v = np.zeros_like(t)
    for i in range(1, t.size):  # exact discretisation of dv/dt = (target − v)/τ
        v[i] = target[i] + (v[i - 1] - target[i]) * np.exp(-1.0 / (TAU * fs))
    return t, v + 0.05 * np.random.default_rng(seed).standard_normal(t.size)


def _levels_found(v: np.ndarray, segs: list[tuple[int, int]]) -> set[int]:
    return {int(round(float(v[a:b].mean()) / 10.0)) for a, b in segs}


def test_slowly_settling_plateaus_are_found():
    _, v = _first_order_plateaus()
    segs = find_steady_segments(v, rel_tol=0.02)
    assert _levels_found(v, segs) == {0, 1, 2, 3, 4}
    for a, b in segs:
        # every kept piece has settled: within 2 % (the tolerance) of its level
        level = 10.0 * round(float(v[a:b].mean()) / 10.0)
        assert abs(float(v[a:b].mean()) - level) <= 0.02 * max(level, 1.0)


def test_larger_tolerance_never_finds_fewer_plateaus():
    _, v = _first_order_plateaus(seed=1)
    found = [len(_levels_found(v, find_steady_segments(v, rel_tol=tol)))
             for tol in (0.005, 0.01, 0.02, 0.05, 0.1)]
    assert found == sorted(found), found


def test_friction_map_from_first_order_steps():
    # u = Fc + Fv·v at the settled speeds, per direction
    t, v = _first_order_plateaus()
    recs = []
    for sign in (1.0, -1.0):
        u = sign * (0.5 + 0.02 * np.abs(v)) + 0.01 * np.random.default_rng(2).standard_normal(
            v.size)
        u[np.abs(v) < 1.0] = 0.0  # standstill before the first step
        recs.append(Record(t=t, x=np.cumsum(sign * v) / 100.0, v=sign * v, u=u,
                           meta={"units": {"x": "rad", "u": "N·m", "v": "rad/s"}}))
    pts = [p for r in recs for p in steady_points(r)]
    fm = estimate_friction_map(pts, models=("coulomb_viscous",))
    # the settled points lie on the line to the noise: 2 % covers the settling residue
    assert fm.estimate.value("Fc_plus") == pytest.approx(0.5, rel=0.02)
    assert fm.estimate.value("Fv_minus") == pytest.approx(0.02, rel=0.02)
