"""Bounded resources (issue 12): time and peak memory of every identify command on big records.

Writes, for N samples (default 10 million), one record per test shape as .npz and runs each
identify command in its own subprocess (so the peak is that command's alone). Per command it
prints wall time, peak resident memory (``VmHWM``), the ratios of both to a baseline
timed in the same run - a subprocess that only reads the free decay (``read_record``) -
and ``peak/record``: the peak over the command's record size, the float64 columns of its
file(s) in memory (columns x 8 B x N).

Records (closed forms, so that making 1e7 samples takes seconds, not a simulation):

* ``decay`` - free decay of the Table 5.1 case-3 oscillator shape (thesis 2.136: viscous
  plus Coulomb envelope, 8000 counts/rev quantisation), 100 kHz: logdec, hilbert, wavelet,
  envelope;
* ``motion`` - a 0.5 Hz sine of 0.1 m with u = 3 a + asymmetric Coulomb + viscous friction
  and noise, 10 kHz: idim, friction-map (binned, ``--inertia 3``);
* ``ramps`` - force ramps to breakaway at 0.05 N·m (sticks, then slides): breakaway;
* ``dahl`` - a 1 Hz force sine with the Dahl presliding displacement built branch by
  branch (sigma0 = 1e5 N/m): loop;
* ``static`` - loads and settled deflections (K = 500 N·m/rad): static-stiffness. A real
  static test has one row per load (tens of rows); N rows only show the method scales;
* ``steps`` - a DC-biased square-wave command and the exact discrete second-order response
  (zeta 0.2, omega0 20 rad/s), 1 kHz: step;
* ``forced`` - three steady sine runs (2, 4, 6 rad/s) of N/3 samples each: forced.

Usage::

    .venv/bin/python benchmarks/bench_big_records.py [--n 1e7] [--timeout 900]
        [--commands logdec,logdec-peaks,idim,...] [--profile]

``--profile`` also splits ``identify logdec --method peaks`` into its phases and prints each
phase's traced peak (tracemalloc), to show where the memory goes.
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
# VmHWM: this process's own high-water mark (ru_maxrss keeps the forking parent's RSS as a
# floor across exec, so a parent holding the records would hide every child's peak)
try:
    with open("/proc/self/status") as fh:
        peak = next(int(l.split()[1]) * 1024 for l in fh if l.startswith("VmHWM:"))
except (OSError, StopIteration):
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
print("RESULT " + json.dumps({"status": status, "seconds": elapsed, "peak": peak}))
"""

#: command label -> (record shape, extra CLI arguments)
COMMANDS = {
    "logdec": ("decay", ["--mass", "1"]),
    "logdec-peaks": ("decay", ["--mass", "1", "--method", "peaks"]),
    "envelope": ("decay", ["--mass", "1"]),
    "hilbert": ("decay", ["--mass", "1"]),
    "wavelet": ("decay", []),
    "idim": ("motion", ["--cutoff-hz", "20", "--offset", "0"]),
    "friction-map": ("motion", ["--inertia", "3", "--models", "coulomb_viscous",
                                "--min-speed", "0.02"]),
    "breakaway": ("ramps", ["--v-break", "0.05"]),
    "loop": ("dahl", ["--kind", "presliding"]),
    "static-stiffness": ("static", []),
    "step": ("steps", []),
    "forced": ("forced", []),
}


def _decay(n):
    import numpy as np

    fs = 1e5
    t = np.arange(n) / fs
    # a viscous + Coulomb decay (2.136 with c = 0.3, fk = 0.07, J = 1, K = 16) sampled
    # exactly is not needed for timing: an exponentially decaying cosine with a linear
    # (Coulomb) envelope term has the same peak structure and costs nothing to make
    omega = 4.0
    envelope = np.maximum(10.0 * np.exp(-0.15 * t) - 0.0044 * t, 0.0)
    x = envelope * np.cos(omega * np.sqrt(1 - 0.0375**2) * t)
    x = np.round(x * 8000 / (2 * np.pi)) * (2 * np.pi / 8000)  # 8000 counts/rev encoder
    return [dict(t=t, x=x, u=np.zeros(n))], {"x": "rad", "u": "N·m"}


def _motion(n):
    import numpy as np

    t = np.arange(n) / 1e4
    w = 2 * np.pi * 0.5
    x = 0.1 * np.sin(w * t)
    v, a = 0.1 * w * np.cos(w * t), -0.1 * w**2 * np.sin(w * t)
    u = 3.0 * a + np.where(v > 0, 2.0 + 8.0 * v, -1.5 + 6.0 * v)
    u += 0.05 * np.random.default_rng(0).standard_normal(n)
    return [dict(t=t, x=x, u=u)], {"x": "m", "u": "N"}


def _ramps(n):
    import numpy as np

    fs = 1e3
    t = np.arange(n) / fs
    period = 5.0  # a ramp of 0.02 N·m/s from rest every 5 s, alternating sign
    k = np.floor(t / period)
    tau = t - k * period
    sign = np.where(k % 2 == 0, 1.0, -1.0)
    u = sign * np.where(tau < 0.5, 0.0, 0.02 * (tau - 0.5))
    # sticks until |u| reaches fs = 0.05, then slides against fk = 0.04 (J = 1e-3)
    t_break = 0.5 + 0.05 / 0.02
    slide = np.maximum(tau - t_break, 0.0)
    travel = sign * (0.01 * slide**2 / 2e-3 + 0.02 * slide**3 / 6e-3)
    # each ramp starts where the last one ended (no jump in x): + travel, then back
    end = 0.01 * (period - t_break)**2 / 2e-3 + 0.02 * (period - t_break)**3 / 6e-3
    x = travel + end * (k % 2)
    u += 1e-4 * np.random.default_rng(0).standard_normal(n)
    return [dict(t=t, x=x, u=u)], {"x": "rad", "u": "N·m"}


def _dahl(n):
    import numpy as np

    fs = 2e3
    t = np.arange(n) / fs
    force = 6.0 * np.sin(2 * np.pi * t)
    x = np.zeros(n)
    # Dahl branches (sigma0 = 1e5 N/m, level 10 N), one vectorised branch per half period:
    # a branch starts at sample i where the force's direction s changes, from (f, x)[i - 1]
    s = np.where(np.diff(force) > 0, 1, -1)
    starts = [1, *(np.flatnonzero(np.diff(s)) + 2).tolist()]
    fr, xr = 0.0, 0.0
    for i0, i1 in zip(starts, [*starts[1:], n], strict=True):
        if i0 > 1:
            fr, xr = force[i0 - 1], x[i0 - 1]
        sign = s[i0 - 1]
        x[i0:i1] = xr - sign * 10.0 / 1e5 * np.log((sign * 10.0 - force[i0:i1])
                                                  / (sign * 10.0 - fr))
    return [dict(t=t, x=x, u=force)], {"x": "m", "u": "N"}


def _static(n):
    import numpy as np

    rng = np.random.default_rng(0)
    loads = rng.uniform(-3.0, 3.0, n)
    defl = loads / 500.0 + 1e-6 * rng.standard_normal(n)
    return [dict(t=np.arange(n, dtype=float), x=defl, u=loads)], {"x": "rad", "u": "N·m"}


def _steps(n):
    import numpy as np
    from scipy import signal

    fs = 1e3
    zeta, w0 = 0.2, 20.0
    t = np.arange(n) / fs
    cmd = np.where((t % 2.0) < 1.0, 1.0, 0.0) + 0.5
    # exact zero-order-hold discretisation of w0^2/(s^2 + 2 zeta w0 s + w0^2): lfilter is C
    b, a, _ = signal.cont2discrete(([w0**2], [1, 2 * zeta * w0, w0**2]), 1 / fs)
    y = signal.lfilter(np.ravel(b), a, cmd)
    return [dict(t=t, x=np.cumsum(y) / fs, v=y, u=cmd)], {"x": "rad", "u": "N·m",
                                                         "v": "rad/s"}


def _forced(n):
    import numpy as np

    J, C, K = 1.0, 0.4, 16.0
    runs = []
    for om in (2.0, 4.0, 6.0):
        t = np.arange(n // 3) / 1e4
        h = 1.0 / (K - J * om**2 + 1j * C * om)
        runs.append(dict(t=t, x=np.abs(h) * np.sin(om * t + np.angle(h)), u=np.sin(om * t)))
    return runs, {"x": "rad", "u": "N·m"}


SHAPES = {"decay": _decay, "motion": _motion, "ramps": _ramps, "dahl": _dahl,
          "static": _static, "steps": _steps, "forced": _forced}


def _make(shape: str, n: int, folder: Path) -> tuple[list[Path], int]:
    """Write the records of one shape; return their paths and float64 bytes in memory."""
    from driveid.io import Record, write_record

    runs, units = SHAPES[shape](n)
    paths, size = [], 0
    for k, cols in enumerate(runs):
        rec = Record(**cols, meta={"units": units}, max_jitter=None)
        paths.append(write_record(rec, folder / f"{shape}{k}.npz"))
        size += 8 * sum(c.size for c in cols.values())
    return paths, size


def _make_record(n: int, folder: Path) -> Path:
    """The free decay alone (kept for scripts that import it)."""
    return _make("decay", n, folder)[0][0]


def _run(args: list[str], timeout: float) -> dict:
    start = time.perf_counter()
    try:
        res = subprocess.run([sys.executable, "-c", _CHILD, json.dumps(args)],
                             capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return {"status": "timeout", "seconds": time.perf_counter() - start, "peak": None}
    for line in res.stdout.splitlines():
        if line.startswith("RESULT "):
            out = json.loads(line[7:])
            if out["status"]:
                out["status"] = f"{out['status']}: {res.stderr.strip().splitlines()[-1:]}"
            return out
    return {"status": f"failed: {res.stderr.strip().splitlines()[-1:]}",
            "seconds": time.perf_counter() - start, "peak": None}


def _profile_logdec(path: Path, n: int) -> None:
    import tracemalloc

    from driveid.identify.free_decay.logdec import estimate_log_decrement
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
    parser.add_argument("--commands", default=",".join(COMMANDS),
                        help=f"comma-separated, from {', '.join(COMMANDS)}")
    parser.add_argument("--profile", action="store_true", help="phases of logdec")
    opts = parser.parse_args()
    n = int(opts.n)
    names = [c for c in opts.commands.split(",") if c]
    unknown = set(names) - set(COMMANDS)
    if unknown:
        parser.error(f"unknown command(s) {sorted(unknown)}; choose from {list(COMMANDS)}")
    with tempfile.TemporaryDirectory() as d:
        made: dict[str, tuple[list[Path], int]] = {}
        for shape in ["decay"] + [COMMANDS[c][0] for c in names]:
            if shape not in made:
                t0 = time.perf_counter()
                made[shape] = _make(shape, n, Path(d))
                disk = sum(p.stat().st_size for p in made[shape][0]) / 1e6
                print(f"record {shape}: {n:.3g} samples, {made[shape][1] / 1e6:.0f} MB in "
                      f"memory, {disk:.0f} MB on disk, made in {time.perf_counter() - t0:.1f} s",
                      flush=True)
        decay_path, decay_bytes = made["decay"][0][0], made["decay"][1]
        base = _run(["read", str(decay_path)], opts.timeout)
        rows = [("read_record (baseline)", base, decay_bytes)]
        for name in names:
            shape, extra = COMMANDS[name]
            paths, size = made[shape]
            command = name.split("-peaks")[0]
            args = ["identify", command, *map(str, paths), "--json", *extra]
            rows.append((f"identify {name}", _run(args, opts.timeout), size))
            print(f"  done: {name} ({rows[-1][1]['seconds']:.0f} s)", flush=True)
        print(f"{'command':<26}{'time [s]':>10}{'peak [MB]':>11}{'x time':>8}{'x peak':>8}"
              f"{'record [MB]':>13}{'peak/record':>13}  status")
        for label, r, size in rows:
            peak = r["peak"]
            ratio_t = r["seconds"] / base["seconds"] if base["seconds"] else float("nan")
            ratio_p = (peak / base["peak"]) if peak and base["peak"] else float("nan")
            per_rec = peak / size if peak else float("nan")
            print(f"{label:<26}{r['seconds']:>10.1f}"
                  f"{(peak or float('nan')) / 1e6:>11.0f}{ratio_t:>8.2f}{ratio_p:>8.2f}"
                  f"{size / 1e6:>13.0f}{per_rec:>13.2f}  {r['status']}")
        if opts.profile:
            _profile_logdec(decay_path, n)


if __name__ == "__main__":
    main()
