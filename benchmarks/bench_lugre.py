"""LuGre stick–slip (workload W2 of issue 4): our Radau IIA kernel vs scipy solve_ivp.

Workload: m = 1 kg on a spring k = 2 N/m whose far end moves at 0.1 m/s; LuGre friction with
sigma0 = 1e5 N/m, sigma1 = sqrt(1e5) N·s/m, sigma2 = 0.4 N·s/m, Fc = 1 N, Fs = 1.5 N,
vs = 1e-3 m/s; 20 s sampled at 1 kHz. Truth: our integrator at rtol = 1e-10, checked against
scipy Radau at rtol = 1e-10, atol = (1e-12, 1e-12, 1e-14). Accuracy is max |x - x_ref| /
max |x_ref|; the target is 1e-4. The baseline is LSODA with per-state absolute tolerances
(rtol times the state scales Fs/k, vs, Fs/sigma0), tightened by decades until it meets the
target. Also shown: RK45 with solve_ivp's default tolerances, which returns no warning.
First lines: compile time of the kernels with an empty numba cache (a fresh interpreter each,
CPU seconds of its first simulation, so the machine's load matters less).
Run: ``.venv/bin/python benchmarks/bench_lugre.py``.
"""

import math
import os
import subprocess
import sys
import tempfile
import time

import numpy as np
from scipy.integrate import solve_ivp

from driveid.models.dynamic_friction import LuGreParams
from driveid.sim.lugre import simulate_lugre_oscillator

P = LuGreParams(sigma0=1e5, sigma1=math.sqrt(1e5), sigma2=0.4, fc=1.0, fs=1.5, vs=1e-3,
                check_passivity=False)
M, K, BELT, T_END, FS = 1.0, 2.0, 0.1, 20.0, 1000.0
T = np.arange(int(T_END * FS) + 1) / FS
SCALES = np.array([P.fs / K, P.vs, P.fs / P.sigma0])
TARGET = 1e-4


def rhs(t, y):
    x, v, z = y
    g = P.fc + (P.fs - P.fc) * math.exp(-((v / P.vs) ** 2))
    zd = v - P.sigma0 * abs(v) * z / g
    f = P.sigma0 * z + P.sigma1 * zd + P.sigma2 * v
    return [v, K * (BELT * t - x) - f, zd]


COLD = {
    "LuGre oscillator kernel (sim/lugre.py)":
        "from driveid.sim.lugre import simulate_lugre_oscillator as f\n"
        "call = lambda: f(P, m=1.0, k=2.0, belt_speed=0.1, duration=0.01)",
    "smooth drive kernel, one LuGre body (sim/_smooth_kernels.py)":
        "from driveid.sim import BodyParams, DriveParams, simulate_drive\n"
        "d = DriveParams(bodies=(BodyParams(J=1.0, K=2.0, lugre=P),))\n"
        "call = lambda: simulate_drive(d, duration=0.01, fs=1000.0, torque=[0.0])",
}


def cold_compile_seconds(setup):
    """CPU seconds of a fresh interpreter's first call ``call()`` with an empty numba cache."""
    code = ("import time\nfrom driveid.models.dynamic_friction import LuGreParams\n"
            "P = LuGreParams(sigma0=1e5, sigma1=316.2, sigma2=0.4, fc=1.0, fs=1.5, vs=1e-3, "
            "check_passivity=False)\n" + setup +
            "\nc0 = time.process_time()\ncall()\nprint(time.process_time() - c0)")
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, NUMBA_CACHE_DIR=cache)
        run = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                             text=True, check=True)
    return float(run.stdout.split()[-1])


def rel_error(x, ref):
    return float(np.max(np.abs(x - ref)) / np.max(np.abs(ref)))


def best_time(fn, repeat):
    best, out = float("inf"), None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out


def main():
    for name, setup in COLD.items():
        print(f"compile with an empty cache, {name}: {cold_compile_seconds(setup):.2f} s CPU")
    t0 = time.perf_counter()
    simulate_lugre_oscillator(P, m=M, k=K, belt_speed=BELT, duration=0.01)
    print(f"first call (numba load/compile, cached on disk): {time.perf_counter() - t0:.2f} s")

    ref = simulate_lugre_oscillator(P, m=M, k=K, belt_speed=BELT, duration=T_END, rtol=1e-10)
    radau = solve_ivp(rhs, (0, T_END), [0.0, 0.0, 0.0], method="Radau", t_eval=T, rtol=1e-10,
                      atol=[1e-12, 1e-12, 1e-14])
    print(f"reference check: ours(rtol 1e-10) vs scipy Radau(rtol 1e-10): "
          f"{rel_error(ref.x, radau.y[0]):.1e} relative on x")

    ours_t, ours = best_time(
        lambda: simulate_lugre_oscillator(P, m=M, k=K, belt_speed=BELT, duration=T_END), 20)
    ours_err = rel_error(ours.x, ref.x)
    print(f"ours, default rtol 1e-6: {ours_t * 1e3:.2f} ms, error {ours_err:.1e}, "
          f"{ours.n_steps} steps + {ours.n_rejected} rejected")
    loose_t, loose = best_time(
        lambda: simulate_lugre_oscillator(P, m=M, k=K, belt_speed=BELT, duration=T_END,
                                          rtol=1e-5), 20)
    print(f"ours, rtol 1e-5:         {loose_t * 1e3:.2f} ms, error "
          f"{rel_error(loose.x, ref.x):.1e}")

    lsoda_t = lsoda_err = None
    for rtol in (1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9):
        dt, sol = best_time(
            lambda rtol=rtol: solve_ivp(rhs, (0, T_END), [0.0, 0.0, 0.0], method="LSODA",
                                        t_eval=T, rtol=rtol, atol=rtol * SCALES), 2)
        err = rel_error(sol.y[0], ref.x) if sol.status == 0 else float("inf")
        print(f"LSODA rtol {rtol:.0e}, atol = rtol*{SCALES.tolist()}: {dt:.3f} s, "
              f"error {err:.1e}, nfev {sol.nfev}")
        if err < TARGET:
            lsoda_t, lsoda_err = dt, err
            break

    rk_t, rk = best_time(
        lambda: solve_ivp(rhs, (0, T_END), [0.0, 0.0, 0.0], method="RK45", t_eval=T), 1)
    print(f"RK45 default tolerances (rtol 1e-3, atol 1e-6): {rk_t:.3f} s, status "
          f"{rk.status} ({rk.message!r}), error on x {rel_error(rk.y[0], ref.x):.1e}, "
          f"on v {rel_error(rk.y[1], ref.v):.1e}, peak v {rk.y[1].max():.3f} m/s "
          f"(truth {ref.v.max():.3f})")

    if lsoda_t is None:
        print("LSODA never reached the target")
    else:
        print(f"speed-up at matched accuracy (ours default, error {ours_err:.1e}, vs LSODA, "
              f"error {lsoda_err:.1e}): {lsoda_t / ours_t:.0f}x (target >= 3x)")


if __name__ == "__main__":
    main()
