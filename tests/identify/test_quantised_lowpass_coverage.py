"""Bootstrap error bars of quantised free decays under band-limited noise (issue 24).

Truth: the exact simulator ``driveid.sim.simulate_free_decay``; the noise is white noise through
a 4th-order Butterworth low-pass at 5x the mode (3.2 Hz at 200 Hz), sd 0.01 rad, then an
encoder step of 0.01 rad on a grid of random phase: the ``lowpass+q`` class of
``benchmarks/bench_noise_coverage.py``. Before the fix the bootstrap drew AR noise of the
BIC order that already held the rounding's white floor, and its 95 % intervals covered
0.81-0.88 (200 records); the fix draws a long AR model less the floor and calibrates for
the record's own noise-model error.
"""

import math
import warnings

import numpy as np
from scipy.signal import butter, lfilter

from driveid.identify.core._noise import NoiseModel
from driveid.identify.free_decay._quantised import _continuous_noise, noise_model_calibration
from driveid.identify.free_decay.output_error import estimate_output_error
from driveid.sim import OscillatorParams, simulate_free_decay

P = OscillatorParams(J=1.0, K=16.0, c_mean=0.3, c_delta=0.1, fk_mean=0.07, fk_delta=0.03)
TRUTH = {"c_mean": 0.3, "c_delta": 0.1, "fk_mean": 0.07, "fk_delta": 0.03, "K": 16.0}
FS, SIGMA, QUANTUM = 200.0, 0.01, 0.01


def _lowpass_noise(n, rng):
    """Stationary low-pass noise of sd SIGMA [rad] (burn-in of 20 000 samples)."""
    b, a = butter(4, 5 * 4.0 / (2 * math.pi) / (FS / 2))
    pulse = np.zeros(20_000)
    pulse[0] = 1.0
    gain = math.sqrt(float(np.sum(lfilter(b, a, pulse) ** 2)))  # sd of unit white input
    return SIGMA / gain * lfilter(b, a, rng.standard_normal(n + 20_000))[20_000:]


def test_lowpass_quantised_intervals_cover():
    """40 seeded records x 5 parameters: at most 18 of the 200 95 % intervals miss.

    Honest intervals miss Binomial(200, 0.05): mean 10, sd 3.1; the five parameters of one
    record are correlated (c_mean with fk_mean, c_delta with fk_delta), which about doubles
    the variance (sd 4.4), so 18 is ~1.8 sd above honest and P(fail | honest) is about 3 %.
    On 2026-11-27 main (b412e39) missed 27 of these 200 (coverage 0.865), the fix 10.
    """
    rec = simulate_free_decay(P, x0=1.0, duration=10.0, fs=FS).record
    misses = 0
    for seed in range(40):
        rng = np.random.default_rng(seed)
        x = rec.x + _lowpass_noise(rec.n, rng)
        phase = rng.uniform(0.0, QUANTUM)
        x = QUANTUM * np.round((x - phase) / QUANTUM) + phase
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # slow-noise and inadequacy notes are not tested here
            est = estimate_output_error(rec.replace(x=x), mass=1.0, rng=seed)
        assert est.diagnostics["quantum"] is not None
        misses += sum(abs(est.value(n) - v) > 1.96 * est.stderr(n) for n, v in TRUTH.items())
    assert misses <= 18, misses


def test_replicate_noise_has_the_spectrum_less_the_rounding_floor():
    """AR(1) 0.9 noise with a white floor taken off: variance and lag-1 correlation."""
    model = NoiseModel(ar=(0.9,), innovation_variance=1.0, variance=1.0 / 0.19, n=1000)
    q = math.sqrt(12 * 0.25)  # floor q²/12 = 0.25, below the density's minimum 1/1.9² = 0.277
    x = _continuous_noise(model, q, [200_000], np.random.default_rng(0))
    # the two-sided density 1/|A|² - 0.25 integrates to 1/0.19 - 0.25; the sample variance
    # of 200 000 samples of a 0.9 pole is within ~1.3 % (3 sd)
    assert abs(np.var(x) / (1.0 / 0.19 - 0.25) - 1.0) < 0.03
    # a white floor sits at lag 0 only: lag 1 keeps the AR(1)'s 0.9/0.19, so the correlation
    # is (0.9/0.19)/(1/0.19 - 0.25) = 0.945, not the AR(1)'s 0.9 (sd of r1 here ~0.001)
    r1 = float(np.corrcoef(x[1:], x[:-1])[0, 1])
    assert abs(r1 - (0.9 / 0.19) / (1.0 / 0.19 - 0.25)) < 0.005


def test_calibration_widens_only():
    """Replicate readings that agree with the record's: only the Student width is added."""
    reading = np.array([1.0, 4.0])
    same = [reading * (1.0 + 0.05 * s) for s in np.linspace(-1, 1, 25)]
    factors = noise_model_calibration(reading, same, 25)
    # reading/mean = 1 (no bias), relative variance 0.05² × 0.36 ≈ 1e-3 beside 2/24: the
    # pooled ν is ~23, t_23/t_24 ≈ 1.002
    assert np.all(factors >= 1.0) and np.all(factors < 1.01)
    short = [0.5 * r for r in same]  # replicates read half the record's variance
    assert np.allclose(noise_model_calibration(reading, short, 25), math.sqrt(2.0), rtol=0.01)
    assert np.all(noise_model_calibration(reading, same[:5], 25) == 1.0)  # < 8 readings
