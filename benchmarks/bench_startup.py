"""Start-up time of the command line against a same-run baseline.

Prints the median wall time of ``driveid --help`` (and a few subcommand ``--help`` pages and
``import driveid``) over repeated fresh processes, as a ratio to ``python -c "import numpy"``
timed in the same run. Target (issue 18): ``driveid --help`` <= 2x the numpy import.

With ``--compile`` it also times ``driveid warmup`` (every simulation kernel) with an empty
numba cache (a fresh ``NUMBA_CACHE_DIR``: the first simulation after an install) against the
same command loading that cache, and (issue 28) the first ``driveid simulate drive --preset
testbed-a`` after an install (an empty cache: it compiles the drive kernel) against the same
command loading the cache, with the CPU seconds of each (on a shared machine the wall time
also counts other people's work; the target is <= 10 s).

Run: ``python benchmarks/bench_startup.py [--repeats 15] [--compile]``
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

BIN = Path(sys.executable).parent


def _time(cmd: list[str], repeats: int, **extra_env: str) -> float:
    return _time_cpu(cmd, repeats, **extra_env)[0]


def _time_cpu(cmd: list[str], repeats: int, **extra_env: str) -> tuple[float, float]:
    """Median wall time [s] and median CPU time of the child process [s]."""
    env = dict(os.environ, MPLBACKEND="Agg", **extra_env)
    times, cpus = [], []
    for _ in range(repeats):
        before = os.times()
        start = time.perf_counter()
        subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, env=env)
        times.append(time.perf_counter() - start)
        after = os.times()
        cpus.append(after.children_user + after.children_system
                    - before.children_user - before.children_system)
    return statistics.median(times), statistics.median(cpus)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=15)
    parser.add_argument("--compile", action="store_true",
                        help="also time the kernels' first compilation (driveid warmup)")
    args = parser.parse_args()
    driveid = str(BIN / "driveid")
    baseline = _time([sys.executable, "-c", "import numpy"], args.repeats)
    print(f"baseline python -c 'import numpy': {baseline * 1e3:7.1f} ms (median of "
          f"{args.repeats})")
    cases = {
        "driveid --help": [driveid, "--help"],
        "driveid identify logdec --help": [driveid, "identify", "logdec", "--help"],
        "driveid pho run --help": [driveid, "pho", "run", "--help"],
        "python -c 'import driveid'": [sys.executable, "-c", "import driveid"],
    }
    for name, cmd in cases.items():
        t = _time(cmd, args.repeats)
        print(f"{name:34s} {t * 1e3:7.1f} ms   {t / baseline:5.2f}x numpy import")
    if args.compile:
        with tempfile.TemporaryDirectory() as cache:
            cold = _time([driveid, "warmup"], 1, NUMBA_CACHE_DIR=cache)
            warm = _time([driveid, "warmup"], 3, NUMBA_CACHE_DIR=cache)
        print(f"driveid warmup, empty kernel cache  {cold:7.1f} s    {cold / warm:5.1f}x the "
              f"same command loading the cache ({warm:.1f} s)")
        with tempfile.TemporaryDirectory() as cache:
            out = str(Path(cache) / "first.csv")
            cmd = [driveid, "simulate", "drive", "--preset", "testbed-a", "--out", out,
                   "--overwrite"]
            cold, cold_cpu = _time_cpu(cmd, 1, NUMBA_CACHE_DIR=cache)
            warm, warm_cpu = _time_cpu(cmd, 3, NUMBA_CACHE_DIR=cache)
        print(f"first simulate drive, empty cache   {cold:7.1f} s    (CPU {cold_cpu:.1f} s; "
              f"target <= 10 s); loading the cache {warm:.1f} s (CPU {warm_cpu:.1f} s)")


if __name__ == "__main__":
    main()
