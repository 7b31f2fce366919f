"""RK4 keeps its fourth order under a delayed feedback: the delay history holds a node at
each event, and a step ends where an event's kink arrives one delay later."""

import numpy as np

from driveid.sim import simulate_drive

from .test_drive import _w3
from .test_drive_strides import _all_state_error


def test_rk4_keeps_its_order_with_a_delay():
    # 14 switches and 20 contact closures in 2 s, each leaving a kink in the motor's motion
    # that the 10 ms delayed PD reads again. Halving the step divides the error by ~15
    # (2^4 = 16); before nodes and split steps the ratios were irregular (5.9 and 52 over
    # 1 s): one Hermite across a kink errs by ~h^2 times its jump, depending on where the
    # kink falls in the step.
    drive = _w3()
    ref = simulate_drive(drive, duration=2.0, max_step=1e-3 / 400)
    errors = [_all_state_error(simulate_drive(drive, duration=2.0, max_step=1e-3 / n), ref)
              for n in (10, 20, 40)]
    ratios = np.array(errors[:-1]) / np.array(errors[1:])
    assert np.all((ratios > 11.0) & (ratios < 22.0)), (errors, ratios)  # order 3.5 .. 4.5
    assert errors[-1] < 2e-7  # 9.2e-8 at h = 25 us


def test_the_order_holds_for_a_delay_off_the_grid():
    # a delay that is no multiple of the step: the history's grid points and the kinks'
    # arrivals never coincide. Before: ratio 3.1 (10.37 ms) where 10 ms gave 52; now ~15
    for delay in (0.01, 0.01037):
        drive = _w3(delay=delay)
        ref = simulate_drive(drive, duration=1.0, max_step=1e-3 / 400)
        e20 = _all_state_error(simulate_drive(drive, duration=1.0, max_step=1e-3 / 20), ref)
        e40 = _all_state_error(simulate_drive(drive, duration=1.0, max_step=1e-3 / 40), ref)
        assert e20 / e40 > 11.0, (delay, e20, e40)
