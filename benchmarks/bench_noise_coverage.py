"""Coverage and efficiency of the free-decay output-error fit under coloured noise (issue 24).

The demo system (J = 1, K = 16, c = 0.3 ± 0.1, f_k = 0.07 ± 0.03; released at rest from 1 rad,
10 s at 200 Hz) with noise of standard deviation 0.01 rad of each class:

* ``white``; ``ar0.5``, ``ar0.9``, ``ar0.97`` (AR(1) with that pole);
* ``lowpass``: white noise through a 4th-order Butterworth low-pass at 5x the mode (3.2 Hz);
* ``pink``: 1/f-like, the sum of AR(1) processes with poles 0.5, 0.9, 0.99, 0.999;
* ``mains``: a 50 Hz line of random phase (70 % of the variance) plus white noise

(defined once in ``_noise_classes.py``, shared with ``bench_noise_coverage_fits.py``),
each without and with an encoder step of 0.01 rad (``+q``; bootstrap error bars).
Printed per parameter: coverage of the 95 % intervals, efficiency = coloured-noise Cramér–Rao
variance / observed variance (``free_decay_crlb(noise_ar=...)`` with a long AR fit of the
true noise spectrum), bias / sd and the mean reported / observed sd.

    python benchmarks/bench_noise_coverage.py --repeats 200            # the full table
    python benchmarks/bench_noise_coverage.py --repeats 10 --classes white,ar0.9
"""

from __future__ import annotations

import argparse
import math
import time
import warnings

import numpy as np
from _noise_classes import CLASSES, noise_ar
from _noise_classes import noise as noise_of_class

from driveid.errors import DriveIdError
from driveid.identify.crlb import free_decay_crlb
from driveid.identify.free_decay.output_error import estimate_output_error
from driveid.sim import OscillatorParams, simulate_free_decay

P = OscillatorParams(J=1.0, K=16.0, c_mean=0.3, c_delta=0.1, fk_mean=0.07, fk_delta=0.03)
TRUTH = {"c_mean": 0.3, "c_delta": 0.1, "fk_mean": 0.07, "fk_delta": 0.03, "K": 16.0}
FS, DURATION, X0, SIGMA, QUANTUM = 200.0, 10.0, 1.0, 0.01, 0.01
LOWPASS_HZ = 5 * 4.0 / (2 * math.pi)  # 5x the mode omega0 = 4 rad/s: 3.2 Hz


def noise(kind: str, n: int, rng: np.random.Generator) -> np.ndarray:
    """Stationary noise of the class, scaled to SIGMA [rad]; low-pass at 5x the mode."""
    return noise_of_class(kind, n, rng, fs=FS, sigma=SIGMA, lowpass_hz=LOWPASS_HZ)


def bound(kind: str) -> dict[str, float]:
    """Coloured-noise Cramér–Rao sd: the true spectrum as a long AR fit (orders <= 40)."""
    ar = noise_ar(kind, fs=FS, lowpass_hz=LOWPASS_HZ)
    return free_decay_crlb(P, fs=FS, duration=DURATION, x0=X0, noise_std=SIGMA,
                           noise_ar=ar or None)


def run(kind: str, quantised: bool, repeats: int) -> list[str]:
    """Identify ``repeats`` realisations; return the printed rows."""
    rec = simulate_free_decay(P, x0=X0, duration=DURATION, fs=FS).record
    sd0 = bound(kind)
    rng = np.random.default_rng(2024)
    est_values = {n: [] for n in TRUTH}
    hits = dict.fromkeys(TRUTH, 0)
    reported = {n: [] for n in TRUTH}
    failures = 0
    for _ in range(repeats):
        x = rec.x + noise(kind, rec.n, rng)
        if quantised:
            phase = rng.uniform(0, QUANTUM)
            x = QUANTUM * np.round((x - phase) / QUANTUM) + phase
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                est = estimate_output_error(rec.replace(x=x), mass=1.0, rng=rng)
        except DriveIdError:
            failures += 1
            continue
        for n, v in TRUTH.items():
            est_values[n].append(est.value(n))
            reported[n].append(est.stderr(n))
            hits[n] += abs(est.value(n) - v) <= 1.96 * est.stderr(n)
    rows = []
    label = kind + ("+q" if quantised else "")
    for n, v in TRUTH.items():
        vals = np.array(est_values[n])
        if vals.size < 3:
            continue
        sd = float(np.std(vals, ddof=1))
        rows.append(f"{label:10s} {n:9s} {hits[n] / vals.size:9.2f} "
                    f"{sd0[n] ** 2 / sd ** 2:10.2f} {(vals.mean() - v) / sd:8.2f} "
                    f"{np.mean(reported[n]) / sd:9.2f} {vals.size:4d} {failures:3d}")
    return rows


def main() -> None:
    """Print the coverage table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=200)
    parser.add_argument("--classes", default=",".join(CLASSES))
    parser.add_argument("--quantised", choices=["no", "yes", "both"], default="both")
    args = parser.parse_args()
    print(f"{'noise':10s} {'param':9s} {'coverage':>9s} {'efficiency':>10s} {'bias/sd':>8s} "
          f"{'se/sd':>9s} {'runs':>4s} {'err':>3s}")
    for kind in args.classes.split(","):
        for quantised in {"no": [False], "yes": [True], "both": [False, True]}[args.quantised]:
            start = time.perf_counter()
            for row in run(kind, quantised, args.repeats):
                print(row)
            print(f"# {kind}{'+q' if quantised else ''}: "
                  f"{(time.perf_counter() - start) / args.repeats:.2f} s a record", flush=True)


if __name__ == "__main__":
    main()
