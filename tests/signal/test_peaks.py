"""Regression tests of the oscillation peak finder (start of record) and its blocked DFT."""

import numpy as np
import pytest

from driveid.signal.peaks import find_oscillation_peaks
from driveid.sim.drive import BodyParams, DriveParams, PDFeedback, simulate_drive


def test_heavily_damped_release_found_near_the_start():
    # ζ ≈ 0.33 with Coulomb friction: the first detected extremum lies within the
    # "near the start" window; this path once left a flag unset (UnboundLocalError).
    params = DriveParams(bodies=(BodyParams(J=0.0115355, c_mean=0.0007457, fk_mean=0.109456),),
                         feedback=PDFeedback(P=8.0, D=0.2))
    record = simulate_drive(params, duration=6.0, fs=1000.0, x0=[1.0]).record
    pk = find_oscillation_peaks(record)
    # 1 %: the one-sided fit of the release is coarse at this damping (measured 0.45 %)
    assert pk.t[0] == 0.0 and abs(pk.x[0] - 1.0) < 1e-2
    assert len(pk) >= 3


def test_batched_refinement_equals_the_scalar_fit():
    # the batched golden-section + Newton search must land on the scalar Brent search's
    # minimum: same two-sided quartic, same residual, so the same peak to round-off
    import numpy as np

    from driveid.signal import peaks as pk_mod

    fs, w = 1000.0, 2 * np.pi * 2.0
    t = np.arange(4000) / fs
    # a linear (Coulomb) envelope: the acceleration jumps at every peak
    x = np.maximum(1 - 0.2 * t, 0.05) * np.cos(w * t)
    x = x + 1e-4 * np.random.default_rng(2).standard_normal(t.size)
    idx = np.arange(250, 3800, 250)
    half_w = 40
    many = pk_mod._refine_many(t, x, idx, half_w)
    one = np.array([pk_mod._refine(t, x, int(i), half_w) for i in idx]).T
    # Brent stops at xatol = 1e-9 dt; Newton gets closer: 1e-5 samples is far below the
    # time standard error (~0.1 sample at this noise) and a residual minimum is flat there
    assert np.max(np.abs(many[0] - one[0])) * fs < 1e-5
    assert np.max(np.abs(many[1] - one[1])) < 1e-9  # value: 1e-5 of the 1e-4 noise
    # the standard errors come from the same fit: equal to a few parts in 1e4
    assert np.allclose(many[2], one[2], rtol=1e-3) and np.allclose(many[3], one[3], rtol=1e-4)


@pytest.mark.parametrize("n", [1, 700, 4096, 9000])
def test_blocked_dft_equals_the_direct_sum(n):
    """``_dft_at`` against the defining sum, for records shorter than, equal to and longer
    than its block (a short record uses a table only as wide as itself, issue 28)."""
    from driveid.signal.peaks import _dft_at

    rng = np.random.default_rng(n)
    x = rng.normal(size=n)
    cycles = np.array([0.0, 0.013, 0.25, 0.4999])
    direct = np.exp(-2j * np.pi * np.outer(cycles, np.arange(n))) @ x
    # both are sums of n terms of size ~1: rounding ~1e-16 sqrt(n) n, far below 1e-9
    np.testing.assert_allclose(_dft_at(x, cycles), direct, rtol=0, atol=1e-9 * max(1, n))
