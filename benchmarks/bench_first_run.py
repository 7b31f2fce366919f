"""The first ``driveid simulate drive`` after an install (empty numba cache), before and after.

Issue 28: the first simulation after an install waited ~30 s while the drive kernel
compiled; the target is <= 10 s. Each repeat takes a fresh, empty ``NUMBA_CACHE_DIR`` and
runs, as fresh processes:

1. ``driveid simulate drive --preset testbed-a`` as it is now: a run this short goes to the
   kernel's interpreted functions while the cache is cold (``driveid.sim._first_run``);
2. the same with ``DRIVEID_INTERPRET_STEPS=0``, the behaviour before: it compiles the
   kernel (and fills the cache);
3. the same loading the cache that (2) filled: the baseline, a warm run.

It prints wall and CPU seconds of each (on a shared machine the wall time also counts other
people's work), their spread over the repeats, and the ratios. ``--duration`` makes the run
longer (the interpreted budget, 100 000 body-steps by default, then decides).

Run: ``python benchmarks/bench_first_run.py [--repeats 3] [--preset testbed-a]``
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

DRIVEID = str(Path(sys.executable).parent / "driveid")


def _run(cmd: list[str], **extra_env: str) -> tuple[float, float]:
    """Wall time [s] and CPU time of the child process [s] of one run of ``cmd``."""
    env = dict(os.environ, MPLBACKEND="Agg", **extra_env)
    before = os.times()
    start = time.perf_counter()
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, env=env)
    wall = time.perf_counter() - start
    after = os.times()
    cpu = (after.children_user + after.children_system
           - before.children_user - before.children_system)
    return wall, cpu


def _line(name: str, rows: list[tuple[float, float]], baseline: float | None) -> str:
    walls, cpus = [r[0] for r in rows], [r[1] for r in rows]
    text = (f"{name:46s} wall {statistics.median(walls):6.2f} s ({min(walls):.2f}-"
            f"{max(walls):.2f})  CPU {statistics.median(cpus):6.2f} s ({min(cpus):.2f}-"
            f"{max(cpus):.2f})")
    if baseline is not None:
        text += f"  {statistics.median(cpus) / baseline:5.1f}x warm (CPU)"
    return text


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--preset", default="testbed-a")
    parser.add_argument("--duration", type=float, default=None,
                        help="run length [s] (default: the preset's, 5 s)")
    args = parser.parse_args()
    cases: dict[str, list[tuple[float, float]]] = {"now": [], "before": [], "warm": []}
    for _ in range(args.repeats):
        with tempfile.TemporaryDirectory() as cache:
            out = str(Path(cache) / "first.csv")
            cmd = [DRIVEID, "simulate", "drive", "--preset", args.preset, "--out", out,
                   "--overwrite"]
            if args.duration is not None:
                cmd += ["--duration", str(args.duration)]
            cases["now"].append(_run(cmd, NUMBA_CACHE_DIR=cache))
            cases["before"].append(_run(cmd, NUMBA_CACHE_DIR=cache, DRIVEID_INTERPRET_STEPS="0"))
            cases["warm"].append(_run(cmd, NUMBA_CACHE_DIR=cache))
    warm = statistics.median(r[1] for r in cases["warm"])
    print(f"first `driveid simulate drive --preset {args.preset}` after an install, "
          f"{args.repeats} repeats (median, range); target <= 10 s")
    print(_line("before: empty cache, compiles the kernel", cases["before"], warm))
    print(_line("now: empty cache, short run interpreted", cases["now"], warm))
    print(_line("baseline: warm cache (loads the kernel)", cases["warm"], None))
    before = statistics.median(r[1] for r in cases["before"])
    now = statistics.median(r[1] for r in cases["now"])
    print(f"now / before (CPU): {now / before:.3f}   before / now: {before / now:.0f}x")


if __name__ == "__main__":
    main()
