"""IDIM's errors-in-variables correction: position noise in the acceleration column."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from scipy.signal import lfilter

from driveid.identify.friction._idim_eiv import _lagged, _whitened, position_noise_sigma, row_noise
from driveid.identify.friction.idim import estimate_idim
from driveid.io.record import Record
from driveid.signal.differentiate import differentiate
from driveid.signal.envelope import block_decimate

FS = 500.0


def test_position_noise_is_read_from_rounding_and_from_gaussian_noise():
    t = np.arange(6000) / FS
    x = 0.05 * np.sin(0.8 * np.pi * t) + 0.01 * np.sin(2.2 * np.pi * t)
    q = 1e-6
    rounded = q * np.round(x / q)
    # rounding at tens of counts a sample is white with variance q²/12 exactly; 6000
    # fourth differences give the variance to about 4 % (sd of a mean square, 70 σ² each,
    # correlated over 4 lags), hence 5 %
    assert position_noise_sigma(rounded, FS, 50.0) == pytest.approx(q / np.sqrt(12), rel=0.05)
    noisy = x + 2e-6 * np.random.default_rng(3).standard_normal(t.size)
    assert position_noise_sigma(noisy, FS, 50.0) == pytest.approx(2e-6, rel=0.05)
    # a smooth motion at 500 Hz leaves fourth differences of ~1e-12 m
    assert position_noise_sigma(x, FS, 50.0) < 1e-10


def test_the_rows_noise_covariance_is_that_of_noise_pushed_through_the_rows():
    """σ²C(ℓ) from the kernels against noise filtered, differentiated, decimated, whitened."""
    q, ar, sigma = 3, (0.9,), 1e-6
    noise = row_noise(np.zeros(64), FS, 50.0, q, sigma)
    g = _whitened(noise.kernels, q, ar)
    lagged = _lagged(g, q)
    mid = lagged.shape[0] // 2
    c0, c1 = sigma**2 * lagged[mid], sigma**2 * lagged[mid + 1]
    e = sigma * np.random.default_rng(7).standard_normal(600_000)
    _, v, a = differentiate(e, FS, cutoff_hz=50.0)
    rows = np.column_stack([block_decimate(a, q), block_decimate(v, q)])[100:-100]
    rows = lfilter([1.0, -ar[0]], [1.0], rows, axis=0)[1:]
    s0 = rows.T @ rows / rows.shape[0]
    s1 = rows[:-1].T @ rows[1:] / (rows.shape[0] - 1)
    # 2e5 rows correlated over a few lags: sample (co)variances to ~1 %; 3 % leaves 3 sd
    assert s0[0, 0] == pytest.approx(c0[0, 0], rel=0.03)
    assert s0[1, 1] == pytest.approx(c0[1, 1], rel=0.03)
    assert s1[0, 0] == pytest.approx(c1[0, 0], rel=0.03)
    # acceleration against velocity: odd against even kernel, only the AR filter couples
    # them; compare on the scale of the product of their sds
    scale = np.sqrt(c0[0, 0] * c0[1, 1])
    assert abs(s0[0, 1] - c0[0, 1]) < 0.03 * scale
    assert abs(s1[0, 1] - c1[0, 1]) < 0.03 * scale


def _record(seed: int) -> Record:
    """6 s at 500 Hz, AR(1) 0.97 force noise, a 1 µm encoder (issue 24's benchmark cell)."""
    rng = np.random.default_rng((11, seed))
    t = np.arange(3000) / FS
    w1, w2 = 0.8 * np.pi, 2.2 * np.pi
    x = 0.05 * np.sin(w1 * t) + 0.01 * np.sin(w2 * t)
    v = 0.05 * w1 * np.cos(w1 * t) + 0.01 * w2 * np.cos(w2 * t)
    a = -0.05 * w1**2 * np.sin(w1 * t) - 0.01 * w2**2 * np.sin(w2 * t)
    w = rng.standard_normal(t.size + 500) * 0.5 * np.sqrt(1 - 0.97**2)
    u = 10 * a + 50 * v + 3 * np.sign(v) - 0.5 + lfilter([1.0], [1.0, -0.97], w)[500:]
    phase = rng.uniform(0.0, 1e-6)
    x = 1e-6 * np.round((x - phase) / 1e-6) + phase
    return Record(t=t, x=x, u=u, meta={"units": {"x": "m", "u": "N"}})


def test_the_inertia_is_unbiased_under_a_coarse_encoder_and_strongly_coloured_force_noise():
    # the benchmark's worst IDIM cell (docs/validation.md): uncorrected, M is 1.3-1.5 s.e.
    # low and its intervals cover 0.60-0.64
    z, z_off, applied = [], [], []
    for seed in range(40):
        rec = _record(seed)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            est = estimate_idim(rec, cutoff_hz=50.0, decimate=1, edge=20, sensitivity=False)
            off = estimate_idim(rec, cutoff_hz=50.0, decimate=1, edge=20, sensitivity=False,
                                position_noise_std=0)
        z.append((est.value("M") - 10.0) / est.stderr("M"))
        z_off.append((off.value("M") - 10.0) / off.stderr("M"))
        applied.append(est.diagnostics["errors_in_variables"]["applied"])
    z, z_off = np.array(z), np.array(z_off)
    assert all(applied)
    # the mean z of 40 runs has sd 1/sqrt(40) = 0.16: uncorrected -1.19 (below -0.9),
    # corrected +0.01 (within 3 sd of 0)
    assert np.mean(z_off) < -0.9
    assert abs(np.mean(z)) < 0.48
    # coverage on these 40: 0.53 uncorrected, 0.85 corrected (0.60 and 0.90 over the
    # benchmark's 200); 0.8 is a 2-record margin, the uncorrected fit misses it by 11
    assert np.mean(np.abs(z_off) < 1.96) < 0.75
    assert np.mean(np.abs(z) < 1.96) >= 0.8


def test_position_noise_too_large_to_correct_is_said_so():
    # a 20 µm noisy sensor at a 100 Hz cut-off: 89 % of the acceleration column's power
    # is noise (M comes out 0.26 for 10), so the correction, a difference of near-equal
    # numbers, is refused with a warning naming the fix
    t = np.arange(3000) / FS
    w = 0.8 * np.pi
    x = 0.05 * np.sin(w * t)
    v, a = 0.05 * w * np.cos(w * t), -0.05 * w**2 * np.sin(w * t)
    u = 10 * a + 50 * v + 3 * np.sign(v)
    x = x + 2e-5 * np.random.default_rng(5).standard_normal(t.size)
    rec = Record(t=t, x=x, u=u, meta={"units": {"x": "m", "u": "N"}})
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        est = estimate_idim(rec, cutoff_hz=100.0, decimate=1, sensitivity=False)
    eiv = est.diagnostics["errors_in_variables"]
    assert not eiv["applied"] and eiv["noise_share"] >= 0.5
    assert any("too much to correct" in w and "--cutoff-hz" in w for w in est.warnings)
