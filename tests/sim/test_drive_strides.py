"""Strides: simulate_drive(rtol=...), the step-size control of the event-located RK4."""

import numpy as np
import pytest

from driveid.errors import ParameterError
from driveid.sim import (
    BodyParams,
    DriveParams,
    ShaftLink,
    simulate_drive,
    simulate_drive_batch,
)

from .test_drive import _w3  # motor, backlash, frictionless arm, shaft, tool; delayed PD


def _all_state_error(res, ref):
    """Max over states of max|error| / max|reference state| (positions and velocities)."""
    return max(np.max(np.abs(a - b)) / np.max(np.abs(b))
               for a, b in zip([*res.x, *res.v], [*ref.x, *ref.v], strict=True))


def test_strides_follow_rtol_on_the_closed_form():
    # a viscous oscillator against its closed form; output every 10 ms, grid 1 ms: strides
    # of up to 10 grid steps where the estimate allows
    drive = DriveParams(bodies=(BodyParams(J=1.0, K=16.0, c_mean=0.3),))
    kw = dict(duration=20.0, fs=100.0, x0=[1.0], max_step=1e-3)
    exact = simulate_drive(drive, method="exact", **kw)
    fixed = np.max(np.abs(simulate_drive(drive, method="rk4", **kw).x - exact.x))
    errors = []
    for rtol in (1e-8, 1e-10):
        res = simulate_drive(drive, method="rk4", rtol=rtol, **kw)
        errors.append(np.max(np.abs(res.x - exact.x)))
        # each stride's estimate stays below rtol x max|x| (= 1 m); over 2000 strides of a
        # damped oscillator the errors add up to ~23 rtol here (not 2000 rtol: they decay)
        assert fixed < errors[-1] < 100 * rtol + fixed, (rtol, errors[-1], fixed)
    assert errors[1] < errors[0] / 10  # tighter rtol, fewer strides, smaller error


def test_strides_keep_the_fixed_step_accuracy_of_a_delayed_drive():
    # the three-body drive with backlash and a 10 ms delayed PD: strides skip the settled
    # part. Each event makes the delayed feedback kink one delay later; a stride across such
    # a kink loses RK4's order (all-state error 8.8e-7 instead of 9.2e-8 when strides do not
    # stop short of kinks), so this test fails without that rule.
    drive = _w3()
    ref = simulate_drive(drive, duration=2.0, max_step=1e-3 / 400)
    fixed = simulate_drive(drive, duration=2.0, max_step=1e-3 / 40)
    strided = simulate_drive(drive, duration=2.0, max_step=1e-3 / 40, rtol=1e-10)
    e_fixed, e_strided = _all_state_error(fixed, ref), _all_state_error(strided, ref)
    assert e_fixed < 2e-7  # 9.2e-8 (RK4 at h = 25 us)
    assert e_strided < 1.5 * e_fixed, (e_strided, e_fixed)
    assert not np.array_equal(strided.x, fixed.x)  # strides were taken
    assert (strided.n_mode_switches, strided.n_impacts) == (fixed.n_mode_switches,
                                                            fixed.n_impacts)


def test_a_failed_stride_is_retaken_in_grid_steps():
    # quiescent for 0.5 s (strides grow to the output interval), then a torque pulse: the
    # first stride into it fails its estimate and is retaken step by step
    drive = DriveParams(bodies=(BodyParams(J=0.01, c_mean=0.002),
                                BodyParams(J=0.02, K=40.0, c_mean=0.01)),
                        links=(ShaftLink(k=200.0, c=0.05),))
    torque = np.zeros((2, 2001))
    torque[0, 500:1000] = 1.0
    kw = dict(duration=2.0, torque=torque, method="rk4")
    ref = simulate_drive(drive, max_step=1e-6, **kw)
    fixed = simulate_drive(drive, max_step=1e-4, **kw)
    strided = simulate_drive(drive, max_step=1e-4, rtol=1e-10, **kw)
    # 3.6e-9 both (the retaken strides reproduce the grid steps)
    assert _all_state_error(strided, ref) < 1.5 * _all_state_error(fixed, ref)
    assert not np.array_equal(strided.x, fixed.x)
    batch = simulate_drive_batch([drive], max_step=1e-4, rtol=1e-10, duration=2.0,
                                 torque=torque)
    assert np.array_equal(batch[0].x, strided.x)


def test_a_body_without_friction_has_no_reversal_events():
    # its velocity's sign changes nothing: no events, the same closed form
    drive = DriveParams(bodies=(BodyParams(J=1.0, K=16.0, c_mean=0.3),))
    rk4 = simulate_drive(drive, duration=5.0, x0=[1.0], method="rk4")
    exact = simulate_drive(drive, duration=5.0, x0=[1.0], method="exact")
    assert rk4.n_mode_switches == 0
    assert np.max(np.abs(rk4.x - exact.x)) < 1e-9


@pytest.mark.parametrize("rtol", [0.0, -1e-9, 1.0, "1e-9", float("nan")])
def test_rtol_errors(rtol):
    with pytest.raises(ParameterError, match="rtol must be None"):
        simulate_drive(_w3(), duration=0.1, rtol=rtol)


def test_rtol_needs_no_controller():
    plant = DriveParams(bodies=(BodyParams(J=1.0),))
    with pytest.raises(ParameterError, match="rtol .strides. is not available"):
        simulate_drive(plant, duration=0.1, controller=lambda t, x, v: 0.0,
                       control_rate=100.0, rtol=1e-9)
