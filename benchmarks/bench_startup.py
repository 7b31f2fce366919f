"""Start-up time of the command line against a same-run baseline.

Prints the median wall time of ``driveid --help`` (and a few subcommand ``--help`` pages and
``import driveid``) over repeated fresh processes, as a ratio to ``python -c "import numpy"``
timed in the same run. Target (issue 18): ``driveid --help`` <= 2x the numpy import.

Run: ``python benchmarks/bench_startup.py [--repeats 15]``
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

BIN = Path(sys.executable).parent


def _time(cmd: list[str], repeats: int) -> float:
    env = dict(os.environ, MPLBACKEND="Agg")
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, env=env)
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=15)
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


if __name__ == "__main__":
    main()
