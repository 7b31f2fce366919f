"""Extended logarithmic decrement against the exact simulator and thesis Table 5.1."""

import math

import numpy as np
import pytest

from driveid.errors import IdentificationError, ParameterError, RecordError
from driveid.identify.free_decay.logdec import estimate_log_decrement, estimate_log_decrement_thesis
from driveid.io import Record
from driveid.sim import OscillatorParams, measure, simulate_free_decay

# Thesis Table 5.1 "simulated" rows: K = ω0² (J = 1), f̄k ± Δfk [N·m], c̄ ± Δc [N·m·s/rad].
TABLE_5_1 = [
    (10.0, 0.2, 0.5, 0.4, 0.3),
    (16.0, 0.2, 0.5, 0.3, 0.4),
    (16.0, 0.07, 0.13, 0.3, 0.0),
    (16.0, 2.0, 2.0, 0.625, 0.125),
    (4.0, 0.0, 0.0, 0.4, 0.3),
    (4.0, 0.2, 0.0, 0.5, 0.0),
    (16.0, 6.25, 5.75, 0.625, 0.125),
    (16.0, 0.4, 0.3, 0.1, 0.0),
]
# The thesis gives neither x0 nor the sample rate: released at rest from X0 = 10 rad, 1 kHz, 30 s.
X0, FS, DURATION = 10.0, 1000.0, 30.0


def _case(K, fk_mean, fk_delta, c_mean, c_delta, x0=X0):
    p = OscillatorParams(J=1.0, K=K, c_mean=c_mean, c_delta=c_delta, fk_mean=fk_mean,
                         fk_delta=fk_delta)
    return p, simulate_free_decay(p, x0=x0, duration=DURATION, fs=FS)


def _rel_errors(est, p):
    truth = {"K": p.K, "c_mean": p.c_mean, "c_delta": p.c_delta, "fk_mean": p.fk_mean,
             "fk_delta": p.fk_delta, "omega0": p.omega0}
    # relative to the value, or to 1 N·m / N·m·s/rad where the truth is zero
    return {k: abs(est.value(k) - v) / (abs(v) if v else 1.0) for k, v in truth.items()}


@pytest.mark.parametrize("case", TABLE_5_1, ids=[f"case{i + 1}" for i in range(8)])
def test_table_5_1_clean_within_0_01_percent(case):
    p, sim = _case(*case)
    for est in (estimate_log_decrement(sim.record, mass=1.0),
                estimate_log_decrement_thesis(sim.record, corrected=True, mass=1.0)):
        errors = _rel_errors(est, p)
        # the bound; measured worst 5e-6 (peak refinement at 1 kHz)
        assert max(errors.values()) < 1e-4, (est.method, errors)


@pytest.mark.parametrize("case", TABLE_5_1, ids=[f"case{i + 1}" for i in range(8)])
def test_table_5_1_encoder_8000_counts_within_0_5_percent(case):
    p, sim = _case(*case)
    rec = measure(sim.record, counts_per_rev=8000)
    errors = _rel_errors(estimate_log_decrement(rec, mass=1.0), p)
    # the bound for 8000 counts/rev (quantum 7.9e-4 rad); measured worst 2.1e-3
    assert max(errors.values()) < 5e-3, errors


def test_stiffness_known_gives_mass():
    p, sim = _case(16.0, 0.07, 0.03, 0.3, 0.1)
    est = estimate_log_decrement(sim.record, stiffness=16.0)
    assert est.value("J") == pytest.approx(1.0, rel=1e-5)  # clean record: round-off level
    assert est.stderr("K") == 0.0  # K was given, not estimated


def test_thesis_errata_as_printed():
    """Each printed formula fails in the way its erratum predicts (module docstring)."""
    p, sim = _case(16.0, 0.07, 0.03, 0.3, -0.1, x0=1.0)
    printed = estimate_log_decrement_thesis(sim.record, corrected=False)
    fixed = estimate_log_decrement_thesis(sim.record, corrected=True)
    zp = p.zeta(1)
    # median over windows, the last tiny ones too: 1e-3 covers their round-off
    assert fixed.value("zeta_plus") == pytest.approx(zp, rel=1e-3)
    # (2.171) with the β of (2.169): ζ_printed = β/sqrt(π²+β²), β = ζ/sqrt(1-ζ²)
    beta = zp / math.sqrt(1 - zp**2)
    # first window of printed formulas: label follows parity, so compare as a set
    printed_z = {printed.value("zeta_plus"), printed.value("zeta_minus")}
    assert any(abs(z - beta / math.sqrt(math.pi**2 + beta**2)) < 1e-5 for z in printed_z)
    # (2.172) takes |ζ⁺-ζ⁻|: the sign of c_delta < 0 is lost
    assert printed.value("zeta_delta") > 0 > fixed.value("zeta_delta")
    # (2.170b) on measured positions: Δθk has the wrong sign
    assert printed.value("theta_k_delta") == pytest.approx(-0.03 / 16, rel=1e-3)
    # (2.170a) parity: x0 > 0 (first swing negative) gives -θk; x0 < 0 gives +θk
    assert printed.value("theta_k_mean") == pytest.approx(-0.07 / 16, rel=1e-3)
    _, sim_neg = _case(16.0, 0.07, 0.03, 0.3, -0.1, x0=-1.0)
    printed_neg = estimate_log_decrement_thesis(sim_neg.record, corrected=False)
    assert printed_neg.value("theta_k_mean") == pytest.approx(0.07 / 16, rel=1e-3)
    # (2.175) with sqrt(1-ζ) overestimates ω0 by ~ζ/2 (here ≈ 0.6 %)
    assert printed.value("omega0") / 4.0 - 1 > 3e-3
    assert fixed.value("omega0") == pytest.approx(4.0, rel=1e-6)


def test_mixing_positive_and_negative_runs():
    p = OscillatorParams(J=1.0, K=16.0, c_mean=0.3, c_delta=0.1, fk_mean=0.07, fk_delta=0.03)
    rng = np.random.default_rng(3)
    recs = [measure(simulate_free_decay(p, x0=s, duration=20.0).record, noise_std=5e-4,
                    rng=rng) for s in (1.0, -1.0)]
    joint = estimate_log_decrement(recs, mass=1.0)
    single = estimate_log_decrement(recs[0], mass=1.0)
    assert joint.diagnostics["n_records"] == 2
    for name in ("c_mean", "c_delta", "fk_mean", "fk_delta"):
        assert joint.stderr(name) < single.stderr(name)  # twice the peaks, smaller errors
        # 4 standard errors: a deterministic check with a fixed seed, not a coverage claim
        assert abs(joint.value(name) - getattr(p, name)) < 4 * joint.stderr(name)


def test_standard_errors_are_honest_monte_carlo():
    """Truth within ±2 s.e. in about 95 % of noisy runs (issue acceptance)."""
    p = OscillatorParams(J=1.0, K=16.0, c_mean=0.3, c_delta=0.1, fk_mean=0.07, fk_delta=0.03)
    exact = simulate_free_decay(p, x0=1.0, duration=20.0).record
    truth = {"omega0": 4.0, "c_mean": 0.3, "c_delta": 0.1, "fk_mean": 0.07, "fk_delta": 0.03}
    rng = np.random.default_rng(2024)
    runs = 120
    hits = dict.fromkeys(truth, 0)
    for _ in range(runs):
        est = estimate_log_decrement(measure(exact, noise_std=5e-4, rng=rng), mass=1.0)
        for name, value in truth.items():
            hits[name] += abs(est.value(name) - value) <= 2 * est.stderr(name)
    coverage = {k: v / runs for k, v in hits.items()}
    # 120 runs: binomial s.d. of a 95 % coverage is 2 %; 0.85 is 5 s.d. below, so a failure
    # means the errors are too small, not bad luck. Measured: 0.88-0.97 (see README).
    assert min(coverage.values()) >= 0.85, coverage
    assert np.mean(list(coverage.values())) >= 0.90, coverage


def test_errors_name_the_problem():
    t = np.arange(3000) / 1000.0
    with pytest.raises(IdentificationError, match="constant"):
        estimate_log_decrement(Record(t=t, x=np.ones_like(t)))
    over = simulate_free_decay(OscillatorParams(J=1.0, K=16.0, c_mean=20.0), x0=1.0,
                               duration=3.0).record
    with pytest.raises(IdentificationError, match="does not oscillate|usable peaks"):
        estimate_log_decrement(over)
    # ζ = 0.625 seen by an 8000 counts/rev encoder: four peaks above 4 quanta
    damped = measure(simulate_free_decay(OscillatorParams(J=1.0, K=16.0, c_mean=5.0), x0=1.0,
                                         duration=5.0).record, counts_per_rev=8000)
    with pytest.raises(IdentificationError, match="at least 5"):
        estimate_log_decrement(damped)
    good = simulate_free_decay(OscillatorParams(J=1.0, K=16.0, c_mean=0.3), x0=1.0,
                               duration=10.0).record
    with pytest.raises(ParameterError, match="not both"):
        estimate_log_decrement(good, mass=1.0, stiffness=16.0)
    with pytest.raises(ParameterError, match="mass must be a positive"):
        estimate_log_decrement(good, mass=-1.0)
    with pytest.raises(RecordError, match="non-finite"):
        Record(t=t, x=np.r_[np.nan, np.zeros(2999)])


@pytest.mark.parametrize("zetas", [(0.05, 0.025), (0.6, 0.9), (1e-4, 2e-4), (0.999, 0.5)])
def test_vectorised_peak_recursion_equals_the_step_by_step_recursion(zetas):
    # reference: the recursion (2.168) one peak at a time, as written in the thesis
    from driveid.identify.free_decay.logdec import _ratio, peak_recursion

    rng = np.random.default_rng(7)
    directions = np.where(rng.random(5000) < 0.5, 1, -1)
    directions[::2] = -directions[1::2][: directions[::2].size]  # mostly alternating
    kw = dict(zeta_plus=zetas[0], zeta_minus=zetas[1], theta_k_mean=0.003,
              theta_k_delta=-0.001)
    got = peak_recursion(0.7, directions, **kw)
    ref = np.empty(directions.size)
    ref[0] = 0.7
    for n in range(1, directions.size):
        s = int(directions[n])
        eq = -(kw["theta_k_mean"] * s + kw["theta_k_delta"])
        rho = _ratio(kw["zeta_plus"] if s > 0 else kw["zeta_minus"])
        ref[n] = eq - rho * (ref[n - 1] - eq)
    # cumulative products over chunks of <= 256 steps: rounding ~ 256 eps of the swing
    np.testing.assert_allclose(got, ref, rtol=0, atol=1e-12)
