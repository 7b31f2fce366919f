"""Honest error bars of the PHO campaign fit (issue 24): static band, noise model, adequacy.

Truth: the parameters given to the event-located drive simulator, with the plant's static
friction above its kinetic friction (thesis §2.1.1.2, 2.137, 2.155a) — the normal case the
fit used to miss by 50 standard errors. Small seeded Monte-Carlo studies here; the large
ones are ``benchmarks/bench_pho_coverage.py --static 1.1,1.3 --negative-d`` and
``--noise ar1`` (figures in docs/pho-fit.md).
"""

import math

import numpy as np
import pytest
from scipy.signal import lfilter

from driveid.errors import ParameterError
from driveid.identify.pho import _pho_fit_core as core
from driveid.identify.pho.pho_fit import estimate_pho_output_error
from driveid.io.record import Record
from driveid.sim import simulate_drive
from driveid.sim.drive import BodyParams, DriveParams, PDFeedback

#: thesis Table 5.2 "A only" with the asymmetry of test_pho_fit.py
TESTBED = {"J": 0.0115355, "c_mean": 0.0007457, "c_delta": 0.3 * 0.0007457,
           "fk_mean": 0.109456, "fk_delta": 0.1 * 0.109456, "delay": 13.77e-3}
TESTBED_Q = 2 * math.pi / 8000
#: the pendulum-cart preset (Table 5.3 mass, motor friction) with the same asymmetry
CART = {"J": 2.39, "c_mean": 0.3656, "c_delta": 0.3 * 0.3656, "fk_mean": 3.733,
        "fk_delta": 0.1 * 3.733, "delay": 10.84e-3}
CART_Q = 1e-5
#: (P, D, x0): the preset-like pair, and two with negative net damping c + D - P·delay
#: (thesis Fig. 5.3), the second with D < 0, released below the amplitude where Coulomb
#: friction balances the negative viscous damping, 4 fk / (π |c_net| ω)
TESTBED_GRID = ((2.0, 0.03, 1.0), (2.0, 0.015, 0.8), (1.0, -0.005, 0.78))
#: the cart's pairs are chosen so that some runs stop with a force between kinetic and
#: 1.25 x kinetic (on this plant few do; measured by simulating 1.0 against 1.3)
CART_GRID = ((180.0, 2.25, 0.5), (240.0, 2.25, 0.3), (300.0, 2.0, 0.3), (100.0, -0.5, 0.4))
FIELDS = ("J", "c_mean", "c_delta", "fk_mean", "fk_delta")


def campaign(truth, grid, ratio, duration=2.5, fs=500.0):
    """Every (P, D) released from +x0 and -x0; static friction ``ratio`` times kinetic."""
    body = BodyParams(J=truth["J"], c_mean=truth["c_mean"], c_delta=truth["c_delta"],
                      fk_mean=truth["fk_mean"], fk_delta=truth["fk_delta"],
                      fs_mean=ratio * truth["fk_mean"], fs_delta=truth["fk_delta"])
    out = []
    for P, D, x0 in grid:
        for sign in (1.0, -1.0):
            fb = PDFeedback(P=P, D=D, delay=truth["delay"])
            rec = simulate_drive(DriveParams(bodies=(body,), feedback=fb), duration=duration,
                                 fs=fs, x0=[sign * x0]).record
            out.append(Record(rec.t, rec.x, meta={"P": P, "D": D, "x0": sign * x0}))
    return out


def quantised(records, quantum, gen):
    out = []
    for rec in records:
        phase = gen.uniform(0.0, quantum)
        out.append(rec.replace(x=quantum * np.round((rec.x - phase) / quantum) + phase))
    return out


def ar1(records, std, phi, gen):
    out = []
    for rec in records:
        w = gen.normal(0.0, std * math.sqrt(1 - phi**2), rec.n + 300)
        out.append(rec.replace(x=rec.x + lfilter([1.0], [1.0, -phi], w)[300:]))
    return out


def within_acceptance(est, truth):
    """Issue 24: J 3 %, f̄k 5 %, Δf_k within 5 % of f̄k, c̄ 15 %."""
    fk = truth["fk_mean"]
    return (abs(est.value("J") / truth["J"] - 1) <= 0.03
            and abs(est.value("fk_mean") / fk - 1) <= 0.05
            and abs(est.value("fk_delta") - truth["fk_delta"]) <= 0.05 * fk
            and abs(est.value("c_mean") / truth["c_mean"] - 1) <= 0.15)


@pytest.fixture(scope="module")
def sticky_testbed():
    """The issue's case: test bed, static 15 % above kinetic, the decaying runs of the CLI grid."""
    grid = [(2.0, 0.03, 1.0)] + [(P, D, 1.0) for P in (2.0, 3.0) for D in (0.04, 0.05)]
    return campaign(TESTBED, grid, 1.15, duration=4.0)


def test_static_band_is_chosen_and_the_kinetic_fit_warns(sticky_testbed):
    recs = quantised(sticky_testbed, TESTBED_Q, np.random.default_rng(0))
    est = estimate_pho_output_error(recs, delay=TESTBED["delay"], K_known=0.0, rng=0,
                                    bootstrap=25)
    d = est.diagnostics
    assert d["structure"] == "static band free"
    assert d["adequacy"]["structures"]["chosen"] == "static band free"
    assert "chosen over 'static = kinetic'" in d["adequacy"]["structures"]["reason"]
    assert within_acceptance(est, TESTBED)
    for name in FIELDS:
        # an honest 95 % interval; 4 se leaves room for one unlucky draw of 5 fields
        assert abs(est.value(name) - TESTBED[name]) < 4 * est.stderr(name), name
    band = d["static_band"]
    assert band["chosen"] and "fs_mean" in est and "fs_delta" in est
    # the band is bracketed by the rest positions: each bracket holds the true edge
    truth_plus = TESTBED["fk_delta"] + 1.15 * TESTBED["fk_mean"]
    lo, hi = band["bracket_plus"]
    assert lo <= truth_plus * 1.01 and (hi is None or hi >= truth_plus * 0.99)
    assert band["fs_mean"] >= est.value("fk_mean")  # static >= kinetic by construction
    # the structure the fit used to impose is far off (c_delta -41 %, 50 se on main); it
    # now says why and widens its error bars instead of staying silent
    kin = estimate_pho_output_error(recs, delay=TESTBED["delay"], K_known=0.0, rng=0,
                                    bootstrap=25, static="kinetic")
    assert abs(kin.value("c_delta") / TESTBED["c_delta"] - 1) > 0.2
    assert any("static friction is above kinetic" in w for w in kin.warnings)
    assert kin.diagnostics["adequacy"]["covariance"] == "sandwich"
    worst = max(abs(kin.value(n) - TESTBED[n]) / kin.stderr(n) for n in FIELDS)
    assert worst < 5  # widened: no longer tens of standard errors off


def test_coverage_on_sticky_pendulum_cart_with_negative_d_runs():
    # 12 quantised campaigns (10 µm encoder), static 25 % above kinetic; net damping
    # c + D - P·delay of the last two pairs is negative (one with D < 0), of the second ~0.
    # With honest 95 % intervals at most 3 of 12 misses per field happen by chance with
    # probability 0.98
    exact = campaign(CART, CART_GRID, 1.25, duration=4.0)
    reference = campaign(CART, CART_GRID, 1.0, duration=4.0)
    # the band changes where some runs stop (else this would test nothing new)
    assert sum(np.ptp(a.x - b.x) > 1e-4 for a, b in zip(exact, reference, strict=True)) >= 2
    gen = np.random.default_rng(7)
    hits = {n: 0 for n in FIELDS}
    accurate = 0
    for seed in range(12):
        est = estimate_pho_output_error(quantised(exact, CART_Q, gen), delay=CART["delay"],
                                        K_known=0.0, rng=seed, bootstrap=25)
        assert est.diagnostics["static_band"] is not None
        accurate += within_acceptance(est, CART)
        for n in FIELDS:
            hits[n] += abs(est.value(n) - CART[n]) <= 1.96 * est.stderr(n)
    assert accurate == 12
    assert min(hits.values()) >= 9, hits


def test_ar1_noise_is_modelled_and_covered():
    # AR(1) φ = 0.8 position noise (a filtered encoder chain) on an unquantised sticky test
    # bed campaign: the noise model finds order >= 1 with φ near 0.8 and the intervals
    # cover
    exact = campaign(TESTBED, TESTBED_GRID, 1.2)
    gen = np.random.default_rng(3)
    hits = {n: 0 for n in FIELDS}
    white_hits = {n: 0 for n in FIELDS}
    sandwich = 0
    for _ in range(8):
        recs = ar1(exact, 2e-4, 0.8, gen)
        est = estimate_pho_output_error(recs, delay=TESTBED["delay"], K_known=0.0,
                                        quantisation=None)
        noise = est.diagnostics["noise_model"]
        # φ from 15 000 samples: sd ~0.005; 0.1 allows for the higher orders BIC may add
        assert noise["order"] >= 1 and noise["ar"][0] == pytest.approx(0.8, abs=0.1)
        assert est.diagnostics["adequacy"]["covariance"] in ("prewhitened", "sandwich")
        white = estimate_pho_output_error(recs, delay=TESTBED["delay"], K_known=0.0,
                                          quantisation=None, noise_model=False,
                                          static="kinetic")
        sandwich += white.diagnostics["adequacy"]["covariance"] == "sandwich"
        for n in FIELDS:
            hits[n] += abs(est.value(n) - TESTBED[n]) <= 1.96 * est.stderr(n)
            white_hits[n] += abs(white.value(n) - TESTBED[n]) <= 1.96 * white.stderr(n)
    # 8 draws: P(<= 5 hits | 95 %) = 0.006 per field
    assert min(hits.values()) >= 6, hits
    # without the noise model the residuals fail the whiteness test, and the error bars are
    # widened by the sandwich instead of staying white (~3x too narrow): honest too
    assert min(white_hits.values()) >= 6, white_hits
    assert sandwich == 8


def test_white_noise_stays_white_without_loss():
    exact = campaign(TESTBED, TESTBED_GRID[:2], 1.0)
    recs = ar1(exact, 2e-4, 0.0, np.random.default_rng(5))
    est = estimate_pho_output_error(recs, delay=TESTBED["delay"], K_known=0.0,
                                    quantisation=None, static="kinetic")
    plain = estimate_pho_output_error(recs, delay=TESTBED["delay"], K_known=0.0,
                                      quantisation=None, static="kinetic", noise_model=False)
    assert est.diagnostics["noise_model"]["kind"] == "white"
    assert est.diagnostics["adequacy"]["covariance"] == "white"
    for n in FIELDS:
        # same estimator, same error bars: order 0 changes nothing
        assert est.value(n) == plain.value(n)
        assert est.stderr(n) == pytest.approx(plain.stderr(n), rel=1e-12)


def test_static_equal_to_kinetic_keeps_the_simple_structure():
    exact = campaign(TESTBED, TESTBED_GRID[:2], 1.0)
    recs = ar1(exact, 2e-4, 0.0, np.random.default_rng(6))
    est = estimate_pho_output_error(recs, delay=TESTBED["delay"], K_known=0.0,
                                    quantisation=None)
    assert est.diagnostics["structure"] == "static = kinetic"
    assert "fs_mean" not in est
    assert est.diagnostics["static_band"]["chosen"] is False


def test_projection_keeps_friction_branches_non_negative_and_names_the_bound():
    lower = np.concatenate([[1e-9, -np.inf, -np.inf, 0, 0, -np.inf, 0, 0, 0], [-np.inf]])
    theta = np.array([1.0, 0.1, 0.3, 0.0, 0.2, -0.5, 0.01, -0.1, 0.05, 1.0])
    out = core.project(theta, lower, np.full(10, np.inf))
    assert out[1] - out[2] >= 0 and out[1] + out[2] >= 0  # c± >= 0
    assert out[4] + out[5] >= -1e-15 and out[4] - out[5] >= 0  # fk± >= 0
    assert out[7] == 0.0  # static >= kinetic
    names = core.at_bounds(out, list(range(9)), lower)
    assert "c_mean - c_delta = 0" in names and "fk_mean + fk_delta = 0" in names


def test_bad_static_option_is_refused(sticky_testbed):
    with pytest.raises(ParameterError, match="static must be 'auto'"):
        estimate_pho_output_error(sticky_testbed, static="stiction")


def test_a_fit_in_a_wrong_basin_is_restarted_and_says_so():
    # the one campaign of 200 (benchmarks/bench_pho_coverage.py --static 1.2 --noise ar1,
    # seed 0) where the fit from the peak start (c_mean +33 % under AR(1) noise) ended in a
    # wrong basin: c_mean -16 %, c_delta +80 %, residual 11x the noise at rest
    from driveid.identify.pho.peaks import estimate_pho_records
    from driveid.sim.presets import preset

    tb = preset("testbed-a")
    truth = dict(TESTBED, delay=tb.feedback.delay)
    grid = [(2.0, 0.03, 1.0), (2.0, 0.04, 1.0), (2.0, 0.05, 1.0), (3.0, 0.04, 1.0),
            (3.0, 0.05, 1.0), (2.0, 0.015, 0.8), (1.0, -0.005, 0.78)]
    exact = campaign(truth, grid, 1.2, duration=4.0)
    gen = np.random.default_rng(0)
    recs = []
    for rec in exact:  # AR(1) noise, phi 0.8, sd one encoder quantum
        w = gen.normal(0.0, TESTBED_Q * math.sqrt(1.0 - 0.8**2), rec.n + 500)
        recs.append(rec.replace(x=rec.x + lfilter([1.0], [1.0, -0.8], w)[500:]))
    start = estimate_pho_records(recs, K_known=0.0)
    est = estimate_pho_output_error(recs, K_known=0.0, start=start, rng=0)
    restart = est.diagnostics["restart"]
    assert restart["misfit"]["first"] > 3.0  # the wrong basin is still reached first
    assert restart["c_mean_factor"] is not None and est.diagnostics["misfit_ratio"] < 3.0
    assert any("restarted with c_mean" in w for w in est.warnings)
    # the accuracy (c 15 %, fk 5 %) and the truth within 3 s.e. of every field
    assert abs(est.value("c_mean") / truth["c_mean"] - 1) < 0.15
    for name in FIELDS:
        assert abs(est.value(name) - truth[name]) < 3 * est.stderr(name), name
