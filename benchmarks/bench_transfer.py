"""Coverage and time of ``identify transfer`` on a simulated two-mass drive (issue 25, item 3).

Plant: motor J_m = 2e-3 kg·m², load J_l = 6e-3 kg·m², shaft k = 40 N·m/rad, c = 0.02
N·m·s/rad, motor viscous loss c_m = 0.01 N·m·s/rad; torque command, motor speed measured
(resonance 163.3 rad/s, ζ = 0.052). Each realisation: a PRBS (250 Hz clock, 0.2 N·m) or a
Schroeder multisine (0.5-150 Hz, 0.2 N·m peak) of ``--duration`` s at 1 kHz, simulated by
``scipy.signal.cont2discrete`` + ``dlsim`` (independent of driveid's simulation), plus AR(1)
noise (φ = 0.6) of 20 % of the speed's standard deviation; with ``--abs`` the sensor gives
``|speed|`` (the noise added after it).

Printed per structure and field: bias / mean standard error, scatter / mean standard error,
coverage of the 95 % intervals (binomial sd 1.5 % at 200 repeats), and the processor time
per fit, also as a ratio to one simulation of the record by scipy timed in the same run.

    nice -n 10 python benchmarks/bench_transfer.py --repeats 200
    python benchmarks/bench_transfer.py --quick              # 10 repeats
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np
from scipy.signal import cont2discrete, dlsim, lfilter

from driveid.identify.forced.transfer import estimate_transfer
from driveid.io.record import Record
from driveid.signal.excitation import multisine, prbs

FS = 1000.0
TRUTH = {"J_m": 2e-3, "J_l": 6e-3, "k": 40.0, "c": 0.02, "c_m": 0.01}


def _system():
    Jm, Jl, k, c, cm = (TRUTH[n] for n in ("J_m", "J_l", "k", "c", "c_m"))
    A = np.array([[0.0, 1.0, -1.0], [-k / Jm, -(c + cm) / Jm, c / Jm],
                  [k / Jl, c / Jl, -c / Jl]])
    B = np.array([[0.0], [1.0 / Jm], [0.0]])
    C = np.array([[0.0, 1.0, 0.0]])
    poles = np.linalg.eigvals(A)
    p = poles[np.argmax(poles.imag)]
    truth = dict(TRUTH, omega0_1=abs(p), zeta_1=-p.real / abs(p))
    return cont2discrete((A, B, C, np.zeros((1, 1))), 1 / FS, method="zoh")[:4], truth


def _record(kind, seed, duration, absolute, system):
    if kind == "prbs":
        u = prbs(f_clock=250, duration=duration, fs=FS, amplitude=0.2).u
    else:
        u = multisine(f_min=0.5, f_max=150, duration=duration, fs=FS, amplitude=0.2,
                      period=duration / 2).u
    y = dlsim((*system, 1 / FS), u)[1][:, 0]
    rng = np.random.default_rng(seed)
    e = lfilter([1.0], [1.0, -0.6], rng.normal(size=u.size))
    e *= 0.2 * np.std(y) / np.std(e)
    y = (np.abs(y) if absolute else y) + e
    t = np.arange(u.size) / FS
    return Record(t=t, x=np.zeros_like(t), v=y, u=u)


def main(argv=None):
    """Run the benchmark and print the table.

    Parameters
    ----------
    argv : list of str, optional
        Command-line arguments (``--repeats``, ``--duration``, ``--abs``, ``--kind``,
        ``--structure``, ``--quick``).
    """
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=200)
    ap.add_argument("--duration", type=float, default=2.0, help="record length [s]")
    ap.add_argument("--abs", action="store_true", help="speed-magnitude sensor")
    ap.add_argument("--kind", choices=["prbs", "multisine"], default="prbs")
    ap.add_argument("--structure", choices=["tf", "two-mass", "both"], default="both")
    ap.add_argument("--quick", action="store_true", help="10 repeats")
    args = ap.parse_args(argv)
    repeats = 10 if args.quick else args.repeats
    system, truth = _system()
    rec0 = _record(args.kind, 0, args.duration, args.abs, system)
    t0 = time.process_time()
    for _ in range(20):
        dlsim((*system, 1 / FS), rec0.u)
    t_sim = (time.process_time() - t0) / 20
    nonlin = "abs" if args.abs else None
    print(f"two-mass drive, {args.kind}, {args.duration} s at 1 kHz, AR(1) noise 20 %, "
          f"{'|speed|' if args.abs else 'speed'}; {repeats} realisations; one scipy "
          f"simulation of the record: {t_sim * 1e3:.2f} ms")
    print(f"{'structure':10s} {'field':9s} {'bias/se':>8s} {'sd/se':>7s} {'cover95':>8s} "
          f"{'max |err| %':>11s} {'s/fit':>7s} {'x sim':>7s}")
    for structure, fields in (("tf", ["omega0_1", "zeta_1"]),
                              ("two-mass", ["omega0_1", "zeta_1", "J_m", "J_l", "k", "c",
                                            "c_m"])):
        if args.structure not in ("both", structure):
            continue
        err = {f: [] for f in fields}
        se = {f: [] for f in fields}
        cpu = 0.0
        for seed in range(repeats):
            rec = _record(args.kind, 1000 + seed, args.duration, args.abs, system)
            t0 = time.process_time()
            est = estimate_transfer(rec, structure=structure, output_nonlinearity=nonlin,
                                    **({"order": 3} if structure == "tf" else {}))
            cpu += time.process_time() - t0
            for f in fields:
                err[f].append(est.value(f) - truth[f])
                se[f].append(est.stderr(f))
        per_fit = cpu / repeats
        for f in fields:
            e, s = np.array(err[f]), np.array(se[f])
            ms = float(np.mean(s))
            cover = float(np.mean(np.abs(e) < 1.959964 * s))
            worst = 100 * float(np.max(np.abs(e))) / abs(truth[f])
            print(f"{structure:10s} {f:9s} {np.mean(e) / ms:8.2f} {np.std(e) / ms:7.2f} "
                  f"{cover:8.1%} {worst:11.3f} {per_fit:7.3f} {per_fit / t_sim:7.0f}")
    print("coverage binomial sd at this count: "
          f"{100 * math.sqrt(0.95 * 0.05 / repeats):.1f} %")


if __name__ == "__main__":
    main()
