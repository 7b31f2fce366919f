"""Tests of the backbone (amplitude-dependent stiffness) of the Hilbert and wavelet methods.

Truth: closed forms. A linear spring has a constant backbone; a cubic (Duffing) spring
``x'' + K x + k3 x³ = 0`` has the exact frequency ``pi wn sqrt(1 + eps A²) / (2 K(m))``,
``m = eps A² / (2 (1 + eps A²))``, ``eps = k3/K`` (A the peak displacement; first-order
harmonic balance gives ``wn² (1 + 3/4 eps A²)``); a dead-zone spring of half-width b has
``T = (2 pi / wn) (1 + 2 b / (pi (A - b)))`` (see :mod:`driveid.identify.free_decay.backbone`).
"""

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.signal import find_peaks
from scipy.special import ellipk

from driveid.errors import IdentificationError, ParameterError
from driveid.identify.free_decay.backbone import backbone_of, compute_backbone
from driveid.identify.free_decay.hilbert import estimate_hilbert
from driveid.identify.free_decay.wavelet import estimate_wavelet
from driveid.io.record import Record
from driveid.sim.drive import simulate_drive
from driveid.sim.drive_types import BacklashLink, BodyParams, DriveParams

F0 = 2.0  # natural frequency [Hz]
FS = 1000.0  # sampling rate [Hz]: 500 samples per period
WN = 2 * np.pi * F0
K = WN**2  # stiffness [N·m/rad] with J = 1 kg·m²
METHODS = [estimate_hilbert, estimate_wavelet]


def linear_decay(zeta, noise, seed, duration=20.0):
    """Closed-form linear free decay with white noise of std ``noise`` [rad]."""
    sigma, wd = zeta * WN, WN * math.sqrt(1 - zeta**2)
    t = np.arange(int(duration * FS)) / FS
    x = np.exp(-sigma * t) * (np.cos(wd * t) + sigma / wd * np.sin(wd * t))
    x = x + noise * np.random.default_rng(seed).standard_normal(t.size)
    return Record(t=t, x=x)


def peak_amplitude(t, x, tq):
    """Peak displacement |x| at the times ``tq``, interpolated between successive peaks."""
    idx, _ = find_peaks(np.abs(x))
    return np.interp(tq, t[idx], np.abs(x[idx]))


@pytest.fixture(scope="module")
def duffing():
    """x'' + 0.5 x' + K x + k3 x³ = 0 from x = 1 (DOP853, rtol 1e-10), eps A² = 0.27 at A = 1."""
    eps = 0.2 / 0.75
    t = np.arange(int(10 * FS)) / FS
    sol = solve_ivp(lambda _, y: [y[1], -0.5 * y[1] - K * y[0] - eps * K * y[0] ** 3],
                    (0, t[-1]), [1.0, 0.0], t_eval=t, method="DOP853", rtol=1e-10, atol=1e-12)
    return Record(t=t, x=sol.y[0]), eps


@pytest.fixture(scope="module")
def dead_zone():
    """A free body on a dead-zone spring (BacklashLink to a locked body), b = 0.1 rad."""
    b = 0.1
    params = DriveParams(bodies=(BodyParams(J=1.0, locked=True), BodyParams(J=1.0, c_mean=0.1)),
                         links=(BacklashLink(gap_plus=b, gap_minus=b, k=K),))
    res = simulate_drive(params, duration=30.0, fs=FS, x0=[0.0, 1.0], v0=[0.0, 0.0])
    return Record(t=res.t, x=res.x[1]), b


@pytest.mark.parametrize("method", METHODS)
def test_linear_backbone_is_constant(method):
    est = method(linear_decay(0.02, 0.0, 0), mass=1.0)
    fit = est.data_used["backbone_fit"]
    # noise free, the Hilbert/wavelet ripple leaves K2 "significant" but ~1e-4 relative:
    # min_change (5e-3) keeps it "constant"
    assert fit["verdict"] == "constant"
    assert abs(fit["change"]) < 1e-3
    assert abs(fit["K0"] / K - 1) < 1e-3  # K0 = J wn² to the method's 0.1 % accuracy
    bb = est.data_used["backbone"]
    np.testing.assert_allclose(bb["stiffness"], K, rtol=1e-3)
    np.testing.assert_allclose(bb["relative_stiffness"], 1.0, atol=1e-3)


@pytest.mark.parametrize("method", METHODS)
def test_linear_backbone_calibration_monte_carlo(method):
    """Noisy linear decays: K2/stderr and (K_bin - K)/stderr ~ t, no false verdicts."""
    z_fit, z_bins, verdicts = [], [], []
    for seed in range(16):
        est = method(linear_decay(0.02, 0.01, seed), mass=1.0)
        fit, bb = est.data_used["backbone_fit"], est.data_used["backbone"]
        z_fit.append(fit["K2"] / fit["K2_stderr"])
        z_bins.extend((bb["stiffness"] - K) / bb["stiffness_stderr"])
        verdicts.append(fit["verdict"])
    z_fit, z_bins = np.array(z_fit), np.array(z_bins)
    med_fit, med_bins = np.median(np.abs(z_fit)), np.median(np.abs(z_bins))
    print(f"{method.__name__}: median |z| fit {med_fit:.2f}, bins {med_bins:.2f} "
          f"({z_bins.size} bins)")
    # median |z| is 0.67 for N(0,1) and 0.74 for Student t with 4 dof (few blocks per
    # window); 16 seeds put its 99 % range near [0.35, 1.1]; measured 0.48-0.53 (the
    # stderr is ~1.3x conservative), accepted down to 0.3
    assert 0.3 < med_fit < 1.1
    assert 0.3 < med_bins < 1.1
    assert abs(np.mean(z_fit)) < 3 * 1.4 / math.sqrt(16)  # unbiased: 3 sigma, t4 std 1.4
    assert verdicts.count("constant") >= 15  # alpha = 1 %: one false verdict at most


@pytest.mark.parametrize("method", METHODS)
def test_duffing_backbone_against_closed_forms(method, duffing):
    rec, eps = duffing
    est = method(rec, mass=1.0)
    bb, fit = est.data_used["backbone"], est.data_used["backbone_fit"]
    assert fit["verdict"] == "hardening" and fit["p_value"] < 1e-6
    a_peak = peak_amplitude(rec.t, rec.x, bb["t"])
    m = eps * a_peak**2 / (2 * (1 + eps * a_peak**2))
    exact = np.pi * WN * np.sqrt(1 + eps * a_peak**2) / (2 * ellipk(m))
    harmonic = WN * np.sqrt(1 + 0.75 * eps * bb["amplitude"] ** 2)
    err_exact = np.max(np.abs(bb["omega0"] / exact - 1))
    err_hb = np.max(np.abs(bb["omega0"] / harmonic - 1))
    hb_vs_exact = np.max(np.abs(WN * np.sqrt(1 + 0.75 * eps * a_peak**2) / exact - 1))
    print(f"{method.__name__}: vs exact(A_peak) {err_exact:.1e}, vs harmonic balance "
          f"(Hilbert A) {err_hb:.1e}, harmonic balance vs exact {hb_vs_exact:.1e}")
    # measured 1.7e-3/1.9e-3: the block means average a frequency that changes along the
    # block, and the peak amplitude is interpolated between peaks; 0.5 % is the acceptance
    assert err_exact < 5e-3
    assert err_hb < 5e-3  # measured 1.1e-3 / 1.4e-3
    # K2/K0 = 3/4 eps (= 0.2) to first order; measured 0.2025 and 0.2039 (the Hilbert and
    # wavelet amplitudes are those of the fundamental, A_1 = A_peak (1 - eps A²/32 ...))
    assert abs(fit["K2"] / fit["K0"] / (0.75 * eps) - 1) < 0.03
    assert abs(fit["K0"] / K - 1) < 2e-3


@pytest.mark.parametrize("method", METHODS)
def test_dead_zone_backbone_against_closed_form(method, dead_zone):
    rec, b = dead_zone
    est = method(rec, mass=1.0)
    bb, fit = est.data_used["backbone"], est.data_used["backbone_fit"]
    a_peak = peak_amplitude(rec.t, rec.x, bb["t"])
    closed = WN / (1 + 2 * b / (np.pi * (a_peak - b)))
    err = np.max(np.abs(bb["omega0"] / closed - 1))
    print(f"{method.__name__}: dead zone max rel err {err:.1e} over A/b = "
          f"{a_peak.min() / b:.1f}-{a_peak.max() / b:.1f}")
    assert err < 2e-3  # measured 2.6e-4 (damping zeta = 0.004 is removed by omega0)
    # soft at small amplitude: K_eff rises with A, so the verdict is "hardening"
    assert fit["verdict"] == "hardening" and fit["change"] > 0.2
    assert np.all(np.diff(bb["stiffness"]) > 0)
    assert bb["relative_stiffness"][0] < 0.7


def test_compute_backbone_quadratic_law_exact():
    t = np.arange(20000) / 1000.0
    amp = np.exp(-0.1 * t)
    w0 = 10.0 * np.sqrt(1 + 0.2 * amp**2)
    bb = compute_backbone(t, amp, w0, omega=10.0, mass=2.0, units=("m", "N"))
    # omega0² is exactly linear in A² only per sample; block means of A² and A differ by
    # the within-block variance of A, ~(0.1 * 1.3 s)²/12 relative
    assert bb.K0.value == pytest.approx(200.0, rel=1e-3)
    assert bb.K2.value / bb.K0.value == pytest.approx(0.2, rel=5e-3)
    assert bb.K0.unit == "N/m" and bb.K2.unit == "N/m³"
    assert np.all(np.diff(bb.amplitude) > 0)
    assert bb.verdict == "hardening"
    soft = compute_backbone(t, amp, 10.0 * np.sqrt(1 - 0.2 * amp**2), omega=10.0)
    assert soft.verdict == "softening" and soft.mass_normalised
    assert soft.K0.unit == "rad²/s²"


def test_backbone_of_estimate_matches_data_used(duffing):
    rec, _ = duffing
    est = estimate_wavelet(rec, mass=1.0)
    bb = backbone_of(est, mass=1.0)
    assert bb.verdict == est.data_used["backbone_fit"]["verdict"]
    np.testing.assert_allclose(bb.omega0, est.data_used["backbone"]["omega0"])


def test_backbone_summary_in_json():
    est = estimate_hilbert(linear_decay(0.02, 0.0, 0), mass=1.0)
    d = est.to_dict()
    assert d["data_used"]["backbone_fit"]["verdict"] == "constant"
    assert d["diagnostics"]["backbone_verdict"] == "constant"
    assert "backbone" in est.to_dict(series=True)["data_used"]


def test_short_record_backbone_undetermined():
    # 4.5 periods: after trimming, fewer than 4 two-period blocks remain
    est = estimate_hilbert(linear_decay(0.001, 0.0, 0, duration=2.25))
    assert est.data_used["backbone"] is None
    assert est.data_used["backbone_fit"]["verdict"] == "undetermined"


def test_errors():
    t = np.arange(100) / 100.0
    with pytest.raises(ParameterError, match="one length"):
        compute_backbone(t, t[:-1], t, omega=1.0)
    with pytest.raises(ParameterError, match="alpha"):
        compute_backbone(t, t, t, omega=1.0, alpha=2.0)
    with pytest.raises(ParameterError, match="omega"):
        compute_backbone(t, t, t, omega=0.0)
    with pytest.raises(IdentificationError, match="blocks"):
        compute_backbone(t, t + 1, t, omega=2 * np.pi)
    with pytest.raises(IdentificationError, match="constant amplitude"):
        compute_backbone(t, np.ones(100), np.ones(100), omega=2 * np.pi * 10)
    with pytest.raises(ParameterError, match="mode"):
        backbone_of(estimate_wavelet(linear_decay(0.02, 0.0, 0)), mode=3)
