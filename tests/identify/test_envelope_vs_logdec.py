"""Envelope damping separation (Hilbert) against the log decrement on Table 5.1's systems."""

import warnings

import pytest

from driveid.identify.hilbert import estimate_envelope_damping
from driveid.identify.logdec import estimate_log_decrement
from driveid.sim import OscillatorParams, simulate_free_decay

from .test_logdec import TABLE_5_1


@pytest.mark.parametrize(
    "case",
    [pytest.param(TABLE_5_1[0], id="case1", marks=pytest.mark.xfail(
        strict=True, reason="c+ : c- = 7 : 1 and Δfk > f̄k: the symmetric envelope model "
        "misses f̄k by 2.7 % (known limit, see README)"))]
    + [pytest.param(c, id=f"case{i + 2}") for i, c in enumerate(TABLE_5_1[1:])],
)
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
        # issue 6: envelope within 2 %; the log decrement on the same record within 1e-4
        assert abs(env.value(name) - truth) / scale < 0.02, (name, env.value(name))
        assert abs(logdec.value(name) - truth) / scale < 1e-4
