"""Fleet benchmark (issue 16): detection on a simulated plant, and Dask throughput.

Writes a simulated fleet (default 200 axes × 12 months, 10 % faulty; driveid.sim.fleet),
identifies every record on a local Dask cluster into a SQLite catalogue, makes a blueprint
from every axis's first 3 months, judges every axis-month with only the data up to it, and
prints

* detection rate of faulty axes, false-alarm rate on healthy axis-months (target <= 1 %),
  median delay from fault onset to detection [months];
* throughput [records/s] serial in this process (the baseline), on 1 Dask worker with one
  record per task (the per-task overhead) and batched (those three on at most 48 records),
  and on batched workers (``--workers 1 2 4 ...`` on a machine with more cores) over
  ``--throughput-records``: records/s, efficiency against workers x the in-process rate,
  processor time per record and overhead per task (issue 28), and what 100 000 axes per
  8-hour shift needs; ``--methods output-error logdec`` for the costly and the cheapest
  estimator; ``--plain``: the same records in N plain processes at once and a pure-Python
  loop, the machine's own scaling (efficiency = one process's time / N processes' time).

Run: ``MPLBACKEND=Agg .venv/bin/python benchmarks/bench_fleet.py [--axes 200] [--months 12]``.
"""

from __future__ import annotations

import argparse
import os
import statistics
import tempfile
import time
from pathlib import Path

from driveid.catalog import Catalog
from driveid.fleet import identify_file, identify_many
from driveid.health import assess_axis, make_blueprint
from driveid.sim.fleet import read_fleet_truth, simulate_fleet


def _throughput(files, n_workers, folder, batch_size=None, method="output-error"):
    name = f"throughput-{method}-{n_workers}-{batch_size}.sqlite"
    for suffix in ("", "-wal", "-shm"):  # a fresh catalogue: nothing may be skipped
        (folder / f"{name}{suffix}").unlink(missing_ok=True)
    return identify_many([str(f) for f in files], method=method,
                         method_options={"mass": 1.0}, catalog=folder / name,
                         n_workers=n_workers, progress=False, batch_size=batch_size)


def _plain_share(args):
    """One process's share: warm up, wait for the others, time its records [s/record]."""
    files, method, barrier = args
    identify_file(files[0], method=method, method_options={"mass": 1.0})
    barrier.wait()
    t0 = time.perf_counter()
    if method == "pure-python":  # the machine's own ceiling for CPU-bound interpreter work
        for _ in files:
            sum(i * i % 7 for i in range(200_000))
    else:
        for f in files:
            identify_file(f, method=method, method_options={"mass": 1.0})
    return (time.perf_counter() - t0) / len(files)


def _plain_rows(sample, workers, method):
    """The same records in N plain processes at once (no Dask, no catalogue): the machine's
    scaling of this work, the ceiling the Dask rows are measured against."""
    from concurrent.futures import ProcessPoolExecutor
    from multiprocessing import get_context

    ctx = get_context("fork")
    share = max(1, len(sample) // max(workers))  # each process the same work, at any N
    for what in (method, "pure-python"):
        base = None
        for n in sorted(set((1, *workers))):
            with ctx.Manager() as manager, ProcessPoolExecutor(n, mp_context=ctx) as pool:
                barrier = manager.Barrier(n)
                per = list(pool.map(_plain_share, [(sample[i * share:(i + 1) * share] or
                                                    sample[:1], what, barrier)
                                                   for i in range(n)]))
            wall = sum(per) / n
            base = base or wall
            print(f"{'plain ' + str(n) + ' process(es), ' + what:34s} {'-':>5s} "
                  f"{n / wall if what != 'pure-python' else float('nan'):9.2f} "
                  f"{base / wall:10.2f}", flush=True)


def _in_process(files, method):
    """Wall and processor time per record of the records in this process [s]."""
    t0, c0 = time.perf_counter(), time.process_time()
    for f in files:
        identify_file(f, method=method, method_options={"mass": 1.0})
    return ((time.perf_counter() - t0) / len(files), (time.process_time() - c0) / len(files))


def _throughput_study(files, n_records, folder, workers=(1, 2), method="output-error"):
    """In-process baseline, then Dask workers (one record per task, and batched).

    Efficiency = records/s / (workers x in-process records/s); the per-task overhead is the
    wall time each task costs beyond the in-process time of its records, x workers.
    """
    sample = files[: n_records]
    # the in-process baseline and the one-worker rows on at most 48 records (their rates do
    # not depend on the count); the batched multi-worker rows on all of them
    few = sample[:48]
    identify_file(sample[0], method=method, method_options={"mass": 1.0})  # compile first
    serial_wall, serial_cpu = _in_process(few, method)
    serial = 1.0 / serial_wall
    try:
        load = os.getloadavg()[0]
    except OSError:
        load = float("nan")
    print(f"method {method}: load average {load:.1f} on {os.cpu_count()} cores "
          "(throughput shares them)")
    print(f"{'run':34s} {'tasks':>5s} {'records/s':>9s} {'efficiency':>10s} "
          f"{'CPU ms/rec':>10s} {'overhead ms/task':>16s}")
    print(f"{'in-process (baseline)':34s} {'-':>5s} {serial:9.2f} {'1.00':>10s} "
          f"{serial_cpu * 1e3:10.0f} {'-':>16s}")
    rows = [(1, 1)] + [(w, None) for w in workers]
    for n_workers, batch in rows:
        chunk = few if n_workers == 1 else sample
        summary = _throughput(chunk, n_workers, folder, batch, method)
        rate = summary.records_per_second
        overhead = (summary.elapsed * n_workers - len(chunk) * serial_wall) / summary.n_tasks
        label = f"Dask {n_workers} worker(s), " + ("1 record/task" if batch == 1 else
                                                    "guided batches")
        print(f"{label:34s} {summary.n_tasks:5d} {rate:9.2f} "
              f"{rate / (n_workers * serial):10.2f} "
              f"{summary.cpu_seconds_per_record * 1e3:10.0f} {overhead * 1e3:16.1f}")
    # timed again after the Dask rows: a lent machine's core speed was seen to move by half
    # within minutes (docs/performance.md), which the efficiencies above would carry
    again, _ = _in_process(few, method)
    print(f"{'in-process again (drift check)':34s} {'-':>5s} {1.0 / again:9.2f} "
          f"{serial_wall / again:10.2f}")
    need = 100_000 / (8 * 3600)
    print(f"100 000 axes per 8-h shift = {need:.2f} records/s; at {serial_cpu * 1e3:.0f} ms "
          f"of processor time per record that is {need * serial_cpu:.2f} busy cores")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--axes", type=int, default=200)
    parser.add_argument("--months", type=int, default=12)
    parser.add_argument("--faulty", type=float, default=0.1)
    parser.add_argument("--throughput-records", type=int, default=160)
    parser.add_argument("--alpha", type=float, default=0.01)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path, default=None, help="Keep the fleet here.")
    parser.add_argument("--reuse", action="store_true",
                        help="Reuse the fleet and catalogue already under --out.")
    parser.add_argument("--skip-throughput", action="store_true")
    parser.add_argument("--skip-detection", action="store_true")
    parser.add_argument("--workers", type=int, nargs="+", default=[1, 2],
                        help="Dask worker counts of the batched throughput rows.")
    parser.add_argument("--plain", action="store_true",
                        help="Also run the records in N plain processes at once (no Dask) and "
                             "a pure-Python loop: the machine's own scaling, for reference.")
    parser.add_argument("--methods", nargs="+", default=["output-error"],
                        choices=["output-error", "logdec", "auto"],
                        help="Estimators of the throughput study, each in turn (logdec is "
                             "the cheapest).")
    args = parser.parse_args()
    folder = args.out or Path(tempfile.mkdtemp(prefix="driveid-fleet-"))
    t0 = time.perf_counter()
    if args.reuse and (folder / "plant" / "truth.csv").is_file():
        truth = read_fleet_truth(folder / "plant")
        print(f"reusing {len(truth.rows)} records in {folder / 'plant'}")
    else:
        truth = simulate_fleet(folder / "plant", n_axes=args.axes, n_months=args.months,
                               faulty_fraction=args.faulty, seed=args.seed, overwrite=True)
        print(f"simulated {len(truth.rows)} records in {time.perf_counter() - t0:.1f} s "
              f"({folder / 'plant'})")
    files = sorted((folder / "plant").glob("*/*/20*.csv"))

    if not args.skip_throughput:
        for method in args.methods:
            _throughput_study(files, args.throughput_records, folder, tuple(args.workers),
                              method)
            if args.plain:
                _plain_rows(files[: args.throughput_records], tuple(args.workers), method)
    if args.skip_detection:
        return
    # the whole fleet on 2 workers into one catalogue
    catalog = folder / "catalog.sqlite"
    t0 = time.perf_counter()
    summary = identify_many(str(folder / "plant" / "*" / "*" / "20*.csv"),
                            method_options={"mass": 1.0}, catalog=catalog,
                            machine_type="demo", n_workers=2, progress=False)
    print(f"fleet: {summary.n_ok} identified, {summary.n_failed} failed in "
          f"{time.perf_counter() - t0:.0f} s ({summary.records_per_second:.1f} records/s)")

    with Catalog(catalog) as cat:
        entries = cat.entries(machine_type="demo")
    bp = make_blueprint(entries, machine_type="demo", first=3)
    by_axis: dict[tuple[str, str], list] = {}
    for e in entries:
        by_axis.setdefault((e.machine, e.axis), []).append(e)
    axes = truth.axes()
    healthy_months = false_alarms = watch_months = 0
    detected, delays, n_faulty = 0, [], 0
    by_kind: dict[str, list[int]] = {}
    for key, rows in by_axis.items():
        health = assess_axis(rows, bp, alpha=args.alpha)
        fault, onset = axes[key]["fault"], axes[key]["onset_month"]
        verdicts = health.verdicts
        if fault != "none":
            n_faulty += 1
        first_alarm = None
        for month, verdict in enumerate(verdicts):
            faulty_now = onset is not None and month >= onset
            if not faulty_now:
                healthy_months += 1
                false_alarms += verdict == "degraded"
                watch_months += verdict == "watch"
            elif verdict == "degraded" and first_alarm is None:
                first_alarm = month
        if fault != "none":
            by_kind.setdefault(fault, [0, 0])[1] += 1
            if first_alarm is not None:
                detected += 1
                by_kind[fault][0] += 1
                delays.append(first_alarm - onset)
    print(f"blueprint: {bp.source['n_axes']} axes; monitored {', '.join(bp.monitored)}")
    print(f"detection rate: {detected}/{n_faulty} faulty axes = "
          f"{detected / max(n_faulty, 1):.1%} ("
          + ", ".join(f"{k} {d}/{n}" for k, (d, n) in sorted(by_kind.items())) + ")")
    print(f"false-alarm rate: {false_alarms}/{healthy_months} healthy axis-months = "
          f"{false_alarms / healthy_months:.2%} (target <= 1 %); 'watch' on "
          f"{watch_months / healthy_months:.1%}")
    if delays:
        print(f"median delay from onset to detection: {statistics.median(delays):.1f} months "
              f"(onset month counts as 0; range {min(delays)}-{max(delays)})")


if __name__ == "__main__":
    main()
