"""Output error vs peaks vs the Cramér–Rao bound on the thesis's Table 5.1 systems (issue 13).

For each case (J = 1, released at rest from 10 rad, 30 s; README table) and scenario
(white noise of 0.1 % / 0.5 % of the release amplitude at 100 Hz / 1 kHz, or an 8000
counts/rev encoder at 1 kHz), ``--repeats`` seeded realisations are identified by
``estimate_output_error`` (oe) and ``estimate_log_decrement`` (peaks), both with J known.
Printed per parameter and method: bias / CRLB sd, efficiency = CRLB variance / observed
variance, coverage of the 95 % intervals, and the mean time per record relative to the
peak estimator timed in the same run. The bound for the encoder uses noise q/√12; each
encoder realisation has a random encoder zero (rounding itself is deterministic).

    python benchmarks/bench_output_error.py --quick                  # 1 case, 100 Hz, 40 runs
    python benchmarks/bench_output_error.py --cases 3,7 --scenarios n0.5@100 --repeats 200
    python benchmarks/bench_output_error.py --speed                  # 100 Hz, 20k, 1M samples
"""

from __future__ import annotations

import argparse
import math
import sys
import time
import warnings

import numpy as np

from driveid.errors import DriveIdError
from driveid.identify.crlb import free_decay_crlb
from driveid.identify.free_decay.logdec import estimate_log_decrement
from driveid.identify.free_decay.output_error import estimate_output_error
from driveid.sim import OscillatorParams, measure, simulate_free_decay

# (ω0, f̄k, Δfk, c̄, Δc), thesis Table 5.1 (as examples/logdec_table_5_1.py)
CASES = [(3.162, 0.2, 0.5, 0.4, 0.3), (4.0, 0.2, 0.5, 0.3, 0.4), (4.0, 0.07, 0.13, 0.3, 0.0),
         (4.0, 2.0, 2.0, 0.625, 0.125), (2.0, 0.0, 0.0, 0.4, 0.3), (2.0, 0.2, 0.0, 0.5, 0.0),
         (4.0, 6.25, 5.75, 0.625, 0.125), (4.0, 0.4, 0.3, 0.1, 0.0)]
NAMES = ["omega0", "c_mean", "c_delta", "fk_mean", "fk_delta"]
X0, DURATION = 10.0, 30.0
SCENARIOS = {"n0.1@100": (100.0, 0.001, None), "n0.5@100": (100.0, 0.005, None),
             "n0.1@1k": (1000.0, 0.001, None), "n0.5@1k": (1000.0, 0.005, None),
             "enc8000@1k": (1000.0, 0.0, 8000)}


def _params(case):
    omega0, fkm, fkd, cm, cd = CASES[case - 1]
    K = 10.0 if omega0 == 3.162 else omega0**2
    return OscillatorParams(J=1.0, K=K, c_mean=cm, c_delta=cd, fk_mean=fkm, fk_delta=fkd)


def run(case, scenario, repeats, bootstrap):
    fs, rel_noise, counts = SCENARIOS[scenario]
    p = _params(case)
    truth = {"omega0": p.omega0, "c_mean": p.c_mean, "c_delta": p.c_delta,
             "fk_mean": p.fk_mean, "fk_delta": p.fk_delta}
    exact = simulate_free_decay(p, x0=X0, duration=DURATION, fs=fs).record
    noise = rel_noise * X0
    bound_noise = noise if counts is None else 2 * math.pi / counts / math.sqrt(12)
    bound = free_decay_crlb(p, fs=fs, duration=DURATION, x0=X0, noise_std=bound_noise)
    results = {"oe": [], "peaks": []}
    times = {"oe": 0.0, "peaks": 0.0}
    failures = {"oe": 0, "peaks": 0}
    for seed in range(repeats):
        if counts is None:
            rec = measure(exact, noise_std=noise, rng=seed)
        else:  # rounding is deterministic: each realisation gets a random encoder zero
            shift = np.random.default_rng(seed).uniform(0, 2 * math.pi / counts)
            rec = measure(exact.replace(x=exact.x + shift), counts_per_rev=counts)
            rec = rec.replace(x=rec.x - shift)
        for method in ("peaks", "oe"):
            t0 = time.perf_counter()
            try:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    if method == "oe":
                        est = estimate_output_error(rec, mass=1.0, bootstrap=bootstrap,
                                                    rng=seed)
                    else:
                        est = estimate_log_decrement(rec, mass=1.0)
            except DriveIdError:
                failures[method] += 1
                continue
            finally:
                times[method] += time.perf_counter() - t0
            results[method].append([(est.value(n), est.stderr(n)) for n in NAMES])
    print(f"\ncase {case}, {scenario}: {repeats} realisations, CRLB noise {bound_noise:.3g} "
          f"rad, {exact.n} samples; failures oe {failures['oe']}, peaks {failures['peaks']}; "
          f"time per record oe {times['oe'] / repeats:.3f} s = "
          f"{times['oe'] / max(times['peaks'], 1e-12):.2f}x peaks")
    print(f"  {'param':9s} {'CRLB sd':>10s} | {'method':5s} {'bias/sd':>8s} {'eff':>7s} "
          f"{'cover':>6s} {'rel.sd %':>9s}")
    rows = []
    for j, name in enumerate(NAMES):
        for method in ("peaks", "oe"):
            data = np.array(results[method])
            if data.size == 0:
                continue
            vals, ses = data[:, j, 0], data[:, j, 1]
            bias = (np.mean(vals) - truth[name]) / bound[name]
            eff = bound[name] ** 2 / max(np.var(vals, ddof=1), 1e-300)
            cover = np.mean(np.abs(vals - truth[name]) <= 1.96 * ses)
            scale = abs(truth[name]) if truth[name] else 1.0
            rel = 100 * np.std(vals, ddof=1) / scale
            print(f"  {name:9s} {bound[name]:10.3g} | {method:5s} {bias:8.2f} {eff:7.3f} "
                  f"{cover:6.2f} {rel:9.3g}")
            rows.append((case, scenario, name, method, bias, eff, cover))
    sys.stdout.flush()
    return rows


def speed():
    p = _params(3)
    cases = [("100 Hz, 30 s", 100.0, 30.0, 0.01), ("1 kHz, 20 s (20 001 samples)", 1000.0,
                                                   20.0, 0.01),
             ("20 kHz, 50 s (1 000 001 samples)", 20000.0, 50.0, 0.01)]
    for label, fs, duration, noise in cases:
        rec = measure(simulate_free_decay(p, x0=X0, duration=duration, fs=fs).record,
                      noise_std=noise, rng=0)
        t0 = time.perf_counter()
        estimate_log_decrement(rec, mass=1.0)
        t_peaks = time.perf_counter() - t0
        t0 = time.perf_counter()
        est = estimate_output_error(rec, mass=1.0)
        t_oe = time.perf_counter() - t0
        print(f"{label}: output error {t_oe:.2f} s, peaks {t_peaks:.2f} s, ratio "
              f"{t_oe / t_peaks:.2f}; fk_mean {est.value('fk_mean'):.6f} ± "
              f"{est.stderr('fk_mean'):.2g}")
        sys.stdout.flush()


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true",
                    help="case 3, n0.5@100, 40 realisations")
    ap.add_argument("--cases", default="1,2,3,4,5,6,7,8", help="comma-separated case numbers")
    ap.add_argument("--scenarios", default=",".join(SCENARIOS),
                    help=f"comma-separated, of {list(SCENARIOS)}")
    ap.add_argument("--repeats", type=int, default=200)
    ap.add_argument("--bootstrap", type=int, default=25)
    ap.add_argument("--speed", action="store_true", help="only the timing of three sizes")
    args = ap.parse_args(argv)
    if args.speed:
        speed()
        return
    if args.quick:
        args.cases, args.scenarios, args.repeats = "3", "n0.5@100", 40
    for scenario in args.scenarios.split(","):
        for case in (int(c) for c in args.cases.split(",")):
            run(case, scenario, args.repeats, args.bootstrap)


if __name__ == "__main__":
    main()
