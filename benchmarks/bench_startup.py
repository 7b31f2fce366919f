"""Start-up time of the command line against a same-run baseline.

Prints the median wall time of ``driveid --help`` (and a few subcommand ``--help`` pages and
``import driveid``) over repeated fresh processes, as a ratio to ``python -c "import numpy"``
timed in the same run. Target (issue 18): ``driveid --help`` <= 2x the numpy import.

With ``--compile`` it also times ``driveid warmup`` (every simulation kernel) with an empty
numba cache (a fresh ``NUMBA_CACHE_DIR``: the first simulation after an install) against the
same command loading that cache. The first ``driveid simulate drive`` after an install
(issue 28) has its own benchmark, ``benchmarks/bench_first_run.py``.

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
    """Median wall time [s] of ``cmd`` over ``repeats`` fresh processes."""
    env = dict(os.environ, MPLBACKEND="Agg", **extra_env)
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, env=env)
        times.append(time.perf_counter() - start)
    return statistics.median(times)


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


if __name__ == "__main__":
    main()
