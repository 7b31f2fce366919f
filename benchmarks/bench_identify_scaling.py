"""Identification time and peak memory against record length (issue 18).

Workload: a free decay x = exp(-σt) cos(ω_d t) + 1e-3 white noise, f0 = 2 Hz, ζ = 0.02.

* series A, "denser": 30 s of record sampled ever faster (1e3 ... 1e7 samples), so a
  period holds ever more samples — the case that made Hilbert and wavelet O(N^1.6-1.9)
  (a one-period Savitzky-Golay window, a full-resolution scalogram);
* series B, "longer" (log decrement): 1 kHz, ever longer records (more peaks; a slow
  exponential decay keeps 2e3-1e5 peaks above the noise).

For each length it prints the time [s] (one run, wall clock) and the peak of the Python heap
during the call (tracemalloc, a second run) as a multiple of the record's size (t and x,
16 bytes a sample), with the accuracy reached (relative error of ζ against the closed
form), then the exponent of a least-squares fit of log(time) on log(N) from 1e4 to 1e6
(acceptance: <= 1.15), and the log decrement at 1e6 samples with all BLAS threads against
one. Times depend on the load of this shared machine; the exponents and ratios are the
result. Run: python benchmarks/bench_identify_scaling.py [--max 1e7]
"""

import argparse
import inspect
import math
import time
import tracemalloc

import numpy as np

from driveid.identify.free_decay.hilbert import estimate_hilbert
from driveid.identify.free_decay.logdec import estimate_log_decrement
from driveid.identify.free_decay.wavelet import estimate_wavelet
from driveid.io.record import Record

F0, ZETA, NOISE = 2.0, 0.02, 1e-3


def decay(n: int, duration: float, zeta: float = ZETA) -> Record:
    fs = n / duration
    t = np.arange(n) / fs
    w0 = 2 * math.pi * F0
    sigma, wd = zeta * w0, w0 * math.sqrt(1 - zeta**2)
    x = np.exp(-sigma * t) * np.cos(wd * t)
    x += NOISE * np.random.default_rng(0).standard_normal(n)
    return Record(t=t, x=x)


def measure(fn, record, zeta):
    t0 = time.perf_counter()
    est = fn(record)
    elapsed = time.perf_counter() - t0
    if record.t.size <= 2_000_000:  # tracemalloc doubles the run time: skip it at 1e7
        tracemalloc.start()
        fn(record)
        peak = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
    else:
        peak = math.nan
    if "zeta" in est.params:
        got = est.value("zeta")
    else:  # the log decrement: the mean of the two directions' damping ratios
        got = 0.5 * (est.value("zeta_plus") + est.value("zeta_minus"))
    return elapsed, peak / (16 * record.t.size), got / zeta - 1


def exponent(ns, times) -> float:
    keep = [(n, t) for n, t in zip(ns, times, strict=True) if 1e4 <= n <= 1e6]
    if len(keep) < 2:
        return math.nan
    x, y = np.log([k[0] for k in keep]), np.log([k[1] for k in keep])
    return float(np.polyfit(x, y, 1)[0])


def series(name, fn, sizes, make, zeta):
    print(f"== {name}")
    print(f"  {'samples':>9} {'time [s]':>9} {'peak/record':>12} {'zeta rel err':>13}")
    times = []
    for n in sizes:
        elapsed, mem, err = measure(fn, make(n), zeta)
        times.append(elapsed)
        print(f"  {n:9.0e} {elapsed:9.3f} {mem:12.1f} {err:13.1e}")
    print(f"  fitted exponent 1e4..1e6: {exponent(sizes, times):.2f}  (acceptance <= 1.15)")


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--max", type=float, default=1e6, help="largest record [samples]")
    top = parser.parse_args().max
    sizes = [n for n in (1e3, 1e4, 1e5, 1e6, 1e7) if n <= top]
    sizes = [int(n) for n in sizes]
    dense = lambda n: decay(n, 30.0)  # noqa: E731
    series("Hilbert (FREEVIB), 30 s record, denser sampling", estimate_hilbert, sizes[1:],
           dense, ZETA)
    series("Morlet wavelet, 30 s record, denser sampling", estimate_wavelet, sizes[1:], dense,
           ZETA)
    # series B: 1 kHz, longer; a damping that leaves ~1/e of the amplitude at the end
    longer = lambda n: decay(n, n / 1000.0, zeta=1.0 / (2 * math.pi * F0 * n / 1000.0))  # noqa: E731
    print("== log decrement, 1 kHz, longer records (zeta chosen so the decay spans the record)")
    print(f"  {'samples':>9} {'time [s]':>9} {'peak/record':>12} {'zeta rel err':>13}")
    times = []
    for n in sizes[1:]:  # 1e3 samples at 1 kHz hold only 4 peaks
        rec = longer(n)
        elapsed, mem, err = measure(estimate_log_decrement, rec, 1.0 / (2 * math.pi * F0 * n
                                                                        / 1000.0))
        times.append(elapsed)
        print(f"  {n:9.0e} {elapsed:9.3f} {mem:12.1f} {err:13.1e}")
    print(f"  fitted exponent 1e4..1e6: {exponent(sizes[1:], times):.2f}")
    if top >= 1e6:
        rec = longer(1_000_000)
        raw = inspect.unwrap(estimate_log_decrement)  # without the one-BLAS-thread limit
        t0 = time.perf_counter()
        raw(rec)
        t_all = time.perf_counter() - t0
        t0 = time.perf_counter()
        estimate_log_decrement(rec)
        t_one = time.perf_counter() - t0
        print(f"== BLAS threads, log decrement at 1e6 samples: all threads {t_all:.2f} s, "
              f"one thread {t_one:.2f} s  (all/one {t_all / t_one:.2f}x)")


if __name__ == "__main__":
    main()
