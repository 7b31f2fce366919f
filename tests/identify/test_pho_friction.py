"""PHO with asymmetric viscous and kinetic friction under delayed feedback (issue 5 acceptance).

Truth: the parameters given to the event-located drive simulator, whose runs are measured at
1 kHz through an encoder (quantisation) exactly as a test bed would record them.
"""

import math

import numpy as np
import pytest

from driveid.errors import IdentificationError, ParameterError
from driveid.identify.free_decay.logdec import estimate_log_decrement
from driveid.identify.pho.peaks import (
    _mean_offset_gain,
    estimate_pho_records,
    pho_peaks,
    pho_run_from_records,
)
from driveid.io.record import Record
from driveid.sim import simulate_drive
from driveid.sim.drive import BodyParams, DriveParams, PDFeedback
from driveid.sim.oscillator import measure

# Thesis Table 5.2 "A only" (published) and Table 5.3 "motor only", with the asymmetry the
# issue asks for: c_delta = 30 % of c_mean, fk_delta = 10 % of fk_mean.
TESTBED = {"J": 0.0115355, "c_mean": 0.0007457, "fk_mean": 0.109456, "delay": 13.77e-3,
           "grid": [(2.0, 0.03), (3.5, 0.045), (5.0, 0.06), (6.5, 0.075), (8.0, 0.09)],
           "x0": 1.0, "encoder": {"counts_per_rev": 8000}}
PENDULUM = {"J": 1.425, "c_mean": 0.3656, "fk_mean": 3.733, "delay": 10.84e-3,
            "grid": [(200.0, 2.0), (275.0, 2.75), (350.0, 3.5), (425.0, 4.25), (500.0, 5.0)],
            "x0": 0.3, "encoder": {"counts_per_unit": 1e5}}  # 10 µm linear encoder
for plant in (TESTBED, PENDULUM):
    plant["c_delta"] = 0.3 * plant["c_mean"]
    plant["fk_delta"] = 0.1 * plant["fk_mean"]


def body(plant):
    return BodyParams(J=plant["J"], c_mean=plant["c_mean"], c_delta=plant["c_delta"],
                      fk_mean=plant["fk_mean"], fk_delta=plant["fk_delta"])


def run(plant, P, D, x0, *, seed=0, duration=6.0):
    params = DriveParams(bodies=(body(plant),),
                         feedback=PDFeedback(P=P, D=D, delay=plant["delay"]))
    rec = simulate_drive(params, duration=duration, fs=1000.0, x0=[x0]).record
    rec = measure(rec, rng=np.random.default_rng(seed), **plant["encoder"])
    return Record(rec.t, rec.x, u=rec.u, meta=dict(rec.meta, P=P, D=D))


def campaign(plant):
    return [run(plant, P, D, sign * plant["x0"], seed=k)
            for k, (P, D) in enumerate(plant["grid"]) for sign in (1, -1)]


@pytest.fixture(scope="module", params=["testbed", "pendulum"])
def simulated(request):
    plant = TESTBED if request.param == "testbed" else PENDULUM
    return plant, campaign(plant)


def test_kinetic_offset_is_force_over_k_plus_p_not_the_free_decay_one():
    # noise-free pair: the offset must follow F/(K + P); the free-decay reading F/(J ω0²)
    # (J ω0² = K + b with the delayed b ≠ P) is visibly different.
    P, D = 2.0, 0.03
    params = DriveParams(bodies=(body(TESTBED),),
                         feedback=PDFeedback(P=P, D=D, delay=TESTBED["delay"]))
    records = [simulate_drive(params, duration=6.0, fs=1000.0, x0=[s]).record
               for s in (1.0, -1.0)]
    ld = estimate_log_decrement(records, peaks=[pho_peaks(r) for r in records])
    ours = ld.value("theta_k_mean") * P
    free_decay = ld.value("theta_k_mean") * TESTBED["J"] * ld.value("omega0") ** 2
    # 1e-3: the measured effect of the switching transients on the fast delay roots (3e-4).
    assert ours == pytest.approx(TESTBED["fk_mean"], rel=1e-3)
    assert abs(free_decay / TESTBED["fk_mean"] - 1) > 5e-3
    assert ld.value("theta_k_delta") * P == pytest.approx(TESTBED["fk_delta"], rel=1e-2)


def test_delay_correction_of_the_mean_offset():
    # P = 8 on the test bed: the delayed loop biases θk_mean·(K + P) by -2e-3; the
    # step-response correction (module notes of pho.py) must remove it.
    P, D = 8.0, 0.09
    params = DriveParams(bodies=(body(TESTBED),),
                         feedback=PDFeedback(P=P, D=D, delay=TESTBED["delay"]))
    records = [simulate_drive(params, duration=6.0, fs=1000.0, x0=[s]).record
               for s in (1.0, -1.0)]
    feat = pho_run_from_records(records, P=P, D=D)
    plain = feat.theta_k_mean * P / TESTBED["fk_mean"] - 1
    gain = _mean_offset_gain(feat, TESTBED["J"], TESTBED["c_mean"], 0.0, TESTBED["delay"])
    corrected = feat.theta_k_mean / gain / TESTBED["fk_mean"] - 1
    assert plain < -1e-3
    assert abs(corrected) < 2e-4  # measured 6e-6; 2e-4 is the level seen over P = 2 ... 8


def test_campaign_meets_the_issue_bounds_and_the_uncompensated_one_does_not(simulated):
    plant, records = simulated
    est = estimate_pho_records(records, delay=plant["delay"], K_known=0.0)
    # The issue's acceptance bounds (measured errors are 10-100x smaller, see README).
    assert est.value("J") == pytest.approx(plant["J"], rel=5e-3)
    assert est.value("c_mean") == pytest.approx(plant["c_mean"], rel=3e-2)
    assert est.value("fk_mean") == pytest.approx(plant["fk_mean"], rel=1e-2)
    assert est.value("c_delta") == pytest.approx(plant["c_delta"], rel=0.1)
    assert est.value("fk_delta") == pytest.approx(plant["fk_delta"], rel=0.1)
    for name in ("J", "c_mean", "c_delta", "fk_mean", "fk_delta"):
        assert 0 < est.stderr(name) < math.inf
    # the delay estimated from the same campaign changes nothing that matters
    free = estimate_pho_records(records, K_known=0.0)
    assert free.value("delay") == pytest.approx(plant["delay"], rel=1e-2)
    assert free.value("J") == pytest.approx(plant["J"], rel=5e-3)
    # Δt = 0 (the thesis's Table 5.2): mass off by percents, viscous friction by far more
    plain = estimate_pho_records(records, delay=0.0, K_known=0.0)
    assert abs(plain.value("J") / plant["J"] - 1) > 0.01
    assert abs(plain.value("c_mean") / plant["c_mean"] - 1) > 1.0


def test_negative_d_gives_a_bullet_envelope_that_is_still_identified():
    # P = 2, D = 0: the delay makes the net damping negative (σ < 0), kinetic friction
    # still stops the motion, and the peaks shrink faster as they shrink.
    P, D = 2.0, 0.0
    records = [run(TESTBED, P, D, s * 0.3, duration=4.0) for s in (1, -1)]
    swings = np.abs(np.diff(pho_peaks(records[0]).x))  # peak to peak, offsets cancel
    decrements = -np.diff(swings)
    assert swings.size >= 5 and np.all(decrements > 0)
    assert np.all(np.diff(decrements) > 0)  # accelerating: the bullet shape
    feat = pho_run_from_records(records, P=P, D=D)
    assert feat.sigma < 0
    others = [run(TESTBED, P2, D2, s * TESTBED["x0"]) for P2, D2 in TESTBED["grid"][2:4]
              for s in (1, -1)]
    est = estimate_pho_records(records + others, delay=TESTBED["delay"], K_known=0.0)
    assert est.value("J") == pytest.approx(TESTBED["J"], rel=5e-3)  # issue bound
    assert est.value("fk_mean") == pytest.approx(TESTBED["fk_mean"], rel=1e-2)  # issue bound


def test_ill_posed_campaigns_say_what_to_add():
    one = run(TESTBED, 2.0, 0.03, 1.0, duration=3.0)
    with pytest.raises(IdentificationError, match="share P=2.0, D=0.03.*add runs"):
        estimate_pho_records([one])
    with pytest.raises(IdentificationError, match="share P=2.0"):
        estimate_pho_records([one, run(TESTBED, 2.0, 0.03, -1.0, duration=3.0)])
    with pytest.raises(IdentificationError, match="no records"):
        estimate_pho_records([])
    # P·x0 below the kinetic friction: the release never moves the body
    dead = run(TESTBED, 0.05, 0.01, 1.0, duration=3.0)
    with pytest.raises(IdentificationError, match="P=0.05, D=0.01.*no oscillation"):
        estimate_pho_records([one, dead])
    bare = Record(one.t, one.x)
    with pytest.raises(ParameterError, match=r"meta\['P'\]"):
        estimate_pho_records([bare, one])


def test_campaign_figure_shows_each_run_against_the_estimate(simulated, tmp_path):
    plant, records = simulated
    est = estimate_pho_records(records, delay=plant["delay"], K_known=0.0)
    for name in ("c_mean", "fk_mean", "fk_delta"):
        per_run = est.data_used[f"{name}_per_run"]
        assert per_run.shape == (len(plant["grid"]),)
        # each run alone within 5 % of the truth: the campaign is consistent run by run
        np.testing.assert_allclose(per_run, plant[name], rtol=5e-2)
    from driveid.report.figures import plot_estimate

    fig = plot_estimate(est)
    path = tmp_path / "pho.png"
    fig.savefig(path)
    assert path.stat().st_size > 10_000
