"""Fast paths of the event-located RK4 kernel (issue 18) against closed forms and the general path.

The kernel reuses the derivative at a step's start (the first RK4 stage) for every trial
step of the event search and, with delayed feedback, for the history of the fed-back body;
it evaluates the forces at a step's end only while a body is stuck (the breakaway test is
the only event function that reads them); and it reads a constant input (one column)
without interpolating. Each is checked here where it would show: a delayed PD loop and a
breakaway under a ramp, both solved in closed form, and a constant torque given as one
column against the same torque as a full grid.
"""

import numpy as np
import pytest

from driveid.sim.drive import BacklashLink, BodyParams, DriveParams, PDFeedback, simulate_drive


def test_delayed_pd_matches_method_of_steps_closed_form():
    """A free body under delayed PD over the first two delay intervals (method of steps).

    For t < Δ the delayed state is the initial rest, so x'' = P r / J = A; on [Δ, 2Δ] the
    delayed state is that parabola, so x'' = A - (P/J) A u²/2 - (D/J) A u with u = t - Δ:
    x is a quartic in t. With the delay a whole number of steps, RK4 is exact for it on
    every step and the cubic Hermite history is exact for the parabola it reads, so only
    round-off remains: tolerance 1e-12 of the 5e-3 rad swing (the delayed state read from
    the wrong grid point, or a first stage from the wrong modes, errs by ~1e-8 or more).
    """
    J, P, D, r, delay = 1.0, 1.0, 0.1, 1.0, 0.05
    drive = DriveParams(bodies=(BodyParams(J=J),),
                        feedback=PDFeedback(P=P, D=D, delay=delay, reference=r))
    res = simulate_drive(drive, duration=2 * delay, fs=1000.0, method="rk4", max_step=1e-3)
    a = P * r / J
    t = res.t
    u = t - delay
    first = t <= delay
    x = np.where(first, a * t**2 / 2,
                 a * delay**2 / 2 + a * delay * u + a * u**2 / 2 - P * a / (24 * J) * u**4
                 - D * a / (6 * J) * u**3)
    v = np.where(first, a * t,
                 a * delay + a * u - P * a / (6 * J) * u**3 - D * a / (2 * J) * u**2)
    assert res.n_mode_switches == 0  # the body moves forward throughout
    np.testing.assert_allclose(res.x[0], x, rtol=0, atol=1e-12 * np.max(x))
    np.testing.assert_allclose(res.v[0], v, rtol=0, atol=1e-12 * np.max(v))
    # the command is the delayed PD law on the closed form
    cmd = np.where(first, P * r, P * (r - a * u**2 / 2) - D * a * u)
    np.testing.assert_allclose(res.command, cmd, rtol=0, atol=1e-12)


def test_breakaway_under_a_ramp_matches_closed_form():
    """A stuck body under a torque ramp a·t breaks away at t* = fs/a, then x'' = (a t - fk)/J.

    The breakaway is the event that needs the forces at a step's end (skipped while no
    body is stuck). The ramp is interpolated exactly and RK4 is exact for the cubic motion,
    so the error is the event location (1e-15 of a step) and round-off: 1e-11 rad of a
    ~0.05 rad motion.
    """
    J, fk, fs_static, a = 2.0, 0.1, 0.2, 1.0
    drive = DriveParams(bodies=(BodyParams(J=J, fk_mean=fk, fs_mean=fs_static),))
    fs = 1000.0
    t = np.arange(801) / fs
    res = simulate_drive(drive, duration=0.8, fs=fs, torque=(a * t)[None, :],
                         method="rk4", max_step=1e-3)
    ts = fs_static / a
    after = np.clip(t - ts, 0.0, None)
    x = (a / 6 * ((ts + after) ** 3 - ts**3) - a * ts**2 / 2 * after - fk / 2 * after**2) / J
    v = (a / 2 * ((ts + after) ** 2 - ts**2) - fk * after) / J
    assert res.n_mode_switches == 1  # stuck -> forward, once
    np.testing.assert_allclose(res.x[0], x, rtol=0, atol=1e-11)
    np.testing.assert_allclose(res.v[0], v, rtol=0, atol=1e-11)


@pytest.mark.parametrize("feedback", [None, PDFeedback(P=2.0, D=0.1, delay=0.004,
                                                       reference=0.3)])
def test_constant_input_column_equals_the_full_grid(feedback):
    """A constant torque passed as one column (read without interpolation) gives the same run
    as the same torque passed as a full (n_bodies, n) grid (interpolated): stick-slip,
    backlash contacts and delayed feedback included.

    Interpolating a constant is exact to a few ulp (~1e-18 N·m here), so the runs may differ
    by round-off only: 1e-15 rad and rad/s (a missing or shifted input would give >= 1e-6).
    """
    bodies = (BodyParams(J=0.01, c_mean=1e-3, fk_mean=0.02, fs_mean=0.03),
              BodyParams(J=0.004, fk_mean=0.01))
    drive = DriveParams(bodies=bodies,
                        links=(BacklashLink(gap_plus=0.01, gap_minus=0.005, k=1e3, c=0.5),),
                        feedback=feedback)
    u = np.array([0.05, -0.004])  # the arm's torque well inside its static band
    n = 1001
    one = simulate_drive(drive, duration=1.0, torque=u)
    grid = simulate_drive(drive, duration=1.0, torque=np.repeat(u[:, None], n, axis=1))
    assert one.n_impacts > 0  # contact events on the path
    assert (one.n_mode_switches, one.n_impacts) == (grid.n_mode_switches, grid.n_impacts)
    np.testing.assert_allclose(one.x, grid.x, rtol=0, atol=1e-15)
    np.testing.assert_allclose(one.v, grid.v, rtol=0, atol=1e-15)
    np.testing.assert_allclose(one.command, grid.command, rtol=0, atol=1e-15)
