"""Whole-drive output-error fit: time per fit as a ratio to one simulation, and coverage.

Three-body test bed (preset ``testbed``: motor A, backlash to B, shaft to C, delayed PD),
released from 1 rad, motor ``x1`` and load ``x3`` measured with 2e-4 rad noise and an
8000 counts/rev encoder; estimated: the inertias, A's kinetic friction, the gap, the shaft
stiffness and the loop delay, from starts 35 % off. Prints the time of one fit against one
simulation of the record (same run), the errors, and the coverage of the 95 % intervals
over ``--runs`` noise realisations (issue 25 asks >= 100; pass a small count to check),
with the bias and scatter of the estimates in units of the reported standard error.
``--design two-body``: the open-loop two-body backlash drive instead (motor torque three
sines, 6 s, x1 and x2 measured, J, c, f_k of both bodies, both gaps and the contact k); its
whole-record fit is followed by the fit in pieces (``--pieces``, default auto: 0.5 s pieces
for an open-loop drive with backlash, halved once where over a tenth of the piece channels
are not white), and the whole-record fit's own coverage is printed beside.

    PYTHONPATH=src python benchmarks/bench_drive_fit.py --runs 5
    PYTHONPATH=src python benchmarks/bench_drive_fit.py --runs 112 --workers 16   # many cores
    PYTHONPATH=src python benchmarks/bench_drive_fit.py --design two-body --runs 30 \
        --workers 2 --skip-timing --pieces 0.5
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from driveid.errors import DriveIdError
from driveid.identify.drive._drive_model import get_value, with_values
from driveid.identify.drive.drive_fit import DriveRecord, estimate_drive
from driveid.sim import simulate_drive
from driveid.sim.presets import preset_testbed

NAMES = ["body1.J", "body1.c_mean", "body1.fk_mean", "body2.J", "body3.J",
         "link1.gap_plus", "link2.k", "feedback.delay"]


def _open_loop_timing() -> None:
    """The issue's speed case: a 10 s, 1 kHz two-body backlash record, 9 free parameters."""
    DESIGNS["two-body"](10.0)  # compiled before timing
    t0 = time.perf_counter()
    for _ in range(20):
        DESIGNS["two-body"](10.0)
    one_sim = (time.perf_counter() - t0) / 20
    fit, val, _, n_sims, info = _one_fit(0, 0.35, 2e-4, 8000.0, "two-body", 10.0)
    true = _setup(0.35, "two-body", 10.0)[3]
    worst = float(np.max(np.abs(val / true - 1)))
    print(f"open loop, two bodies, 10 s at 1 kHz, 9 parameters from 35 % off: fit {fit:.1f} s "
          f"= {fit / one_sim:.0f} x one simulation ({1e3 * one_sim:.2f} ms); "
          f"{n_sims} simulations; max |error| {100 * worst:.2f} %"
          + (f"; with {info['n_pieces']} pieces of {info['length']:g} s" if info["done"]
             else "")
          + (f"; {info['ridge_restarts']['tried']} ridge restarts (cost "
             f"{info['ridge_restarts']['cost_to_noise']:.3f} -> "
             f"{info['ridge_restarts']['final_cost_to_noise']:.3f} of the noise)"
             if info.get("ridge_restarts", {}).get("tried") else ""))


TWO_BODY_NAMES = ["body1.J", "body1.c_mean", "body1.fk_mean", "body2.J", "body2.c_mean",
                  "body2.fk_mean", "link1.gap_plus", "link1.gap_minus", "link1.k"]


def _three_sines(duration: float) -> np.ndarray:
    """The open-loop designs' motor torque at 1 kHz: sines of 0.5, 2.3 and 7.1 Hz [N·m]."""
    t = np.arange(int(round(duration * 1000)) + 1) / 1000.0
    return (0.3 * np.sin(2 * np.pi * 0.5 * t) + 0.2 * np.sin(2 * np.pi * 2.3 * t)
            + 0.1 * np.sin(2 * np.pi * 7.1 * t))


def _two_body_truth():
    from driveid.sim import BacklashLink, BodyParams, DriveParams

    return DriveParams(bodies=(BodyParams(J=0.0115, c_mean=0.002, fk_mean=0.11),
                               BodyParams(J=0.0035, c_mean=0.0011, fk_mean=0.03)),
                       links=(BacklashLink(gap_plus=0.02, gap_minus=0.02, k=100.0, c=0.05),))


def _two_body(duration: float = 6.0):
    """Open-loop two-body backlash drive, three sines on the motor, ``duration`` s at 1 kHz."""
    truth = _two_body_truth()
    u = _three_sines(duration)
    res = simulate_drive(truth, duration=duration, torque=np.vstack([u, 0 * u]))
    return truth, res, u, TWO_BODY_NAMES, (("x1", 0), ("x2", 1))


def _testbed(duration: float = 5.0):
    """The thesis test bed under its delayed PD loop, released from 1 rad, 1 kHz."""
    truth = preset_testbed()
    res = simulate_drive(truth, duration=duration, fs=1000.0, x0=[1.0, 1.0, 1.0])
    return truth, res, None, NAMES, (("x1", 0), ("x3", 2))


def _two_body_pd(duration: float = 5.0):
    """The two-body backlash drive under a delayed PD loop on the motor (P 5 N·m/rad, D 0.1
    N·m·s/rad, 13.77 ms), released from 1 rad, 1 kHz; the 9 parameters and the delay."""
    import dataclasses

    from driveid.sim import PDFeedback

    truth = dataclasses.replace(_two_body_truth(),
                                feedback=PDFeedback(P=5.0, D=0.1, delay=0.01377))
    res = simulate_drive(truth, duration=duration, fs=1000.0, x0=[1.0, 1.0])
    return truth, res, None, TWO_BODY_NAMES + ["feedback.delay"], (("x1", 0), ("x2", 1))


THREE_BODY_NAMES = ["body1.J", "body1.c_mean", "body1.fk_mean", "body2.J", "body3.J",
                    "body3.fk_mean", "link1.gap_plus", "link1.gap_minus", "link2.k"]


def _three_body(duration: float = 6.0):
    """The test bed open loop (no feedback): motor torque three sines, x1 and x3, 1 kHz."""
    import dataclasses

    truth = dataclasses.replace(preset_testbed(), feedback=None)
    u = _three_sines(duration)
    res = simulate_drive(truth, duration=duration, torque=np.vstack([u, 0 * u, 0 * u]))
    return truth, res, u, THREE_BODY_NAMES, (("x1", 0), ("x3", 2))


DESIGNS = {"testbed": _testbed, "two-body": _two_body, "two-body-pd": _two_body_pd,
           "three-body": _three_body}


def _setup(start_off: float, design: str = "testbed", duration: float | None = None):
    truth, res, u, names, chans = (DESIGNS[design]() if duration is None
                                   else DESIGNS[design](duration))
    zero = np.zeros(truth.n_bodies)
    signs = [1 if i % 2 == 0 else -1 for i in range(len(names))]
    start, _, _ = with_values(truth, zero, zero, {
        n: get_value(truth, zero, zero, n) * (1 + s * start_off)
        for n, s in zip(names, signs, strict=True)})
    true = np.array([get_value(truth, zero, zero, n) for n in names])
    return truth, res, start, true, names, chans, u


def _one_fit(seed: int, start_off: float, noise: float, counts_per_rev: float,
             design: str = "testbed", duration: float | None = None,
             pieces: float | None = None, segment: float = 0.5, paths: int | None = None,
             test_rest: bool = True):
    """One noise realisation: (seconds, values, standard errors, simulations, pieces)."""
    _, res, start, _, names, chans, u = _setup(start_off, design, duration)
    rng = np.random.default_rng(seed)
    data = {c: res.x[i] + rng.normal(0, noise, res.t.size) for c, i in chans}
    if counts_per_rev:
        q = 2 * np.pi / counts_per_rev
        data = {c: np.round(y / q) * q for c, y in data.items()}
    rec = DriveRecord(t=res.t, channels=data, u=u)
    t0 = time.perf_counter()
    try:
        est = estimate_drive(rec, start, estimate=names, pieces=pieces, segment=segment,
                             paths=paths, test_rest=test_rest)
    except DriveIdError as exc:
        # one failed fit is a result of the benchmark (a miss), not the end of the run
        nan = np.full(len(names), np.nan)
        return (time.perf_counter() - t0, nan, nan, 0,
                {"done": False, "warned": True, "failed": f"{type(exc).__name__}: {exc}"})
    seconds = time.perf_counter() - t0
    # the encoder note ("x1 is quantised with a step of ...") comes with every quantised
    # record and says nothing of this fit's adequacy: not counted as a warning here
    info = dict(est.diagnostics["pieces"], warned=any(
        "is quantised with a step" not in w for w in est.warnings))
    return (seconds, np.array([est.value(n) for n in names]),
            np.array([est.stderr(n) for n in names]), est.diagnostics["n_simulations"],
            info)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--runs", type=int, default=100)
    ap.add_argument("--first-seed", type=int, default=0,
                    help="seed of the first realisation (fresh seeds: another range)")
    ap.add_argument("--start-off", type=float, default=0.35)
    ap.add_argument("--counts-per-rev", type=float, default=8000.0,
                    help="encoder resolution; 0: no quantisation")
    ap.add_argument("--noise", type=float, default=2e-4, help="position noise sd [rad]")
    ap.add_argument("--workers", type=int, default=1,
                    help="processes for the realisations (each fit on one core)")
    ap.add_argument("--skip-timing", action="store_true")
    ap.add_argument("--design", choices=sorted(DESIGNS), default="testbed",
                    help="testbed: three bodies under delayed PD (8 parameters); two-body: "
                         "open-loop backlash drive, 6 s (9 parameters); two-body-pd: the same "
                         "under a delayed PD, 5 s (10 with the delay); three-body: the test "
                         "bed open loop, 6 s, x1 and x3 (9)")
    ap.add_argument("--pieces", default="auto",
                    help="second stage in pieces of this length [s] (open loop); auto: as "
                         "estimate_drive decides (backlash or a poor residual); 0: never")
    ap.add_argument("--segment", type=float, default=0.5,
                    help="first horizon of the whole-record fit [s] (estimate_drive's default "
                         "0.5; a fit far above the noise is retried from heads 5 times "
                         "shorter: docs/drive-fit.md)")
    ap.add_argument("--paths", type=int, default=None,
                    help="whole-record fits from first horizons segment, /5, /2, the lowest "
                         "cost kept (default: estimate_drive's, 3 for backlash under PD)")
    ap.add_argument("--no-rest-test", action="store_true",
                    help="keep the fit with free start velocities (estimate_drive's "
                         "test_rest=False)")
    args = ap.parse_args()
    pieces = None if args.pieces == "auto" else float(args.pieces)
    if not args.skip_timing:
        _open_loop_timing()
    _, _, _, true, names, _, _ = _setup(args.start_off, args.design)
    reps = 20
    t0 = time.perf_counter()
    for _ in range(reps):
        DESIGNS[args.design]()
    one_sim = (time.perf_counter() - t0) / reps
    hits = np.zeros(len(names))
    # issue 25's acceptance: friction (viscous, kinetic) within 10 %, every other within 5 %
    limit = np.array([0.10 if n.endswith((".c_mean", ".fk_mean")) else 0.05 for n in names])
    accepted = 0
    errors, times, ses, vals, whole = [], [], [], [], []
    work = [(seed, args.start_off, args.noise, args.counts_per_rev, args.design, None, pieces,
             args.segment, args.paths, not args.no_rest_test)
            for seed in range(args.first_seed, args.first_seed + args.runs)]
    pool = None
    if args.workers > 1:
        from concurrent.futures import ProcessPoolExecutor

        pool = ProcessPoolExecutor(args.workers)
        # in order, each printed as it arrives: a run cut short still leaves its lines
        outcomes = pool.map(_one_fit, *zip(*work, strict=True))
    else:
        outcomes = (_one_fit(*w) for w in work)
    warned = [0, 0]  # runs warned; of them outside the acceptance
    quiet_outside = 0
    failed = 0  # fits that raised (counted outside the acceptance, covering nothing)
    for seed, (seconds, val, se, _, info) in enumerate(outcomes, start=args.first_seed):
        times.append(seconds)
        if "failed" in info:
            print(f"run {seed}: {seconds:.1f} s, FAILED ({info['failed']}), outside the "
                  "acceptance", flush=True)
            failed += 1
            errors.append(np.full(len(names), np.inf))
            ses.append(se)
            vals.append(val)
            continue
        if info["done"]:
            whole.append(([info["whole_record_values"][n] for n in names],
                          [info["whole_record_stderr"][n] for n in names]))
        hits += np.abs(val - true) <= 1.96 * se
        errors.append(val / true - 1)
        ses.append(se)
        vals.append(val)
        # covered (1) or not (0), parameter by parameter: a cut-short run can still be counted
        covered = "".join("1" if c else "0" for c in np.abs(val - true) <= 1.96 * se)
        within = bool(np.all(np.abs(errors[-1]) <= limit))
        accepted += within
        warned[0] += info["warned"]
        warned[1] += info["warned"] and not within
        quiet_outside += not info["warned"] and not within
        worst = int(np.argmax(np.abs(errors[-1])))
        print(f"run {seed}: {times[-1]:.1f} s, covered {covered}, max |error| "
              f"{100 * abs(errors[-1][worst]):.2f} % ({names[worst]})"
              f"{'' if within else ', outside the acceptance'}"
              f"{', warned' if info['warned'] else ''}"
              + (f", {info['n_pieces']} pieces of {info['length']:g} s "
                 f"({info['pieces_not_white']} of {info['piece_channels']} channels not white"
                 + (f"; halved from {info['halved_from']['length']:g} s, "
                    f"{info['halved_from']['not_white']} not white" if info["halved_from"]
                    else "") + ")" if info["done"] else "")
              + (f", {info['ridge_restarts']['tried']} ridge restarts "
                 f"({info['ridge_restarts']['taken']} taken, cost "
                 f"{info['ridge_restarts']['cost_to_noise']:.3f} -> "
                 f"{info['ridge_restarts']['final_cost_to_noise']:.3f} of the noise)"
                 if info.get("ridge_restarts", {}).get("tried") else "")
              + (f", refitted from {info['short_horizon_retry']['segment']:g} s heads "
                 f"(residual {info['short_horizon_retry']['residual_to_noise']:.3g} -> "
                 f"{info['short_horizon_retry']['retried_residual_to_noise']:.3g} times the "
                 f"noise{'' if info['short_horizon_retry']['kept'] else ', not kept'})"
                 if info.get("short_horizon_retry") else "")
              + (f", best of {len(info['paths']['segments'])} paths: "
                 f"{info['paths']['segments'][info['paths']['kept']]:g} s heads"
                 if info.get("paths") else "")
              + (f", start at rest {'kept' if info['start_at_rest']['at_rest'] else 'refused'}"
                 f" (chi2 {info['start_at_rest']['delta_chi2']:+.3g})"
                 if info.get("start_at_rest") else ""),
              flush=True)
    if pool is not None:
        pool.shutdown()
    errors = np.array(errors)
    print(f"one simulation {1e3 * one_sim:.2f} ms; one fit median {np.median(times):.1f} s "
          f"= {np.median(times) / one_sim:.0f} simulations")
    ses, vals = np.array(ses), np.array(vals)
    # bias and scatter in units of the median reported standard error: bias/se near 0 and
    # sd/se near 1 is what a 95 % coverage needs
    sd = np.std(vals, axis=0, ddof=1) if args.runs > 1 else np.full(len(names), np.nan)
    mid_se = np.median(ses, axis=0)
    print(f"{'parameter':16s} {'median err %':>12s} {'max |err| %':>12s} {'bias/se':>8s} "
          f"{'sd/se':>6s} {'coverage':>9s}")
    for j, n in enumerate(names):
        print(f"{n:16s} {100 * np.median(errors[:, j]):12.3f} "
              f"{100 * np.max(np.abs(errors[:, j])):12.3f} "
              f"{np.mean(vals[:, j] - true[j]) / mid_se[j]:8.2f} {sd[j] / mid_se[j]:6.2f} "
              f"{hits[j] / args.runs:9.2f}")
    print(f"within the acceptance (friction 10 %, the rest 5 %): {accepted} of {args.runs}; "
          f"warned {warned[0]} (of them outside: {warned[1]}); outside without a warning: "
          f"{quiet_outside}; fits that failed: {failed}")
    print(f"binomial sd of a 95 % coverage over {args.runs} runs: "
          f"{100 * np.sqrt(0.95 * 0.05 / args.runs):.1f} %")
    if whole:
        # the same runs' first stage (the whole record) with its own error bars
        wv, ws = (np.array(a) for a in zip(*whole, strict=True))
        cover = np.mean(np.abs(wv - true) <= 1.96 * ws, axis=0)
        print(f"{len(whole)} runs went on in pieces; their whole-record fit alone:")
        for j, n in enumerate(names):
            print(f"{n:16s} max |err| {100 * np.max(np.abs(wv[:, j] / true[j] - 1)):8.3f} %  "
                  f"median |err|/se {np.median(np.abs(wv[:, j] - true[j]) / ws[:, j]):8.1f}"
                  f"  coverage {cover[j]:.2f}")

if __name__ == "__main__":
    main()
