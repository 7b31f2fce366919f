"""Tests of the Morlet-wavelet identification (de Marchi 1998, §2.2.10-2.2.11)."""

import math

import numpy as np
import pytest

from driveid.errors import IdentificationError, ParameterError, RecordError
from driveid.identify.free_decay.wavelet import estimate_wavelet, morlet_transform, scalogram
from driveid.io.record import Record

FS = 1000.0  # sampling rate [Hz]: >= 80 samples per period of every mode below


def decay(modes, *, duration, noise=0.0, seed=0):
    """Closed-form sum of damped modes (f [Hz], zeta, amplitude), released from rest."""
    t = np.arange(int(duration * FS)) / FS
    x = np.zeros_like(t)
    for f, zeta, amp in modes:
        w0 = 2 * np.pi * f
        sigma, wd = zeta * w0, w0 * math.sqrt(1 - zeta**2)
        x += amp * np.exp(-sigma * t) * (np.cos(wd * t) + sigma / wd * np.sin(wd * t))
    x += noise * np.abs(x[0]) * np.random.default_rng(seed).standard_normal(t.size)
    return Record(t=t, x=x)


def test_transform_normalisation_matches_2_244():
    # x = A cos(w t): W = sqrt(a) A exp(j w t)/2 at the tuned dilation (factor 1/2: erratum)
    t = np.arange(4000) / FS
    w, a = 2 * np.pi * 10.0, 5.0 / (2 * np.pi * 10.0)
    W = morlet_transform(0.7 * np.cos(w * t), FS, a, omega_c=5.0)
    mid = slice(1000, 3000)
    expected = math.sqrt(a) * 0.7 / 2 * np.exp(1j * w * t[mid])
    assert np.max(np.abs(W[mid] - expected)) < 1e-9  # FFT exact for interior samples
    # the Gaussian gain exp(-(a w - omega_c)^2/2) off tune (2.247)
    W2 = morlet_transform(0.7 * np.cos(w * t), FS, 1.2 * a, omega_c=5.0)
    assert abs(W2[2000]) == pytest.approx(abs(expected[1000]) * math.sqrt(1.2)
                                          * math.exp(-0.5 * 1.0**2), rel=1e-9)


def test_scalogram_peaks_at_mode():
    t = np.arange(4000) / FS
    omegas = 2 * np.pi * np.array([5.0, 10.0, 20.0])
    s = scalogram(np.cos(omegas[1] * t), FS, omegas, omega_c=5.0)
    assert s[1, 2000] == pytest.approx(1.0, rel=1e-9)
    # off-tune gain exp(-(omega_c w_signal/w_k - omega_c)^2 / 2) of the Gaussian filter
    for k in (0, 2):
        gain = math.exp(-0.5 * (5.0 * omegas[1] / omegas[k] - 5.0) ** 2)
        assert s[k, 2000] == pytest.approx(gain, rel=1e-6, abs=1e-12)


@pytest.mark.parametrize("zeta", [0.01, 0.1])
def test_linear_decay_with_one_percent_noise(zeta):
    f0 = 2.0
    duration = min(30.0, 8.0 / (zeta * 2 * np.pi * f0))
    rec = decay([(f0, zeta, 1.0)], duration=duration, noise=0.01, seed=3)
    est = estimate_wavelet(rec)
    w0 = 2 * np.pi * f0
    err_w, err_z = est.value("omega0") / w0 - 1, est.value("zeta") / zeta - 1
    print(f"wavelet zeta={zeta}: omega0 rel err {err_w:.2e}, zeta rel err {err_z:.2e}")
    assert abs(err_w) < 1e-3  # acceptance: 0.1 %
    assert abs(err_z) < 1e-2  # acceptance: 1 %; seed-to-seed std ~0.2 % at zeta=0.1
    t0, t1 = est.data_used["window"]
    assert t0 >= 3 * est.data_used["modes"][0]["dilation"] - 1e-9  # outside the cone
    # amplitude (2.249 with the factor 2 and the decay gain) is the true envelope
    m = est.data_used["modes"][0]
    truth = np.exp(-zeta * w0 * m["t"]) * math.sqrt(1 + zeta**2 / (1 - zeta**2))
    assert np.median(np.abs(m["amplitude"] / truth - 1)) < 1e-2  # noise-limited


def test_two_modes():
    rec = decay([(5.0, 0.02, 1.0), (12.0, 0.05, 0.7)], duration=8.0)
    est = estimate_wavelet(rec, modes=2)
    for k, (f, zeta) in enumerate([(5.0, 0.02), (12.0, 0.05)], start=1):
        err_w = est.value(f"omega0_{k}") / (2 * np.pi * f) - 1
        err_z = est.value(f"zeta_{k}") / zeta - 1
        print(f"wavelet mode {k}: omega0 rel err {err_w:.2e}, zeta rel err {err_z:.2e}")
        assert abs(err_w) < 5e-3  # acceptance: 0.5 %
        assert abs(err_z) < 5e-2  # acceptance: 5 %
    assert len(est.data_used["modes"]) == 2
    ridge = est.data_used["modes"][0]["ridge"]
    assert np.all(np.abs(ridge / (2 * np.pi * 5.0) - 1) < 0.1)  # scalogram grid spacing
    assert est.to_json()


def test_too_short_record():
    rec = decay([(2.0, 0.01, 1.0)], duration=1.5)
    with pytest.raises(RecordError, match="at least 4 periods"):
        estimate_wavelet(rec)


def test_too_noisy_record():
    rec = decay([(2.0, 0.01, 1.0)], duration=10.0, noise=0.3)
    with pytest.raises(IdentificationError, match="too noisy"):
        estimate_wavelet(rec)


def test_non_oscillating_record():
    t = np.arange(3000) / FS
    with pytest.raises(IdentificationError, match="does not oscillate"):
        estimate_wavelet(Record(t=t, x=np.exp(-2 * t)))


def test_more_modes_than_present():
    rec = decay([(5.0, 0.02, 1.0)], duration=4.0)
    with pytest.raises(IdentificationError, match="fewer than modes=3"):
        estimate_wavelet(rec, modes=3)


def test_bad_options():
    rec = decay([(5.0, 0.02, 1.0)], duration=4.0)
    with pytest.raises(ParameterError, match="modes"):
        estimate_wavelet(rec, modes=0)
    with pytest.raises(ParameterError, match="omega_c"):
        estimate_wavelet(rec, omega_c=1.0)
    with pytest.raises(ParameterError, match="coi_factor"):
        estimate_wavelet(rec, coi_factor=-1.0)


def test_cli_wavelet(tmp_path):
    import json

    from click.testing import CliRunner

    from driveid.commands.instantaneous import wavelet_command
    from driveid.io import write_record

    rec = decay([(5.0, 0.02, 1.0), (12.0, 0.05, 0.7)], duration=8.0)
    path = write_record(rec, tmp_path / "two.npz")
    fig = tmp_path / "w.png"
    runner = CliRunner()
    res = runner.invoke(wavelet_command, [str(path), "--modes", "2", "--json", "--figure",
                                          str(fig)])
    assert res.exit_code == 0, res.output
    out = json.loads(res.output)
    assert [out["parameters"][f"omega0_{k}"]["value"] for k in (1, 2)] == pytest.approx(
        [2 * np.pi * 5.0, 2 * np.pi * 12.0], rel=1e-3)
    assert fig.exists()
    res = runner.invoke(wavelet_command, [str(path), "--modes", "5"])
    assert res.exit_code == 2 and res.output.startswith("error:")


def test_modes_too_close_to_separate():
    rec = decay([(5.0, 0.005, 1.0), (5.3, 0.005, 1.0)], duration=8.0)
    with pytest.raises(IdentificationError, match="need omega_c > 40"):
        estimate_wavelet(rec, modes=2)


def test_decimated_scalogram_equals_every_sample():
    # time decimation by spectral folding is exact: W at every step-th sample, not a
    # filtered resampling; compared with the full-resolution transform to round-off
    t = np.arange(5000) / FS
    x = np.exp(-0.3 * t) * np.cos(2 * np.pi * 3.0 * t) + 0.2 * np.cos(2 * np.pi * 11.0 * t)
    omegas = np.geomspace(2 * np.pi, 2 * np.pi * 20, 9)
    full = scalogram(x, FS, omegas, omega_c=5.0)
    for step in (1, 7, 64):
        dec = scalogram(x, FS, omegas, omega_c=5.0, step=step)
        assert dec.shape == (9, -(-x.size // step))
        assert np.max(np.abs(dec - full[:, ::step])) < 1e-12 * np.max(full)
    with pytest.raises(ParameterError, match="step"):
        morlet_transform(x, FS, 1.0, omega_c=5.0, step=0)


def test_oversampled_record_is_decimated_without_loss():
    """At 20 000 samples per period of the dominant mode the record is boxcar-decimated."""
    f, zeta, fs = 2.0, 0.02, 40_000.0
    w0 = 2 * np.pi * f
    sigma, wd = zeta * w0, w0 * math.sqrt(1 - zeta**2)
    t = np.arange(int(10.0 * fs)) / fs
    x = np.exp(-sigma * t) * (np.cos(wd * t) + sigma / wd * np.sin(wd * t))
    est = estimate_wavelet(Record(t=t, x=x), mass=1.0)
    assert est.diagnostics["decimation"] == 40
    assert abs(est.value("omega0") / w0 - 1) < 1e-3  # acceptance as at 1 kHz: 0.1 %
    assert abs(est.value("zeta") / zeta - 1) < 1e-2  # and 1 %
    assert est.data_used["backbone_fit"]["verdict"] == "constant"
    # stiffness per unit mass: J omega0² with J = 1 (0.2 %: the instantaneous ripple)
    np.testing.assert_allclose(est.data_used["backbone"]["stiffness"], w0**2, rtol=2e-3)
