"""Friction from the amplitude dependence of Hilbert and wavelet envelopes (Table 5.1)."""

import warnings

import numpy as np
import pytest

from driveid.errors import IdentificationError, ParameterError
from driveid.identify.free_decay.envelope_friction import friction_from_envelope
from driveid.identify.free_decay.hilbert import estimate_hilbert
from driveid.identify.free_decay.wavelet import estimate_wavelet
from driveid.sim import OscillatorParams, simulate_free_decay

from .test_logdec import TABLE_5_1

# Measured with the Hilbert envelope and the default amplitude fit (relative errors; case 5
# has fk = 0, so its error is absolute [N·m]):
#   case     1      2      3      4      5       6      7      8
#   c̄    +0.07  +0.21  +0.03  +0.65  -1.69   +0.28  -1.40  +0.03  %
#   f̄k   +2.9   +0.65  -0.43  -1.3   +0.039  -0.90  +1.2   -0.08  %
# Cases 1 and 5 carry a viscous asymmetry of 75 % of c̄ (c_delta = 0.3, c_mean = 0.4):
# the envelope then decays at a period-weighted mix of c± and the Hilbert amplitude
# ripples at the cycle, which the single-rate law reads as part Coulomb (documented reason;
# tolerance 4 % and 0.05 N·m, i.e. 12 % of c̄·A-equivalent, for those two).
TOLERANCE_FK = {1: 0.04, 5: 0.05}


@pytest.mark.parametrize("case", range(1, 9), ids=[f"case{i}" for i in range(1, 9)])
def test_hilbert_envelope_friction_on_table_5_1(case):
    K, fk, fk_delta, c, c_delta = TABLE_5_1[case - 1]
    p = OscillatorParams(J=1.0, K=K, c_mean=c, c_delta=c_delta, fk_mean=fk,
                         fk_delta=fk_delta)
    rec = simulate_free_decay(p, x0=10.0, duration=30.0).record
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the Hilbert method's own plausibility notes
        hil = estimate_hilbert(rec)
    est = friction_from_envelope(hil, mass=1.0)
    # issue 17: c̄ within 2 % on all eight
    assert est.value("c_mean") == pytest.approx(c, rel=0.02)
    if fk == 0:
        assert abs(est.value("fk_mean")) < TOLERANCE_FK.get(case, 0.02)
    else:
        assert est.value("fk_mean") == pytest.approx(fk, rel=TOLERANCE_FK.get(case, 0.02))
    # backbone: K = J ω̄0² from the mean instantaneous ω0; within 2 % (measured worst
    # -1.4 %, case 7, whose 6.25 N·m Coulomb friction stops it within a few cycles)
    assert est.value("K") == pytest.approx(K, rel=0.02)


@pytest.mark.parametrize("case", [2, 3, 8])
def test_wavelet_envelope_friction(case):
    # The Morlet envelope is a time average over ~omega_c cycles: near the stop of a steep
    # Coulomb decay it rounds the linear ramp, so only the cases with a long decay are
    # within 2 % (measured: 2: +0.3/+0.6 %, 3: -0.04/+1.3 %, 8: -0.1/+0.4 % for c̄/f̄k);
    # cases 4, 6 are 20-47 % off in c̄ and case 7 stops before the wavelet finds a mode.
    K, fk, fk_delta, c, c_delta = TABLE_5_1[case - 1]
    p = OscillatorParams(J=1.0, K=K, c_mean=c, c_delta=c_delta, fk_mean=fk,
                         fk_delta=fk_delta)
    rec = simulate_free_decay(p, x0=10.0, duration=30.0).record
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        wav = estimate_wavelet(rec)
    est = friction_from_envelope(wav, mass=1.0)
    assert est.value("c_mean") == pytest.approx(c, rel=0.02)
    assert est.value("fk_mean") == pytest.approx(fk, rel=0.02)


def test_arrays_and_damping_form_agree_on_exact_law():
    # exact envelope of dA/dt = -αA - β: both forms must return the law's parameters
    J, c, fk, w = 2.0, 0.3, 0.05, 4.0
    alpha, beta = c / (2 * J), 2 * fk / (np.pi * J * w)
    t = np.linspace(0, 10, 500)
    A = (5 + beta / alpha) * np.exp(-alpha * t) - beta / alpha
    zeta = (alpha + beta / A) / w
    for method in ("amplitude", "damping"):
        est = friction_from_envelope((t, A, zeta, np.full(t.size, w)), mass=J, method=method)
        assert est.value("c_mean") == pytest.approx(c, rel=1e-6)
        assert est.value("fk_mean") == pytest.approx(fk, rel=1e-6)
    per_unit = friction_from_envelope((t, A, zeta, np.full(t.size, w)))
    assert per_unit["c_mean"].unit == "1/s" and "K" not in per_unit


def test_errors():
    t = np.linspace(0, 1, 50)
    with pytest.raises(ParameterError, match="4 arrays"):
        friction_from_envelope((t, t))
    with pytest.raises(IdentificationError, match="10 %"):
        friction_from_envelope((t, np.ones(50) - 0.001 * t, np.full(50, 0.1), np.ones(50)))
    with pytest.raises(ParameterError, match="method"):
        friction_from_envelope((t, 1 - 0.5 * t, np.full(50, 0.1), np.ones(50)), method="x")
