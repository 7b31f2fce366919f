"""The noise classes of issue 24's coverage benchmarks, in one place.

Every class is stationary and scaled to a given standard deviation ``sigma``:

* ``white``; ``ar0.5``, ``ar0.9``, ``ar0.97`` (AR(1) with that pole, per sample);
* ``lowpass``: white noise through a 4th-order Butterworth low-pass at ``lowpass_hz`` (each
  benchmark sets it at 2-10x the bandwidth that matters for its record and says which);
* ``pink``: 1/f-like, the sum of AR(1) processes with poles 0.5, 0.9, 0.99, 0.999 (per
  sample: three decades below the sampling rate);
* ``mains``: a ``mains_hz`` line of random phase (70 % of the variance) plus white noise.

Used by ``bench_noise_coverage.py`` (free decay) and ``bench_noise_coverage_fits.py`` (IDIM,
forced response, friction map); the draws from ``rng`` are those the free-decay benchmark
made before this module existed, so its seeded figures are unchanged.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.signal import butter, lfilter

CLASSES = ("white", "ar0.5", "ar0.9", "ar0.97", "lowpass", "pink", "mains")
_BURN = 20_000  # samples dropped so that the slowest pole (0.999) has forgotten its start
_VAR: dict[tuple, float] = {}


def _raw(kind: str, n: int, rng: np.random.Generator, fs: float, lowpass_hz: float,
         mains_hz: float) -> np.ndarray:
    w = rng.standard_normal(n + _BURN)
    if kind == "white":
        e = w
    elif kind.startswith("ar"):
        e = lfilter([1.0], [1.0, -float(kind[2:])], w)
    elif kind == "lowpass":
        b, a = butter(4, lowpass_hz / (fs / 2))
        e = lfilter(b, a, w)
    elif kind == "pink":
        e = sum(lfilter([math.sqrt(1 - p * p)], [1.0, -p], rng.standard_normal(n + _BURN))
                for p in (0.5, 0.9, 0.99, 0.999))
    elif kind == "mains":
        t = np.arange(n + _BURN) / fs
        e = math.sqrt(2 * 0.7) * np.sin(2 * math.pi * mains_hz * t
                                        + rng.uniform(0, 2 * math.pi)) + math.sqrt(0.3) * w
    else:
        raise ValueError(f"unknown noise class {kind!r}; use one of {', '.join(CLASSES)}")
    return e[_BURN:]


def _variance(kind: str, fs: float, lowpass_hz: float, mains_hz: float) -> float:
    """Stationary variance of the unscaled class (by simulation, once per setting)."""
    key = (kind, fs, lowpass_hz, mains_hz)
    if key not in _VAR:
        e = _raw(kind, 400_000, np.random.default_rng(99), fs, lowpass_hz, mains_hz)
        _VAR[key] = float(np.var(e))
    return _VAR[key]


def noise(kind: str, n: int, rng: np.random.Generator, *, fs: float, sigma: float,
          lowpass_hz: float, mains_hz: float = 50.0) -> np.ndarray:
    """``n`` samples of class ``kind`` at ``fs`` [Hz], standard deviation ``sigma``."""
    e = _raw(kind, n, rng, fs, lowpass_hz, mains_hz)
    return sigma * e / math.sqrt(_variance(kind, fs, lowpass_hz, mains_hz))


def noise_ar(kind: str, *, fs: float, lowpass_hz: float, mains_hz: float = 50.0,
             max_order: int = 40) -> list[float]:
    """AR coefficients of a long fit of the class's spectrum (``[]`` for white noise).

    A Cramér–Rao bound for coloured noise needs the spectrum; an AR fit of order up to
    ``max_order`` to 200 000 samples approximates any smooth one (only roughly where the
    spectrum has zeros, as the low-pass has at Nyquist).
    """
    from driveid.identify.core._noise import fit_noise_model

    e = noise(kind, 200_000, np.random.default_rng(7), fs=fs, sigma=1.0,
              lowpass_hz=lowpass_hz, mains_hz=mains_hz)
    return list(fit_noise_model(e, max_order=max_order).ar)
