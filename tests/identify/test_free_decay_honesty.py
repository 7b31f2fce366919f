"""Free-decay output error on real-like records (issue 24): noise model, adequacy, bounds.

Truth: the exact simulator (viscous + Coulomb, thesis 2.139-2.143) and, for air drag, an
ODE integration at rtol 1e-11 (tests/fixtures/free_decays.py).
"""

import json
import math

import numpy as np
import pytest
from click.testing import CliRunner
from scipy.signal import lfilter

from driveid.cli import cli
from driveid.errors import RecordWarning
from driveid.identify.core._noise import NoiseModel
from driveid.identify.free_decay import _free_response, output_error
from driveid.identify.free_decay._free_decay_structures import StreamWhitener
from driveid.identify.free_decay.output_error import estimate_output_error
from driveid.io import read_record
from driveid.sim import OscillatorParams, measure, simulate_free_decay
from driveid.validate import compare
from tests.fixtures.free_decays import (
    write_coulomb_pendulum,
    write_eddy_pendulum,
    write_video_pendulum,
)

P = OscillatorParams(J=1.0, K=16.0, c_mean=0.3, c_delta=0.1, fk_mean=0.07, fk_delta=0.03)


def _cli(*args):
    return CliRunner().invoke(cli, [str(a) for a in args])


def test_stream_whitener_equals_whole_record_whitening():
    rng = np.random.default_rng(0)
    x = rng.normal(size=(1000, 3))
    noise = NoiseModel((0.6, -0.2, 0.1), 1.0, 1.0, 1000)
    w = StreamWhitener(noise, 3)
    blocks = np.concatenate([w(x[a:a + 97]) for a in range(0, 1000, 97)])
    # the same FIR filter, state carried: equal to round-off
    assert np.allclose(blocks, noise.whiten(x), atol=1e-12)


def test_white_noise_keeps_the_white_fit():
    rec = measure(simulate_free_decay(P, x0=1.0, duration=20.0, fs=100.0).record,
                  noise_std=0.002, rng=1)
    est = estimate_output_error(rec, mass=1.0)
    assert est.diagnostics["noise_model"]["kind"] == "white"
    assert est.diagnostics["adequacy"]["adequate"]
    assert est.diagnostics["adequacy"]["covariance"] == "prewhitened"


def test_blockwise_prewhitened_normal_equations_match_the_whole_jacobian(monkeypatch):
    """Above SINK_ROWS the whitened normal equations are summed in blocks with carried state."""
    rec = simulate_free_decay(P, x0=1.0, duration=20.0, fs=100.0).record
    e = lfilter([1.0], [1.0, -0.9], np.random.default_rng(2).normal(0, 0.003, rec.n))
    rec = rec.replace(x=rec.x + e)
    whole = estimate_output_error(rec, mass=1.0)
    assert whole.diagnostics["noise_model"]["order"] >= 1
    monkeypatch.setattr(output_error, "SINK_ROWS", 300)
    monkeypatch.setattr(_free_response, "SINK_ROWS", 300)
    blocks = estimate_output_error(rec, mass=1.0)
    for name in ("c_mean", "fk_mean", "c_delta"):
        # same minimum, same covariance: only the summation order differs
        assert blocks.value(name) == pytest.approx(whole.value(name), rel=1e-6)
        assert blocks.stderr(name) == pytest.approx(whole.stderr(name), rel=1e-4)


def test_coloured_noise_coverage_small_monte_carlo():
    """40 records with AR(1) φ = 0.9 noise: 95 % intervals must cover about 95 % of runs.

    Before the noise model the same runs covered 27-59 % (issue 24).
    """
    rec = simulate_free_decay(P, x0=1.0, duration=12.0, fs=50.0).record
    rng = np.random.default_rng(24)
    truth = {"c_mean": 0.3, "c_delta": 0.1, "fk_mean": 0.07, "fk_delta": 0.03}
    hits = dict.fromkeys(truth, 0)
    for _ in range(40):
        w = rng.normal(0.0, 0.01 * math.sqrt(1 - 0.81), rec.n + 300)
        e = lfilter([1.0], [1.0, -0.9], w)[300:]
        est = estimate_output_error(rec.replace(x=rec.x + e), mass=1.0)
        for n, v in truth.items():
            hits[n] += abs(est.value(n) - v) <= 1.96 * est.stderr(n)
    for n in truth:
        # Binomial(40, 0.95): P(<= 33) = 1.4 %, so >= 34 hits from honest intervals
        assert hits[n] >= 34, (n, hits[n])


def test_passive_bounds_and_at_bound_report():
    p = OscillatorParams(J=1.0, K=16.0, c_mean=0.0, fk_mean=0.05)
    rec = measure(simulate_free_decay(p, x0=1.0, duration=30.0, fs=50.0).record,
                  noise_std=0.002, rng=3)
    est = estimate_output_error(rec, mass=1.0)
    assert est.value("zeta_plus") >= 0 and est.value("zeta_minus") >= 0
    # the plausibility check also records ill-determined parameters there (at_bound False)
    bound = [n for n, e in est.diagnostics["at_bound"].items() if e["at_bound"]]
    assert bound  # zero damping with noise: one direction at least ends at its bound
    for name in bound:
        assert any(name in w and "bound" in w for w in est.warnings)
        lo, hi = est.diagnostics["one_sided_95"][name]
        assert lo == 0.0 and hi > est.value(name)
    free = estimate_output_error(rec, mass=1.0, passive=False)
    # without the bound a noisy zero damping comes out either sign; with it never negative
    for name in ("zeta_plus", "zeta_minus"):
        if free.value(name) < 0:  # unbounded, so the plausibility check must say so
            assert free.diagnostics["at_bound"][name]["at_bound"]
            assert any(w.startswith(name) for w in free.warnings)


def test_non_uniform_timestamps_are_modelled_not_resampled():
    rng = np.random.default_rng(4)
    t = np.sort(rng.uniform(0.0, 20.0, 2000))
    t[0] = 0.0
    exact = simulate_free_decay(P, x0=1.0, duration=20.0, t=t).record
    rec = exact.replace(x=exact.x + rng.normal(0, 0.002, exact.n), max_jitter=None)
    with pytest.warns(RecordWarning, match="resampled"):  # the peak start values only
        est = estimate_output_error(rec, mass=1.0)
    assert est.data_used["fit_x"].size == rec.n  # one model value per actual timestamp
    for name, v in (("c_mean", 0.3), ("fk_mean", 0.07)):
        assert abs(est.value(name) - v) < 4 * est.stderr(name), name


def test_eddy_current_pendulum_cassy_export(tmp_path):
    path, truth = write_eddy_pendulum(tmp_path)
    rec = read_record(path, max_jitter=None)
    with pytest.warns(RecordWarning, match="resampled"):  # the peak start values only
        est = estimate_output_error(rec, mass=truth["J"], rng=1)
    assert est.diagnostics["structure"] == "viscous + Coulomb"
    assert est.diagnostics["mid_swing"] == [True]
    assert est.value("zeta_plus") > 0 and est.value("zeta_minus") > 0
    # 4 standard errors: bootstrap error bars (B = 25) are themselves ~15 % uncertain
    assert abs(est.value("c_mean") - truth["c_mean"]) < 4 * est.stderr("c_mean")
    result = _cli("identify", "logdec", path, "--mass", truth["J"], "--max-jitter", "none",
                  "--json", "--seed", 1)
    assert result.exit_code == 0, result.output
    data = json.loads(result.stdout)
    assert data["diagnostics"]["structure"] == "viscous + Coulomb"
    assert data["diagnostics"]["noise_model"]["kind"]


def test_video_pendulum_with_air_drag(tmp_path):
    path, truth = write_video_pendulum(tmp_path)
    rec = read_record(path, max_jitter=None)
    est = estimate_output_error(rec, mass=truth["J"])
    assert est.diagnostics["structure"] == "+ quadratic damping"
    assert est.diagnostics["adequacy"]["adequate"]
    assert est.value("zeta_plus") > 0 and est.value("zeta_minus") > 0
    for name in ("c_mean", "c_quad"):
        # 4 standard errors (the drag is fitted by its equivalent linearisation per half
        # cycle, exact to O(ζ) of the 0.002 damping ratio)
        assert abs(est.value(name) - truth[name]) < 4 * est.stderr(name), name
    # validate simulates the structure that was fitted (until 2026-11-28 it dropped the drag:
    # fit 76.8 % on this record, 87.2 % held out, both warned as "does not describe"); the
    # held-out record (other noise) starts mid-swing, so its release is fitted before the
    # first sample. The residual is then the 0.3 mm sensor noise: 10 % slack for the
    # equivalent linearisation and the held-out release fit.
    fitted = compare(rec, est, index=0)
    assert fitted.residual_rms == pytest.approx(est.diagnostics["residual_rms"], rel=1e-3)
    assert fitted.model["structure"].startswith("+ quadratic damping")
    (tmp_path / "held_out").mkdir()
    other, _ = write_video_pendulum(tmp_path / "held_out", seed=6)
    held = compare(read_record(other, max_jitter=None), est)
    assert held.held_out and held.residual_rms < 1.1 * 3e-4
    assert held.t[0] > held.model["t_release"]  # released before the first sample


def test_coulomb_dominated_500_s(tmp_path):
    path, truth = write_coulomb_pendulum(tmp_path)
    rec = read_record(path, max_jitter=None)
    with pytest.warns(RecordWarning, match="resampled"):  # the peak start values only
        est = estimate_output_error(rec, mass=truth["J"], rng=2)
    assert est.diagnostics["structure"] == "viscous + Coulomb"
    assert est.diagnostics["adequacy"]["adequate"]
    assert est.data_used["release_t"][0] == pytest.approx(-0.7, abs=0.01)  # mid-swing start
    assert est.value("zeta_plus") >= 0 and est.value("zeta_minus") >= 0
    assert est.value("c_mean") >= 0
    # Coulomb friction dominates the decay: within 2 % (the issue saw 2-3x)
    assert est.value("fk_mean") == pytest.approx(truth["fk_mean"], rel=0.02)


def test_coulomb_decay_whose_last_half_cycles_hide_below_the_encoder_step(tmp_path):
    # 0.9 Hz, θk 0.001 rad under a 0.01 rad step: it sticks after ~350 half cycles, and the
    # last five (amplitudes under one step) are invisible, so the start count was 10 off
    # and every count near it was refused (exit 2, "no stop count is consistent") until the
    # search walked on from the refused fits (2026-11-28, a variant of the case above)
    path, truth = write_coulomb_pendulum(tmp_path, seed=32, f0=0.9, zeta=0.0006,
                                         theta_k=0.001, x0=1.0, start=0.05)
    rec = read_record(path, max_jitter=None)
    with pytest.warns(RecordWarning, match="resampled"):
        est = estimate_output_error(rec, mass=truth["J"], rng=1)
    for name in ("c_mean", "fk_mean"):
        # 4 standard errors: a single record's error bars at 95 % miss 1 run in 20
        assert abs(est.value(name) - truth[name]) < 4 * est.stderr(name), name
    assert est.value("fk_mean") == pytest.approx(truth["fk_mean"], rel=0.02)


def test_strict_turns_a_damping_bound_into_exit_2(tmp_path):
    p = OscillatorParams(J=1.0, K=16.0, c_mean=0.0, fk_mean=0.05)
    rec = measure(simulate_free_decay(p, x0=1.0, duration=30.0, fs=50.0).record,
                  noise_std=0.002, rng=3)
    est = estimate_output_error(rec, mass=1.0)
    if not est.warnings:
        pytest.skip("this seed gives no warning")  # pragma: no cover
    from driveid.io import write_record

    path = write_record(rec, tmp_path / "undamped.csv")
    result = _cli("identify", "logdec", path, "--mass", 1.0, "--strict")
    assert result.exit_code == 2, result.output


def _two_mode_decay(seed, amp=0.02, phase=0.0, line=False, sd=0.002):
    """The demo decay plus a second mode at 3 Hz (damped, ζ 0.02), or a 50 Hz line."""
    rec = simulate_free_decay(P, x0=1.0, duration=10 if line else 20,
                              fs=200 if line else 100).record
    t = rec.t
    if line:
        extra = amp * np.sin(2 * np.pi * 50.0 * t + phase)
    else:
        w2 = 2 * np.pi * 3.0
        extra = amp * np.exp(-0.02 * w2 * t) * np.cos(w2 * math.sqrt(1 - 0.02**2) * t + phase)
    noise = sd * np.random.default_rng(seed).normal(size=t.size)
    return rec.replace(x=rec.x + extra + noise)


def test_a_second_mode_is_fitted_named_and_validated():
    """Issue 24 item 2: a second mode (2 % of the release at 3 Hz beside the 0.64 Hz mode).

    Before, every such record was "not explained" (sandwich error bars, warned; over 20
    records c_mean covered 0.85, sd of z 1.25); now the ``+ second mode`` structure is
    chosen, the record is explained, and validate simulates it (a held-out record gets
    its own amplitude and phase, the release excites the mode differently each time)."""
    rec = _two_mode_decay(0)
    est = estimate_output_error(rec, mass=1.0)
    assert est.diagnostics["structure"] == "+ second mode"
    assert est.diagnostics["adequacy"]["adequate"] and not est.warnings
    f2 = 3.0 * math.sqrt(1 - 0.02**2)  # the damped frequency the model carries
    # 3 standard errors: one seeded record; 1 % / 10 % as the physics' tolerance
    assert abs(est.value("f2") - f2) < 3 * est.stderr("f2") and est.value("f2") == \
        pytest.approx(f2, rel=0.01)
    assert abs(est.value("zeta2") - 0.02) < 3 * est.stderr("zeta2")
    for name, true in (("c_mean", 0.3), ("fk_mean", 0.07), ("K", 16.0)):
        assert abs(est.value(name) - true) < 3 * est.stderr(name), name
    own = compare(rec, est, index=0)
    assert own.whiteness["white"] and own.residual_rms < 1.1 * 0.002
    held = compare(_two_mode_decay(1, amp=0.03, phase=1.0), est)
    assert held.held_out and held.residual_rms < 1.1 * 0.002


def test_a_line_that_does_not_decay_is_named_as_one():
    """A 50 Hz line on the position (electrical pickup) is fitted as a second oscillation
    that does not decay, and the structure's reason says it is a line, not a mode (the
    coverage benchmark's mains class: 70 % of 0.01 rad of noise in the line)."""
    est = estimate_output_error(_two_mode_decay(2, amp=0.0118, line=True, sd=0.0055),
                                mass=1.0)
    assert est.diagnostics["structure"] == "+ second mode"
    assert est.value("f2") == pytest.approx(50.0, rel=1e-3)
    reason = est.diagnostics["adequacy"]["structures"]["reason"]
    assert "hardly decays" in reason and "50 Hz" in reason
