"""Coverage of PHO campaign error bars on quantised asymmetric campaigns (issue 13, item 3).

For each plant, ``--repeats`` seeded realisations of one campaign (every (P, D) of the grid
released from +x0 and -x0, simulated by the event-located drive simulator and read through
an encoder whose grid phase is random per run: rounding itself is deterministic) are
identified by the peak analysis (``estimate_pho_records``, today's ``pho analyse``) and by
the whole-record fit (``estimate_pho_output_error``, started from the peaks), both with
K = 0 known and the delay estimated (``--known-delay`` gives it). Printed per field and
method: bias / mean standard error, empirical scatter / mean standard error, coverage of
the 95 % intervals (binomial sd ~1.5 % at 200 repeats), and the time per campaign relative
to the peak analysis timed in the same run (processor time: the machine may be shared).

Issue 24 cases: ``--static 1.1,1.3`` gives the plant static friction 10 % and 30 % above
kinetic (``fs_mean = ratio·fk_mean``, ``fs_delta = fk_delta``); ``--negative-d`` adds run
pairs whose net viscous damping ``c + D - PΔ`` is negative (thesis Fig. 5.3: Coulomb
friction still brings them to rest from below the limit cycle), one with D < 0;
``--noise white|ar1`` replaces the encoder by white or AR(1) (φ = ``--phi``) position noise
of standard deviation ``--noise-std`` quanta. Also printed: the fraction of campaigns with
J within 3 %, f̄k within 5 %, Δf_k within 5 % of f̄k, c̄ within 15 % (the acceptance of
issue 24), the structure chosen and how often the static band was reported.

Plants (asymmetry c_delta = 30 % of c_mean, fk_delta = 10 % of fk_mean, static = kinetic
unless ``--static``):
``testbed``: thesis Table 5.2 "A only" (the ``testbed-a`` preset: the motor body the loop
drives; the 3-body ``testbed`` preset has no single J), 8000 counts/rev;
``pendulum-cart``: the preset (2.39 kg, motor friction, 10.84 ms), 10 µm linear encoder.

    nice -n 10 python benchmarks/bench_pho_coverage.py --repeats 200
    python benchmarks/bench_pho_coverage.py --quick          # 10 repeats, both plants
    python benchmarks/bench_pho_coverage.py --static 1.1,1.3 --negative-d --repeats 40
    python benchmarks/bench_pho_coverage.py --static 1.2 --noise ar1 --phi 0.8 --repeats 40
    python benchmarks/bench_pho_coverage.py --static 1.1,1.3 --negative-d --workers 16
"""

from __future__ import annotations

import argparse
import math
import sys
import time
import warnings
from concurrent.futures import ProcessPoolExecutor
from multiprocessing import get_context

import numpy as np

from driveid.errors import DriveIdError
from driveid.identify.pho.peaks import estimate_pho_records
from driveid.identify.pho.pho_fit import estimate_pho_output_error
from driveid.io.record import Record
from driveid.sim import simulate_drive
from driveid.sim.drive import BodyParams, DriveParams, PDFeedback
from driveid.sim.presets import preset

FIELDS = ["J", "c_mean", "c_delta", "fk_mean", "fk_delta", "delay"]


def _plant(name, negative_d=False):
    key = "testbed-a" if name == "testbed" else name
    params = preset(key)
    b = params.bodies[0]
    truth = {"J": b.J, "c_mean": b.c_mean, "c_delta": 0.3 * b.c_mean, "fk_mean": b.fk_mean,
             "fk_delta": 0.1 * b.fk_mean, "delay": params.feedback.delay}
    # (P, D, x0): net damping c + D - P·delay of the extra pairs is negative; x0 below the
    # amplitude where Coulomb and negative viscous damping balance, 4 fk/(π |c_net| ω)
    # --negative-d: the pairs of `pho run`'s default grid that come to rest (so that the
    # static band decides where), plus the negative-damping pairs
    if name == "testbed":
        grid, quantum = [(2.0, 0.03, 1.0), (5.0, 0.06, 1.0), (8.0, 0.09, 1.0)], 2 * math.pi / 8000
        cli = [(2.0, 0.03, 1.0), (2.0, 0.04, 1.0), (2.0, 0.05, 1.0), (3.0, 0.04, 1.0),
               (3.0, 0.05, 1.0)]
        extra = [(2.0, 0.015, 0.8), (1.0, -0.005, 0.78)]
    else:
        grid, quantum = [(200.0, 3.0, 0.3), (300.0, 4.5, 0.3), (400.0, 6.0, 0.3)], 1e-5
        # the releases vary: on this plant a run seldom stops with a force above kinetic
        # (at 1.3 x kinetic, 3 of these 14 runs do; with x0 = 0.6 everywhere, none)
        cli = [(120.0, 1.35, 0.6), (120.0, 1.8, 0.6), (180.0, 1.8, 0.4), (180.0, 2.25, 0.5),
               (240.0, 2.25, 0.3)]
        extra = [(300.0, 2.0, 0.3), (100.0, -0.5, 0.4)]
    if negative_d:
        grid = cli + extra
    return truth, grid, quantum


def _exact_campaign(truth, grid, duration, fs, static=None):
    fs_mean = None if static is None else static * truth["fk_mean"]
    body = BodyParams(J=truth["J"], c_mean=truth["c_mean"], c_delta=truth["c_delta"],
                      fk_mean=truth["fk_mean"], fk_delta=truth["fk_delta"], fs_mean=fs_mean,
                      fs_delta=None if static is None else truth["fk_delta"])
    out = []
    for P, D, x0 in grid:
        for sign in (1.0, -1.0):
            fb = PDFeedback(P=P, D=D, delay=truth["delay"])
            rec = simulate_drive(DriveParams(bodies=(body,), feedback=fb), duration=duration,
                                 fs=fs, x0=[sign * x0]).record
            out.append(Record(rec.t, rec.x, meta={"P": P, "D": D, "x0": sign * x0}))
    return out


def _noisy(exact, std, phi, gen):
    """Add white (phi = 0) or AR(1) position noise of standard deviation ``std``."""
    from scipy.signal import lfilter

    out = []
    for rec in exact:
        w = gen.normal(0.0, std * math.sqrt(1.0 - phi**2), rec.n + 500)
        out.append(rec.replace(x=rec.x + lfilter([1.0], [1.0, -phi], w)[500:]))
    return out


def _quantise(exact, quantum, gen):
    """Read each run through an encoder whose grid phase is random."""
    out = []
    for rec in exact:
        phase = gen.uniform(0.0, quantum)
        out.append(rec.replace(x=quantum * np.round((rec.x - phase) / quantum) + phase))
    return out


def _accepted(truth, est):
    """Issue 24's accuracy: J 3 %, f̄k 5 %, Δf_k 5 % of f̄k, c̄ 15 %."""
    fk = truth["fk_mean"]
    return (abs(est.value("J") / truth["J"] - 1) <= 0.03
            and abs(est.value("fk_mean") / fk - 1) <= 0.05
            and abs(est.value("fk_delta") - truth["fk_delta"]) <= 0.05 * fk
            and abs(est.value("c_mean") / truth["c_mean"] - 1) <= 0.15)


def _one_thread():
    """One BLAS thread per worker process: the workers are the parallelism."""
    from threadpoolctl import threadpool_limits

    threadpool_limits(1)


_JOB: dict = {}


def _one_realisation(seed):
    """Identify one seeded realisation (of the campaign in ``_JOB``) by peaks and by OE."""
    return _identify(seed, **_JOB)


def _identify(seed, *, exact, quantum, noise, noise_std, phi, delay, bootstrap, refit,
              no_bootstrap, fit_static, noise_model, fields, truth):
    gen = np.random.default_rng(seed)
    if noise == "encoder":
        recs = _quantise(exact, quantum, gen)
    else:
        recs = _noisy(exact, noise_std * quantum, phi if noise == "ar1" else 0.0, gen)
    out = {"times": {"peaks": 0.0, "oe": 0.0}, "failed": {"peaks": 0, "oe": 0},
           "values": {"peaks": None, "oe": None}, "errors": {"peaks": None, "oe": None},
           "accurate": {"peaks": 0, "oe": 0}, "structure": None, "band": 0, "sandwich": 0}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        t0 = time.process_time()  # processor time: the machine is shared
        pk = oe = None
        try:
            pk = estimate_pho_records(recs, delay=delay, K_known=0.0)
        except DriveIdError:
            out["failed"] = {"peaks": 1, "oe": 1}
        t1 = time.process_time()
        if pk is not None:
            out["times"]["peaks"] = t1 - t0
            try:
                oe = estimate_pho_output_error(
                    recs, delay=delay, K_known=0.0, start=pk, bootstrap=bootstrap,
                    refit=refit, rng=seed,
                    quantisation="auto" if noise == "encoder" and not no_bootstrap
                    else None, static=fit_static, noise_model=noise_model)
            except DriveIdError:
                out["failed"]["oe"] = 1
            out["times"]["oe"] = time.process_time() - t0  # includes its peak start
    for method, est in (("peaks", pk), ("oe", oe)):
        if est is None:
            continue
        out["values"][method] = [est.value(f) for f in fields]
        out["errors"][method] = [est.stderr(f) for f in fields]
        out["accurate"][method] = int(_accepted(truth, est))
    if oe is not None:
        d = oe.diagnostics
        out["structure"] = d["structure"]
        out["band"] = int(d["static_band"] is not None)
        out["sandwich"] = int(d["adequacy"]["covariance"] == "sandwich")
    return out

def run(name, repeats, bootstrap, known_delay, refit, duration, fs, every, static=None,
        negative_d=False, noise="encoder", phi=0.8, noise_std=1.0, no_bootstrap=False,
        fit_static="auto", noise_model=True, workers=1):
    truth, grid, quantum = _plant(name, negative_d)
    exact = _exact_campaign(truth, grid, duration, fs, static)
    delay = truth["delay"] if known_delay else None
    fields = [f for f in FIELDS if not (f == "delay" and known_delay)]
    values = {"peaks": [], "oe": []}
    errors = {"peaks": [], "oe": []}
    times = {"peaks": 0.0, "oe": 0.0}
    failures = {"peaks": 0, "oe": 0}
    extra = {"accurate": {"peaks": 0, "oe": 0}, "structures": {}, "band": 0, "sandwich": 0}
    # records do not pickle: the workers inherit the job at the fork
    _JOB.clear()
    _JOB.update(exact=exact, quantum=quantum, noise=noise, noise_std=noise_std, phi=phi,
                delay=delay, bootstrap=bootstrap, refit=refit, no_bootstrap=no_bootstrap,
                fit_static=fit_static, noise_model=noise_model, fields=fields, truth=truth)
    pool = None
    if workers > 1:
        pool = ProcessPoolExecutor(workers, mp_context=get_context("fork"),
                                   initializer=_one_thread)
    outcomes = (pool.map if pool else map)(_one_realisation, range(repeats))
    for seed, outcome in enumerate(outcomes):
        for method in ("peaks", "oe"):
            times[method] += outcome["times"][method]
            failures[method] += outcome["failed"][method]
            if outcome["values"][method] is None:
                continue
            values[method].append(outcome["values"][method])
            errors[method].append(outcome["errors"][method])
            extra["accurate"][method] += outcome["accurate"][method]
        if outcome["structure"] is not None:
            s = outcome["structure"]
            extra["structures"][s] = extra["structures"].get(s, 0) + 1
            extra["band"] += outcome["band"]
            extra["sandwich"] += outcome["sandwich"]
        done = seed + 1
        if done == repeats or done % every == 0:
            kind = (f"encoder quantum {quantum:.4g}" if noise == "encoder" else
                    f"{noise} noise sd {noise_std:g} quanta" + (f", phi {phi:g}"
                                                                 if noise == "ar1" else ""))
            print(f"\n{name} (fit: static {fit_static}"
                  f"{', white noise' if not noise_model else ''}): {len(exact)} runs of "
                  f"{duration:g} s at {fs:g} Hz, {kind}, grid "
                  f"(P, D, x0) {grid}; static/kinetic "
                  f"{'1 (equal)' if static is None else f'{static:g}'}; {done} of {repeats} "
                  f"realisations, bootstrap {bootstrap}{' (refit)' if refit else ''}, "
                  f"delay {'known' if known_delay else 'estimated'}, K = 0 known")
            _summary(truth, fields, values, errors, times, failures, done)
            n_ok = {m: len(values[m]) for m in values}
            print("within J 3 %, fk 5 %, dfk 5 % of fk, c 15 %: "
                  + ", ".join(f"{m} {extra['accurate'][m]}/{n_ok[m]}" for m in n_ok)
                  + f"; oe structure chosen {extra['structures']}, static band reported "
                  f"{extra['band']}/{n_ok['oe']}, sandwich-widened {extra['sandwich']}")
            sys.stdout.flush()
    if pool is not None:
        pool.shutdown()


def _summary(truth, fields, values, errors, times, failures, repeats):
    print(f"{'field':>9} {'method':>6} {'bias/se':>8} {'sd/se':>7} {'coverage':>9}")
    for method in ("peaks", "oe"):
        if not values[method]:
            continue
        v, e = np.array(values[method]), np.array(errors[method])
        t = np.array([truth[f] for f in fields])
        for j, f in enumerate(fields):
            se = float(np.mean(e[:, j]))
            bias = float(np.mean(v[:, j]) - t[j]) / se
            scatter = float(np.std(v[:, j], ddof=1)) / se
            cover = float(np.mean(np.abs(v[:, j] - t[j]) <= 1.96 * e[:, j]))
            print(f"{f:>9} {method:>6} {bias:>8.2f} {scatter:>7.2f} {cover:>8.1%}")
    n_ok = repeats - failures["peaks"]
    if n_ok:
        per = {m: times[m] / n_ok for m in times}
        print(f"processor time per campaign: peaks {per['peaks']:.2f} s, oe {per['oe']:.2f} s "
              f"({per['oe'] / per['peaks']:.1f}x peaks); failures: peaks {failures['peaks']}, "
              f"oe {failures['oe']}")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--plants", default="testbed,pendulum-cart")
    ap.add_argument("--repeats", type=int, default=200)
    ap.add_argument("--bootstrap", type=int, default=50)
    ap.add_argument("--refit", action="store_true", help="full bootstrap refits")
    ap.add_argument("--known-delay", action="store_true")
    ap.add_argument("--duration", type=float, default=3.0, help="[s]")
    ap.add_argument("--fs", type=float, default=1000.0, help="[Hz]")
    ap.add_argument("--quick", action="store_true", help="10 repeats")
    ap.add_argument("--every", type=int, default=25, help="print a summary every N repeats")
    ap.add_argument("--no-bootstrap", action="store_true",
                    help="encoder records fitted with the noise model, not the bootstrap")
    ap.add_argument("--fit-static", choices=["auto", "kinetic", "band"], default="auto",
                    help="the fit's static structure (kinetic: the fit before issue 24)")
    ap.add_argument("--white-noise", action="store_true", help="fit without the noise model")
    ap.add_argument("--static", default="", help="static/kinetic ratios, e.g. 1.1,1.3")
    ap.add_argument("--negative-d", action="store_true",
                    help="grid with negative net damping pairs (Fig. 5.3), one with D < 0")
    ap.add_argument("--noise", choices=["encoder", "white", "ar1"], default="encoder")
    ap.add_argument("--phi", type=float, default=0.8, help="AR(1) coefficient [-]")
    ap.add_argument("--noise-std", type=float, default=1.0,
                    help="noise standard deviation in encoder quanta [-]")
    ap.add_argument("--workers", type=int, default=1,
                    help="processes (one BLAS thread each); the same seeds whatever N")
    args = ap.parse_args(argv)
    repeats = 10 if args.quick else args.repeats
    ratios = [float(v) for v in args.static.split(",") if v.strip()] or [None]
    for name in args.plants.split(","):
        for ratio in ratios:
            run(name.strip(), repeats, args.bootstrap, args.known_delay, args.refit,
                args.duration, args.fs, args.every, static=ratio, negative_d=args.negative_d,
                noise=args.noise, phi=args.phi, noise_std=args.noise_std,
                no_bootstrap=args.no_bootstrap, fit_static=args.fit_static,
                noise_model=not args.white_noise, workers=args.workers)
            sys.stdout.flush()


if __name__ == "__main__":
    main()
