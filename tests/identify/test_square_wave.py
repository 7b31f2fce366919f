"""J, C, K, kinetic and static friction from DC-biased square waves (simulated truth)."""

import numpy as np
import pytest

from driveid.errors import IdentificationError, RecordError
from driveid.identify.friction.square_wave import estimate_square_wave
from driveid.io.record import Record
from driveid.signal.excitation import square_wave
from driveid.sim import BodyParams, DriveParams, simulate_drive

TRUTH = dict(J=0.0115, K=5.0, c_mean=0.01, c_delta=0.002, fk_mean=0.1, fk_delta=0.02,
             fs_mean=0.15, fs_delta=0.02)
DRIVE = DriveParams(bodies=(BodyParams(**TRUTH),))


def _runs(levels, fs=2000.0):
    out = []
    for amp, bias in levels:
        sig = square_wave(frequency=1.0, duration=4, fs=fs, amplitude=amp, bias=bias)
        r = simulate_drive(DRIVE, duration=(sig.t.size - 1) / fs, fs=fs,
                           torque=sig.u[None, :])
        out.append(Record(t=r.t, x=r.x[0], u=sig.u))
    return out


LARGE = [(0.8, 0.1), (0.3, 0.05), (0.5, -0.1)]


@pytest.fixture(scope="module")
def large_runs():
    return _runs(LARGE)


def test_recovers_J_C_K_and_kinetic_friction(large_runs):
    est = estimate_square_wave(large_runs)
    # exact simulator, no noise: the only error is the Savitzky-Golay derivative (quintic,
    # 10 ms window) on the ringing at 3.3 Hz, measured below 4e-7 relative for all six
    for name in ("J", "c_mean", "c_delta", "K", "fk_mean", "fk_delta"):
        assert est.value(name) == pytest.approx(TRUTH[name], rel=1e-5), name


def test_standard_errors_cover_with_noise(large_runs):
    # Seeded Monte Carlo over position noise (sd 2e-5 rad, ~ a 20-bit encoder's quantum
    # times 3) on the same simulated runs: the 2σ intervals should cover >= 95 %; the
    # window inflation of the covariance is conservative, so with 12 repeats we ask
    # >= 10/12 per parameter (a binomial 95 % process fails that with probability 2 %).
    rng = np.random.default_rng(7)
    hits = dict.fromkeys(("J", "c_mean", "K", "fk_mean"), 0)
    for _ in range(12):
        noisy = [Record(t=r.t, x=r.x + 2e-5 * rng.standard_normal(r.n), u=r.u)
                 for r in large_runs]
        est = estimate_square_wave(noisy, smooth=0.02)
        for name in hits:
            hits[name] += abs(est.value(name) - TRUTH[name]) <= 2 * est.stderr(name)
    assert min(hits.values()) >= 10, hits


def test_static_friction_bracketed_by_stuck_half_periods():
    # staircase of small square waves: amplitudes 0.10 ... 0.20 N·m in 0.01 steps, bias 0.
    # Breakaway levels: +(fs_mean + fs_delta) = 0.17, -(fs_mean - fs_delta) = -0.13.
    runs = _runs([(a, 0.0) for a in np.arange(0.10, 0.205, 0.01)] + LARGE[:1], fs=1000.0)
    est = estimate_square_wave(runs)
    assert est.diagnostics["n_stuck"] > 0
    plus, minus = est.data_used["static_brackets"].values()
    assert plus[0] <= 0.17 <= plus[1] and minus[0] <= 0.13 <= minus[1]
    # the bracket is at most one amplitude step (0.01) plus the spring's share; the
    # midpoint is then within 2 of its uniform-distribution standard errors
    for name in ("fs_mean", "fs_delta"):
        assert abs(est.value(name) - TRUTH[name]) <= 2 * est.stderr(name) + 1e-12, name


def test_errors():
    t = np.arange(100) / 100
    with pytest.raises(RecordError, match="input u"):
        estimate_square_wave(Record(t=t, x=np.sin(t)))
    with pytest.raises(IdentificationError, match="moving samples"):
        estimate_square_wave(Record(t=t, x=np.zeros(100), u=np.sign(np.sin(9 * t))))
