"""Output-error free-decay fit (issue 13): exactness, Jacobian, coverage, robustness.

Truth: the exact simulator ``driveid.sim.simulate_free_decay`` (closed form per half cycle)
and the Cramér–Rao bound of :mod:`driveid.identify.crlb`.
"""

import math

import numpy as np
import pytest

from driveid.errors import IdentificationError, ParameterError, RecordWarning
from driveid.identify.crlb import free_decay_crlb
from driveid.identify.free_decay._free_response import kinetic_stop_count, response
from driveid.identify.free_decay._quantised import detect_quantum
from driveid.identify.free_decay.output_error import estimate_output_error
from driveid.io.record import Record
from driveid.sim import OscillatorParams, measure, simulate_free_decay

P = OscillatorParams(J=1.0, K=16.0, c_mean=0.3, c_delta=0.1, fk_mean=0.07, fk_delta=0.03)
TRUTH = {"omega0": 4.0, "c_mean": 0.3, "c_delta": 0.1, "fk_mean": 0.07, "fk_delta": 0.03}
BASE = [4.0, 0.4 / 8, 0.2 / 8, 0.07 / 16, 0.03 / 16]


def _decay(fs=100.0, duration=30.0, x0=10.0, params=P):
    return simulate_free_decay(params, x0=x0, duration=duration, fs=fs).record


def test_response_matches_exact_simulator():
    sim = simulate_free_decay(P, x0=10.0, duration=30.0, fs=1000.0)
    n, _ = kinetic_stop_count(BASE, 10.0, 0.0, 30.0)
    x, _, rev = response(sim.record.t, BASE, 10.0, 0.0, n)
    # same closed form, different code: agreement to round-off of a 10 rad signal
    assert np.max(np.abs(x - sim.record.x)) < 1e-12
    m = min(rev.shape[0], sim.reversal_x.size)
    assert np.allclose(rev[:m, 1], sim.reversal_x[:m], atol=1e-12)


def test_jacobian_matches_finite_differences():
    t = np.arange(0, 12.0, 0.01)
    q = np.array(BASE + [2.0, 0.013])
    _, jac, _ = response(t, q[:5], q[5], q[6], 12)
    for i in range(7):
        h = 1e-6 * max(abs(q[i]), 1e-3)
        up, down = q.copy(), q.copy()
        up[i] += h
        down[i] -= h
        num = (response(t, up[:5], up[5], up[6], 12, jacobian=False)[0]
               - response(t, down[:5], down[5], down[6], 12, jacobian=False)[0]) / (2 * h)
        # central differences: O(h²) truncation, ~1e-7 relative at this step
        assert np.max(np.abs(num - jac[:, i])) <= 1e-5 * np.max(np.abs(jac[:, i]))


def test_clean_record_is_exact():
    est = estimate_output_error(_decay(fs=1000.0), mass=1.0)
    for name, truth in TRUTH.items():
        # noise-free: only round-off remains (the issue asks for <= 0.01 %)
        assert est.value(name) == pytest.approx(truth, rel=1e-7)
    assert est.method == "output-error"
    assert est["J"].fixed and math.isnan(est.stderr("J"))
    names = est.covariance["names"]
    assert "fk_mean" in names and est.covariance["matrix"].shape == (len(names), len(names))


def test_two_runs_share_parameters():
    recs = [_decay(x0=10.0), _decay(x0=-8.0)]
    est = estimate_output_error(recs, stiffness=16.0)
    assert est.value("J") == pytest.approx(1.0, rel=1e-7)
    assert est.value("c_delta") == pytest.approx(0.1, rel=1e-6)
    assert est.data_used["release_x"] == pytest.approx([10.0, -8.0], abs=1e-9)


def test_coverage_and_efficiency_small_monte_carlo():
    """20 seeded noisy records (0.5 % of 10 rad at 100 Hz) against truth and the bound."""
    rec = _decay()
    noise = 0.05
    bound = free_decay_crlb(P, fs=100.0, duration=30.0, x0=10.0, noise_std=noise)
    hits = {n: 0 for n in TRUTH}
    errors = {n: [] for n in TRUTH}
    ses = {n: [] for n in TRUTH}
    for seed in range(20):
        est = estimate_output_error(measure(rec, noise_std=noise, rng=seed), mass=1.0)
        for n in TRUTH:
            err = est.value(n) - TRUTH[n]
            errors[n].append(err)
            ses[n].append(est.stderr(n))
            hits[n] += abs(err) <= 1.96 * est.stderr(n)
    for n in TRUTH:
        # P(<= 15 of 20 | p = 0.95) = 1.6 %: 16 or more hits expected from honest intervals
        assert hits[n] >= 16, (n, hits[n])
        # reported errors are the bound's within 25 % (s² and the Jacobian at the estimate)
        assert np.median(ses[n]) == pytest.approx(bound[n], rel=0.25)
        # observed scatter / bound: sd of a 20-sample sd is ~16 %, so 0.55-1.6 is 3 sigma
        ratio = np.std(errors[n], ddof=1) / bound[n]
        assert 0.55 < ratio < 1.6, (n, ratio)


def test_quantised_record_gets_bootstrap_error_bars():
    rec = measure(_decay(), counts_per_rev=8000)
    q = 2 * math.pi / 8000
    assert detect_quantum(rec.x) == pytest.approx(q)
    est = estimate_output_error(rec, mass=1.0, rng=1)
    assert est.diagnostics["quantum"] == pytest.approx(q)
    assert est.diagnostics["bootstrap"] == 25
    for n in ("c_mean", "fk_mean", "omega0"):
        # 4 bootstrap standard errors: the B = 25 error bars are themselves ~15 % uncertain
        assert abs(est.value(n) - TRUTH[n]) < 4 * est.stderr(n), n
        assert est.stderr(n) > 0
    none = estimate_output_error(rec, mass=1.0, quantisation=None)
    assert none.diagnostics["bootstrap"] == 0


def test_mid_swing_start_detected():
    rec = _decay(fs=1000.0).crop(0.3, None)
    est = estimate_output_error(rec, mass=1.0)
    assert est.diagnostics["mid_swing"] == [True]
    assert any("mid-swing" in w for w in est.warnings)
    for name, truth in TRUTH.items():
        assert est.value(name) == pytest.approx(truth, rel=1e-6)


def test_drift_is_fitted():
    rec = measure(_decay(), noise_std=0.01, rng=2)
    rec = rec.replace(x=rec.x + 0.1 * rec.t / 30.0)  # 1 % of the amplitude over the record
    est = estimate_output_error(rec, mass=1.0, drift=True)
    assert est.data_used["drift"][0] == pytest.approx(0.1 / 30.0, rel=0.1)
    for name, truth in TRUTH.items():
        assert abs(est.value(name) - truth) < 4 * est.stderr(name), name


def test_25_hz_sampling():
    rec = measure(_decay(fs=25.0), noise_std=0.01, rng=3)
    est = estimate_output_error(rec, mass=1.0)
    for name, truth in TRUTH.items():
        assert abs(est.value(name) - truth) < 4 * est.stderr(name), name


def test_non_uniform_time():
    rng = np.random.default_rng(4)
    t = np.sort(rng.uniform(0.0, 30.0, 3000))
    t[0] = 0.0
    exact = simulate_free_decay(P, x0=10.0, duration=30.0, t=t).record
    rec = Record(t=exact.t, x=exact.x + rng.normal(0, 0.01, exact.n), max_jitter=None)
    with pytest.warns(RecordWarning, match="resampled"):  # the peak start values only
        est = estimate_output_error(rec, mass=1.0)
    assert est.data_used["fit_x"].size == rec.n
    for name, truth in TRUTH.items():
        assert abs(est.value(name) - truth) < 4 * est.stderr(name), name


def test_coulomb_dominated_decay_with_many_cycles():
    p = OscillatorParams(J=1.0, K=16.0, c_mean=0.002, fk_mean=0.05, fk_delta=0.01)
    sim = simulate_free_decay(p, x0=1.5, duration=200.0, fs=50.0)
    assert sim.n_reversals > 100
    est = estimate_output_error(measure(sim.record, noise_std=0.003, rng=5), mass=1.0)
    assert est.value("fk_mean") == pytest.approx(0.05, rel=0.01)
    assert abs(est.value("c_mean") - 0.002) < 4 * est.stderr("c_mean")


def test_bad_arguments_are_refused():
    rec = _decay()
    with pytest.raises(ParameterError, match="not both"):
        estimate_output_error(rec, mass=1.0, stiffness=16.0)
    with pytest.raises(ParameterError, match="bootstrap"):
        estimate_output_error(rec, mass=1.0, bootstrap=5)
    with pytest.raises(ParameterError, match="quantisation"):
        estimate_output_error(rec, mass=1.0, quantisation=-1.0)
    flat = Record(t=np.arange(100) * 0.01, x=np.zeros(100))
    with pytest.raises(IdentificationError):
        estimate_output_error(flat, mass=1.0)


def test_decimated_search_gives_the_full_fit(monkeypatch):
    """Long records search the stop count on a decimated copy; the final fit uses all samples."""
    import driveid.identify.free_decay.output_error as oe

    rec = measure(_decay(), noise_std=0.01, rng=6)
    full = estimate_output_error(rec, mass=1.0)
    monkeypatch.setattr(oe, "_SEARCH_SAMPLES", 500)  # decimate the 3001 samples by 7
    fast = estimate_output_error(rec, mass=1.0)
    for name in TRUTH:
        # same minimum of the same full-record problem: agreement far inside one s.e.
        assert fast.value(name) == pytest.approx(full.value(name), abs=1e-3 * full.stderr(name))
        assert fast.stderr(name) == pytest.approx(full.stderr(name), rel=1e-3)


def test_encoder_offset_warns_only_when_it_makes_friction_push():
    # fk_delta = 0: an encoder zero d away from the spring zero trades one-for-one with
    # theta_k_delta (unidentifiable); at d = 3 theta_k_mean one direction's friction would push
    sym = OscillatorParams(J=1.0, K=16.0, c_mean=0.3, c_delta=0.0, fk_mean=0.07, fk_delta=0.0)
    rec = simulate_free_decay(sym, x0=2.0, duration=20.0, fs=100.0).record
    offset = 3 * 0.07 / 16
    shifted = Record(t=rec.t, x=rec.x + offset)
    warned = estimate_output_error([shifted], mass=1.0)
    assert any("x_ref" in w for w in warned.warnings)
    told = estimate_output_error([shifted], mass=1.0, x_ref=offset)
    assert not any("x_ref" in w for w in told.warnings)
    # with the spring zero given, the symmetric truth comes back (clean record: 1e-6 of fk)
    assert abs(told.value("fk_delta")) < 1e-6 * 0.07
    assert told.value("fk_mean") == pytest.approx(0.07, rel=1e-6)


def test_long_records_are_fitted_on_every_kth_sample_with_honest_errors(monkeypatch):
    # the memory bound of issue 12, forced on a short record: 4x fewer samples -> the same
    # estimate within its errors, and errors about sqrt(4) = 2x those of the full fit
    import driveid.identify.free_decay.output_error as oe

    rec = _decay(fs=1000.0, duration=20.0, x0=1.0)
    noisy = Record(t=rec.t, x=rec.x + np.random.default_rng(3).normal(0, 1e-3, rec.n))
    full = estimate_output_error([noisy], mass=1.0, quantisation=None)
    monkeypatch.setattr(oe, "_MAX_FIT_SAMPLES", rec.n // 4 + 1)
    thin = estimate_output_error([noisy], mass=1.0, quantisation=None)
    assert any("every 4th sample" in w for w in thin.warnings)
    for name in ("c_mean", "fk_mean", "omega0"):
        ratio = thin.stderr(name) / full.stderr(name)
        assert 1.6 < ratio < 2.5, (name, ratio)  # sqrt(4) = 2, +-25 % for the candidate mix
        # same data subsampled: the two estimates differ by ~ the thin fit's error
        assert abs(thin.value(name) - full.value(name)) < 4 * thin.stderr(name)


def test_detect_quantum_reads_an_encoder_printed_with_few_decimals():
    # a lab's export: 8000 counts/rev converted to rad and printed to 1e-7 rad (each step
    # then 1e-4 of itself off) over ~1000 counts; the old smallest-step search missed it
    q = 2 * np.pi / 8000
    walk = np.cumsum(np.random.default_rng(0).normal(0, 3e-3, 20000))
    printed = np.round(np.round(walk / q) * q, 7)
    # 1e-6: the refined step averages ~1e4 steps of 5e-8 rad print error each
    assert detect_quantum(printed) == pytest.approx(q, rel=1e-6)
    assert detect_quantum(walk) is None  # continuous data: no grid
