"""Steady-velocity friction map on records of our own exact simulator (issue 7, simulated truth).

With K = 0 and a constant torque u0 the body settles at v = (u0 - F_k)/C (thesis 2.149), so a
set of ± torque levels gives a steady-velocity experiment with known asymmetric friction.
"""

import numpy as np

from driveid.identify.friction.friction_map import estimate_friction_map
from driveid.sim import OscillatorParams, measure, simulate_free_decay


def test_asymmetric_coulomb_viscous_from_simulated_steady_runs():
    p = OscillatorParams(J=1.0, K=0.0, c_mean=0.3, c_delta=0.1, fk_mean=0.07, fk_delta=0.03)
    rng = np.random.default_rng(7)
    records = []
    for u0 in (0.2, 0.35, 0.5, 0.8, 1.2, -0.2, -0.35, -0.5, -0.8, -1.2):
        rec = simulate_free_decay(p, x0=0.0, u0=u0, duration=40.0, fs=1000.0).record
        # 8000 counts/rev encoder plus 0.2 mrad noise; keep the last 10 s (12 time constants in)
        rec = measure(rec, noise_std=2e-4, counts_per_rev=8000, rng=rng)
        records.append(rec.crop(30.0, 40.0))
    est = estimate_friction_map(records, models=("coulomb_viscous",)).estimate
    for name in ("fk_mean", "fk_delta", "c_mean", "c_delta"):
        # issue 7: every parameter within 1 % at realistic noise
        assert abs(est.value(name) - getattr(p, name)) < 0.01 * abs(getattr(p, name)), name
