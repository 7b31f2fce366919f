"""Envelope damping separation (Hilbert) against the log decrement on Table 5.1's systems."""

import warnings

import numpy as np
import pytest

from driveid.identify.free_decay.hilbert import estimate_envelope_damping
from driveid.identify.free_decay.logdec import estimate_log_decrement
from driveid.io.record import Record
from driveid.sim import OscillatorParams, simulate_free_decay

from .test_logdec import TABLE_5_1


@pytest.mark.parametrize("case", TABLE_5_1, ids=[f"case{i + 1}" for i in range(8)])
def test_envelope_method_within_2_percent(case):
    K, fk_mean, fk_delta, c_mean, c_delta = case
    p = OscillatorParams(J=1.0, K=K, c_mean=c_mean, c_delta=c_delta, fk_mean=fk_mean,
                         fk_delta=fk_delta)
    rec = simulate_free_decay(p, x0=10.0, duration=30.0).record
    with warnings.catch_warnings():
        # the chosen model may warn that fk is not significant in the viscous-only case
        warnings.simplefilter("ignore")
        env = estimate_envelope_damping(rec, mass=1.0)
    logdec = estimate_log_decrement(rec, mass=1.0)
    for name, truth in (("c_mean", c_mean), ("fk_mean", fk_mean)):
        scale = abs(truth) if truth else 1.0
        # issue 6: envelope within 2 % (measured worst 0.65 %, f̄k of case 7; c̄ of case 5
        # is 0.5 % off because c_delta makes the per-cycle decay a period-weighted mean of
        # c±); the log decrement on the same record within 1e-4
        assert abs(env.value(name) - truth) / scale < 0.02, (name, env.value(name))
        assert abs(logdec.value(name) - truth) / scale < 1e-4


@pytest.mark.parametrize("case", TABLE_5_1, ids=[f"case{i + 1}" for i in range(8)])
def test_envelope_method_with_noise_within_2_percent(case):
    """The same records with white measurement noise of 0.01 rad (0.1 % of x0)."""
    K, fk_mean, fk_delta, c_mean, c_delta = case
    p = OscillatorParams(J=1.0, K=K, c_mean=c_mean, c_delta=c_delta, fk_mean=fk_mean,
                         fk_delta=fk_delta)
    rec = simulate_free_decay(p, x0=10.0, duration=30.0).record
    noise = 0.01 * np.random.default_rng(1).standard_normal(rec.t.size)
    env = estimate_envelope_damping(Record(t=rec.t, x=rec.x + noise), mass=1.0)
    for name, truth in (("c_mean", c_mean), ("fk_mean", fk_mean)):
        scale = abs(truth) if truth else 1.0
        # issue 6: 2 %; measured worst 0.64 % over seeds 0-2 (f̄k, case 1)
        assert abs(env.value(name) - truth) / scale < 0.02, (name, env.value(name))
