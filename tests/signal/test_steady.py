"""Tests of driveid.signal.steady (thesis Steady.m counterpart)."""

import numpy as np
import pytest

from driveid.errors import ParameterError, RecordError
from driveid.signal.steady import find_steady_segments, n_effective, noise_level, segment_mean


def _plateaus(noise: float, seed: int = 0) -> tuple[np.ndarray, list[tuple[int, int]]]:
    levels = [0.5, 1.0, -0.7, -2.0]
    parts, truth, i = [], [], 0
    for lo, hi in zip([0.0] + levels[:-1], levels, strict=True):
        parts.append(np.linspace(lo, hi, 200))  # ramp (transient)
        parts.append(np.full(600, hi))
        truth.append((i + 199, i + 800))  # the ramp ends on the level
        i += 800
    y = np.concatenate(parts)
    return y + noise * np.random.default_rng(seed).standard_normal(y.size), truth


def test_finds_each_plateau_inside_its_true_span():
    y, truth = _plateaus(0.01)
    segs = find_steady_segments(y)
    assert len(segs) == len(truth)
    for (a, b), (ta, tb) in zip(segs, truth, strict=True):
        # detected run lies inside the plateau and covers most of it (window 25 lost per end)
        assert ta <= a and b <= tb and (b - a) > 0.85 * (tb - ta)


def test_noise_level_and_segment_mean_stderr():
    rng = np.random.default_rng(3)
    y = rng.normal(5.0, 0.2, 40000)
    # 40000 samples: the MAD estimator has ~1 % relative standard error; 4 % bound
    assert noise_level(y) == pytest.approx(0.2, rel=0.04)
    m, se = segment_mean(y)
    # white noise: stderr = 0.2/sqrt(40000) = 0.001 within 5 %
    assert se == pytest.approx(0.001, rel=0.05)
    assert abs(m - 5.0) < 4 * se


def test_n_effective_ar1():
    rng = np.random.default_rng(4)
    rho, n = 0.8, 200000
    e = rng.standard_normal(n)
    y = np.empty(n)
    y[0] = e[0]
    for i in range(1, n):
        y[i] = rho * y[i - 1] + e[i]
    # AR(1): n_eff = n (1 - rho)/(1 + rho) = n/9; lag-1 estimate within 3 %
    assert n_effective(y) == pytest.approx(n / 9, rel=0.03)


def test_errors_and_short_input():
    with pytest.raises(ParameterError, match="window must be"):
        find_steady_segments(np.ones(100), window=2)
    with pytest.raises(ParameterError, match="min_samples must be"):
        find_steady_segments(np.ones(100), window=25, min_samples=10)
    with pytest.raises(ParameterError, match="rel_tol and noise_factor"):
        find_steady_segments(np.ones(100), rel_tol=-1.0)
    with pytest.raises(RecordError, match="at least 2 samples"):
        segment_mean(np.ones(1))
    with pytest.raises(RecordError, match="at least 3 samples"):
        noise_level(np.ones(2))
    assert find_steady_segments(np.ones(10)) == []
