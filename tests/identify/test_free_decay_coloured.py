"""Free-decay output error under strongly coloured noise (issue 24): the mechanisms and coverage.

Truth: the exact simulator (viscous + Coulomb, thesis 2.139-2.143) and the analytic Jacobian
of :mod:`driveid.identify.free_decay._free_response`; noise drawn from known filters.
"""

import numpy as np
from scipy.signal import butter, lfilter

from driveid.identify.core._noise import NoiseModel, fit_noise_model
from driveid.identify.core._noise_replicates import linearised_replicates
from driveid.identify.free_decay._free_decay_structures import fit_structure
from driveid.identify.free_decay._free_response import kinetic_stop_count, response
from driveid.identify.free_decay.output_error import estimate_output_error
from driveid.sim import OscillatorParams, simulate_free_decay

P = OscillatorParams(J=1.0, K=16.0, c_mean=0.3, c_delta=0.1, fk_mean=0.07, fk_delta=0.03)
TRUTH = {"c_mean": 0.3, "c_delta": 0.1, "fk_mean": 0.07, "fk_delta": 0.03, "K": 16.0}
#: the base unknowns at the truth: omega0, zeta+, zeta-, theta_k_mean, theta_k_delta
GLOBAL = np.array([4.0, 0.4 / 8.0, 0.2 / 8.0, 0.07 / 16.0, 0.03 / 16.0])


def _lowpass(n, rng, fs=50.0):
    """White noise through a 4th-order Butterworth at 5x the mode (3.2 Hz), sd 0.01 rad."""
    b, a = butter(4, 3.2 / (fs / 2.0))
    e = lfilter(b, a, rng.normal(size=n + 2000))[2000:]
    return 0.01 * e / np.std(e)


def _coverage(records, noise, rng):
    rec = simulate_free_decay(P, x0=1.0, duration=12.0, fs=50.0).record
    hits = dict.fromkeys(TRUTH, 0)
    for _ in range(records):
        est = estimate_output_error(rec.replace(x=rec.x + noise(rec.n, rng)), mass=1.0)
        for name, value in TRUTH.items():
            hits[name] += abs(est.value(name) - value) <= 1.96 * est.stderr(name)
    return hits


def test_low_pass_noise_coverage_small_monte_carlo():
    """20 records, noise behind a low-pass at 5x the mode (no white floor).

    Before the fix the 95 % intervals covered 53-60 % of runs (c̄, Δc, Δf_k, K): the noise
    model was thrown away (raw RSS up > 5 %) or a spurious ``+ drift`` chosen, whose
    Jacobian (forward differences after the filter) made the error bars 3-10x short.
    """
    hits = _coverage(20, _lowpass, np.random.default_rng(24))
    for name in TRUTH:
        # Binomial(20, 0.95): P(<= 16) = 1.6 %, so >= 17 hits from honest intervals; at the
        # old coverage 0.6, P(>= 17) = 1.6 %
        assert hits[name] >= 17, (name, hits[name])


def test_ar_097_noise_coverage_small_monte_carlo():
    """20 records with AR(1) φ = 0.97 noise (time constant 0.66 s, 0.4 of a period)."""

    def ar(n, rng):
        e = lfilter([1.0], [1.0, -0.97], rng.normal(size=n + 2000))[2000:]
        return 0.01 * e / np.std(e)

    hits = _coverage(20, ar, np.random.default_rng(97))
    for name in TRUTH:
        # Binomial(20, 0.95): P(<= 16) = 1.6 %
        assert hits[name] >= 17, (name, hits[name])


def test_ar_bias_correction_through_the_fit():
    """The fit absorbs the noise's slow wander: Burg on its residuals gives φ ≈ 0.963 for 0.97.

    Replicates through the same linearised fit remove that bias (the mean over 16 records
    has sd 0.007/4 ≈ 0.002; the raw bias is ~0.007, the corrected ~0.001).
    """
    fs, n = 200.0, 2000
    t = np.arange(n) / fs
    count = kinetic_stop_count(GLOBAL, 1.0, 0.0, float(t[-1]))[0]
    x, jac, _ = response(t, GLOBAL, 1.0, 0.0, count, jacobian=True)
    true = NoiseModel((0.97,), 1.0, 1.0, n)
    jw = true.whiten(jac)
    rng = np.random.default_rng(5)
    raw, corrected = [], []
    for _ in range(16):
        e = lfilter([1.0], [1.0, -0.97], rng.normal(size=n + 3000))[3000:]
        r = e - jac @ np.linalg.lstsq(jw, true.whiten(e), rcond=None)[0]
        fitted = fit_noise_model(r, n_params=jac.shape[1], order=1)
        raw.append(fitted.ar[0])
        corrected.append(linearised_replicates(fitted, jac, r).noise.ar[0])
    bias_raw, bias_corrected = np.mean(raw) - 0.97, np.mean(corrected) - 0.97
    assert bias_raw < -0.004  # the absorption is real (the test can fail without it)
    # at least halved: ~6 sd of the mean apart at the measured biases
    assert abs(bias_corrected) < 0.5 * abs(bias_raw), (bias_raw, bias_corrected)


def test_structure_jacobian_survives_deep_prewhitening():
    """The structure fits' Jacobian equals the analytic one passed through the filter.

    A low-pass AR(40) model amplifies the stopband ~10⁴x and all but cancels an offset:
    differences carried that gain on their round-off (θk_delta's column 5.5x too long).
    """
    fs, n = 200.0, 2000
    t = np.arange(n) / fs
    count = kinetic_stop_count(GLOBAL, 1.0, 0.0, float(t[-1]))[0]
    x, jac, _ = response(t, GLOBAL, 1.0, 0.0, count, jacobian=True)
    noise = fit_noise_model(_lowpass(200_000, np.random.default_rng(7), fs), max_order=40)
    assert noise.order >= 30  # a deep stopband: the filter's gain is large
    theta = np.r_[GLOBAL, 1.0, 0.0]
    fit = fit_structure([t], x, theta, [count], 2, False, False, noise, [n], max_nfev=2)
    expected = noise.whiten(jac)
    error = np.linalg.norm(fit["jac"] - expected, axis=0) / np.linalg.norm(expected, axis=0)
    # the analytic columns, filtered: equal to round-off (central differences of f, 1e-8
    # relative before the filter, came out up to 5.5x off after it; the old forward
    # differences likewise)
    assert np.all(error < 1e-6), error


def _pink(n, rng):
    """1/f-like: four AR(1) processes of unit variance, poles 0.5, 0.9, 0.99, 0.999."""
    e = sum(lfilter([np.sqrt(1 - p * p)], [1.0, -p], rng.normal(size=n + 20_000))[20_000:]
            for p in (0.5, 0.9, 0.99, 0.999))
    return 0.01 * e / 2.0


def test_slow_noise_is_warned_not_hidden():
    """1/f-like noise slower than the record is absorbed as offset and drift: warn.

    The slowest component (time constant 5 s) is half the 10 s record; with the AR model alone
    Δf_k and Δc covered ~0.45, with the slow-noise excess ~0.75-0.80 (docs/output-error.md).
    The low-frequency test fired on 11 of 20 such records and on 0 of 20 white ones in the
    benchmark's seeds.
    """
    rec = simulate_free_decay(P, x0=1.0, duration=10.0, fs=200.0).record
    rng = np.random.default_rng(1)
    fired = {"pink": 0, "white": 0}
    for kind in fired:
        for _ in range(10):
            e = _pink(rec.n, rng) if kind == "pink" else rng.normal(0.0, 0.01, rec.n)
            est = estimate_output_error(rec.replace(x=rec.x + e), mass=1.0)
            slow = est.diagnostics["adequacy"]["slow_noise"]
            fired[kind] += slow["excess"]
            widened = bool(slow["excess_fit"] and slow["excess_fit"]["applied"])
            assert (slow["excess"] or widened) == any(w.startswith("slow noise")
                                                      for w in est.warnings)
    # rate ~0.55 on 1/f records: P(< 3 of 10) = 2.7 %; white at the 1 % level:
    # P(>= 2 of 10) = 0.4 %
    assert fired["pink"] >= 3, fired
    assert fired["white"] <= 1, fired


def test_slow_noise_excess_widens_the_asymmetries():
    """1/f-like noise: the power-law excess at the slowest frequencies widens Δc and Δf_k.

    On these 20 seeded records the AR model alone covered Δc 11 and Δf_k 7 times (misses
    up to 11 s.e.); with the excess (issue 24) 17 and 17. At the 60-record benchmark rates
    (0.43-0.48 before, 0.75-0.80 now) the 40 intervals cover ~19 before and ~31 now.
    """
    rec = simulate_free_decay(P, x0=1.0, duration=10.0, fs=200.0).record
    rng = np.random.default_rng(7)
    hits, applied = 0, 0
    for _ in range(20):
        est = estimate_output_error(rec.replace(x=rec.x + _pink(rec.n, rng)), mass=1.0)
        hits += sum(abs(est.value(n) - TRUTH[n]) <= 1.96 * est.stderr(n)
                    for n in ("c_delta", "fk_delta"))
        excess = est.diagnostics["adequacy"]["slow_noise"]["excess_fit"]
        applied += bool(excess and excess["applied"])
    # Binomial(40, 0.775): P(<= 27) ~ 10 %; Binomial(40, 0.5) (the AR model alone):
    # P(>= 28) ~ 1 % (the two parameters of one record are correlated, so these are rough)
    assert hits >= 28, hits
    # the excess was found on 45 of the benchmark's 60 records: P(<= 9 of 20) ~ 1 %
    assert applied >= 10, applied
