"""The whole-drive fit estimates Stribeck parameters of a body (issue 25 item 4)."""

from __future__ import annotations

import numpy as np
import pytest

from driveid.errors import ParameterError
from driveid.identify.drive._drive_model import get_value, parameter_names, with_values
from driveid.identify.drive.drive_fit import DriveRecord, estimate_drive
from driveid.sim import simulate_drive
from driveid.sim.drive import BodyParams, DriveParams

_ZERO = np.zeros(1)
_NOISE = 1e-4  # position noise [rad]
_TRUTH = DriveParams(bodies=(BodyParams(J=0.01, c_mean=0.02, fk_mean=0.1, fs_mean=0.25,
                                        fs_delta=0.03, stribeck="lorentzian", v_s=0.3,
                                        v_s_delta=0.05),))


def _record(seed: int) -> DriveRecord:
    """Open loop, two sines: 13 stick-slip switches in 4 s, speeds up to 3.4 rad/s."""
    t = np.arange(4001) / 1000.0
    u = 0.3 * np.sin(2 * np.pi * 1.0 * t) + 0.1 * np.sin(2 * np.pi * 2.7 * t)
    res = simulate_drive(_TRUTH, duration=4.0, fs=1000.0, torque=u[None])
    rng = np.random.default_rng(seed)
    return DriveRecord(t=res.t, channels={"x1": res.x[0] + rng.normal(0, _NOISE, t.size)},
                       u=u)


@pytest.mark.parametrize("off", [-0.3, 0.3])
def test_stribeck_level_and_velocity_from_30_percent_off(off):
    names = ["body1.fs_mean", "body1.v_s"]
    start, _, _ = with_values(_TRUTH, _ZERO, _ZERO, {"body1.fs_mean": 0.25 * (1 + off),
                                                     "body1.v_s": 0.3 * (1 - off)})
    est = estimate_drive(_record(3), start, estimate=names, x0=[0.0], v0=[0.0],
                         starts_from_record=False)
    for name in names:
        true = get_value(_TRUTH, _ZERO, _ZERO, name)
        # the fit reaches the noise (1e-4 rad rms): observed errors <= 1e-4 relative and
        # 1.8 standard errors; 1 % is issue 25's friction tolerance (10 %) tightened to
        # what this noise allows, far below the 30 % start offset; 4 standard errors
        # catches error bars that are too small
        assert est.value(name) == pytest.approx(true, rel=0.01), name
        assert abs(est.value(name) - true) < 4 * est.stderr(name) + 1e-12, name
    assert est["body1.J"].fixed
    assert 'stribeck = "lorentzian"' in est.diagnostics["model_toml"]


def test_stribeck_and_dwell_names_exist_only_on_bodies_that_have_them():
    names = parameter_names(_TRUTH, states=False)
    assert "body1.v_s" in names and "body1.v_s_delta" in names
    assert "body1.stribeck_exponent" not in names  # not a parameter of the Lorentzian map
    plain = DriveParams(bodies=(BodyParams(J=1.0, fk_mean=0.1),))
    with pytest.raises(ParameterError, match="v_s"):
        estimate_drive(_record(3), plain, estimate=["body1.v_s"], x0=[0.0], v0=[0.0])
    dwell = DriveParams(bodies=(BodyParams(J=1.0, fk_mean=0.1, fs_mean=0.2,
                                           dwell_gamma=0.5),))
    assert {"body1.dwell_gamma", "body1.dwell_kappa"} <= set(parameter_names(dwell))


@pytest.mark.parametrize("off", [-0.3, 0.3])
def test_rising_static_friction_from_breakaways_after_different_dwells(off):
    """Rests of 0.05-1 s, each followed by a ramp to breakaway: fs_mean and dwell_gamma."""
    truth = DriveParams(bodies=(BodyParams(J=0.01, c_mean=0.05, fk_mean=0.1, fs_mean=0.3,
                                           dwell_gamma=0.3, dwell_kappa=1.0),))
    rate, u, sign = 1000.0, [], 1.0
    for dwell in (0.05, 0.15, 0.4, 1.0, 0.1, 0.6):
        u += [0.0] * int(dwell * rate)  # at rest: the static level rises
        u += list(sign * np.linspace(0.0, 0.4, int(0.25 * rate)))  # ramp to breakaway
        u += [0.0] * int(0.1 * rate)
        sign = -sign
    u = np.array(u)
    t = np.arange(u.size) / rate
    res = simulate_drive(truth, duration=t[-1], fs=rate, torque=u[None])
    rng = np.random.default_rng(5)
    rec = DriveRecord(t=res.t, channels={"x1": res.x[0] + rng.normal(0, _NOISE, t.size)},
                      u=u)
    names = ["body1.fs_mean", "body1.dwell_gamma"]
    start, _, _ = with_values(truth, _ZERO, _ZERO, {"body1.fs_mean": 0.3 * (1 + off),
                                                    "body1.dwell_gamma": 0.3 * (1 - off)})
    est = estimate_drive(rec, start, estimate=names, x0=[0.0], v0=[0.0],
                         starts_from_record=False)
    for name in names:
        true = get_value(truth, _ZERO, _ZERO, name)
        # observed: 5e-5 relative, within 2 standard errors (noise 1e-4 rad); 1 % and 4
        # s.e. as in the Stribeck test above
        assert est.value(name) == pytest.approx(true, rel=0.01), name
        assert abs(est.value(name) - true) < 4 * est.stderr(name), name
