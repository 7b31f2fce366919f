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


def test_plateau_force_error_bar_is_honest_under_low_pass_noise():
    # issue 24: force noise through a 4th-order 25 Hz low-pass at 500 Hz on constant-speed
    # plateaus; the lag-1 (AR(1)) effective count made the mean's s.e. 3x too wide
    # (benchmarks/bench_noise_coverage_fits.py: friction-map sd/se 0.31-0.35); the AR(p)
    # long-run variance is right to a few %. 150 plateaus: the sd of an sd estimate is
    # 1/sqrt(2·150) = 6 %, so [0.8, 1.25] is ~3.5 sd wide on each side
    from scipy.signal import butter, lfilter

    from driveid.identify.friction.friction_map import _plateau_mean
    from driveid.signal.steady import segment_mean

    rng = np.random.default_rng(11)
    b, a = butter(4, 25.0 / 250.0)
    means, se_new, se_old = [], [], []
    for _ in range(150):
        n = int(rng.integers(500, 751))
        y = 3.0 + lfilter(b, a, rng.standard_normal(n + 2000))[2000:]
        m, s = _plateau_mean(y)
        means.append(m)
        se_new.append(s)
        se_old.append(segment_mean(y)[1])
    sd = float(np.std(means))
    assert 0.8 < sd / np.mean(se_new) < 1.25
    assert sd / np.mean(se_old) < 0.5  # the old error bar, for contrast


def test_plateau_force_error_bar_is_honest_under_mains_hum():
    # issue 24: a 50 Hz line (70 % of the variance, random phase) plus white noise at
    # 500 Hz. A line of 10 samples a period made the AR model seasonal with a pole near
    # zero frequency: error bars 1.9x the scatter (friction-map sd/se 0.55-0.58). With the
    # line found and fitted beside the mean, within a few %. 150 plateaus: [0.8, 1.25]
    # as above; the plateau lengths vary, so the line is not always a whole number of
    # periods
    from driveid.identify.core._noise import spectral_lines
    from driveid.identify.friction.friction_map import _plateau_mean

    rng = np.random.default_rng(12)
    means, ses = [], []
    for _ in range(150):
        n = int(rng.integers(500, 751))
        t = np.arange(n) / 500.0
        y = (3.0 + np.sqrt(1.4) * np.sin(2 * np.pi * 50.0 * t + rng.uniform(0, 2 * np.pi))
             + np.sqrt(0.3) * rng.standard_normal(n))
        m, s = _plateau_mean(y)
        means.append(m)
        ses.append(s)
    assert 0.8 < float(np.std(means)) / np.mean(ses) < 1.25
    # the line is found at 50 Hz (0.1 cycles a sample, to the Fourier resolution 1/n)
    assert spectral_lines(y)[0] == pytest.approx(0.1, abs=1.0 / n)
    # and white noise has none (the threshold's false-line rate is well under 1 %)
    assert sum(bool(spectral_lines(rng.standard_normal(750))) for _ in range(100)) <= 1


def test_plateau_means_drifting_between_plateaus_are_warned():
    # issue 24: a slow wander of the force that spans plateaus (1/f-like, here a random walk
    # of 0.3 N rms across the record) moves whole plateau means together; the map's
    # intervals then miss, so the fit must say so. Without the drift: no such warning
    from driveid.identify.friction.friction_map import _scatter_warning

    rng = np.random.default_rng(2)
    speeds = np.array([0.01, 0.02, 0.04, 0.07, 0.1])
    se = np.full(speeds.size, 0.02)  # each plateau mean's own error bar [N]

    def branch(drift):
        from driveid.identify.friction.friction_map import _fit_branch
        from driveid.signal.steady import SteadySegment

        force = 3.0 + 50.0 * speeds + se * rng.standard_normal(speeds.size) + drift
        pts = [SteadySegment(0, 100, v, 1e-4, f, s, 100)
               for v, f, s in zip(speeds, force, se, strict=True)]
        return _fit_branch("coulomb_viscous", pts)

    drifted = branch(np.cumsum(0.3 * rng.standard_normal(speeds.size)))
    assert _scatter_warning("coulomb_viscous", "plus", drifted)
    # honest plateaus: chi2 with 3 dof exceeds its 1 % point in 1 % of cases; seeded here
    assert not _scatter_warning("coulomb_viscous", "plus", branch(0.0))


def test_scattered_branch_error_bars_carry_students_t():
    # closed form: a straight-line fit of 5 points with known error bars. Where the χ²
    # test flags the scatter, the standard errors are the Birge-scaled least-squares ones
    # times t_{0.975,3}/1.96 = 3.182/1.960 (Student's interval from 3 degrees of freedom)
    from driveid.identify.friction.friction_map import SCATTER_P, _fit_branch
    from driveid.signal.steady import SteadySegment

    speeds = np.array([0.01, 0.02, 0.04, 0.07, 0.1])
    se = np.full(speeds.size, 0.02)
    wander = np.array([0.3, -0.2, 0.25, -0.3, 0.1])  # far beyond the 0.02 N error bars
    pts = [SteadySegment(0, 100, v, 1e-4, 3.0 + 50.0 * v + w, s, 100)
           for v, w, s in zip(speeds, wander, se, strict=True)]
    res = _fit_branch("coulomb_viscous", pts)
    assert res["scatter_p"] < SCATTER_P
    a = np.column_stack([np.ones(5), speeds]) / se[:, None]
    plain = np.sqrt(np.diag(np.linalg.inv(a.T @ a) * res["chi2_red"]))
    factor = 3.182446305284263 / 1.959964
    assert res["stderr"]["Fc"] == pytest.approx(plain[0] * factor, rel=1e-5)
    assert res["stderr"]["Fv"] == pytest.approx(plain[1] * factor, rel=1e-5)
