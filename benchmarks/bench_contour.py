"""Circular contour test (issue 27): the simulator against closed forms, identification
accuracy and interval coverage, compensation, and time per simulation and identification.

Part 1, closed form: linear axes (50 kg, 100 N·s/m, PID kp = 2e5 N/m, kd = 6e3 N·s/m,
ki = 1e6 N/(m·s), 2 kHz) on circles at several feeds and radii; the steady radius over the
last fifth of six turns against ``R |G|`` of the sampled loop and of the continuous transfer
function (:func:`driveid.sim.contour.closed_loop_gain`).

Part 2, identification: the axes of ``examples/drive_configs/contour_xy.toml`` (truth: x
59 N, 6 N, 270 N·s/m, 12 µm; y 43 N, -3 N, 195 N·s/m, 8 µm) on circles at four feeds and
radii; each replicate draws a start angle (a different trajectory, so a different model
error) and a noise seed (1e-7 m on positions, 0.5 N on commands). Printed per parameter:
largest relative error, coverage of the 95 % intervals (value ± 1.96 s.e.) and the ratio of
the observed scatter to the mean standard error. The first replicate of each case also runs
the compensation from its own estimate in the true plant: the peak radial error without,
with, and with the friction 20 % low and high.

Part 3, time: per contour simulation (two axes, sampled PID through the controller callback
of ``simulate_drive``) against the same axes under the in-kernel continuous PD feedback
(``PDFeedback`` with a reference array: no Python per control period) in the same run; per
identification without and with the validation/compensation preview.

Run: ``.venv/bin/python benchmarks/bench_contour.py [--reps 10]``.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import time

import numpy as np

from driveid.identify.contour.circle import (
    ContourRecord,
    compensation_from_estimate,
    estimate_contour,
)
from driveid.sim.contour import circle_reference, closed_loop_gain, simulate_contour
from driveid.sim.contour_config import load_contour_config, parse_contour_config
from driveid.sim.drive import PDFeedback, simulate_drive

EXAMPLE = "examples/drive_configs/contour_xy.toml"
CASES = ((0.025, 0.1), (0.05, 0.1), (0.05, 0.05), (0.1, 0.25))
NAMES = ("fk_mean", "fk_delta", "c_mean", "gap")


def closed_form() -> None:
    print("1. linear axes: steady radius error against the closed loop")
    print(f"{'R [mm]':>7} {'feed':>6} {'ω':>6} {'R(|G|-1) [µm]':>14} {'sim - sampled':>14} "
          f"{'sim - continuous':>17}")
    for radius, feed in ((0.01, 0.3), (0.02, 0.15), (0.05, 0.5), (0.005, 0.05)):
        axis = {"body": [{"J": 50.0, "c_mean": 100.0}],
                "controller": {"kp": 2e5, "kd": 6e3, "ki": 1e6, "rate": 2000.0}}
        cfg = parse_contour_config({"x": axis, "y": axis, "path": {
            "radius": radius, "feed": feed, "revolutions": 6.0, "fs": 2000.0,
            "ramp": 0.02}})
        res = simulate_contour(cfg)
        idx = np.flatnonzero(res.metrics["steady"])
        dr = res.metrics["radial"][idx[4 * idx.size // 5:]]
        omega = feed / radius
        ctl = cfg.axes["x"].controller
        exp_s = radius * (abs(closed_loop_gain(50.0, 100.0, ctl, omega)) - 1)
        exp_c = radius * (abs(closed_loop_gain(50.0, 100.0, ctl, omega, sampled=False)) - 1)
        print(f"{radius * 1e3:7.1f} {feed:6.2f} {omega:6.1f} {exp_s * 1e6:14.4f} "
              f"{np.max(np.abs(dr - exp_s)) / abs(exp_s):13.2e}x "
              f"{np.max(np.abs(dr - exp_c)) / abs(exp_c):16.2e}x")
    print("   (relative to the radius error; the continuous form differs by the hold, O(ωT))")


def _truth(config) -> dict:
    out = {}
    for a, axis in config.axes.items():
        bodies, link = axis.drive.bodies, axis.drive.links[0]
        out[a] = {"fk_mean": sum(b.fk_mean for b in bodies),
                  "fk_delta": sum(b.fk_delta for b in bodies),
                  "c_mean": sum(b.c_mean for b in bodies),
                  "gap": link.gap_plus + link.gap_minus}
    return out


def identification(reps: int) -> dict:
    base = load_contour_config(EXAMPLE)
    truth = _truth(base)
    rng = np.random.default_rng(2027)
    print(f"\n2. identification, {reps} replicates per case (start angle and noise drawn)")
    times = {"simulate": [], "identify": [], "identify+preview": []}
    for radius, feed in CASES:
        errs = {f"{a}.{n}": [] for a in truth for n in NAMES}
        z = {k: [] for k in errs}
        se = {k: [] for k in errs}
        vals = {k: [] for k in errs}
        for rep in range(reps):
            path = dataclasses.replace(base.path, radius=radius, feed=feed,
                                       start_angle=float(rng.uniform(20.0, 70.0)))
            noise = dataclasses.replace(base.noise, seed=int(rng.integers(1 << 31)))
            cfg = dataclasses.replace(base, path=path, noise=noise)
            t0 = time.perf_counter()
            res = simulate_contour(cfg)
            times["simulate"].append(time.perf_counter() - t0)
            rec = ContourRecord.from_columns(res.columns(cfg.noise))
            t0 = time.perf_counter()
            est = estimate_contour(rec, cfg, validate=False, compensation=False)
            times["identify"].append(time.perf_counter() - t0)
            for a, tr in truth.items():
                for n, value in tr.items():
                    k = f"{a}.{n}"
                    scale = tr["fk_mean"] if n == "fk_delta" else abs(value)
                    errs[k].append((est.value(k) - value) / scale)
                    z[k].append((est.value(k) - value) / est.stderr(k))
                    se[k].append(est.stderr(k))
                    vals[k].append(est.value(k))
            if rep == 0:
                t0 = time.perf_counter()
                estimate_contour(rec, cfg)
                times["identify+preview"].append(time.perf_counter() - t0)
                peaks = {"without": res.metrics["peak"]}
                for label, factor in (("with", 1.0), ("-20 %", 0.8), ("+20 %", 1.2)):
                    comp = compensation_from_estimate(est, friction=factor, config=cfg)
                    peaks[label] = simulate_contour(cfg, compensation=comp).metrics["peak"]
        print(f"R = {radius * 1e3:.0f} mm, feed = {feed} m/s "
              f"(ω = {feed / radius:.1f} rad/s)")
        print(f"  {'parameter':12s} {'max |error|':>12s} {'coverage':>9s} {'sd/se':>6s}")
        for k in errs:
            unit = "of fk_mean" if k.endswith("fk_delta") else ""
            sd = np.std(vals[k], ddof=1) if reps > 1 else math.nan
            print(f"  {k:12s} {np.max(np.abs(errs[k])) * 100:10.3f} % "
                  f"{np.mean(np.abs(z[k]) < 1.96):9.2f} {sd / np.mean(se[k]):6.2f} {unit}")
        ratio = peaks["without"] / peaks["with"]
        print(f"  peak radial error [µm]: without {peaks['without'] * 1e6:.2f}, with "
              f"{peaks['with'] * 1e6:.2f} ({ratio:.1f}x lower), friction -20 % "
              f"{peaks['-20 %'] * 1e6:.2f} ({peaks['without'] / peaks['-20 %']:.1f}x), "
              f"+20 % {peaks['+20 %'] * 1e6:.2f} ({peaks['without'] / peaks['+20 %']:.1f}x)")
    return times


def timing(times: dict) -> None:
    base = load_contour_config(EXAMPLE)
    t_pd = []
    for _ in range(3):  # the same axes under in-kernel continuous PD on a reference array
        t0 = time.perf_counter()
        for name, axis in base.axes.items():
            ctl = axis.controller
            drive = dataclasses.replace(axis.drive, feedback=PDFeedback(
                P=ctl.kp, D=ctl.kd, body=ctl.body))
            t = np.arange(int(base.path.duration * base.path.fs) + 1) / base.path.fs
            ref = circle_reference(base.path, t)["p1" if name == "x" else "p2"]
            simulate_drive(drive, duration=base.path.duration, fs=base.path.fs,
                           x0=np.full(axis.drive.n_bodies, ref[0]), reference=ref)
        t_pd.append(time.perf_counter() - t0)
    t_sim = []
    for _ in range(3):
        t0 = time.perf_counter()
        simulate_contour(base)
        t_sim.append(time.perf_counter() - t0)
    print("\n3. time (median; the example: two axes, 3.24 s of path, 2 kHz)")
    print(f"  contour simulation, sampled PID (callback): {np.median(t_sim):.3f} s; the same "
          f"axes under in-kernel PD: {np.median(t_pd):.3f} s "
          f"(ratio {np.median(t_sim) / np.median(t_pd):.2f})")
    print(f"  over all replicates: simulation {np.median(times['simulate']):.3f} s, "
          f"identification {np.median(times['identify']) * 1e3:.0f} ms, with validation "
          f"and compensation preview {np.median(times['identify+preview']):.2f} s")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--reps", type=int, default=10, help="replicates per case")
    args = parser.parse_args()
    simulate_contour(load_contour_config(EXAMPLE))  # compile the kernels first
    closed_form()
    timing(identification(args.reps))


if __name__ == "__main__":
    main()
