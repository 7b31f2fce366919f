"""Stribeck maps and rising static friction in the drive simulator: speed cost and fit coverage.

1. Speed: the same drives with Coulomb + viscous friction (the baseline, timed in the same run)
   and with a Lorentzian or Bo–Pavelescu map, and with rising static friction (dwell):
   a one-body stick-slip run (spring pulled at constant speed, 20 s at 1 kHz) and the
   three-body drive of bench_drive.py's W3 shape (backlash, shaft, delayed PD, 5 s). Best
   of ``--repeat`` runs; printed as ratios to the Coulomb baseline. A Stribeck map can also
   shorten the RK4 step (its falling branch is a negative damping, ``stribeck_slope``):
   the step is printed so the two costs can be told apart.
2. Fit: ``identify drive`` estimating ``fs_mean`` and ``v_s`` of a Lorentzian body
   (tests/identify/test_drive_fit_stribeck.py's record) from starts 30 % off, ``--runs``
   noise realisations: time per fit, largest error, and the coverage of the 95 % intervals.

With ``--memory`` the Lorentzian body also has frictional memory (Eq. 2.12, ``memory`` =
10 ms in the speed runs, its cost printed against the same map without memory), and the fit
estimates ``fs_mean``, ``v_s`` and ``memory`` (20 ms) of tests/identify/test_drive_fit_memory.py's
drive, from fs_mean 30 % low, v_s 30 % high and the memory alternately 30 % low and high.

    PYTHONPATH=src python benchmarks/bench_drive_stribeck.py --repeat 5 --runs 20
    PYTHONPATH=src python benchmarks/bench_drive_stribeck.py --memory --repeat 5 --runs 100
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from driveid.identify.drive._drive_model import with_values
from driveid.identify.drive.drive_fit import DriveRecord, estimate_drive
from driveid.sim.drive import (
    BacklashLink,
    BodyParams,
    DriveParams,
    PDFeedback,
    ShaftLink,
    _prepare,
    simulate_drive,
)

COULOMB = dict(c_mean=0.01, fk_mean=0.1, fs_mean=0.3)
VARIANTS = {
    "coulomb": {},
    "lorentzian": dict(stribeck="lorentzian", v_s=0.05),
    "bo_pavelescu": dict(stribeck="bo_pavelescu", v_s=0.05, stribeck_exponent=1.5),
    "dwell": dict(dwell_gamma=0.3, dwell_kappa=0.8),
    "lorentzian+dwell": dict(stribeck="lorentzian", v_s=0.05, dwell_gamma=0.3),
}


def _best(fns: dict, repeat: int) -> dict:
    """Best time of each callable over ``repeat`` interleaved rounds (a shared machine's
    load then falls on every variant alike)."""
    for fn in fns.values():
        fn()  # compile / warm
    best = dict.fromkeys(fns, np.inf)
    for _ in range(repeat):
        for key, fn in fns.items():
            t0 = time.perf_counter()
            fn()
            best[key] = min(best[key], time.perf_counter() - t0)
    return best


def _one_body(extra: dict) -> tuple:
    drive = DriveParams(bodies=(BodyParams(J=0.01, K=10.0, **COULOMB, **extra),))
    t = np.arange(20001) / 1000.0
    torque = 10.0 * 0.05 * t[None]  # the spring's far end pulled at 0.05 rad/s
    return drive, dict(duration=20.0, fs=1000.0, torque=torque)


def _three_body(extra: dict) -> tuple:
    bodies = (BodyParams(J=0.01, **COULOMB, **extra),
              BodyParams(J=0.02, c_mean=0.02, fk_mean=0.1),
              BodyParams(J=0.005, c_mean=0.001, fk_mean=0.02))
    drive = DriveParams(bodies=bodies,
                        links=(BacklashLink(gap_plus=0.01, gap_minus=0.01, k=300.0, c=0.5),
                               ShaftLink(k=100.0, c=0.2)),
                        feedback=PDFeedback(P=5.0, D=0.3, delay=0.002, body=0))
    t = np.arange(5001) / 1000.0
    return drive, dict(duration=5.0, fs=1000.0, reference=0.5 * np.sin(2 * np.pi * t))


MEMORY_VARIANTS = {
    "lorentzian+memory": dict(stribeck="lorentzian", v_s=0.05, memory=0.01),
}


def speed(repeat: int, memory: bool = False) -> None:
    variants = {**VARIANTS, **MEMORY_VARIANTS} if memory else VARIANTS
    for label, build in (("one body, stick-slip 20 s", _one_body),
                         ("three bodies, PD 5 s", _three_body)):
        print(f"{label}:")
        coulomb_step = _prepare(*_args(*build({})))["max_step"]
        fns, info = {}, {}
        for name, extra in variants.items():
            drive, kw = build(extra)
            run = _prepare(*_args(drive, kw))
            res = simulate_drive(drive, **kw)
            info[name] = (1e3 / (run["fs"] * run["n_sub"]), res.n_mode_switches)
            fns[name] = lambda d=drive, k=kw: simulate_drive(d, **k)
            # on Coulomb's grid step: the map's own cost per step, without its finer step
            fns[name + "@"] = lambda d=drive, k=kw, h=coulomb_step: simulate_drive(
                d, **k, max_step=h)
        best = _best(fns, repeat)
        # "coulomb" and "coulomb@" are the same run (its own step): the better of the two
        base = min(best["coulomb"], best["coulomb@"])
        for name in variants:
            step, switches = info[name]
            print(f"  {name:18s} {best[name] * 1e3:8.2f} ms  x{best[name] / base:5.2f} of "
                  f"Coulomb  step {step:.3g} ms  (x{best[name + '@'] / base:5.2f} on "
                  f"Coulomb's step)  switches {switches}")
        if memory:  # the memory's own cost: the same map and step without it
            print(f"  memory against the Lorentzian map alone: "
                  f"x{best['lorentzian+memory'] / best['lorentzian']:.2f}")


def _args(drive: DriveParams, kw: dict) -> tuple:
    """Positional arguments of ``_prepare`` for a run of ``simulate_drive(drive, **kw)``."""
    return (drive, kw["duration"], kw["fs"], None, None, kw.get("torque"),
            kw.get("reference"), None, 200)


def _record(truth: DriveParams, seed: int) -> DriveRecord:
    t = np.arange(4001) / 1000.0
    u = 0.3 * np.sin(2 * np.pi * 1.0 * t) + 0.1 * np.sin(2 * np.pi * 2.7 * t)
    res = simulate_drive(truth, duration=4.0, fs=1000.0, torque=u[None])
    rng = np.random.default_rng(seed)
    return DriveRecord(t=res.t, channels={"x1": res.x[0] + rng.normal(0, 1e-4, t.size)}, u=u)


def fit_coverage(runs: int, memory: bool = False) -> None:
    truth = DriveParams(bodies=(BodyParams(J=0.01, c_mean=0.02, fk_mean=0.1, fs_mean=0.25,
                                           fs_delta=0.03, stribeck="lorentzian", v_s=0.3,
                                           v_s_delta=0.05, memory=0.02 if memory else 0.0),))
    names = ["body1.fs_mean", "body1.v_s"] + (["body1.memory"] if memory else [])
    true = np.array([0.25, 0.3, 0.02][:len(names)])
    zero = np.zeros(1)
    t = np.arange(4001) / 1000.0
    u = 0.3 * np.sin(2 * np.pi * 1.0 * t) + 0.1 * np.sin(2 * np.pi * 2.7 * t)
    t_sim = _best({"sim": lambda: simulate_drive(truth, duration=4.0, fs=1000.0,
                                                 torque=u[None])}, 5)["sim"]
    inside = np.zeros(len(names))
    worst = np.zeros(len(names))
    seconds = []
    failed = 0
    for seed in range(runs):
        off = 0.3 if seed % 2 == 0 else -0.3
        values = {names[0]: true[0] * (1 + off), names[1]: true[1] * (1 - off)}
        if memory:  # the memory 30 % off either way, fs_mean low and v_s high (the test's)
            values = {names[0]: true[0] * 0.7, names[1]: true[1] * 1.3,
                      names[2]: true[2] * (1 + off)}
        start, _, _ = with_values(truth, zero, zero, values)
        rec = _record(truth, 1000 + seed)
        t0 = time.perf_counter()
        try:
            est = estimate_drive(rec, start, estimate=names, x0=[0.0], v0=[0.0],
                                 starts_from_record=False)
        except Exception as exc:  # a benchmark counts failures instead of stopping
            failed += 1
            print(f"  seed {seed}: failed ({exc})")
            continue
        seconds.append(time.perf_counter() - t0)
        value = np.array([est.value(n) for n in names])
        se = np.array([est.stderr(n) for n in names])
        inside += np.abs(value - true) <= 1.96 * se
        worst = np.maximum(worst, np.abs(value / true - 1))
    ok = runs - failed
    print(f"fit of {', '.join(n.split('.')[1] for n in names)} (starts +-30 %), {ok}/{runs} "
          "converged:")
    print(f"  time per fit {np.median(seconds):.2f} s = x{np.median(seconds) / t_sim:.0f} one "
          f"simulation of the record ({t_sim * 1e3:.2f} ms)")
    for j, n in enumerate(names):
        print(f"  {n}: largest error {worst[j] * 100:.3f} %, 95 % coverage "
              f"{inside[j] / max(ok, 1) * 100:.0f} % ({int(inside[j])}/{ok})")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=5, help="timing repeats (best of)")
    ap.add_argument("--runs", type=int, default=100, help="noise realisations of the fit")
    ap.add_argument("--memory", action="store_true",
                    help="add frictional memory (Eq. 2.12) to the Lorentzian body")
    args = ap.parse_args()
    speed(args.repeat, args.memory)
    if args.runs > 0:
        fit_coverage(args.runs, args.memory)


if __name__ == "__main__":
    main()
