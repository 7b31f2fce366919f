"""Excitation signals: amplitude limits, spectra, and Schroeder's crest factor."""

import math

import numpy as np
import pytest

from driveid.errors import ParameterError
from driveid.signal import excitation as ex


def test_schroeder_crest_factor_matches_textbook():
    # Schroeder (1970) phases on F consecutive harmonics from the fundamental with a flat
    # spectrum give a crest factor of about 1.7 (Pintelon & Schoukens 2012, §5.2). The
    # value falls slowly towards ~1.66 as F grows (1.77 at F = 20), so "about 1.7" is
    # checked to ±0.05 for F = 50 and 100 lines.
    for f_max in (50.0, 100.0):
        sig = ex.multisine(f_min=1.0, f_max=f_max, duration=1.0, fs=100 * f_max,
                           amplitude=1.0)
        assert len(sig.settings["frequencies"]) == int(f_max)
        assert abs(sig.crest_factor - 1.7) < 0.05
    # random phases, for contrast, give a clearly larger crest factor (> 2.5 typically)
    rng = np.random.default_rng(0)
    t = np.arange(20000) / 20000
    u = sum(np.cos(2 * np.pi * k * t + rng.uniform(0, 2 * np.pi)) for k in range(1, 51))
    assert np.abs(u).max() / np.sqrt(np.mean(u**2)) > sig.crest_factor


def test_multisine_is_flat_on_its_lines_and_zero_elsewhere():
    sig = ex.multisine(f_min=1, f_max=20, duration=10, fs=1000, amplitude=0.5)
    f, amp = sig.spectrum()
    lines = np.isin(np.round(f, 9), np.round(sig.settings["frequencies"], 9))
    # whole period, rectangular window: every line has the same amplitude to rounding
    assert np.ptp(amp[lines]) < 1e-12 * amp[lines].max()
    assert amp[~lines].max() < 1e-12 * amp[lines].max()
    assert max(abs(v) for v in sig.amplitude_limits) == pytest.approx(0.5, abs=1e-12)


def test_chirp_sweeps_its_band():
    sig = ex.chirp(f_min=2, f_max=20, duration=10, fs=1000, amplitude=1.0, method="linear")
    f, amp = sig.spectrum()
    in_band = (f > 1.5) & (f < 20.5)
    # the energy of a slow linear sweep (time-bandwidth product 180) lies in its band
    # plus half a hertz: > 95 % of the power (the Fresnel ripples at the edges take the rest)
    assert np.sum(amp[in_band] ** 2) > 0.95 * np.sum(amp**2)
    assert sig.amplitude_limits[1] <= 1.0 + 1e-12
    log = ex.chirp(f_min=1, f_max=50, duration=5, fs=1000, amplitude=1.0, method="logarithmic")
    assert log.u[0] == pytest.approx(0.0, abs=1e-12)


def test_prbs_is_binary_and_periodic():
    sig = ex.prbs(f_clock=100, duration=3.0, fs=1000, amplitude=0.3, order=7)
    assert set(np.unique(sig.u)) == {-0.3, 0.3}
    n_period = (2**7 - 1) * 10
    assert np.array_equal(sig.u[:n_period], sig.u[n_period:2 * n_period])
    # m-sequence: one more +1 than -1 bit per period, so the mean is amplitude/period
    assert sig.u[:n_period].mean() == pytest.approx(0.3 / 127, rel=1e-12)


def test_filtered_random_band_and_seed():
    a = ex.filtered_random(f_min=5, f_max=20, duration=20, fs=1000, amplitude=1.0, seed=3)
    b = ex.filtered_random(f_min=5, f_max=20, duration=20, fs=1000, amplitude=1.0, seed=3)
    assert np.array_equal(a.u, b.u)
    f, amp = a.spectrum()
    # 4th-order Butterworth, applied twice: at 2 octaves outside the band the power
    # is down by > 40 dB, so < 1 % of the power lies outside [2.5, 40] Hz
    out = (f < 2.5) | (f > 40)
    assert np.sum(amp[out] ** 2) < 0.01 * np.sum(amp**2)


def test_square_wave_and_ramps():
    sq = ex.square_wave(frequency=0.5, duration=4, fs=100, amplitude=1.0, bias=0.2)
    assert sq.amplitude_limits == (-0.8, 1.2)
    assert np.mean(sq.u) == pytest.approx(0.2, abs=1e-12)   # two whole periods
    rp = ex.ramps_with_dwell(amplitude=1.5, ramp_time=1.0, dwell_time=1.0, fs=100,
                             n_cycles=2)
    assert rp.amplitude_limits == (-1.5, 1.5)
    assert rp.t[-1] == pytest.approx(16.0 - 0.01)
    assert ex.sine(frequency=2.5, duration=2, fs=200, amplitude=1).crest_factor == \
        pytest.approx(math.sqrt(2), rel=1e-12)


@pytest.mark.parametrize("call, match", [
    (lambda: ex.multisine(f_min=5, f_max=2, duration=1, fs=100, amplitude=1), "exceed"),
    (lambda: ex.chirp(f_min=1, f_max=60, duration=1, fs=100, amplitude=1), "Nyquist"),
    (lambda: ex.sine(frequency=1, duration=1, fs=100, amplitude=-1), "amplitude"),
    (lambda: ex.multisine(f_min=0.3, f_max=0.6, duration=1, fs=100, amplitude=1), "period"),
    (lambda: ex.square_wave(frequency=30, duration=1, fs=100, amplitude=1), "half period"),
    (lambda: ex.chirp(f_min=1, f_max=2, duration=1, fs=100, amplitude=1, method="x"),
     "linear"),
    (lambda: ex.prbs(f_clock=10, duration=1, fs=100, amplitude=1, order=40), "order"),
    (lambda: ex.sine(frequency=1, duration=0.01, fs=100, amplitude=1), "8"),
])
def test_bad_arguments(call, match):
    with pytest.raises(ParameterError, match=match):
        call()
