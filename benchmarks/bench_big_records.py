"""Bounded resources (issue 12): time and peak memory of every identify command on a big record.

Writes a free decay of N samples (default 10 million: 100 s at 100 kHz of the Table 5.1
case-3 oscillator, thesis 2.136, with encoder quantisation) as .npz, then runs each command
in its own subprocess (so peak memory is that command's alone) and prints, per command:
wall time, peak resident memory (``ru_maxrss``) and the ratios of both to a baseline timed
in the same run - a subprocess that only reads the record (``read_record``). The record
itself is 3 columns x 8 B x N (240 MB at N = 1e7).

``--profile`` also splits ``identify logdec`` into its phases (read, uniform resampling,
period estimate, peak finding, fit) and prints each phase's traced peak (tracemalloc), to
show where the memory goes.

Usage::

    .venv/bin/python benchmarks/bench_big_records.py [--n 1e7] [--timeout 900]
        [--commands logdec,hilbert,wavelet] [--profile]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

_CHILD = r"""
import json, resource, sys, time, warnings
t0 = time.perf_counter()
args = json.loads(sys.argv[1])
if args[0] == "read":
    from driveid.io import read_record
    rec = read_record(args[1])
    status = 0
else:
    from driveid.cli import cli
    import io, contextlib
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        status = cli.main(args, prog_name="driveid", standalone_mode=False)
elapsed = time.perf_counter() - t0
peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
print("RESULT " + json.dumps({"status": status, "seconds": elapsed, "peak": peak}))
"""


def _make_record(n: int, folder: Path) -> Path:
    import numpy as np

    from driveid.io import Record, write_record

    fs = 1e5
    t = np.arange(n) / fs
    # a viscous + Coulomb decay (2.136 with c = 0.3, fk = 0.07, J = 1, K = 16) sampled
    # exactly is not needed for timing: an exponentially decaying cosine with a linear
    # (Coulomb) envelope term has the same peak structure and costs nothing to make
    omega = 4.0
    envelope = np.maximum(10.0 * np.exp(-0.15 * t) - 0.0044 * t, 0.0)
    x = envelope * np.cos(omega * np.sqrt(1 - 0.0375**2) * t)
    x = np.round(x * 8000 / (2 * np.pi)) * (2 * np.pi / 8000)  # 8000 counts/rev encoder
    rec = Record(t=t, x=x, u=np.zeros(n))
    path = folder / "big.npz"
    write_record(rec, path)
    return path


def _run(args: list[str], timeout: float) -> dict:
    start = time.perf_counter()
    try:
        res = subprocess.run([sys.executable, "-c", _CHILD, json.dumps(args)],
                             capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return {"status": "timeout", "seconds": time.perf_counter() - start, "peak": None}
    for line in res.stdout.splitlines():
        if line.startswith("RESULT "):
            return json.loads(line[7:])
    return {"status": f"failed: {res.stderr.strip().splitlines()[-1:]}",
            "seconds": time.perf_counter() - start, "peak": None}


def _profile_logdec(path: Path, n: int) -> None:
    import tracemalloc

    from driveid.identify.logdec import estimate_log_decrement
    from driveid.io import read_record
    from driveid.signal.peaks import dominant_period, find_oscillation_peaks

    tracemalloc.start()
    state: dict = {}
    phases = [
        ("read_record", lambda: state.setdefault("rec", read_record(path))),
        ("resampled_uniform", lambda: state.setdefault(
            "uni", state["rec"].resampled_uniform(purpose="peak refinement"))),
        ("dominant_period", lambda: dominant_period(state["uni"])),
        ("find_oscillation_peaks", lambda: find_oscillation_peaks(state["uni"])),
        ("estimate_log_decrement", lambda: estimate_log_decrement(state["rec"], mass=1.0)),
    ]
    print(f"{'logdec phase':<26}{'time [s]':>10}{'traced peak [MB]':>18}{'x record':>10}")
    for name, step in phases:
        tracemalloc.reset_peak()
        t0 = time.perf_counter()
        step()
        peak = tracemalloc.get_traced_memory()[1]
        print(f"{name:<26}{time.perf_counter() - t0:>10.1f}{peak / 1e6:>18.0f}"
              f"{peak / (24 * n):>10.2f}")
    tracemalloc.stop()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=float, default=1e7, help="samples")
    parser.add_argument("--timeout", type=float, default=900.0, help="per command [s]")
    parser.add_argument("--commands", default="logdec,hilbert,wavelet")
    parser.add_argument("--profile", action="store_true", help="phases of logdec")
    opts = parser.parse_args()
    n = int(opts.n)
    with tempfile.TemporaryDirectory() as d:
        t0 = time.perf_counter()
        path = _make_record(n, Path(d))
        print(f"record: {n:.3g} samples, {path.stat().st_size / 1e6:.0f} MB on disk, "
              f"made in {time.perf_counter() - t0:.1f} s")
        base = _run(["read", str(path)], opts.timeout)
        print(f"{'command':<22}{'time [s]':>10}{'peak [MB]':>11}{'x time':>8}{'x peak':>8}"
              f"{'peak/record':>13}  status")
        record_bytes = 3 * 8 * n
        rows = [("read_record (baseline)", base)]
        for name in opts.commands.split(","):
            args = ["identify", name, str(path), "--json"]
            if name in ("logdec", "hilbert"):
                args += ["--mass", "1"]
            rows.append((f"identify {name}", _run(args, opts.timeout)))
        for label, r in rows:
            peak = r["peak"]
            ratio_t = r["seconds"] / base["seconds"] if base["seconds"] else float("nan")
            ratio_p = (peak / base["peak"]) if peak and base["peak"] else float("nan")
            per_rec = peak / record_bytes if peak else float("nan")
            print(f"{label:<22}{r['seconds']:>10.1f}"
                  f"{(peak or float('nan')) / 1e6:>11.0f}{ratio_t:>8.2f}{ratio_p:>8.2f}"
                  f"{per_rec:>13.2f}  {r['status']}")
        if opts.profile:
            _profile_logdec(path, n)


if __name__ == "__main__":
    main()
