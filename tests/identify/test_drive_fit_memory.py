"""The whole-drive fit estimates the frictional memory of a body (Eq. 2.12, issue 25 item 4)."""

from __future__ import annotations

import numpy as np
import pytest

from driveid.errors import ParameterError
from driveid.identify.drive._drive_model import parameter_names, parameter_unit, with_values
from driveid.identify.drive.drive_fit import DriveRecord, estimate_drive
from driveid.sim import simulate_drive
from driveid.sim.drive import BodyParams, DriveParams

_ZERO = np.zeros(1)
_NOISE = 1e-4  # position noise [rad]
_TRUTH = DriveParams(bodies=(BodyParams(J=0.01, c_mean=0.02, fk_mean=0.1, fs_mean=0.25,
                                        fs_delta=0.03, stribeck="lorentzian", v_s=0.3,
                                        v_s_delta=0.05, memory=0.02),))
_NAMES = ["body1.fs_mean", "body1.v_s", "body1.memory"]
_TRUE = {"body1.fs_mean": 0.25, "body1.v_s": 0.3, "body1.memory": 0.02}


@pytest.fixture(scope="module")
def motion():
    """Open loop, two sines: 13 stick-slip switches in 4 s (the memory moves x by 0.08 rad)."""
    t = np.arange(4001) / 1000.0
    u = 0.3 * np.sin(2 * np.pi * 1.0 * t) + 0.1 * np.sin(2 * np.pi * 2.7 * t)
    res = simulate_drive(_TRUTH, duration=4.0, fs=1000.0, torque=u[None])
    return res.t, res.x[0], u


def _record(motion, seed: int) -> DriveRecord:
    t, x, u = motion
    rng = np.random.default_rng(seed)
    return DriveRecord(t=t, channels={"x1": x + rng.normal(0, _NOISE, t.size)}, u=u)


def _start(memory: float) -> DriveParams:
    """The truth with fs_mean 30 % low, v_s 30 % high and the given memory."""
    start, _, _ = with_values(_TRUTH, _ZERO, _ZERO, {"body1.fs_mean": 0.25 * 0.7,
                                                     "body1.v_s": 0.3 * 1.3,
                                                     "body1.memory": memory})
    return start


@pytest.mark.parametrize("off", [-0.3, 0.3])
def test_memory_with_the_stribeck_map_from_30_percent_off(motion, off):
    est = estimate_drive(_record(motion, 3), _start(0.02 * (1 + off)), estimate=_NAMES,
                         x0=[0.0], v0=[0.0], starts_from_record=False)
    for name, true in _TRUE.items():
        # the fit reaches the noise (1e-4 rad rms): observed errors <= 1.1e-4 relative (v_s;
        # the memory 6e-6) and 1.4 standard errors; 1 % is issue 25's friction tolerance
        # (10 %) tightened to what this noise allows, far below the 30 % start offset; 4
        # standard errors catches error bars that are too small
        assert est.value(name) == pytest.approx(true, rel=0.01), name
        assert abs(est.value(name) - true) < 4 * est.stderr(name), name
    assert est["body1.memory"].unit == "s"
    # the drive written back carries it (simulate drive reads the key)
    lines = [ln for ln in est.diagnostics["model_toml"].splitlines()
             if ln.startswith("memory = ")]
    assert len(lines) == 1
    assert float(lines[0].split()[2]) == pytest.approx(est.value("body1.memory"))


def test_memory_from_a_start_of_zero(motion):
    """A start at the bound 0 scales by 1 ms (not by its own size) and leaves the bound."""
    start, _, _ = with_values(_TRUTH, _ZERO, _ZERO, {"body1.memory": 0.0})
    est = estimate_drive(_record(motion, 4), start, estimate=["body1.memory"], x0=[0.0],
                         v0=[0.0], starts_from_record=False)
    # observed 0.02 ± 3e-7 s; the same 1 % and 4 standard errors as above
    assert est.value("body1.memory") == pytest.approx(0.02, rel=0.01)
    assert abs(est.value("body1.memory") - 0.02) < 4 * est.stderr("body1.memory")


def test_memory_interval_coverage_small_monte_carlo(motion):
    """20 noise realisations: the 95 % intervals of the memory hold the truth about 95 %."""
    start = _start(0.014)
    z = []
    for seed in range(20):
        est = estimate_drive(_record(motion, 100 + seed), start, estimate=_NAMES, x0=[0.0],
                             v0=[0.0], starts_from_record=False)
        z.append((est.value("body1.memory") - 0.02) / est.stderr("body1.memory"))
    z = np.abs(np.array(z))
    # measured 19/20 inside 1.96 s.e. (spread of z 0.88; seeds 0-19 gave 20/20); with a true
    # 95 % coverage, 15 or fewer of 20 has probability 1.6 %; intervals 10x too narrow would
    # leave most outside, so >= 16 of 20 is asked; and some spread must be left (errors
    # 10x too wide put every |z| below 0.3)
    assert np.sum(z < 1.96) >= 16, z
    assert np.max(z) > 0.3, z


def test_memory_is_a_parameter_of_stribeck_bodies_only(motion):
    assert "body1.memory" in parameter_names(_TRUTH, states=False)
    assert parameter_unit("body1.memory") == "s"
    plain = DriveParams(bodies=(BodyParams(J=0.01, fk_mean=0.1),))
    assert "body1.memory" not in parameter_names(plain, states=False)
    with pytest.raises(ParameterError, match="memory"):
        estimate_drive(_record(motion, 3), plain, estimate=["body1.memory"], x0=[0.0],
                       v0=[0.0])
